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
    assert!(ok, "{err}");
    assert!(
        out.contains("frame 0: not usable: dot grid not found"),
        "{out}"
    );
    assert!(
        out.contains("frame 1: grid found: 63 points identified over 9×7, complete"),
        "{out}"
    );
    assert!(out.contains("3 shots in kept"), "{out}");
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
    assert!(!ok && err.contains("4 of 5 usable shots kept"), "{err}");
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
    assert!(ok, "{err}");
    assert!(
        out.contains("left sheet: ") && out.contains("the sheets meet at"),
        "{out}"
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
    assert!(ok, "{err}");
    assert_eq!(
        out.matches("grid found: 54 points identified over 9×6, complete")
            .count(),
        3,
        "{out}"
    );
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
    assert!(!ok && err.contains("0 of 1 usable shots kept"), "{err}");
    assert!(out.contains("frame 0: not usable"), "{out}");
}
