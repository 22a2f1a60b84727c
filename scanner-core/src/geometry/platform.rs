//! The platform of a turntable scanner with a fixed laser (the Ciclop and FabScanPi way): where
//! it stands in the camera's frame, and a point seen at a turn of the platform carried into the
//! platform's own frame, where the object does not move.
//!
//! The platform's frame: origin on the turning axis at the platform's top, `z` up the axis,
//! `x` and `y` on the top (at turn 0). A point `X` seen by the camera when the platform has
//! turned by `θ` (counter-clockwise seen from above, about `z`) lies at `Rz(−θ) · Rᵀ (X − t)` in
//! the platform's frame, `R` and `t` the platform's pose at turn 0 (its axes' directions and its
//! origin in camera coordinates): the turn undone.

use nalgebra::{Matrix3, Point3, Vector3};

use super::board::Board;
use super::plane::Plane;
use crate::real::all_finite;
use crate::{GeomError, Real};

/// A turning platform's pose in the camera's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Platform<T: Real> {
    rotation: Matrix3<T>,
    origin: Point3<T>,
}

impl<T: Real> Platform<T> {
    /// The platform whose axes (`x`, `y`, and `z` up the turning axis) are the columns of
    /// `rotation`, camera coordinates, and whose origin (on the axis, at the top) is `origin`.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`]; [`GeomError::BadParameter`] for a matrix that is not a rotation
    /// (columns not unit and orthogonal within 1e-3, or a mirror); [`GeomError::PlaneThroughCamera`]
    /// for a platform whose top passes through the camera centre.
    pub fn new(rotation: Matrix3<T>, origin: Point3<T>) -> Result<Self, GeomError> {
        if !rotation.iter().all(|v| v.finite()) || !all_finite(&origin.coords) {
            return Err(GeomError::NotFinite);
        }
        let gram = rotation.transpose() * rotation - Matrix3::identity();
        if gram.iter().any(|v| v.abs() > T::lit(1e-3)) || rotation.determinant() < T::zero() {
            return Err(GeomError::BadParameter(
                "platform rotation must be a rotation (orthonormal columns, no mirror)",
            ));
        }
        let p = Self { rotation, origin };
        if p.top()?.offset().abs() < T::lit(1e-6) {
            return Err(GeomError::PlaneThroughCamera);
        }
        Ok(p)
    }

    /// The axes' directions (columns: `x`, `y`, `z` up the axis), camera coordinates.
    pub fn rotation(&self) -> &Matrix3<T> {
        &self.rotation
    }

    /// The origin: the axis at the platform's top, camera coordinates.
    pub fn origin(&self) -> &Point3<T> {
        &self.origin
    }

    /// The turning axis's direction (up), camera coordinates.
    pub fn axis(&self) -> Vector3<T> {
        self.rotation.column(2).into_owned()
    }

    /// The platform's top as a plane in camera coordinates, its normal up the axis.
    ///
    /// # Errors
    /// As [`Plane::from_point_normal`].
    pub fn top(&self) -> Result<Plane<T>, GeomError> {
        let axis = self.axis();
        let d = -axis.dot(&self.origin.coords);
        Plane::new(axis, d)
    }

    /// `p` (camera coordinates, seen with the platform turned by `angle` radians,
    /// counter-clockwise seen from above) in the platform's frame: the turn undone.
    pub fn to_platform(&self, p: &Point3<T>, angle: T) -> Point3<T> {
        let q = self.rotation.transpose() * (p - self.origin);
        let (s, c) = ((-angle).sin(), (-angle).cos());
        Point3::new(c * q.x - s * q.y, s * q.x + c * q.y, q.z)
    }

    /// The platform's two known surfaces as a board: its top (left) and the upright plane
    /// `radius` mm behind its axis as the camera sees it (right). A point below the top or
    /// beyond the back plane is not the object; one on the top is the platform.
    ///
    /// # Errors
    /// [`GeomError::BadParameter`] for a radius that is not positive; [`GeomError::Parallel`]
    /// when the camera looks down the axis (no back plane); as [`Board::new`].
    pub fn known_surfaces(&self, radius: T) -> Result<Board<T>, GeomError> {
        if !(radius > T::zero()) || !radius.finite() {
            return Err(GeomError::BadParameter("platform radius must be positive"));
        }
        let axis = self.axis();
        let to_camera = -self.origin.coords;
        let level = to_camera - axis * axis.dot(&to_camera);
        let len = level.norm();
        if !(len > T::lit(1e-6) * to_camera.norm()) {
            return Err(GeomError::Parallel);
        }
        let toward = level / len;
        let back = Plane::from_point_normal(&(self.origin - toward * radius), &toward)?;
        Board::new(self.top()?, back)
    }

    /// The camera's centre in the platform's frame with the platform turned by `angle`.
    pub fn camera_centre(&self, angle: T) -> Point3<T> {
        self.to_platform(&Point3::origin(), angle)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn platform() -> Platform<f64> {
        // camera looking along +z at an upright axis 300 mm ahead: platform z = camera −y
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        Platform::new(r, Point3::new(0.0, 50.0, 300.0)).unwrap()
    }

    #[test]
    fn a_point_on_the_axis_stays_there_whatever_the_turn() {
        let p = platform();
        let on_axis = Point3::new(0.0, 20.0, 300.0);
        for angle in [0.0, 1.0, 2.5] {
            let q = p.to_platform(&on_axis, angle);
            assert!((q - Point3::new(0.0, 0.0, 30.0)).norm() < 1e-12, "{q}");
        }
    }

    #[test]
    fn a_quarter_turn_is_undone() {
        let p = platform();
        // seen on the platform's +x after a quarter turn counter-clockwise: it stood on −y
        let q = p.to_platform(
            &Point3::new(10.0, 50.0, 300.0),
            core::f64::consts::FRAC_PI_2,
        );
        assert!((q - Point3::new(0.0, -10.0, 0.0)).norm() < 1e-12, "{q}");
    }

    #[test]
    fn the_known_surfaces_keep_the_object_and_drop_the_top_and_what_lies_behind() {
        use crate::geometry::Surface;
        let p = platform();
        let b = p.known_surfaces(70.0).unwrap();
        // above the platform near the axis: object
        assert_eq!(
            b.locate(&Point3::new(0.0, 20.0, 300.0), 1.0),
            Ok(Surface::Object)
        );
        // on the top
        assert!(
            matches!(b.locate(&Point3::new(10.0, 50.0, 290.0), 1.0), Ok(s) if s != Surface::Object)
        );
        // beyond the back plane (z > 370)
        assert!(!matches!(
            b.locate(&Point3::new(0.0, 20.0, 380.0), 1.0),
            Ok(Surface::Object)
        ));
        assert!(p.known_surfaces(0.0).is_err());
    }

    #[test]
    fn mirrors_and_skews_are_refused() {
        let mirror = Matrix3::new(-1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        assert!(Platform::new(mirror, Point3::new(0.0, 0.0, 300.0)).is_err());
        let skew = Matrix3::new(1.0, 0.1, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        assert!(Platform::new(skew, Point3::new(0.0, 0.0, 300.0)).is_err());
        let nan = Matrix3::new(f64::NAN, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        assert_eq!(
            Platform::new(nan, Point3::new(0.0, 0.0, 300.0)),
            Err(GeomError::NotFinite)
        );
        // the camera on the platform's top
        let flat = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        assert_eq!(
            Platform::new(flat, Point3::new(0.0, 0.0, 300.0)),
            Err(GeomError::PlaneThroughCamera)
        );
    }
}
