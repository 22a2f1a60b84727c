//! Fusion of registered views into one closed mesh (issue 17): the rig's sphere seen from
//! several sides (views turned about two axes), its lit points taken from the truth and moved
//! back into one frame by the true poses, fused (signed distance near the points, the winding
//! number where no view saw, marching tetrahedra).

use scanner_core::nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use scanner_merge::fuse::{area_share, check, fuse, unseen_faces};
use scanner_rig::{Rig, Scene, SurfaceId};

/// The demo's sphere (centre, radius) and its true lit points and normals from several views.
type SphereViews = (Point3<f64>, f64, Vec<Point3<f64>>, Vec<Vector3<f64>>);

/// The true lit points and normals of the demo's sphere from views turned by `turns` (axis,
/// degrees) about its centre, in one frame.
fn sphere_views(turns: &[(Vector3<f64>, f64)]) -> SphereViews {
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
    scene.views = turns.iter().map(|&(a, d)| turn(a, d)).collect();
    let (mut points, mut normals) = (Vec::new(), Vec::new());
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
            normals.push((q - centre).normalize());
        }
    }
    (centre, radius, points, normals)
}

/// Four turns about the vertical and two about the horizontal: every side seen.
const SIX_SIDES: [(Vector3<f64>, f64); 6] = [
    (Vector3::new(0.0, 1.0, 0.0), 0.0),
    (Vector3::new(0.0, 1.0, 0.0), 90.0),
    (Vector3::new(0.0, 1.0, 0.0), 180.0),
    (Vector3::new(0.0, 1.0, 0.0), 270.0),
    (Vector3::new(1.0, 0.0, 0.0), 90.0),
    (Vector3::new(1.0, 0.0, 0.0), -90.0),
];

#[test]
fn six_views_of_a_sphere_fuse_into_one_closed_surface_of_its_volume() {
    let (centre, radius, points, normals) = sphere_views(&SIX_SIDES);
    let off = points
        .iter()
        .map(|p| ((p - centre).norm() - radius).abs())
        .fold(0.0, f64::max);
    println!("truth points: worst {off:.4} mm off the sphere");
    let t0 = std::time::Instant::now();
    let m = fuse(&points, &normals, 1.0).unwrap();
    let c = check(&m);
    let truth = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
    let off: Vec<f64> = m
        .vertices
        .iter()
        .map(|v| ((v.cast::<f64>() - centre).norm() - radius).abs())
        .collect();
    let mean = off.iter().sum::<f64>() / off.len() as f64;
    let worst = off.iter().copied().fold(0.0, f64::max);
    println!(
        "{} points → {} vertices, {} faces in {:.2} s; open edges {}, non-manifold vertices {}, components {}, volume {:.0} mm³ (true {truth:.0}, {:+.2} %), vertices off the sphere by {mean:.3} mm on average, {worst:.2} mm at most",
        points.len(),
        m.vertices.len(),
        m.faces.len(),
        t0.elapsed().as_secs_f64(),
        c.open_edges,
        c.nonmanifold_vertices,
        c.components,
        c.volume_mm3,
        100.0 * (c.volume_mm3 / truth - 1.0)
    );
    assert!(c.watertight, "{} open edges", c.open_edges);
    assert_eq!(c.nonmanifold_vertices, 0);
    assert_eq!(c.components, 1);
    assert!(
        (c.volume_mm3 / truth - 1.0).abs() < 0.005,
        "volume {} vs {truth}",
        c.volume_mm3
    );
    // The gaps between the views' stripes close a little flat (the winding number's patch):
    // the worst vertex stays within a millimetre, the mean within a tenth.
    assert!(mean < 0.1 && worst < 1.0, "mean {mean}, worst {worst}");
}

#[test]
fn a_sphere_seen_from_three_sides_closes_over_what_no_view_saw() {
    // Front, left and right: the back and the poles are not seen.
    let (centre, radius, points, normals) = sphere_views(&[
        (Vector3::y(), 0.0),
        (Vector3::y(), 90.0),
        (Vector3::y(), -90.0),
    ]);
    let m = fuse(&points, &normals, 1.0).unwrap();
    let c = check(&m);
    let unseen = unseen_faces(&m, &points, 3.0);
    let share = area_share(&m, &unseen);
    let truth = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
    // Vertices of the seen part against the sphere.
    let seen_off: Vec<f64> = m
        .faces
        .iter()
        .zip(&unseen)
        .filter(|(_, u)| !**u)
        .flat_map(|(f, _)| {
            f.map(|i| ((m.vertices[i as usize].cast::<f64>() - centre).norm() - radius).abs())
        })
        .collect();
    let mean = seen_off.iter().sum::<f64>() / seen_off.len() as f64;
    println!(
        "{} points → {} faces; unseen {:.1} % of the area; open edges {}, non-manifold vertices {}, components {}, volume {:+.2} % of the sphere's; seen part off the sphere by {mean:.3} mm on average",
        points.len(),
        m.faces.len(),
        100.0 * share,
        c.open_edges,
        c.nonmanifold_vertices,
        c.components,
        100.0 * (c.volume_mm3 / truth - 1.0)
    );
    assert!(
        c.watertight && c.nonmanifold_vertices == 0 && c.components == 1,
        "{c:?}"
    );
    assert!(share > 0.1 && share < 0.6, "unseen share {share}");
    // Closed across the back: the volume is most of the sphere's, not a sliver or a box.
    assert!(
        c.volume_mm3 > 0.6 * truth && c.volume_mm3 < 1.02 * truth,
        "{c:?}"
    );
    assert!(mean < 0.1, "seen part {mean} mm off");
}

#[test]
fn points_of_low_weight_give_way_where_sure_points_saw_the_same_surface() {
    // A view's edge points lie off the surface, nearer its camera (the stripe cut at the edge):
    // here a cap of the sphere gets a second layer 1 mm outside, as such points would lie. At
    // the merge's edge weight the sure points place the surface; at full weight the layer pulls
    // it out.
    use scanner_merge::error::FuseError;
    use scanner_merge::fuse::fuse_with;
    let (centre, radius, mut points, mut normals) = sphere_views(&SIX_SIDES);
    let cap = |p: &Point3<f64>| (p - centre).normalize().x > 0.8;
    let sure = points.len();
    let layer: Vec<(Point3<f64>, Vector3<f64>)> = points
        .iter()
        .zip(&normals)
        .filter(|(p, _)| cap(p))
        .map(|(p, n)| (p + n * 1.0, *n))
        .collect();
    assert!(layer.len() > 500, "{} layer points", layer.len());
    for (p, n) in layer {
        points.push(p);
        normals.push(n);
    }
    let off_in_cap = |weights: &[f64]| {
        let m = fuse_with(&points, &normals, weights, 1.0, |_, _| {}).unwrap();
        let off: Vec<f64> = m
            .vertices
            .iter()
            .map(|v| v.cast::<f64>())
            .filter(|v| cap(v))
            .map(|v| (v - centre).norm() - radius)
            .collect();
        off.iter().sum::<f64>() / off.len() as f64
    };
    let edge = scanner_merge::fuse::edge_weight(Some(0.0));
    let weighted: Vec<f64> = (0..points.len())
        .map(|i| if i < sure { 1.0 } else { edge })
        .collect();
    let (low, full) = (off_in_cap(&weighted), off_in_cap(&[]));
    println!(
        "cap with a layer 1 mm out: surface {low:+.3} mm off the sphere with the layer at weight {edge}, {full:+.3} mm at weight 1"
    );
    assert!(low.abs() < 0.1, "{low}");
    assert!(full > 0.3, "{full}");
    // A weight per point or none, each 0 to 1.
    assert!(matches!(
        fuse_with(&points, &normals, &weighted[1..], 1.0, |_, _| {}),
        Err(FuseError::Lengths { .. })
    ));
    for bad in [f64::NAN, -0.1, 1.5, f64::INFINITY] {
        let mut w = weighted.clone();
        w[7] = bad;
        let e = fuse_with(&points, &normals, &w, 1.0, |_, _| {}).unwrap_err();
        assert!(matches!(e, FuseError::Weight { index: 7, .. }), "{e}");
    }
}

/// A cut by a plane (`fuse_cut`, what `merge --flat-base` runs): the sphere from six sides cut
/// half a radius below its centre stays closed and manifold, nothing lies beyond the plane, and
/// the cap is flat, faces away from the kept side and has the area of the sphere's section there
/// (π (r² − (r/2)²)); the volume is the cut sphere's.
#[test]
fn a_plane_cuts_the_fused_sphere_and_closes_it_flat() {
    use scanner_merge::fuse::{HalfSpace, area_on, fuse_cut};
    let (centre, radius, points, normals) = sphere_views(&SIX_SIDES);
    // Camera y points down: keep y ≤ centre + r/2, i.e. (−y)·x ≥ −(centre.y + r/2).
    let keep = HalfSpace {
        up: -Vector3::y(),
        at: -(centre.y + radius / 2.0),
    };
    let m = fuse_cut(&points, &normals, &[], 1.0, Some(keep), |_, _| {}).unwrap();
    let c = check(&m);
    let beyond = m
        .vertices
        .iter()
        .map(|v| keep.at - keep.up.dot(&v.cast::<f64>().coords))
        .fold(f64::NEG_INFINITY, f64::max);
    let cap = area_on(&m, &keep, 0.01);
    let section = std::f64::consts::PI * (radius * radius - radius * radius / 4.0);
    // The cap of a sphere of radius r cut at height h = r/2 below the centre: the kept part's
    // volume is the sphere's less the cap of height r/2: π h² (3r − h)/3 with h = r/2.
    let h = radius / 2.0;
    let truth = 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3)
        - std::f64::consts::PI * h * h * (3.0 * radius - h) / 3.0;
    let down: f64 = m
        .faces
        .iter()
        .filter(|f| {
            f.iter().all(|&i| {
                (keep.up.dot(&m.vertices[i as usize].cast::<f64>().coords) - keep.at).abs() <= 0.01
            })
        })
        .map(|f| {
            let [a, b, c] = f.map(|i| m.vertices[i as usize].cast::<f64>());
            (b - a).cross(&(c - a)).dot(&keep.up)
        })
        .fold(f64::NEG_INFINITY, f64::max);
    println!(
        "cut sphere: {c:?}; farthest beyond the plane {beyond:.4} mm; cap {cap:.0} mm² against {section:.0}; volume {:+.2} % of the cut sphere's",
        100.0 * (c.volume_mm3 / truth - 1.0)
    );
    assert!(
        c.watertight && c.nonmanifold_vertices == 0 && c.components == 1,
        "{c:?}"
    );
    assert!(beyond <= 1e-3, "a vertex {beyond} mm beyond the plane");
    assert!(
        (cap / section - 1.0).abs() < 0.03,
        "cap {cap} mm², section {section} mm²"
    );
    assert!(down < 0.0, "every cap face faces out of the kept side");
    assert!(
        (c.volume_mm3 / truth - 1.0).abs() < 0.01,
        "{c:?} against {truth}"
    );
}
