//! Calibration maths: the camera's image distance by the paper's two-position procedure
//! ([`distance`], eq. 7–9), and beyond the paper, full intrinsics and target poses from several
//! views of planar targets ([`bundle`]) with markers modelled as printed discs ([`model`]), and
//! the calibration's share of each scanned point's uncertainty ([`spread`]).
//!
//! All of it is `f64`, fixed memory and allocation-free: the caller owns the observations; the
//! non-linear refinement folds each view into a 9×9 reduced system (Schur complement), so memory
//! does not grow with the number of views or markers.

pub mod bundle;
pub mod distance;
pub mod model;
pub mod spread;

pub use bundle::{Covariance, Free, Refinement, TargetImage};
pub use distance::{CrossShot, ImageDistance, image_distance};
