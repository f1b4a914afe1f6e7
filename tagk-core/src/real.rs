//! The scalar type the estimators are generic over.

use core::fmt::{Debug, Display};
use core::ops::{AddAssign, DivAssign, MulAssign, SubAssign};

/// A real scalar the estimators compute in: implemented for `f32` and `f64`.
///
/// Built on [`num_traits::Float`] with its `libm` backend, so `sqrt` and friends work in
/// `no_std` code on a microcontroller as well as on the host.
pub trait Real:
    num_traits::Float
    + Debug
    + Display
    + Default
    + Send
    + Sync
    + 'static
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// Converts an `f64` constant or configuration value into this type (rounding for `f32`).
    fn cast(x: f64) -> Self;
    /// Widens this value to `f64` (exact for both implementations).
    fn as_f64(self) -> f64;
}

impl Real for f64 {
    #[inline(always)]
    fn cast(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn as_f64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    #[inline(always)]
    fn cast(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn as_f64(self) -> f64 {
        self as f64
    }
}
