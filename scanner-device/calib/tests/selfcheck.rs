//! The calibration's check of itself on synthetic corners with known truth: a flat target and a
//! lens the model describes (the halves agree as the noise predicts, the map states the fit's
//! real error), and shots skewed by a moving rolling shutter (the halves disagree beyond the
//! noise: a warning).

use scanner_calib::selfcheck::{MAP_CELLS, self_check};
use scanner_calib::{ImageFit, IntrinsicsFit, Target};
use scanner_core::calib::bundle::{initial_camera, initial_pose, refine};
use scanner_core::calib::{Free, TargetImage};
use scanner_core::geometry::Pose;
use scanner_core::nalgebra::{Point2, Point3, Rotation3, Vector2, Vector3};
use scanner_core::{Camera, Distortion};

const TARGET: Target = Target::Chessboard {
    cols: 12,
    rows: 9,
    square: 35.0,
};
const SIZE: (u32, u32) = (1280, 960);

fn truth() -> Camera<f64> {
    Camera::new(
        1000.0,
        1002.0,
        650.0,
        470.0,
        Distortion {
            k1: -0.2,
            k2: 0.08,
            p1: 0.0005,
            p2: -0.0003,
            k3: 0.0,
        },
    )
    .unwrap()
}

/// A small deterministic generator (xorshift) and Gaussian samples by Box–Muller.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// The target's poses: tilted ±25° and spread over the image at 500–800 mm.
fn poses(n: usize) -> Vec<Pose> {
    (0..n)
        .map(|i| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            let tilt = Vector3::new(0.45 * t.cos(), 0.45 * (1.7 * t).sin(), 0.2 * t.sin());
            let z = 500.0 + 300.0 * ((i * 7) % n) as f64 / n as f64;
            Pose {
                rotation: Rotation3::new(tilt),
                translation: Vector3::new(
                    -110.0 + 0.28 * z * t.cos(),
                    -80.0 + 0.2 * z * (2.0 * t).sin(),
                    z,
                ),
            }
        })
        .collect()
}

/// Where the corners appear through `camera` with noise of `sigma` px, each shot skewed by a
/// random share of up to `skew` px per 1000 rows (a rolling shutter while the hand moved: no
/// pose of a flat target makes it, so the intrinsics take it). Only corners inside the image
/// are kept.
fn observe(
    camera: &Camera<f64>,
    pose: &Pose,
    skew: f64,
    sigma: f64,
    noise: &mut Noise,
) -> Vec<(usize, Point2<f64>)> {
    let shear = skew * 1e-3 * (2.0 * noise.uniform() - 1.0);
    TARGET
        .points()
        .iter()
        .enumerate()
        .filter_map(|(k, s)| {
            let p = pose.rotation * Vector3::new(s.x, s.y, 0.0) + pose.translation;
            let q = camera.project(&Point3::from(p)).ok()?;
            let moved = Vector2::new(shear * (q.y - f64::from(SIZE.1) / 2.0), 0.0);
            let q = q + moved + Vector2::new(sigma * noise.gauss(), sigma * noise.gauss());
            (q.x > 0.0 && q.y > 0.0 && q.x < f64::from(SIZE.0) && q.y < f64::from(SIZE.1))
                .then_some((k, q))
        })
        .collect()
}

/// A calibration of `n` views as `calibrate intrinsics` would make it.
fn calibrate(n: usize, skew: f64, sigma: f64, seed: u64) -> IntrinsicsFit {
    let mut noise = Noise(seed);
    let points = TARGET.points();
    let found: Vec<Vec<(usize, Point2<f64>)>> = poses(n)
        .iter()
        .map(|p| observe(&truth(), p, skew, sigma, &mut noise))
        .collect();
    let layout: Vec<Vec<Point2<f64>>> = found
        .iter()
        .map(|f| f.iter().map(|(k, _)| points[*k]).collect())
        .collect();
    let pixels: Vec<Vec<Point2<f64>>> = found
        .iter()
        .map(|f| f.iter().map(|(_, p)| *p).collect())
        .collect();
    let views: Vec<TargetImage> = layout
        .iter()
        .zip(&pixels)
        .map(|(l, p)| TargetImage {
            layout: l,
            pixels: p,
        })
        .collect();
    let start = initial_camera(&views, SIZE.0, SIZE.1).unwrap();
    let mut fitted: Vec<Pose> = views
        .iter()
        .map(|v| initial_pose(&start, v).unwrap())
        .collect();
    let r = refine(&start, Free::NO_K3, &views, &mut fitted, 0.0).unwrap();
    IntrinsicsFit {
        size: SIZE,
        camera: r.camera,
        rms_px: r.rms_px,
        views: found
            .into_iter()
            .zip(fitted)
            .map(|(f, pose)| {
                Ok(ImageFit {
                    residuals: vec![Vector2::zeros(); f.len()],
                    found: f,
                    dropped: Vec::new(),
                    pose,
                    rms_px: r.rms_px,
                    max_px: 0.0,
                })
            })
            .collect(),
        free: Free::NO_K3,
    }
}

#[test]
fn a_lens_the_model_describes_gives_halves_that_agree_as_the_noise_predicts() {
    let mut ratios = Vec::new();
    for seed in 1..=4 {
        let fit = calibrate(14, 0.0, 0.15, seed);
        let c = self_check(&fit, &TARGET).unwrap();
        let h = c.halves.as_ref().unwrap();
        println!("seed {seed}: {h:?}, noise {:.3}", c.covariance.noise_px);
        assert_eq!(h.images, (7, 7));
        assert!((c.covariance.noise_px - 0.15).abs() < 0.02, "{c:?}");
        assert!(!h.too_far(), "seed {seed}: {h:?}");
        ratios.push(h.ratio());
        // the whole image is less certain than where the features were
        assert!(h.expected_image_rms_px >= h.expected_features_rms_px);
    }
    // Over four draws the ratio averages near 1 (a 9-parameter difference: scatter, no bias).
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!((0.5..=1.5).contains(&mean), "{ratios:?}");
}

#[test]
fn the_map_states_the_error_the_fit_really_has() {
    // The fitted camera against the truth, rotation taken out as the map does, over ten draws:
    // the RMS error at the map's cells over the map's σ there (worst direction, so a little
    // above the RMS of both directions: expect 0.5–1.2).
    let mut err2 = 0.0;
    let mut sig2 = 0.0;
    for seed in 11..=20 {
        let fit = calibrate(12, 0.0, 0.2, seed);
        let c = self_check(&fit, &TARGET).unwrap();
        let (cols, rows) = MAP_CELLS;
        let cells: Vec<Point2<f64>> = (0..rows)
            .flat_map(|r| {
                (0..cols).map(move |k| {
                    Point2::new(
                        (k as f64 + 0.5) * f64::from(SIZE.0) / cols as f64,
                        (r as f64 + 0.5) * f64::from(SIZE.1) / rows as f64,
                    )
                })
            })
            .collect();
        let features: Vec<Point2<f64>> = fit
            .views
            .iter()
            .flatten()
            .flat_map(|v| v.found.iter().map(|f| f.1))
            .collect();
        let rot = best_rotation(&fit.camera, &truth(), &features);
        for (q, s) in cells.iter().zip(&c.map.sigma_px) {
            let r = fit.camera.pixel_to_ray(q).unwrap();
            let p = truth().project(&Point3::from(rot * r)).unwrap();
            if c.map.covered[(q.y / f64::from(SIZE.1) * rows as f64) as usize * cols
                + (q.x / f64::from(SIZE.0) * cols as f64) as usize]
            {
                err2 += (p - q).norm_squared();
                sig2 += s * s;
            }
        }
    }
    let ratio = (err2 / sig2).sqrt();
    println!("error / stated σ where the features were: {ratio:.2}");
    assert!((0.5..=1.2).contains(&ratio), "{ratio}");
}

/// The rotation taking `a`'s rays to where `b` sees the same pixels (least squares, small angle).
fn best_rotation(a: &Camera<f64>, b: &Camera<f64>, pts: &[Point2<f64>]) -> Rotation3<f64> {
    // Kabsch on unit rays.
    let mut h = scanner_core::nalgebra::Matrix3::zeros();
    for q in pts {
        let (Ok(ra), Ok(rb)) = (a.pixel_to_ray(q), b.pixel_to_ray(q)) else {
            continue;
        };
        h += rb.normalize() * ra.normalize().transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = scanner_core::nalgebra::Matrix3::identity();
    d[(2, 2)] = (u * vt).determinant().signum();
    Rotation3::from_matrix_unchecked(u * d * vt)
}

#[test]
fn shots_that_moved_are_warned_about() {
    // ±2 px of skew over the image's height (a rolling shutter while the target moved), in
    // corner noise of 0.15 px: the halves differ 3.7× more than the noise explains.
    let fit = calibrate(14, 4.0, 0.15, 3);
    let c = self_check(&fit, &TARGET).unwrap();
    let h = c.halves.as_ref().unwrap();
    println!("{h:?}, ratio {:.2}", h.ratio());
    assert!(h.too_far(), "{h:?}");
}

#[test]
fn too_few_images_to_halve_is_said_and_the_map_still_drawn() {
    let fit = calibrate(5, 0.0, 0.15, 9);
    let c = self_check(&fit, &TARGET).unwrap();
    assert!(
        matches!(
            c.halves,
            Err(scanner_calib::CalibError::TooFewImages {
                usable: 5,
                needed: 6,
                ..
            })
        ),
        "{:?}",
        c.halves
    );
    assert!(c.map.covered_median() > 0.0 && c.map.max() >= c.map.covered_median());
}
