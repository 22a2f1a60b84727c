//! Monte Carlo of the board-plane estimators under marker noise: the paper's two lines of three
//! markers per plane (eq. 1–6 form, [`board::plane_from_marker_lines`]) against the layout pose
//! ([`pose::plane_pose`]) from the same six markers.
//!
//! Setup as in `NOTES.md`: 1600×1200, f = 1400 px, a right-angled board whose halves are at 45° to
//! the view (with ±8° pose jitter), marker spacing D/7, the camera known exactly. Errors:
//! - board: the depth error a stripe point on the board would get, i.e. the distance between the
//!   true point and the estimated plane's point on the same ray, over a 5×5 grid covering the
//!   marker area of each half;
//! - object: points on the laser plane in front of the board, triangulated with a laser plane
//!   fitted (least squares) to stripe points taken from the estimated board, stripe noise
//!   `stripe_noise_px`.
//!
//! All in % of the camera–board distance.

use rand::{Rng, SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use scanner_core::geometry::{
    Board, LaserFitConfig, Limits, Plane, board, laser, pose, triangulate,
};
use scanner_core::nalgebra::{Point2, Point3};
use scanner_core::{Camera, Distortion};

use super::{Scene, SceneParams};

/// Which board-plane estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Two lines of three markers, eq. 1–6 (the paper).
    PaperLines,
    /// Homography + refinement over the known 2-D layout.
    Layout,
}

/// Error statistics in % of the distance.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stats {
    pub board_mean: f64,
    pub board_max: f64,
    pub object_mean: f64,
    pub object_max: f64,
    pub trials: usize,
    pub failed: usize,
}

fn params(distance: f64, rng: &mut StdRng) -> SceneParams {
    let mut j = |a: f64| rng.random_range(-a..a);
    SceneParams {
        distance,
        angle_deg: 90.0,
        yaw: j(0.14),
        pitch: j(0.14),
        roll: j(0.05),
        offset: (j(0.03) * distance, j(0.03) * distance),
        fx: 1400.0,
        aspect: 1.0,
        pp: (0.0, 0.0),
        dist: [0.0; 5],
        laser: (j(0.2), 0.3 + j(0.1), j(0.05)),
        laser_v: (j(0.8), j(0.8)),
    }
}

/// Runs `trials` random scenes at `distance` (mm) and returns the statistics of both methods.
pub fn run(
    distance: f64,
    marker_noise_px: f64,
    stripe_noise_px: f64,
    trials: usize,
    seed: u64,
) -> [(Method, Stats); 2] {
    let mut rng = StdRng::seed_from_u64(seed);
    let marker = Normal::new(0.0, marker_noise_px).unwrap();
    let stripe = Normal::new(0.0, stripe_noise_px).unwrap();
    let mut acc = [
        (Method::PaperLines, Stats::default()),
        (Method::Layout, Stats::default()),
    ];
    let mut sums = [(0.0, 0usize, 0.0, 0usize); 2];
    let camera: Camera<f64> =
        Camera::new(1400.0, 1400.0, 799.5, 599.5, Distortion::none()).unwrap();
    let limits = Limits::default();
    let mut done = 0;
    while done < trials {
        let s = Scene::new(&params(distance, &mut rng));
        let lines = s.paper_layout();
        let flat: Vec<Point2<f64>> = lines.iter().flatten().copied().collect();
        if !s.markers_visible(&flat) || !s.well_viewed() {
            continue;
        }
        let (left_true, right_true) = s.stripe_points(40);
        let objects = s.object_points(&[0.1, 0.2, 0.3]);
        if left_true.len() < 10 || right_true.len() < 10 || objects.is_empty() {
            continue;
        }
        done += 1;
        // noisy marker pixels, the same for both methods
        let noisy: Vec<Vec<Point2<f64>>> = [&s.left, &s.right]
            .iter()
            .map(|p| {
                flat.iter()
                    .map(|uv| {
                        let px = camera.project(&p.transform(uv)).unwrap();
                        Point2::new(
                            px.x + marker.sample(&mut rng),
                            px.y + marker.sample(&mut rng),
                        )
                    })
                    .collect()
            })
            .collect();
        let noisy_stripe = |pts: &[Point3<f64>], rng: &mut StdRng| -> Vec<Point2<f64>> {
            pts.iter()
                .map(|q| {
                    let px = camera.project(q).unwrap();
                    Point2::new(px.x + stripe.sample(rng), px.y + stripe.sample(rng))
                })
                .collect()
        };
        let (sl, sr, so) = (
            noisy_stripe(&left_true, &mut rng),
            noisy_stripe(&right_true, &mut rng),
            noisy_stripe(&objects, &mut rng),
        );
        for (k, method) in [Method::PaperLines, Method::Layout].into_iter().enumerate() {
            let planes: Result<Vec<Plane<f64>>, _> = noisy
                .iter()
                .map(|px| match method {
                    Method::PaperLines => {
                        let rays = [0, 1].map(|l| {
                            [0, 1, 2].map(|i| camera.pixel_to_ray(&px[l * 3 + i]).unwrap())
                        });
                        board::plane_from_marker_lines(&rays, [s.spacing; 2]).map(|f| f.plane)
                    }
                    Method::Layout => {
                        pose::plane_pose(&camera, &flat, px).and_then(|f| f.pose.plane())
                    }
                })
                .collect();
            let Ok(planes) = planes else {
                acc[k].1.failed += 1;
                continue;
            };
            let Ok(est) = Board::new(planes[0], planes[1]) else {
                acc[k].1.failed += 1;
                continue;
            };
            // board error over the marker area
            for (pose, plane) in [(&s.left, &planes[0]), (&s.right, &planes[1])] {
                for i in 0..5 {
                    for j in 0..5 {
                        let uv = Point2::new(
                            s.spacing * (0.3 + 2.6 * i as f64 / 4.0),
                            s.spacing * (-1.3 + 2.6 * j as f64 / 4.0),
                        );
                        let q = pose.transform(&uv);
                        let Ok(hit) = plane.intersect_ray(&q.coords, 0.0) else {
                            continue;
                        };
                        let e = (hit - q).norm() / distance * 100.0;
                        sums[k].0 += e;
                        sums[k].1 += 1;
                        acc[k].1.board_max = acc[k].1.board_max.max(e);
                    }
                }
            }
            // object error through the laser plane fitted on the estimated board
            let on_board = |px: &[Point2<f64>]| -> Vec<Point3<f64>> {
                px.iter()
                    .filter_map(|p| {
                        triangulate::board_point(&camera, &est, p, &limits)
                            .ok()
                            .map(|b| b.0)
                    })
                    .collect()
            };
            let Ok(lp) =
                laser::least_squares(&on_board(&sl), &on_board(&sr), &LaserFitConfig::default())
            else {
                acc[k].1.failed += 1;
                continue;
            };
            for (px, q) in so.iter().zip(&objects) {
                if let Ok(p) = triangulate::ray_plane(&camera, &lp.plane, px, &limits) {
                    let e = (p - q).norm() / distance * 100.0;
                    sums[k].2 += e;
                    sums[k].3 += 1;
                    acc[k].1.object_max = acc[k].1.object_max.max(e);
                }
            }
            acc[k].1.trials += 1;
        }
    }
    for k in 0..2 {
        acc[k].1.board_mean = sums[k].0 / sums[k].1.max(1) as f64;
        acc[k].1.object_mean = sums[k].2 / sums[k].3.max(1) as f64;
    }
    acc
}
