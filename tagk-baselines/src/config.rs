//! Configurations of the two filters, validated by the constructors.

use core::any::TypeId;

use tagk_core::{ConfigError, Real};

/// Which dense-algebra code runs the block update.
///
/// Both backends compute the same algorithm (see the crate docs) in the same preallocated
/// buffers, and share the Cholesky factorisation. They differ in how the matrix products and
/// the triangular solve are executed. So results agree to round-off, not bit for bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Backend {
    /// The backend measured fastest: [`Backend::Faer`] for `f64` with the `faer` feature (it
    /// measured faster than the portable kernel, and than nalgebra's fixed-size and dynamic
    /// matrices, at every `n` measured with `m = 30`; figures in the README), else
    /// [`Backend::Loops`].
    #[default]
    Auto,
    /// The portable kernel: hand-written dot products with a fixed summation order, generic
    /// over the scalar, `no_std`, the code the Cortex-M7 firmware runs. Slower than
    /// [`Backend::Faer`] on a host.
    Loops,
    /// `faer`'s matrix products (feature `faer`, `f64` only) (SIMD with run-time CPU dispatch) and triangular solve on
    /// views of the buffers, with the hand-written Cholesky factorisation, which is faster
    /// than faer's for the small `m × m` innovation covariance.
    Faer,
}

impl Backend {
    /// The concrete backend this choice runs for scalars `T` ([`Backend::Auto`] resolved:
    /// [`Backend::Faer`] for `f64` when the `faer` feature is on, [`Backend::Loops`]
    /// otherwise).
    ///
    /// # Errors
    /// [`ConfigError::InvalidParameter`] for [`Backend::Faer`] with `f32` or without the
    /// `faer` feature.
    pub fn resolve<T: Real>(self) -> Result<Backend, ConfigError> {
        let faer = cfg!(feature = "faer") && TypeId::of::<T>() == TypeId::of::<f64>();
        match self {
            Backend::Auto if faer => Ok(Backend::Faer),
            Backend::Auto => Ok(Backend::Loops),
            Backend::Faer if !faer => Err(ConfigError::InvalidParameter {
                name: "backend",
                value: f64::NAN,
                reason: "the faer backend needs f64 scalars and the `faer` feature",
            }),
            other => Ok(other),
        }
    }
}

/// The prior covariance scale of every paper preset: `P₀ = 10³·I`.
pub const PAPER_P0: f64 = 1e3;

/// Covariance wind-up guard of [`Rls`](crate::Rls).
///
/// With forgetting (`λ < 1`), windows may leave some directions of `θ` unexcited.
/// In those directions the covariance grows by `1/λ` per window, without bound ("wind-up").
/// Then a single new window swings the estimate violently, or `P` overflows.
/// The guard is **off** by default so the TAG-K paper's baselines stay as published.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum WindupGuard {
    /// No guard: the textbook recursion.
    #[default]
    None,
    /// After each update, if `trace(P) > max_trace`, scale `P` by `max_trace / trace(P)`
    /// (a uniform shrink keeps `P` symmetric positive definite and its eigenvectors
    /// unchanged). `max_trace` is in the units of `P` (squared units of `θ`); a natural
    /// choice is `p₀·n`, the trace of the prior.
    MaxTrace(f64),
}

/// Configuration of [`Rls`](crate::Rls): block recursive least squares with exponential
/// forgetting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor `λ ∈ (0, 1]`, applied once per window: window `k` of `N` is
    /// weighted by `λ^(N−k)`. `1` is ordinary (growing-memory) least squares.
    pub lambda: f64,
    /// Prior covariance scale `p₀ > 0`: `P₀ = p₀·I` (squared units of `θ`).
    pub p0: f64,
    /// Covariance wind-up guard (default: none).
    pub windup_guard: WindupGuard,
    /// Dense-algebra backend (default: chosen by dimension).
    pub backend: Backend,
}

impl Default for RlsConfig {
    /// `λ = 1`, `p₀ = 10³`, no guard, automatic backend.
    fn default() -> Self {
        Self {
            lambda: 1.0,
            p0: PAPER_P0,
            windup_guard: WindupGuard::None,
            backend: Backend::Auto,
        }
    }
}

impl RlsConfig {
    /// The TAG-K paper's "RLS-low": `λ = 0.99`, `P₀ = 10³·I`.
    pub const LOW: RlsConfig = RlsConfig {
        lambda: 0.99,
        p0: PAPER_P0,
        windup_guard: WindupGuard::None,
        backend: Backend::Auto,
    };
    /// The TAG-K paper's "RLS-high": `λ = 0.96`, `P₀ = 10³·I`.
    pub const HIGH: RlsConfig = RlsConfig {
        lambda: 0.96,
        p0: PAPER_P0,
        windup_guard: WindupGuard::None,
        backend: Backend::Auto,
    };

    /// Sets the forgetting factor.
    pub fn with_lambda(mut self, lambda: f64) -> Self {
        self.lambda = lambda;
        self
    }
    /// Sets the prior covariance scale.
    pub fn with_p0(mut self, p0: f64) -> Self {
        self.p0 = p0;
        self
    }
    /// Sets the wind-up guard.
    pub fn with_windup_guard(mut self, guard: WindupGuard) -> Self {
        self.windup_guard = guard;
        self
    }
    /// Sets the backend.
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// Checks every setting; called by the constructors.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.lambda > 0.0 && self.lambda <= 1.0) {
            return Err(ConfigError::InvalidParameter {
                name: "lambda",
                value: self.lambda,
                reason: "the forgetting factor must lie in (0, 1]",
            });
        }
        check_positive("p0", self.p0)?;
        if let WindupGuard::MaxTrace(t) = self.windup_guard {
            check_positive("max_trace", t)?;
        }
        Ok(())
    }
}

/// Configuration of [`KalmanFilter`](crate::KalmanFilter): `θ` as a random walk observed
/// through the windows.
///
/// Model: `θ_k = θ_{k−1} + w_k`, `w_k ~ N(0, σ_Q²·I)`, and `b_k = A_k θ_k + v_k`,
/// `v_k ~ N(0, σ_R²·I)`. Standard deviations are in the units of `θ` (`σ_Q`, per window) and
/// of `b` (`σ_R`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KalmanConfig {
    /// Process noise standard deviation `σ_Q ≥ 0` (per window, units of `θ`).
    pub sigma_q: f64,
    /// Measurement noise standard deviation `σ_R > 0` (units of `b`).
    pub sigma_r: f64,
    /// Prior covariance scale `p₀ > 0`: `P₀ = p₀·I` (squared units of `θ`).
    pub p0: f64,
    /// Dense-algebra backend (default: chosen by dimension).
    pub backend: Backend,
}

impl Default for KalmanConfig {
    /// The "KF-low" noise levels (`σ_Q = 10⁻³`, `σ_R = 10⁻⁵`), `p₀ = 10³`.
    fn default() -> Self {
        Self::LOW
    }
}

impl KalmanConfig {
    /// The TAG-K paper's "KF-low": `σ_Q = 10⁻³`, `σ_R = 10⁻⁵`, `P₀ = 10³·I`.
    pub const LOW: KalmanConfig = KalmanConfig {
        sigma_q: 1e-3,
        sigma_r: 1e-5,
        p0: PAPER_P0,
        backend: Backend::Auto,
    };
    /// The TAG-K paper's "KF-high": `σ_Q = 10⁻¹`, `σ_R = 10⁻³`, `P₀ = 10³·I`.
    pub const HIGH: KalmanConfig = KalmanConfig {
        sigma_q: 1e-1,
        sigma_r: 1e-3,
        p0: PAPER_P0,
        backend: Backend::Auto,
    };

    /// Sets the process noise standard deviation.
    pub fn with_sigma_q(mut self, sigma_q: f64) -> Self {
        self.sigma_q = sigma_q;
        self
    }
    /// Sets the measurement noise standard deviation.
    pub fn with_sigma_r(mut self, sigma_r: f64) -> Self {
        self.sigma_r = sigma_r;
        self
    }
    /// Sets the prior covariance scale.
    pub fn with_p0(mut self, p0: f64) -> Self {
        self.p0 = p0;
        self
    }
    /// Sets the backend.
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// Checks every setting; called by the constructors.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.sigma_q >= 0.0
            && self.sigma_q.is_finite()
            && (self.sigma_q * self.sigma_q).is_finite())
        {
            return Err(ConfigError::InvalidParameter {
                name: "sigma_q",
                value: self.sigma_q,
                reason: "the process noise standard deviation must be finite and non-negative",
            });
        }
        check_positive("sigma_r", self.sigma_r)?;
        if !(self.sigma_r * self.sigma_r > 0.0 && (self.sigma_r * self.sigma_r).is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "sigma_r",
                value: self.sigma_r,
                reason: "the measurement noise variance σ_R² must be positive and finite",
            });
        }
        check_positive("p0", self.p0)?;
        Ok(())
    }
}

fn check_positive(name: &'static str, value: f64) -> Result<(), ConfigError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::InvalidParameter {
            name,
            value,
            reason: "must be positive and finite",
        })
    }
}
