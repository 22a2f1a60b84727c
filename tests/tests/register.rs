//! Registration of two views without an initial guess (issue 17, first stage): the rig's bunny
//! in views turned by 60°, 180° and laid on its side, each view's lit surface points taken from
//! the rig's truth (the stripe's exact points, so that this tests the registration alone), and a
//! view of another object that must be reported, not merged.

use scanner_core::nalgebra::Isometry3;
use scanner_host::register::{Cloud, RegisterError, RegisterOptions, normals, register};
use scanner_rig::{Rig, Scene, SurfaceId};

fn bunny_views() -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scanner-device/scenes/bunny-360.toml");
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
