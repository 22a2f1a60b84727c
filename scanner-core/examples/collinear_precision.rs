//! Prints the worst relative error of the paper's closed form (eq. 1-6) and of the vector form on
//! exact data, against the marker spacing relative to the distance.
use scanner_core::geometry::collinear;
use scanner_core::nalgebra::{Point3, Vector3};

fn main() {
    println!("{:>8} {:>12} {:>12}", "m/z", "paper", "vector");
    for ratio in [
        0.5,
        1.0 / 7.0,
        1.0 / 20.0,
        1.0 / 50.0,
        1.0 / 200.0,
        1.0 / 1000.0,
    ] {
        let (mut wp, mut wv) = (0.0f64, 0.0f64);
        for i in 0..2000 {
            let f = |k: u32| ((i * 7919 + k * 104729) % 1000) as f64 / 1000.0;
            let z = 200.0 + 3800.0 * f(1);
            let a = Point3::new((f(2) - 0.5) * 0.8 * z, (f(3) - 0.5) * 0.6 * z, z);
            let th = f(4) * std::f64::consts::TAU;
            let tilt = (f(5) - 0.5) * 2.4;
            let u = Vector3::new(th.cos() * tilt.cos(), th.sin() * tilt.cos(), tilt.sin());
            let m = ratio * z;
            let pts = [a, a + u * m, a + u * 2.0 * m];
            if pts.iter().any(|p| p.z < 50.0) || u.cross(&pts[1].coords.normalize()).norm() < 0.1 {
                continue;
            }
            let rays = pts.map(|p| p.coords / p.z * 1400.0);
            let err = |r: [Point3<f64>; 3]| {
                (0..3)
                    .map(|k| (r[k] - pts[k]).norm() / pts[k].coords.norm())
                    .fold(0.0, f64::max)
            };
            if let Ok(r) = collinear::paper(&rays, m) {
                wp = wp.max(err(r));
            }
            if let Ok(r) = collinear::solve(&rays, m) {
                wv = wv.max(err(r));
            }
        }
        println!("{ratio:>8.4} {wp:>12.2e} {wv:>12.2e}");
    }
}
