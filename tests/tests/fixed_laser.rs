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

/// The vertices of a binary PLY written by the host (x, y, z first, floats).
fn ply_vertices(path: &Path) -> Vec<[f32; 3]> {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let n: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    let stride = 4 * header
        .lines()
        .filter(|l| l.starts_with("property float"))
        .count()
        + 3 * header
            .lines()
            .filter(|l| l.starts_with("property uchar"))
            .count();
    (0..n)
        .map(|i| {
            let f = |k: usize| {
                let o = end + i * stride + 4 * k;
                f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap())
            };
            [f(0), f(1), f(2)]
        })
        .collect()
}

#[test]
fn the_real_bust_becomes_one_closed_model_without_the_platform() {
    let data = fabscan();
    let dir = tempfile::tempdir().unwrap();
    let (device, host) = (
        workspace_bin("scanner-device"),
        workspace_bin("scanner-host"),
    );
    let config = data.join("dummy.config.json");
    let (ok, _, err) = run_in(
        &device,
        dir.path(),
        &[
            "import-fabscan",
            config.to_str().unwrap(),
            "--out",
            "cal.toml",
        ],
    );
    assert!(ok, "{err}");
    let frames = data.join("1_1");
    let (ok, _, err) = run_in(
        &device,
        dir.path(),
        &[
            "scan",
            "--source",
            frames.to_str().unwrap(),
            "--calibration",
            "cal.toml",
            "--fixed-laser",
            "0",
            "--frames-per-turn",
            "100",
            "--columns",
            "--out",
            "bust.stream",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run_in(
        &host,
        dir.path(),
        &["receive", "bust.stream", "--out", "bust"],
    );
    assert!(ok, "{err}");
    let summary = json(&dir.path().join("bust/summary.json"));
    let fixed = &summary["fixed"];
    eprintln!("{fixed}");
    assert_eq!(fixed["frames"], 101, "every frame gave points");
    let turned = fixed["turned_deg"].as_f64().unwrap();
    assert!((turned - 360.0).abs() < 0.01, "{turned}");
    assert_eq!(fixed["watertight"], true);
    let object = fixed["object_points"].as_u64().unwrap();
    let still = fixed["still"].as_u64().unwrap();
    assert!(object > 40_000, "{object} object points");
    // the laser on what did not turn (the scanner's back and sides) is left out, and is not
    // most of what was lit
    assert!(still > 1_000 && still < object, "{still} still of {object}");
    // the bust: about 110 mm across and 120 mm tall (FabScanPi's own model of it is)
    let cloud = ply_vertices(&dir.path().join("bust/cloud.ply"));
    let model = ply_vertices(&dir.path().join("bust/scan.ply"));
    assert_eq!(cloud.len() as u64, object);
    let height = cloud.iter().map(|v| v[1]).fold(f32::MIN, f32::max);
    assert!((100.0..140.0).contains(&height), "{height} mm tall");
    // no point of the platform's surface: nothing in the cloud under 1 mm above its top, and the
    // model's base is its flat cut, not the turntable's disc around the bust
    assert!(cloud.iter().all(|v| v[1] >= 1.0));
    let base: Vec<&[f32; 3]> = model.iter().filter(|v| v[1] < 2.0).collect();
    let reach = base.iter().map(|v| v[0].hypot(v[2])).fold(0.0f32, f32::max);
    assert!(
        reach < 65.0,
        "the base reaches {reach} mm from the axis: the platform's edge"
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
        err.contains("bad.config.json") && err.contains("is not a FabScanPi config"),
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
        err.contains("[[laser]] 0") && err.contains("through the camera"),
        "{err}"
    );
    // no steps per turn
    let steps = config_with(dir.path(), "\"steps\": 6400", "\"steps\": 0");
    let (ok, _, err) = import(&steps);
    assert!(!ok);
    assert!(err.contains("steps_per_turn 0"), "{err}");
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
        err.contains("--turn-deg, --steps-per-frame or --frames-per-turn"),
        "{err}"
    );
    let (ok, _, err) = scan(&["--fixed-laser", "1", "--frames-per-turn", "100"]);
    assert!(!ok);
    assert!(
        err.contains("--fixed-laser 1") && err.contains("1 fixed laser plane"),
        "{err}"
    );
    let (ok, _, err) = scan(&["--fixed-laser", "0", "--steps-per-frame", "0"]);
    assert!(!ok);
    assert!(err.contains("--steps-per-frame 0"), "{err}");
}
