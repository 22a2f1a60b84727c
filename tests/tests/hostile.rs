//! Hostile input and misuse through the real binaries: each case ends in the stated exit code
//! and a message naming the input and what is wrong — never a panic (101), a hang or runaway
//! memory (every binary runs under a 3 GB address-space limit, `prlimit --as`), never a
//! "success" with a wrong result. Issue 15's list, case by case.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use scanner_core::geometry::{Board, Plane};
use scanner_core::nalgebra::Vector3;
use scanner_core::pipeline::HeadConfig;
use scanner_core::stripe::{Axis, Method, PixelFormat, StripeConfig};
use scanner_core::{Camera, Distortion};
use scanner_device::session::{ScanOptions, truth_calibration};
use scanner_device::source::{FrameSource, RigSource};
use scanner_rig::{Rig, Scene};
use scanner_tests::workspace_bin;
use scanner_wire::{Header, MAX_ENCODED, Message, PlaneMethod};

/// The address-space limit every binary runs under, bytes.
const LIMIT: &str = "3000000000";

/// Runs a workspace binary under the memory limit: (exit code, stdout, stderr).
fn run_in(dir: &Path, bin: &str, args: &[&str]) -> (i32, String, String) {
    let out = Command::new("prlimit")
        .arg(format!("--as={LIMIT}"))
        .arg("--")
        .arg(workspace_bin(bin))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("prlimit (util-linux) runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Expects exit code `code` and every one of `words` in stderr.
#[track_caller]
fn expect(dir: &Path, bin: &str, args: &[&str], code: i32, words: &[&str]) -> String {
    let (c, _, err) = run_in(dir, bin, args);
    assert_eq!(c, code, "{bin} {args:?}: exit {c}, stderr:\n{err}");
    // the message family of hostile input: each sentence names what was wrong and where
    for w in words {
        assert!(err.contains(w), "{bin} {args:?}: {w:?} not in:\n{err}");
    }
    err
}

fn dev(dir: &Path, args: &[&str], code: i32, words: &[&str]) -> String {
    expect(dir, "scanner-device", args, code, words)
}

fn host(dir: &Path, args: &[&str], code: i32, words: &[&str]) -> String {
    expect(dir, "scanner-host", args, code, words)
}

/// The default board file with `from` replaced by `to` (first occurrence).
fn board_file(dir: &Path, name: &str, from: &str, to: &str) -> PathBuf {
    let text = scanner_calib::board::BoardFile::default()
        .to_toml()
        .unwrap();
    assert!(text.contains(from), "{text}");
    let p = dir.join(name);
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    p
}

/// A PNG file of a header chunk and empty data, claiming `w`×`h` pixels: a decoder reads the
/// size, and decoding would allocate for all of them.
fn png_header(path: &Path, w: u32, h: u32) {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    let mut chunk = b"IHDR".to_vec();
    chunk.extend(w.to_be_bytes());
    chunk.extend(h.to_be_bytes());
    chunk.extend([8, 2, 0, 0, 0]);
    let mut f = b"\x89PNG\r\n\x1a\n".to_vec();
    for (len, chunk) in [(13u32, chunk), (0, b"IDAT".to_vec()), (0, b"IEND".to_vec())] {
        f.extend(len.to_be_bytes());
        f.extend(&chunk);
        f.extend(crc32(&chunk).to_be_bytes());
    }
    std::fs::write(path, f).unwrap();
}

/// Records a short rig scan at `w`×`h` (scan id `id`) into a stream file.
fn record(w: u32, h: u32, id: u32, path: &Path) {
    let mut scene = Scene::demo(w, h);
    scene.laser.frames = 12;
    let rig = Rig::new(scene).unwrap();
    let cal = truth_calibration(&rig);
    let mut source = RigSource::new(rig, PixelFormat::Gray8);
    let opts = ScanOptions {
        head: HeadConfig::new(StripeConfig::new(Method::Dim, Axis::Columns)),
        header_every: 30,
        status_every: 30,
        scan_id: id,
        find_axis: false,
        find_colour: false,
        disc: None,
        fixed: None,
        markers: None,
        shadow: false,
        temporal: false,
    };
    scanner_tests::record_scan(
        &mut source,
        &cal,
        opts,
        Box::new(std::fs::File::create(path).unwrap()),
    );
}

/// One encoded header frame, changed by `edit`.
fn header_frame(width: u16, height: u16, edit: impl FnOnce(&mut Header)) -> Vec<u8> {
    let camera = Camera::new(500.0f64, 500.0, 320.0, 240.0, Distortion::none()).unwrap();
    let plane = |x: f64| Plane::new(Vector3::new(x, 0.0, -1.0).normalize(), 800.0).unwrap();
    let board = Board::new(plane(0.7), plane(-0.7)).unwrap();
    let mut h = Header::new(
        9,
        (width, height),
        (&camera).into(),
        (&board).into(),
        false,
        PlaneMethod::LeastSquares,
    );
    edit(&mut h);
    let (mut scratch, mut out) = (vec![0; scanner_wire::MAX_MESSAGE], vec![0; MAX_ENCODED]);
    let n = scanner_wire::encode(&Message::Header(h), &mut scratch, &mut out).unwrap();
    out.truncate(n);
    out
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn board_files_and_options_that_would_panic_or_allocate_without_bound() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let huge = board_file(d, "cols.toml", "cols = 3", "cols = 18446744073709551615");
    dev(
        d,
        &["board", "--board", s(&huge), "--out", "x1"],
        1,
        &["at most 256 per sheet"],
    );
    dev(
        d,
        &[
            "calibrate",
            "board",
            "--board",
            s(&huge),
            "--camera",
            "cam.toml",
            "--out",
            "c.toml",
            "none.png",
        ],
        1,
        &["at most 256 per sheet"],
    );
    let big = board_file(d, "sheet.toml", "width = 420.0", "width = 1e9");
    dev(
        d,
        &["board", "--board", s(&big), "--out", "x2"],
        1,
        &["[sheet]", "between 0 and 10000 mm", "1.0000e9"],
    );
    assert!(
        !d.join("x2").exists(),
        "nothing is written for a refused board"
    );
    let grid = board_file(d, "grid.toml", "rows = 2", "rows = 10000");
    dev(
        d,
        &["board", "--board", s(&grid), "--out", "x3"],
        1,
        &["30000 markers"],
    );
    dev(
        d,
        &["board", "--out", "x4", "--dpi", "1200"],
        1,
        &["choose a lower --dpi"],
    );
    assert!(
        !d.join("x4").exists(),
        "the sizes are checked before anything is written"
    );
    dev(
        d,
        &[
            "calibrate",
            "intrinsics",
            "--dots",
            "18446744073709551615x2",
            "a.png",
        ],
        2,
        &["COLSxROWS"],
    );
    dev(
        d,
        &[
            "calibrate",
            "intrinsics",
            "--dots",
            "1000000x1000000",
            "a.png",
        ],
        2,
        &["at most 256"],
    );
    dev(
        d,
        &["scan", "--source", "rig", "--link-depth", "100000000"],
        2,
        &["1 to 64"],
    );
}

#[test]
fn scenes_and_images_beyond_the_limits() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    std::fs::write(d.join("zero.toml"), "width = 0\n").unwrap();
    std::fs::write(d.join("huge.toml"), "width = 8192\nheight = 8192\n").unwrap();
    for scene in ["zero.toml", "huge.toml"] {
        dev(
            d,
            &["render", "--scene", scene, "--out", "r"],
            1,
            &[scene, "image size"],
        );
        dev(
            d,
            &["render-calibration", "--scene", scene, "--out", "r"],
            1,
            &["image size"],
        );
    }
    dev(
        d,
        &["scan", "--source", "rig:0x0", "--calibration", "c.toml"],
        1,
        &["rig:0x0"],
    );
    dev(
        d,
        &[
            "scan",
            "--source",
            "rig:8192x8192",
            "--calibration",
            "c.toml",
        ],
        1,
        &["at most 8294400 pixels"],
    );
    png_header(&d.join("huge.png"), 20000, 20000);
    for args in [
        vec![
            "calibrate",
            "intrinsics",
            "--out",
            "cam.toml",
            "huge.png",
            "huge.png",
            "huge.png",
        ],
        vec![
            "calibrate",
            "distance",
            "--near",
            "huge.png",
            "--near-mm",
            "400",
            "--far",
            "huge.png",
            "--far-mm",
            "800",
            "--out",
            "cam.toml",
        ],
    ] {
        dev(
            d,
            &args,
            1,
            &["huge.png is 20000×20000 pixels", "1 to 4096"],
        );
    }
    std::fs::create_dir(d.join("folder.png")).unwrap();
    dev(
        d,
        &["calibrate", "intrinsics", "--out", "cam.toml", "folder.png"],
        1,
        &["folder.png is a folder"],
    );
}

#[test]
fn a_closed_stdout_is_not_an_error_and_the_work_is_done() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    record(160, 120, 1, &d.join("scan.stream"));
    let closed = |bin: &str, args: &[&str]| {
        let mut child = Command::new(workspace_bin(bin))
            .args(args)
            .current_dir(d)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader goes away at once, like `| true`
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        // a panic would end it with 101: a closed stdout is no failure
        assert!(
            out.status.success(),
            "{bin} {args:?} with stdout closed:\n{err}"
        );
    };
    closed(
        "scanner-host",
        &["replay", "scan.stream", "--out", "o", "-q"],
    );
    assert!(d.join("o/scan.obj").exists());
    closed("scanner-host", &["ports"]);
    closed("scanner-device", &["board", "--out", "b"]);
    assert!(d.join("b/left-sheet.png").exists());
    closed("scanner-device", &["--info"]);
}

#[test]
fn the_host_refuses_its_own_journal_a_second_session_and_crafted_headers() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    record(160, 120, 1, &d.join("a.stream"));
    host(d, &["receive", "a.stream", "--out", "o", "-q"], 0, &[]);
    host(
        d,
        &["receive", "o/journal.stream", "--out", "o", "-q"],
        1,
        &["own journal"],
    );
    let journal = std::fs::metadata(d.join("o/journal.stream")).unwrap().len();
    host(
        d,
        &["receive", "a.stream", "--out", "o", "-q"],
        1,
        &["already holds", "--append"],
    );
    assert_eq!(
        std::fs::metadata(d.join("o/journal.stream")).unwrap().len(),
        journal
    );
    host(
        d,
        &["receive", "a.stream", "--out", "o", "-q", "--append"],
        0,
        &[],
    );
    host(
        d,
        &["receive", ".", "--out", "p", "-q"],
        1,
        &["is a folder"],
    );
    host(
        d,
        &["receive", "serial:/dev/ttyS0@0", "--out", "p", "-q"],
        2,
        &["baud"],
    );

    // Crafted headers: sizes beyond the head's, a zero unit, an absurd lens.
    let cases: [(&str, Vec<u8>, &[&str]); 4] = [
        (
            "big",
            header_frame(16384, 16384, |_| {}),
            &["16384×16384", "1 to 4096"],
        ),
        ("zero", header_frame(0, 0, |_| {}), &["image size"]),
        (
            "unit",
            header_frame(640, 480, |h| h.unit_um = 0),
            &["unit is 0"],
        ),
        (
            "lens",
            header_frame(640, 480, |h| h.camera.k1 = 1e30),
            &["radial distortion"],
        ),
    ];
    for (name, frame, words) in cases {
        let f = d.join(format!("{name}.stream"));
        std::fs::write(&f, &frame).unwrap();
        let mut w = vec!["header of scan 00000009"];
        w.extend_from_slice(words);
        host(d, &["replay", s(&f), "--out", name], 1, &w);
    }
    for (cell, words) in [
        ("0.05px", &["choose a larger cell size"][..]),
        ("1e9px", &["at least 2×2", "choose a smaller cell size"][..]),
    ] {
        host(
            d,
            &["replay", "a.stream", "--out", "q", "--cell", cell],
            1,
            words,
        );
    }
}

#[test]
fn mixed_cut_and_failed_streams_say_so() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    record(160, 120, 1, &d.join("a.stream"));
    record(200, 150, 2, &d.join("b.stream"));
    let (a, b) = (
        std::fs::read(d.join("a.stream")).unwrap(),
        std::fs::read(d.join("b.stream")).unwrap(),
    );
    std::fs::write(d.join("ab.stream"), [a.clone(), b].concat()).unwrap();
    let (code, out, err) = run_in(d, "scanner-host", &["replay", "ab.stream", "--out", "ab"]);
    assert_eq!(code, 0, "{err}");
    let ab = scanner_tests::summary(&d.join("ab"));
    assert_eq!(ab["other_camera_scans"], serde_json::json!([2]), "{out}");
    // A stream cut in the middle of its last frame.
    std::fs::write(d.join("cut.stream"), &a[..a.len() - 5]).unwrap();
    let (code, out, err) = run_in(d, "scanner-host", &["replay", "cut.stream", "--out", "c"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        scanner_tests::summary(&d.join("c"))["link"]["truncated"],
        1,
        "{out}"
    );
    // A failed replay into a folder with an earlier run's outputs leaves no stale mesh.
    host(d, &["replay", "a.stream", "--out", "f", "-q"], 0, &[]);
    assert!(d.join("f/scan.obj").exists());
    std::fs::write(d.join("junk.stream"), b"not a scanner stream at all\0").unwrap();
    host(
        d,
        &["replay", "junk.stream", "--out", "f"],
        1,
        &["no session header"],
    );
    assert!(
        !d.join("f/scan.obj").exists(),
        "an earlier mesh beside the error"
    );
}

#[test]
fn calibration_files_with_absurd_values_are_refused_by_name() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let rig = Rig::new(Scene::demo(160, 120)).unwrap();
    let good = rig.truth_calibration();
    good.save(&d.join("good.toml")).unwrap();
    let text = std::fs::read_to_string(d.join("good.toml")).unwrap();
    let edit = |name: &str, key: &str, value: &str| {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("{key} = ")))
            .unwrap_or_else(|| panic!("{key} in {text}"));
        std::fs::write(
            d.join(name),
            text.replacen(line, &format!("{key} = {value}"), 1),
        )
        .unwrap();
    };
    edit("fx.toml", "fx", "1e308");
    edit("k1.toml", "k1", "1e30");
    edit("offset.toml", "offset", "1e300");
    for (file, words) in [
        (
            "fx.toml",
            &["fx.toml", "[camera]", "focal length", "1.0000e308"][..],
        ),
        (
            "k1.toml",
            &["k1.toml", "radial distortion", "1.0000e30"][..],
        ),
        ("offset.toml", &["offset.toml", "offset 1.0000e300 mm"][..]),
    ] {
        let err = dev(
            d,
            &[
                "scan",
                "--source",
                "rig:160x120",
                "--calibration",
                file,
                "--out",
                "x.stream",
            ],
            1,
            words,
        );
        assert!(
            !err.contains("board file"),
            "blamed on the board file: {err}"
        );
    }
}

#[test]
fn scans_that_give_nothing_or_share_stdout_say_so_plainly() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let rig = Rig::new(Scene::demo(160, 120)).unwrap();
    rig.truth_calibration().save(&d.join("cal.toml")).unwrap();
    // A folder of laser frames without reference.png: the laser was on for the reference.
    let sweep = d.join("sweep");
    std::fs::create_dir(&sweep).unwrap();
    let mut source = RigSource::new(rig.clone(), PixelFormat::Rgb24);
    let frames: Vec<_> = (0..48)
        .filter_map(|_| source.next_frame().unwrap())
        .collect();
    for (i, f) in frames.iter().skip(30).take(10).enumerate() {
        image::RgbImage::from_raw(160, 120, f.data.clone())
            .unwrap()
            .save(sweep.join(format!("f{i:02}.png")))
            .unwrap();
    }
    dev(
        d,
        &[
            "scan",
            "--source",
            "dir:sweep",
            "--calibration",
            "cal.toml",
            "--out",
            "x.stream",
        ],
        1,
        &["laser was on while the laser-off reference was taken"],
    );
    // One laser-off frame and its reference: one frame, no points, said plainly.
    let one = d.join("one");
    std::fs::create_dir(&one).unwrap();
    let reference = source.reference().unwrap();
    for name in ["reference.png", "frame.png"] {
        image::RgbImage::from_raw(160, 120, reference.data.clone())
            .unwrap()
            .save(one.join(name))
            .unwrap();
    }
    // Without a stripe the first frame cannot tell its direction: the error names the flags.
    let (code, _, err) = run_in(
        d,
        "scanner-device",
        &[
            "scan",
            "--source",
            "dir:one",
            "--calibration",
            "cal.toml",
            "--out",
            "x.stream",
        ],
    );
    assert!(
        code == 1 && err.contains("--columns") && err.contains("--rows"),
        "{err}"
    );
    let (code, out, err) = run_in(
        d,
        "scanner-device",
        &[
            "scan",
            "--columns",
            "--source",
            "dir:one",
            "--calibration",
            "cal.toml",
            "--out",
            "y.stream",
            "--report",
            "y.json",
        ],
    );
    assert_eq!(code, 0, "{err}\n{out}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("y.json")).unwrap()).unwrap();
    assert_eq!(
        (&r["frames"], &r["packets"], &r["points"]),
        (
            &serde_json::json!(1),
            &serde_json::json!(0),
            &serde_json::json!(0)
        ),
        "{r}"
    );
    // no point sent: no bytes per point to tell
    assert!(r["bytes_per_point"].is_null(), "{r}");
    // `--out -`: stdout carries the stream alone, the summary goes to stderr.
    let out = Command::new(workspace_bin("scanner-device"))
        .args([
            "scan",
            "--source",
            "rig:160x120",
            "--calibration",
            "cal.toml",
            "--out",
            "-",
            "-q",
        ])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("point packets"), "{err}");
    let mut dec = Box::new(scanner_wire::Decoder::<MAX_ENCODED>::new());
    let mut frames = 0;
    dec.feed(&out.stdout, |m| {
        assert!(m.is_ok(), "a frame of stdout did not decode: {:?}", m.err());
        frames += 1;
    });
    assert!(
        frames > 2 && dec.pending() == 0,
        "{frames} frames, {} bytes left",
        dec.pending()
    );
    let _ = std::io::stderr().flush();
}

#[test]
fn a_board_calibration_from_a_dot_grid_image_is_refused() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    dev(d, &["render-calibration", "--out", "shots"], 0, &[]);
    for grid in ["grid-00.png", "grid-03.png", "grid-07.png"] {
        let err = dev(
            d,
            &[
                "calibrate",
                "board",
                "--camera",
                "shots/truth-calibration.toml",
                "--out",
                "cal.toml",
                "--overlay",
                "o.png",
                &format!("shots/{grid}"),
            ],
            1,
            &[grid],
        );
        // Sheets that cannot be a two-plane board, or markers off any board layout; said once.
        assert!(
            err.contains("implausible result") || err.contains("do not meet"),
            "{grid}: {err}"
        );
        assert!(err.matches("do not meet").count() <= 1, "repeated: {err}");
        assert!(
            !d.join("cal.toml").exists(),
            "{grid}: a calibration file was written"
        );
    }
    dev(
        d,
        &[
            "calibrate",
            "board",
            "--camera",
            "shots/truth-calibration.toml",
            "--out",
            "cal.toml",
            "--overlay",
            "o.png",
            "shots/board.png",
        ],
        0,
        &[],
    );
    // One view three times: nothing constrains the focal length.
    for copy in ["a.png", "b.png", "c.png"] {
        std::fs::copy(d.join("shots/grid-02.png"), d.join(copy)).unwrap();
    }
    dev(
        d,
        &[
            "calibrate",
            "intrinsics",
            "--out",
            "cam.toml",
            "a.png",
            "b.png",
            "c.png",
        ],
        1,
        &["1 of 3 images usable"],
    );
    let (_, out, _) = run_in(
        d,
        "scanner-device",
        &[
            "calibrate",
            "intrinsics",
            "--out",
            "cam.toml",
            "a.png",
            "b.png",
            "c.png",
        ],
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("cam-report.json")).unwrap()).unwrap();
    let b = &r["images"][1];
    assert!(
        b["path"] == "b.png"
            && b["refused"]["reason"] == "same_view"
            && b["refused"]["same_as"] == "a.png",
        "{r}\n{out}"
    );
    assert!(r["camera"].is_null() && r["error"].is_string(), "{r}");
    assert!(!d.join("cam.toml").exists());
}
