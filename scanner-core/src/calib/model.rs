//! Where a printed marker appears in the image.
//!
//! A corner (a chessboard's) images at the projection of its point. A printed disc does not: its
//! image is (before lens distortion) an ellipse whose centre is *not* the projection of the disc's
//! centre when the sheet is tilted — the near half of the disc looks larger than the far half. On
//! a board at 45° this eccentricity is 0.1–0.2 px for a 25 mm disc at 800 mm, several times a good
//! detector's noise, so calibration predicts the centre of the imaged ellipse instead.
//!
//! The circle `(u − a)² + (v − b)² = r²` on the sheet is the conic `Q`; with the sheet → image
//! homography `H = [r₁ r₂ t]` its image is the conic `C = H⁻ᵀ Q H⁻¹`, whose centre is the pole of
//! the line at infinity, `C⁻¹ (0, 0, 1)ᵀ = H Q⁻¹ Hᵀ (0, 0, 1)ᵀ`. Written out, with `P` the disc's
//! centre in camera coordinates:
//! ```text
//! centre ∝ P_z · P − r² · (r₁_z · r₁ + r₂_z · r₂)
//! ```
//! which is `P` itself for `r = 0`. The area centroid of an ellipse is its centre; lens
//! distortion then bends the ellipse slightly, which moves its centroid by a second-order amount
//! (below 0.01 px for the rig's markers, measured against rendered discs in the device tests).

use nalgebra::{Point2, Vector2, Vector3};

use crate::geometry::Pose;
use crate::{Camera, GeomError};

/// Undistorted normalised image coordinates of the centre of the imaged disc of radius `radius`
/// (mm; 0 for a point) centred at `sheet` on a sheet at `pose`.
///
/// # Errors
/// [`GeomError::BehindCamera`] if the disc's centre is not in front of the camera,
/// [`GeomError::NotFinite`].
pub fn dot_centre(
    pose: &Pose,
    sheet: &Point2<f64>,
    radius: f64,
) -> Result<Vector2<f64>, GeomError> {
    let p = pose.transform(sheet).coords;
    if !(p.z > 0.0) {
        return Err(GeomError::BehindCamera);
    }
    let c = if radius > 0.0 {
        let r1: Vector3<f64> = pose.rotation * Vector3::x();
        let r2: Vector3<f64> = pose.rotation * Vector3::y();
        p * p.z - (r1 * r1.z + r2 * r2.z) * (radius * radius)
    } else {
        p
    };
    if !(c.z > 0.0) {
        // The disc reaches behind the camera: its image is not an ellipse.
        return Err(GeomError::BehindCamera);
    }
    let n = Vector2::new(c.x / c.z, c.y / c.z);
    if n.x.is_finite() && n.y.is_finite() {
        Ok(n)
    } else {
        Err(GeomError::NotFinite)
    }
}

/// The pixel where a detector finds the marker at `sheet`: the imaged disc's centre (radius
/// `radius` mm; 0 for a corner), distorted by the lens.
///
/// # Errors
/// As [`dot_centre`].
pub fn predict(
    camera: &Camera<f64>,
    pose: &Pose,
    sheet: &Point2<f64>,
    radius: f64,
) -> Result<Point2<f64>, GeomError> {
    let px = camera.normalized_to_pixel(dot_centre(pose, sheet, radius)?);
    if px.x.is_finite() && px.y.is_finite() {
        Ok(px)
    } else {
        Err(GeomError::NotFinite)
    }
}
