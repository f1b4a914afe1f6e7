//! The Table III estimators over one caller-provided buffer each.
//!
//! Nothing here is a second copy of an algorithm: TAG-K is tagk-core's kernel ([`TagK`],
//! `Kaczmarz<T, S, true, true>`) and RLS and the Kalman filter are tagk-baselines' ([`Rls`],
//! [`KalmanFilter`], its portable `no_std` kernel), each with a borrowed slice as storage. The
//! estimator list is tagk-baselines' [`EstimatorKind`], the presets are
//! [`RlsConfig::LOW`](tagk_baselines::RlsConfig::LOW), [`KalmanConfig::LOW`](tagk_baselines::KalmanConfig::LOW) /
//! [`HIGH`](tagk_baselines::KalmanConfig::HIGH) and tagk-core's [`tagk_paper_config`].
//!
//! Each estimator can also live in a const-generic array (`TagK<f32, [f32; LEN]>`,
//! `Rls<f64, [f64; LEN]>`, with `LEN` from [`kaczmarz_buffer_len`],
//! [`compact_covariance_buffer_len`] or [`covariance_buffer_len`](tagk_baselines::covariance_buffer_len)); [`McuEstimator`] is the
//! borrowed-slice form the harness uses.
//!
//! RLS and the Kalman filter get the **compact** buffer here:
//! [`compact_covariance_buffer_len`], `n² + 3n + 2mn + m² + 3m` scalars, about half of
//! [`covariance_buffer_len`](tagk_baselines::covariance_buffer_len). The covariance is updated
//! in place and there is no information-form fallback. A window that would need it pins a
//! direction far below the rounding level of the prior (`p₀ ‖a‖² / d ≳ 10¹²`); KF-low's first
//! window on quadrotor data is one. Such a window is refused with a typed
//! [`EstimatorError::NumericalFailure`] and changes nothing. It fires on none of the Table III
//! updates, whose bits are those of the full buffer. Build [`Rls`] / [`KalmanFilter`] in a
//! [`covariance_buffer_len`](tagk_baselines::covariance_buffer_len) buffer to keep the fallback.

use tagk_baselines::{Backend, EstimatorKind, KalmanFilter, Rls, compact_covariance_buffer_len};
use tagk_core::{
    ConfigError, EstimatorError, OnlineEstimator, Real, TagK, UpdateInfo, kaczmarz_buffer_len,
    tagk_paper_config,
};

/// Scalars of storage the estimator `kind` needs for dimension `n` and windows of up to `m`
/// rows ([`compact_covariance_buffer_len`]: no information-form fallback, see the
/// [module docs](self); or [`kaczmarz_buffer_len`]). Saturates at `usize::MAX` where the
/// length overflows, as they do.
pub const fn buffer_len(kind: EstimatorKind, n: usize, m: usize) -> usize {
    if kind.is_kaczmarz() {
        kaczmarz_buffer_len(n, m)
    } else {
        compact_covariance_buffer_len(n, m)
    }
}

/// Bytes of RAM one estimator `kind` occupies with scalars of type `T`: its buffer plus the
/// estimator value itself (configuration, sizes, TAG-K's random generator). The window `A`,
/// `b` (`(m n + m)` scalars, shared by all) is not included. Saturates at `usize::MAX`
/// where the size overflows.
pub const fn state_bytes<T: Real>(kind: EstimatorKind, n: usize, m: usize) -> usize {
    buffer_len(kind, n, m)
        .saturating_mul(core::mem::size_of::<T>())
        .saturating_add(match kind {
            EstimatorKind::RlsLow | EstimatorKind::RlsHigh => {
                core::mem::size_of::<Rls<T, &'static mut [T]>>()
            }
            EstimatorKind::KfLow | EstimatorKind::KfHigh => {
                core::mem::size_of::<KalmanFilter<T, &'static mut [T]>>()
            }
            _ => core::mem::size_of::<TagK<T, &'static mut [T]>>(),
        })
}

/// One of the Table III estimators over a borrowed buffer, behind [`OnlineEstimator`].
///
/// The TAG-K variant is the largest (its ChaCha8 generator keeps a 256-byte block buffer);
/// without an allocator it stays inline rather than boxed. Not `Clone`: it borrows its buffer
/// (build a second one in a second buffer instead).
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum McuEstimator<'a, T: Real> {
    /// Recursive least squares (RLS-low, RLS-high).
    Rls(Rls<T, &'a mut [T]>),
    /// Random-walk Kalman filter (KF-low, KF-high).
    Kf(KalmanFilter<T, &'a mut [T]>),
    /// TAG-K (tagk-core's kernel).
    TagK(TagK<T, &'a mut [T]>),
}

impl<'a, T: Real> McuEstimator<'a, T> {
    /// Builds the estimator `kind` of dimension `n` for windows of up to `m` rows in `buf`
    /// (at least [`buffer_len`] scalars); the initial estimate is zero and its `name()` is
    /// [`EstimatorKind::name`]. RLS and the KF run the portable kernel
    /// ([`Backend::Loops`]) on every target, so the host computes the firmware's bits.
    ///
    /// # Errors
    /// The constructors' [`ConfigError`]s (a short buffer, a zero dimension), and
    /// [`ConfigError::InvalidParameter`] for GRK, TARK and RK, which this crate does not run.
    pub fn build(
        kind: EstimatorKind,
        n: usize,
        m: usize,
        buf: &'a mut [T],
    ) -> Result<Self, ConfigError> {
        if let Some(config) = kind.rls_config() {
            return Ok(Self::Rls(
                Rls::with_storage(n, m, config.with_backend(Backend::Loops), buf)?
                    .with_name(kind.name()),
            ));
        }
        if let Some(config) = kind.kalman_config() {
            return Ok(Self::Kf(
                KalmanFilter::with_storage(n, m, config.with_backend(Backend::Loops), buf)?
                    .with_name(kind.name()),
            ));
        }
        match kind {
            EstimatorKind::TagK => Ok(Self::TagK(TagK::with_storage(
                n,
                m,
                tagk_paper_config(),
                buf,
            )?)),
            _ => Err(ConfigError::InvalidParameter {
                name: "kind",
                value: f64::NAN,
                reason: "tagk-mcu runs RLS, the Kalman filter and TAG-K only",
            }),
        }
    }
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
