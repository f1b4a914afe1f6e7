//! The three estimators of Table III over one caller-provided buffer each.
//!
//! TAG-K is tagk-core's own kernel ([`TagK`], `Kaczmarz<T, S, true, true>`) with a borrowed
//! slice as storage: this crate adds no second copy of the algorithm. RLS and the Kalman
//! filter are this crate's allocation-free [`Rls`] and [`KalmanFilter`].
//!
//! Each estimator can also live in a const-generic array (`TagK<f32, [f32; LEN]>`,
//! `Rls<f64, [f64; LEN]>`, with `LEN` from [`kaczmarz_buffer_len`] or
//! [`covariance_buffer_len`]); [`McuEstimator`] is the borrowed-slice form the harness uses.

use tagk_core::{
    ConfigError, EstimatorError, KaczmarzConfig, OnlineEstimator, Real, TagK, UpdateInfo,
    kaczmarz_buffer_len,
};

use crate::covariance::{KalmanFilter, KfConfig, Rls, RlsConfig, covariance_buffer_len};

/// TAG-K as the paper runs it: `T = m` projections per window, tail average over the last
/// half (`t_b = ⌊m/2⌋`), warm start from the previous average, zero tolerance, seed 0.
pub fn tagk_paper_config() -> KaczmarzConfig {
    KaczmarzConfig::default()
}

/// Which estimator of Table III.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EstimatorKind {
    /// [`Rls`] with [`RlsConfig::low`] (`λ = 0.99`, `P₀ = 10³ I`).
    RlsLow,
    /// [`KalmanFilter`] with [`KfConfig::low`] (`σ_Q = 10⁻³`, `σ_R = 10⁻⁵`, `P₀ = 10³ I`).
    KfLow,
    /// [`KalmanFilter`] with [`KfConfig::high`] (`σ_Q = 10⁻¹`, `σ_R = 10⁻³`, `P₀ = 10³ I`).
    ///
    /// The harness's single-precision Kalman filter: KF-low's `P₀ / σ_R² = 10¹³` is beyond
    /// `f32`, whose covariance loses positive definiteness within a few windows (a typed
    /// [`EstimatorError::NumericalFailure`]). KF-high runs the same instructions per update.
    KfHigh,
    /// tagk-core's [`TagK`] with [`tagk_paper_config`].
    TagK,
}

impl EstimatorKind {
    /// Every kind.
    pub const ALL: [Self; 4] = [Self::RlsLow, Self::KfLow, Self::KfHigh, Self::TagK];

    /// The name used in tables (equal to the built estimator's `name()`).
    pub const fn label(self) -> &'static str {
        match self {
            Self::RlsLow => "RLS-low",
            Self::KfLow => "KF-low",
            Self::KfHigh => "KF-high",
            Self::TagK => "TAG-K",
        }
    }

    /// Scalars of storage the estimator needs for dimension `n` and windows of up to `m` rows.
    pub const fn buffer_len(self, n: usize, m: usize) -> usize {
        match self {
            Self::RlsLow | Self::KfLow | Self::KfHigh => covariance_buffer_len(n, m),
            Self::TagK => kaczmarz_buffer_len(n, m),
        }
    }

    /// Bytes of RAM one estimator occupies with scalars of type `T`: its buffer plus the
    /// estimator value itself (configuration, sizes, TAG-K's random generator). The window
    /// `A`, `b` (`(m n + m)` scalars, shared by all three) is not included.
    pub const fn state_bytes<T: Real>(self, n: usize, m: usize) -> usize {
        self.buffer_len(n, m) * core::mem::size_of::<T>()
            + match self {
                Self::RlsLow => core::mem::size_of::<Rls<T, &'static mut [T]>>(),
                Self::KfLow | Self::KfHigh => {
                    core::mem::size_of::<KalmanFilter<T, &'static mut [T]>>()
                }
                Self::TagK => core::mem::size_of::<TagK<T, &'static mut [T]>>(),
            }
    }

    /// Builds the estimator of dimension `n` for windows of up to `m` rows in `buf` (at least
    /// [`buffer_len`](Self::buffer_len) scalars); the initial estimate is zero.
    pub fn build<T: Real>(
        self,
        n: usize,
        m: usize,
        buf: &mut [T],
    ) -> Result<McuEstimator<'_, T>, ConfigError> {
        Ok(match self {
            Self::RlsLow => McuEstimator::Rls(Rls::with_storage(n, m, RlsConfig::low(), buf)?),
            Self::KfLow => {
                McuEstimator::Kf(KalmanFilter::with_storage(n, m, KfConfig::low(), buf)?)
            }
            Self::KfHigh => {
                McuEstimator::Kf(KalmanFilter::with_storage(n, m, KfConfig::high(), buf)?)
            }
            Self::TagK => McuEstimator::TagK(TagK::with_storage(n, m, tagk_paper_config(), buf)?),
        })
    }
}

/// One of the Table III estimators over a borrowed buffer, behind [`OnlineEstimator`].
///
/// The TAG-K variant is the largest (its ChaCha8 generator keeps a 256-byte block buffer);
/// without an allocator it stays inline rather than boxed.
#[allow(clippy::large_enum_variant)]
pub enum McuEstimator<'a, T: Real> {
    /// Recursive least squares.
    Rls(Rls<T, &'a mut [T]>),
    /// Random-walk Kalman filter.
    Kf(KalmanFilter<T, &'a mut [T]>),
    /// TAG-K (tagk-core's kernel).
    TagK(TagK<T, &'a mut [T]>),
}

macro_rules! dispatch {
    ($self:expr, $e:ident => $body:expr) => {
        match $self {
            McuEstimator::Rls($e) => $body,
            McuEstimator::Kf($e) => $body,
            McuEstimator::TagK($e) => $body,
        }
    };
}

impl<T: Real> OnlineEstimator<T> for McuEstimator<'_, T> {
    fn name(&self) -> &str {
        dispatch!(self, e => e.name())
    }
    fn dim(&self) -> usize {
        dispatch!(self, e => e.dim())
    }
    fn capacity(&self) -> usize {
        dispatch!(self, e => e.capacity())
    }
    fn estimate(&self) -> &[T] {
        dispatch!(self, e => e.estimate())
    }
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        dispatch!(self, e => e.update(a, b))
    }
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        dispatch!(self, e => e.reset(estimate))
    }
}
