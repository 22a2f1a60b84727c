//! The live view (`receive --view`) in a real browser, and its server's rules.
//!
//! The browser tests drive a headless Chromium over the DevTools protocol (a WebSocket: the
//! page is loaded, a DOM counter the page keeps is read, screenshots are taken) while a rig scan
//! is written into the host's pseudo-terminal at a steady pace. They need Debian's `chromium`
//! (`scripts/setup` installs it; `CHROMIUM=path` names another). Without it they fail, naming
//! what is missing, unless `SCANNER_SKIP_BROWSER=1` is set, which they then print loudly.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use scanner_core::nalgebra::Point3;
use scanner_tests::browser::{Browser, chromium, lines_of, wait_line};
use scanner_tests::interrupt;
use scanner_web::live::LiveView;

fn bin(name: &str) -> PathBuf {
    scanner_tests::workspace_bin(name)
}

// ---------------------------------------------------------------------------------------------
// The scan: a rig sweep recorded once, then written into the host's pseudo-terminal at a pace.

/// A sphere and the bunny in front of the demo board, 400×300, recorded to a stream file.
fn recorded_scan(dir: &Path) -> PathBuf {
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scanner-device/scenes/bunny.obj");
    std::fs::copy(bunny, dir.join("bunny.obj")).unwrap();
    let text = "width = 400\nheight = 300\n\n[laser]\nframes = 160\n\n\
         [[objects]]\nshape = \"sphere\"\ncentre = [-110.0, 20.0, 540.0]\nradius = 45.0\n\n\
         [[objects]]\nshape = \"mesh\"\npath = \"bunny.obj\"\ncentre = [40.0, 25.0, 520.0]\nheight_mm = 100.0\nyaw_deg = 20.0\n";
    std::fs::write(dir.join("scene.toml"), text).unwrap();
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(text, dir).unwrap()).unwrap();
    rig.truth_calibration()
        .save(&dir.join("calibration.toml"))
        .unwrap();
    let stream = dir.join("scan.stream");
    let (ok, _, err) = scanner_tests::run(
        bin("scanner-device").to_str().unwrap(),
        &[
            "scan",
            "--source",
            "rig",
            "--scene",
            dir.join("scene.toml").to_str().unwrap(),
            "--calibration",
            dir.join("calibration.toml").to_str().unwrap(),
            "--format",
            "rgb",
            "--colour",
            "--scan-id",
            "7",
            "--quiet",
            "--out",
            stream.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
    stream
}

/// A host the test started, killed when the test ends without having stopped it (a failed
/// assertion would otherwise leave it running).
struct Started(Option<Child>);

impl Started {
    /// The host, for the test to stop itself.
    fn take(mut self) -> Child {
        self.0.take().expect("the host, not yet taken")
    }
}

impl Drop for Started {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// `receive pty --until-done --view` into `out`: the host, its stderr's lines, the page's
/// address and the device end of its link.
fn live_host(out: &Path, extra: &[&str]) -> (Started, Receiver<String>, String, String) {
    let mut child = Command::new(bin("scanner-host"))
        .args(["receive", "pty", "--until-done", "--quiet", "--out"])
        .arg(out)
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = lines_of(child.stderr.take().unwrap());
    let url =
        wait_line(&lines, "live view: ", Duration::from_secs(20)).expect("the page's address");
    let port = wait_line(&lines, "device end of the link: ", Duration::from_secs(20))
        .expect("the link's device end");
    (Started(Some(child)), lines, url, port)
}

/// Writes `stream` into the serial device `port` in `chunks` pieces, `gap` apart (a head that
/// streams over several seconds).
fn stream_into(
    port: &str,
    stream: &Path,
    chunks: usize,
    gap: Duration,
) -> std::thread::JoinHandle<()> {
    let bytes = std::fs::read(stream).unwrap();
    let port = port.to_string();
    std::thread::spawn(move || {
        let mut p = serialport::new(&port, 921_600)
            .timeout(Duration::from_secs(10))
            .open_native()
            .expect("the device end opens");
        for piece in bytes.chunks(bytes.len().div_ceil(chunks)) {
            p.write_all(piece).unwrap();
            p.flush().unwrap();
            std::thread::sleep(gap);
        }
    })
}

/// The same recording received without a live view, for comparison.
fn reference_outputs(stream: &Path, out: &Path) {
    let (ok, _, err) = scanner_tests::run(
        bin("scanner-host").to_str().unwrap(),
        &[
            "receive",
            stream.to_str().unwrap(),
            "--until-done",
            "--quiet",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
}

fn assert_same_outputs(a: &Path, b: &Path) {
    for f in scanner_host::outputs::OUTPUT_FILES
        .iter()
        .chain(&["journal.stream"])
    {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

/// Pixels of the 3-D view that are not its background, right of the panel.
fn object_pixels(img: &image::RgbImage) -> usize {
    let bg = [0x1d_i32, 0x21, 0x28];
    img.enumerate_pixels()
        .filter(|(x, _, _)| *x >= 420)
        .filter(|(_, _, p)| {
            p.0.iter()
                .zip(bg)
                .map(|(a, b)| (i32::from(*a) - b).abs())
                .sum::<i32>()
                > 40
        })
        .count()
}

/// Where the test's screenshots go: `LIVE_VIEW_SHOTS=folder` keeps them (the README's pictures
/// are made so); a temporary folder otherwise.
fn shots_dir(tmp: &Path) -> PathBuf {
    std::env::var_os("LIVE_VIEW_SHOTS").map_or_else(|| tmp.to_path_buf(), PathBuf::from)
}

/// The page has opened its stream.
const CONNECTED: &str = "document.getElementById('state').textContent !== 'connecting…'";

#[test]
fn the_page_shows_the_scan_as_it_streams_then_offers_the_mesh() {
    let Some(exe) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let stream = recorded_scan(dir.path());
    let live = dir.path().join("live");
    let (host, _lines, url, port) = live_host(&live, &["--view"]);
    assert!(
        url.starts_with("http://127.0.0.1:"),
        "loopback by default: {url}"
    );
    let mut b = Browser::launch(&exe);
    b.navigate(&url);
    assert!(
        b.wait_for(CONNECTED, Duration::from_secs(30)),
        "the page connected to its stream"
    );
    // About 6 s of streaming.
    let writer = stream_into(&port, &stream, 60, Duration::from_millis(100));
    assert!(
        b.wait_for(
            "Number(document.body.dataset.points) >= 3000",
            Duration::from_secs(60)
        ),
        "the page counted points while they came: {}",
        b.eval("document.body.dataset.points || '0'")
    );
    // Still streaming: the scan is shown as it happens, not after.
    let state = b.eval("document.getElementById('state').textContent");
    let fps = b.eval("Number(document.getElementById('fps').textContent)");
    let mid = b.screenshot();
    let points_mid = b.eval("Number(document.body.dataset.points)");
    writer.join().unwrap();
    assert_eq!(state, "receiving", "the points came before the scan ended");
    assert!(
        fps.as_f64().is_some_and(|f| f > 0.0),
        "the status panel shows the frame rate: {fps}"
    );
    let lit = object_pixels(&mid);
    assert!(
        lit > 300,
        "the screenshot shows the points ({lit} non-background pixels)"
    );

    // The end: the mesh replaces the points, the files are offered.
    assert!(
        b.wait_for(
            "document.body.dataset.mesh === 'shown'",
            Duration::from_secs(60)
        ),
        "the finished mesh is shown"
    );
    let downloads = b.eval("Number(document.body.dataset.downloads)");
    assert_eq!(
        downloads, 7,
        "scan.obj/ply/stl, depth.png, preview.png, summary.json and .txt offered"
    );
    let received = b
        .eval("Number(document.body.dataset.points)")
        .as_u64()
        .unwrap();
    let sent = scanner_tests::summary(&live)["points"].as_u64().unwrap();
    assert_eq!(
        received, sent,
        "every point reached the page ({points_mid} of them mid-scan)"
    );
    let done = b.screenshot();
    assert!(object_pixels(&done) > 1000, "the mesh is drawn");
    let shots = shots_dir(dir.path());
    std::fs::create_dir_all(&shots).unwrap();
    mid.save(shots.join("live-view-streaming.png")).unwrap();
    done.save(shots.join("live-view-done.png")).unwrap();
    // A download is the file itself.
    let body = http_get(&url, "/files/scan.obj");
    assert_eq!(body.0, 200);
    assert_eq!(body.1, std::fs::read(live.join("scan.obj")).unwrap());
    interrupt(host.take());

    // The same bytes without the live view: identical outputs and journal.
    let plain = dir.path().join("plain");
    reference_outputs(&stream, &plain);
    assert_same_outputs(&live, &plain);
}

/// Offers `total` points at `rate` points/s (3 000 per update) to the page.
fn offer_points(v: &LiveView, total: u64, rate: f64) -> Duration {
    let pts: Vec<Point3<f32>> = (0..3000)
        .map(|i| Point3::new((i % 60) as f32, (i / 60) as f32, 500.0 + (i % 7) as f32))
        .collect();
    let t0 = Instant::now();
    let mut sent = 0u64;
    while sent < total {
        v.points(&pts, &[]);
        sent += pts.len() as u64;
        // Paced by the clock, not by the sleeps.
        let due = Duration::from_secs_f64(sent as f64 / rate);
        if let Some(wait) = due.checked_sub(t0.elapsed()) {
            std::thread::sleep(wait);
        }
    }
    t0.elapsed()
}

#[test]
fn the_page_keeps_up_with_300_000_points_a_second_in_bounded_memory() {
    let Some(exe) = chromium() else { return };
    let v = LiveView::start("127.0.0.1:0".parse().unwrap(), &[]).unwrap();
    let mut b = Browser::launch(&exe);
    // The page's default: at most 1 000 000 points drawn.
    b.navigate(v.url());
    assert!(b.wait_for(CONNECTED, Duration::from_secs(30)));
    // 300 000 points a second for 4 s…
    let t0 = Instant::now();
    let offered = offer_points(&v, 1_200_000, 300_000.0);
    assert!(
        b.wait_for(
            "Number(document.body.dataset.points) === 1200000",
            Duration::from_secs(60)
        ),
        "the page received all points: {}",
        b.eval("document.body.dataset.points")
    );
    println!(
        "1 200 000 points offered in {:.2} s ({:.0}/s); all on the page after {:.2} s",
        offered.as_secs_f64(),
        1.2e6 / offered.as_secs_f64(),
        t0.elapsed().as_secs_f64()
    );
    // …and on to a 5-million-point scan. Past 2 million the host thins its history by half, so
    // a page that lags behind then gets part of what it has not yet had: most, not all. Asked:
    // the first 2 million and half of the rest (3.5 million, 70 %), what the halving leaves a
    // page that lags from 2 million on (seen: about 90 % on an idle machine, 88 % beside
    // another test binary).
    offer_points(&v, 3_801_000, 300_000.0);
    let settled = "(() => { const n = Number(document.body.dataset.points); \
        const same = n === window.lastSeen; window.lastSeen = n; return same && n >= 3500000; })()";
    assert!(
        b.wait_for(settled, Duration::from_secs(120)),
        "the page received at least the first 2 million and half of the other 3 001 000 points: {}",
        b.eval("document.body.dataset.points")
    );
    let received = b.eval("Number(document.body.dataset.points)");
    let stored = b
        .eval("Number(document.body.dataset.stored)")
        .as_u64()
        .unwrap();
    assert!(
        (500_000..=1_000_000).contains(&stored),
        "drawn points thinned to the page's cap: {stored}"
    );
    assert_eq!(v.dropped(), 0, "no view update dropped at these rates");
    let heap = b.eval("performance.memory ? performance.memory.usedJSHeapSize : 0");
    println!(
        "page: {stored} points drawn of {received} received (5 001 000 offered); JS heap {heap} bytes"
    );
}

// ---------------------------------------------------------------------------------------------
// The server's rules, through raw connections.

/// Sends `request` raw and returns the status code and body.
fn raw(addr: &str, request: &[u8]) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let _ = s.write_all(request);
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer);
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = answer
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map_or_else(Vec::new, |i| answer[i + 4..].to_vec());
    (code, body)
}

fn host_port(url: &str) -> String {
    url.trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap()
        .to_string()
}

fn http_get(url: &str, path: &str) -> (u16, Vec<u8>) {
    let addr = host_port(url);
    raw(
        &addr,
        format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes(),
    )
}

#[test]
fn only_this_scans_data_is_served_and_bad_requests_are_refused() {
    let v = LiveView::start("127.0.0.1:0".parse().unwrap(), &[]).unwrap();
    let url = v.url().to_string();
    let addr = host_port(&url);
    let (code, page) = http_get(&url, "/");
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&page).contains("Live scan"));
    assert_eq!(http_get(&url, "/vendor/three.module.min.js").0, 200);
    let (code, licence) = http_get(&url, "/vendor/three-LICENSE.txt");
    assert_eq!(code, 200);
    assert!(
        String::from_utf8_lossy(&licence)
            .to_lowercase()
            .contains("three.js authors")
    );
    // The finished scan: a folder with the outputs and a file that is no output.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scan.obj"), "v 0 0 0\n").unwrap();
    std::fs::write(dir.path().join("journal.stream"), "private").unwrap();
    assert_eq!(
        http_get(&url, "/files/scan.obj").0,
        404,
        "nothing before the scan ends"
    );
    assert_eq!(http_get(&url, "/mesh.bin").0, 404);
    v.finish(
        None,
        None,
        dir.path(),
        &scanner_host::outputs::OUTPUT_FILES,
        "input ended",
    );
    let t0 = Instant::now();
    while http_get(&url, "/files/scan.obj").0 != 200 {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the finished scan is offered"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(http_get(&url, "/files/scan.obj").1, b"v 0 0 0\n");
    for path in [
        "/files/journal.stream",
        "/files/../journal.stream",
        "/files/%2e%2e/journal.stream",
        "/../../etc/passwd",
        "/files//etc/passwd",
        "/etc/passwd",
        "/app.js/../../Cargo.toml",
    ] {
        assert_eq!(http_get(&url, path).0, 404, "{path}");
    }
    let post = format!("POST / HTTP/1.1\r\nHost: {addr}\r\nContent-Length: 5\r\n\r\nhello");
    assert_eq!(raw(&addr, post.as_bytes()).0, 405);
    // the request line counts in the head's bytes
    let long_target = format!(
        "GET /{} HTTP/1.1\r\nHost: {addr}\r\n\r\n",
        "a".repeat(20_000)
    );
    assert_eq!(raw(&addr, long_target.as_bytes()).0, 431);
    let huge_head = format!(
        "GET / HTTP/1.1\r\nHost: {addr}\r\nX-Filler: {}\r\n\r\n",
        "b".repeat(20_000)
    );
    assert_eq!(raw(&addr, huge_head.as_bytes()).0, 431);
    assert_eq!(raw(&addr, b"\x16\x03\x01 not http at all\r\n\r\n").0, 400);
    assert_eq!(http_get(&url, "/live").0, 400, "/live is a WebSocket only");
}

#[test]
fn another_address_than_loopback_needs_the_token() {
    let v = LiveView::start("0.0.0.0:0".parse().unwrap(), &[]).unwrap();
    assert!(v.is_public());
    let url = v.url().to_string();
    let (_, token) = url.split_once("?token=").expect("a token in the address");
    assert!(token.len() >= 32, "128 random bits: {token}");
    let port = url.rsplit(':').next().unwrap().split('/').next().unwrap();
    let local = format!("http://127.0.0.1:{port}/");
    assert_eq!(http_get(&local, "/").0, 403, "no token");
    assert_eq!(http_get(&local, "/?token=0123").0, 403, "a wrong token");
    let mut wrong = token.to_string();
    wrong.replace_range(0..1, if token.starts_with('0') { "1" } else { "0" });
    assert_eq!(
        http_get(&local, &format!("/?token={wrong}")).0,
        403,
        "one digit off"
    );
    assert_eq!(
        http_get(&local, "/vendor/three.module.min.js").0,
        403,
        "every path needs it"
    );
    let (code, page) = http_get(&local, &format!("/?token={token}"));
    assert_eq!(code, 200);
    assert!(
        String::from_utf8_lossy(&page).contains(&format!("app.js?token={token}")),
        "the page's own requests carry the token"
    );
    let ws = format!(
        "GET /live HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    assert_eq!(
        raw(&format!("127.0.0.1:{port}"), ws.as_bytes()).0,
        403,
        "the stream too"
    );

    // Through the binary: the warning.
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(bin("scanner-host"))
        .args([
            "receive",
            "-",
            "--quiet",
            "--view",
            "0.0.0.0:0",
            "--view-for",
            "0",
            "--out",
        ])
        .arg(dir.path().join("out"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let _ = child.wait();
    assert!(
        err.contains("warning: the live view is served on 0.0.0.0"),
        "{err}"
    );
    assert!(err.contains("?token="), "{err}");
}

#[test]
fn a_flood_of_connections_is_bounded_and_survived() {
    let v = LiveView::start("127.0.0.1:0".parse().unwrap(), &[]).unwrap();
    let url = v.url().to_string();
    let addr = host_port(&url);
    // 100 connections that say nothing hold no page back…
    let mut idle: Vec<TcpStream> = (0..100)
        .map(|_| TcpStream::connect(&addr).unwrap())
        .collect();
    assert_eq!(
        http_get(&url, "/").0,
        200,
        "idle connections lock nobody out"
    );
    // …up to the stated bound: past it a connection is closed at once,
    let bound = scanner_web::front::FrontLimits::DEFAULT.connections;
    idle.extend((100..bound + 4).map(|_| TcpStream::connect(&addr).unwrap()));
    std::thread::sleep(Duration::from_millis(300));
    let (code, _) = http_get(&url, "/");
    assert_eq!(code, 0, "past the bound a connection is closed at once");
    // and once they go, the page is served again.
    drop(idle);
    let t0 = Instant::now();
    while http_get(&url, "/").0 != 200 {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the server recovers"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn fifty_connections_at_once_leave_the_scan_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let stream = recorded_scan(dir.path());
    let live = dir.path().join("live");
    let (host, _lines, url, port) = live_host(&live, &["--view", "--view-for", "0"]);
    let addr = host_port(&url);
    let writer = stream_into(&port, &stream, 30, Duration::from_millis(100));
    // 50 at once: pages that never read, plain requests, idle sockets and garbage.
    let mut held = Vec::new();
    let mut pages = Vec::new();
    for i in 0..50 {
        match i % 4 {
            0 => {
                if let Ok((ws, _)) = tungstenite::connect(format!("ws://{addr}/live")) {
                    pages.push(ws);
                }
            }
            1 => {
                let mut s = TcpStream::connect(&addr).unwrap();
                let _ = s.write_all(format!("GET / HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes());
                held.push(s);
            }
            2 => held.push(TcpStream::connect(&addr).unwrap()),
            _ => {
                let mut s = TcpStream::connect(&addr).unwrap();
                let _ = s.write_all(&[0xff; 4096]);
                held.push(s);
            }
        }
    }
    writer.join().unwrap();
    let mut child = host.take();
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the receive completed"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success());
    drop((held, pages));
    let plain = dir.path().join("plain");
    reference_outputs(&stream, &plain);
    assert_same_outputs(&live, &plain);
}

#[test]
fn a_port_in_use_is_named() {
    let a = LiveView::start("127.0.0.1:0".parse().unwrap(), &[]).unwrap();
    let addr: std::net::SocketAddr = host_port(a.url()).parse().unwrap();
    let e = LiveView::start(addr, &[]).err().expect("the port is taken");
    assert!(
        e.to_string().contains(&addr.to_string()),
        "the error names the address: {e}"
    );
}

/// `scanner-device preview` of a set-up the head cannot scan: the laser held at the camera, so
/// that every frame's light plane passes through it. The page shows the thumbnails, the board's
/// dots drawn on them, the line, and why a scan would skip the frame.
#[test]
fn the_preview_shows_the_picture_the_dots_and_why_a_scan_would_skip() {
    let Some(exe) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = "width = 400\nheight = 300\n\n[laser]\nframes = 40\nsource = [0.0, 0.0, 0.0]\n";
    std::fs::write(d.join("scene.toml"), text).unwrap();
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::from_toml_in(text, d).unwrap()).unwrap();
    rig.truth_calibration()
        .save(&d.join("calibration.toml"))
        .unwrap();
    let stream = d.join("preview.stream");
    let (ok, _, err) = scanner_tests::run(
        bin("scanner-device").to_str().unwrap(),
        &[
            "preview",
            "--source",
            "rig",
            "--scene",
            d.join("scene.toml").to_str().unwrap(),
            "--calibration",
            d.join("calibration.toml").to_str().unwrap(),
            "--every",
            "10",
            // As from a camera: the head prompts the operator (here, over the link).
            "--wait-for-laser",
            "5",
            "--quiet",
            "--out",
            stream.to_str().unwrap(),
        ],
    );
    assert!(ok, "{err}");
    let live = d.join("live");
    let (host, _lines, url, port) = live_host(&live, &["--view"]);
    let mut b = Browser::launch(&exe);
    b.navigate(&url);
    assert!(b.wait_for(CONNECTED, Duration::from_secs(30)));
    let writer = stream_into(&port, &stream, 8, Duration::from_millis(250));
    assert!(
        b.wait_for(
            "Number(document.body.dataset.previews) >= 2",
            Duration::from_secs(60)
        ),
        "thumbnails arrived: {}",
        b.eval("document.body.dataset.previews || '0'")
    );
    writer.join().unwrap();
    let dots = b.eval("Number(document.body.dataset.previewDots)");
    let lit = b.eval("Number(document.body.dataset.previewLit)");
    let state = b.eval("document.body.dataset.previewState");
    let skip = b.eval("document.body.dataset.previewSkip");
    let shown = b.eval("document.getElementById('preview-why').textContent");
    // The head's last prompt, "switch the laser ON now", is on the page.
    let notice = b.eval("document.body.dataset.notice");
    let prompt = b.eval("document.getElementById('notice').textContent");
    assert_eq!(notice, "switch_laser_on");
    assert!(prompt.as_str().is_some_and(|s| !s.is_empty()), "{prompt}");
    assert!(
        dots.as_u64().is_some_and(|n| n >= 8),
        "the board's dots: {dots}"
    );
    assert!(lit.as_u64().is_some_and(|n| n >= 40), "the line: {lit}");
    assert_eq!(state, "skipped");
    let reason = scanner_io::words::skip_reason(scanner_wire::Skip::PlaneThroughCamera);
    assert_eq!(skip, reason);
    assert!(
        shown.as_str().is_some_and(|s| s.contains(reason)),
        "the reason is on the page: {shown}"
    );
    // The dots are drawn: rings of their colour (#4cc9f0) on the thumbnail.
    let shot = b.screenshot();
    let rings = shot
        .pixels()
        .filter(|p| {
            let [r, g, bl] = p.0;
            r < 120 && g > 150 && bl > 180 && (i32::from(bl) - i32::from(r)) > 100
        })
        .count();
    assert!(rings > 100, "rings drawn on the thumbnail: {rings} pixels");
    let shots = shots_dir(d);
    std::fs::create_dir_all(&shots).unwrap();
    shot.save(shots.join("live-view-preview.png")).unwrap();
    interrupt(host.take());
    let summary = scanner_tests::summary(&live);
    assert_eq!(summary["previews"], 4, "{summary}");
}
