//! Speed of a 360° merge (the target: 8 views of 50 000 points each registered and fused in
//! ≤ 10 s on one core): `cargo bench -p scanner-merge --bench merge` (run it pinned,
//! `taskset -c 1`). On eight synthetic views of a lumpy closed surface (about 60 mm across)
//! turned by 45° about the vertical, each view the half of the surface that faces its camera,
//! 50 000 points with exact normals: first the stages one by one as [`scanner_merge::run`] runs
//! them after the views are read — thinning, every pair registered without a guess and the
//! agreeing candidates chosen, the joint refinement (and the turns about one axis it finds), the
//! free-space check, the edge points, the outlier filter and the fusion — each stage's time and
//! each view's error against the truth; then the whole of `run` (which adds the loop-closure
//! check and the free-space check inside the registration's choice); then, not in the total,
//! the registration and the joint refinement with the turntable's step (`merge --turntable
//! 45`).

use std::time::Instant;

use scanner_core::nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use scanner_merge::depth::{DepthMap, conflicts};
use scanner_merge::fuse::{check, fuse_with};
use scanner_merge::fuse::{contradicted, edge_weight, fused_points};
use scanner_merge::pose::RegisterOptions;
use scanner_merge::pose::register_clouds;
use scanner_merge::refine::{GIVEN_STEP, Turns, found_turns, refine, refine_turns};
use scanner_merge::spatial::Cloud;
use scanner_merge::{MergeOptions, ScanPoints, View};

const VIEWS: usize = 8;
const POINTS: usize = 50_000;

/// Bumps on the surface: (azimuth °, elevation °, height, width) — different on every side, so
/// that no view looks like another.
const BUMPS: [(f64, f64, f64, f64); 6] = [
    (0.0, 10.0, 0.35, 0.25),
    (70.0, -25.0, 0.25, 0.35),
    (150.0, 30.0, 0.4, 0.2),
    (220.0, -5.0, 0.3, 0.3),
    (290.0, 40.0, 0.2, 0.25),
    (330.0, -40.0, 0.3, 0.2),
];

/// The surface's radius in the direction `d` (unit): a sphere of 30 mm with lumps and bumps.
fn radius(d: &Vector3<f64>) -> f64 {
    let bumps: f64 = BUMPS
        .iter()
        .map(|&(az, el, h, w)| {
            let (az, el) = (az.to_radians(), el.to_radians());
            let c = Vector3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
            h * (-(d - c).norm_squared() / (w * w)).exp()
        })
        .sum();
    30.0 * (1.0 + 0.1 * (3.0 * d.x).sin() * (2.0 * d.y).cos() + bumps)
}

/// The surface point and outward normal in direction `d` (normal by central differences).
fn surface(d: &Vector3<f64>) -> (Point3<f64>, Vector3<f64>) {
    let at = |v: Vector3<f64>| {
        let v = v.normalize();
        v * radius(&v)
    };
    let p = at(*d);
    // two tangents
    let a = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let (t1, t2) = (d.cross(&a).normalize(), d.cross(&d.cross(&a)).normalize());
    let h = 1e-4;
    let du = at(d + t1 * h) - at(d - t1 * h);
    let dv = at(d + t2 * h) - at(d - t2 * h);
    let mut n = du.cross(&dv).normalize();
    if n.dot(&p) < 0.0 {
        n = -n;
    }
    (Point3::from(p), n)
}

/// The object's pose in view `k`'s camera: turned by 45° k about the vertical, 500 mm ahead.
fn pose(k: usize) -> Isometry3<f64> {
    Translation3::new(0.0, 0.0, 500.0)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), (45.0 * k as f64).to_radians())
}

/// View `k`: the points the camera at the origin sees (normal facing it), in its frame.
fn view(k: usize) -> Cloud {
    let pose = pose(k);
    let mut c = Cloud::default();
    // a Fibonacci sphere of directions, dense enough that the visible half holds POINTS
    let n = 2 * POINTS + 20_000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..n {
        if c.points.len() == POINTS {
            break;
        }
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - y * y).sqrt();
        let t = golden * i as f64;
        let (p, nrm) = surface(&Vector3::new(r * t.cos(), y, r * t.sin()));
        let (p, nrm) = (pose * p, pose * nrm);
        if nrm.dot(&-p.coords.normalize()) > 0.15 {
            c.points.push(p);
            c.normals.push(nrm);
        }
    }
    c
}

/// The worst view's rotation (degrees) and translation (mm) off the truth, view 0 fixing the
/// frame.
fn worst_view(poses: &[Isometry3<f64>]) -> (f64, f64) {
    (1..VIEWS)
        .map(|k| {
            let truth = pose(0) * pose(k).inverse();
            let d = truth.inverse() * poses[k];
            (d.rotation.angle().to_degrees(), d.translation.vector.norm())
        })
        .fold((0.0f64, 0.0f64), |a, b| (a.0.max(b.0), a.1.max(b.1)))
}

fn main() {
    let t = Instant::now();
    let clouds: Vec<Cloud> = (0..VIEWS).map(view).collect();
    println!(
        "{VIEWS} views of {} points each (made in {:.1} s)",
        clouds[0].points.len(),
        t.elapsed().as_secs_f64()
    );
    let o = RegisterOptions::default();
    let t0 = Instant::now();
    // As `merge` takes each view: thinned when it is made.
    let views: Vec<View> = clouds
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let surface = ScanPoints {
                cloud: c.clone(),
                ..ScanPoints::default()
            };
            View::new(format!("view {k}"), header(), &surface, None)
        })
        .collect();
    let clouds: Vec<Cloud> = views.iter().map(|v| v.cloud.clone()).collect();
    let t_thin = t0.elapsed().as_secs_f64();
    let refs: Vec<&Cloud> = clouds.iter().collect();
    // As `merge` registers: every pair's candidates, the agreeing set chosen, the fine fits.
    let mut pairs = 0;
    let placed = register_clouds(&refs, &o, |_, _| Vec::new(), |_| None, |_, all| pairs = all)
        .expect("the views register");
    let poses: Vec<Isometry3<f64>> = placed.iter().map(|r| r.pose).collect();
    let t_chain = t0.elapsed().as_secs_f64() - t_thin;
    let t1 = Instant::now();
    let free = refine(&refs, &poses, o.voxel_mm, 8, |_| {});
    // As `merge` does without a hint: views whose poses are turns about one axis refined again
    // as such turns (and kept if they fit as well).
    let (poses, found) = found_turns(&refs, free, o.voxel_mm);
    let t_joint = t1.elapsed().as_secs_f64();
    // As `merge` checks the poses: every view's points against every other's free space, seen
    // by a 1280×960 camera of f = 1120 px.
    let t4 = Instant::now();
    let tol = scanner_merge::free::tolerance(o.voxel_mm);
    let worst = conflicts(&refs, &poses, tol, |k| {
        DepthMap::of(
            &clouds[k].points,
            [1120.0, 1120.0, 639.5, 479.5],
            (1280, 960),
        )
    })
    .into_iter()
    .map(|c| c.share())
    .fold(0.0, f64::max);
    let t_seen = t4.elapsed().as_secs_f64();
    // As `merge` leaves edge points off another view's clear surface out of the fusion: here
    // the points seen at a slant (the view's rims) stand for the edge points.
    let t5 = Instant::now();
    let clear: Vec<Vec<f64>> = clouds
        .iter()
        .map(|c| {
            c.points
                .iter()
                .zip(&c.normals)
                .map(|(p, n)| f64::from(u8::from(n.dot(&-p.coords.normalize()) > 0.3)))
                .collect()
        })
        .collect();
    let clear_refs: Vec<&[f64]> = clear.iter().map(|c| &c[..]).collect();
    let off = contradicted(&refs, &clear_refs, &poses);
    let edges = clear.iter().flatten().filter(|&&c| c < 1.0).count();
    let t_edges = t5.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let (mut points, mut normals) = (Vec::new(), Vec::new());
    for (c, p) in clouds.iter().zip(&poses) {
        points.extend(c.points.iter().map(|q| p * q));
        normals.extend(c.normals.iter().map(|n| p * n));
    }
    // As `merge` chooses the points it fuses: not isolated, not contradicted, not off_surface.
    let weights: Vec<f64> = clear
        .iter()
        .flatten()
        .map(|&c| edge_weight(Some(c)))
        .collect();
    let (keep, off_surface_count) = fused_points(&points, &normals, &weights, &off);
    let points: Vec<Point3<f64>> = keep.iter().map(|&i| points[i]).collect();
    let normals: Vec<Vector3<f64>> = keep.iter().map(|&i| normals[i]).collect();
    let weights: Vec<f64> = keep.iter().map(|&i| weights[i]).collect();
    let t_filter = t2.elapsed().as_secs_f64();
    let t3 = Instant::now();
    // As `merge` fuses: the edge points weighed down.
    let mesh = fuse_with(&points, &normals, &weights, 1.0, |_, _| {}).expect("fusion");
    let t_fuse = t3.elapsed().as_secs_f64();
    let total = t0.elapsed().as_secs_f64();
    let c = check(&mesh);
    println!("| stage | seconds |\n|---|---|");
    println!(
        "| thinning to 0.75 mm cubes ({} points a view) | {t_thin:.2} |",
        clouds[0].points.len()
    );
    println!(
        "| registration, {pairs} pairs without a guess, the agreeing set chosen | {t_chain:.2} |"
    );
    println!(
        "| joint refinement, 8 rounds, then the turns found ({} views as turns about one axis) | {t_joint:.2} |",
        found.map_or(0, |t| t.views.len())
    );
    println!(
        "| free-space check (worst: {:.2} % of a view's points in front of another's surface) | {t_seen:.2} |",
        100.0 * worst
    );
    println!(
        "| edge points against the others' clear surfaces ({} of {edges} left out) | {t_edges:.2} |",
        off.iter().filter(|&&o| o).count()
    );
    println!(
        "| outlier filter and edge points off the surface by the winding number ({off_surface_count} left out; {} points) | {t_filter:.2} |",
        keep.len()
    );
    println!(
        "| fusion, 1 mm cells ({} vertices, {}, {} component(s)) | {t_fuse:.2} |",
        mesh.vertices.len(),
        if c.watertight { "watertight" } else { "open" },
        c.components
    );
    println!("| **total** (target ≤ 10 s) | **{total:.2}** |");
    let worst = worst_view(&poses);
    println!(
        "worst view against the truth: {:.4}° {:.3} mm",
        worst.0, worst.1
    );
    // The whole entry point, as `scanner-host merge` calls it once the views are read.
    let t9 = Instant::now();
    let merged = scanner_merge::run(&views, &MergeOptions::default(), &mut ()).expect("run");
    let t_run = t9.elapsed().as_secs_f64();
    let worst = worst_view(&merged.poses);
    println!(
        "`scanner_merge::run` on the same views (thinning included; also the loop closure and the free-space check inside the choice): {t_run:.2} s; worst view {:.4}° {:.3} mm; model watertight: {}",
        worst.0,
        worst.1,
        merged.report.fusion.is_some_and(|f| f.check.watertight)
    );
    // With the turntable's step (`merge --turntable 45`): each pair also tries the step's turns
    // (placed across the axis, as `merge` places them), and the views on the turntable are
    // refined as turns about one axis.
    let t7 = Instant::now();
    let hints = |a: usize, b: usize| {
        let angle = 45.0 * (a as f64 - b as f64);
        scanner_merge::pose::turntable_motions(&Vector3::y(), refs[a], refs[b], angle).to_vec()
    };
    let stepped = register_clouds(&refs, &o, hints, |_| None, |_, _| {})
        .expect("the views register with the step");
    let t_step = t7.elapsed().as_secs_f64();
    let t8 = Instant::now();
    let on: Vec<bool> = stepped.iter().map(|r| r.on_turntable).collect();
    let start: Vec<Isometry3<f64>> = stepped.iter().map(|r| r.pose).collect();
    let turns = Turns::fit(&start, &on, GIVEN_STEP);
    let as_turns = turns.as_ref().map_or(0, |t| t.views.len());
    let (turned, _) = refine_turns(&refs, &start, turns, o.voxel_mm, 8, |_| {});
    let t_turns = t8.elapsed().as_secs_f64();
    let worst = worst_view(&turned);
    println!(
        "with the turntable's step (`--turntable 45`, not in the total): registration {t_step:.2} s, \
         joint refinement with {as_turns} views as turns about one axis {t_turns:.2} s; worst view \
         {:.4}° {:.3} mm",
        worst.0, worst.1
    );
}

/// The header of a 1280×960 camera of f = 1120 px before a board 600 mm away.
fn header() -> scanner_wire::Header {
    let camera = scanner_core::Camera::new(
        1120.0,
        1120.0,
        639.5,
        479.5,
        scanner_core::Distortion::none(),
    )
    .expect("a camera");
    let plane = |x: f64| {
        scanner_core::geometry::Plane::new(Vector3::new(x, 0.0, -0.707), 600.0 * 0.707)
            .expect("a plane")
    };
    let board = scanner_core::geometry::Board::new(plane(0.707), plane(-0.707)).expect("a board");
    scanner_wire::Header::new(
        1,
        (1280, 960),
        (&camera).into(),
        (&board).into(),
        false,
        scanner_wire::PlaneMethod::LeastSquares,
    )
}
