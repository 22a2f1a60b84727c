//! The one error type of the geometry.

use core::fmt;

/// Why a geometric computation gave no result.
///
/// Every public function of this crate returns one of these instead of a NaN, an infinity or a
/// panic. The per-point variants ([`BehindCamera`](Self::BehindCamera),
/// [`Grazing`](Self::Grazing), [`BeyondRange`](Self::BeyondRange),
/// [`BehindBoard`](Self::BehindBoard)) double as the reasons a stripe pixel is not a valid point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum GeomError {
    /// An input number is NaN or infinite.
    NotFinite,
    /// A parameter is out of its domain (the text names it).
    BadParameter(&'static str),
    /// Fewer points than the computation needs.
    TooFewPoints {
        /// How many are needed.
        needed: usize,
        /// How many were given.
        got: usize,
    },
    /// Two slices that must pair up have different lengths.
    LengthMismatch,
    /// The point is at or behind the camera (z ≤ 0), or the ray meets the plane behind it.
    BehindCamera,
    /// The ray is (nearly) parallel to the plane it should meet.
    Grazing,
    /// The point is farther than the configured range.
    BeyondRange,
    /// The point lies behind a board plane, where the camera cannot see anything.
    BehindBoard,
    /// An iterative method did not converge within its bounded number of steps.
    NoConvergence,
    /// Image points that must be distinct coincide: the 3-D line passes through the camera centre.
    CoincidentPoints,
    /// Points that must span a plane are (nearly) collinear, or a line's points coincide.
    Collinear,
    /// Two planes (or two lines) that must meet are (nearly) parallel.
    Parallel,
    /// The laser plane (nearly) contains the camera centre: every ray grazes it.
    PlaneThroughCamera,
    /// The stripe lies on one board plane only, so the laser plane is not determined.
    OnePlaneOnly,
    /// A closed form's denominator or radicand vanished or changed sign: the data is inconsistent
    /// or too close to a degenerate configuration.
    IllConditioned,
}

impl fmt::Display for GeomError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotFinite => f.write_str("an input number is NaN or infinite"),
            Self::BadParameter(what) => write!(f, "parameter out of range: {what}"),
            Self::TooFewPoints { needed, got } => {
                write!(f, "too few points: {got} given, {needed} needed")
            }
            Self::LengthMismatch => f.write_str("paired inputs have different lengths"),
            Self::BehindCamera => f.write_str("point is behind the camera"),
            Self::Grazing => f.write_str("ray is nearly parallel to the plane"),
            Self::BeyondRange => f.write_str("point is beyond the configured range"),
            Self::BehindBoard => f.write_str("point is behind the calibration board"),
            Self::NoConvergence => f.write_str("iteration did not converge"),
            Self::CoincidentPoints => {
                f.write_str("image points coincide (the line passes through the camera centre)")
            }
            Self::Collinear => f.write_str("points are collinear; a plane is not determined"),
            Self::Parallel => f.write_str("planes or lines are parallel; they do not meet"),
            Self::PlaneThroughCamera => f.write_str("laser plane passes through the camera centre"),
            Self::OnePlaneOnly => f.write_str("stripe lies on one board plane only"),
            Self::IllConditioned => f.write_str("ill-conditioned or inconsistent data"),
        }
    }
}

impl core::error::Error for GeomError {}
