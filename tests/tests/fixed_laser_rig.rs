//! A fixed-laser turntable scan rendered by the rig (`scanner_rig::TurningScan`: a sphere and
//! an upright cylinder standing off the axis on a turning platform, the laser's plane holding
//! the axis, 100 frames a turn), scanned through the binaries with the true calibration: the
//! model against the objects' true surfaces.

use scanner_tests::{json, run_in, workspace_bin};

#[test]
fn the_rigs_turntable_scan_is_accurate_and_closed() {
    let scan = scanner_rig::TurningScan::demo(640, 480);
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    for k in 0..scan.frames {
        let f = scan.render(k).unwrap();
        image::RgbImage::from_raw(f.width as u32, f.height as u32, f.data)
            .unwrap()
            .save(frames.join(format!("{k:03}.png")))
            .unwrap();
    }
    scan.truth_calibration()
        .save(&dir.path().join("cal.toml"))
        .unwrap();
    let (device, host) = (
        workspace_bin("scanner-device"),
        workspace_bin("scanner-host"),
    );
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
            "--rows",
            "--out",
            "rig.stream",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run_in(
        &host,
        dir.path(),
        &["receive", "rig.stream", "--out", "rig"],
    );
    assert!(ok, "{err}");
    let summary = json(&dir.path().join("rig/summary.json"));
    let fixed = &summary["fixed"];
    eprintln!("{fixed}");
    assert_eq!(fixed["watertight"], true);
    assert_eq!(fixed["frames"], 101);
    // the cloud's points and the model's vertices (y up: platform (x, y, z) written as
    // (x, z, −y)) against the true surfaces, the flat cut at the base left out
    let floor = fixed["floor_mm"].as_f64().unwrap() + 1.0;
    let cell = fixed["cell_mm"].as_f64().unwrap();
    let cloud = vertices(&dir.path().join("rig/cloud.ply"));
    let model = vertices(&dir.path().join("rig/scan.ply"));
    let d = scan.distance_to_platform();
    let stats = |errors: &mut Vec<f64>| {
        errors.sort_by(f64::total_cmp);
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        (mean, errors[errors.len() * 99 / 100])
    };
    let mut cloud_errors: Vec<f64> = cloud
        .iter()
        .filter(|p| p.z > floor + 2.0)
        .map(|p| scan.distance(p))
        .collect();
    let (cloud_mean, cloud_p99) = stats(&mut cloud_errors);
    // the model where the laser saw the surface: within a cell of a point of the cloud (the
    // rest closes what the camera never saw: the ball's underside, between the objects)
    let tree = scanner_merge::spatial::tree(&cloud);
    let (mut seen, mut closed) = (Vec::new(), 0usize);
    for p in model.iter().filter(|p| p.z > floor + 2.0) {
        let near = tree.nearest_one::<kiddo::SquaredEuclidean>(&[p.x, p.y, p.z]);
        if near.distance <= cell * cell {
            seen.push(scan.distance(p));
        } else {
            closed += 1;
        }
    }
    let (seen_mean, seen_p99) = stats(&mut seen);
    let pc = |mm: f64| 100.0 * mm / d;
    eprintln!(
        "D {d:.0} mm; cloud ({} points): mean {cloud_mean:.4} mm ({:.4} % of D), p99 {cloud_p99:.3} mm; model where seen ({} vertices): mean {seen_mean:.4} mm ({:.4} %), p99 {seen_p99:.3} mm; {closed} vertices close unseen surface",
        cloud_errors.len(),
        pc(cloud_mean),
        seen.len(),
        pc(seen_mean),
    );
    assert!(cloud_errors.len() > 5_000 && seen.len() > 5_000);
    assert!(
        pc(cloud_mean) <= 0.03,
        "cloud mean {cloud_mean} mm at {d} mm"
    );
    assert!(pc(seen_mean) <= 0.03, "model mean {seen_mean} mm at {d} mm");
}

/// The vertices of a PLY the host wrote, back in the platform's frame (written y up).
fn vertices(path: &std::path::Path) -> Vec<scanner_core::nalgebra::Point3<f64>> {
    scanner_tests::read_ply(&std::fs::read(path).unwrap())
        .0
        .iter()
        .map(|v| {
            scanner_core::nalgebra::Point3::new(f64::from(v[0]), -f64::from(v[2]), f64::from(v[1]))
        })
        .collect()
}
