//! Planes and lines in camera coordinates.

use nalgebra::{Point3, Vector3};

use scanner_wire::PlaneBlock;

use crate::real::all_finite;
use crate::{GeomError, Real};

/// A plane `n · x + d = 0` with unit normal `n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane<T: Real> {
    normal: Vector3<T>,
    d: T,
}

impl<T: Real> Plane<T> {
    /// A plane from a normal (any length) and offset: `normal · x + d = 0`.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`], or [`GeomError::BadParameter`] for a zero normal.
    pub fn new(normal: Vector3<T>, d: T) -> Result<Self, GeomError> {
        if !all_finite(&normal) || !d.finite() {
            return Err(GeomError::NotFinite);
        }
        let len = normal.norm();
        if !(len > T::zero()) || !len.finite() {
            return Err(GeomError::BadParameter("plane normal must be non-zero"));
        }
        Ok(Self {
            normal: normal / len,
            d: d / len,
        })
    }

    /// The plane through `point` with the given normal.
    ///
    /// # Errors
    /// As [`Plane::new`].
    pub fn from_point_normal(point: &Point3<T>, normal: &Vector3<T>) -> Result<Self, GeomError> {
        if !all_finite(&point.coords) {
            return Err(GeomError::NotFinite);
        }
        let p = Self::new(*normal, T::zero())?;
        let d = -p.normal.dot(&point.coords);
        Self::new(p.normal, d)
    }

    /// Unit normal.
    pub fn normal(&self) -> &Vector3<T> {
        &self.normal
    }

    /// Offset `d`: the signed distance of the camera centre (origin) from the plane.
    pub fn offset(&self) -> T {
        self.d
    }

    /// Signed distance of `p` from the plane (positive on the side the normal points to).
    pub fn signed_distance(&self, p: &Point3<T>) -> T {
        self.normal.dot(&p.coords) + self.d
    }

    /// The same plane with its normal chosen so that the camera centre is on the positive side
    /// (`d ≥ 0`), i.e. the normal points towards the camera.
    pub fn facing_camera(self) -> Self {
        if self.d < T::zero() {
            Self {
                normal: -self.normal,
                d: -self.d,
            }
        } else {
            self
        }
    }

    /// The point where the ray `s · ray` (`s > 0`) from the camera centre meets the plane.
    ///
    /// `min_sin` is the smallest accepted sine of the angle between the ray and the plane.
    ///
    /// # Errors
    /// [`GeomError::NotFinite`], [`GeomError::Grazing`] (ray nearly parallel to the plane),
    /// [`GeomError::PlaneThroughCamera`] (the plane contains the camera centre) or
    /// [`GeomError::BehindCamera`] (the ray meets it behind the camera).
    pub fn intersect_ray(&self, ray: &Vector3<T>, min_sin: T) -> Result<Point3<T>, GeomError> {
        if !all_finite(ray) {
            return Err(GeomError::NotFinite);
        }
        let len = ray.norm();
        if !(len > T::zero()) || !len.finite() {
            return Err(GeomError::BadParameter("ray must be non-zero"));
        }
        // The ray is scaled by -d / (n·ray) as it is: normalising it first adds a rounding.
        let dot = self.normal.dot(ray);
        if dot.abs() <= min_sin * len {
            return Err(GeomError::Grazing);
        }
        if self.d == T::zero() {
            return Err(GeomError::PlaneThroughCamera);
        }
        let s = -self.d / dot;
        if s <= T::zero() {
            return Err(GeomError::BehindCamera);
        }
        let p = Point3::from(ray * s);
        if all_finite(&p.coords) {
            Ok(p)
        } else {
            Err(GeomError::NotFinite)
        }
    }

    /// The line where this plane meets `other`.
    ///
    /// `min_sin` is the smallest accepted sine of the angle between the two normals.
    ///
    /// # Errors
    /// [`GeomError::Parallel`].
    pub fn intersection(&self, other: &Self, min_sin: T) -> Result<Line<T>, GeomError> {
        let dir = self.normal.cross(&other.normal);
        let sin = dir.norm();
        if !(sin > min_sin) {
            return Err(GeomError::Parallel);
        }
        // The point of the line closest to the origin: a combination of both normals.
        let n1n2 = self.normal.dot(&other.normal);
        let det = T::one() - n1n2 * n1n2;
        let a = (-self.d + other.d * n1n2) / det;
        let b = (-other.d + self.d * n1n2) / det;
        let point = Point3::from(self.normal * a + other.normal * b);
        Line::new(point, dir)
    }

    /// Angle between the two planes' normals, radians in `[0, π]`.
    pub fn normal_angle(&self, other: &Self) -> T {
        // atan2 of |cross| and dot keeps full precision near 0 and π, unlike acos.
        let c = self.normal.dot(&other.normal);
        let s = self.normal.cross(&other.normal).norm();
        s.atan2(c)
    }

    /// Converts to another float type.
    pub fn cast<U: Real>(&self) -> Plane<U> {
        Plane {
            normal: self.normal.map(|v| U::lit(v.to_f64())),
            d: U::lit(self.d.to_f64()),
        }
    }
}

/// A line: a point on it and a unit direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line<T: Real> {
    point: Point3<T>,
    dir: Vector3<T>,
}

/// A board plane as the wire carries it.
impl<T: Real> From<&Plane<T>> for PlaneBlock {
    fn from(p: &Plane<T>) -> Self {
        let n = p.normal();
        PlaneBlock {
            normal: [n.x, n.y, n.z].map(|v| v.to_f64() as f32),
            offset: p.offset().to_f64() as f32,
        }
    }
}

impl TryFrom<PlaneBlock> for Plane<f32> {
    type Error = GeomError;
    /// The plane a header carries, checked as [`Plane::new`] checks it.
    fn try_from(b: PlaneBlock) -> Result<Self, GeomError> {
        Plane::new(
            Vector3::new(b.normal[0], b.normal[1], b.normal[2]),
            b.offset,
        )
    }
}

impl<T: Real> Line<T> {
    /// A line through `point` along `dir` (any length).
    ///
    /// # Errors
    /// [`GeomError::NotFinite`], or [`GeomError::BadParameter`] for a zero direction.
    pub fn new(point: Point3<T>, dir: Vector3<T>) -> Result<Self, GeomError> {
        if !all_finite(&point.coords) || !all_finite(&dir) {
            return Err(GeomError::NotFinite);
        }
        let len = dir.norm();
        if !(len > T::zero()) || !len.finite() {
            return Err(GeomError::BadParameter("line direction must be non-zero"));
        }
        Ok(Self {
            point,
            dir: dir / len,
        })
    }

    /// A point on the line.
    pub fn point(&self) -> &Point3<T> {
        &self.point
    }

    /// Unit direction.
    pub fn direction(&self) -> &Vector3<T> {
        &self.dir
    }

    /// Distance of `p` from the line.
    pub fn distance(&self, p: &Point3<T>) -> T {
        let v = p - self.point;
        (v - self.dir * v.dot(&self.dir)).norm()
    }

    /// The point of this line nearest to `other`, and the point of `other` nearest to this line.
    ///
    /// `min_sin` is the smallest accepted sine of the angle between the lines.
    ///
    /// # Errors
    /// [`GeomError::Parallel`].
    pub fn closest_points(
        &self,
        other: &Self,
        min_sin: T,
    ) -> Result<(Point3<T>, Point3<T>), GeomError> {
        let b = self.dir.dot(&other.dir);
        let det = T::one() - b * b;
        if !(det.sqrt() > min_sin) {
            return Err(GeomError::Parallel);
        }
        let w = self.point - other.point;
        let d = self.dir.dot(&w);
        let e = other.dir.dot(&w);
        let s = (b * e - d) / det;
        let t = (e - b * d) / det;
        Ok((self.point + self.dir * s, other.point + other.dir * t))
    }

    /// Converts to another float type.
    pub fn cast<U: Real>(&self) -> Line<U> {
        Line {
            point: self.point.map(|v| U::lit(v.to_f64())),
            dir: self.dir.map(|v| U::lit(v.to_f64())),
        }
    }
}
