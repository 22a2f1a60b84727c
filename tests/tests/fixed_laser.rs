//! A fixed laser over a turning platform, on FabScanPi's real recording of a real bust
//! (`../shared/data/real-fabscan`, GPL-2.0: read from the shared folder, never copied here),
//! through the binaries as an owner of that scanner would run them: its config imported, the
//! frames of `1_1` scanned with laser 0 at 100 frames a turn, the stream received into one
//! closed model. And the imports and options a scan must refuse.

use std::path::{Path, PathBuf};

use scanner_tests::{json, run_in, workspace_bin};

/// The shared FabScanPi recording; a missing folder fails the test (no silent skip).
fn fabscan() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/real-fabscan");
    assert!(
        dir.join("dummy.config.json").is_file(),
        "the shared FabScanPi recording is missing at {}",
        dir.display()
    );
    dir
}

/// The vertices of a PLY the host wrote.
fn ply_vertices(path: &Path) -> Vec<[f32; 3]> {
    scanner_tests::read_ply(&std::fs::read(path).unwrap()).0
}

/// What the fixture made once: the imported and the own calibration, and the scans of both
/// recordings with the own one (`1_1` with laser 0, `1_2` with laser 1) and of `1_1` with the
/// imported one.
struct Fixture {
    dir: tempfile::TempDir,
}

impl Fixture {
    fn path(&self, p: &str) -> PathBuf {
        self.dir.path().join(p)
    }
}

fn fixture() -> &'static Fixture {
    static F: std::sync::OnceLock<Fixture> = std::sync::OnceLock::new();
    F.get_or_init(|| {
        let data = fabscan();
        let dir = tempfile::tempdir().unwrap();
        let device = workspace_bin("scanner-device");
        let config = data.join("dummy.config.json");
        let (ok, _, err) = run_in(
            &device,
            dir.path(),
            &[
                "import-fabscan",
                config.to_str().unwrap(),
                "--out",
                "imported.toml",
            ],
        );
        assert!(ok, "{err}");
        let mut args = vec![
            "calibrate",
            "fixed",
            "--chessboard-corners",
            "10x8",
            "--square",
            "7",
            "--origin-distance",
            "12",
            "--steps-per-turn",
            "6400",
            "--radius",
            "70",
            "--clockwise",
            "--out",
            "own.toml",
        ];
        let mut frames: Vec<PathBuf> = std::fs::read_dir(data.join("calibration_8x10"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        frames.sort();
        let names: Vec<String> = frames.iter().map(|p| p.display().to_string()).collect();
        args.extend(names.iter().map(String::as_str));
        let (ok, out, err) = run_in(&device, dir.path(), &args);
        assert!(ok, "{err}");
        eprintln!("{out}");
        for (cal, laser, rec, name) in [
            ("imported.toml", "0", "1_1", "imported0"),
            ("own.toml", "0", "1_1", "own0"),
            ("own.toml", "1", "1_2", "own1"),
        ] {
            scan(dir.path(), cal, laser, &data.join(rec), name);
        }
        Fixture { dir }
    })
}

/// Scans a recording with laser `laser` of calibration `cal` into the folder `name`.
fn scan(dir: &Path, cal: &str, laser: &str, frames: &Path, name: &str) {
    let (device, host) = (
        workspace_bin("scanner-device"),
        workspace_bin("scanner-host"),
    );
    let stream = format!("{name}.stream");
    let (ok, _, err) = run_in(
        &device,
        dir,
        &[
            "scan",
            "--source",
            frames.to_str().unwrap(),
            "--calibration",
            cal,
            "--fixed-laser",
            laser,
            "--frames-per-turn",
            "100",
            "--columns",
            "--out",
            &stream,
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run_in(&host, dir, &["receive", &stream, "--out", name]);
    assert!(ok, "{err}");
}

/// Checks one model of the bust: every frame used, a whole turn, closed, the background left
/// out, the bust's size, and nothing of the platform's surface.
fn check_model(dir: &Path) {
    let summary = json(&dir.join("summary.json"));
    let fixed = &summary["fixed"];
    eprintln!("{}: {fixed}", dir.display());
    assert_eq!(fixed["frames"], 101, "every frame gave points");
    let turned = fixed["turned_deg"].as_f64().unwrap();
    assert!((turned - 360.0).abs() < 0.01, "{turned}");
    assert_eq!(fixed["watertight"], true);
    let object = fixed["object_points"].as_u64().unwrap();
    assert!(object > 40_000, "{object} object points");
    // the laser on what did not stand on the platform (the scanner's case) is left out, and
    // is not most of what was lit
    let off = fixed["off_model"].as_u64().unwrap() + fixed["off_platform"].as_u64().unwrap();
    assert!(
        off > 1_000 && off < object,
        "{off} off the model of {object}"
    );
    // the platform's surface as the points show it: within 3 mm of the calibrated top, level
    // with it within a degree
    let (floor, tilt) = (
        fixed["floor_mm"].as_f64().unwrap(),
        fixed["floor_tilt_deg"].as_f64().unwrap(),
    );
    assert!(floor.abs() < 3.0 && tilt < 1.0, "floor {floor} mm, {tilt}°");
    let cloud = ply_vertices(&dir.join("cloud.ply"));
    assert_eq!(cloud.len() as u64, object);
    // the bust: 76 mm tall (FabScanPi's own model of it is)
    let mut heights: Vec<f32> = cloud.iter().map(|v| v[1]).collect();
    heights.sort_by(f32::total_cmp);
    let tall = heights[heights.len() * 995 / 1000];
    assert!((70.0..90.0).contains(&tall), "{tall} mm tall");
    // no point of the platform's surface: nothing in the cloud under 1 mm above it, and the
    // model's base is its flat cut, not the turntable's disc around the bust (35 mm from the
    // axis at most: the bust's foot)
    let top = floor + 1.0;
    assert!(cloud.iter().all(|v| f64::from(v[1]) >= top - 1.0));
    let model = ply_vertices(&dir.join("scan.ply"));
    let lowest = model.iter().map(|v| v[1]).fold(f32::MAX, f32::min);
    let reach = model
        .iter()
        .filter(|v| v[1] < lowest + 1.0)
        .map(|v| v[0].hypot(v[2]))
        .fold(0.0f32, f32::max);
    assert!(
        reach < 35.0,
        "the base reaches {reach} mm from the axis: the platform's top"
    );
}

#[test]
fn the_real_bust_becomes_one_closed_model_without_the_platform() {
    let f = fixture();
    for name in ["imported0", "own0", "own1"] {
        check_model(&f.path(name));
    }
}

#[test]
fn the_own_calibration_from_the_raw_frames_is_close_to_fabscans() {
    let f = fixture();
    let report = json(&f.path("own-report.json"));
    eprintln!("{report:#}");
    let imported = scanner_calib::file::CalibrationFile::load(&f.path("imported.toml")).unwrap();
    let own = scanner_calib::file::CalibrationFile::load(&f.path("own.toml")).unwrap();
    // the focal lengths within 1 % of its stored camera matrix
    for (a, b, name) in [
        (own.camera.fx, imported.camera.fx, "fx"),
        (own.camera.fy, imported.camera.fy, "fy"),
    ] {
        let off = (a / b - 1.0).abs();
        eprintln!("{name}: own {a:.2}, FabScanPi {b:.2}: {:.3} %", 100.0 * off);
        assert!(off < 0.01, "{name} {a} against {b}");
    }
    // most of the 100 lit shots (two show the pattern too steeply)
    assert!(
        report["camera"]["shots"].as_u64().unwrap() >= 60,
        "{report}"
    );
    // laser 0 against FabScanPi's plane: the angle between them and their distance at the
    // platform's origin (FabScanPi finds the stripe without the lens's distortion)
    let (ours, theirs) = (
        own.lasers[0].plane().unwrap().facing_camera(),
        imported.lasers[0].plane().unwrap().facing_camera(),
    );
    let angle = ours
        .normal()
        .dot(theirs.normal())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let origin = scanner_core::nalgebra::Point3::from(imported.platform.unwrap().origin);
    let apart = (ours.signed_distance(&origin) - theirs.signed_distance(&origin)).abs();
    eprintln!(
        "laser 0: {angle:.3}° and {apart:.3} mm from FabScanPi's plane at the platform's origin"
    );
    assert!(angle < 2.0 && apart < 3.0, "{angle}° {apart} mm");
    // the second laser, which FabScanPi's config has no plane for, is found too
    assert_eq!(own.lasers.len(), 2);
    // the platform: the pattern's centre on one circle, the axis near FabScanPi's
    let circle = report["platform"]["circle_rms_mm"].as_f64().unwrap();
    assert!(circle < 0.2, "{circle} mm");
    let (a, b) = (
        own.platform.unwrap().platform().unwrap(),
        imported.platform.unwrap().platform().unwrap(),
    );
    let tilt = a.axis().dot(&b.axis()).clamp(-1.0, 1.0).acos().to_degrees();
    let moved = (a.origin() - b.origin()).norm();
    eprintln!("platform: axis {tilt:.3}° and origin {moved:.2} mm from FabScanPi's");
    assert!(tilt < 2.0 && moved < 3.0, "{tilt}° {moved} mm");
}

/// Model `a`'s vertices' distances to model `b`'s surface (the nearest vertex's tangent plane),
/// after `a` is moved onto `b` by ICP (two recordings: the bust stood otherwise on the
/// platform): the median and the 90th percentile, mm.
fn apart(a: &Path, b: &Path) -> (f64, f64) {
    use scanner_core::nalgebra::{Isometry3, Point3};
    use scanner_merge::spatial::{Cloud, normals, tree};
    let cloud = |p: &Path| {
        let points: Vec<Point3<f64>> = ply_vertices(p)
            .iter()
            .map(|v| Point3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
            .collect();
        let normals = normals(&points, 12);
        Cloud { points, normals }
    };
    let (ca, cb) = (cloud(a), cloud(b));
    let mut pose = Isometry3::identity();
    for max in [10.0, 5.0, 2.0] {
        pose = scanner_merge::pose::icp(&ca, &cb, pose, max, 40).pose;
    }
    let t = tree(&cb.points);
    let mut d: Vec<f64> = ca
        .points
        .iter()
        .map(|p| {
            let q = pose * p;
            let n = t.nearest_one::<kiddo::SquaredEuclidean>(&[q.x, q.y, q.z]);
            let i = n.item as usize;
            (q - cb.points[i]).dot(&cb.normals[i]).abs()
        })
        .collect();
    d.sort_by(f64::total_cmp);
    (d[d.len() / 2], d[d.len() * 9 / 10])
}

#[test]
fn the_two_lasers_models_of_the_bust_are_compared() {
    let f = fixture();
    let (median, p90) = apart(&f.path("own0/scan.ply"), &f.path("own1/scan.ply"));
    eprintln!("laser 0's model to laser 1's: median {median:.3} mm, p90 {p90:.3} mm");
    // measured 1.7–2.3 mm: far from the 0.1 mm aimed at (docs/turntable-scanners.md says why)
    assert!(median < 3.0, "{median}");
    let (median, p90) = apart(&f.path("imported0/scan.ply"), &f.path("own0/scan.ply"));
    eprintln!(
        "laser 0 with FabScanPi's calibration to laser 0 with ours: median {median:.3} mm, p90 {p90:.3} mm"
    );
    assert!(median < 2.0, "{median}");
}

/// The host holds laser 1's model against laser 0's (`--other-laser`): the agreement in
/// summary.json, and a disagreement refused unless accepted. On the shared 1_1/1_2 the two
/// disagree (the docs' 1.5–2.4 mm): the refusal and its cause are what the data give.
#[test]
fn the_host_says_whether_the_two_lasers_agree_and_refuses_them_when_not() {
    let f = fixture();
    let host = workspace_bin("scanner-host");
    let receive = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "receive",
            "own1.stream",
            "--out",
            out,
            "--other-laser",
            "own0",
            "-q",
        ];
        args.extend_from_slice(extra);
        run_in(&host, f.dir.path(), &args)
    };
    let (ok, _, err) = receive("own1-vs-0", &[]);
    let a = &json(&f.path("own1-vs-0/summary.json"))["lasers"];
    eprintln!("laser 1 against laser 0: {a}");
    assert_eq!(a["lasers"], serde_json::json!([1, 0]));
    let median = a["median_mm"].as_f64().unwrap();
    let volume = a["volume_ratio"].as_f64().unwrap();
    // the same figure as the test's own comparison, within its sampling
    let (own, _) = apart(&f.path("own1/scan.ply"), &f.path("own0/scan.ply"));
    assert!(
        (median - own).abs() < 0.25 * own.max(0.1),
        "{median} vs {own}"
    );
    let agree = median <= 0.3 && (volume - 1.0).abs() <= 0.02;
    assert_eq!(a["agree"].as_bool(), Some(agree), "{a}");
    if agree {
        assert!(ok, "{err}");
    } else {
        assert!(!ok, "a disagreement must not pass silently");
        assert!(
            scanner_tests::error_kinds(&err)
                .iter()
                .any(|k| k.contains("Disagree")),
            "{err}"
        );
        assert!(a["likely_cause"].is_string(), "{a}");
        assert_eq!(a["accepted"], false);
        // every output is written all the same
        assert!(f.path("own1-vs-0/scan.obj").exists());
        let (ok, _, err) = receive("own1-accepted", &["--accept-disagreement"]);
        assert!(ok, "{err}");
        let a = &json(&f.path("own1-accepted/summary.json"))["lasers"];
        assert_eq!(
            (&a["agree"], &a["accepted"]),
            (&serde_json::json!(false), &serde_json::json!(true))
        );
    }
    // a distance that is none, and a folder that holds no turntable scan: refused by name
    for within in ["NaN", "0"] {
        let (ok, _, err) = receive("own1-bad", &["--agree-within", within]);
        assert!(!ok);
        assert!(
            scanner_tests::error_kinds(&err)
                .iter()
                .any(|k| k.contains("Within")),
            "{within}: {err}"
        );
    }
    std::fs::create_dir_all(f.path("empty")).unwrap();
    let (ok, _, err) = run_in(
        &host,
        f.dir.path(),
        &[
            "receive",
            "own1.stream",
            "--out",
            "own1-vs-empty",
            "--other-laser",
            "empty",
            "-q",
        ],
    );
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k.contains("Model") || k.contains("Summary")),
        "{err}"
    );
}

/// A FabScanPi config with one value replaced.
fn config_with(dir: &Path, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(fabscan().join("dummy.config.json")).unwrap();
    assert!(text.contains(from), "{from}");
    let path = dir.join("bad.config.json");
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path
}

#[test]
fn bad_configs_and_options_get_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let device = workspace_bin("scanner-device");
    let import = |path: &Path| {
        run_in(
            &device,
            dir.path(),
            &[
                "import-fabscan",
                path.to_str().unwrap(),
                "--out",
                "cal.toml",
            ],
        )
    };
    // a NaN in the plane (Python writes NaN, which JSON has not)
    let nan = config_with(
        dir.path(),
        "\"distance\": 77.47936416348523",
        "\"distance\": NaN",
    );
    let (ok, _, err) = import(&nan);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err).iter().any(|k| k == "Json"),
        "{err}"
    );
    // a laser plane through the camera
    let through = config_with(
        dir.path(),
        "\"distance\": 77.47936416348523",
        "\"distance\": 0.0",
    );
    let (ok, _, err) = import(&through);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "ThroughCamera"),
        "{err}"
    );
    // no steps per turn
    let steps = config_with(dir.path(), "\"steps\": 6400", "\"steps\": 0");
    let (ok, _, err) = import(&steps);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "Steps"),
        "{err}"
    );
    // a good import, then scans without a turn, with a laser it does not have, with 0 steps
    let (ok, _, err) = import(&fabscan().join("dummy.config.json"));
    assert!(ok, "{err}");
    let frames = fabscan().join("1_1");
    let scan = |extra: &[&str]| {
        let mut args = vec![
            "scan",
            "--source",
            frames.to_str().unwrap(),
            "--calibration",
            "cal.toml",
            "--out",
            "x.stream",
            "-q",
        ];
        args.extend_from_slice(extra);
        run_in(&device, dir.path(), &args)
    };
    let (ok, _, err) = scan(&["--fixed-laser", "0"]);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "NoTurn"),
        "{err}"
    );
    let (ok, _, err) = scan(&["--fixed-laser", "1", "--frames-per-turn", "100"]);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "NoSuchLaser"),
        "{err}"
    );
    // 101 frames of a recording at 3.6° a frame said to be at 7.2°: more than one turn
    let (ok, _, err) = scan(&["--fixed-laser", "0", "--steps-per-frame", "128"]);
    assert!(!ok);
    // the message family of a turntable's turn: the sentence names the frames and the turn
    assert!(
        err.contains("holds 101 frames") && err.contains("50 frames make a turn"),
        "{err}"
    );
    let (ok, _, err) = scan(&["--fixed-laser", "0", "--steps-per-frame", "0"]);
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "NoSteps"),
        "{err}"
    );
}

/// What the simulated FabScanPi firmware was told, and how it is to fail.
#[derive(Debug, Default, Clone)]
struct Told {
    /// Every command line, in order.
    commands: Vec<String>,
}

/// FabScanPi's firmware on the far end of a pseudo-terminal, as its source does it: every
/// character echoed, a command run at the line's end, then `>`; `M200` answers its version.
/// Stops answering after `silent_after` turns when given. Returns the port's device path and
/// the thread, which ends when the port closes or falls silent, with what it was told.
fn simulated_fabscan(
    silent_after: Option<usize>,
) -> (String, serialport::TTYPort, std::thread::JoinHandle<Told>) {
    use serialport::SerialPort;
    use std::io::{Read, Write};
    let (mut ours, theirs) = serialport::TTYPort::pair().expect("a pseudo-terminal pair");
    let path = theirs.name().expect("the pseudo-terminal's device path");
    ours.set_timeout(std::time::Duration::from_millis(200))
        .unwrap();
    let thread = std::thread::spawn(move || {
        let mut told = Told::default();
        let (mut line, mut idle) = (Vec::new(), 0);
        let mut turns = 0;
        let mut buf = [0u8; 256];
        loop {
            let n = match ours.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {
                    idle += 1;
                    // the scan ends or fails: nothing more comes
                    if idle > 50 {
                        break;
                    }
                    continue;
                }
                Err(_) => break,
            };
            idle = 0;
            for &c in &buf[..n] {
                line.push(c);
                if c != b'\n' {
                    continue;
                }
                let command = String::from_utf8_lossy(&line).trim().to_string();
                line.clear();
                let silent = silent_after.is_some_and(|k| turns >= k);
                if command.starts_with("G02") {
                    turns += 1;
                }
                told.commands.push(command.clone());
                if silent {
                    continue;
                }
                let mut reply = format!("{command}\n");
                if command == "M200" {
                    reply += "v.20210318\n";
                }
                reply += ">\n";
                let _ = ours.write_all(reply.as_bytes());
            }
        }
        told
    });
    (path, theirs, thread)
}

/// Scans FabScanPi's `1_1` with laser 0 of the imported calibration, the platform turned 64
/// steps a frame by the board at the pseudo-terminal `path`, into `stream`.
fn motor_scan(f: &Fixture, path: &str, stream: &str, extra: &[&str]) -> (bool, String, String) {
    let frames = fabscan().join("1_1");
    let motor = format!("serial:{path}@115200");
    let mut args = vec![
        "scan",
        "--source",
        frames.to_str().unwrap(),
        "--calibration",
        "imported.toml",
        "--fixed-laser",
        "0",
        "--steps-per-frame",
        "64",
        "--motor",
        &motor,
        "--columns",
        "--out",
        stream,
        "-q",
    ];
    args.extend_from_slice(extra);
    run_in(&workspace_bin("scanner-device"), f.dir.path(), &args)
}

#[test]
fn the_simulated_firmware_turns_the_platform_through_a_whole_scan() {
    let f = fixture();
    let host = workspace_bin("scanner-host");
    let (path, _keep, firmware) = simulated_fabscan(None);
    let (ok, _, err) = motor_scan(f, &path, "motor.stream", &[]);
    assert!(ok, "{err}");
    drop(_keep);
    let told = firmware.join().unwrap();
    let turns = told
        .commands
        .iter()
        .filter(|c| *c == "G02 T64 F200")
        .count();
    // one turn between each two of the 101 frames; the laser on before, off after
    assert_eq!(turns, 100, "{:?}", told.commands);
    assert_eq!(told.commands.first().map(String::as_str), Some("M200"));
    assert_eq!(told.commands.get(1).map(String::as_str), Some("M21"));
    assert_eq!(told.commands.last().map(String::as_str), Some("M22"));
    let (ok, _, err) = run_in(
        &host,
        f.dir.path(),
        &["receive", "motor.stream", "--out", "motor"],
    );
    assert!(ok, "{err}");
    let summary = json(&f.path("motor/summary.json"));
    assert_eq!(summary["fixed"]["frames"], 101);
    assert_eq!(summary["fixed"]["watertight"], true);
}

#[test]
fn a_firmware_that_falls_silent_ends_the_scan_with_what_it_took() {
    let f = fixture();
    let host = workspace_bin("scanner-host");
    let (path, _keep, firmware) = simulated_fabscan(Some(30));
    let (ok, _, err) = motor_scan(f, &path, "silent.stream", &["--motor-timeout-ms", "300"]);
    assert!(
        !ok,
        "a scan whose motor fell silent must not end as a success"
    );
    assert!(
        err.contains("did not answer \"G02 T64 F200\" within 300 ms"),
        "{err}"
    );
    drop(_keep);
    let told = firmware.join().unwrap();
    assert_eq!(
        told.commands
            .iter()
            .filter(|c| c.starts_with("G02"))
            .count(),
        31
    );
    // the 31 frames taken before the silence (the first, then one per acknowledged turn) are
    // on the link, with the final status, and make a model of what they saw
    let (ok, _, err) = run_in(
        &host,
        f.dir.path(),
        &["receive", "silent.stream", "--out", "silent"],
    );
    assert!(ok, "{err}");
    let summary = json(&f.path("silent/summary.json"));
    assert_eq!(summary["fixed"]["frames"], 31, "{summary}");
    let turned = summary["fixed"]["turned_deg"].as_f64().unwrap();
    assert!((turned - 108.0).abs() < 0.01, "{turned}");
}

/// Both lasers' recordings in one folder (`laser0_NNN.jpg` and `laser1_NNN.jpg`, as a scanner
/// that takes each step with each laser saves them): refused without `--series`, naming both
/// series; with `--series laser0_*.jpg`, the frames of laser 0 alone, as the recording alone
/// gives them.
#[test]
fn a_folder_of_both_lasers_frames_is_read_one_series_at_a_time() {
    let f = fixture();
    let data = fabscan();
    let mixed = f.path("mixed");
    std::fs::create_dir_all(&mixed).unwrap();
    for (laser, rec) in [(0, "1_1"), (1, "1_2")] {
        for k in 0..=100 {
            let from = data.join(rec).join(format!("20210213-230202_{k:03}.jpg"));
            let to = mixed.join(format!("laser{laser}_{k:03}.jpg"));
            if !to.exists() {
                std::os::unix::fs::symlink(&from, &to).unwrap();
            }
        }
    }
    let device = workspace_bin("scanner-device");
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "scan",
            "--source",
            "mixed",
            "--calibration",
            "imported.toml",
            "--fixed-laser",
            "0",
            "--frames-per-turn",
            "100",
            "--columns",
            "--out",
            "mixed.stream",
            "--report",
            "mixed.json",
            "-q",
        ];
        a.extend_from_slice(extra);
        a
    };
    let (ok, _, err) = run_in(&device, f.dir.path(), &args(&[]));
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "Series"),
        "{err}"
    );
    assert!(
        err.contains("laser0_*.jpg") && err.contains("laser1_*.jpg"),
        "{err}"
    );
    let (ok, _, err) = run_in(&device, f.dir.path(), &args(&["--series", "laser2_*.jpg"]));
    assert!(!ok);
    assert!(
        scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "NoSuchSeries"),
        "{err}"
    );
    let (ok, _, err) = run_in(&device, f.dir.path(), &args(&["--series", "laser0_*.jpg"]));
    assert!(ok, "{err}");
    let r = json(&f.path("mixed.json"));
    assert_eq!(r["frames"], 101, "{r}");
    let alone = json(&f.path("imported0/summary.json"));
    assert_eq!(r["points"], alone["points"], "{r}");
}
