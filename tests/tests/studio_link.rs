//! The studio and a head at the far end of a serial cable (the Pi's path): both on
//! pseudo-terminals, the test the cable between them, which fails in the middle of a sweep
//! (every byte either way lost for 1.5 s, then some bytes damaged). Nothing already received is
//! lost, commands sent during the fault are answered when it ends, and the job goes on to its
//! model. Driven through the page's own requests (`/api/...`), without a browser.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};
use std::time::Duration;

use scanner_tests::{page, workspace_bin};
use serialport::{SerialPort, TTYPort};

/// The cable's state: 0 good, 1 cut (every byte lost), 2 noisy (every 97th byte flipped).
#[derive(Clone)]
struct Cable {
    state: Arc<AtomicU8>,
    lost: Arc<AtomicU64>,
}

impl Cable {
    /// Joins two pseudo-terminals' far ends, both ways.
    fn join(a: TTYPort, b: TTYPort) -> Cable {
        let cable = Cable {
            state: Arc::new(AtomicU8::new(0)),
            lost: Arc::new(AtomicU64::new(0)),
        };
        for (mut from, mut to) in [
            (a.try_clone_native().unwrap(), b.try_clone_native().unwrap()),
            (b, a),
        ] {
            let c = cable.clone();
            from.set_timeout(Duration::from_millis(20)).unwrap();
            std::thread::spawn(move || {
                let mut buf = [0u8; 4096];
                let mut k = 0u64;
                loop {
                    let n = match from.read(&mut buf) {
                        Ok(0) => return,
                        Ok(n) => n,
                        Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                        Err(_) => return,
                    };
                    match c.state.load(Ordering::SeqCst) {
                        1 => {
                            c.lost.fetch_add(n as u64, Ordering::SeqCst);
                            continue;
                        }
                        2 => {
                            for b in &mut buf[..n] {
                                k += 1;
                                if k.is_multiple_of(97) {
                                    *b ^= 0x24;
                                }
                            }
                        }
                        _ => {}
                    }
                    if to.write_all(&buf[..n]).is_err() {
                        return;
                    }
                }
            });
        }
        cable
    }
}

struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The processes `pid` has started and not yet reaped, from each of its threads' `children`
/// list in /proc.
fn children_of(pid: u32) -> Vec<u32> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("children")).ok())
        .flat_map(|s| {
            s.split_whitespace()
                .filter_map(|w| w.parse().ok())
                .collect::<Vec<u32>>()
        })
        .collect()
}

/// Watches `pid`'s children every 2 ms until dropped; [`ChildWatch::seen`] is every child pid
/// seen.
struct ChildWatch {
    stop: Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<Vec<u32>>>,
}

impl ChildWatch {
    fn start(pid: u32) -> ChildWatch {
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut seen = Vec::new();
            while !s.load(Ordering::SeqCst) {
                for c in children_of(pid) {
                    if !seen.contains(&c) {
                        seen.push(c);
                    }
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            seen
        });
        ChildWatch {
            stop,
            thread: Some(thread),
        }
    }

    fn seen(mut self) -> Vec<u32> {
        self.stop.store(true, Ordering::SeqCst);
        self.thread.take().unwrap().join().unwrap()
    }
}

fn request(url: &str, method: &str, path: &str, body: &str) -> (u16, serde_json::Value) {
    let addr = page::addr_of(url);
    match method {
        "POST" => page::post(&addr, path, body),
        _ => page::get(&addr, path),
    }
}

fn command(url: &str, body: &str) -> serde_json::Value {
    request(url, "POST", "/api/command", body).1
}

fn state(url: &str) -> serde_json::Value {
    page::state(&page::addr_of(url))
}

fn wait(url: &str, secs: u64, what: &str, f: impl Fn(&serde_json::Value) -> bool) {
    page::wait(&page::addr_of(url), secs, what, f);
}

fn scene(dir: &Path) {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scanner-device/scenes/turntable.toml"
    ))
    .unwrap()
    .replace("width = 1280", "width = 640")
    .replace("height = 960", "height = 480")
    .replace("paper = \"a4\"", "paper = \"a3\"")
    .replace("frames = 300", "frames = 240");
    std::fs::write(dir.join("job.toml"), text).unwrap();
}

#[test]
fn a_cable_fault_mid_sweep_loses_nothing_received_and_the_job_goes_on() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    scene(dir);
    // the head's end of the cable and the studio's
    let (head_far, head_end) = TTYPort::pair().unwrap();
    let (host_far, host_end) = TTYPort::pair().unwrap();
    let cable = Cable::join(head_far, host_far);
    let head_process = Killed(
        Command::new(workspace_bin("scanner-device"))
            .args([
                "serve", "--source", "rig", "--scene", "job.toml", "--work", "head",
            ])
            .arg("--out")
            .arg(format!("serial:{}", head_end.name().unwrap()))
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap(),
    );
    let head = format!("serial:{}", host_end.name().unwrap());
    let studio = scanner_tests::StudioProcess::start(
        dir,
        &[
            "--listen",
            "127.0.0.1:0",
            "--project",
            "project",
            "--head",
            &head,
        ],
    );
    let url = studio.url.clone();

    // the set-up check: the preview, its picture and verdict
    assert_eq!(
        command(&url, r#"{"command":"preview","on":true}"#)["outcome"],
        "accepted"
    );
    wait(&url, 60, "a good set-up", |s| {
        s["preview"]["verdict"] == "good" && s["sharpness"]["edge_px"].as_f64().is_some()
    });
    assert_eq!(
        command(&url, r#"{"command":"preview","on":false}"#)["outcome"],
        "accepted"
    );
    wait(&url, 60, "the preview stops", |s| {
        s["head"]["state"] == "idle"
    });

    // calibration
    for _ in 0..6 {
        assert_eq!(
            command(&url, r#"{"command":"shot"}"#)["outcome"],
            "accepted"
        );
        wait(&url, 60, "a shot", |s| s["head"]["state"] == "idle");
    }
    assert_eq!(
        command(&url, r#"{"command":"shot","board":true}"#)["outcome"],
        "accepted"
    );
    wait(&url, 60, "the board's shot", |s| {
        s["head"]["state"] == "idle"
    });
    // the head calibrates in its own process: no child of it runs while it calibrates
    let watch = ChildWatch::start(head_process.0.id());
    assert_eq!(
        command(&url, r#"{"command":"calibrate"}"#)["outcome"],
        "accepted"
    );
    wait(&url, 180, "the calibration", |s| {
        s["calibration"]["result"] == "calibrated"
    });
    assert_eq!(
        watch.seen(),
        Vec::<u32>::new(),
        "the head started processes"
    );
    let log = std::fs::read_to_string(dir.join("head/calibrate.log")).unwrap();
    assert!(log.lines().count() >= 3, "the calibration's lines: {log}");

    // view 1, with the cable failing in its middle
    assert_eq!(
        command(&url, r#"{"command":"sweep","disc":2}"#)["outcome"],
        "accepted"
    );
    wait(&url, 60, "points arrive", |s| {
        s["views"][0]["points"].as_u64().unwrap_or(0) > 500
    });
    let before = state(&url)["views"][0]["points"].as_u64().unwrap();
    let journal = dir.join("project/views/view-1.stream");
    let on_disk = std::fs::metadata(&journal).unwrap().len();
    cable.state.store(1, Ordering::SeqCst);
    // a command during the fault: sent again until the cable is back
    let asked = std::thread::spawn({
        let url = url.clone();
        move || command(&url, r#"{"command":"hello"}"#)
    });
    std::thread::sleep(Duration::from_millis(800));
    cable.state.store(2, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(400));
    cable.state.store(0, Ordering::SeqCst);
    assert_eq!(asked.join().unwrap()["outcome"], "accepted");
    assert!(
        cable.lost.load(Ordering::SeqCst) > 0,
        "the cable lost bytes"
    );
    // the view ends, by its last status or, when the fault took that, by the head's word
    // that it is idle
    wait(&url, 120, "view 1 ends", |s| s["views"][0]["done"] == true);
    let s = state(&url);
    let ended = s["views"][0]["ended"].as_str().unwrap_or("").to_string();
    assert!(ended == "completed" || ended == "end_lost", "{ended}");
    // what came before the fault is all still there, in the job and in the journal
    let after = s["views"][0]["points"].as_u64().unwrap();
    assert!(
        after >= before,
        "points after the fault: {before} → {after}"
    );
    assert!(std::fs::metadata(&journal).unwrap().len() >= on_disk);
    eprintln!(
        "view 1: {before} points before the fault, {after} at its end ({ended}); {} bytes lost on the cable",
        cable.lost.load(Ordering::SeqCst)
    );

    // the job goes on: two more views on the disc, one on the object's side (the scene's
    // views 0, 2, 4 and 6), the merge
    for _ in 0..3 {
        assert_eq!(
            command(&url, r#"{"command":"turn","steps":2}"#)["outcome"],
            "accepted"
        );
        let n = state(&url)["views"].as_array().unwrap().len();
        assert_eq!(
            command(&url, r#"{"command":"sweep","disc":2}"#)["outcome"],
            "accepted"
        );
        wait(&url, 120, "a view", |s| {
            s["views"].as_array().unwrap().len() == n + 1 && s["views"][n]["done"] == true
        });
    }
    let disc: Vec<String> = state(&url)["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["disc"].as_str().unwrap_or("").to_string())
        .collect();
    assert_eq!(disc[..3], ["found", "found", "found"], "{disc:?}");
    assert_ne!(disc[3], "found", "the side view is off the disc");
    // the default least overlap first; a side view that shares too little with the others is
    // left out (the page's views table), as the refusal advises, and the rest merged
    let merge = |overlap: &str| {
        let (status, _) = request(
            &url,
            "POST",
            "/api/merge",
            &format!(r#"{{"min_overlap":{overlap}}}"#),
        );
        assert_eq!(status, 202);
        wait(&url, 600, "the merge", |s| {
            s["merge"]["state"] != "running" && !s["merge"].is_null()
        });
        state(&url)["merge"]["state"] == "merged"
    };
    let mut merged_views = 4;
    if !merge("0.4") {
        // a refusal names the side view as the table numbers it (the merge counts from 0)
        let m = state(&url)["merge"].clone();
        eprintln!("the first merge: {}", m["refusal"]);
        if !m["refusal"].is_null() {
            assert_eq!(m["state"], "refused", "{m}");
            assert!(m["refusal"]["kind"].is_string(), "{m}");
            let views: Vec<u64> = m["refusal"]["views"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap())
                .collect();
            assert!(views.contains(&4), "{m}");
        }
        let (status, _) = request(&url, "POST", "/api/view", r#"{"view":4,"left_out":true}"#);
        assert_eq!(status, 200);
        merged_views = 3;
        assert!(
            merge("0.4"),
            "the disc views merge: {}",
            state(&url)["merge"]
        );
    }
    eprintln!("merged {merged_views} views");
    let s = state(&url);
    assert_eq!(s["merge"]["state"], "merged", "{}", s["merge"]);
    assert!(dir.join("project/model/model.3mf").exists());
    // the job on disk says the same, and a studio started again on the folder opens it
    let job = scanner_tests::json(&dir.join("project/job.json"));
    assert_eq!(job["views"].as_array().map(Vec::len), Some(4));
    drop(studio);
    let head = format!("serial:{}", host_end.name().unwrap());
    let again = scanner_tests::StudioProcess::start(
        dir,
        &[
            "--listen",
            "127.0.0.1:0",
            "--project",
            "project",
            "--head",
            &head,
        ],
    );
    let url = again.url.clone();
    let s = state(&url);
    assert_eq!(s["views"].as_array().map(Vec::len), Some(4));
    assert_eq!(s["merge"]["state"], "merged");
    assert_eq!(s["calibration"]["result"], "calibrated");
    let (status, _) = request(&url, "GET", "/files/model.3mf", "");
    assert_eq!(status, 200);
}

/// The studio's own child head over a pseudo-terminal (`--pty`), as over a cable: answered,
/// and its shots reach the job.
#[test]
fn a_child_head_over_a_pseudo_terminal_answers() {
    let tmp = tempfile::tempdir().unwrap();
    let studio = scanner_tests::StudioProcess::start(
        tmp.path(),
        &[
            "--listen",
            "127.0.0.1:0",
            "--project",
            "project",
            "--source",
            "rig",
            "--pty",
        ],
    );
    let url = studio.url.clone();
    assert_eq!(
        command(&url, r#"{"command":"hello"}"#)["outcome"],
        "accepted"
    );
    assert_eq!(
        command(&url, r#"{"command":"shot"}"#)["outcome"],
        "accepted"
    );
    wait(&url, 60, "the shot", |s| {
        s["shots"].as_array().is_some_and(|a| a.len() == 1)
    });
    // refused commands come back with their reason in words
    let r = command(&url, r#"{"command":"sweep"}"#);
    assert_eq!(r["outcome"], "not_calibrated");
    assert!(r["words"].as_str().is_some_and(|w| !w.is_empty()));
    let (status, r) = request(&url, "POST", "/api/command", r#"{"command":"fly"}"#);
    assert_eq!((status, r["outcome"].as_str()), (400, Some("bad_request")));
}

fn raw(url: &str, request: &str) -> u16 {
    let host = url
        .trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap()
        .to_string();
    let mut s = TcpStream::connect(&host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    s.write_all(request.replace("HOST", &host).as_bytes())
        .unwrap();
    let mut text = Vec::new();
    let _ = s.read_to_end(&mut text);
    String::from_utf8_lossy(&text)[9..12].parse().unwrap()
}

/// Commands from another site's page, path tricks, oversized bodies and, beyond loopback,
/// requests without the token are refused.
#[test]
fn cross_site_requests_path_tricks_and_requests_without_the_token_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let studio = scanner_tests::StudioProcess::start(
        tmp.path(),
        &[
            "--listen",
            "0.0.0.0:0",
            "--project",
            "project",
            "--source",
            "rig",
        ],
    );
    let url = studio.url.clone();
    let token = url.split("token=").nth(1).expect("a token beyond loopback");
    assert_eq!(token.len(), 32);
    let url = url.replace("<this-computer's-address>", "127.0.0.1");
    let get = |path: &str, with: bool| {
        let h = if with {
            format!("x-scanner-token: {token}\r\n")
        } else {
            String::new()
        };
        raw(
            &url,
            &format!("GET {path} HTTP/1.1\r\nHost: HOST\r\n{h}Connection: close\r\n\r\n"),
        )
    };
    assert_eq!(get("/api/state", false), 403, "no token");
    assert_eq!(get("/api/state", true), 200);
    assert_eq!(get(&format!("/api/state?token={token}"), false), 200);
    assert_eq!(get("/api/state?token=00", false), 403, "a wrong token");
    for trick in [
        "/files/../job.json",
        "/files/%2e%2e%2fjob.json",
        "/files/model.3mf/../../job.json",
        "/files//etc/passwd",
    ] {
        assert_eq!(get(trick, true), 404, "{trick}");
    }
    let post = |headers: &str, body: &str| {
        raw(
            &url,
            &format!(
                "POST /api/command HTTP/1.1\r\nHost: HOST\r\nx-scanner-token: {token}\r\n{headers}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
                body.len()
            ),
        )
    };
    let hello = r#"{"command":"hello"}"#;
    assert_eq!(post("Content-Type: application/json\r\n", hello), 200);
    assert_eq!(
        post("Content-Type: text/plain\r\n", hello),
        415,
        "a form's post"
    );
    assert_eq!(
        post(
            "Content-Type: application/json\r\nOrigin: http://evil.example\r\n",
            hello
        ),
        403,
        "another site's page"
    );
    let big = format!(r#"{{"command":"hello","pad":"{}"}}"#, "x".repeat(5000));
    assert_eq!(post("Content-Type: application/json\r\n", &big), 413);
    assert_eq!(post("Content-Type: application/json\r\n", "{not json"), 400);
}

/// The watch of the calibration test sees a child when there is one: a shell running `sleep`.
#[test]
fn the_child_watch_sees_a_child() {
    let shell = Killed(
        Command::new("sh")
            .args(["-c", "sleep 0.5; sleep 0.5"])
            .spawn()
            .unwrap(),
    );
    let watch = ChildWatch::start(shell.0.id());
    std::thread::sleep(Duration::from_millis(300));
    assert!(!watch.seen().is_empty());
}
