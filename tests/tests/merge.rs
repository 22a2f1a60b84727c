//! `scanner-host merge` through the real binaries. The head scans the rig's bunny in views
//! turned about the vertical (and one laid on its side), the host receives each, and `merge`
//! registers them with no guess: the rotations it finds match the rig's truth, the model lies on
//! the true surface. A second object, a part of flat faces, must merge right or be refused.
//! Bad input: one view, a folder that is not a scan, views from another camera, a scan without
//! points. The views are scanned once per test binary ([`bunny`], [`part`]); every test merges
//! into a folder of its own, and asserts on `merge-report.json`'s fields.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use scanner_tests::workspace_bin;
use serde_json::Value;

fn run(dir: &Path, bin: &str, args: &[&str]) -> (bool, String, String) {
    scanner_tests::run_in(&workspace_bin(bin), dir, args)
}

/// The merge report a merge wrote into `dir`.
fn report(dir: &Path) -> Value {
    let path = dir.join("merge-report.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A number of a report.
fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// Each view's rotation from view 0 in a report, degrees.
fn rotations(r: &Value) -> Vec<f64> {
    r["views"]
        .as_array()
        .expect("the views")
        .iter()
        .map(|v| num(&v["rotation_deg"]))
        .collect()
}

/// The bunny's merge of views 0, 1 and 6 (report `r`): views 1 and 2 (the scene's 1 and 6)
/// turned from view 0 within `deg` of the rig's rotations.
fn bunny_rotations_within(r: &Value, scene: &scanner_rig::Scene, deg: f64) {
    let found = rotations(r);
    for (k, scene_view) in [(1, 1), (2, 6)] {
        let truth = true_rotation(scene, scene_view);
        assert!(
            (found[k] - truth).abs() < deg,
            "view {k}: {}° found, {truth}° true",
            found[k]
        );
    }
}

/// The rig's rotation of view `k` from view 0 of `scene`, degrees.
fn true_rotation(scene: &scanner_rig::Scene, k: usize) -> f64 {
    (scene.view(0).unwrap().object_pose * scene.view(k).unwrap().object_pose.inverse())
        .rotation
        .angle()
        .to_degrees()
}

/// A 360° scene of `scenes/` (`name`, its mesh `mesh`) made small for a test — 640×480, 200
/// frames — written to `d/s.toml` with the rig's true calibration in `d/cal.toml`.
fn small_scene(d: &Path, name: &str, mesh: &str) -> scanner_rig::Scene {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scanner-device/scenes");
    let text = std::fs::read_to_string(scenes.join(name))
        .unwrap()
        .replace("width = 1280", "width = 640")
        .replace("height = 960", "height = 480")
        .replace("frames = 300", "frames = 200")
        .replace(
            &format!("path = \"{mesh}\""),
            &format!("path = {:?}", scenes.join(mesh).display().to_string()),
        );
    std::fs::write(d.join("s.toml"), &text).unwrap();
    let scene = scanner_device::cli::render::load_scene(Some(&d.join("s.toml"))).unwrap();
    scanner_rig::Rig::new(scene.clone())
        .unwrap()
        .truth_calibration()
        .save(&d.join("cal.toml"))
        .unwrap();
    scene
}

/// The head scans view `k` of `d/s.toml` (with `extra` options) into `d/vK.stream`, and the host
/// receives it into `d/vK`.
fn scan_view(d: &Path, k: &str, extra: &[&str]) {
    scanner_tests::scan_rig_view(d, k, extra, &[]);
}

/// Views of a scene, scanned once for every test of this binary.
struct Fixture {
    dir: PathBuf,
    scene: scanner_rig::Scene,
}

/// A fresh folder of this test binary's fixtures (an earlier run's is removed).
fn fixture_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("merge-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The bunny's views 0, 1 and 6 (turned 60°, laid on its side) in colour, and view 5 (turned
/// 300°) in gray, scanned at 640×480.
fn bunny() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = fixture_dir("bunny");
        let scene = small_scene(&dir, "bunny-360.toml", "bunny.obj");
        for k in ["0", "1", "6"] {
            scan_view(&dir, k, &["--format", "rgb", "--colour"]);
        }
        scan_view(&dir, "5", &[]);
        Fixture { dir, scene }
    })
}

/// `merge v0 v1 v6 --out model` of the bunny's views: (success, stdout, stderr), merged once.
fn bunny_model() -> &'static (bool, String, String) {
    static M: OnceLock<(bool, String, String)> = OnceLock::new();
    M.get_or_init(|| {
        run(
            &bunny().dir,
            "scanner-host",
            &["merge", "v0", "v1", "v6", "--out", "model", "-q"],
        )
    })
}

/// The part's six views 60° apart (`v0` … `v5`) and a seventh laid on its side (`side`),
/// scanned at 640×480.
fn part() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = fixture_dir("part");
        let scene = small_scene(&dir, "part-360.toml", "part.obj");
        for k in ["0", "1", "2", "3", "4", "5", "6"] {
            scan_view(&dir, k, &[]);
        }
        std::fs::rename(dir.join("v6"), dir.join("side")).unwrap();
        Fixture { dir, scene }
    })
}

/// The part's six turned views.
const PART_VIEWS: [&str; 6] = ["v0", "v1", "v2", "v3", "v4", "v5"];

#[test]
fn three_views_of_the_bunny_register_with_the_rigs_rotations() {
    let f = bunny();
    let d = &f.dir;
    let (ok, out, err) = bunny_model();
    assert!(ok, "{err}");
    println!("{out}");
    for file in ["views.ply", "views.png", "merge-report.txt", "model.stl"] {
        assert!(d.join("model").join(file).exists(), "no {file}");
    }
    let r = report(&d.join("model"));
    // The fused model is written, closed over what the three views left unseen (the bunny's
    // back and underside), and described.
    let fusion = &r["fusion"];
    assert_eq!(fusion["check"]["watertight"], true, "{fusion}");
    assert!(num(&fusion["unseen_share"]) > 0.0, "{fusion}");
    // Right poses leave (next to) no view's points in front of what another saw.
    let share = num(&r["free_space"]["worst_share"]);
    assert!(share < 0.005, "{share} in front");
    // The edge points left out of the fusion are counted, by each check (one run: 110 off
    // another view's clear surface, 533 by the winding number).
    let left_out = num(&fusion["contradicted"]) + num(&fusion["off_surface"]);
    assert!(left_out > 0.0, "{fusion}");
    model_against_the_truth(d, &f.scene, &[0, 1, 6]);
    // Coloured per vertex from the views' colours (the bunny's albedo, lit), in the OBJ read
    // back by an independent reader (tobj reads the OBJ's vertex colours).
    assert_eq!(fusion["coloured"], true);
    let (models, _) = tobj::load_obj(d.join("model/model.obj"), &tobj::LoadOptions::default())
        .expect("the model's OBJ reads back");
    let mesh = &models[0].mesh;
    assert_eq!(mesh.vertex_color.len(), mesh.positions.len());
    let mean_red =
        mesh.vertex_color.iter().step_by(3).sum::<f32>() / (mesh.vertex_color.len() / 3) as f32;
    let mean_blue = mesh.vertex_color.iter().skip(2).step_by(3).sum::<f32>()
        / (mesh.vertex_color.len() / 3) as f32;
    assert!(
        mean_red > 0.1 && mean_red > mean_blue,
        "the bunny's albedo is warm (0.75, 0.7, 0.65): red {mean_red}, blue {mean_blue}"
    );
    // The rotation of each view from view 0, against the truth. Scanned points at 640×480
    // (about 1 500 per view), registered on those clear of the views' edges: 0.030° and 0.018°
    // off in one run (0.15° and 0.03° before the edges were left out and the views refined
    // together in one solve).
    bunny_rotations_within(&r, &f.scene, 0.1);
}

/// Views whose images are wide get coarse cells by default (2 px for every 640 px of width);
/// when the views then share too few points to be registered by their shapes, the merge reads
/// them again at 2 px and says so in its report. The bunny's 640×480 views 0, 1 and 6 with
/// their headers' width set to 2 560 px (8 px cells by default) cannot be registered at 8 px
/// cells, and are merged at 2 px as the views themselves are.
#[test]
fn views_too_sparse_at_their_default_cells_are_read_again_at_finer_ones() {
    let f = bunny();
    let d = &f.dir;
    for k in ["0", "1", "6"] {
        let journal = std::fs::read(d.join(format!("v{k}/journal.stream"))).unwrap();
        let wide = d.join(format!("wide{k}"));
        std::fs::create_dir_all(&wide).unwrap();
        std::fs::write(wide.join("journal.stream"), with_width(&journal, 2560)).unwrap();
    }
    let views = ["wide0", "wide1", "wide6"];
    let mut args = vec!["merge"];
    args.extend(views);
    args.extend(["--cell", "8px", "--out", "coarse", "-q"]);
    let (ok, _, err) = run(d, "scanner-host", &args);
    let kinds = scanner_tests::error_kinds(&err);
    assert!(
        !ok && (kinds.contains(&"NoMatch".to_string()) || kinds.contains(&"Apart".to_string())),
        "at 8 px cells the views do not register: {err}"
    );
    let mut args = vec!["merge"];
    args.extend(views);
    args.extend(["--out", "finer", "-q"]);
    let (ok, _, err) = run(d, "scanner-host", &args);
    assert!(ok, "{err}");
    let r = report(&d.join("finer"));
    assert_eq!(r["finer_cell_px"], 2.0, "{r}");
    assert_eq!(r["fusion"]["check"]["watertight"], true, "{r}");
    bunny_rotations_within(&r, &f.scene, 0.1);
    // Read at the cells the views were scanned with, nothing is read again.
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v1", "v6", "--out", "as-chosen", "-q"],
    );
    assert!(ok, "{err}");
    assert_eq!(report(&d.join("as-chosen"))["finer_cell_px"], Value::Null);
}

/// A journal's frames with every header's image width set to `width`, each frame re-encoded
/// as the head sends it.
fn with_width(journal: &[u8], width: u16) -> Vec<u8> {
    rewrite_headers(journal, |h| h.width = width)
}

/// Views 0, 1 and 5 of the bunny are turns by 60° and 300° about one axis (a turntable whose
/// step nobody gave), view 6 is laid on its side: `merge` without a hint finds the turns, says
/// so, and refines the three as turns about one axis (each by its turn within 0.5°), the side
/// view not among them; every view's rotation from view 0 within 0.1° of the rig's. (Views 1
/// and 5 each share half their points with view 0; at 640×480 view 2, 120° from view 0, shares
/// a quarter and one run placed it 12.7° off, which the free-space check refused.)
#[test]
fn turns_about_one_axis_are_found_without_a_hint() {
    let f = bunny();
    let (ok, out, err) = run(
        &f.dir,
        "scanner-host",
        &["merge", "v0", "v1", "v5", "v6", "--out", "found", "-q"],
    );
    println!("turns found without a hint:\n{out}{err}");
    assert!(ok, "{out}{err}");
    let r = report(&f.dir.join("found"));
    let turns = &r["turns"];
    assert_eq!(turns["hinted"], false, "{turns}");
    let views: Vec<(u64, f64)> = turns["views"]
        .as_array()
        .expect("turns found")
        .iter()
        .map(|t| (t["view"].as_u64().unwrap(), num(&t["deg"])))
        .collect();
    assert_eq!(
        views.iter().map(|t| t.0).collect::<Vec<_>>(),
        [0, 1, 2],
        "{turns}"
    );
    for ((_, a), want) in views.iter().zip([0.0, 60.0, 300.0]) {
        assert!((a - want).abs() < 0.5, "turned {a}°, not {want}°: {turns}");
    }
    let found = rotations(&r);
    for (k, scene_view) in [(1, 1), (2, 5), (3, 6)] {
        let truth = true_rotation(&f.scene, scene_view);
        assert!(
            (found[k] - truth).abs() < 0.1,
            "view {k}: {}° found, {truth}° true",
            found[k]
        );
    }
}

/// `merge --sheet 0.6` (the rig's light sheet, σ 0.6 mm): each view's points moved to where the
/// sheet's middle crosses the surface lie nearer the true surface than the head's, clear of the
/// views' edges (where the lit band's skew on the curved bunny moves them); the report says how
/// many moved, and the merge still meets its targets. A sheet thicker than any line laser, and
/// one that is no number, are refused.
#[test]
fn the_sheets_correction_moves_the_views_nearer_the_truth() {
    let f = bunny();
    let d = &f.dir;
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &[
            "merge", "v0", "v1", "v6", "--sheet", "0.6", "--out", "sheet", "-q",
        ],
    );
    assert!(ok, "{err}");
    let r = report(&d.join("sheet"));
    for v in r["views"].as_array().unwrap() {
        let moved = v["sheet_moved"].as_array().expect("points moved");
        assert!(
            moved[0].as_u64().unwrap() > 0 && moved[0].as_u64() <= moved[1].as_u64(),
            "{v}"
        );
    }
    let mut medians = Vec::new();
    for k in [0usize, 1, 6] {
        let scanner_rig::Shape::Mesh(truth) = &f.scene.view(k).unwrap().objects[0].shape else {
            panic!("the bunny is a mesh")
        };
        // The clear points' mean signed distance from the truth (+ towards the camera) and
        // their median distance.
        let [head, corrected] = [0.0, 0.6].map(|sheet| {
            let v = scanner_host::views::load_view(
                k,
                &d.join(format!("v{k}")),
                "2px".parse().unwrap(),
                sheet,
            )
            .unwrap();
            let clear = v.clear_cloud();
            let mut e: Vec<f64> = clear
                .points
                .iter()
                .zip(&clear.normals)
                .map(|(p, n)| (p - truth.closest(p).unwrap()).dot(n))
                .collect();
            let mean = e.iter().sum::<f64>() / e.len() as f64;
            e.iter_mut().for_each(|x| *x = x.abs());
            e.sort_by(f64::total_cmp);
            (mean, e[e.len() / 2])
        });
        medians.push((k, head, corrected));
    }
    println!("(mean signed, median) distance from the truth, head and corrected, mm: {medians:?}");
    // One run: the mean −0.016, −0.010, −0.013 mm → −0.009, −0.005, −0.010 mm, the medians 3–6 %
    // lower (at 640×480 the sensor's noise and the speckle dominate the medians; on the
    // 1280×960 demo with the true calibration the views' worst rotation halves, docs/reports.md).
    for (k, head, corrected) in &medians {
        assert!(
            corrected.0.abs() < head.0.abs() && corrected.1 < head.1,
            "view {k}: {corrected:?} mm corrected, {head:?} mm"
        );
    }
    let (head, corrected): (f64, f64) = medians
        .iter()
        .fold((0.0, 0.0), |(h, c), m| (h + m.1.0.abs(), c + m.2.0.abs()));
    assert!(corrected < 0.8 * head, "{medians:?}");
    assert_eq!(r["fusion"]["check"]["watertight"], true);
    // Out of range, or no thickness: refused by kind.
    for (bad, value, kind) in [
        ("thick", "9", "ThicknessError"),
        ("thin", "thin", "ValueValidation"),
    ] {
        let (ok, _, err) = run(
            d,
            "scanner-host",
            &["merge", "v0", "v1", "--sheet", value, "--out", bad, "-q"],
        );
        assert!(!ok && scanner_tests::has_kind(&err, kind), "{err}");
        assert!(!d.join(bad).join("model.obj").exists());
    }
}

/// `--sheet auto`: the views refined at each thickness tried, the one where they agree best
/// taken (one run: 0.70 mm for the rig's 0.6 on these three 640×480 views; on nine folders of
/// seven 1280×960 views 10–30 % under the rig's σ, docs/reports.md).
#[test]
fn sheet_auto_finds_the_thickness_where_the_views_agree_best() {
    let f = bunny();
    let (ok, _, err) = run(
        &f.dir,
        "scanner-host",
        &[
            "merge", "v0", "v1", "v6", "--sheet", "auto", "--out", "auto", "-q",
        ],
    );
    assert!(ok, "{err}");
    let r = report(&f.dir.join("auto"));
    let search = &r["sheet_search"];
    println!("{search}");
    let sigma = num(&search["sigma_mm"]);
    assert!((0.3..=0.8).contains(&sigma), "{search}");
    let tried = search["tried"].as_array().unwrap();
    assert_eq!(tried.len(), scanner_merge::thickness_tries().len());
    assert!(
        tried.iter().all(|t| t["disagreement_mm"].is_number()),
        "{search}"
    );
    // the views were read with the thickness found
    assert!(r["views"][0]["sheet_moved"].is_array(), "{r}");
}

/// The files `merge` writes for the model (beside its report and pictures).
const MODEL_FILES: [&str; 5] = [
    "model.obj",
    "model.ply",
    "model.stl",
    "model.3mf",
    "views.ply",
];

/// Each of `files` is byte for byte the same in folders `a` and `b`.
fn same_files(a: &Path, b: &Path, files: &[&str]) {
    for f in files {
        assert!(
            std::fs::read(a.join(f)).unwrap() == std::fs::read(b.join(f)).unwrap(),
            "{} differs from {}",
            a.join(f).display(),
            b.join(f).display()
        );
    }
}

/// `merge --view`: the page shows the registered views in their colours, then the model with
/// its files; the outputs are those of the merge without the page.
#[test]
fn the_live_view_shows_the_views_then_the_model() {
    use std::time::Duration;
    let f = bunny();
    let d = &f.dir;
    let (ok, _, err) = bunny_model();
    assert!(ok, "{err}");
    let args = ["merge", "v0", "v1", "v6", "--out", "model-live", "-q"];
    let Some((child, mut b)) = merge_in_browser(d, &args) else {
        return;
    };
    let mut child = Kill(Some(child));
    assert!(
        b.wait_for(
            "document.body.dataset.mesh === 'shown'",
            Duration::from_secs(120)
        ),
        "the model is shown: state {}",
        b.eval("document.getElementById('state').textContent")
    );
    // The views came first, in their own colours (the page switched to them).
    let points = b.eval("Number(document.body.dataset.points)");
    assert!(points.as_u64().unwrap() > 1000, "{points}");
    assert_eq!(b.eval("document.getElementById('colouring').value"), "1");
    assert_eq!(
        b.eval("document.getElementById('title').textContent"),
        "Merging views"
    );
    assert_eq!(b.eval("Number(document.body.dataset.downloads)"), 9);
    let shot = b.screenshot();
    if let Some(dir) = std::env::var_os("LIVE_VIEW_SHOTS") {
        shot.save(Path::new(&dir).join("live-view-merge.png"))
            .unwrap();
    }
    scanner_tests::interrupt(child.0.take().unwrap());
    same_files(
        &d.join("model"),
        &d.join("model-live"),
        &[
            MODEL_FILES.as_slice(),
            &["merge-report.txt", "merge-report.json"],
        ]
        .concat(),
    );
}

/// A child process killed when the test ends, failed or not.
struct Kill(Option<std::process::Child>);

impl Drop for Kill {
    fn drop(&mut self) {
        if let Some(c) = &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// `merge --flat-base` of two views from the front (the underside unseen): the model, read back
/// by tobj, is closed, and stands on a flat base — nothing lies below its lowest level, where
/// faces of a real area lie flat and face down — as large as the report says. It cannot be
/// asked together with `--trim-unseen`, nor without a board to say where up is.
#[test]
fn a_flat_base_closes_the_model_for_printing() {
    let d = &bunny().dir;
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v1", "--out", "flat", "--flat-base", "-q"],
    );
    assert!(ok, "{err}");
    let r = report(&d.join("flat"));
    // Two views close no loop: said, since nothing checked the registration.
    assert!(r["closure"]["after"].is_null(), "{r}");
    assert!(err.contains("warning"), "{err}");
    let said = num(&r["fusion"]["base_mm2"]);
    let (models, _) = tobj::load_obj(d.join("flat/model.obj"), &tobj::LoadOptions::default())
        .expect("the model's OBJ reads back");
    let mesh = &models[0].mesh;
    assert_eq!(open_edges(mesh), 0);
    let p = |i: u32| {
        let i = 3 * i as usize;
        scanner_core::nalgebra::Vector3::new(
            f64::from(mesh.positions[i]),
            f64::from(mesh.positions[i + 1]),
            f64::from(mesh.positions[i + 2]),
        )
    };
    let low = (0..mesh.positions.len() as u32 / 3)
        .map(|i| p(i).y)
        .fold(f64::INFINITY, f64::min);
    let (mut base, mut facing_down) = (0.0, true);
    for f in mesh.indices.chunks(3) {
        let [a, b, c] = [p(f[0]), p(f[1]), p(f[2])];
        if [a, b, c].iter().all(|v| v.y - low < 0.01) {
            let n = (b - a).cross(&(c - a));
            base += n.norm() / 2.0;
            facing_down &= n.y < 0.0;
        }
    }
    println!("flat base at y = {low:.3} mm: {base:.0} mm² read back, {said} mm² reported");
    assert!(
        base > 20.0 && facing_down,
        "base {base} mm², facing down {facing_down}"
    );
    assert!(
        (base - said).abs() <= 0.02 * said + 1.0,
        "{base} read, {said} said"
    );
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v1", "--flat-base", "--trim-unseen"],
    );
    assert!(
        !ok && scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "ArgumentConflict"),
        "{err}"
    );
    // A view 0 whose scan carries no usable board (both planes the same: no crease, so no up):
    // the flat base cannot be placed, and says why; the merge without it still runs.
    let journal = std::fs::read(d.join("v0/journal.stream")).expect("view 0's journal");
    std::fs::create_dir_all(d.join("noboard")).unwrap();
    std::fs::write(d.join("noboard/journal.stream"), without_board(&journal)).unwrap();
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "noboard", "v1", "--out", "nb", "--flat-base", "-q"],
    );
    assert!(
        !ok && scanner_tests::error_kinds(&err).iter().any(|k| k == "NoUp"),
        "{err}"
    );
    assert!(!d.join("nb/model.obj").exists());
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "noboard", "v1", "--out", "nb", "-q"],
    );
    assert!(ok && d.join("nb/model.obj").exists(), "{err}");
}

/// `receive --merge`: the three sweeps in one session (one stream after the other, as a head
/// sends them when the object is turned between scans) are split into three views, each with
/// the outputs its own receive gives, and merged into the model `merge` makes of them. With a
/// turntable's step, the views it fits are refined as turns; a step that is no step, and
/// options that do not go with `--merge`, are refused.
#[test]
fn one_session_of_three_sweeps_is_split_into_views_and_merged() {
    let d = &bunny().dir;
    let (ok, _, err) = bunny_model();
    assert!(ok, "{err}");
    let mut all = Vec::new();
    for k in ["0", "1", "6"] {
        all.extend(std::fs::read(d.join(format!("v{k}.stream"))).unwrap());
    }
    std::fs::write(d.join("session.stream"), all).unwrap();
    let (ok, out, err) = run(
        d,
        "scanner-host",
        &[
            "receive",
            "session.stream",
            "--merge",
            "--out",
            "session",
            "-q",
        ],
    );
    assert!(ok, "{out}\n{err}");
    for (view, k) in [("view-1", "v0"), ("view-2", "v1"), ("view-3", "v6")] {
        for f in ["scan.obj", "journal.stream", "summary.json"] {
            assert!(
                std::fs::read(d.join("session").join(view).join(f)).unwrap()
                    == std::fs::read(d.join(k).join(f)).unwrap(),
                "{view}/{f} is not {k}/{f}"
            );
        }
    }
    assert!(!d.join("session/view-4").exists());
    same_files(&d.join("session/model"), &d.join("model"), &MODEL_FILES);
    // A turntable's step reaches the merge: views 0 and 1 (view 0 and the one turned 60°) are
    // refined as turns about one axis, the side view is not.
    let (ok, out, err) = run(
        d,
        "scanner-host",
        &[
            "receive",
            "session.stream",
            "--merge",
            "--turntable",
            "60",
            "--out",
            "session-turntable",
            "-q",
        ],
    );
    assert!(ok, "{out}\n{err}");
    let turns = &report(&d.join("session-turntable/model"))["turns"];
    assert_eq!(turns["hinted"], true, "{turns}");
    let views: Vec<u64> = turns["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["view"].as_u64().unwrap())
        .collect();
    assert_eq!(views, [0, 1], "{turns}");
    assert_eq!(num(&turns["views"][0]["deg"]), 0.0);
    for (bad, args) in [
        ("--turntable", vec!["--merge", "--turntable", "0"]),
        ("--turntable", vec!["--merge", "--turntable", "270"]),
        ("--turntable", vec!["--merge", "--turntable", "NaN"]),
        ("--merge", vec!["--turntable", "60"]),
        ("min-overlap", vec!["--merge", "--min-overlap", "2"]),
        ("--merge", vec!["--min-overlap", "0.3"]),
        ("--until-done", vec!["--merge", "--until-done"]),
    ] {
        let mut all = vec!["receive", "session.stream", "--out", "refused"];
        all.extend(args);
        let (ok, _, err) = run(d, "scanner-host", &all);
        assert!(!ok && err.contains(bad), "{all:?}: {err}");
    }
}

/// The turntable hint (60° steps about the vertical) changes nothing where the registration
/// finds the views by itself; a step that is no step is refused.
#[test]
fn the_turntable_hint_changes_nothing_where_the_views_register_alone() {
    let d = &bunny().dir;
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &[
            "merge",
            "v0",
            "v1",
            "--turntable",
            "60",
            "--out",
            "mt",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v1", "--out", "mp", "-q"],
    );
    assert!(ok, "{err}");
    let (hinted, plain) = (
        rotations(&report(&d.join("mt"))),
        rotations(&report(&d.join("mp"))),
    );
    assert!((hinted[1] - plain[1]).abs() < 0.05, "{hinted:?} {plain:?}");
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v1", "--turntable", "0"],
    );
    assert!(
        !ok && scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "Option"),
        "{err}"
    );
}

/// Bad input is refused, naming the view: one view, a folder that is no scan, a scan of another
/// camera, a scan that sent no point (the laser off for the whole sweep).
#[test]
fn bad_views_are_refused_and_named() {
    let d = &bunny().dir;
    let (ok, _, err) = run(d, "scanner-host", &["merge", "v0", "--out", "m1"]);
    assert!(
        !ok && scanner_tests::error_kinds(&err).contains(&"TooFewViews".to_string()),
        "{err}"
    );
    std::fs::create_dir_all(d.join("empty")).unwrap();
    let (ok, _, err) = run(d, "scanner-host", &["merge", "v0", "empty", "--out", "m2"]);
    // the message family of bad views: the sentence names the view by number and name
    assert!(!ok && err.contains("view 1 (empty)"), "{err}");
    let small = scanner_rig::Rig::new(scanner_rig::Scene::demo(320, 240)).unwrap();
    small
        .truth_calibration()
        .save(&d.join("small.toml"))
        .unwrap();
    let (ok, _, err) = run(
        d,
        "scanner-device",
        &[
            "scan",
            "--source",
            "rig:320x240",
            "--calibration",
            "small.toml",
            "--out",
            "small.stream",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "small.stream", "--out", "m3"],
    );
    assert!(
        !ok && scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "OtherCamera"),
        "{err}"
    );
    std::fs::write(
        d.join("dark.toml"),
        std::fs::read_to_string(d.join("s.toml"))
            .unwrap()
            .replace("[laser]", "[laser]\npower = 0.0"),
    )
    .unwrap();
    let (ok, _, err) = run(
        d,
        "scanner-device",
        &[
            "scan",
            "--columns",
            "--source",
            "rig",
            "--scene",
            "dark.toml",
            "--calibration",
            "cal.toml",
            "--frames",
            "20",
            "--out",
            "dark.stream",
            "-q",
        ],
    );
    assert!(ok, "{err}");
    let (ok, _, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "dark.stream", "--out", "m4"],
    );
    assert!(
        !ok && scanner_tests::error_kinds(&err)
            .iter()
            .any(|k| k == "NoPoints"),
        "{err}"
    );
    for m in ["m1", "m2", "m3", "m4"] {
        assert!(!d.join(m).join("model.obj").exists());
    }
}

/// The rig's part (`part.obj`, a twisted notched block of flat faces) in six views 60° apart
/// about the vertical, scanned at 640×480 through the binaries: the merge either registers every
/// view within 1° of the truth and writes the model, or refuses (the loop left open, or a view's
/// points in front of what another saw) and writes no model — never a wrong model called
/// watertight. In one run it refused: views 3 and 4 placed wrongly (174.1° found for 180°,
/// 149.7° for 120°), the worst loop 1.46° and 6.5 mm open after the joint refinement
/// (docs/reports.md: the registration's known failure on such parts); in another, view 1's
/// points 35 % in front of what view 3 saw.
/// Refused with `--view`, the page says why and keeps what the refusal left.
#[test]
fn views_of_a_part_of_flat_faces_are_merged_right_or_refused() {
    let f = part();
    let d = &f.dir;
    let mut args = vec!["merge"];
    args.extend(PART_VIEWS);
    args.extend(["--out", "model", "--min-overlap", "0.3", "-q"]);
    let (ok, out, err) = run(d, "scanner-host", &args);
    println!("{out}{err}");
    // What a refusal leaves, and what it does not.
    assert!(d.join("model/views.png").exists() && d.join("model/merge-report.txt").exists());
    let r = report(&d.join("model"));
    assert!(
        r["turns"].is_null() || r["turns"]["hinted"] == false,
        "no step given: {r}"
    );
    if ok {
        let found = rotations(&r);
        for (k, found) in found.iter().enumerate().skip(1) {
            let truth = true_rotation(&f.scene, k);
            assert!(
                (found - truth).abs() < 1.0,
                "view {k} merged {}° off",
                found - truth
            );
        }
        assert!(d.join("model/model.obj").exists());
    } else {
        // refused by one of the checks a wrong registration fails: the loop left open, or one
        // view's points in front of what another saw (the order of the stripe's lines of any
        // width moved which of the two speaks first)
        let check = r["refused"]["check"].as_str().unwrap_or_default();
        assert!(["loop_open", "seen_through"].contains(&check), "{r}");
        assert!(r["fusion"].is_null(), "{r}");
        assert!(!d.join("model/model.obj").exists() && !d.join("model/model.stl").exists());
        live_view_of_a_refused_merge(d);
    }
}

/// `merge --view` refused: the page says it stopped and why (in a failure's colour), offers what
/// the refusal left (views.png, views.ply, merge-report.txt and .json), and stays up; the exit
/// status still fails when it closes.
fn live_view_of_a_refused_merge(d: &Path) {
    use std::process::Command;
    use std::time::{Duration, Instant};
    let mut args = vec!["merge"];
    args.extend(PART_VIEWS);
    args.extend(["--out", "refused-live", "--min-overlap", "0.3", "-q"]);
    let Some((child, mut b)) = merge_in_browser(d, &args) else {
        return;
    };
    let mut child = Kill(Some(child));
    assert!(
        b.wait_for(
            "document.getElementById('state').textContent.startsWith('stopped: ')",
            Duration::from_secs(120)
        ),
        "the page says the merge stopped: state {}",
        b.eval("document.getElementById('state').textContent")
    );
    assert_eq!(
        report(&d.join("refused-live"))["refused"]["check"],
        report(&d.join("model"))["refused"]["check"],
        "the page's merge refuses as the command's did"
    );
    assert_eq!(
        b.eval("document.getElementById('state').className"),
        "figure state-lost"
    );
    assert_eq!(b.eval("Number(document.body.dataset.downloads)"), 4);
    // The registered views stay on the page, to see which one went wrong.
    let points = b.eval("Number(document.body.dataset.points)");
    assert!(points.as_u64().unwrap() > 1000, "{points}");
    assert!(!d.join("refused-live/model.obj").exists());
    let shot = b.screenshot();
    if let Some(dir) = std::env::var_os("LIVE_VIEW_SHOTS") {
        shot.save(Path::new(&dir).join("live-view-merge-refused.png"))
            .unwrap();
    }
    // Still up after the refusal, until Ctrl-C; then the exit status fails.
    let c = child.0.as_mut().unwrap();
    let sent = Command::new("kill")
        .args(["-INT", &c.id().to_string()])
        .status();
    assert!(sent.is_ok_and(|s| s.success()));
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = c.try_wait().unwrap() {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(20), "no exit on Ctrl-C");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(!status.success(), "a refused merge exits with failure");
}

/// The part's six views with the turntable's step given, and a seventh view of it laid on its
/// side, which no step describes: `merge --turntable 60` places every view the right way round
/// (the part is nearly the same turned 180° about the vertical: without the step its back views
/// fit the front ones as well) and writes the model; the side view is placed by its own match;
/// the six are refined as turns about one axis, each within 0.5° of its step. Each view's
/// rotation from view 0 is within 1.5° of the rig's (at 1280×960 the side view is 1.05° off,
/// the turned ones 0.08–0.17°; docs/reports.md). At 640×480 views 60° apart share about 30 %
/// (the fine fit of views 4 and 3 covers under 30 %), so 25 % is asked, as `merge --help`
/// advises for views turned far apart; at 30 % that pair fails, the side view places views 2
/// and 3 wrongly and the free-space check refuses the merge.
#[test]
fn the_part_on_a_turntable_is_merged_with_its_step() {
    let f = part();
    let d = &f.dir;
    let mut args = vec!["merge"];
    args.extend(PART_VIEWS);
    args.extend([
        "side",
        "--turntable",
        "60",
        "--out",
        "turntable",
        "--min-overlap",
        "0.25",
        "-q",
    ]);
    let (ok, out, err) = run(d, "scanner-host", &args);
    println!("with the turntable's step:\n{out}{err}");
    assert!(ok, "{out}{err}");
    let r = report(&d.join("turntable"));
    for (k, found) in rotations(&r).iter().enumerate().skip(1) {
        let truth = true_rotation(&f.scene, k);
        assert!(
            (found - truth).abs() < 1.5,
            "view {k} merged {}° off",
            found - truth
        );
    }
    assert!(num(&r["free_space"]["worst_share"]) < 0.005, "{r}");
    assert!(d.join("turntable/model.obj").exists());
    // The six turned views refined as turns about one axis (the side view is not among them),
    // each by its step: one run 59.97°, 119.95°, 179.97°, 239.97° and 300.00°.
    let turns = &r["turns"];
    assert_eq!(turns["hinted"], true, "{turns}");
    let views = turns["views"].as_array().unwrap();
    assert_eq!(views.len(), PART_VIEWS.len(), "{turns}");
    for (k, t) in views.iter().enumerate() {
        let (a, want) = (num(&t["deg"]), 60.0 * k as f64);
        assert!(
            t["view"] == k && (a - want).abs() < 0.5,
            "view {k} turned {a}°, not {want}°: {turns}"
        );
    }
}

/// Two views of the part close no loop, so only their free space can tell a wrong registration
/// (a face laid on the wrong face) by itself. Each pair is refused as overlapping too little,
/// merged right (within 1° of the truth, next to no point in front of what the other view saw),
/// refused because one view's points lie where the other saw empty space, or — where a wrong
/// placement leaves the other's free space alone — merged wrong with the warning that no loop
/// checked it. Some pair must be refused by its free space.
#[test]
fn two_views_of_the_part_are_merged_right_or_refused_by_their_free_space() {
    let f = part();
    let d = &f.dir;
    let mut seen_through = 0;
    for (a, b) in [(1, 2), (0, 2), (1, 3), (4, 5), (5, 0), (2, 3)] {
        let (va, vb) = (format!("v{a}"), format!("v{b}"));
        let out_dir = format!("pair{a}{b}");
        let (ok, out, err) = run(
            d,
            "scanner-host",
            &[
                "merge",
                &va,
                &vb,
                "--out",
                &out_dir,
                "--min-overlap",
                "0.3",
                "-q",
            ],
        );
        let written = d.join(&out_dir).join("merge-report.json").exists();
        let outcome = if !written {
            // refused before any view was placed: the second view overlaps the first too little
            assert!(
                !ok && (err.contains(&format!("({va})")) || err.contains(&format!("({vb})"))),
                "views {a} and {b}: {err}"
            );
            "too little overlap"
        } else {
            let r = report(&d.join(&out_dir));
            if ok {
                let truth = (f.scene.view(a).unwrap().object_pose
                    * f.scene.view(b).unwrap().object_pose.inverse())
                .rotation
                .angle()
                .to_degrees();
                let found = rotations(&r)[1];
                assert!(r["closure"]["after"].is_null(), "{r}");
                if (found - truth).abs() < 1.0 {
                    assert!(num(&r["free_space"]["worst_share"]) < 0.005, "{r}");
                    "right"
                } else {
                    "wrong, with the warning"
                }
            } else {
                assert_eq!(
                    r["refused"]["check"], "seen_through",
                    "views {a} and {b}: {r}"
                );
                assert!(!d.join(&out_dir).join("model.obj").exists());
                seen_through += 1;
                "refused by its free space"
            }
        };
        println!("views {a} and {b}: {outcome}\n{out}{err}");
    }
    assert!(seen_through > 0, "no pair was refused by its free space");
}

/// A view that overlaps none of the others (the bunny, scanned by the same set-up, among views
/// of the part) is named, and nothing is merged.
#[test]
fn a_view_of_another_object_overlaps_no_other_view() {
    let d = &part().dir;
    let bunny = bunny().dir.join("v6");
    let bunny = bunny.to_str().unwrap();
    let (ok, out, err) = run(
        d,
        "scanner-host",
        &["merge", "v0", "v3", "v4", bunny, "--out", "m5", "-q"],
    );
    assert!(
        !ok && err.contains(&format!("view 3 ({bunny})")),
        "{out}{err}"
    );
    assert!(!d.join("m5/model.obj").exists());
}

/// Edges of `mesh` (as tobj read it) not in exactly two faces.
fn open_edges(mesh: &tobj::Mesh) -> usize {
    let mut edges = std::collections::HashMap::new();
    for f in mesh.indices.chunks(3) {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    edges.values().filter(|&&c| c != 2).count()
}

/// A journal's frames with every header's right board plane replaced by its left one, each
/// frame re-encoded as the head sends it.
fn without_board(journal: &[u8]) -> Vec<u8> {
    rewrite_headers(journal, |h| h.board[1] = h.board[0])
}

/// A journal's frames with `change` made to every header, each frame re-encoded as the head
/// sends it.
fn rewrite_headers(journal: &[u8], change: impl Fn(&mut scanner_wire::Header)) -> Vec<u8> {
    use scanner_wire::{Decoder, MAX_ENCODED, MAX_MESSAGE, Message};
    let mut out = Vec::new();
    let (mut scratch, mut frame) = (vec![0u8; MAX_MESSAGE], vec![0u8; MAX_ENCODED]);
    let mut decoder = Box::new(Decoder::<MAX_ENCODED>::new());
    decoder.feed(journal, |m| {
        let mut m = m.expect("a journal of good frames");
        if let Message::Header(h) = &mut m {
            change(h);
        }
        let n = scanner_wire::encode(&m, &mut scratch, &mut frame).expect("re-encoded");
        out.extend_from_slice(&frame[..n]);
    });
    out
}

/// The merged model in `d/model`, read back by an independent reader (tobj), is watertight by
/// its own edge count, its 3MF holds the same mesh, and it lies on the true bunny where the
/// views saw it (the truth's lit points of the views, moved into view 0 by the true poses): both
/// ways, area-weighted.
fn model_against_the_truth(d: &Path, scene: &scanner_rig::Scene, views: &[usize]) {
    use scanner_core::nalgebra::Point3;
    let (models, _) = tobj::load_obj(d.join("model/model.obj"), &tobj::LoadOptions::default())
        .expect("the model's OBJ reads back");
    let mesh = &models[0].mesh;
    let open = open_edges(mesh);
    assert_eq!(open, 0, "{open} edges not in exactly two faces");
    // The 3MF holds the same mesh: its package read by the `zip` crate, its model's vertices
    // and triangles counted and checked against the OBJ's.
    let mut package =
        zip::ZipArchive::new(std::fs::File::open(d.join("model/model.3mf")).unwrap()).unwrap();
    for part in ["[Content_Types].xml", "_rels/.rels"] {
        assert!(package.by_name(part).is_ok(), "3MF without {part}");
    }
    let mut xml = String::new();
    std::io::Read::read_to_string(&mut package.by_name("3D/3dmodel.model").unwrap(), &mut xml)
        .unwrap();
    assert!(xml.contains("unit=\"millimeter\""));
    let attr = |tag: &str, key: &str| -> Vec<f64> {
        xml.split(tag)
            .skip(1)
            .map(|e| {
                let v = e.split(&format!("{key}=\"")).nth(1).unwrap();
                v[..v.find('"').unwrap()].parse().unwrap()
            })
            .collect()
    };
    let xs = attr("<vertex ", "x");
    let v1 = attr("<triangle ", "v1");
    assert_eq!(xs.len() * 3, mesh.positions.len());
    assert_eq!(v1.len() * 3, mesh.indices.len());
    assert!(
        xs.iter()
            .zip(mesh.positions.iter().step_by(3))
            .all(|(a, b)| (a - f64::from(*b)).abs() < 1e-3)
    );
    // Its colours (materials extension): one per vertex, as the OBJ's, each triangle's corners
    // naming their vertices'.
    let colours: Vec<[f32; 3]> = xml
        .split("<m:color color=\"#")
        .skip(1)
        .map(|c| {
            core::array::from_fn(|i| {
                f32::from(u8::from_str_radix(&c[2 * i..2 * i + 2], 16).unwrap()) / 255.0
            })
        })
        .collect();
    assert_eq!(colours.len() * 3, mesh.vertex_color.len());
    assert!(
        colours
            .iter()
            .flatten()
            .zip(&mesh.vertex_color)
            .all(|(a, b)| (a - b).abs() < 1e-3)
    );
    assert_eq!(attr("<triangle ", "p1"), v1);
    // The model is in the board's frame (y up); the truth in view 0's camera frame.
    let view0 =
        scanner_host::views::load_view(0, &d.join("v0"), "2px".parse().unwrap(), 0.0).unwrap();
    let frame = scanner_host::mesh::MeshFrame::board(
        &scanner_core::geometry::Board::<f32>::try_from(view0.header.board).unwrap(),
    );
    let to_board = |p: &Point3<f64>| frame.point(&p.cast::<f32>()).cast::<f64>();
    let v0 = scene.view(0).unwrap();
    let scanner_rig::Shape::Mesh(truth) = &v0.objects[0].shape else {
        panic!("the bunny is a mesh")
    };
    let truth = scanner_rig::mesh::SceneMesh::new(
        truth
            .triangles()
            .iter()
            .map(|t| t.map(|p| to_board(&p)))
            .collect(),
    );
    let mut seen = Vec::new();
    for &k in views {
        let v = scene.view(k).unwrap();
        let into_view0 = v0.object_pose * v.object_pose.inverse();
        let rig = scanner_rig::Rig::new(v).unwrap();
        for f in 0..rig.scene().laser.frames {
            for t in rig.truth(f).unwrap().into_iter().flatten() {
                if matches!(t.surface, scanner_rig::SurfaceId::Object(_)) {
                    seen.push(to_board(&(into_view0 * t.point)));
                }
            }
        }
    }
    let p = &mesh.positions;
    let model: Vec<[Point3<f64>; 3]> = mesh
        .indices
        .chunks(3)
        .map(|f| {
            [f[0], f[1], f[2]].map(|i| {
                let i = 3 * i as usize;
                Point3::new(p[i], p[i + 1], p[i + 2]).cast::<f64>()
            })
        })
        .collect();
    let c = scanner_rig::compare::compare(
        &model,
        &truth,
        &scanner_rig::compare::Seen::new(&seen, 1.5),
        0.5,
    );
    let pct = |mm: f64| 100.0 * mm / scene.board.distance;
    println!(
        "model → truth {:.0} mm²: mean {:.4} %, p99 {:.4} %; truth → model {:.0} mm²: mean {:.4} %, p99 {:.4} %",
        c.to_truth.area_mm2,
        pct(c.to_truth.mean),
        pct(c.to_truth.p99),
        c.to_model.area_mm2,
        pct(c.to_model.mean),
        pct(c.to_model.p99)
    );
    assert!(
        c.to_truth.area_mm2 > 5000.0 && c.to_model.area_mm2 > 5000.0,
        "{c:?}"
    );
    // The targets are means of 0.03 % and a p99 of 0.15 % at 1280×960 (docs/reports.md
    // for the seven-view demo); three views at 640×480 here, one run: means 0.020 % and
    // 0.022 %, p99 0.12 % and 0.16 % (the holes of three views take the leaving out of edge
    // points that float off the surface to its limit: with a margin of 0.30 instead of 0.35 the
    // second p99 was 0.39 %).
    let (mean, p99) = (
        pct(c.to_truth.mean.max(c.to_model.mean)),
        pct(c.to_truth.p99.max(c.to_model.p99)),
    );
    assert!(mean < 0.03 && p99 < 0.2, "mean {mean} %, p99 {p99} %");
}

/// `scanner-host ARGS --view` started in `d` and its page opened in a headless Chromium (`None`
/// without one: the browser module says so).
fn merge_in_browser(
    d: &Path,
    args: &[&str],
) -> Option<(std::process::Child, scanner_tests::browser::Browser)> {
    use scanner_tests::browser::{Browser, chromium, lines_of, wait_line};
    use std::process::{Command, Stdio};
    let exe = chromium()?;
    let mut child = Command::new(workspace_bin("scanner-host"))
        .current_dir(d)
        .args(args)
        .arg("--view")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let lines = lines_of(child.stderr.take().unwrap());
    let url =
        wait_line(&lines, "live view: ", std::time::Duration::from_secs(20)).expect("the address");
    let mut b = Browser::launch(&exe);
    b.navigate(&url);
    Some((child, b))
}
