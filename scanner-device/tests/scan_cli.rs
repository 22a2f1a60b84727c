//! `scanner-device scan` from the outside: a rig scan into a file with its summary, and a clear
//! error for each thing that can be wrong before the first frame.

fn run(args: &[&str]) -> (bool, String, String) {
    scanner_tests::run(env!("CARGO_BIN_EXE_scanner-device"), args)
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
    let (ok, stdout, err) = run(&[
        "scan",
        "--source",
        "rig:320x240",
        "--calibration",
        &truth,
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert!(ok, "{err}");
    assert!(
        stdout.contains("60 frames") && stdout.contains("bytes per point"),
        "{stdout}"
    );
    assert!(stdout.contains("115200 baud UART:"), "{stdout}");
    assert!(std::fs::metadata(&out).unwrap().len() > 1000);
}

#[test]
fn errors_before_the_first_frame_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).display().to_string();
    let truth = truth_file(dir.path(), 320, 240);
    // No calibration.
    let (ok, _, err) = run(&["scan", "--out", &d("a")]);
    assert!(!ok && err.contains("no calibration"), "{err}");
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
    assert!(
        !ok && err.contains("is for 1280×960 images but rig:320x240 gives 320×240"),
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
    assert!(!ok && err.contains("no board"), "{err}");
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
    assert!(!ok && err.contains("corrupt.toml"), "{err}");
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
    assert!(!ok && err.contains("/dev/video99"), "{err}");
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
    assert!(
        !ok && err.contains("unsupported camera pixel format \"H264\""),
        "{err}"
    );
    let (ok, _, err) = run(&["scan", "--format", "bayer", "--calibration", &truth]);
    assert!(!ok && err.contains("bayer"), "{err}");
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
    assert!(
        !ok && err.contains("cannot write the stream to /nonexistent-dir/x.stream"),
        "{err}"
    );
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
    assert!(
        !ok && err.contains("cannot open serial port /dev/ttyNONE at 115200 baud"),
        "{err}"
    );
    // The rig's truth for another size than the source's.
    let (ok, _, err) = run(&["scan", "--source", "rig:640x480", "--calibration", &truth]);
    assert!(!ok && err.contains("is for 320×240 images"), "{err}");
}
