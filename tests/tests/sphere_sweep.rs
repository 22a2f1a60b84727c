//! End to end through the public geometry API: calibrate the board from noisy marker pixels
//! (f64, layout pose), hand the calibration to the f32 per-frame path, sweep a laser over a
//! sphere in front of the board, and compare the recovered sphere with the truth.
//!
//! Every stripe pixel of a frame — board and sphere alike, with occlusion and laser shadow — goes
//! into the laser-plane fit as a "board" pixel, as the head will see them: the sphere's pixels
//! must be rejected as outliers there and come back as object points in triangulation.

use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use scanner_core::geometry::{
    Board, LaserFitConfig, Limits, Plane, Surface, laser, pose, triangulate,
};
use scanner_core::nalgebra::{Matrix4, Point2, Point3, Vector3, Vector4};
use scanner_core::{Camera, Distortion};

const D: f64 = 800.0;

struct Sphere {
    c: Point3<f64>,
    r: f64,
}

impl Sphere {
    /// `true` if the segment from `a` to `b` passes through the sphere (excluding the ends).
    fn blocks(&self, a: &Point3<f64>, b: &Point3<f64>) -> bool {
        let d = b - a;
        let t = ((self.c - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        let closest = a + d * t;
        t > 1e-6 && t < 1.0 - 1e-6 && (closest - self.c).norm() < self.r * (1.0 - 1e-9)
    }
}

/// Least-squares sphere: |p|² = 2 c·p + (r² − |c|²).
fn fit_sphere(pts: &[Point3<f64>]) -> (Point3<f64>, f64) {
    let (mut a, mut b) = (Matrix4::zeros(), Vector4::zeros());
    for p in pts {
        let row = Vector4::new(2.0 * p.x, 2.0 * p.y, 2.0 * p.z, 1.0);
        a += row * row.transpose();
        b += row * p.coords.norm_squared();
    }
    let x = a.cholesky().unwrap().solve(&b);
    let c = Point3::new(x[0], x[1], x[2]);
    (c, (x[3] + c.coords.norm_squared()).sqrt())
}

#[test]
fn calibrate_then_scan_a_sphere() {
    let mut rng = StdRng::seed_from_u64(2012);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut jitter =
        |p: Point2<f64>| Point2::new(p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng));
    let camera = Camera::new(
        1400.0,
        1400.0,
        799.5,
        599.5,
        Distortion {
            k1: -0.08,
            k2: 0.02,
            p1: 0.0005,
            p2: -0.0003,
            k3: 0.0,
        },
    )
    .unwrap();

    // A right-angled board, halves at 45° to the view, crease at (0, 0, D).
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let crease = Vector3::new(0.0, 0.0, D);
    let half = |h: Vector3<f64>| pose::Pose {
        rotation: scanner_core::nalgebra::Rotation3::from_matrix_unchecked(
            scanner_core::nalgebra::Matrix3::from_columns(&[
                h,
                Vector3::y(),
                h.cross(&Vector3::y()),
            ]),
        ),
        translation: crease,
    };
    let (left, right) = (
        half(Vector3::new(-s, 0.0, -s)),
        half(Vector3::new(s, 0.0, -s)),
    );
    let m = D / 7.0;
    let layout: Vec<Point2<f64>> = [-1.0, 1.0]
        .iter()
        .flat_map(|&v| [0.6, 1.6, 2.6].map(|u| Point2::new(u * m, v * m)))
        .collect();

    // Calibration (f64): noisy marker pixels → layout poses → board.
    let planes: Vec<Plane<f64>> = [&left, &right]
        .iter()
        .map(|p| {
            let px: Vec<_> = layout
                .iter()
                .map(|uv| jitter(camera.project(&p.transform(uv)).unwrap()))
                .collect();
            let fit = pose::plane_pose(&camera, &layout, &px).unwrap();
            assert!(fit.rms_px < 0.3, "marker reprojection {} px", fit.rms_px);
            fit.pose.plane().unwrap()
        })
        .collect();
    let board = Board::new(planes[0], planes[1]).unwrap();
    assert!(
        (board.angle().to_degrees() - 90.0).abs() < 0.5,
        "board angle {}",
        board.angle().to_degrees()
    );

    // The head (f32).
    let (cam32, board32) = (camera.cast::<f32>(), board.cast::<f32>());
    let limits = Limits::<f32>::default();
    let cfg = LaserFitConfig::<f32>::default();

    let sphere = Sphere {
        c: Point3::new(10.0, -40.0, D - 300.0),
        r: 80.0,
    };
    let source = Point3::new(30.0, -200.0, 20.0);
    let (mut object, mut frames_used, mut stray) = (Vec::new(), 0, 0usize);
    for k in 0..40 {
        // the laser plane through the source and the horizontal line y = yk at the crease depth
        let yk = -80.0 + 280.0 * k as f64 / 39.0;
        let n = Vector3::x()
            .cross(&(Point3::new(0.0, yk, D) - source))
            .normalize();
        let d = -n.dot(&source.coords);
        let on_plane_y = |z: f64| -(n.z * z + d) / n.y;
        let mut truth = Vec::new();
        for i in 0..=200 {
            let x = -260.0 + 520.0 * i as f64 / 200.0;
            let z = D - x.abs();
            truth.push(Point3::new(x, on_plane_y(z), z));
        }
        // the sphere's circle on the laser plane
        let dist = n.dot(&sphere.c.coords) + d;
        if dist.abs() < sphere.r {
            let centre = sphere.c - n * dist;
            let rho = (sphere.r * sphere.r - dist * dist).sqrt();
            let u = n.cross(&Vector3::x()).normalize();
            let w = n.cross(&u);
            for i in 0..360 {
                let a = (i as f64).to_radians();
                truth.push(centre + (u * a.cos() + w * a.sin()) * rho);
            }
        }
        // what the camera sees lit: not hidden from the camera or the laser by the sphere
        let visible: Vec<Point3<f64>> = truth
            .into_iter()
            .filter(|p| !sphere.blocks(&Point3::origin(), p) && !sphere.blocks(&source, p))
            .filter(|p| {
                let on_sphere = ((p - sphere.c).norm() - sphere.r).abs() < 1e-6;
                // a sphere point must face both the camera and the laser
                !on_sphere
                    || ((p - sphere.c).dot(&-p.coords) > 0.0
                        && (p - sphere.c).dot(&(source - p)) > 0.0)
            })
            .collect();
        let pixels: Vec<Point2<f32>> = visible
            .iter()
            .filter_map(|p| camera.project(p).ok())
            .filter(|px| px.x >= 0.0 && px.y >= 0.0 && px.x < 1600.0 && px.y < 1200.0)
            .map(|px| jitter(px).cast())
            .collect();
        // every stripe pixel as a board candidate, split by the board half its ray meets
        let (mut bl, mut br) = (Vec::new(), Vec::new());
        for px in &pixels {
            if let Ok((p, side)) = triangulate::board_point(&cam32, &board32, px, &limits) {
                if side == Surface::Left {
                    bl.push(p)
                } else {
                    br.push(p)
                }
            }
        }
        let Ok(lp) = laser::least_squares(&bl, &br, &cfg) else {
            continue;
        };
        frames_used += 1;
        assert!(
            lp.quality.rms < 0.2,
            "frame {k}: laser plane rms {} mm",
            lp.quality.rms
        );
        for px in &pixels {
            if let Ok((p, Surface::Object)) =
                triangulate::triangulate(&cam32, &board32, &lp.plane, px, &limits)
            {
                let p = p.cast::<f64>();
                if ((p - sphere.c).norm() - sphere.r).abs() > 1.0 {
                    stray += 1;
                }
                object.push(p);
            }
        }
    }
    assert_eq!(frames_used, 40, "every frame has a laser plane");
    assert!(object.len() > 2000, "only {} sphere points", object.len());
    assert!(
        stray * 200 < object.len(),
        "{stray} of {} object points are more than 1 mm off the sphere",
        object.len()
    );
    let (c, r) = fit_sphere(&object);
    let rms = (object
        .iter()
        .map(|p| ((p - c).norm() - r).powi(2))
        .sum::<f64>()
        / object.len() as f64)
        .sqrt();
    println!(
        "{} points; sphere centre off by {:.4} mm, radius off by {:.4} mm, rms {:.4} mm",
        object.len(),
        (c - sphere.c).norm(),
        r - sphere.r,
        rms
    );
    // 0.02 % of the distance for the centre and the radius, 0.05 % for the residual
    assert!((c - sphere.c).norm() < 2e-4 * D);
    assert!((r - sphere.r).abs() < 2e-4 * D);
    assert!(rms < 5e-4 * D);
}
