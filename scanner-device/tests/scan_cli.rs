//! `scanner-device scan` from the outside: a rig scan into a file with its summary, and a clear
//! error for each thing that can be wrong before the first frame.

fn run(args: &[&str]) -> (bool, String, String) {
    scanner_tests::run(env!("CARGO_BIN_EXE_scanner-device"), args)
}

/// Whether a failed command's error (from its stderr) has a cause of this kind.
fn has_kind(err: &str, kind: &str) -> bool {
    scanner_tests::error_kinds(err).iter().any(|k| k == kind)
}

/// The demo rig's truth at `w × h` as a calibration file in `dir` (what `render-calibration`
/// writes as `truth-calibration.toml`); its path.
fn truth_file(dir: &std::path::Path, w: u32, h: u32) -> String {
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::demo(w, h)).unwrap();
    let path = dir.join(format!("truth-{w}x{h}.toml"));
    rig.truth_calibration().save(&path).unwrap();
    path.display().to_string()
}

#[test]
fn a_rig_scan_into_a_file_reports_its_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scan.stream");
    let truth = truth_file(dir.path(), 320, 240);
    let report = dir.path().join("scan.json");
    let (ok, stdout, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "-q",
    ]);
    assert!(ok, "{err}");
    let r = json(&report);
    assert_eq!(r["frames"], 60, "{stdout}");
    let bpp = r["bytes_per_point"]
        .as_f64()
        .unwrap_or_else(|| panic!("{r}"));
    assert!(bpp > 0.0 && bpp < 20.0, "{r}");
    assert!(std::fs::metadata(&out).unwrap().len() > 1000);
}

#[test]
fn errors_before_the_first_frame_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).display().to_string();
    let truth = truth_file(dir.path(), 320, 240);
    // No calibration.
    let (ok, _, err) = run(&["scan", "--out", &d("a")]);
    assert!(!ok && has_kind(&err, "NoCalibration"), "{err}");
    // A calibration for another resolution.
    let cam = scanner_rig::Scene::demo(1280, 960).camera;
    let mut f =
        scanner_calib::file::CalibrationFile::from_camera(&cam, (1280, 960), "test".into(), None);
    let rig = scanner_rig::Rig::new(scanner_rig::Scene::demo(1280, 960)).unwrap();
    f.board = rig.truth_calibration().board;
    f.save(&dir.path().join("cal.toml")).unwrap();
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &d("cal.toml"),
        "--out",
        &d("b"),
    ]);
    // the message family of sizes: the sentence names both
    assert!(
        !ok && has_kind(&err, "CalibrationSize")
            && err.contains("1280×960 images but rig:320x240 gives 320×240"),
        "{err}"
    );
    // A calibration without a board.
    scanner_calib::file::CalibrationFile::from_camera(&cam, (1280, 960), "test".into(), None)
        .save(&dir.path().join("cam.toml"))
        .unwrap();
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:1280x960",
        "--calibration",
        &d("cam.toml"),
        "--out",
        &d("c"),
    ]);
    assert!(!ok && has_kind(&err, "NoBoard"), "{err}");
    // A corrupt calibration file.
    std::fs::write(
        dir.path().join("corrupt.toml"),
        "version = 1\n[image]\nwidth = 320\n",
    )
    .unwrap();
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &d("corrupt.toml"),
        "--out",
        &d("g"),
    ]);
    assert!(!ok && has_kind(&err, "Toml"), "{err}");
    // An unknown camera.
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "/dev/video99",
        "--calibration",
        &truth,
        "--out",
        &d("e"),
    ]);
    assert!(!ok && has_kind(&err, "Camera"), "{err}");
    // An unsupported pixel format.
    let (ok, _, err) = run(&[
        "scan",
        "--fourcc",
        "H264",
        "--calibration",
        &truth,
        "--out",
        &d("f"),
    ]);
    assert!(!ok && has_kind(&err, "UnsupportedFormat"), "{err}");
    let (ok, _, err) = run(&["scan", "--format", "bayer", "--calibration", &truth]);
    assert!(!ok && has_kind(&err, "InvalidValue"), "{err}");
    // An output that cannot be written.
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        "/nonexistent-dir/x.stream",
    ]);
    assert!(!ok && has_kind(&err, "File"), "{err}");
    // A serial port that is not there.
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        "serial:/dev/ttyNONE@115200",
    ]);
    assert!(!ok && has_kind(&err, "Serial"), "{err}");
    // The rig's truth for another size than the source's.
    let (ok, _, err) = run(&["scan", "--source", "rig:640x480", "--calibration", &truth]);
    assert!(!ok && has_kind(&err, "CalibrationSize"), "{err}");
}

/// The last status message of a stream file.
fn final_status(path: &std::path::Path) -> scanner_wire::Status {
    use scanner_wire::{Decoder, MAX_ENCODED, Message};
    let bytes = std::fs::read(path).unwrap();
    let mut dec = Box::new(Decoder::<MAX_ENCODED>::new());
    let mut last = None;
    dec.feed(&bytes, |m| {
        if let Ok(Message::Status(s)) = m {
            last = Some(s);
        }
    });
    assert_eq!(dec.stats().rejected(), 0, "a damaged stream");
    last.expect("a status message")
}

#[test]
fn frame_and_time_limits_end_the_scan_with_a_final_stopped_status() {
    use scanner_wire::EndReason;
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_file(dir.path(), 320, 240);
    let out = dir.path().join("a.stream");
    let (ok, stdout, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "--frames",
        "7",
        "--report",
        dir.path().join("a.json").to_str().unwrap(),
        "-q",
    ]);
    assert!(ok, "{err}\n{stdout}");
    let r = json(&dir.path().join("a.json"));
    assert_eq!(r["frames"], 7, "{r}");
    assert!(
        r["stopped"]
            .as_str()
            .is_some_and(|s| s.contains("--frames")),
        "the limit named: {r}"
    );
    let s = final_status(&out);
    assert!(
        s.done && s.ended == EndReason::Stopped && s.frames == 7,
        "{s:?}"
    );
    let out = dir.path().join("b.stream");
    let (ok, stdout, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "--duration",
        "0.05",
        "-q",
    ]);
    assert!(ok, "{err}");
    let s = final_status(&out);
    assert!(
        s.done && s.ended == EndReason::Stopped && s.frames < 60,
        "{s:?} {stdout}"
    );
    let (ok, _, err) = run(&["scan", "--duration=-1"]);
    assert!(!ok && has_kind(&err, "ValueValidation"), "{err}");
    let (ok, _, err) = run(&["scan", "--edge-reach", "9"]);
    // the message family of option values: the sentence names the option and its range
    assert!(
        !ok && has_kind(&err, "ValueValidation")
            && err.contains(
                "'--edge-reach <EDGE_REACH>': \"9\": a number of profile widths from 0 to 4"
            ),
        "{err}"
    );
    let (ok, _, err) = run(&["scan", "--print-ratio", "1.0"]);
    assert!(!ok && has_kind(&err, "ValueValidation"), "{err}");
}

#[test]
fn sigterm_and_sigint_end_the_scan_with_a_final_status() {
    use scanner_wire::EndReason;
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_file(dir.path(), 640, 480);
    for signal in ["TERM", "INT"] {
        let out = dir.path().join(format!("{signal}.stream"));
        let report = dir.path().join(format!("{signal}.json"));
        let child = std::process::Command::new(env!("CARGO_BIN_EXE_scanner-device"))
            .args([
                "scan",
                "--source",
                "rig:640x480",
                "--calibration",
                &truth,
                "--out",
                out.to_str().unwrap(),
                "--report",
                report.to_str().unwrap(),
                "-q",
            ])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until frames flow (the stream grows past its header), then signal.
        let t0 = std::time::Instant::now();
        while std::fs::metadata(&out).map_or(0, |m| m.len()) < 2000 {
            assert!(t0.elapsed().as_secs() < 60, "no frames within 60 s");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let kill = std::process::Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let result = child.wait_with_output().unwrap();
        let stdout = String::from_utf8_lossy(&result.stdout);
        assert!(
            result.status.success(),
            "SIG{signal}: {:?}\n{}",
            result.status,
            String::from_utf8_lossy(&result.stderr)
        );
        let r = json(&report);
        assert!(
            r["stopped"].is_string() && r["ended_early"].is_null(),
            "SIG{signal}: {r}\n{stdout}"
        );
        let s = final_status(&out);
        assert!(
            s.done && s.ended == EndReason::Stopped,
            "SIG{signal}: {s:?}"
        );
        assert!(s.frames < 120, "SIG{signal}: the whole sweep ran: {s:?}");
    }
}

#[test]
fn a_recorded_scan_reprocesses_to_the_same_stream_and_with_a_new_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).display().to_string();
    let truth = truth_file(dir.path(), 320, 240);
    let scan = |source: &str, cal: &str, out: &str, extra: &[&str]| {
        let mut args = vec![
            "scan",
            "--source",
            source,
            "--format",
            "yuyv",
            "--calibration",
            cal,
            "--out",
            out,
            "--scan-id",
            "77",
            "--link-depth",
            "64",
            "-q",
        ];
        args.extend_from_slice(extra);
        let (ok, stdout, err) = run(&args);
        assert!(ok, "{args:?}: {err}");
        stdout
    };
    let rec = d("rec");
    scan(
        "rig:320x240",
        &truth,
        &d("live.stream"),
        &["--record", &rec],
    );
    let meta = std::fs::read_to_string(dir.path().join("rec/recording.toml")).unwrap();
    assert!(meta.contains("yuyv") && meta.contains("320"), "{meta}");
    // Reprocessed with the calibration it was made with: the very same bytes.
    let source = format!("record:{rec}");
    scan(
        &source,
        &truth,
        &d("again.stream"),
        &["--report", &d("again.json")],
    );
    assert_eq!(json(&dir.path().join("again.json"))["frames"], 60);
    let (a, b) = (
        std::fs::read(d("live.stream")).unwrap(),
        std::fs::read(d("again.stream")).unwrap(),
    );
    assert!(a.len() > 1000);
    assert!(
        a == b,
        "the reprocessed stream differs ({} vs {} bytes)",
        a.len(),
        b.len()
    );
    // With another calibration (the board moved 5 mm): a different, valid stream.
    let text = std::fs::read_to_string(&truth).unwrap();
    let line = text.lines().find(|l| l.starts_with("offset = ")).unwrap();
    let v: f64 = line["offset = ".len()..].parse().unwrap();
    std::fs::write(
        d("moved.toml"),
        text.replacen(line, &format!("offset = {}", v + 5.0), 1),
    )
    .unwrap();
    scan(&source, &d("moved.toml"), &d("moved.stream"), &[]);
    let c = std::fs::read(d("moved.stream")).unwrap();
    assert!(c != a && final_status(&dir.path().join("moved.stream")).done);
    // A recording is not overwritten, and a format other than the recorded one is refused.
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--format",
        "yuyv",
        "--calibration",
        &truth,
        "--out",
        &d("x.stream"),
        "--record",
        &rec,
    ]);
    assert!(!ok && has_kind(&err, "RecordingExists"), "{err}");
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        &source,
        "--format",
        "gray",
        "--calibration",
        &truth,
        "--out",
        &d("y.stream"),
    ]);
    assert!(!ok && has_kind(&err, "RecordedFormat"), "{err}");
}

#[test]
fn waiting_for_the_laser_skips_the_frames_before_it() {
    use scanner_device::source::FrameSource;
    let dir = tempfile::tempdir().unwrap();
    let truth = truth_file(dir.path(), 320, 240);
    // A "camera": the reference, four more laser-off frames, then the sweep's middle.
    let mut src = scanner_device::source::RigSource::new(
        scanner_rig::Rig::new(scanner_rig::Scene::demo(320, 240)).unwrap(),
        scanner_core::stripe::PixelFormat::Rgb24,
    );
    let reference = src.reference().unwrap();
    let laser: Vec<_> = (0..40)
        .filter_map(|_| src.next_frame().unwrap())
        .skip(30)
        .collect();
    let folder = dir.path().join("cam");
    std::fs::create_dir(&folder).unwrap();
    let save = |name: &str, data: &[u8]| {
        image::RgbImage::from_raw(320, 240, data.to_vec())
            .unwrap()
            .save(folder.join(name))
            .unwrap();
    };
    save("reference.png", &reference.data);
    for i in 0..4 {
        save(&format!("a{i}.png"), &reference.data);
    }
    for (i, f) in laser.iter().enumerate() {
        save(&format!("b{i}.png"), &f.data);
    }
    let out = dir.path().join("w.stream");
    let source = format!("dir:{}", folder.display());
    let (ok, stdout, err) = run(&[
        "scan",
        "--source",
        &source,
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "--wait-for-laser",
        "5",
        "-q",
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("waiting for the laser") && err.contains("laser seen"),
        "{err}"
    );
    assert!(
        stdout.contains(&format!("{} frames", laser.len())),
        "{stdout}"
    );
    // Only laser-off frames: the wait ends with a clear error, not a scan of nothing.
    for f in std::fs::read_dir(&folder).unwrap() {
        let p = f.unwrap().path();
        if p.file_name().unwrap().to_str().unwrap().starts_with('b') {
            std::fs::remove_file(p).unwrap();
        }
    }
    let (ok, _, err) = run(&[
        "scan",
        "--source",
        &source,
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "--wait-for-laser",
        "5",
        "-q",
    ]);
    assert!(!ok && has_kind(&err, "NoLaser"), "{err}");
}

/// A JSON report a command wrote.
fn json(path: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

#[test]
fn a_disc_of_unknown_paper_is_refused_naming_the_sizes() {
    let (ok, _, err) = run(&["scan", "--source", "rig:64x48", "--disc", "a5"]);
    assert!(!ok && has_kind(&err, "ValueValidation"), "{err}");
}

/// `preview`'s own option is checked, and its other options are `scan`'s, refused alike.
#[test]
fn a_preview_with_bad_options_is_refused_naming_them() {
    let (ok, _, err) = run(&["preview", "--source", "rig:64x48", "--every", "0"]);
    assert!(!ok && has_kind(&err, "ValueValidation"), "{err}");
    let (ok, _, err) = run(&["preview", "--source", "rig:64x48", "--size", "NaNxNaN"]);
    assert!(!ok && has_kind(&err, "SizeError"), "{err}");
    let (ok, _, err) = run(&["preview", "--source", "no-such:thing", "--out", "-"]);
    assert!(!ok && has_kind(&err, "Unknown"), "{err}");
}
