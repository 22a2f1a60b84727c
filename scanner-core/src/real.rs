//! The float types the geometry runs in.

use nalgebra::RealField;

/// A float the geometry is computed in: `f32` (per-frame path) or `f64` (calibration).
///
/// Sealed: only `f32` and `f64` implement it.
pub trait Real: RealField + Copy + sealed::Sealed {
    /// Machine epsilon of the type.
    const EPSILON: Self;

    /// Converts an `f64` constant into this type.
    #[inline]
    fn lit(x: f64) -> Self {
        nalgebra::convert(x)
    }

    /// Converts this value to `f64` (exact for both types).
    fn to_f64(self) -> f64;

    /// `true` if the value is neither NaN nor infinite.
    fn finite(self) -> bool;
}

impl Real for f32 {
    const EPSILON: Self = f32::EPSILON;
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
}

impl Real for f64 {
    const EPSILON: Self = f64::EPSILON;
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// `true` if every component is finite.
#[inline]
pub(crate) fn all_finite<T: Real, const N: usize>(v: &nalgebra::SVector<T, N>) -> bool {
    v.iter().all(|x| x.finite())
}
