//! Fusion of registered views into one closed mesh (issue 17, first version): the rig's sphere
//! seen from six sides (views turned about two axes), its lit points taken from the truth and
//! moved back into one frame by the true poses, fused by a signed distance and surface nets.

use scanner_core::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use scanner_host::fuse::{check, fuse};
use scanner_rig::{Rig, Scene, SurfaceId};

#[test]
fn six_views_of_a_sphere_fuse_into_one_closed_surface_of_its_volume() {
    let mut scene = Scene::demo(640, 480);
    scene.objects.truncate(1);
    scene.laser.frames = 180; // stripes about 2 mm apart on the sphere
    let scanner_rig::Shape::Sphere { centre, radius } = scene.objects[0].shape else {
        panic!("the demo's first object is a sphere")
    };
    let turn = |axis: Vector3<f64>, deg: f64| -> Isometry3<f64> {
        Translation3::from(centre.coords)
            * UnitQuaternion::from_axis_angle(
                &scanner_core::nalgebra::Unit::new_normalize(axis),
                deg.to_radians(),
            )
            * Translation3::from(-centre.coords)
    };
    scene.views = vec![
        Isometry3::identity(),
        turn(Vector3::y(), 90.0),
        turn(Vector3::y(), 180.0),
        turn(Vector3::y(), 270.0),
        turn(Vector3::x(), 90.0),
        turn(Vector3::x(), -90.0),
    ];
    let (mut points, mut normals_all) = (Vec::new(), Vec::new());
    for k in 0..scene.view_count() {
        let v = scene.view(k).unwrap();
        let pose = v.object_pose;
        let rig = Rig::new(v).unwrap();
        let pts: Vec<_> = (0..180)
            .flat_map(|f| rig.truth(f).unwrap())
            .flatten()
            .filter(|t| matches!(t.surface, SurfaceId::Object(_)))
            .map(|t| t.point)
            .collect();
        // The true normals (the fusion is tested here, not the normals' estimation, which along
        // a single stripe's dense points is ill-posed).
        for p in &pts {
            let q = pose.inverse_transform_point(p);
            points.push(q);
            normals_all.push((q - centre).normalize());
        }
    }
    let off = points
        .iter()
        .map(|p| ((p - centre).norm() - radius).abs())
        .fold(0.0, f64::max);
    println!("truth points: worst {off:.4} mm off the sphere");
    let t0 = std::time::Instant::now();
    let m = fuse(&points, &normals_all, 1.0).unwrap();
    let c = check(&m);
    let truth = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
    let worst = m
        .vertices
        .iter()
        .map(|v| ((v.cast::<f64>() - centre).norm() - radius).abs())
        .fold(0.0, f64::max);
    println!(
        "{} points → {} vertices, {} faces in {:.2} s; open edges {}, components {}, volume {:.0} mm³ (true {truth:.0}, {:+.2} %), worst vertex {worst:.2} mm off the sphere",
        points.len(),
        m.vertices.len(),
        m.faces.len(),
        t0.elapsed().as_secs_f64(),
        c.open_edges,
        c.components,
        c.volume_mm3,
        100.0 * (c.volume_mm3 / truth - 1.0)
    );
    assert!(c.watertight, "{} open edges", c.open_edges);
    assert_eq!(c.components, 1);
    assert!(
        (c.volume_mm3 / truth - 1.0).abs() < 0.02,
        "volume {} vs {truth}",
        c.volume_mm3
    );
}
