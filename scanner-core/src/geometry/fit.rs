//! Least-squares plane and line fits over point sets, without storing the points.
//!
//! Both fits take a cloneable iterator and read it twice: once for the centroid, once for the
//! centred scatter matrix, which stays accurate for points far from the origin.

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

use super::plane::{Line, Plane};
use crate::real::all_finite;
use crate::{GeomError, Real};

/// Iterations allowed to the 3×3 symmetric eigen-solver.
const EIGEN_MAX_ITER: usize = 64;

/// A fitted plane with its residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneFit<T: Real> {
    /// The plane, normal towards the camera.
    pub plane: Plane<T>,
    /// Centroid of the points.
    pub centroid: Point3<T>,
    /// Root-mean-square distance of the points from the plane.
    pub rms: T,
    /// Largest distance of a point from the plane.
    pub max: T,
    /// Number of points.
    pub count: usize,
    /// Square root of the scatter's middle eigenvalue, mm: the points' extent along the plane's
    /// narrower in-plane direction, times √count. A residual σ over it is the standard
    /// uncertainty of the normal's tilt towards that direction, radians.
    pub spread: T,
}

/// A fitted line with its residuals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineFit<T: Real> {
    /// The line, through the centroid.
    pub line: Line<T>,
    /// Root-mean-square distance of the points from the line.
    pub rms: T,
    /// Number of points.
    pub count: usize,
}

/// Centroid, scatter matrix (sorted eigen decomposition) and count of a point set.
struct Scatter<T: Real> {
    centroid: Point3<T>,
    /// Eigenvalues ascending.
    values: [T; 3],
    /// Eigenvectors in the order of `values`.
    vectors: [Vector3<T>; 3],
    count: usize,
}

fn scatter<T, I>(points: I, needed: usize) -> Result<Scatter<T>, GeomError>
where
    T: Real,
    I: Iterator<Item = Point3<T>> + Clone,
{
    // Accumulated and solved in f64 whatever T is: a few hundred flops per fit, and an `f32`
    // frame's plane is then limited by its points' rounding, not by the 3×3 eigen-solve.
    let wide = |p: Point3<T>| Vector3::new(p.x.to_f64(), p.y.to_f64(), p.z.to_f64());
    let mut sum = Vector3::<f64>::zeros();
    let mut count = 0usize;
    for p in points.clone() {
        if !all_finite(&p.coords) {
            return Err(GeomError::NotFinite);
        }
        sum += wide(p);
        count += 1;
    }
    if count < needed {
        return Err(GeomError::TooFewPoints { needed, got: count });
    }
    let centroid = sum / count as f64;
    let mut m = Matrix3::<f64>::zeros();
    for p in points {
        let v = wide(p) - centroid;
        m += v * v.transpose();
    }
    if !m.iter().all(|v| v.is_finite()) {
        return Err(GeomError::NotFinite);
    }
    let eig =
        SymmetricEigen::try_new(m, f64::EPSILON, EIGEN_MAX_ITER).ok_or(GeomError::NoConvergence)?;
    let mut order = [0usize, 1, 2];
    order.sort_unstable_by(|&a, &b| {
        eig.eigenvalues[a]
            .partial_cmp(&eig.eigenvalues[b])
            .unwrap_or(core::cmp::Ordering::Equal)
    });
    let narrow = |v: Vector3<f64>| v.map(T::lit);
    Ok(Scatter {
        centroid: Point3::from(narrow(centroid)),
        values: order.map(|i| T::lit(eig.eigenvalues[i].max(0.0))),
        vectors: order.map(|i| narrow(eig.eigenvectors.column(i).into_owned())),
        count,
    })
}

/// Spread ratio (second axis over first, as lengths) below which points count as collinear
/// (or, for a line, as coincident).
fn degenerate_ratio<T: Real>() -> T {
    T::lit(1000.0) * T::EPSILON
}

/// Least-squares plane through at least three non-collinear points.
///
/// The normal faces the camera (origin on the positive side).
///
/// # Errors
/// [`GeomError::TooFewPoints`], [`GeomError::NotFinite`], [`GeomError::Collinear`] or
/// [`GeomError::NoConvergence`].
pub fn fit_plane<T, I>(points: I) -> Result<PlaneFit<T>, GeomError>
where
    T: Real,
    I: IntoIterator<Item = Point3<T>>,
    I::IntoIter: Clone,
{
    let points = points.into_iter();
    let s = scatter(points.clone(), 3)?;
    if !(s.values[1].sqrt() > degenerate_ratio::<T>() * s.values[2].sqrt()) {
        return Err(GeomError::Collinear);
    }
    let plane = Plane::from_point_normal(&s.centroid, &s.vectors[0])?.facing_camera();
    let (mut sum2, mut max) = (T::zero(), T::zero());
    for p in points {
        let r = plane.signed_distance(&p).abs();
        sum2 += r * r;
        max = max.max(r);
    }
    Ok(PlaneFit {
        plane,
        centroid: s.centroid,
        rms: (sum2 / T::lit(s.count as f64)).sqrt(),
        max,
        count: s.count,
        spread: s.values[1].sqrt(),
    })
}

/// Least-squares (orthogonal) line through at least two distinct points.
///
/// # Errors
/// [`GeomError::TooFewPoints`], [`GeomError::NotFinite`], [`GeomError::Collinear`] when the
/// points coincide, or [`GeomError::NoConvergence`].
pub fn fit_line<T, I>(points: I) -> Result<LineFit<T>, GeomError>
where
    T: Real,
    I: IntoIterator<Item = Point3<T>>,
    I::IntoIter: Clone,
{
    let s = scatter(points.into_iter(), 2)?;
    if !(s.values[2] > T::zero()) {
        return Err(GeomError::Collinear);
    }
    let line = Line::new(s.centroid, s.vectors[2])?;
    Ok(LineFit {
        line,
        rms: ((s.values[0] + s.values[1]) / T::lit(s.count as f64)).sqrt(),
        count: s.count,
    })
}
