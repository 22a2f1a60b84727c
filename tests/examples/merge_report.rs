//! Issue 17's figures of a 360° merge against the rig's truth: `cargo run --release -p
//! scanner-tests --example merge_report -- OUT [SCENE] [--on-truth]`, where OUT is the folder
//! `scripts/scan-rig-360 OUT` wrote (its views `view0`, `view1`, … scanned at 1280×960 with a
//! calibration from images) and SCENE the scene they were scanned from (default
//! `scanner-device/scenes/bunny-360.toml`). The views are merged as `scripts/scan-rig-360` merges
//! them (`scanner_merge::run`, as `scanner-host merge` calls it) and measured:
//! - every view's points against the true surface (placed by the view's true pose), those clear
//!   of the view's edges and those on them apart (what the merge registers on, what it only
//!   fills in with);
//! - every view's pose against the truth: rotation (with its rotation vector in view 0's camera
//!   frame, degrees about x, y and z), and the displacement of the object's centre (mm and % of
//!   the camera–board distance);
//! - the fused mesh against the true mesh both ways over the surface the views saw: model → truth
//!   from the model's seen faces (area-weighted samples), truth → model from samples of the true
//!   surface within the unseen distance of a registered point (so holes count);
//! - watertight, manifold vertices, components, volume against the true mesh's, and which way
//!   the model is off: the mean signed distance of its faces from the truth, seen and unseen.
//!
//! With `--on-truth` every point is first moved onto the true surface (its nearest point there):
//! what is then left of the poses' and the mesh's errors is the merge's own, not the points'.
//! With `--sheet MM` the views are read as `merge --sheet MM` reads them: each frame's points
//! moved to where a light sheet of that thickness (σ) has its middle on the surface. With
//! `--turntable DEG` they are registered with `merge --turntable DEG`'s hint.
//!
//! Prints the table docs/reports.md quotes.

use std::path::{Path, PathBuf};

use scanner_core::nalgebra::{Isometry3, Point3};
use scanner_merge::{MergeOptions, Progress, Registered, Stage};
use scanner_rig::{Scene, Shape, compare};

/// Keeps the points the fusion takes (the registered views, less the isolated and the
/// contradicted points), which tell the surface the views saw.
#[derive(Default)]
struct Fused(Vec<Point3<f64>>);

impl Progress for Fused {
    fn stage(&mut self, _: Stage) {}
    fn registered(&mut self, r: &Registered<'_>) {
        self.0 = r.fused.to_vec();
    }
}

/// The surface within this distance of a registered point counts as seen, mm.
const SEEN_MM: f64 = 1.5;

fn main() {
    if let Err(e) = run() {
        eprintln!("merge_report: {e}");
        std::process::exit(1);
    }
}

fn run() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // --on-truth: every point moved onto the true surface (its nearest point there) before the
    // merge, so that what is left of the poses' errors is the registration's own.
    let on_truth = args.iter().any(|a| a == "--on-truth");
    args.retain(|a| a != "--on-truth");
    // --sheet MM: the views read as `merge --sheet MM` reads them (the light sheet's thickness).
    let mut sheet_mm = 0.0;
    if let Some(i) = args.iter().position(|a| a == "--sheet") {
        let v = args
            .get(i + 1)
            .ok_or_else(|| anyhow::anyhow!("--sheet needs the sheet's thickness in mm"))?;
        sheet_mm = v.parse().map_err(|e| anyhow::anyhow!("--sheet {v}: {e}"))?;
        args.drain(i..=i + 1);
    }
    // --turntable DEG: the views merged with `merge --turntable DEG`'s hint.
    let mut turntable = None;
    if let Some(i) = args.iter().position(|a| a == "--turntable") {
        let v = args
            .get(i + 1)
            .ok_or_else(|| anyhow::anyhow!("--turntable needs the step in degrees"))?;
        turntable = Some(
            v.parse()
                .map_err(|e| anyhow::anyhow!("--turntable {v}: {e}"))?,
        );
        args.drain(i..=i + 1);
    }
    let mut args = args.into_iter();
    let out = PathBuf::from(args.next().ok_or_else(|| {
        anyhow::anyhow!(
            "usage: merge_report OUT [SCENE] (OUT: the folder scripts/scan-rig-360 wrote)"
        )
    })?);
    let scene_path = args.next().map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../scanner-device/scenes/bunny-360.toml"),
        PathBuf::from,
    );
    let text = std::fs::read_to_string(&scene_path)
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene_path.display()))?;
    let scene = Scene::from_toml_in(&text, scene_path.parent().unwrap_or(Path::new(".")))
        .map_err(|e| anyhow::anyhow!("{}: {e}", scene_path.display()))?;
    let n = scene.view_count();
    let cell: scanner_host::grid::Cell = "2px".parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let t0 = std::time::Instant::now();
    let mut views = Vec::new();
    for k in 0..n {
        views.push(
            scanner_host::views::load_view(k, &out.join(format!("view{k}")), cell, sheet_mm)
                .map_err(|e| anyhow::anyhow!("{e}"))?,
        );
    }
    if on_truth {
        for (k, v) in views.iter_mut().enumerate() {
            let placed = placed(&scene, k)?;
            for p in &mut v.cloud.points {
                *p = placed.closest(p).unwrap_or(*p);
            }
        }
    }
    // As scripts/scan-rig-360 merges: 30 % overlap asked, the defaults otherwise.
    let opts = MergeOptions {
        min_overlap: 0.3,
        turntable_deg: turntable,
        ..MergeOptions::default()
    };
    let mut input = Fused::default();
    let merged =
        scanner_merge::run(&views, &opts, &mut input).map_err(|e| anyhow::anyhow!("{e}"))?;
    let fusion = merged
        .report
        .fusion
        .clone()
        .ok_or_else(|| anyhow::anyhow!("the merge made no model"))?;
    let seconds = t0.elapsed().as_secs_f64();
    let distance = scene.board.distance;
    let pct = |mm: f64| 100.0 * mm / distance;

    // The truth: the object as placed in view 0 (camera frame), and each view's pose into it.
    let true_pose = |k: usize| -> anyhow::Result<Isometry3<f64>> {
        let p0 = scene
            .view(0)
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .object_pose;
        let pk = scene
            .view(k)
            .map_err(|e| anyhow::anyhow!("{e}"))?
            .object_pose;
        Ok(p0 * pk.inverse())
    };
    let truth = placed(&scene, 0)?;
    let centre = truth.centroid();
    println!(
        "{} views of {} from {} (camera–board distance {distance:.0} mm); merged in {seconds:.1} s",
        n,
        scene_path.display(),
        out.display()
    );
    // Each view's points against the true surface as the rig placed it in that view.
    println!(
        "view | clear of its edges: points, median, p99, over 0.5 mm | on its edges: points, median, p99, over 0.5 mm"
    );
    for (k, v) in views.iter().enumerate() {
        let placed = placed(&scene, k)?;
        let mut parts = [Vec::new(), Vec::new()];
        // Clear of the edges: at least half the grid cells averaged into the point are.
        for (p, c) in v.cloud.points.iter().zip(&v.clearance) {
            parts[usize::from(*c < 0.5)].push(placed.distance(p));
        }
        let cols: Vec<String> = parts
            .iter_mut()
            .map(|d| {
                d.sort_by(f64::total_cmp);
                let q = |f: f64| d.get(((d.len().max(1) - 1) as f64 * f) as usize).copied();
                format!(
                    "{}, {:.3} mm, {:.3} mm, {}",
                    d.len(),
                    q(0.5).unwrap_or(f64::NAN),
                    q(0.99).unwrap_or(f64::NAN),
                    d.iter().filter(|&&x| x > 0.5).count()
                )
            })
            .collect();
        println!("{k} | {} | {}", cols[0], cols[1]);
    }
    // Each view's clear points alone, placed by the view's true pose and fitted onto the true
    // surface (point-to-plane ICP): how far the points' own shape turns and moves the view, which
    // no registration of the views onto each other can take out.
    let surface = surface_cloud(&truth);
    let mut alone = Vec::with_capacity(n);
    for (k, v) in views.iter().enumerate() {
        let fit = scanner_merge::pose::icp(&v.clear_cloud(), &surface, true_pose(k)?, 2.0, 40);
        alone.push(fit.pose);
    }
    let turn = |e: &Isometry3<f64>| {
        let axis = e.rotation.scaled_axis().map(f64::to_degrees);
        let moved = (e * centre - centre).norm();
        (
            e.rotation.angle().to_degrees(),
            moved,
            format!(
                "{:.4}° (x {:+.3}, y {:+.3}, z {:+.3}), {moved:.3} mm",
                e.rotation.angle().to_degrees(),
                axis.x,
                axis.y,
                axis.z
            ),
        )
    };
    println!(
        "view | points | pose error: rotation (about x, y, z), centre displaced | its points alone fitted onto the truth"
    );
    let (mut worst_rot, mut worst_move, mut worst_alone) = (0.0f64, 0.0f64, 0.0f64);
    for (k, (pose, r)) in merged.poses.iter().zip(&merged.report.views).enumerate() {
        let (rot, moved, err) = turn(&(pose * true_pose(k)?.inverse()));
        let (rot_alone, _, fit) = turn(&(alone[k] * true_pose(k)?.inverse()));
        worst_rot = worst_rot.max(rot);
        worst_move = worst_move.max(moved);
        worst_alone = worst_alone.max(rot_alone);
        println!("{k} | {} | {err} ({:.4} %) | {fit}", r.points, pct(moved));
    }
    println!(
        "worst view: {worst_rot:.4}° (target 0.05°), {worst_move:.3} mm = {:.4} % (target 0.05 %)",
        pct(worst_move)
    );
    println!(
        "each view's points alone, fitted onto the truth, turn it by up to {worst_alone:.4}° off its true pose (what the points themselves allow)"
    );
    let c = &merged.report.closure;
    println!(
        "loop closure ({} pairs): {:?} before the joint refinement, {:?} after",
        c.pairs, c.before, c.after
    );

    // Model → truth over the seen faces; truth → model over the true surface the views saw.
    // "Seen": within SEEN_MM of a registered point (the points lie about 1 mm apart), and, as a
    // looser reading, within the fusion's unseen distance (3 cells), which takes in the
    // closing patches along the gaps' rims.
    println!(
        "surface no view saw: {:.1} % of the model's area (closed by the winding number)",
        100.0 * fusion.unseen_share
    );
    let model = &merged.model;
    let model_tris: Vec<[Point3<f64>; 3]> = model
        .faces
        .iter()
        .map(|f| f.map(|i| model.vertices[i as usize].cast()))
        .collect();
    for reach in [SEEN_MM, fusion.unseen_reach_mm] {
        let seen = compare::Seen::new(&input.0, reach);
        let c = compare::compare(&model_tris, &truth, &seen, 0.5);
        let line = |name: &str, d: &compare::Distances| {
            println!(
                "  {name}: {:.0} mm², mean {:.4} mm ({:.4} %), p99 {:.3} mm ({:.4} %), max {:.3} mm",
                d.area_mm2,
                d.mean,
                pct(d.mean),
                d.p99,
                pct(d.p99),
                d.max
            );
        };
        println!("seen = within {reach:.1} mm of a registered point:");
        line("model → truth", &c.to_truth);
        line("truth → model", &c.to_model);
        println!(
            "  both ways: mean {:.4} % (target 0.03 %), p99 {:.4} % (target 0.15 %)",
            pct(c.to_truth.mean.max(c.to_model.mean)),
            pct(c.to_truth.p99.max(c.to_model.p99))
        );
    }
    // Which way the model is off: the area-weighted mean of its faces' signed distances from
    // the truth (positive outside), over the seen faces and over the others.
    let mut signed = [(0.0, 0.0); 2];
    let seen = compare::Seen::new(&input.0, SEEN_MM);
    for t in &model_tris {
        let c = Point3::from((t[0].coords + t[1].coords + t[2].coords) / 3.0);
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let (area, Some(on)) = (n.norm() / 2.0, truth.closest(&c)) else {
            continue;
        };
        if area <= 0.0 {
            continue;
        }
        let s = &mut signed[usize::from(!seen.contains(&c))];
        s.0 += area * (c - on).dot(&n.normalize());
        s.1 += area;
    }
    let [(a, wa), (b, wb)] = signed;
    println!(
        "model off the truth (signed, + outside): seen faces mean {:+.4} mm over {wa:.0} mm², unseen {:+.4} mm over {wb:.0} mm² (volume {:+.0} and {:+.0} mm³)",
        a / wa.max(1e-9),
        b / wb.max(1e-9),
        a,
        b
    );
    let c = fusion.check;
    let true_volume = compare::volume(truth.triangles());
    println!(
        "mesh: {} vertices, {} faces; open edges {}, non-manifold vertices {}, components {}; volume {:.0} mm³ against {true_volume:.0} mm³ true ({:+.2} %, target ±0.5 %)",
        model.vertices.len(),
        model.faces.len(),
        c.open_edges,
        c.nonmanifold_vertices,
        c.components,
        c.volume_mm3,
        100.0 * (c.volume_mm3 / true_volume - 1.0)
    );
    Ok(())
}

/// The object as the rig placed it in view `k` (camera frame).
fn placed(scene: &Scene, k: usize) -> anyhow::Result<std::sync::Arc<scanner_rig::mesh::SceneMesh>> {
    match scene
        .view(k)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .objects
        .first()
        .map(|o| o.shape.clone())
    {
        Some(Shape::Mesh(m)) => Ok(m),
        _ => Err(anyhow::anyhow!("the scene's first object is not a mesh")),
    }
}

/// Points with normals over the true surface: every face sampled on a triangular lattice (45
/// points a face, about 0.5 mm apart on the bunny), for fitting views onto it.
fn surface_cloud(truth: &scanner_rig::mesh::SceneMesh) -> scanner_merge::spatial::Cloud {
    const M: usize = 8;
    let mut c = scanner_merge::spatial::Cloud::default();
    for t in truth.triangles() {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        if n.norm() <= 0.0 {
            continue;
        }
        for i in 0..=M {
            for j in 0..=M - i {
                let (a, b) = (i as f64 / M as f64, j as f64 / M as f64);
                c.points.push(t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b);
                c.normals.push(n.normalize());
            }
        }
    }
    c
}
