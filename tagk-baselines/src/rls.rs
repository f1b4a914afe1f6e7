//! Block recursive least squares with exponential forgetting.

use tagk_core::{ConfigError, EstimatorError, OnlineEstimator, Real, Storage, UpdateInfo};

use crate::filter::{BlockFilter, Model};
use crate::{DefaultStorage, RlsConfig, WindupGuard};

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
/// Generic over the scalar `T` (`f64` by default, or `f32`) and the storage `S` of its one
/// buffer ([`covariance_buffer_len`](crate::covariance_buffer_len) scalars): a `Vec` for
/// [`Rls::new`], or an array or a `&mut [T]` for [`Rls::with_storage`] (no allocator needed).
/// `Clone` when the storage is (owned storage; a borrowed `&mut [T]` cannot be duplicated).
///
/// With `λ < 1` and poorly exciting windows the covariance winds up (grows without bound);
/// see [`WindupGuard`].
#[derive(Clone)]
pub struct Rls<T: Real = f64, S: Storage<T> = DefaultStorage<T>> {
    config: RlsConfig,
    name: &'static str,
    filter: BlockFilter<T, S>,
}

#[cfg(feature = "alloc")]
impl Rls {
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows, with
    /// `θ = 0` and `P = p₀·I`. Its [`name`](OnlineEstimator::name) is `"RLS"`.
    pub fn new(n: usize, m_max: usize, config: RlsConfig) -> Result<Self, ConfigError> {
        tagk_core::check_dimensions(n, m_max)?;
        config.validate()?;
        Self::with_storage(n, m_max, config, crate::owned_buffer(n, m_max)?)
    }

    /// The TAG-K paper's "RLS-low" baseline ([`RlsConfig::LOW`]: `λ = 0.99`, `P₀ = 10³·I`).
    pub fn rls_low(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Ok(Self::new(n, m_max, RlsConfig::LOW)?.with_name("RLS-low"))
    }

    /// The TAG-K paper's "RLS-high" baseline ([`RlsConfig::HIGH`]: `λ = 0.96`, `P₀ = 10³·I`).
    pub fn rls_high(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Ok(Self::new(n, m_max, RlsConfig::HIGH)?.with_name("RLS-high"))
    }
}

impl<T: Real, S: Storage<T>> Rls<T, S> {
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows in `buf`
    /// (at least [`covariance_buffer_len`](crate::covariance_buffer_len)`(n, m_max)` scalars;
    /// its contents are overwritten), with `θ = 0` and `P = p₀·I`. Named `"RLS"`. With the
    /// portable kernel ([`Backend::Loops`](crate::Backend::Loops)) a buffer of only
    /// [`compact_covariance_buffer_len`](crate::compact_covariance_buffer_len) scalars is
    /// accepted too, without the information-form fallback (see
    /// [`has_information_fallback`](Self::has_information_fallback)).
    ///
    /// ```
    /// use tagk_baselines::{covariance_buffer_len, OnlineEstimator, Rls, RlsConfig};
    /// const LEN: usize = covariance_buffer_len(2, 2);
    /// let mut rls = Rls::<f32, [f32; LEN]>::with_storage(2, 2, RlsConfig::LOW, [0.0; LEN])?;
    /// rls.update(&[1.0, 0.0, 0.0, 1.0], &[3.0, -1.0])?;
    /// assert!((rls.estimate()[0] - 3.0).abs() < 1e-2);
    /// # Ok::<(), Box<dyn core::error::Error>>(())
    /// ```
    pub fn with_storage(
        n: usize,
        m_max: usize,
        config: RlsConfig,
        buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let backend = config.backend.resolve::<T>()?;
        let model = Model {
            q: T::zero(),
            d: T::cast(config.lambda),
            scale: T::cast(1.0 / config.lambda),
            p0: T::cast(config.p0),
            max_trace: match config.windup_guard {
                WindupGuard::None => None,
                WindupGuard::MaxTrace(t) => Some(T::cast(t)),
            },
        };
        Ok(Self {
            config,
            name: "RLS",
            filter: BlockFilter::new(n, m_max, backend, model, buf)?,
        })
    }
}

crate::filter::covariance_filter_api!(Rls, RlsConfig);
