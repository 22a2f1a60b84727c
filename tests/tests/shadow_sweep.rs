//! Lines of any width and shadow sweeps on rendered frames, through the binaries, each cloud and
//! model against the rig's truth (the distance of every point to the nearest true surface):
//! - the demo's sphere and cylinder (640×480), swept by a narrow laser and by a rod's shadow
//!   from a 6 mm bulb (`scan --shadow`) — the scene the shadow's edges were developed on;
//! - a box and a tilted plate seen closer (f = 1800 px), swept by a narrow laser, a laser line
//!   about 40 px wide (flat-topped and saturated) and the shadow — kept out of the shadow's
//!   development (the wide line's border check was developed on it).
//!
//! Figures printed with `-- --nocapture`; the bounds are the measured figures with a margin.

use std::path::Path;

use scanner_core::nalgebra::Point3;
use scanner_rig::{Rig, Scene};
use scanner_tests::{run_in, scan_rig, workspace_bin};
use scanner_wire::{Decoder, MAX_ENCODED, Message, points};

/// 640×480, 120 frames, the demo's objects.
const DEMO: &str = "width = 640\nheight = 480\n\n[laser]\nframes = 120\n";

/// A box and a tilted plate, seen closer, 120 frames.
const FLAT: &str = "width = 640\nheight = 480\n\n[camera]\nfx = 1800.0\nfy = 1800.0\n\n\
    [[objects]]\nshape = \"box\"\ncentre = [-40.0, 10.0, 600.0]\nsize = [50.0, 70.0, 40.0]\nyaw_deg = 35.0\n\n\
    [[objects]]\nshape = \"plane\"\ncentre = [45.0, 0.0, 620.0]\nsize = [50.0, 80.0]\ntilt_x_deg = 25.0\ntilt_y_deg = -30.0\n\n\
    [laser]\nframes = 120\nsweep = [-70.0, 70.0]\n";

/// What a scan's cloud and model are against the truth.
#[derive(Debug)]
#[allow(dead_code)] // read through Debug
struct Figures {
    /// Points sent, and their packets (a shadow sends two per frame: one per edge).
    points: usize,
    packets: usize,
    /// Packets with an odd number (a shadow's falling edge).
    odd_packets: usize,
    /// Median, mean and 99th percentile of the points' errors, mm.
    median: f64,
    mean: f64,
    p99: f64,
    /// The points' mean error as a share of their distance from the camera, %.
    mean_of_distance_pct: f64,
    /// The host's model (camera frame): vertices and the mean and 99th percentile of their
    /// errors, mm.
    vertices: usize,
    model_mean: f64,
    model_p99: f64,
}

/// Median, mean and 99th percentile of `errs` (sorted here).
fn stats(errs: &mut [f64]) -> (f64, f64, f64) {
    errs.sort_by(f64::total_cmp);
    let n = errs.len().max(1);
    let at = |q: usize| {
        errs.get((n * q / 100).min(n - 1))
            .copied()
            .unwrap_or(f64::NAN)
    };
    (at(50), errs.iter().sum::<f64>() / n as f64, at(99))
}

/// Every point of a stream, its packets and its odd-numbered packets.
fn cloud(stream: &Path) -> (Vec<Point3<f64>>, usize, usize) {
    let bytes = std::fs::read(stream).unwrap();
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    let (mut pts, mut packets, mut odd) = (Vec::new(), 0, 0);
    d.feed(&bytes, |m| {
        if let Ok(Message::Points(p)) = m {
            packets += 1;
            odd += (p.frame % 2) as usize;
            points::decode(p.xyz, p.count as usize, |q| {
                pts.push(Point3::from(q.map(points::dequantise)).cast::<f64>());
            })
            .unwrap();
        }
    });
    (pts, packets, odd)
}

/// Scans `scene` with `args` in `dir/name`, receives it and measures the cloud and the model.
fn scan(dir: &Path, scene: &str, args: &[&str], name: &str) -> Figures {
    let sub = dir.join(name);
    std::fs::create_dir_all(&sub).unwrap();
    scan_rig(&sub, scene, args, "scan.stream");
    let rig = Rig::new(Scene::from_toml_in(scene, &sub).unwrap()).unwrap();
    let (pts, packets, odd_packets) = cloud(&sub.join("scan.stream"));
    let mut errs: Vec<f64> = pts.iter().map(|p| rig.surface_distance(p)).collect();
    let mean_of_distance_pct = 100.0
        * errs
            .iter()
            .zip(&pts)
            .map(|(e, p)| e / p.coords.norm())
            .sum::<f64>()
        / errs.len().max(1) as f64;
    let (median, mean, p99) = stats(&mut errs);
    let (ok, _, err) = run_in(
        &workspace_bin("scanner-host"),
        &sub,
        &[
            "receive",
            "scan.stream",
            "--frame",
            "camera",
            "--out",
            "model",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let ply = std::fs::read(sub.join("model/scan.ply")).unwrap();
    let (vertices, _, _) = scanner_tests::read_ply(&ply);
    let mut model: Vec<f64> = vertices
        .iter()
        .map(|v| rig.surface_distance(&Point3::new(v[0], v[1], v[2]).cast::<f64>()))
        .collect();
    let (_, model_mean, model_p99) = stats(&mut model);
    let f = Figures {
        points: errs.len(),
        packets,
        odd_packets,
        median,
        mean,
        p99,
        mean_of_distance_pct,
        vertices: model.len(),
        model_mean,
        model_p99,
    };
    println!("{name}: {f:?}");
    f
}

#[test]
fn a_shadow_sweep_measures_the_objects_through_the_binaries() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let narrow = scan(d, DEMO, &[], "narrow");
    let shadow = scan(d, &format!("{DEMO}\n[shadow]\n"), &["--shadow"], "shadow");
    // two packets a frame, one per edge, and both edges give points
    assert!(
        shadow.packets > 200 && shadow.odd_packets > 100,
        "{shadow:?}"
    );
    assert!(shadow.points > narrow.points, "{shadow:?} {narrow:?}");
    assert!(shadow.vertices > narrow.vertices, "{shadow:?} {narrow:?}");
    // measured: cloud mean 0.135 mm, p99 0.65 mm (the narrow laser's 0.075 and 0.30): 1.8× and
    // 2.2× the narrow laser's, short of the 1.5× target; the model 0.12 and 0.80 mm
    assert!(shadow.mean < 0.2 && shadow.p99 < 1.0, "{shadow:?}");
    assert!(
        shadow.model_mean < 0.2 && shadow.model_p99 < 1.2,
        "{shadow:?}"
    );
    assert!(shadow.mean < 2.5 * narrow.mean, "{shadow:?} {narrow:?}");
}

/// The same sweep read through time (`--shadow --temporal`): one point per pixel and edge,
/// the band's way found from the frames, the cloud and the model against the truth, and the
/// report's coverage of the object.
#[test]
fn a_shadow_sweep_read_through_time_measures_the_objects() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let scene = format!("{DEMO}\n[shadow]\n");
    let frame_by_frame = scan(d, &scene, &["--shadow"], "frames");
    let through_time = scan(
        d,
        &scene,
        &["--shadow", "--temporal", "--report", "../temporal.json"],
        "temporal",
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("temporal.json")).unwrap()).unwrap();
    let r = &report["temporal"];
    println!("{}", serde_json::to_string(r).unwrap());
    // the rig's rod sweeps its shadow up and down: edges placed along columns
    assert_eq!(r["along"], "columns", "{r}");
    // measured: 98.9 % of the objects' pixels with a point, 5.8 times the frame-by-frame
    // reading's points (one a pixel); the two edges 0.21 mm apart on the objects (median),
    // 0.32 mm on the board
    assert!(
        through_time.points > 4 * frame_by_frame.points,
        "{through_time:?}"
    );
    assert!(r["coverage"].as_f64().unwrap() > 0.95, "{r}");
    assert!(r["edges_apart_mm"][0].as_f64().unwrap() < 0.4, "{r}");
    // a pixel's point is the middle of its two edges' points: most pixels have both
    let both = r["points_both"].as_u64().unwrap();
    let one = r["points_one_edge"][0].as_u64().unwrap() + r["points_one_edge"][1].as_u64().unwrap();
    assert!(both > 5 * one, "{r}");
    assert_eq!(both + one, through_time.points as u64, "{r}");
    // measured: cloud mean 0.25 mm, p99 1.52 mm, the model 0.20 and 1.50 mm (each edge's own
    // points: 0.30 and 1.59 mm), where the frame-by-frame reading's (object points only, run
    // ends dropped) are 0.135 and 0.65 mm: every pixel's point is kept, those across the
    // objects' outlines too
    assert!(
        through_time.mean < 0.32 && through_time.p99 < 2.0,
        "{through_time:?}"
    );
    // measured: 0.039 % of the points' distance from the camera (the target: 0.05 %)
    assert!(through_time.mean_of_distance_pct < 0.05, "{through_time:?}");
    assert!(
        through_time.model_mean < 0.3 && through_time.model_p99 < 2.0,
        "{through_time:?}"
    );
    // crossings that agree are kept; those that do not are counted
    assert!(r["crossed_agreeing"][0].as_u64().unwrap() > 10_000, "{r}");
}

/// A hand sweep that goes back over part of the scene: the demo's frames written to a folder
/// in the order 0…70, 69…45, 46…119, read through time, against the same frames in order.
/// The pixels the rod crossed again are kept where their crossings agree (the same planes place
/// them), and the cloud stays as near the truth as the straight sweep's.
#[test]
fn a_sweep_whose_rod_goes_back_keeps_the_crossings_that_agree() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let scene = format!("{DEMO}\n[shadow]\n");
    let rig = Rig::new(Scene::from_toml_in(&scene, d).unwrap()).unwrap();
    rig.truth_calibration().save(&d.join("cal.toml")).unwrap();
    let frames: Vec<_> = (0..120)
        .map(|k| rig.frame(k).unwrap().to_gray_image())
        .collect();
    let sweep = |name: &str, order: &[usize]| {
        std::fs::create_dir(d.join(name)).unwrap();
        for (n, &k) in order.iter().enumerate() {
            frames[k]
                .save(d.join(format!("{name}/f{n:03}.png")))
                .unwrap();
        }
        let source = format!("dir:{name}");
        let (stream, json) = (format!("{name}.stream"), format!("{name}.json"));
        let (ok, err) = device(
            d,
            &[
                "scan",
                "--source",
                &source,
                "--calibration",
                "cal.toml",
                "--shadow",
                "--temporal",
                "--out",
                &stream,
                "--report",
                &json,
                "-q",
            ],
        );
        assert!(ok, "{err}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(&json)).unwrap()).unwrap();
        let r = report["temporal"].clone();
        assert_eq!(r["frames"], order.len(), "{r}");
        let (pts, ..) = cloud(&d.join(&stream));
        let mut errs: Vec<f64> = pts.iter().map(|p| rig.surface_distance(p)).collect();
        let (median, mean, p99) = stats(&mut errs);
        println!(
            "{name}: {} points, median {median:.3} mean {mean:.3} p99 {p99:.3} mm\n{r}",
            pts.len()
        );
        (r, mean, p99)
    };
    let straight = sweep("straight", &(0..120).collect::<Vec<_>>());
    let order: Vec<usize> = (0..=70).chain((45..=69).rev()).chain(46..120).collect();
    let back = sweep("back", &order);
    // measured: 15.5 k and 14.7 k more pixels crossed again by each edge with crossings that
    // agree, 0.3 k and 0.2 k more that disagree (left out)
    let n = |r: &serde_json::Value, k: &str, i: usize| r[k][i].as_u64().unwrap();
    for k in 0..2 {
        let agreeing = n(&back.0, "crossed_agreeing", k) - n(&straight.0, "crossed_agreeing", k);
        let refused =
            n(&back.0, "crossed_again", k).saturating_sub(n(&straight.0, "crossed_again", k));
        assert!(
            agreeing > 10_000 && agreeing > 10 * refused,
            "{} {}",
            back.0,
            straight.0
        );
    }
    assert!(back.0["coverage"].as_f64().unwrap() > 0.95, "{}", back.0);
    // measured: both clouds a mean 0.25 mm from the truth, p99 1.5 mm
    assert!(
        back.1 < straight.1 * 1.1 + 0.02 && back.2 < 2.0,
        "{back:?} {straight:?}"
    );
}

#[test]
fn a_wide_line_and_a_shadow_on_a_scene_kept_out_of_the_shadows_development() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let narrow = scan(d, FLAT, &[], "narrow");
    // σ 3.5 mm at f = 1800 px, saturated: a flat-topped band about 40 px wide
    let wide = scan(
        d,
        &format!("{FLAT}sigma_mm = 3.5\npower = 40.0\n"),
        &[],
        "wide",
    );
    let shadow = scan(d, &format!("{FLAT}\n[shadow]\n"), &["--shadow"], "shadow");
    for f in [&narrow, &wide, &shadow] {
        assert!(f.points > 5000 && f.vertices > 2000, "{f:?}");
    }
    // measured: the narrow laser's median 0.037 mm (mean 0.084, p99 1.33); the wide line's
    // median 0.40 mm, mean 3.7 mm, p99 24 mm — a band 40 px wide straddles the box's edges and
    // the plate's border over its own width, and where one of its sides is cut off the centre
    // of what is left is not the sheet's (the 1.5× target is not met); the shadow's median
    // 0.24 mm, mean 0.35 mm, p99 2.9 mm (4.2× the narrow laser's mean)
    assert!(wide.median < 0.6 && wide.model_mean < 4.5, "{wide:?}");
    assert!(
        shadow.median < 0.35 && shadow.mean < 0.5 && shadow.p99 < 4.0,
        "{shadow:?}"
    );
}

/// `scanner-device scan` in `dir` with `args`: its exit and standard error.
fn device(dir: &Path, args: &[&str]) -> (bool, String) {
    let (ok, _, err) = run_in(&workspace_bin("scanner-device"), dir, args);
    (ok, err)
}

#[test]
fn a_shadow_in_the_shadow_free_frame_a_band_beyond_the_limit_and_a_blurred_shadow_are_refused() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let short = DEMO.replace("frames = 120", "frames = 16");
    // a folder of a shadow sweep's frames, with one of them given as the shadow-free frame
    let scene = format!("{short}\n[shadow]\n");
    let rig = Rig::new(Scene::from_toml_in(&scene, d).unwrap()).unwrap();
    rig.truth_calibration().save(&d.join("cal.toml")).unwrap();
    std::fs::create_dir(d.join("sweep")).unwrap();
    for k in 0..16 {
        let name = d.join(format!("sweep/f{k:02}.png"));
        rig.frame(k).unwrap().to_gray_image().save(name).unwrap();
    }
    let common = ["scan", "--calibration", "cal.toml", "--columns", "-q"];
    let (ok, err) = device(
        d,
        &[
            &common[..],
            &[
                "--source",
                "dir:sweep",
                "--shadow",
                "--reference",
                "sweep/f08.png",
            ],
            &["--out", "held.stream"],
        ]
        .concat(),
    );
    assert!(
        !ok && scanner_tests::has_kind(&err, "ShadowInReference"),
        "{err}"
    );
    // the same folder read twice (its brightest and darkest) scans
    let (ok, err) = device(
        d,
        &[
            &common[..],
            &[
                "--source",
                "dir:sweep",
                "--shadow",
                "--out",
                "folder.stream",
            ],
        ]
        .concat(),
    );
    assert!(ok, "{err}");
    // a scene of the rig written to `name.toml` and scanned with `extra`
    let rig_scan = |name: &str, scene: String, extra: &[&str]| {
        let file = format!("{name}.toml");
        let out = format!("{name}.stream");
        std::fs::write(d.join(&file), scene).unwrap();
        let args = ["--source", "rig", "--scene", &file, "--out", &out];
        device(d, &[&common[..], &args, extra].concat())
    };
    // a laser line 150 px wide in a 640 px image: beyond the limit of 64 px
    let (ok, err) = rig_scan(
        "wide",
        format!("{short}sigma_mm = 45.0\npower = 40.0\n"),
        &[],
    );
    assert!(!ok && scanner_tests::has_kind(&err, "TooWide"), "{err}");
    // a bulb 80 mm across, 250 mm behind an 8 mm rod: the rod never hides all of it
    let scene = format!("{short}\n[shadow]\nlamp_radius_mm = 40.0\n");
    let (ok, err) = rig_scan("blur", scene, &["--shadow"]);
    assert!(!ok && scanner_tests::has_kind(&err, "FaintShadow"), "{err}");
}

/// Shadow sweeps of the bunny from three sides (the 360° demo's views 0, 1 and 6 at 640×480:
/// turned 60°, then laid on its side), each through the binaries, merged by their shapes into
/// one closed model: the model watertight (what no view saw closed by the points' winding
/// number), every view's rotation against the rig's.
#[test]
fn shadow_sweeps_from_three_sides_merge_into_a_watertight_model() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scanner-device/scenes");
    let text = std::fs::read_to_string(scenes.join("bunny-360.toml"))
        .unwrap()
        .replace("width = 1280", "width = 640")
        .replace("height = 960", "height = 480")
        .replace("frames = 300", "frames = 200")
        .replace(
            "path = \"bunny.obj\"",
            &format!(
                "path = {:?}",
                scenes.join("bunny.obj").display().to_string()
            ),
        )
        + "\n[shadow]\n";
    std::fs::write(d.join("s.toml"), &text).unwrap();
    let scene = scanner_device::cli::render::load_scene(Some(&d.join("s.toml"))).unwrap();
    Rig::new(scene.clone())
        .unwrap()
        .truth_calibration()
        .save(&d.join("cal.toml"))
        .unwrap();
    for k in ["0", "1", "6"] {
        scanner_tests::scan_rig_view(d, k, &["--shadow"], &[]);
    }
    let (ok, out, err) = run_in(
        &workspace_bin("scanner-host"),
        d,
        &["merge", "v0", "v1", "v6", "--out", "model", "-q"],
    );
    println!("{out}");
    assert!(ok, "{err}");
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("model/merge-report.json")).unwrap()).unwrap();
    assert_eq!(r["fusion"]["check"]["watertight"], true, "{r}");
    // every view's rotation within 0.25° of the rig's: 0.002° and 0.092° off in one run (the
    // laser's sweeps of the same views in tests/merge.rs: 0.030° and 0.018°); at 150 frames the
    // side view was 0.21° off
    for (k, view) in [(1, 1), (2, 6)] {
        let found = r["views"][k]["rotation_deg"].as_f64().unwrap();
        let truth = (scene.view(0).unwrap().object_pose
            * scene.view(view).unwrap().object_pose.inverse())
        .rotation
        .angle()
        .to_degrees();
        assert!(
            (found - truth).abs() < 0.25,
            "view {view}: {found}° found, {truth}° true"
        );
    }
}
