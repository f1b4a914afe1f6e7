//! Block recursive least squares with exponential forgetting.

use tagk_core::{ConfigError, EstimatorError, OnlineEstimator, UpdateInfo, validate_window};

use crate::state::{FilterState, trace};
use crate::{Backend, RlsConfig, WindupGuard};

/// Block recursive least squares with forgetting factor `λ` and prior `P₀ = p₀·I`.
///
/// Each window `A θ ≈ b` (`m × n`, `m ≤ capacity`) updates the estimate and the covariance
/// `P` (squared units of `θ`) as
///
/// ```text
/// S = A P Aᵀ + λ I          (m × m, Cholesky-factorised: S = L Lᵀ)
/// K = P Aᵀ S⁻¹               (never formed: K r = Gᵀ L⁻¹ r with G = L⁻¹ A P)
/// θ ← θ + K (b − A θ)
/// P ← (P − K A P) / λ        (= (P − Gᵀ G)/λ, symmetric by construction)
/// ```
///
/// which is exactly the minimiser of `Σ_k λ^(N−k) ‖b_k − A_k θ‖² + λ^N (θ − θ₀)ᵀ P₀⁻¹ (θ − θ₀)`
/// over the windows `k = 1..N` seen so far, with `P_N = (λ^N P₀⁻¹ + Σ_k λ^(N−k) A_kᵀ A_k)⁻¹`.
/// The cost per update is `O(m n²)` (see the crate docs); nothing is allocated after
/// construction. Zero rows of a window carry no information and change nothing.
///
/// With `λ < 1` and poorly exciting windows the covariance winds up (grows without bound);
/// see [`WindupGuard`].
pub struct Rls {
    config: RlsConfig,
    name: &'static str,
    state: FilterState,
}

impl Rls {
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows, with
    /// `θ = 0` and `P = p₀·I`. Its [`name`](OnlineEstimator::name) is `"RLS"`.
    pub fn new(n: usize, m_max: usize, config: RlsConfig) -> Result<Self, ConfigError> {
        Self::named(n, m_max, config, "RLS")
    }

    /// The TAG-K paper's "RLS-low" baseline ([`RlsConfig::LOW`]: `λ = 0.99`, `P₀ = 10³·I`).
    pub fn rls_low(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Self::named(n, m_max, RlsConfig::LOW, "RLS-low")
    }

    /// The TAG-K paper's "RLS-high" baseline ([`RlsConfig::HIGH`]: `λ = 0.96`, `P₀ = 10³·I`).
    pub fn rls_high(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Self::named(n, m_max, RlsConfig::HIGH, "RLS-high")
    }

    fn named(
        n: usize,
        m_max: usize,
        config: RlsConfig,
        name: &'static str,
    ) -> Result<Self, ConfigError> {
        tagk_core::check_dimensions(n, m_max)?;
        config.validate()?;
        Ok(Self {
            config,
            name,
            state: FilterState::new(n, m_max, config.p0, config.backend),
        })
    }

    /// The configuration this estimator was built with.
    pub fn config(&self) -> &RlsConfig {
        &self.config
    }

    /// The covariance `P` (`n × n`, row-major, symmetric; squared units of `θ`).
    pub fn covariance(&self) -> &[f64] {
        &self.state.p
    }

    /// `trace(P)`, the quantity the [`WindupGuard::MaxTrace`] bound acts on.
    pub fn covariance_trace(&self) -> f64 {
        self.state.trace()
    }

    /// The backend in use ([`Backend::Auto`] resolved).
    pub fn backend(&self) -> Backend {
        self.state.ws.backend()
    }
}

impl OnlineEstimator<f64> for Rls {
    fn name(&self) -> &str {
        self.name
    }

    fn dim(&self) -> usize {
        self.state.n
    }

    fn capacity(&self) -> usize {
        self.state.m_max
    }

    fn estimate(&self) -> &[f64] {
        &self.state.theta
    }

    fn update(&mut self, a: &[f64], b: &[f64]) -> Result<UpdateInfo, EstimatorError> {
        let st = &mut self.state;
        let n = st.n;
        let m = validate_window(n, st.m_max, a, b)?;
        let prior_residual_norm = st.ws.residual(a, b, &st.theta)?;
        let lambda = self.config.lambda;
        st.p_next.copy_from_slice(&st.p);
        st.ws
            .update(a, m, lambda, 1.0 / lambda, &st.p, 0.0, &mut st.p_next)?;
        if let WindupGuard::MaxTrace(max_trace) = self.config.windup_guard {
            let tr = trace(&st.p_next, n);
            if tr > max_trace {
                let shrink = max_trace / tr;
                for v in st.p_next.iter_mut() {
                    *v *= shrink;
                }
            }
        }
        st.commit()?;
        Ok(UpdateInfo {
            rows: m,
            iterations: 1,
            prior_residual_norm,
            converged: false,
        })
    }

    fn reset(&mut self, estimate: &[f64]) -> Result<(), EstimatorError> {
        self.state.reset(estimate)
    }
}
