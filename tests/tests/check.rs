//! `scanner-host check` through the real binaries on rendered artefacts with known truth: the
//! rig renders a bar of two 40 mm spheres 120 mm apart in front of the board; the head scans
//! them with the board points kept; `check` finds both spheres and the board's plane without
//! help. Its figures are compared with the rig's truth computed independently here (the
//! points' radial distances from the true spheres), its pass/fail with the tolerances, and its
//! errors with bad input.

use std::path::Path;

use scanner_core::nalgebra::{Point3, Vector3};
use scanner_tests::workspace_bin;

fn run(dir: &Path, bin: &str, args: &[&str]) -> (bool, String, String) {
    scanner_tests::run_in(&workspace_bin(bin), dir, args)
}

/// The bar in front of the board, scanned as a check is: the laser held 300 mm above the camera
/// (the demo holds it 150 mm above: half the angle between the light sheet and the camera's
/// rays, twice the depth per pixel of stripe noise).
const SCENE: &str = "width = 800\nheight = 600\n\n\
    [laser]\nframes = 240\nsource = [20.0, -300.0, 30.0]\n\n\
    [[objects]]\nshape = \"sphere\"\ncentre = [-60.0, 20.0, 560.0]\nradius = 20.0\n\n\
    [[objects]]\nshape = \"sphere\"\ncentre = [60.0, 20.0, 570.0]\nradius = 20.0\n";

/// The check report a check wrote into `dir`.
fn report(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("check-report.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A number of a report.
fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn a_two_sphere_bar_and_the_board_are_checked_against_the_truth() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    scanner_tests::scan_rig(
        d,
        SCENE,
        &[
            "--keep-board",
            "--scan-id",
            "9",
            "--edge-reach",
            "1",
            "--print-ratio",
            "1.5",
        ],
        "bar.stream",
    );
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["receive", "bar.stream", "--out", "bar", "-q"],
    );
    assert!(ok, "{err}");
    let (a, b) = (
        Point3::new(-60.0, 20.0, 560.0),
        Point3::new(60.0, 20.0, 570.0),
    );
    let spacing = (a - b).norm();
    let nominal = format!("{spacing:.4}");
    let bar = |more: &[&str]| {
        let mut args = vec!["check", "bar", "--sphere", "40", "--sphere", "40"];
        args.extend(["--spacing", &nominal]);
        args.extend(more);
        run(d, "scanner-host", &args)
    };

    // Tolerances loose enough for this 800×600 scan: it passes, exit 0.
    let (ok, out, err) = bar(&[
        "--plane",
        "--size-tolerance",
        "0.2",
        "--form-tolerance",
        "0.4",
        "--flatness-tolerance",
        "0.4",
        "--out",
        "loose",
    ]);
    assert!(ok, "{out}\n{err}");
    println!("{out}");
    let loose = report(&d.join("loose"));
    assert_eq!(loose["pass"], true, "{loose}");
    assert_eq!(
        std::fs::read_to_string(d.join("loose/check-report.txt"))
            .unwrap()
            .trim_end(),
        out.trim_end()
    );
    let residuals = image::open(d.join("loose/check-residuals.png"))
        .unwrap()
        .to_rgb8();
    let coloured = residuals
        .pixels()
        .filter(|p| p.0[0] > 120 || p.0[2] > 120)
        .count();
    assert!(
        coloured > 500,
        "the residual picture shows the checked points ({coloured})"
    );

    // Against the truth and an independent fit: the check's centres must be the rig's, and its
    // diameters those of a plain algebraic least-squares sphere (written here) through the
    // scan's points within 1.5 mm of each true sphere (the camera-frame mesh, rebuilt from the
    // journal). The truth's own radial residuals are printed: a free fit to a front cap is not
    // their mean (radius and depth trade off), which is why 2634-2 defines the size by the fit.
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &[
            "replay",
            "bar/journal.stream",
            "--frame",
            "camera",
            "--out",
            "cam",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (models, _) =
        tobj::load_obj(d.join("cam/scan.obj"), &tobj::LoadOptions::default()).unwrap();
    let pts: Vec<Point3<f64>> = models[0]
        .mesh
        .positions
        .chunks(3)
        .map(|c| Point3::new(f64::from(c[0]), f64::from(c[1]), f64::from(c[2])))
        .collect();
    for k in 1..=2 {
        let which = format!("sphere {k}:");
        let sphere = &loose["spheres"][k - 1];
        let measured = num(&sphere["measured_mm"]);
        let c: Vec<f64> = sphere["centre_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(num)
            .collect();
        let found = Point3::new(c[0], c[1], c[2]);
        let truth = if (found - a).norm() < (found - b).norm() {
            a
        } else {
            b
        };
        assert!(
            (found - truth).norm() < 0.5,
            "{which} centre {found} vs the rig's {truth}"
        );
        let near: Vec<Point3<f64>> = pts
            .iter()
            .filter(|p| ((*p - truth).norm() - 20.0).abs() < 1.5)
            .copied()
            .collect();
        let mean = near.iter().map(|p| (p - truth).norm() - 20.0).sum::<f64>() / near.len() as f64;
        let independent = 2.0 * algebraic_radius(&near);
        println!(
            "{which} {} points near the true sphere: mean radial residual {mean:+.4} mm; plain fit ⌀ {independent:.4}; check ⌀ {measured}",
            near.len()
        );
        assert!(
            (measured - independent).abs() < 0.2,
            "{which} check ⌀ {measured} vs a plain fit's {independent:.4}"
        );
        assert!((measured - 40.0).abs() < 0.8, "{which} ⌀ {measured}");
    }
    let found = num(&loose["spacing"]["measured_mm"]);
    assert!(
        (found - spacing).abs() < 0.2,
        "spacing {found} vs true {spacing:.4}"
    );

    // At the default tolerances (the project's targets: size and spacing 0.05 %, form 0.15 %,
    // flatness 0.08 %) the bar and the board, scanned for a check (`--edge-reach 1`: the lines
    // within a profile's width of a run's end dropped, where the spheres' outlines cut their
    // profiles; `--print-ratio 1.5`: the lines across the board's printed dots), pass.
    let (ok, out, err) = bar(&["--plane", "--out", "strict"]);
    println!("{out}");
    assert!(ok, "{out}\n{err}");
    let strict = report(&d.join("strict"));
    assert_eq!(strict["pass"], true, "{strict}");
    for sphere in strict["spheres"].as_array().unwrap() {
        assert_eq!(sphere["size"]["pass"], true, "{sphere}");
        assert_eq!(sphere["form"]["pass"], true, "{sphere}");
    }
    assert_eq!(strict["spacing"]["error"]["pass"], true, "{strict}");
    let flatness = &strict["plane"]["flatness"];
    assert_eq!(flatness["pass"], true, "{flatness}");
    assert!(num(&flatness["pct"]) <= 0.08, "{flatness}");

    // The same bar with the laser held as in the demo, 150 mm above the camera: the stripe's
    // noise is worth twice the depth, and the board is less flat (0.12 % in one run).
    let near = d.join("near");
    std::fs::create_dir(&near).unwrap();
    scanner_tests::scan_rig(
        &near,
        &SCENE.replace("source = [20.0, -300.0, 30.0]\n", ""),
        &["--keep-board", "--edge-reach", "1", "--print-ratio", "1.5"],
        "bar.stream",
    );
    let (ok, _, err) = run(
        &near,
        "scanner-host",
        &["receive", "bar.stream", "--out", "bar", "-q"],
    );
    assert!(ok, "{err}");
    let (_, out, _) = run(
        &near,
        "scanner-host",
        &["check", "bar", "--plane", "--out", "flat"],
    );
    println!("laser 150 mm above the camera:\n{out}");
    let near_flatness = num(&report(&near.join("flat"))["plane"]["flatness"]["pct"]);
    assert!(
        near_flatness > 1.3 * num(&flatness["pct"]),
        "{near_flatness} % with the laser 150 mm above, {flatness} with it 300 mm above"
    );

    // A wrong nominal diameter (a 40 mm ball called 38) fails by name.
    let (ok, out, err) = run(
        d,
        "scanner-host",
        &[
            "check",
            "bar",
            "--sphere",
            "38",
            "--size-tolerance",
            "0.2",
            "--form-tolerance",
            "0.4",
            "--out",
            "wrong",
        ],
    );
    let wrong = report(&d.join("wrong"));
    assert!(
        !ok && wrong["spheres"][0]["size"]["pass"] == false && wrong["pass"] == false,
        "{out}\n{err}"
    );

    // Bad input.
    for (args, says) in [
        (vec!["check", "bar"], "nothing to check"),
        (
            vec!["check", "bar", "--sphere", "0"],
            "--sphere must be a diameter",
        ),
        (
            vec!["check", "bar", "--sphere", "40", "--spacing", "100"],
            "--spacing needs two spheres",
        ),
        (
            vec!["check", "bar", "--sphere", "40", "--size-tolerance", "0"],
            "--size-tolerance must be",
        ),
        (
            vec!["check", "bar", "--sphere", "150"],
            "no sphere of about 150 mm",
        ),
        (vec!["check", "nowhere", "--sphere", "40"], "nowhere"),
    ] {
        let (ok, _, err) = run(d, "scanner-host", &args);
        assert!(!ok && err.contains(says), "{args:?}: {err}");
    }
    std::fs::create_dir(d.join("empty")).unwrap();
    let (ok, _, err) = run(d, "scanner-host", &["check", "empty", "--sphere", "40"]);
    assert!(!ok && err.contains("empty/journal.stream"), "{err}");
}

/// The radius of the algebraic least-squares sphere |p|² + D·p + G = 0 through `pts`.
fn algebraic_radius(pts: &[Point3<f64>]) -> f64 {
    use scanner_core::nalgebra::{Matrix4, Vector4};
    let (mut ata, mut atb) = (Matrix4::<f64>::zeros(), Vector4::<f64>::zeros());
    for p in pts {
        let row = Vector4::new(p.x, p.y, p.z, 1.0);
        ata += row * row.transpose();
        atb -= row * p.coords.norm_squared();
    }
    let x = ata.lu().solve(&atb).unwrap();
    let c = Vector3::new(-x[0] / 2.0, -x[1] / 2.0, -x[2] / 2.0);
    (c.norm_squared() - x[3]).sqrt()
}
