//! Three collinear points with equal known spacing, seen by the camera → their 3-D positions
//! (paper section 2A).
//!
//! `A`, `B`, `C` lie on one line with `B` the midpoint and `|AB| = |BC| = m`. Their images are the
//! rays `A'`, `B'`, `C'` (the paper's `(x, y, d_z)`, or [`Camera::pixel_to_ray`]'s `(x_n, y_n,
//! 1)`; any positive scale, each ray is put on the image plane `z = 1` first), and
//! `A = t1·A'`, `B = t2·B'`, `C = t3·C'`.
//!
//! Two forms are given:
//! - [`paper`]: eq. 1–6 as printed (they are correct, see `NOTES.md`).
//! - [`solve`]: `B = (A + C)/2` gives `t1 (A' − B') = t3 (B' − C')`, which fixes `t1/t3` by least
//!   squares, and `|t1 A' − t3 C'| = 2m` fixes the scale. Shorter, no cancellation in the
//!   `T1 T2 − M1 M2` denominator, and no worse under noise.
//!
//! Both are written with 3-D vector norms and dot products, so they are invariant to rotations
//! about the optical axis: image points on an axis (the paper's section 4 "quadrant" problem,
//! which came from its per-coordinate arithmetic) are ordinary input here and need no coordinate
//! transformation. What remains degenerate — a line through the camera centre (coincident image
//! points), points out of order, vanishing denominators — is a typed error.
//!
//! [`Camera::pixel_to_ray`]: crate::Camera::pixel_to_ray

use nalgebra::{Point3, Vector3};

use nalgebra::ComplexField;

use crate::GeomError;
use crate::real::all_finite;

/// Relative size below which an image separation counts as zero.
const COINCIDENT: f64 = 1e-12;

fn check(rays: &[Vector3<f64>; 3], m: f64) -> Result<(), GeomError> {
    if !rays.iter().all(all_finite) || !m.is_finite() {
        return Err(GeomError::NotFinite);
    }
    if !(m > 0.0) {
        return Err(GeomError::BadParameter("marker spacing must be positive"));
    }
    if rays.iter().any(|r| !(r.norm() > 0.0)) {
        return Err(GeomError::BadParameter("ray must be non-zero"));
    }
    Ok(())
}

fn points(rays: &[Vector3<f64>; 3], t: [f64; 3]) -> Result<[Point3<f64>; 3], GeomError> {
    if !t.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    let p = [0, 1, 2].map(|i| Point3::from(rays[i] * t[i]));
    if p.iter().all(|p| all_finite(&p.coords)) {
        Ok(p)
    } else {
        Err(GeomError::NotFinite)
    }
}

/// Puts the rays on the common image plane `z = 1` (the paper's image points up to the factor
/// `d_z`), which both forms assume: `t2 = (t1 + t3)/2` holds only for rays of equal depth.
fn on_image_plane(rays: &[Vector3<f64>; 3]) -> Result<[Vector3<f64>; 3], GeomError> {
    if !rays.iter().all(|r| r.z > 0.0) {
        return Err(GeomError::BehindCamera);
    }
    let out = rays.map(|r| r / r.z);
    if out.iter().all(all_finite) {
        Ok(out)
    } else {
        Err(GeomError::NotFinite)
    }
}

/// The paper's closed form, eq. 1–6, for rays `[A', B', C']` and spacing `m`.
///
/// # Errors
/// [`GeomError::NotFinite`], [`GeomError::BadParameter`], [`GeomError::CoincidentPoints`], or
/// [`GeomError::IllConditioned`] where a denominator vanishes or a radicand is negative.
pub fn paper(rays: &[Vector3<f64>; 3], m: f64) -> Result<[Point3<f64>; 3], GeomError> {
    check(rays, m)?;
    let [a1, b1, c1] = on_image_plane(rays)?;
    if (a1 - b1).norm() < COINCIDENT || (b1 - c1).norm() < COINCIDENT {
        return Err(GeomError::CoincidentPoints);
    }
    // The midpoint images between the ends. Eq. 1–6 use distances only and would return a
    // "solution" for images out of order.
    if !((a1 - b1).dot(&(c1 - b1)) < 0.0) {
        return Err(GeomError::IllConditioned);
    }
    // eq. 2 and 3 (a, b, c as 3-D differences: equal to the paper's 2-D ones when the rays share
    // the image plane z = d_z)
    let (d1s, d2s, d3s) = (a1.norm_squared(), b1.norm_squared(), c1.norm_squared());
    let a2 = (a1 - b1).norm_squared();
    let b2 = (b1 - c1).norm_squared();
    let c2 = (a1 - c1).norm_squared();
    let m2 = m * m;
    // eq. 4
    let u = d1s + d2s - a2;
    let v = d2s + d3s - b2;
    let w = d1s + d3s - c2;
    if !(w.abs() > COINCIDENT) {
        return Err(GeomError::IllConditioned);
    }
    // eq. 5
    let t1 = (u - d2s) * d1s / (2.0 * w) - (d1s - u / 2.0 + d2s / 4.0);
    let t2 = (v - d2s) * d3s / (2.0 * w) - (d3s - v / 2.0 + d2s / 4.0);
    let m1 = d2s / 4.0 - (u - d2s) * d3s / (2.0 * w);
    let m2_ = d2s / 4.0 - (v - d2s) * d1s / (2.0 * w);
    let n1 = (u - d2s) * 4.0 * m2 / (2.0 * w) - m2;
    let n2 = (v - d2s) * 4.0 * m2 / (2.0 * w) - m2;
    // eq. 6
    let den = t1 * t2 - m1 * m2_;
    let size = (t1 * t2).abs().max((m1 * m2_).abs());
    if !(den.abs() > COINCIDENT * size) {
        return Err(GeomError::IllConditioned);
    }
    let r1 = (m1 * n2 + t2 * n1) / den;
    let r3 = (m2_ * n1 + t1 * n2) / den;
    if !(r1 > 0.0 && r3 > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    let (s1, s3) = (r1.sqrt(), r3.sqrt());
    points(&[a1, b1, c1], [s1, (s1 + s3) / 2.0, s3])
}

/// The better-conditioned form for rays `[A', B', C']` and spacing `m`.
///
/// # Errors
/// [`GeomError::NotFinite`], [`GeomError::BadParameter`], [`GeomError::CoincidentPoints`], or
/// [`GeomError::IllConditioned`] when the images are out of order (`B'` not between `A'` and
/// `C'`).
pub fn solve(rays: &[Vector3<f64>; 3], m: f64) -> Result<[Point3<f64>; 3], GeomError> {
    check(rays, m)?;
    let [a1, b1, c1] = on_image_plane(rays)?;
    let u = a1 - b1;
    let v = b1 - c1;
    let uu = u.norm_squared();
    if uu.sqrt() < COINCIDENT || v.norm() < COINCIDENT {
        return Err(GeomError::CoincidentPoints);
    }
    // t1 u = t3 v  →  ρ = t1/t3 minimises |ρ u − v|².
    let rho = u.dot(&v) / uu;
    if !(rho > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    let span = (a1 * rho - c1).norm();
    if !(span > COINCIDENT) {
        return Err(GeomError::IllConditioned);
    }
    let t3 = 2.0 * m / span;
    let t1 = rho * t3;
    points(&[a1, b1, c1], [t1, (t1 + t3) / 2.0, t3])
}
