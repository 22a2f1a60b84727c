//! The 360° merge on the turntable disc, through the binaries: a small part standing on the
//! printed disc (`scanner-device/scenes/turntable.toml` at 640×480, the A3 disc), six hand turns
//! of uneven steps scanned with `scan --disc a3`, one view with the disc taken away and the part laid
//! on its side. The head finds the disc in each sweep's reference and sends its pose; the merge
//! poses those views by it, registers the side view by its shape onto them, and the report says
//! which was which. The rig's true calibration is used (calibration from images is tested
//! elsewhere).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use scanner_core::nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use scanner_tests::{json, run_in, workspace_bin};
use serde_json::Value;

struct Fixture {
    dir: PathBuf,
    scene: scanner_rig::Scene,
    /// Per view, the laser's true points on the object (not the disc) in view 0's frame, every
    /// other frame: what the view saw. Found once.
    seen: OnceLock<Vec<Vec<scanner_core::nalgebra::Point3<f64>>>>,
}

impl Fixture {
    fn seen(&self) -> &[Vec<scanner_core::nalgebra::Point3<f64>>] {
        self.seen.get_or_init(|| {
            let disc = self.scene.turntable.as_ref().unwrap().object as u16;
            let v0 = self.scene.view(0).unwrap();
            (0..self.scene.view_count())
                .map(|k| {
                    let v = self.scene.view(k).unwrap();
                    let into_view0 = v0.object_pose * v.object_pose.inverse();
                    let rig = scanner_rig::Rig::new(v).unwrap();
                    (0..rig.scene().laser.frames)
                        .step_by(2)
                        .flat_map(|fr| rig.truth(fr).unwrap())
                        .flatten()
                        .filter(|t| {
                            matches!(t.surface, scanner_rig::SurfaceId::Object(n)
                                if n != disc && !self.scene.fixed.contains(&usize::from(n)))
                        })
                        .map(|t| into_view0 * t.point)
                        .collect()
                })
                .collect()
        })
    }
}

/// The scene at 640×480 with 160 frames per sweep, every view scanned once and received.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("turntable");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scanner-device/scenes/turntable.toml"
        );
        let text = std::fs::read_to_string(path)
            .unwrap()
            .replace("width = 1280", "width = 640")
            .replace("height = 960", "height = 480")
            .replace("frames = 300", "frames = 160")
            // At 640×480 the A4 disc's dots are 4 px across and its pose 0.02–0.04° off; the
            // A3 disc's within 0.007° (`scanner-calib`'s disc test).
            .replace("paper = \"a4\"", "paper = \"a3\"");
        scan_views(dir, &text, false)
    })
}

/// A view's pose in view 0's frame from the report.
fn pose(v: &Value) -> Isometry3<f64> {
    let q: Vec<f64> = v["rotation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let t: Vec<f64> = v["translation_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    Isometry3::from_parts(
        Translation3::from(Vector3::new(t[0], t[1], t[2])),
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

#[test]
fn views_on_the_disc_are_posed_by_it_and_the_side_view_by_its_shape() {
    let f = fixture();
    let (ok, err, r) = merge_in(f, &[], "model");
    assert!(ok, "{err}");
    let disc = r["disc"].as_array().expect("the report's disc section");
    assert_eq!(disc.len(), 7);
    for (k, v) in disc.iter().enumerate() {
        assert_eq!(v["by_disc"].as_bool(), Some(k < 6), "view {k}");
    }
    let e = pose_errors(f, &r);
    for (k, (deg, mm)) in e.iter().enumerate() {
        println!("view {k}: {deg:.4}° {mm:.3} mm from the rig's pose");
    }
    // The targets, 0.05° and 0.05 % of the 800 mm camera–board distance, for the views
    // the disc posed; the side view's pose rests on its points (660 here, mostly round faces
    // that slide along one another): held to 0.5° and 3 mm.
    for (k, &(deg, mm)) in e.iter().enumerate() {
        let (max_deg, max_mm) = if k < 6 { (0.05, 0.4) } else { (0.5, 3.0) };
        assert!(deg < max_deg && mm < max_mm, "view {k}: {deg}° {mm} mm");
    }
    let check = &r["fusion"]["check"];
    assert_eq!(check["watertight"].as_bool(), Some(true), "{check}");
    // The part's true volume, its three solids apart (they only touch).
    let truth: f64 = f.scene.objects[1..]
        .iter()
        .map(|o| match &o.shape {
            scanner_rig::Shape::Cuboid { half, .. } => 8.0 * half.x * half.y * half.z,
            scanner_rig::Shape::Cylinder { radius, height, .. } => {
                std::f64::consts::PI * radius * radius * height
            }
            scanner_rig::Shape::Sphere { radius, .. } => {
                4.0 / 3.0 * std::f64::consts::PI * radius.powi(3)
            }
            other => panic!("not in the part: {other:?}"),
        })
        .sum();
    let volume = check["volume_mm3"].as_f64().unwrap();
    println!("volume {volume:.0} mm³, the part's {truth:.0} mm³");
    assert!(
        (volume / truth - 1.0).abs() < 0.1,
        "{volume} against {truth}"
    );
}

/// The wire stream `from` with every disc message replaced by the first of `disc_of` (its scan
/// id made `from`'s).
fn with_disc_of(from: &[u8], disc_of: &[u8]) -> Vec<u8> {
    use scanner_wire::{Decoder, MAX_ENCODED, MAX_MESSAGE, Message, encode};
    let mut found = None;
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    d.feed(disc_of, |m| {
        if let Ok(Message::Disc(p)) = m {
            found.get_or_insert(p);
        }
    });
    let disc = found.expect("a disc message");
    let (mut out, mut scratch, mut buf) = (Vec::new(), vec![0; MAX_MESSAGE], vec![0; MAX_ENCODED]);
    let mut d = Box::new(Decoder::<MAX_ENCODED>::new());
    d.feed(from, |m| {
        let Ok(m) = m else { return };
        let m = match m {
            Message::Disc(p) => Message::Disc(scanner_wire::DiscPose {
                scan_id: p.scan_id,
                ..disc
            }),
            other => other,
        };
        let n = encode(&m, &mut scratch, &mut buf).unwrap();
        out.extend_from_slice(&buf[..n]);
    });
    out
}

#[test]
fn a_view_that_moved_on_the_disc_is_refused() {
    // View 2's sweep with view 3's disc pose: as if the object had turned 63° on the disc
    // between the reference frame and the sweep. The merge must refuse and write no model.
    let f = fixture();
    let moved = with_disc_of(
        &std::fs::read(f.dir.join("v2.stream")).unwrap(),
        &std::fs::read(f.dir.join("v3.stream")).unwrap(),
    );
    std::fs::write(f.dir.join("moved.stream"), moved).unwrap();
    let args = [
        "receive",
        "moved.stream",
        "--out",
        "moved",
        "-q",
        "--cell",
        "2px",
    ];
    let (ok, _, err) = run_in(&workspace_bin("scanner-host"), &f.dir, &args);
    assert!(ok, "{err}");
    let args = [
        "merge",
        "v0",
        "v1",
        "moved",
        "v3",
        "v4",
        "v5",
        "--out",
        "model-moved",
        "-q",
    ];
    let (ok, _, err) = run_in(&workspace_bin("scanner-host"), &f.dir, &args);
    assert!(
        !ok,
        "a model was written from a view that moved on the disc"
    );
    let r = json(&f.dir.join("model-moved/merge-report.json"));
    assert_eq!(r["refused"]["check"].as_str(), Some("disc_moved"), "{err}");
    assert!(!f.dir.join("model-moved/model.obj").exists());
}

/// The family's objects (`scanner-device/scenes/family/`), each scanned once for the tests of
/// this binary: 640×480, sparse sweeps of 100 frames, every view with `--disc a3`.
fn family(name: &str) -> std::sync::Arc<Fixture> {
    scanned("family", name, false, |t| {
        t.replace("width = 1280", "width = 640")
            .replace("height = 960", "height = 480")
            .replace("frames = 200", "frames = 100")
    })
}

/// The scene `scanner-device/scenes/{folder}/{name}.toml`, `edit`ed, every view scanned once for
/// the tests of this binary (with `--disc`; `without_disc`: once more without it, into `nd/`).
fn scanned(
    folder: &str,
    name: &str,
    without_disc: bool,
    edit: impl Fn(String) -> String,
) -> std::sync::Arc<Fixture> {
    static DONE: std::sync::Mutex<Vec<(String, std::sync::Arc<Fixture>)>> =
        std::sync::Mutex::new(Vec::new());
    let key = format!("{folder}-{name}");
    let mut done = DONE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if let Some((_, f)) = done.iter().find(|(n, _)| *n == key) {
        return f.clone();
    }
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(&key);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("nd")).unwrap();
    let path = format!(
        "{}/../scanner-device/scenes/{folder}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = edit(std::fs::read_to_string(path).unwrap());
    let f = std::sync::Arc::new(scan_views(dir.clone(), &text, without_disc));
    if without_disc {
        // The same sweeps, the head not told of the disc: every view keeps the disc's and
        // the stand's points. Its frames are the disc scan's, read back from its recording
        // (the rig renders a frame many times slower than the head reads one).
        for k in 0..f.scene.view_count() {
            let (record, stream) = (format!("record:rec{k}"), format!("nd/v{k}.stream"));
            let (ok, _, err) = run_in(
                &workspace_bin("scanner-device"),
                &dir,
                &[
                    "scan",
                    "--source",
                    &record,
                    "--calibration",
                    "cal.toml",
                    "--out",
                    &stream,
                    "-q",
                ],
            );
            assert!(ok, "scan view {k} again: {err}");
            let out = format!("nd/v{k}");
            let (ok, _, err) = run_in(
                &workspace_bin("scanner-host"),
                &dir,
                &["receive", &stream, "--out", &out, "-q", "--cell", "2px"],
            );
            assert!(ok, "receive view {k} again: {err}");
            let _ = std::fs::remove_dir_all(dir.join(format!("rec{k}")));
        }
    }
    done.push((key, f.clone()));
    f
}

/// Writes `text` as the scene, the rig's true calibration beside it, and scans every view
/// (`record`: each view's frames kept in `rec{k}` as well).
fn scan_views(dir: PathBuf, text: &str, record: bool) -> Fixture {
    std::fs::write(dir.join("s.toml"), text).unwrap();
    let scene = scanner_rig::Scene::from_toml_in(text, &dir).unwrap();
    let rig = scanner_rig::Rig::new(scene.clone()).unwrap();
    rig.truth_calibration().save(&dir.join("cal.toml")).unwrap();
    let paper = scene
        .turntable
        .as_ref()
        .map_or("a3", |t| t.disc.paper.name());
    for k in 0..scene.view_count() {
        let k = k.to_string();
        let (report, rec) = (format!("r{k}.json"), format!("rec{k}"));
        let mut head = vec!["--disc", paper, "--report", &report];
        if record {
            head.extend(["--record", &rec]);
        }
        scanner_tests::scan_rig_view(&dir, &k, &head, &["--cell", "2px"]);
        // The head's report says what it found of the disc: the disc in every view on it, none
        // where it was taken away.
        let disc = &json(&dir.join(&report))["disc"];
        let on = !scene
            .turntable
            .as_ref()
            .is_some_and(|t| t.absent_in.contains(&k.parse().unwrap()));
        assert_eq!(disc["found"].as_bool(), Some(on), "view {k}: {disc}");
        if !on {
            assert_eq!(disc["missed"].as_str(), Some("too_few_markers"), "view {k}");
        }
    }
    Fixture {
        dir,
        scene,
        seen: OnceLock::new(),
    }
}

/// `merge v0 … --out OUT EXTRA` in the fixture's folder: success, stderr, the JSON report.
fn merge_in(f: &Fixture, extra: &[&str], out: &str) -> (bool, String, Value) {
    merge_views(f, f.scene.view_count(), extra, out)
}

/// `merge v0 … v{n-1} --out OUT EXTRA`: the first `n` views.
fn merge_views(f: &Fixture, n: usize, extra: &[&str], out: &str) -> (bool, String, Value) {
    let views: Vec<String> = (0..n).map(|k| format!("v{k}")).collect();
    let mut args: Vec<&str> = vec!["merge"];
    args.extend(views.iter().map(String::as_str));
    args.extend_from_slice(&["--out", out, "-q"]);
    args.extend_from_slice(extra);
    let (ok, _, err) = run_in(&workspace_bin("scanner-host"), &f.dir, &args);
    let report = f.dir.join(out).join("merge-report.json");
    let r = if report.exists() {
        json(&report)
    } else {
        Value::Null
    };
    (ok, err, r)
}

/// Each view's rotation (degrees) and the object centre's displacement (mm) from its true pose.
fn pose_errors(f: &Fixture, r: &Value) -> Vec<(f64, f64)> {
    let centre = f.scene.turntable.as_ref().unwrap().pose.translation.vector;
    let c = scanner_core::nalgebra::Point3::from(centre);
    r["views"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let truth = f.scene.views[0] * f.scene.views[k].inverse();
            let d = pose(v).inverse() * truth;
            (d.rotation.angle().to_degrees(), (d * c - c).norm())
        })
        .collect()
}

/// The model of the first `views` views against the truth, % of the camera–board distance: the
/// mean and p99 distance from the true surface of its vertices within 1.5 mm of the seen surface
/// (the laser's true points on the object in those views; `merge.rs` measures so), and the share of the seen surface with no
/// model vertex within 2 mm (two of the fusion's cells: a hole).
fn model_errors(f: &Fixture, out: &str, views: usize) -> (f64, f64, f64) {
    use kiddo::{KdTree, SquaredEuclidean};
    use scanner_core::nalgebra::Point3;
    let (models, _) = tobj::load_obj(
        f.dir.join(out).join("model.obj"),
        &tobj::LoadOptions::default(),
    )
    .expect("the model's OBJ reads back");
    let view0 =
        scanner_host::views::load_view(0, &f.dir.join("v0"), "2px".parse().unwrap(), 0.0).unwrap();
    let scanner_host::mesh::MeshFrame::Board { rotation, origin } =
        scanner_host::mesh::MeshFrame::board(
            &scanner_core::geometry::Board::<f32>::try_from(view0.header.board).unwrap(),
        )
    else {
        panic!("a board frame")
    };
    let to_camera = |p: Point3<f64>| {
        Point3::from(rotation.transpose().cast::<f64>() * p.coords) + origin.coords.cast::<f64>()
    };
    let p = &models[0].mesh.positions;
    let model: Vec<Point3<f64>> = p
        .chunks(3)
        .map(|v| to_camera(Point3::new(v[0], v[1], v[2]).cast()))
        .collect();
    let seen: Vec<Point3<f64>> = f.seen()[..views].concat();
    let v0 = f.scene.view(0).unwrap();
    let tree = |pts: &[Point3<f64>]| {
        let mut t: KdTree<f64, 3> = KdTree::new();
        for (i, q) in pts.iter().enumerate() {
            t.add(&[q.x, q.y, q.z], i as u64);
        }
        t
    };
    let (seen_tree, model_tree) = (tree(&seen), tree(&model));
    let near = |t: &KdTree<f64, 3>, q: &Point3<f64>| {
        t.nearest_one::<SquaredEuclidean>(&[q.x, q.y, q.z])
            .distance
            .sqrt()
    };
    let truth = scanner_rig::Rig::new(v0).unwrap();
    let mut d: Vec<f64> = model
        .iter()
        .filter(|q| near(&seen_tree, q) < 1.5)
        .map(|q| truth.surface_distance(q))
        .collect();
    d.sort_by(f64::total_cmp);
    let missing = seen.iter().filter(|q| near(&model_tree, q) > 2.0).count();
    let pct = |mm: f64| 100.0 * mm / f.scene.board.distance;
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    (
        pct(mean),
        pct(d[(d.len() * 99 / 100).min(d.len() - 1)]),
        100.0 * missing as f64 / seen.len().max(1) as f64,
    )
}

/// With the disc: the six views on it posed to the targets and their model near the
/// truth; with the side view (no disc) as well: placed and the model still near the truth, or
/// refused with advice; without the disc: merged right or refused with advice, never wrong.
fn family_member(name: &str) {
    let f = family(name);
    let (ok, err, r) = merge_views(&f, 6, &[], "model");
    assert!(ok, "{name}: {err}");
    let e = pose_errors(&f, &r);
    for (k, (deg, mm)) in e.iter().enumerate() {
        println!("{name} view {k}: {deg:.4}° {mm:.3} mm from its true pose");
        assert!(*deg < 0.05 && *mm < 0.4, "{name} view {k}: {deg}° {mm} mm");
    }
    assert_eq!(
        r["fusion"]["check"]["watertight"].as_bool(),
        Some(true),
        "{name}"
    );
    let (mean, p99, missing) = model_errors(&f, "model", 6);
    println!(
        "{name}: model mean {mean:.4} %, p99 {p99:.4} % of D; {missing:.2} % of the seen surface missing"
    );
    assert!(
        mean < 0.03 && p99 < 0.15 && missing < 1.0,
        "{name}: {mean} {p99} {missing}"
    );
    let (ok, err, r) = merge_in(&f, &[], "model-side");
    if ok {
        let side = pose_errors(&f, &r)[6];
        let (mean, p99, missing) = model_errors(&f, "model-side", 7);
        println!(
            "{name} with the side view: placed {:.3}° {:.2} mm off; model mean {mean:.4} %, p99 {p99:.4} %, {missing:.2} % missing",
            side.0, side.1
        );
        // Its pose is not the check: a symmetric object laid on its side fits as well turned
        // about its axis, or end over end (the held-out bottle's side view went 112° "off" with
        // its points on the true surface). The model is: a view placed wrong lays its points
        // off the surface.
        assert!(
            mean < 0.05 && p99 < 0.3 && missing < 3.0,
            "{name}: the model with the side view {mean} {p99} {missing}"
        );
    } else {
        println!("{name} with the side view: refused: {err}");
        assert!(err.contains("disc"), "{name}: {err}");
    }
    let (ok, err, r) = merge_in(&f, &["--no-disc"], "model-no-disc");
    if ok {
        let worst = pose_errors(&f, &r).iter().fold(0.0f64, |a, b| a.max(b.0));
        println!("{name} without the disc: merged, worst view {worst:.3}°");
        assert!(
            worst < 1.0,
            "{name}: a wrong model written without the disc ({worst}°)"
        );
    } else {
        println!("{name} without the disc: refused: {err}");
        assert!(
            err.contains("--disc") || r["refused"].is_object(),
            "{name}: {err}"
        );
    }
}

#[test]
fn family_bracket() {
    family_member("bracket");
}

#[test]
fn family_flange_nearly_symmetric() {
    family_member("flange");
}

#[test]
fn family_vase_symmetric() {
    family_member("vase");
}

#[test]
fn family_bottle_held_out() {
    family_member("bottle");
}

#[test]
fn family_gearbox_held_out() {
    family_member("gearbox");
}

/// A scene of `scanner-device/scenes/stand/` (the disc on something wider than it, which stays
/// put), every view scanned once with `--disc` and once without: at 640×480 with the A3 disc,
/// as the family (the scenes' 1280×960 quadruples the rendering; what is tested here is the
/// merge, not the camera's resolution).
fn stand(name: &str) -> std::sync::Arc<Fixture> {
    scanned("stand", name, true, |t| {
        t.replace("width = 1280", "width = 640")
            .replace("height = 960", "height = 480")
            .replace("paper = \"a4\"", "paper = \"a3\"")
    })
}

/// The part's true volume (mm³): every object but the disc and what stays put, by counting
/// samples of a fine grid inside any of them (their overlaps once).
fn part_volume(scene: &scanner_rig::Scene) -> f64 {
    use scanner_core::nalgebra::{Point3, Vector3};
    use scanner_rig::Shape;
    let disc = scene.turntable.as_ref().map(|t| t.object);
    let parts: Vec<&Shape> = (0..scene.objects.len())
        .filter(|&i| Some(i) != disc && !scene.fixed.contains(&i))
        .map(|i| &scene.objects[i].shape)
        .collect();
    let inside = |s: &Shape, p: &Point3<f64>| match s {
        Shape::Sphere { centre, radius } => (p - centre).norm() <= *radius,
        Shape::Cylinder {
            base,
            axis,
            radius,
            height,
        } => {
            let d = p - base;
            let h = d.dot(axis);
            (0.0..=*height).contains(&h) && (d - axis.into_inner() * h).norm() <= *radius
        }
        Shape::Cuboid { centre, half, axes } => {
            let d = p - centre;
            (0..3).all(|k| d.dot(&axes[k]).abs() <= half[k])
        }
        other => panic!("not a solid of the part: {other:?}"),
    };
    let (mut lo, mut hi) = (Point3::from([f64::MAX; 3]), Point3::from([f64::MIN; 3]));
    for s in &parts {
        // a sphere round each solid, about its centre
        let r = match s {
            Shape::Sphere { radius, .. } => *radius,
            Shape::Cylinder { radius, height, .. } => radius + height / 2.0,
            Shape::Cuboid { half, .. } => half.norm(),
            _ => unreachable!("not a solid of the part"),
        };
        let c = s.centre();
        lo = lo.inf(&(c - Vector3::repeat(r)));
        hi = hi.sup(&(c + Vector3::repeat(r)));
    }
    let step = 0.4;
    let n = ((hi - lo) / step).map(|v| v.ceil() as usize);
    let mut count = 0usize;
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let p = lo + Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * step;
                count += usize::from(parts.iter().any(|s| inside(s, &p)));
            }
        }
    }
    count as f64 * step.powi(3)
}

/// The disc on a stand or a table wider than it: every view posed within 0.05° by the disc,
/// the seen surface within 0.03 % of D (mean), under 1 % of it missing, the undersides no view saw
/// filled and the part's true volume between the report's bounds; without the disc, the stand's
/// and the disc's points left out as still and the model right (every view within 1°) or refused,
/// never one that aligns the stand.
fn stand_member(name: &str) {
    let f = stand(name);
    let (ok, err, r) = merge_in(&f, &[], "model");
    assert!(ok, "{name}: {err}");
    let e = pose_errors(&f, &r);
    for (k, (deg, mm)) in e.iter().enumerate() {
        println!("{name} view {k}: {deg:.4}° {mm:.3} mm from its true pose");
        assert!(*deg < 0.05 && *mm < 0.4, "{name} view {k}: {deg}° {mm} mm");
    }
    let fusion = &r["fusion"];
    let (mean, p99, missing) = model_errors(&f, "model", f.scene.view_count());
    let unseen = fusion["unseen_share"].as_f64().unwrap();
    println!(
        "{name}: model mean {mean:.4} %, p99 {p99:.4} % of D; {missing:.2} % of the seen surface missing; {:.1} % of the model unseen",
        100.0 * unseen
    );
    assert_eq!(
        fusion["check"]["watertight"].as_bool(),
        Some(true),
        "{name}"
    );
    assert_eq!(fusion["filled"].as_bool(), Some(true), "{name}");
    assert!(
        mean < 0.03 && missing < 1.0,
        "{name}: {mean} {p99} {missing}"
    );
    let bounds: Vec<f64> = fusion["volume_bounds_mm3"]
        .as_array()
        .expect("the volume's bounds")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let truth = part_volume(&f.scene);
    let volume = fusion["check"]["volume_mm3"].as_f64().unwrap();
    println!(
        "{name}: volume {volume:.0} mm³ (bounds {:.0}–{:.0}), the part's {truth:.0} mm³",
        bounds[0], bounds[1]
    );
    assert!(
        bounds[0] <= truth && truth <= bounds[1],
        "{name}: the part's {truth} mm³ outside {bounds:?}"
    );
    assert!(unseen > 0.0 && unseen < 1.0, "{name}: {unseen}");
    // Without the disc: the views as the head sent them, disc and stand and all.
    let nd = Fixture {
        dir: f.dir.join("nd"),
        scene: f.scene.clone(),
        seen: OnceLock::new(),
    };
    let (ok, err, r) = merge_in(&nd, &[], "model");
    if ok {
        let worst = pose_errors(&nd, &r).iter().fold(0.0f64, |a, b| a.max(b.0));
        let still: Vec<u64> = r["still"]
            .as_array()
            .expect("the still points per view")
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        println!("{name} without the disc: merged, worst view {worst:.3}°; still points {still:?}");
        assert!(
            worst < 1.0,
            "{name}: a wrong model without the disc ({worst}°)"
        );
        assert!(
            still.iter().all(|&n| n > 0),
            "{name}: the stand left in: {still:?}"
        );
    } else {
        println!("{name} without the disc: refused: {err}");
        assert!(
            !nd.dir.join("model/model.obj").exists(),
            "{name}: a model written beside a refusal"
        );
    }
}

#[test]
fn stand_round() {
    stand_member("stand");
}

#[test]
fn stand_plinth_held_out() {
    stand_member("plinth");
}
