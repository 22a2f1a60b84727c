//! `scanner-device capture` without a camera: a folder of rendered calibration shots stands in
//! for the camera; each frame is checked by the detector, only usable ones are kept, and what is
//! kept calibrates.

use std::path::Path;

fn run(dir: &Path, args: &[&str]) -> (bool, String, String) {
    scanner_tests::run_in(Path::new(env!("CARGO_BIN_EXE_scanner-device")), dir, args)
}

#[test]
fn capture_keeps_the_usable_shots_and_says_why_of_the_others() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let (ok, _, err) = run(d, &["render-calibration", "--out", "shots"]);
    assert!(ok, "{err}");
    // A "camera" that shows the cross first (no grid), then grid shots.
    std::fs::create_dir(d.join("cam")).unwrap();
    std::fs::copy(d.join("shots/cross-near.png"), d.join("cam/a-cross.png")).unwrap();
    for i in 0..4 {
        std::fs::copy(
            d.join(format!("shots/grid-{i:02}.png")),
            d.join(format!("cam/b-grid-{i}.png")),
        )
        .unwrap();
    }
    let (ok, out, err) = run(
        d,
        &[
            "capture", "--source", "dir:cam", "--count", "3", "--out", "kept",
        ],
    );
    assert!(ok, "{err}\n{out}");
    let r = json(&d.join("kept/capture-report.json"));
    let shots = r["shots"].as_array().unwrap();
    assert_eq!(shots[0]["refused"]["reason"], "no_grid", "{r}");
    assert!(shots[0]["kept_as"].is_null(), "{r}");
    assert_eq!(
        shots[1]["grid"],
        serde_json::json!({"points": 63, "cols": 9, "rows": 7, "complete": true}),
        "{r}"
    );
    assert_eq!(shots[1]["kept_as"], "grid-00.png", "{r}");
    assert_eq!(
        (r["kept"].as_u64(), r["count"].as_u64()),
        (Some(3), Some(3))
    );
    for i in 0..3 {
        assert!(d.join(format!("kept/grid-{i:02}.png")).exists());
    }
    assert!(
        !d.join("kept/grid-03.png").exists(),
        "more than --count kept"
    );
    // Too few usable shots is an error that says so.
    let (ok, _, err) = run(
        d,
        &[
            "capture", "--source", "dir:cam", "--count", "5", "--out", "few",
        ],
    );
    assert!(!ok && scanner_tests::has_kind(&err, "TooFewShots"), "{err}");
    // The board, checked with a camera file, then calibrated from the kept shot.
    std::fs::create_dir(d.join("boardcam")).unwrap();
    std::fs::copy(d.join("shots/board.png"), d.join("boardcam/board.png")).unwrap();
    let (ok, out, err) = run(
        d,
        &[
            "capture",
            "--source",
            "dir:boardcam",
            "--board",
            "shots/truth-calibration.toml",
            "--out",
            "keptb",
        ],
    );
    assert!(ok, "{err}\n{out}");
    let r = json(&d.join("keptb/capture-report.json"));
    let shot = &r["shots"][0];
    assert_eq!(shot["kept_as"], "board.png", "{r}");
    assert_eq!(shot["sheets"].as_array().map(Vec::len), Some(2), "{r}");
    assert!(
        shot["angle_deg"]
            .as_f64()
            .is_some_and(|a| a > 30.0 && a < 150.0),
        "{r}"
    );
    let (ok, _, err) = run(
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
            "keptb/board.png",
        ],
    );
    assert!(ok, "{err}");
}

#[test]
fn capture_checks_real_webcam_photographs_of_a_chessboard() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/real-calibration");
    std::fs::create_dir(d.join("cam")).unwrap();
    for name in ["right01.jpg", "right02.jpg", "right03.jpg"] {
        std::fs::copy(real.join(name), d.join("cam").join(name)).unwrap();
    }
    let (ok, out, err) = run(
        d,
        &[
            "capture",
            "--source",
            "dir:cam",
            "--chessboard-corners",
            "9x6",
            "--count",
            "3",
            "--out",
            "kept",
        ],
    );
    assert!(ok, "{err}\n{out}");
    let r = json(&d.join("kept/capture-report.json"));
    for shot in r["shots"].as_array().unwrap() {
        assert_eq!(
            shot["grid"],
            serde_json::json!({"points": 54, "cols": 9, "rows": 6, "complete": true}),
            "{r}"
        );
    }
    assert_eq!(r["kept"], 3, "{r}");
    // A count smaller than the board shows (a 9x6 board given as 8x5) finds no usable shot and
    // says so (a larger count is a partial view of a bigger board, which is allowed).
    let (ok, out, err) = run(
        d,
        &[
            "capture",
            "--source",
            "dir:cam",
            "--chessboard-corners",
            "8x5",
            "--count",
            "1",
            "--out",
            "wrong",
        ],
    );
    assert!(
        !ok && scanner_tests::has_kind(&err, "TooFewShots"),
        "{err}\n{out}"
    );
    let r = json(&d.join("wrong/capture-report.json"));
    assert_eq!(r["shots"][0]["refused"]["reason"], "count_mismatch", "{r}");
    assert_eq!(r["kept"], 0, "{r}");
}

/// A JSON report a command wrote.
fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}
