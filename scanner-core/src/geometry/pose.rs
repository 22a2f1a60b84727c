//! Pose of a planar marker layout from its image: homography, decomposition, refinement.
//!
//! A board plane carries markers at known 2-D positions `(u, v)` in mm on the sheet. Their 3-D
//! positions in camera coordinates are `R (u, v, 0) + t`. From the marker pixels:
//! 1. undistort to normalised coordinates,
//! 2. the homography layout → normalised image by the normalised DLT (Hartley), accumulated as a
//!    9×9 normal matrix so that memory does not grow with the number of markers,
//! 3. `H ∝ [r1 r2 t]` gives the initial pose (Zhang 2000), projected onto a rotation by SVD,
//! 4. Levenberg–Marquardt on the 6 pose parameters minimises the reprojection error, weighted by
//!    the focal lengths so that it is measured in pixels.
//!
//! This uses every marker of a plane with its known layout, which is what takes the board planes
//! past the paper's three-point lines (see `NOTES.md`): the paper's 2×3 layout already works
//! (6 markers), and denser layouts work the same way.

use nalgebra::{
    Matrix3, Matrix6, Point2, Point3, Rotation3, SMatrix, SVD, SymmetricEigen, Vector2, Vector3,
    Vector6,
};

use nalgebra::ComplexField;

use super::plane::Plane;
use crate::real::all_finite;
use crate::{Camera, GeomError};

/// Fewest markers a layout pose accepts (a homography has 8 degrees of freedom).
pub const MIN_MARKERS: usize = 4;
/// Most markers one plane may carry (fixed memory: the undistorted markers live on the stack).
pub const MAX_MARKERS: usize = crate::config::MAX_MARKERS;
/// Largest number of Levenberg–Marquardt iterations.
pub const MAX_ITERATIONS: usize = 100;

/// A rigid transform from board-sheet coordinates (mm, sheet in `z = 0`) to camera coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation sheet → camera.
    pub rotation: Rotation3<f64>,
    /// Position of the sheet origin in camera coordinates, mm.
    pub translation: Vector3<f64>,
}

impl Pose {
    /// Camera coordinates of the sheet point `(u, v, 0)`.
    pub fn transform(&self, uv: &Point2<f64>) -> Point3<f64> {
        Point3::from(self.rotation * Vector3::new(uv.x, uv.y, 0.0) + self.translation)
    }

    /// The sheet's plane in camera coordinates, normal towards the camera.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`] for a pose with non-finite values.
    pub fn plane(&self) -> Result<Plane<f64>, GeomError> {
        let normal = self.rotation * Vector3::z();
        Ok(Plane::from_point_normal(&Point3::from(self.translation), &normal)?.facing_camera())
    }
}

/// A refined layout pose with its reprojection residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFit {
    /// The pose.
    pub pose: Pose,
    /// Root-mean-square reprojection error, pixels.
    pub rms_px: f64,
    /// Largest reprojection error, pixels.
    pub max_px: f64,
    /// Levenberg–Marquardt iterations used.
    pub iterations: usize,
}

/// Similarity transform that moves points to their centroid and scales the mean distance to √2.
fn normalising_transform<I: Iterator<Item = Vector2<f64>> + Clone>(
    pts: I,
) -> Result<Matrix3<f64>, GeomError> {
    let (mut sum, mut n) = (Vector2::zeros(), 0.0);
    for p in pts.clone() {
        sum += p;
        n += 1.0;
    }
    let c = sum / n;
    let mean_dist = pts.map(|p| (p - c).norm()).sum::<f64>() / n;
    if !(mean_dist > 0.0) {
        return Err(GeomError::Collinear);
    }
    let s = core::f64::consts::SQRT_2 / mean_dist;
    Ok(Matrix3::new(
        s,
        0.0,
        -s * c.x,
        0.0,
        s,
        -s * c.y,
        0.0,
        0.0,
        1.0,
    ))
}

fn apply_h(h: &Matrix3<f64>, p: &Vector2<f64>) -> Vector2<f64> {
    let q = h * Vector3::new(p.x, p.y, 1.0);
    Vector2::new(q.x / q.z, q.y / q.z)
}

/// The homography `H` with `image ∝ H · (u, v, 1)` from `layout` (sheet mm) to `image` points
/// (normalised camera coordinates), by the normalised DLT.
///
/// # Errors
/// [`GeomError::LengthMismatch`], [`GeomError::TooFewPoints`], [`GeomError::NotFinite`],
/// [`GeomError::Collinear`] (the layout or its image spans no plane) or
/// [`GeomError::NoConvergence`].
pub fn homography(
    layout: &[Point2<f64>],
    image: &[Vector2<f64>],
) -> Result<Matrix3<f64>, GeomError> {
    if layout.len() != image.len() {
        return Err(GeomError::LengthMismatch);
    }
    if layout.len() < MIN_MARKERS {
        return Err(GeomError::TooFewPoints {
            needed: MIN_MARKERS,
            got: layout.len(),
        });
    }
    if !layout.iter().all(|p| all_finite(&p.coords)) || !image.iter().all(all_finite) {
        return Err(GeomError::NotFinite);
    }
    let ts = normalising_transform(layout.iter().map(|p| p.coords))?;
    let td = normalising_transform(image.iter().copied())?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (s, d) in layout.iter().zip(image) {
        let s = apply_h(&ts, &s.coords);
        let d = apply_h(&td, d);
        let r1 = SMatrix::<f64, 9, 1>::from_column_slice(&[
            0.0,
            0.0,
            0.0,
            -s.x,
            -s.y,
            -1.0,
            d.y * s.x,
            d.y * s.y,
            d.y,
        ]);
        let r2 = SMatrix::<f64, 9, 1>::from_column_slice(&[
            s.x,
            s.y,
            1.0,
            0.0,
            0.0,
            0.0,
            -d.x * s.x,
            -d.x * s.y,
            -d.x,
        ]);
        ata += r1 * r1.transpose() + r2 * r2.transpose();
    }
    let eig = SymmetricEigen::try_new(ata, f64::EPSILON, 200).ok_or(GeomError::NoConvergence)?;
    let mut vals: [(f64, usize); 9] = core::array::from_fn(|i| (eig.eigenvalues[i], i));
    vals.sort_unstable_by(|a, b| a.0.partial_cmp(&b.0).unwrap_or(core::cmp::Ordering::Equal));
    // A planar layout seen by a camera leaves exactly one null vector; a second one (collinear
    // points) leaves the homography undetermined.
    if !(vals[1].0 > 1e-9 * vals[8].0) {
        return Err(GeomError::Collinear);
    }
    let h = eig.eigenvectors.column(vals[0].1);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let td_inv = td.try_inverse().ok_or(GeomError::IllConditioned)?;
    let hm = td_inv * hn * ts;
    if hm.iter().all(|v| v.is_finite()) {
        Ok(hm)
    } else {
        Err(GeomError::NotFinite)
    }
}

/// Initial pose from a homography to normalised coordinates (`K = I`).
pub(crate) fn pose_from_homography(h: &Matrix3<f64>) -> Result<Pose, GeomError> {
    let h1 = h.column(0).into_owned();
    let h2 = h.column(1).into_owned();
    let h3 = h.column(2).into_owned();
    let norm = (h1.norm() + h2.norm()) / 2.0;
    if !(norm > 0.0) {
        return Err(GeomError::IllConditioned);
    }
    let mut lambda = 1.0 / norm;
    if h3.z * lambda < 0.0 {
        lambda = -lambda; // the sheet is in front of the camera
    }
    let r1 = h1 * lambda;
    let r2 = h2 * lambda;
    let r3 = r1.cross(&r2);
    let m = Matrix3::from_columns(&[r1, r2, r3]);
    let svd = SVD::try_new(m, true, true, f64::EPSILON, 200).ok_or(GeomError::NoConvergence)?;
    let (u, vt) = (
        svd.u.ok_or(GeomError::NoConvergence)?,
        svd.v_t.ok_or(GeomError::NoConvergence)?,
    );
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        r = u2 * vt;
    }
    Ok(Pose {
        rotation: Rotation3::from_matrix_unchecked(r),
        translation: h3 * lambda,
    })
}

/// Reprojection residuals in pixels (predicted − observed normalised, scaled by fx, fy), their
/// sum of squares, and optionally the normal equations of the pose parameters (ω, t).
fn accumulate(
    pose: &Pose,
    layout: &[Point2<f64>],
    obs: &[Vector2<f64>],
    f: (f64, f64),
    normal_eq: Option<(&mut Matrix6<f64>, &mut Vector6<f64>)>,
) -> Result<(f64, f64), GeomError> {
    let (mut cost, mut max) = (0.0, 0.0f64);
    let mut jtj = Matrix6::zeros();
    let mut jtr = Vector6::zeros();
    for (uv, o) in layout.iter().zip(obs) {
        let rx = pose.rotation * Vector3::new(uv.x, uv.y, 0.0);
        let p = rx + pose.translation;
        if !(p.z > 0.0) {
            return Err(GeomError::BehindCamera);
        }
        let iz = 1.0 / p.z;
        let r = Vector2::new((p.x * iz - o.x) * f.0, (p.y * iz - o.y) * f.1);
        cost += r.norm_squared();
        max = max.max(r.norm());
        // d(u, v)/dp, then dp/dω = −[R X]×, dp/dt = I.
        let du = Vector3::new(iz, 0.0, -p.x * iz * iz) * f.0;
        let dv = Vector3::new(0.0, iz, -p.y * iz * iz) * f.1;
        let ju = Vector6::new(
            rx.cross(&du).x,
            rx.cross(&du).y,
            rx.cross(&du).z,
            du.x,
            du.y,
            du.z,
        );
        let jv = Vector6::new(
            rx.cross(&dv).x,
            rx.cross(&dv).y,
            rx.cross(&dv).z,
            dv.x,
            dv.y,
            dv.z,
        );
        jtj += ju * ju.transpose() + jv * jv.transpose();
        jtr += ju * r.x + jv * r.y;
    }
    if let Some((a, b)) = normal_eq {
        *a = jtj;
        *b = jtr;
    }
    if cost.is_finite() {
        Ok((cost, max))
    } else {
        Err(GeomError::NotFinite)
    }
}

/// Pose of a planar layout from its marker pixels.
///
/// `layout[i]` (mm on the sheet) is seen at `pixels[i]`. Needs at least [`MIN_MARKERS`] markers,
/// not all on one line, and at most [`MAX_MARKERS`]; the paper's 2×3 layout (6 markers) and
/// denser ones work.
///
/// # Errors
/// [`GeomError::LengthMismatch`], [`GeomError::TooFewPoints`], [`GeomError::NotFinite`],
/// [`GeomError::Collinear`], [`GeomError::BehindCamera`] or [`GeomError::NoConvergence`] (also
/// from undistorting a marker pixel).
pub fn plane_pose(
    camera: &Camera<f64>,
    layout: &[Point2<f64>],
    pixels: &[Point2<f64>],
) -> Result<PoseFit, GeomError> {
    if layout.len() != pixels.len() {
        return Err(GeomError::LengthMismatch);
    }
    if pixels.len() > MAX_MARKERS {
        return Err(GeomError::BadParameter(
            "more markers on one plane than MAX_MARKERS",
        ));
    }
    let mut store = [Vector2::zeros(); MAX_MARKERS];
    let obs = &mut store[..pixels.len()];
    for (o, px) in obs.iter_mut().zip(pixels) {
        *o = camera.undistort(px)?;
    }
    let obs = &*obs;
    let h = homography(layout, obs)?;
    let mut pose = pose_from_homography(&h)?;
    let f = (camera.fx(), camera.fy());
    let (mut jtj, mut jtr) = (Matrix6::zeros(), Vector6::zeros());
    let (mut cost, _) = accumulate(&pose, layout, obs, f, Some((&mut jtj, &mut jtr)))?;
    let mut mu = 1e-3 * (0..6).map(|i| jtj[(i, i)]).fold(0.0, f64::max);
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let mut a = jtj;
        for i in 0..6 {
            a[(i, i)] += mu * jtj[(i, i)].max(1e-12);
        }
        let Some(chol) = a.cholesky() else {
            mu *= 10.0;
            continue;
        };
        let delta = chol.solve(&-jtr);
        let omega = Vector3::new(delta[0], delta[1], delta[2]);
        let candidate = Pose {
            rotation: Rotation3::new(omega) * pose.rotation,
            translation: pose.translation + Vector3::new(delta[3], delta[4], delta[5]),
        };
        let (mut jtj2, mut jtr2) = (Matrix6::zeros(), Vector6::zeros());
        match accumulate(&candidate, layout, obs, f, Some((&mut jtj2, &mut jtr2))) {
            Ok((c, _)) if c <= cost => {
                let converged = cost - c <= 1e-15 * cost.max(1e-300)
                    || delta.norm() <= 1e-13 * (1.0 + pose.translation.norm());
                pose = candidate;
                cost = c;
                jtj = jtj2;
                jtr = jtr2;
                mu = (mu / 10.0).max(1e-15);
                if converged {
                    break;
                }
            }
            _ => {
                mu *= 10.0;
                if mu > 1e20 {
                    break;
                }
            }
        }
    }
    let (cost, max_px) = accumulate(&pose, layout, obs, f, None)?;
    let rms_px = (cost / (2.0 * layout.len() as f64)).sqrt();
    if !all_finite(&pose.translation) {
        return Err(GeomError::NotFinite);
    }
    Ok(PoseFit {
        pose,
        rms_px,
        max_px,
        iterations,
    })
}
