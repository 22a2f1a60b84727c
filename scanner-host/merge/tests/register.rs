//! Registration of two views without an initial guess (issue 17, first stage): the rig's bunny
//! in views turned by 60°, 180° and laid on its side, each view's lit surface points taken from
//! the rig's truth (the stripe's exact points, so that this tests the registration alone), and a
//! view of another object that must be reported, not merged.

use scanner_core::nalgebra::Isometry3;
use scanner_merge::error::RegisterError;
use scanner_merge::pose::{RegisterOptions, register};
use scanner_merge::spatial::{Cloud, normals};
use scanner_rig::{Rig, Scene, SurfaceId};

fn bunny_views() -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scanner-device/scenes/bunny-360.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    Scene::from_toml_in(&text, path.parent().unwrap()).unwrap()
}

/// View `k`'s lit object points (every other frame) with estimated normals, and its true pose.
fn view_cloud(scene: &Scene, k: usize) -> (Cloud, Isometry3<f64>) {
    let mut v = scene.view(k).unwrap();
    v.camera = Scene::demo(640, 480).camera;
    (v.width, v.height) = (640, 480);
    let pose = v.object_pose;
    let rig = Rig::new(v).unwrap();
    let points: Vec<_> = (0..rig.scene().laser.frames)
        .step_by(2)
        .flat_map(|f| rig.truth(f).unwrap())
        .flatten()
        .filter(|t| matches!(t.surface, SurfaceId::Object(_)))
        .map(|t| t.point)
        .collect();
    let normals = normals(&points, 12);
    (Cloud { points, normals }, pose)
}

fn angle_deg(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.rotation.angle().to_degrees(), d.translation.vector.norm())
}

#[test]
fn views_turned_by_large_angles_register_without_a_guess() {
    let mut scene = bunny_views();
    // One more view: upside down, turned 180° about the camera's axis (view 7).
    let centre = scene.view(0).unwrap().objects[0].shape.centre();
    scene.views.push(
        scanner_core::nalgebra::Translation3::from(centre.coords)
            * scanner_core::nalgebra::UnitQuaternion::from_axis_angle(
                &scanner_core::nalgebra::Vector3::z_axis(),
                std::f64::consts::PI,
            )
            * scanner_core::nalgebra::Translation3::from(-centre.coords),
    );
    // Neighbouring sweeps overlap: 60° apart about the vertical, on its side (90° about the
    // viewing axis), upside down (180°).
    for (k, j) in [(1, 0), (3, 2), (6, 0), (7, 0)] {
        let (target, posej) = view_cloud(&scene, j);
        let (source, posek) = view_cloud(&scene, k);
        let truth = posej * posek.inverse();
        let t0 = std::time::Instant::now();
        let r = register(&source, &target, &RegisterOptions::default())
            .unwrap_or_else(|e| panic!("view {k}: {e}"));
        let (rot, trans) = angle_deg(&truth, &r.pose);
        println!(
            "view {k} → {j}: {} and {} points, overlap {:.0} %, rms {:.3} mm, error {rot:.4}° {trans:.3} mm ({:.1} s)",
            source.points.len(),
            target.points.len(),
            100.0 * r.overlap,
            r.rms_mm,
            t0.elapsed().as_secs_f64()
        );
        // 0.05 % of the 800 mm camera–board distance is 0.4 mm.
        assert!(
            rot < 0.05 && trans < 0.4,
            "view {k}: off by {rot}° and {trans} mm"
        );
    }
}

#[test]
fn a_turntable_hint_registers_alone_and_is_never_required() {
    use scanner_merge::pose::{register_hinted, turntable_motions};
    let scene = bunny_views();
    let (target, pose0) = view_cloud(&scene, 0);
    let (source, pose1) = view_cloud(&scene, 1);
    let truth = pose0 * pose1.inverse();
    // Without descriptors (no RANSAC trials) nothing is found…
    let blind = RegisterOptions {
        trials: 0,
        ..RegisterOptions::default()
    };
    assert!(register(&source, &target, &blind).is_err());
    // …but the turntable's 60° step about the board's vertical (−y here) is enough…
    let up = scanner_core::nalgebra::Vector3::new(0.0, -1.0, 0.0);
    let hints = turntable_motions(&up, &source, &target, 60.0);
    let r = register_hinted(&source, &target, &blind, &hints).expect("the hint registers");
    let (rot, trans) = angle_deg(&truth, &r.pose);
    println!("hint alone: {rot:.4}° {trans:.3} mm");
    assert!(rot < 0.05 && trans < 0.4, "off by {rot}° and {trans} mm");
    // …and a wrong step beside the descriptors' own guesses does not mislead them.
    let wrong = turntable_motions(&up, &source, &target, 100.0);
    let r = register_hinted(&source, &target, &RegisterOptions::default(), &wrong).unwrap();
    let (rot, trans) = angle_deg(&truth, &r.pose);
    assert!(
        rot < 0.05 && trans < 0.4,
        "a wrong hint: off by {rot}° and {trans} mm"
    );
}

/// A journal can hold any number of one exact point (a stuck stripe, a hostile file): kiddo's
/// k-d tree panics at the 33rd copy in a leaf, so the registration keeps 16 of each. Two views
/// of the bunny, each with 200 copies of one point added, still register, and a view that is
/// one point 200 times is refused with the reason, not a panic.
#[test]
fn views_with_many_copies_of_one_point_register_without_a_panic() {
    let scene = bunny_views();
    let (mut target, pose0) = view_cloud(&scene, 0);
    let (mut source, pose1) = view_cloud(&scene, 1);
    for c in [&mut target, &mut source] {
        let (p, n) = (c.points[0], c.normals[0]);
        c.points.extend(std::iter::repeat_n(p, 200));
        c.normals.extend(std::iter::repeat_n(n, 200));
    }
    let r = register(&source, &target, &RegisterOptions::default()).expect("registers");
    let (rot, trans) = angle_deg(&(pose0 * pose1.inverse()), &r.pose);
    assert!(rot < 0.05 && trans < 0.4, "off by {rot}° and {trans} mm");
    let one = Cloud {
        points: vec![source.points[0]; 200],
        normals: vec![source.normals[0]; 200],
    };
    assert!(matches!(
        register(&one, &target, &RegisterOptions::default()),
        Err(RegisterError::TooFewPoints { .. })
    ));
    // The same point 200 times in both views, beside their own: a thinned view keeps one of
    // them, the fine fit's trees hold 16.
    let r = scanner_merge::pose::fine(&source, &target, r.pose, &RegisterOptions::default());
    assert!(r.is_ok(), "{r:?}");
}

#[test]
fn views_of_opposite_sides_are_reported_not_merged() {
    let scene = bunny_views();
    let (target, _) = view_cloud(&scene, 0);
    let (source, _) = view_cloud(&scene, 3);
    match register(&source, &target, &RegisterOptions::default()) {
        Err(e @ RegisterError::NoOverlap { .. }) => println!("front and back: {e}"),
        other => panic!("the back registered onto the front: {other:?}"),
    }
}

#[test]
fn a_view_of_another_object_is_reported_not_merged() {
    let scene = bunny_views();
    let (target, _) = view_cloud(&scene, 0);
    let mut other = Scene::demo(640, 480);
    other.objects.truncate(1); // the demo's textured sphere alone
    let rig = Rig::new(other).unwrap();
    let points: Vec<_> = (0..60)
        .flat_map(|f| rig.truth(f).unwrap())
        .flatten()
        .filter(|t| matches!(t.surface, SurfaceId::Object(_)))
        .map(|t| t.point)
        .collect();
    let source = Cloud {
        normals: normals(&points, 12),
        points,
    };
    match register(&source, &target, &RegisterOptions::default()) {
        Err(e @ RegisterError::NoOverlap { .. }) => println!("{e}"),
        other => panic!("a sphere registered onto the bunny: {other:?}"),
    }
}

type Loop = scanner_merge::refine::LoopError;

/// The views that close the chain's loop: those not registered onto view 0 (all but view 1),
/// each onto view 0 directly.
const LOOPS: &[(usize, usize)] = &[(2, 0), (3, 0), (4, 0), (5, 0)];

/// The six views around the vertical with `noise` mm of noise along each point's normal, each
/// registered onto the one before (a chain of five links), then refined jointly: the loop
/// closure before and after, and the worst view's (rotation °, translation mm) against the truth
/// before and after.
fn chain_and_joint(sigma: f64) -> (Loop, Loop, (f64, f64), (f64, f64)) {
    use scanner_merge::refine::{loop_error, refine};
    let (clouds, chain, truth) = noisy_chain(sigma);
    let refs: Vec<&Cloud> = clouds.iter().collect();
    let before = loop_error(&refs, &chain, LOOPS, 3.0, 0.25).expect("view 5 overlaps view 0");
    let t0 = std::time::Instant::now();
    let joint = refine(&refs, &chain, 3.0, 8, |_| {});
    let took = t0.elapsed().as_secs_f64();
    let after = loop_error(&refs, &joint, LOOPS, 3.0, 0.25).expect("view 5 overlaps view 0");
    let (wb, wa) = (worst(&truth, &chain), worst(&truth, &joint));
    println!(
        "noise {sigma} mm: loop closure (view {}) {:.4}° {:.3} mm before, {:.4}° {:.3} mm after the joint refinement ({took:.1} s); worst view against the truth {:.4}° {:.3} mm before, {:.4}° {:.3} mm after",
        before.view,
        before.rotation_deg,
        before.translation_mm,
        after.rotation_deg,
        after.translation_mm,
        wb.0,
        wb.1,
        wa.0,
        wa.1
    );
    assert_eq!(before.view, after.view);
    (before, after, wb, wa)
}

/// The worst of `poses`' views against the `truth` (rotation °, translation mm).
fn worst(truth: &[Isometry3<f64>], poses: &[Isometry3<f64>]) -> (f64, f64) {
    (1..poses.len())
        .map(|k| angle_deg(&truth[k], &poses[k]))
        .fold((0.0f64, 0.0f64), |a, b| (a.0.max(b.0), a.1.max(b.1)))
}

/// The six views around the vertical with `sigma` mm of noise along each point's normal, each
/// registered onto the one before (a chain of five links): the clouds, the chain's poses in view
/// 0's frame and the true ones.
fn noisy_chain(sigma: f64) -> (Vec<Cloud>, Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let scene = bunny_views();
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    let noise = Normal::new(0.0, sigma).unwrap();
    let (mut clouds, mut truths) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let (mut c, pose) = view_cloud(&scene, k);
        for (p, n) in c.points.iter_mut().zip(&c.normals) {
            *p += n * noise.sample(&mut rng);
        }
        c.normals = normals(&c.points, 12);
        clouds.push(c);
        truths.push(pose);
    }
    let truth = |k: usize| truths[0] * truths[k].inverse();
    let mut chain = vec![Isometry3::identity()];
    for k in 1..6 {
        // 60° apart, a sweep from one side shares only a third of its points with the next:
        // 25 % asked here (the default asks 40 %)
        let o = RegisterOptions {
            min_overlap: 0.25,
            ..RegisterOptions::default()
        };
        let r =
            register(&clouds[k], &clouds[k - 1], &o).unwrap_or_else(|e| panic!("view {k}: {e}"));
        chain.push(chain[k - 1] * r.pose);
    }
    let truth = (0..6).map(truth).collect();
    (clouds, chain, truth)
}

/// The six views as on a turntable, refined as turns about one axis (what `merge --turntable`
/// does with the views on it): the poses are turns about one axis, that axis is the rig's
/// vertical (0.023° off in one run), each angle its view's turn within 0.05°, and with 0.15 mm
/// of noise on every point the worst view ends nearer the truth than the free joint refinement
/// leaves it (one run: 0.058° / 0.47 mm against 0.063° / 0.53 mm; what noise leaves of each
/// turn's angle stays).
#[test]
fn views_on_a_turntable_are_refined_as_turns_about_one_axis() {
    use scanner_merge::refine::{GIVEN_STEP, Turns, refine, refine_turns};
    let (clouds, chain, truth) = noisy_chain(0.15);
    let refs: Vec<&Cloud> = clouds.iter().collect();
    let free = refine(&refs, &chain, 3.0, 8, |_| {});
    let start =
        Turns::fit(&chain, &[true; 6], GIVEN_STEP).expect("six views turned about one axis");
    assert_eq!(start.views, [1, 2, 3, 4, 5]);
    assert!(Turns::fit(&chain, &[false, true, true, true, true, true], GIVEN_STEP).is_none());
    // A view flagged on the turntable that is not one of its turns (laid on its side, 90° about
    // the camera's z; or turned 3° off the axis) is left out of them.
    {
        use scanner_core::nalgebra::{Translation3, UnitQuaternion, Vector3};
        let mut poses = chain.clone();
        let side = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 90f64.to_radians());
        poses.push(Isometry3::from_parts(
            Translation3::new(0.0, 10.0, 0.0),
            side,
        ));
        let tilt = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 3f64.to_radians());
        poses[2] = Isometry3::from_parts(poses[2].translation, tilt * poses[2].rotation);
        let fitted = Turns::fit(&poses, &[true; 7], GIVEN_STEP).expect("the others are turns");
        assert_eq!(fitted.views, [1, 3, 4, 5]);
    }
    let (turned, turns) = refine_turns(&refs, &chain, Some(start), 3.0, 8, |_| {});
    let turns = turns.expect("the turns, refined");
    let vertical = truth[1].rotation.axis().unwrap();
    let tilt = turns
        .axis
        .angle(&vertical)
        .min(turns.axis.angle(&-vertical));
    for (i, &k) in turns.views.iter().enumerate() {
        assert_eq!(
            turned[k],
            turns.pose(i),
            "view {k} is not the turn it was given"
        );
        let want = truth[k].rotation.angle().to_degrees();
        let got = turns.angles[i].to_degrees().abs();
        let got = if got > 180.0 { 360.0 - got } else { got };
        assert!((got - want).abs() < 0.05, "view {k}: {got}° for {want}°");
    }
    let (wf, wt) = (worst(&truth, &free), worst(&truth, &turned));
    println!(
        "axis {:.4}° off the vertical; worst view {:.4}° {:.3} mm refined freely, {:.4}° {:.3} mm as turns",
        tilt.to_degrees(),
        wf.0,
        wf.1,
        wt.0,
        wt.1
    );
    assert!(tilt.to_degrees() < 0.05, "axis {}° off", tilt.to_degrees());
    assert!(wt.0 < wf.0 && wt.1 < wf.1, "{wf:?} → {wt:?}");
}

/// Without a hint the merge finds views that are turns about one axis (`found_turns`): the six
/// noisy views as on a turntable are refined as turns, and the worst view ends nearer the truth
/// than the free joint refinement leaves it; the same views with the object slid by about a
/// millimetre between sweeps (turned by hand on a table) fit together as well but are no turns
/// about one axis: they are not taken for a turntable's and keep their free poses.
#[test]
fn turns_about_one_axis_are_found_without_a_hint_and_slid_views_are_not() {
    use scanner_core::nalgebra::{Translation3, Vector3};
    use scanner_merge::refine::{found_turns, refine};
    let (clouds, chain, truth) = noisy_chain(0.15);
    let refs: Vec<&Cloud> = clouds.iter().collect();
    let free = refine(&refs, &chain, 3.0, 8, |_| {});
    let (turned, turns) = found_turns(&refs, free.clone(), 3.0);
    let turns = turns.expect("six views on a turntable are found to be turns");
    assert_eq!(turns.views, [1, 2, 3, 4, 5]);
    let (wf, wt) = (worst(&truth, &free), worst(&truth, &turned));
    println!(
        "worst view {:.4}° {:.3} mm refined freely, {:.4}° {:.3} mm as the turns found",
        wf.0, wf.1, wt.0, wt.1
    );
    assert!(wt.0 < wf.0 && wt.1 < wf.1, "{wf:?} → {wt:?}");
    // Each view's points moved by its slide in its own frame, its pose by the opposite.
    let slides = [
        [0.0, 0.0, 0.0],
        [0.8, 0.0, 0.6],
        [-0.7, 0.0, 0.7],
        [-0.9, 0.0, -0.4],
        [0.5, 0.0, -0.9],
        [1.0, 0.0, 0.2],
    ]
    .map(Vector3::from);
    let slid: Vec<Cloud> = clouds
        .iter()
        .zip(&slides)
        .map(|(c, s)| Cloud {
            points: c.points.iter().map(|p| p + s).collect(),
            normals: c.normals.clone(),
        })
        .collect();
    let slid_poses: Vec<Isometry3<f64>> = free
        .iter()
        .zip(&slides)
        .map(|(p, s)| p * Translation3::from(-s))
        .collect();
    let refs: Vec<&Cloud> = slid.iter().collect();
    let (kept, turns) = found_turns(&refs, slid_poses.clone(), 3.0);
    assert!(turns.is_none(), "slid views taken for turns: {turns:?}");
    assert_eq!(kept, slid_poses);
}

/// Exact stripe points: after the joint refinement every view is well within the 0.05°
/// and 0.05 % of the 800 mm distance (0.4 mm) of the truth (one run: 0.0099° and 0.069 mm; 0.030°
/// and 0.28 mm when views were moved one at a time), and the loop closes better.
#[test]
fn the_joint_refinement_closes_the_loop_of_views_around_the_object() {
    let (before, after, _, wa) = chain_and_joint(0.0);
    assert!(
        after.rotation_deg < 0.6 * before.rotation_deg,
        "{before:?} → {after:?}"
    );
    assert!(
        after.translation_mm < 0.5 * before.translation_mm,
        "{before:?} → {after:?}"
    );
    assert!(wa.0 < 0.025 && wa.1 < 0.2, "after: {wa:?}");
}

/// 0.15 mm of noise on every point (a single stripe at 640×480, no grid averaging): the chain's
/// errors add up to a loop that misses by a quarter of a degree; the refinement closes most of it
/// and moves no view away from the truth: the worst view 0.063° off in one run (0.12° when views
/// were moved one at a time; the 0.05° target is not met at this noise).
#[test]
fn the_joint_refinement_spreads_a_noisy_chains_error_over_the_loop() {
    let (before, after, wb, wa) = chain_and_joint(0.15);
    assert!(
        after.rotation_deg < 0.5 * before.rotation_deg,
        "{before:?} → {after:?}"
    );
    assert!(
        after.translation_mm < 0.5 * before.translation_mm,
        "{before:?} → {after:?}"
    );
    assert!(wa.0 <= wb.0 && wa.1 <= wb.1, "{wb:?} → {wa:?}");
    assert!(wa.0 < 0.09, "after: {wa:?}");
}

/// A view that overlaps none of the others at its pose (here a copy of view 0 a metre away)
/// leaves the joint solve of the others intact and stays where it is; the others still reach
/// the truth.
#[test]
fn a_view_without_partners_stays_put_in_the_joint_refinement() {
    use scanner_core::nalgebra::{Translation3, UnitQuaternion, Vector3};
    use scanner_merge::refine::refine;
    let scene = bunny_views();
    let (c0, p0) = view_cloud(&scene, 0);
    let (c1, p1) = view_cloud(&scene, 1);
    let far = Cloud {
        points: c0
            .points
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.0, 1000.0))
            .collect(),
        normals: c0.normals.clone(),
    };
    let truth1 = p0 * p1.inverse();
    // View 1 half a degree and a millimetre off; the far view anywhere.
    let nudge = Translation3::new(1.0, 0.0, 0.0)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.5f64.to_radians());
    let start = [
        Isometry3::identity(),
        nudge * truth1,
        Isometry3::translation(5.0, 0.0, 0.0),
    ];
    let got = refine(&[&c0, &c1, &far], &start, 3.0, 8, |_| {});
    let (rot, mm) = angle_deg(&truth1, &got[1]);
    println!(
        "view 1 after: {rot:.4}° {mm:.3} mm off; the far view moved {}",
        (got[2].translation.vector - start[2].translation.vector).norm()
    );
    assert!(rot < 0.05 && mm < 0.4, "{rot}° {mm} mm");
    assert!(angle_deg(&start[2], &got[2]).0 < 1e-9 && angle_deg(&start[2], &got[2]).1 < 1e-6);
}

/// The views chosen together (`merge::register_clouds`, what `merge` runs): the bunny's seven
/// views (six about the vertical, one on its side) from the rig's truth points, given in a
/// scrambled order, are all placed right (within 0.5° of the truth from the pairwise fits, within
/// 0.05° after the joint refinement); two
/// views of another object (the part of flat faces) among them match each other but not the
/// bunny, and are named as a group apart.
#[test]
fn views_chosen_together_are_placed_right_and_a_group_apart_is_named() {
    use scanner_merge::pose::{Unplaced, register_clouds};
    let scene = bunny_views();
    let order = [3usize, 0, 5, 1, 6, 2, 4];
    let (clouds, poses): (Vec<Cloud>, Vec<Isometry3<f64>>) =
        order.iter().map(|&k| view_cloud(&scene, k)).unzip();
    let refs: Vec<&Cloud> = clouds.iter().collect();
    let o = RegisterOptions {
        min_overlap: 0.25,
        ..RegisterOptions::default()
    };
    let placed = register_clouds(&refs, &o, |_, _| Vec::new(), |_| None, |_, _| {})
        .unwrap_or_else(|e| panic!("the bunny's views: {e:?}"));
    let chosen: Vec<Isometry3<f64>> = placed.iter().map(|r| r.pose).collect();
    let joint = scanner_merge::refine::refine(&refs, &chosen, 3.0, 8, |_| {});
    for (i, r) in placed.iter().enumerate() {
        let truth = poses[0] * poses[i].inverse();
        let (deg, mm) = angle_deg(&truth, &r.pose);
        let (after, _) = angle_deg(&truth, &joint[i]);
        println!(
            "view {} (given {i}): onto {:?}, also agrees with {:?}, {deg:.4}° {mm:.3} mm off, {after:.4}° after the joint refinement",
            order[i], r.onto, r.agrees
        );
        assert!(
            deg < 0.5 && after < 0.05,
            "view {} placed {deg}° off, {after}° after",
            order[i]
        );
    }
    // Two views of the part join the first two of the bunny.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scanner-device/scenes/part-360.toml");
    let part = Scene::from_toml_in(
        &std::fs::read_to_string(&path).unwrap(),
        path.parent().unwrap(),
    )
    .unwrap();
    let (p0, _) = view_cloud(&part, 0);
    let (p1, _) = view_cloud(&part, 1);
    let mixed = [refs[0], refs[1], &p0, &p1];
    match register_clouds(&mixed, &o, |_, _| Vec::new(), |_| None, |_, _| {}) {
        Err(Unplaced::Apart { placed, apart }) => {
            assert_eq!((placed, apart), (vec![0, 1], vec![2, 3]));
        }
        other => panic!("the part's views among the bunny's: {other:?}"),
    }
}
