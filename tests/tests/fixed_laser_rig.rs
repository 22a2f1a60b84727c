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
    scanner_tests::write_turning_frames(&scan, &frames);
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

/// A green laser on the rig's turntable (25 frames a turn): its colour is found from the
/// first frame and read with; a brighter one whose core the camera clips white (its light
/// spills into red and blue, as a webcam's colour processing makes it) is found green and
/// saturated, and read as whichever of green and brightness finds the line on more lines (as
/// many points as the better of the two given); a red laser given for green frames is refused.
#[test]
fn a_green_lasers_colour_is_found_and_a_clipped_one_read_by_brightness() {
    let (device, host) = (
        workspace_bin("scanner-device"),
        workspace_bin("scanner-host"),
    );
    for (name, colour, power, clipped) in [
        ("green", [0.03, 1.0, 0.05], 0.15, false),
        ("clipped", [0.35, 1.0, 0.4], 1.5, true),
    ] {
        let mut scan = scanner_rig::TurningScan::demo(640, 480);
        scan.frames = 26;
        scan.turn = std::f64::consts::TAU / 25.0;
        scan.scene.laser.colour = colour;
        scan.scene.laser.power = power;
        let dir = tempfile::tempdir().unwrap();
        scanner_tests::write_turning_frames(&scan, &dir.path().join("frames"));
        scan.truth_calibration()
            .save(&dir.path().join("cal.toml"))
            .unwrap();
        let args = |extra: &[&'static str]| {
            let mut a = vec![
                "scan",
                "--source",
                "frames",
                "--calibration",
                "cal.toml",
                "--fixed-laser",
                "0",
                "--frames-per-turn",
                "25",
                "--rows",
                "--out",
                "s.stream",
                "--report",
                "r.json",
                "-q",
            ];
            a.extend_from_slice(extra);
            a
        };
        let (ok, _, err) = run_in(&device, dir.path(), &args(&[]));
        assert!(ok, "{name}: {err}");
        let r = json(&dir.path().join("r.json"));
        println!(
            "{name}: seen {}, read as {}, {} points",
            r["laser_colour_seen"], r["laser_colour"], r["points"]
        );
        assert_eq!(r["laser_colour_seen"]["colour"], "green", "{name}: {r}");
        assert_eq!(r["laser_colour_seen"]["saturated"], clipped, "{name}: {r}");
        assert_eq!(r["laser_colour_found"], true, "{name}");
        let points = r["points"].as_u64().unwrap();
        // the colour read finds the line as well as the better of green and brightness
        let mut best = 0;
        for colour in ["green", "white"] {
            let (ok, _, err) = run_in(&device, dir.path(), &args(&["--laser", colour]));
            assert!(ok, "{name} --laser {colour}: {err}");
            let given = json(&dir.path().join("r.json"));
            assert_eq!(given["laser_colour_found"], false);
            println!("{name} --laser {colour}: {} points", given["points"]);
            best = best.max(given["points"].as_u64().unwrap());
        }
        if !clipped {
            assert_eq!(r["laser_colour"], "green", "{name}");
        }
        assert!(
            points > 1_000 && points as f64 >= 0.9 * best as f64,
            "{name}: {points} points read as {}, {best} the better of green and white",
            r["laser_colour"]
        );
        // the report of the scan found (the runs above rewrote it)
        let (ok, _, err) = run_in(&device, dir.path(), &args(&[]));
        assert!(ok, "{name}: {err}");
        let (ok, _, err) = run_in(
            &host,
            dir.path(),
            &["receive", "s.stream", "--out", "model", "-q"],
        );
        assert!(ok, "{name}: {err}");
        let fixed = &json(&dir.path().join("model/summary.json"))["fixed"];
        assert_eq!(fixed["watertight"], true, "{name}: {fixed}");
        // red given for a green line: refused, naming both
        let (ok, _, err) = run_in(&device, dir.path(), &args(&["--laser", "red"]));
        assert!(!ok, "{name}");
        assert!(
            scanner_tests::error_kinds(&err)
                .iter()
                .any(|k| k.contains("Colour")),
            "{name}: {err}"
        );
    }
}

/// A platform carrying four ArUco markers (DICT_4X4_50, 20 mm, 50 mm from the axis) in a lit
/// room, seen from 30° above, 50 frames a turn, the motor slipping 2° at frame 20: scanned with
/// `--markers` and no step count, each frame's turn on the wire lies within 0.1° of the truth,
/// the slip is reported at its frame, and the model is as close to the true surfaces as a scan
/// whose turns were known; the same frames taken at steady steps build the slip into the model.
#[test]
fn a_platforms_markers_give_each_frames_turn_and_report_a_slip() {
    let markers = scanner_rig::PlatformMarkers {
        dictionary: scanner_calib::aruco::Dictionary::named("DICT_4X4_50").unwrap(),
        ids: vec![0, 1, 2, 3],
        side: 20.0,
        radius: 50.0,
    };
    let mut scan = scanner_rig::TurningScan::demo(640, 480).with_markers(&markers, 40.0);
    scan.frames = 51;
    scan.turn = std::f64::consts::TAU / 50.0;
    let slip = 2f64.to_radians();
    scan.slips = vec![(20, slip)];
    let dir = tempfile::tempdir().unwrap();
    scanner_tests::write_turning_frames(&scan, &dir.path().join("frames"));
    scan.truth_calibration()
        .save(&dir.path().join("cal.toml"))
        .unwrap();
    let (device, host) = (
        workspace_bin("scanner-device"),
        workspace_bin("scanner-host"),
    );
    let scan_with = |turn: &[&str], out: &str| {
        let mut a = vec![
            "scan",
            "--source",
            "frames",
            "--calibration",
            "cal.toml",
            "--fixed-laser",
            "0",
            "--rows",
            "--laser",
            "red",
            "--out",
        ];
        let stream = format!("{out}.stream");
        let report = format!("{out}.json");
        a.extend([stream.as_str(), "--report", report.as_str(), "-q"]);
        a.extend_from_slice(turn);
        let (ok, _, err) = run_in(&device, dir.path(), &a);
        assert!(ok, "{out}: {err}");
        let (ok, _, err) = run_in(
            &host,
            dir.path(),
            &["receive", stream.as_str(), "--out", out, "-q"],
        );
        assert!(ok, "{out}: {err}");
        (
            json(&dir.path().join(report)),
            json(&dir.path().join(out).join("summary.json"))["fixed"].clone(),
        )
    };
    let (report, fixed) = scan_with(&["--markers", "DICT_4X4_50"], "markers");
    let m = &report["markers"];
    eprintln!("markers: {m}\nmodel: {fixed}");
    // every frame's turn measured, the slip reported at its frame and no other
    assert_eq!(m["frames"], 51, "{m}");
    assert_eq!(m["missed"].as_array().unwrap().len(), 0, "{m}");
    let unsteady = m["unsteady"].as_array().unwrap();
    assert_eq!(unsteady.len(), 1, "{m}");
    assert_eq!(unsteady[0]["frame"], 20);
    assert!(
        (unsteady[0]["deg"].as_f64().unwrap() - 2.0).abs() < 0.2,
        "{m}"
    );
    assert!((m["step_deg"].as_f64().unwrap() - 7.2).abs() < 0.05, "{m}");
    // each frame's turn on the wire against the truth
    let bytes = std::fs::read(dir.path().join("markers.stream")).unwrap();
    let mut decoder = Box::new(scanner_wire::Decoder::<{ scanner_wire::MAX_ENCODED }>::new());
    let mut turns = Vec::new();
    decoder.feed(&bytes, |m| {
        if let Ok(scanner_wire::Message::Turn(t)) = m {
            turns.push(t);
        }
    });
    assert_eq!(turns.len(), 51);
    let worst = turns
        .iter()
        .map(|t| (t.angle - scan.angle(t.frame as usize)).to_degrees().abs())
        .fold(0.0, f64::max);
    eprintln!("turns: worst {worst:.4}° from the truth");
    assert!(worst <= 0.1, "a frame's turn {worst}° from the truth");
    assert_eq!(fixed["turns_measured"], true);
    assert_eq!(fixed["frames_without_turn"], 0);
    assert_eq!(fixed["watertight"], true);
    // the model against the true surfaces where the laser saw them (within a millimetre of a
    // point), with the turns measured and with steady steps: the median (the lit room leaves a
    // few per cent of the points off the laser in both)
    let d = scan.distance_to_platform();
    let seen_median = |name: &str| {
        let model = vertices(&dir.path().join(name).join("scan.ply"));
        let cloud = vertices(&dir.path().join(name).join("cloud.ply"));
        let tree = scanner_merge::spatial::tree(&cloud);
        let mut errors: Vec<f64> = model
            .iter()
            .filter(|p| p.z > 3.0)
            .filter(|p| {
                tree.nearest_one::<kiddo::SquaredEuclidean>(&[p.x, p.y, p.z])
                    .distance
                    <= 1.0
            })
            .map(|p| scan.distance(p))
            .collect();
        assert!(errors.len() > 1_000, "{name}: {} vertices", errors.len());
        errors.sort_by(f64::total_cmp);
        eprintln!(
            "{name}: the model where seen, mean {:.4} mm, median {:.4} mm",
            errors.iter().sum::<f64>() / errors.len() as f64,
            errors[errors.len() / 2]
        );
        errors[errors.len() / 2]
    };
    let measured = seen_median("markers");
    let (_, steady_fixed) = scan_with(&["--frames-per-turn", "50"], "steady");
    assert_eq!(steady_fixed["turns_measured"], false);
    let steady = seen_median("steady");
    eprintln!(
        "model where seen, median: {measured:.4} mm ({:.4} % of D) with the markers' turns, {steady:.4} mm with steady steps",
        100.0 * measured / d
    );
    assert!(100.0 * measured / d <= 0.02, "{measured} mm at {d} mm");
    assert!(
        steady > 2.0 * measured,
        "steady steps {steady} mm, markers {measured} mm"
    );
}
