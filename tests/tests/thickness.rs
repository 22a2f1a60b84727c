//! The laser sheet's correction of a single scan (`--sheet MM` on `receive`, `replay` and
//! `check`), through the real binaries on a rendered bar of two 40 mm spheres: the points'
//! radial errors from the true spheres (computed here) before and after, the same outputs
//! from a live receive and from a replay of its journal, and bad values refused.

use std::path::Path;

use scanner_core::nalgebra::{Point3, Vector3};
use scanner_tests::workspace_bin;

fn run(dir: &Path, bin: &str, args: &[&str]) -> (bool, String, String) {
    scanner_tests::run_in(&workspace_bin(bin), dir, args)
}

/// The rig's demo laser (σ 0.6 mm) on two spheres in front of the board.
const SCENE: &str = "width = 800\nheight = 600\n\n[laser]\nframes = 240\n\n\
    [[objects]]\nshape = \"sphere\"\ncentre = [-60.0, 20.0, 560.0]\nradius = 20.0\n\n\
    [[objects]]\nshape = \"sphere\"\ncentre = [60.0, 20.0, 570.0]\nradius = 20.0\n";

const CENTRES: [[f64; 3]; 2] = [[-60.0, 20.0, 560.0], [60.0, 20.0, 570.0]];
const RADIUS: f64 = 20.0;

/// The vertices of an OBJ (camera frame), read with tobj.
fn vertices(obj: &Path) -> Vec<Point3<f64>> {
    let (models, _) = tobj::load_obj(obj, &tobj::LoadOptions::default()).unwrap();
    models
        .iter()
        .flat_map(|m| {
            m.mesh
                .positions
                .chunks_exact(3)
                .map(|p| Point3::new(p[0], p[1], p[2]).cast::<f64>())
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Per sphere: the mean signed radial error of the vertices within 2 mm of it (+ outside), their
/// RMS, and the mean over its upper half (normals up, towards the laser) minus that over its
/// lower half.
fn radial(points: &[Point3<f64>]) -> Vec<(f64, f64, f64)> {
    CENTRES
        .iter()
        .map(|c| {
            let c = Point3::from(*c);
            let (mut n, mut sum, mut sq) = (0.0, 0.0, 0.0);
            let mut halves = [(0.0, 0.0); 2];
            for p in points {
                let d: Vector3<f64> = p - c;
                let r = d.norm() - RADIUS;
                if r.abs() >= 2.0 {
                    continue;
                }
                n += 1.0;
                sum += r;
                sq += r * r;
                let h = &mut halves[usize::from(d.y > 0.0)];
                h.0 += r;
                h.1 += 1.0;
            }
            assert!(n > 200.0, "{n} points on a sphere");
            let [(up, nu), (down, nd)] = halves;
            (sum / n, (sq / n).sqrt(), up / nu - down / nd)
        })
        .collect()
}

#[test]
fn the_sheet_correction_moves_a_spheres_points_onto_it() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    scanner_tests::scan_rig(d, SCENE, &[], "bar.stream");
    // Live: receive corrects this session's frames from its journal at the end.
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &[
            "receive",
            "bar.stream",
            "--out",
            "live",
            "--frame",
            "camera",
            "--sheet",
            "0.6",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let live = scanner_tests::summary(&d.join("live"));
    let (moved, points) = (
        live["sheet_moved"]
            .as_u64()
            .unwrap_or_else(|| panic!("{live}")),
        live["points"].as_u64().unwrap(),
    );
    assert!(
        moved * 10 > points * 8,
        "most points move: {moved} of {points}"
    );
    // The same from a replay of the journal, and without the correction.
    for (sheet, folder) in [("0.6", "again"), ("0", "plain")] {
        let (ok, out, err) = run(
            d,
            "scanner-host",
            &[
                "replay",
                "live/journal.stream",
                "--out",
                folder,
                "--frame",
                "camera",
                "--sheet",
                sheet,
                "-q",
            ],
        );
        assert!(ok, "{err}\n{out}");
        assert_eq!(
            scanner_tests::summary(&d.join(folder))["sheet_moved"].is_u64(),
            sheet != "0",
            "{folder}"
        );
    }
    assert_eq!(
        std::fs::read(d.join("live/scan.obj")).unwrap(),
        std::fs::read(d.join("again/scan.obj")).unwrap(),
        "receive --sheet and replay --sheet give the same mesh"
    );
    let before = radial(&vertices(&d.join("plain/scan.obj")));
    let after = radial(&vertices(&d.join("live/scan.obj")));
    for (k, (b, a)) in before.iter().zip(&after).enumerate() {
        eprintln!(
            "sphere {k}: mean {:+.4} → {:+.4} mm, RMS {:.4} → {:.4} mm, upper − lower {:+.4} → {:+.4} mm",
            b.0, a.0, b.1, a.1, b.2, a.2
        );
        // The band's skew puts the upper half (lit from above) inside and the lower outside.
        assert!(
            b.2 < -0.05,
            "sphere {k}: the skew is there to correct: {b:?}"
        );
        assert!(a.0.abs() < b.0.abs(), "sphere {k}: mean {b:?} → {a:?}");
        assert!(a.1 < b.1, "sphere {k}: RMS {b:?} → {a:?}");
        assert!(
            a.2.abs() < 0.8 * b.2.abs(),
            "sphere {k}: halves {b:?} → {a:?}"
        );
    }
    // check takes it too, and says so.
    let (ok, out, err) = run(
        d,
        "scanner-host",
        &[
            "check",
            "live",
            "--sphere",
            "40",
            "--sphere",
            "40",
            "--sheet",
            "0.6",
            "--out",
            "chk",
            "--form-tolerance",
            "1",
        ],
    );
    assert!(ok, "{err}\n{out}");
    let checked: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("chk/check-report.json")).unwrap())
            .unwrap();
    assert_eq!(checked["sheet"]["sigma_mm"], 0.6, "{checked}");
    assert!(checked["sheet"]["moved"].as_u64() > Some(0), "{checked}");
    // Bad values are refused, naming the option.
    for (cmd, v) in [
        ("replay", "9"),
        ("replay", "-1"),
        ("receive", "nan"),
        ("check", "6"),
    ] {
        let input = if cmd == "check" { "live" } else { "bar.stream" };
        let sheet = format!("--sheet={v}");
        let (ok, _, err) = run(d, "scanner-host", &[cmd, input, "--out", "bad", &sheet]);
        assert!(
            !ok && scanner_tests::has_kind(&err, "ThicknessError"),
            "{cmd} --sheet {v}: {err}"
        );
    }
}
