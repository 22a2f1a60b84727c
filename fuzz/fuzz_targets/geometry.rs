//! The geometry on arbitrary floats: camera projection and undistortion, plane intersections,
//! the paper's collinear points, the laser-plane fits, the image distance. Errors are fine;
//! panics and non-finite results are not.
#![no_main]
use libfuzzer_sys::fuzz_target;
use scanner_core::geometry::{LaserFitConfig, Plane, collinear, laser};
use scanner_core::nalgebra::{Point2, Point3, Vector3};
use scanner_core::{Camera, Distortion};

fuzz_target!(|data: &[u8]| {
    let f: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    if f.len() < 24 {
        return;
    }
    let d = Distortion {
        k1: f[4],
        k2: f[5],
        p1: f[6],
        p2: f[7],
        k3: f[8],
    };
    if let Ok(cam) = Camera::new(f[0], f[1], f[2], f[3], d) {
        if let Ok(n) = cam.undistort(&Point2::new(f[9], f[10])) {
            assert!(n.x.is_finite() && n.y.is_finite());
        }
        if let Ok(p) = cam.project(&Point3::new(f[11], f[12], f[13])) {
            assert!(p.x.is_finite() && p.y.is_finite());
        }
    }
    if let Ok(plane) = Plane::new(Vector3::new(f[14], f[15], f[16]), f[17]) {
        if let Ok(p) = plane.intersect_ray(&Vector3::new(f[18], f[19], f[20]), 1e-3) {
            assert!(p.coords.iter().all(|v| v.is_finite()));
        }
    }
    let rays = [
        Vector3::new(f[0], f[1], 1.0),
        Vector3::new(f[2], f[3], 1.0),
        Vector3::new(f[4], f[5], 1.0),
    ];
    if let Ok(pts) = collinear::solve(&rays, f[21]) {
        assert!(pts.iter().all(|p| p.coords.iter().all(|v| v.is_finite())));
    }
    let pts: Vec<Point3<f64>> = f
        .chunks_exact(3)
        .map(|c| Point3::new(c[0], c[1], c[2]))
        .collect();
    let (l, r) = pts.split_at(pts.len() / 2);
    if let Ok(fit) = laser::least_squares(l, r, &LaserFitConfig::default()) {
        assert!(fit.plane.normal().iter().all(|v| v.is_finite()));
    }
    let _ = scanner_core::calib::image_distance(
        f[22],
        scanner_core::calib::CrossShot {
            tape_mm: f[23],
            span_px: f[0],
        },
        scanner_core::calib::CrossShot {
            tape_mm: f[1],
            span_px: f[2],
        },
    );
});
