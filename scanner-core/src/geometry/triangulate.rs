//! Triangulation of stripe pixels: the ray through the pixel meets the laser plane (paper section
//! 2B, last paragraph), and the point is classified against the board.

use nalgebra::{Point2, Point3};

use super::board::{Board, Surface};
use super::plane::Plane;
use crate::{Camera, GeomError, Real};

/// When a triangulated point counts as valid. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits<T> {
    /// Smallest accepted sine of the angle between a ray and the plane it meets.
    pub min_sin: T,
    /// Largest accepted distance from the camera centre.
    pub max_range: T,
    /// Distance from a board plane within which a point counts as on it.
    pub board_tol: T,
}

impl<T: Real> Default for Limits<T> {
    fn default() -> Self {
        Self {
            min_sin: T::lit(0.035), // 2°
            max_range: T::lit(10_000.0),
            board_tol: T::lit(1.0),
        }
    }
}

/// The point where the ray through `pixel` meets `plane`.
///
/// # Errors
/// From [`Camera::pixel_to_ray`] and [`Plane::intersect_ray`]; [`GeomError::BeyondRange`].
pub fn ray_plane<T: Real>(
    camera: &Camera<T>,
    plane: &Plane<T>,
    pixel: &Point2<T>,
    limits: &Limits<T>,
) -> Result<Point3<T>, GeomError> {
    let ray = camera.pixel_to_ray(pixel)?;
    let p = plane.intersect_ray(&ray, limits.min_sin)?;
    if p.coords.norm() > limits.max_range {
        return Err(GeomError::BeyondRange);
    }
    Ok(p)
}

/// The board point seen at a stripe pixel (before the laser plane is known): the nearer crossing
/// of the pixel's ray with the two board planes.
///
/// # Errors
/// From [`Camera::pixel_to_ray`] and [`Board::intersect_ray`]; [`GeomError::BeyondRange`].
pub fn board_point<T: Real>(
    camera: &Camera<T>,
    board: &Board<T>,
    pixel: &Point2<T>,
    limits: &Limits<T>,
) -> Result<(Point3<T>, Surface), GeomError> {
    let ray = camera.pixel_to_ray(pixel)?;
    let (p, s) = board.intersect_ray(&ray, limits.min_sin)?;
    if p.coords.norm() > limits.max_range {
        return Err(GeomError::BeyondRange);
    }
    Ok((p, s))
}

/// Triangulates a stripe pixel with the frame's laser plane and says where the point lies.
///
/// # Errors
/// The point is invalid, with the reason: [`GeomError::BehindCamera`], [`GeomError::Grazing`],
/// [`GeomError::PlaneThroughCamera`], [`GeomError::BeyondRange`], [`GeomError::BehindBoard`],
/// [`GeomError::NotFinite`] or [`GeomError::NoConvergence`] (undistortion).
pub fn triangulate<T: Real>(
    camera: &Camera<T>,
    board: &Board<T>,
    laser: &Plane<T>,
    pixel: &Point2<T>,
    limits: &Limits<T>,
) -> Result<(Point3<T>, Surface), GeomError> {
    let p = ray_plane(camera, laser, pixel, limits)?;
    let s = board.locate(&p, limits.board_tol)?;
    Ok((p, s))
}
