//! Intrinsics calibration (Zhang's closed form + joint refinement) and the disc-centre model, on
//! exact synthetic views with known truth.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use scanner_core::calib::bundle::{initial_camera, initial_pose, refine, residuals};
use scanner_core::calib::model::{dot_centre, predict};
use scanner_core::calib::{Free, TargetImage};
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Point2, Rotation3, Vector2, Vector3};
use scanner_core::{Camera, Distortion, GeomError};

const W: u32 = 1280;
const H: u32 = 960;

fn truth_camera() -> Camera<f64> {
    Camera::new(
        1120.0,
        1118.0,
        646.3,
        472.8,
        Distortion {
            k1: -0.08,
            k2: 0.05,
            p1: 0.0008,
            p2: -0.0005,
            k3: -0.01,
        },
    )
    .unwrap()
}

/// A 9×7 dot grid, 25 mm pitch, centred.
fn grid() -> Vec<Point2<f64>> {
    (0..7)
        .flat_map(|r| {
            (0..9).map(move |c| Point2::new((c as f64 - 4.0) * 25.0, (r as f64 - 3.0) * 25.0))
        })
        .collect()
}

/// Poses that look at the grid from several tilts, 450–750 mm away.
fn poses(n: usize, rng: &mut SmallRng) -> Vec<Pose> {
    (0..n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            let tilt = 0.6 + 0.2 * rng.random::<f64>();
            Pose {
                rotation: Rotation3::from_euler_angles(
                    tilt * a.cos(),
                    tilt * a.sin(),
                    0.3 * (rng.random::<f64>() - 0.5),
                ),
                translation: Vector3::new(
                    rng.random_range(-150.0..150.0),
                    rng.random_range(-110.0..110.0),
                    rng.random_range(450.0..750.0),
                ),
            }
        })
        .collect()
}

fn observe(
    cam: &Camera<f64>,
    pose: &Pose,
    layout: &[Point2<f64>],
    radius: f64,
    noise: f64,
    rng: &mut SmallRng,
) -> Vec<Point2<f64>> {
    let n = Normal::new(0.0, noise.max(1e-300)).unwrap();
    layout
        .iter()
        .map(|s| {
            let p = predict(cam, pose, s, radius).unwrap();
            if noise > 0.0 {
                Point2::new(p.x + n.sample(rng), p.y + n.sample(rng))
            } else {
                p
            }
        })
        .collect()
}

fn calibrate(
    pixels: &[Vec<Point2<f64>>],
    layout: &[Point2<f64>],
    radius: f64,
) -> (Camera<f64>, f64, Vec<Pose>) {
    let views: Vec<TargetImage> = pixels
        .iter()
        .map(|p| TargetImage { layout, pixels: p })
        .collect();
    let init = initial_camera(&views, W, H).unwrap();
    let mut poses: Vec<Pose> = views
        .iter()
        .map(|v| initial_pose(&init, v).unwrap())
        .collect();
    let r = refine(&init, Free::ALL, &views, &mut poses, radius).unwrap();
    (r.camera, r.rms_px, poses)
}

#[test]
fn disc_centre_is_the_centroid_of_the_projected_circle() {
    let mut rng = SmallRng::seed_from_u64(1);
    for pose in poses(12, &mut rng) {
        let (c, r) = (Point2::new(60.0, -40.0), 15.0);
        let n = dot_centre(&pose, &c, r).unwrap();
        // Polygon centroid of the projected rim (no distortion: an exact ellipse).
        let rim: Vec<Vector2<f64>> = (0..20000)
            .map(|i| {
                let a = i as f64 / 20000.0 * std::f64::consts::TAU;
                let p = pose.transform(&Point2::new(c.x + r * a.cos(), c.y + r * a.sin()));
                Vector2::new(p.x / p.z, p.y / p.z)
            })
            .collect();
        let (mut area, mut cx, mut cy) = (0.0, 0.0, 0.0);
        for i in 0..rim.len() {
            let (p, q) = (rim[i], rim[(i + 1) % rim.len()]);
            let cr = p.x * q.y - q.x * p.y;
            area += cr;
            cx += (p.x + q.x) * cr;
            cy += (p.y + q.y) * cr;
        }
        let centroid = Vector2::new(cx / (3.0 * area), cy / (3.0 * area));
        let centre = pose.transform(&c);
        let naive = Vector2::new(centre.x / centre.z, centre.y / centre.z);
        // In pixels at f = 1120: the model matches to 1e-6 px, the naive projection does not.
        assert!(
            (n - centroid).norm() * 1120.0 < 1e-6,
            "model {}",
            (n - centroid).norm() * 1120.0
        );
        assert!((naive - centroid).norm() * 1120.0 > 1e-3);
    }
}

#[test]
fn exact_views_recover_the_camera_exactly() {
    let mut rng = SmallRng::seed_from_u64(2);
    let truth = truth_camera();
    let layout = grid();
    let ps = poses(10, &mut rng);
    let pixels: Vec<_> = ps
        .iter()
        .map(|p| observe(&truth, p, &layout, 4.0, 0.0, &mut rng))
        .collect();
    let (cam, rms, got) = calibrate(&pixels, &layout, 4.0);
    assert!(rms < 1e-8, "rms {rms}");
    let rel = |a: f64, b: f64| ((a - b) / b).abs();
    assert!(
        rel(cam.fx(), truth.fx()) < 1e-8 && rel(cam.fy(), truth.fy()) < 1e-8,
        "{cam:?}"
    );
    assert!((cam.principal_point() - truth.principal_point()).norm() < 1e-6);
    let (d, t) = (cam.distortion(), truth.distortion());
    for (a, b) in [
        (d.k1, t.k1),
        (d.k2, t.k2),
        (d.p1, t.p1),
        (d.p2, t.p2),
        (d.k3, t.k3),
    ] {
        assert!((a - b).abs() < 1e-6, "{d:?} vs {t:?}");
    }
    for (a, b) in got.iter().zip(&ps) {
        assert!((a.translation - b.translation).norm() < 1e-6);
        assert!((a.rotation.matrix() - b.rotation.matrix()).norm() < 1e-8);
    }
}

#[test]
fn noisy_views_recover_focal_length_to_a_small_fraction() {
    let mut rng = SmallRng::seed_from_u64(3);
    let truth = truth_camera();
    let layout = grid();
    let ps = poses(12, &mut rng);
    let pixels: Vec<_> = ps
        .iter()
        .map(|p| observe(&truth, p, &layout, 4.0, 0.05, &mut rng))
        .collect();
    let (cam, rms, _) = calibrate(&pixels, &layout, 4.0);
    // The RMS is per marker over both axes (as OpenCV's): σ·√2 for σ per axis.
    assert!(
        (rms - 0.05 * 2f64.sqrt()).abs() < 0.01,
        "rms {rms} for 0.05 px noise"
    );
    assert!(
        ((cam.fx() - truth.fx()) / truth.fx()).abs() < 5e-4,
        "{cam:?}"
    );
    // The principal point is the weakly determined part (it trades off against tangential
    // distortion): 0.4–1.1 px over seeds at this noise with 12 views.
    assert!(
        (cam.principal_point() - truth.principal_point()).norm() < 1.5,
        "{cam:?}"
    );
}

#[test]
fn ignoring_the_disc_model_biases_the_result() {
    // Large discs, strong tilts: fitting disc images as points leaves a residual the model
    // removes.
    let mut rng = SmallRng::seed_from_u64(4);
    let truth = truth_camera();
    let layout = grid();
    let ps = poses(10, &mut rng);
    let pixels: Vec<_> = ps
        .iter()
        .map(|p| observe(&truth, p, &layout, 9.0, 0.0, &mut rng))
        .collect();
    let (_, rms_disc, _) = calibrate(&pixels, &layout, 9.0);
    let (_, rms_point, _) = calibrate(&pixels, &layout, 0.0);
    assert!(
        rms_disc < 1e-8 && rms_point > 1e-4,
        "disc {rms_disc}, point {rms_point}"
    );
}

#[test]
fn pose_only_refinement_and_residuals() {
    let mut rng = SmallRng::seed_from_u64(5);
    let truth = truth_camera();
    let layout = grid();
    let pose = poses(1, &mut rng)[0];
    let pixels = observe(&truth, &pose, &layout, 4.0, 0.0, &mut rng);
    let view = TargetImage {
        layout: &layout,
        pixels: &pixels,
    };
    let mut p = [initial_pose(&truth, &view).unwrap()];
    let r = refine(&truth, Free::NONE, &[view], &mut p, 4.0).unwrap();
    assert_eq!(r.camera, truth);
    assert!((p[0].translation - pose.translation).norm() < 1e-7);
    let mut out = vec![Vector2::zeros(); layout.len()];
    let rms = residuals(&truth, &view, &p[0], 4.0, &mut out).unwrap();
    assert!(rms < 1e-8 && out.iter().all(|r| r.norm() < 1e-7));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let layout = grid();
    let few = &layout[..3];
    let px = vec![Point2::new(1.0, 1.0); 3];
    let v = TargetImage {
        layout: few,
        pixels: &px,
    };
    assert!(matches!(
        initial_camera(&[v], W, H),
        Err(GeomError::TooFewPoints { .. })
    ));
    let nan = vec![Point2::new(f64::NAN, 1.0); layout.len()];
    let v = TargetImage {
        layout: &layout,
        pixels: &nan,
    };
    assert_eq!(
        initial_camera(&[v], W, H).unwrap_err(),
        GeomError::NotFinite
    );
    let mut poses = [];
    assert!(refine(&truth_camera(), Free::ALL, &[], &mut poses, 1.0).is_err());
    // One view cannot fix 9 intrinsics with 6 pose parameters from 4 markers.
    let four: Vec<_> = layout[..4].to_vec();
    let pix: Vec<_> = (0..4)
        .map(|i| Point2::new(100.0 + i as f64, 50.0 * (i % 2) as f64))
        .collect();
    let v = TargetImage {
        layout: &four,
        pixels: &pix,
    };
    let mut p = [Pose {
        rotation: Rotation3::identity(),
        translation: Vector3::new(0.0, 0.0, 500.0),
    }];
    assert!(matches!(
        refine(&truth_camera(), Free::ALL, &[v], &mut p, 1.0),
        Err(GeomError::TooFewPoints { .. })
    ));
}
