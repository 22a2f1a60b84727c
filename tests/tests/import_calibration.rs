//! Other programs' calibrations imported and scanned with: a Horus `calibration.json`, an
//! OpenCV FileStorage YAML and a NumPy `.npz`, each written here as its program writes it
//! (Horus's `profile.py`: every setting an object with its `value`, the calibration of the
//! turned frames; OpenCV's calibration sample's YAML; NumPy's `.npy` format description inside
//! a stored zip, as `np.savez` makes it), never by our own writer. The rig's fixed-laser
//! turntable (`scanner_rig::TurningScan`, 50 frames a turn) is scanned with each import, its
//! points against the objects' true surfaces.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use scanner_calib::file::CalibrationFile;
use scanner_tests::{error_kinds, json, run_in, workspace_bin};

/// Frames per turn of the rig's scan here.
const FRAMES: usize = 50;

struct Fixture {
    dir: PathBuf,
    scan: scanner_rig::TurningScan,
    truth: CalibrationFile,
}

/// The rig's turntable at 640×480, 50 frames a turn, rendered once, with its true calibration.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let mut scan = scanner_rig::TurningScan::demo(640, 480);
        scan.frames = FRAMES + 1;
        scan.turn = std::f64::consts::TAU / FRAMES as f64;
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("import-calibration");
        let _ = std::fs::remove_dir_all(&dir);
        scanner_tests::write_turning_frames(&scan, &dir.join("frames"));
        let truth = scan.truth_calibration();
        truth.save(&dir.join("truth.toml")).unwrap();
        // a calibration whose camera is wrong (focal lengths 5 % long): a camera file put into
        // it must replace its camera for the scan to come out right
        let mut wrong = truth.clone();
        wrong.camera.fx *= 1.05;
        wrong.camera.fy *= 1.05;
        wrong.save(&dir.join("wrong-camera.toml")).unwrap();
        Fixture { dir, scan, truth }
    })
}

/// `scanner-device import ARGS` in the fixture's folder: success and stderr.
fn import(args: &[&str]) -> (bool, String) {
    let f = fixture();
    let mut all = vec!["import"];
    all.extend_from_slice(args);
    let (ok, _, err) = run_in(&workspace_bin("scanner-device"), &f.dir, &all);
    (ok, err)
}

/// Scans the rig's frames with `cal` (laser 0) and receives them into `out`: the mean distance
/// of the cloud's points from the true surfaces as a share of the platform's distance (%), and
/// their count.
fn scan_with(cal: &str, out: &str) -> (f64, usize) {
    let f = fixture();
    let frames = FRAMES.to_string();
    let stream = format!("{out}.stream");
    let (ok, _, err) = run_in(
        &workspace_bin("scanner-device"),
        &f.dir,
        &[
            "scan",
            "--source",
            "frames",
            "--calibration",
            cal,
            "--fixed-laser",
            "0",
            "--frames-per-turn",
            &frames,
            "--rows",
            "--out",
            &stream,
            "-q",
        ],
    );
    assert!(ok, "scan with {cal}: {err}");
    let (ok, _, err) = run_in(
        &workspace_bin("scanner-host"),
        &f.dir,
        &["receive", &stream, "--out", out, "-q"],
    );
    assert!(ok, "receive with {cal}: {err}");
    let fixed = &json(&f.dir.join(out).join("summary.json"))["fixed"];
    let floor = fixed["floor_mm"].as_f64().unwrap() + 3.0;
    let cloud =
        scanner_tests::read_ply(&std::fs::read(f.dir.join(out).join("cloud.ply")).unwrap()).0;
    // written y up: platform (x, y, z) as (x, z, −y)
    let errors: Vec<f64> = cloud
        .iter()
        .map(|v| {
            scanner_core::nalgebra::Point3::new(f64::from(v[0]), -f64::from(v[2]), f64::from(v[1]))
        })
        .filter(|p| p.z > floor)
        .map(|p| f.scan.distance(&p))
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    (100.0 * mean / f.scan.distance_to_platform(), errors.len())
}

/// The camera and laser planes of two calibrations agree to `tol` (relative).
fn same_camera(a: &CalibrationFile, b: &CalibrationFile) -> bool {
    let (a, b) = (&a.camera, &b.camera);
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * (1.0 + x.abs().max(y.abs()));
    close(a.fx, b.fx)
        && close(a.fy, b.fy)
        && close(a.cx, b.cx)
        && close(a.cy, b.cy)
        && close(a.k1, b.k1)
        && close(a.k2, b.k2)
        && close(a.p1, b.p1)
        && close(a.p2, b.p2)
        && close(a.k3, b.k3)
}

/// A Horus `calibration.json` of the rig's scanner as Horus keeps it: the camera turned as
/// Horus turns it by default (`camera_rotate` and `camera_hflip` on: transposed, then flipped
/// left–right, so a stored pixel (u, v) is turned (H−1−v, u) and a camera point (x, y, z)
/// becomes (−y, x, z)), each setting an object with its `value` (and its limits).
fn horus_json(t: &CalibrationFile) -> String {
    let (w, h) = (t.image.width, t.image.height);
    let c = &t.camera;
    let turn = |v: [f64; 3]| [-v[1], v[0], v[2]];
    let l = &t.lasers[0];
    let n = turn(l.normal);
    // a second laser on the other side (a Ciclop has two): the first's plane mirrored
    let n2 = [-n[0], n[1], n[2]];
    let p = t.platform.as_ref().unwrap();
    let r = p.rotation;
    let rt = [
        turn([r[0][0], r[1][0], r[2][0]]),
        turn([r[0][1], r[1][1], r[2][1]]),
        turn([r[0][2], r[1][2], r[2][2]]),
    ];
    let rows = [
        [rt[0][0], rt[1][0], rt[2][0]],
        [rt[0][1], rt[1][1], rt[2][1]],
        [rt[0][2], rt[1][2], rt[2][2]],
    ];
    let value = |v: String| format!("{{\"value\": {v}}}");
    let arr = |v: &[f64]| {
        format!(
            "[{}]",
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let settings = [
        (
            "camera_width",
            format!("{{\"max_value\": 10000, \"min_value\": 1, \"value\": {w}}}"),
        ),
        (
            "camera_height",
            format!("{{\"max_value\": 10000, \"min_value\": 1, \"value\": {h}}}"),
        ),
        ("camera_rotate", value("true".into())),
        ("camera_hflip", value("true".into())),
        ("camera_vflip", value("false".into())),
        (
            "camera_matrix",
            value(format!(
                "[{}, {}, [0.0, 0.0, 1.0]]",
                arr(&[c.fy, 0.0, f64::from(h) - 1.0 - c.cy]),
                arr(&[0.0, c.fx, c.cx])
            )),
        ),
        (
            "distortion_vector",
            value(arr(&[c.k1, c.k2, c.p2, -c.p1, c.k3])),
        ),
        ("use_distortion", value("true".into())),
        ("distance_left", value(format!("{:?}", -l.offset))),
        ("normal_left", value(arr(&n))),
        ("distance_right", value(format!("{:?}", -l.offset))),
        ("normal_right", value(arr(&n2))),
        (
            "rotation_matrix",
            value(format!(
                "[{}, {}, {}]",
                arr(&rows[0]),
                arr(&rows[1]),
                arr(&rows[2])
            )),
        ),
        ("translation_vector", value(arr(&turn(p.origin)))),
        (
            "pattern_rows",
            "{\"max_value\": 50, \"min_value\": 2, \"value\": 6}".to_string(),
        ),
        (
            "pattern_columns",
            "{\"max_value\": 50, \"min_value\": 2, \"value\": 11}".to_string(),
        ),
        (
            "pattern_square_width",
            "{\"min_value\": 1.0, \"value\": 13.0}".to_string(),
        ),
        (
            "pattern_origin_distance",
            "{\"min_value\": 0.0, \"value\": 0.0}".to_string(),
        ),
        ("laser_triangulation_hash", value("\"\"".into())),
        ("platform_extrinsics_hash", value("\"\"".into())),
    ];
    let body: Vec<String> = settings
        .iter()
        .map(|(k, v)| format!("        \"{k}\": {v}"))
        .collect();
    format!(
        "{{\n    \"calibration_settings\": {{\n{}\n    }},\n    \"settings_version\": 1\n}}\n",
        body.join(",\n")
    )
}

#[test]
fn a_horus_calibration_scans_the_rig_as_its_truth_does() {
    let f = fixture();
    std::fs::write(f.dir.join("calibration.json"), horus_json(&f.truth)).unwrap();
    let (ok, err) = import(&[
        "calibration.json",
        "--radius",
        "70",
        "--height",
        "120",
        "--steps-per-turn",
        "6400",
        "--out",
        "horus.toml",
    ]);
    assert!(ok, "{err}");
    let cal = CalibrationFile::load(&f.dir.join("horus.toml")).unwrap();
    assert!(
        same_camera(&cal, &f.truth),
        "{:?} vs {:?}",
        cal.camera,
        f.truth.camera
    );
    assert_eq!(cal.lasers.len(), 2);
    let (a, b) = (&cal.lasers[0], &f.truth.lasers[0]);
    let normal_off = (0..3)
        .map(|i| (a.normal[i] - b.normal[i]).abs())
        .fold(0.0, f64::max);
    assert!(
        normal_off < 1e-9 && (a.offset - b.offset).abs() < 1e-9,
        "{a:?} vs {b:?}"
    );
    let (p, q) = (cal.platform.unwrap(), f.truth.platform.unwrap());
    assert_eq!(
        (p.radius, p.height, p.steps_per_turn, p.clockwise),
        (70.0, 120.0, 6400, false)
    );
    let origin_off = (0..3)
        .map(|i| (p.origin[i] - q.origin[i]).abs())
        .fold(0.0, f64::max);
    assert!(origin_off < 1e-9, "{p:?} vs {q:?}");
    let (mean, points) = scan_with("horus.toml", "horus");
    println!("Horus calibration.json: {points} points, mean {mean:.4} % of D from the truth");
    assert!(
        points > 2_000 && mean < 0.03,
        "{points} points, mean {mean} % of D"
    );
}

/// OpenCV's calibration sample's YAML of the rig's camera (its exponents as older OpenCV
/// writes them, three digits).
fn opencv_yaml(t: &CalibrationFile) -> String {
    let c = &t.camera;
    let e = |v: f64| {
        let s = format!("{v:.16e}");
        // Rust writes 6.5e2; OpenCV 6.5e+002
        let (m, x) = s.split_once('e').unwrap();
        let x: i32 = x.parse().unwrap();
        format!("{m}e{}{:03}", if x < 0 { '-' } else { '+' }, x.abs())
    };
    format!(
        "%YAML:1.0\n---\ncalibration_time: \"Mon 07 Dec 2026 14:00:00 UTC\"\nimage_width: {}\nimage_height: {}\nboard_width: 9\nboard_height: 6\nsquare_size: 25.\nflags: 0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {}, 0., {}, 0.,\n       {}, {}, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n   data: [ {}, {}, {},\n       {}, {} ]\navg_reprojection_error: 2.1e-001\n",
        t.image.width,
        t.image.height,
        e(c.fx),
        e(c.cx),
        e(c.fy),
        e(c.cy),
        e(c.k1),
        e(c.k2),
        e(c.p1),
        e(c.p2),
        e(c.k3)
    )
}

#[test]
fn an_opencv_camera_put_into_a_calibration_scans_the_rig() {
    let f = fixture();
    std::fs::write(f.dir.join("camera.yml"), opencv_yaml(&f.truth)).unwrap();
    let (ok, err) = import(&[
        "camera.yml",
        "--into",
        "wrong-camera.toml",
        "--out",
        "yaml.toml",
    ]);
    assert!(ok, "{err}");
    let cal = CalibrationFile::load(&f.dir.join("yaml.toml")).unwrap();
    assert!(same_camera(&cal, &f.truth), "{:?}", cal.camera);
    assert_eq!(cal.lasers, f.truth.lasers);
    let (mean, points) = scan_with("yaml.toml", "yaml");
    println!("OpenCV YAML camera: {points} points, mean {mean:.4} % of D from the truth");
    assert!(
        points > 2_000 && mean < 0.03,
        "{points} points, mean {mean} % of D"
    );
    // another image size than the calibration's is refused
    let (ok, err) = import(&[
        "camera.yml",
        "--size",
        "1280x960",
        "--into",
        "wrong-camera.toml",
        "--out",
        "other.toml",
    ]);
    assert!(!ok);
    assert!(error_kinds(&err).iter().any(|k| k == "Invalid"), "{err}");
    assert!(!f.dir.join("other.toml").exists());
}

/// An `.npy` (version 1) as NumPy's format description lays it out.
fn npy(shape: &str, values: &[f64]) -> Vec<u8> {
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&u16::try_from(header.len()).unwrap().to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[test]
fn a_numpy_camera_needs_its_size_and_then_scans_the_rig() {
    use std::io::Write as _;
    let f = fixture();
    let c = &f.truth.camera;
    // np.savez('camera.npz', mtx=mtx, dist=dist, rvecs=…): stored entries NAME.npy
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in [
        (
            "mtx.npy",
            npy("(3, 3)", &[c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0]),
        ),
        ("dist.npy", npy("(1, 5)", &[c.k1, c.k2, c.p1, c.p2, c.k3])),
        ("rvecs.npy", npy("(2, 3)", &[0.1, 0.2, 0.3, 0.4, 0.5, 0.6])),
    ] {
        zip.start_file(name, stored).unwrap();
        zip.write_all(&bytes).unwrap();
    }
    let bytes = zip.finish().unwrap().into_inner();
    std::fs::write(f.dir.join("camera.npz"), bytes).unwrap();
    // an .npz holds no image size
    let (ok, err) = import(&[
        "camera.npz",
        "--into",
        "wrong-camera.toml",
        "--out",
        "npz.toml",
    ]);
    assert!(!ok);
    assert!(error_kinds(&err).iter().any(|k| k == "NoSize"), "{err}");
    let (ok, err) = import(&[
        "camera.npz",
        "--size",
        "640x480",
        "--into",
        "wrong-camera.toml",
        "--out",
        "npz.toml",
    ]);
    assert!(ok, "{err}");
    let cal = CalibrationFile::load(&f.dir.join("npz.toml")).unwrap();
    assert!(same_camera(&cal, &f.truth), "{:?}", cal.camera);
    let (mean, points) = scan_with("npz.toml", "npz");
    println!("NumPy .npz camera: {points} points, mean {mean:.4} % of D from the truth");
    assert!(
        points > 2_000 && mean < 0.03,
        "{points} points, mean {mean} % of D"
    );
}

#[test]
fn a_horus_file_with_one_laser_uncalibrated_is_refused() {
    let f = fixture();
    let text = horus_json(&f.truth);
    let one = text.replacen(
        "\"normal_right\": {\"value\": [",
        "\"normal_right\": {\"value\": [0.0, 0.0, 0.0], \"was\": [",
        1,
    );
    std::fs::write(f.dir.join("one-laser.json"), one).unwrap();
    let (ok, err) = import(&["one-laser.json", "--out", "one.toml"]);
    assert!(!ok);
    assert!(error_kinds(&err).iter().any(|k| k == "Invalid"), "{err}");
    std::fs::write(f.dir.join("not-a-calibration.json"), "{\"other\": 1}").unwrap();
    let (ok, err) = import(&["not-a-calibration.json", "--out", "x.toml"]);
    assert!(!ok);
    assert!(
        error_kinds(&err).iter().any(|k| k == "UnknownFormat"),
        "{err}"
    );
}
