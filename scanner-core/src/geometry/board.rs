//! The background calibration board: two planes meeting at the crease line `L_c` (paper section
//! 2B).
//!
//! The board is concave as seen from the camera (the crease is its deepest part), at any opening
//! angle: the paper allows more or less than a right angle, and the angle as built is measured
//! here from the two planes, never assumed. Each half of a concave board lies on the camera side
//! of the other half's plane, so "in front of both planes" is exactly the space an object can
//! occupy, and a point behind either plane cannot be seen.

use nalgebra::{Point3, Vector3};

use super::collinear;
use super::fit::{PlaneFit, fit_plane};
use super::plane::{Line, Plane};
use scanner_wire::PlaneBlock;

use crate::{GeomError, Real};

/// Smallest accepted sine of the angle between the two board planes' normals (2°).
const MIN_BOARD_SIN: f64 = 0.035;

/// Where a triangulated point lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Surface {
    /// On the left board plane.
    Left,
    /// On the right board plane.
    Right,
    /// In front of both board planes: on the object.
    Object,
}

/// The two board planes and their crease line, in camera coordinates (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Board<T: Real> {
    left: Plane<T>,
    right: Plane<T>,
    crease: Line<T>,
}

/// The board's planes as the wire carries them, left then right.
impl<T: Real> From<&Board<T>> for [PlaneBlock; 2] {
    fn from(b: &Board<T>) -> Self {
        [b.left().into(), b.right().into()]
    }
}

impl TryFrom<[PlaneBlock; 2]> for Board<f32> {
    type Error = GeomError;
    /// The board a header carries, checked: planes that are not planes or do not meet get a
    /// [`GeomError`].
    fn try_from([left, right]: [PlaneBlock; 2]) -> Result<Self, GeomError> {
        Board::new(left.try_into()?, right.try_into()?)
    }
}

impl<T: Real> Board<T> {
    /// A board from its two planes (normals are turned to face the camera).
    ///
    /// # Errors
    /// [`GeomError::PlaneThroughCamera`] if a plane contains the camera centre,
    /// [`GeomError::Parallel`] if the planes are (nearly) parallel.
    pub fn new(left: Plane<T>, right: Plane<T>) -> Result<Self, GeomError> {
        let (left, right) = (left.facing_camera(), right.facing_camera());
        if !(left.offset() > T::zero() && right.offset() > T::zero()) {
            return Err(GeomError::PlaneThroughCamera);
        }
        let crease = left.intersection(&right, T::lit(MIN_BOARD_SIN))?;
        Ok(Self {
            left,
            right,
            crease,
        })
    }

    /// The left plane, normal towards the camera.
    pub fn left(&self) -> &Plane<T> {
        &self.left
    }

    /// The right plane, normal towards the camera.
    pub fn right(&self) -> &Plane<T> {
        &self.right
    }

    /// The crease line `L_c` where the planes meet.
    pub fn crease(&self) -> &Line<T> {
        &self.crease
    }

    /// Up along the crease, unit: its direction turned to point up the image (−y in camera
    /// coordinates), since the board stands on the table the objects stand on.
    pub fn up(&self) -> Vector3<T> {
        let d = self.crease.direction().normalize();
        if d.y >= T::zero() { -d } else { d }
    }

    /// The opening angle of the board as built, radians: π/2 for a right-angled corner, π for a
    /// flat wall.
    pub fn angle(&self) -> T {
        T::pi() - self.left.normal_angle(&self.right)
    }

    /// Which surface the point `p` lies on, with tolerance `tol` (mm) for "on a plane".
    ///
    /// # Errors
    /// [`GeomError::NotFinite`], or [`GeomError::BehindBoard`] when `p` is more than `tol`
    /// behind either plane.
    pub fn locate(&self, p: &Point3<T>, tol: T) -> Result<Surface, GeomError> {
        let dl = self.left.signed_distance(p);
        let dr = self.right.signed_distance(p);
        if !(dl.finite() && dr.finite()) {
            return Err(GeomError::NotFinite);
        }
        if dl < -tol || dr < -tol {
            return Err(GeomError::BehindBoard);
        }
        Ok(match (dl <= tol, dr <= tol) {
            (true, true) if dr.abs() < dl.abs() => Surface::Right,
            (true, _) => Surface::Left,
            (false, true) => Surface::Right,
            (false, false) => Surface::Object,
        })
    }

    /// The board point seen along `ray` from the camera: the nearer of its crossings with the two
    /// planes (inside a concave board, the ray leaves the open space through the nearer one).
    ///
    /// `min_sin` is the smallest accepted sine of the angle between the ray and a plane.
    ///
    /// # Errors
    /// [`GeomError::Grazing`] or [`GeomError::BehindCamera`] when the ray meets neither plane
    /// usefully; [`GeomError::NotFinite`].
    pub fn intersect_ray(
        &self,
        ray: &Vector3<T>,
        min_sin: T,
    ) -> Result<(Point3<T>, Surface), GeomError> {
        let l = self.left.intersect_ray(ray, min_sin);
        let r = self.right.intersect_ray(ray, min_sin);
        match (l, r) {
            (Ok(pl), Ok(pr)) if pr.coords.norm() < pl.coords.norm() => Ok((pr, Surface::Right)),
            (Ok(pl), _) => Ok((pl, Surface::Left)),
            (Err(_), Ok(pr)) => Ok((pr, Surface::Right)),
            (Err(e), Err(_)) => Err(e),
        }
    }

    /// Converts to another float type.
    pub fn cast<U: Real>(&self) -> Board<U> {
        Board {
            left: self.left.cast(),
            right: self.right.cast(),
            crease: self.crease.cast(),
        }
    }
}

/// A board plane the paper's way: from two parallel lines of three markers each, with the middle
/// marker of each line at the midpoint. `lines[k]` holds the rays of line `k`'s markers in order,
/// `spacing[k]` its marker spacing (mm). Each line is solved by [`collinear::solve`] and the plane
/// is the least-squares plane of the six points.
///
/// # Errors
/// As [`collinear::solve`] and [`fit_plane`].
pub fn plane_from_marker_lines(
    lines: &[[Vector3<f64>; 3]; 2],
    spacing: [f64; 2],
) -> Result<PlaneFit<f64>, GeomError> {
    let a = collinear::solve(&lines[0], spacing[0])?;
    let b = collinear::solve(&lines[1], spacing[1])?;
    fit_plane(a.into_iter().chain(b))
}
