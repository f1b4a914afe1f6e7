//! Kalman filter with the parameters as a random walk.

use tagk_core::{ConfigError, EstimatorError, OnlineEstimator, Real, Storage, UpdateInfo};

use crate::filter::{BlockFilter, Model};
use crate::{DefaultStorage, KalmanConfig};

/// Kalman filter for `θ` modelled as a random walk observed through the windows.
///
/// Model (see [`KalmanConfig`]): `θ_k = θ_{k−1} + w_k`, `w_k ~ N(0, Q)`, `Q = σ_Q²·I`, and
/// `b_k = A_k θ_k + v_k`, `v_k ~ N(0, R)`, `R = σ_R²·I`. Each window (`m × n`,
/// `m ≤ capacity`) runs one predict and one update step:
///
/// ```text
/// P⁻ = P + Q
/// S  = A P⁻ Aᵀ + R           (m × m, Cholesky-factorised: S = L Lᵀ)
/// K  = P⁻ Aᵀ S⁻¹             (never formed: K r = Gᵀ L⁻¹ r with G = L⁻¹ A P⁻)
/// θ ← θ + K (b − A θ)
/// P  = P⁻ − K S Kᵀ = P⁻ − Gᵀ G
/// ```
///
/// **Covariance update: the symmetrised form `P⁻ − Gᵀ G`, not the Joseph form.** With
/// `G = L⁻¹ A P⁻`, the subtracted term `K S Kᵀ = K A P⁻` is a Gram matrix. Only its upper
/// triangle is computed, then mirrored, so `P` is symmetric *exactly*. The asymmetric drift of
/// the plain `(I − K A) P⁻` product, the usual reason for Joseph, cannot occur. The cost is
/// `m n²/2` multiply-adds. The Joseph form `(I − KA) P⁻ (I − KA)ᵀ + K R Kᵀ` costs `2n³` as
/// written: 4–5× the whole update at `n = 120, m = 30`. Its `O(m n²)` rearrangement is again a
/// difference of nearly equal terms. So it buys nothing over the symmetrised form in the one
/// regime where either loses accuracy. That is a window that pins a direction far below the
/// rounding level of the prior (`p₀ ‖a‖² / σ_R² ≳ 10¹²`); KF-low's first window on quadrotor
/// data is one. That regime is detected: a diagonal entry that kept fewer than ~4 digits, or a
/// failed Cholesky factorisation of `S`. The window is then redone in information form, which
/// is well conditioned there (see the crate docs). Every update also checks that `P` stays
/// finite with a positive diagonal. Otherwise it is refused ([`EstimatorError::Diverged`] /
/// [`EstimatorError::NumericalFailure`]) and the state is kept.
///
/// The cost per update is `O(m n²)` (see the crate docs); nothing is allocated after
/// construction. Zero rows of a window carry no information and change nothing (a window of
/// only zero rows is refused with [`EstimatorError::NoUsableRow`], without a predict step).
///
/// Generic over the scalar and the storage like [`Rls`](crate::Rls): `f64` in a `Vec` by
/// default, `f32` or caller storage with [`KalmanFilter::with_storage`].
#[derive(Clone)]
pub struct KalmanFilter<T: Real = f64, S: Storage<T> = DefaultStorage<T>> {
    config: KalmanConfig,
    name: &'static str,
    filter: BlockFilter<T, S>,
}

#[cfg(feature = "alloc")]
impl KalmanFilter {
    /// Builds a filter of dimension `n` for windows of at most `m_max` rows, with `θ = 0`
    /// and `P = p₀·I`. Its [`name`](OnlineEstimator::name) is `"KF"`.
    pub fn new(n: usize, m_max: usize, config: KalmanConfig) -> Result<Self, ConfigError> {
        tagk_core::check_dimensions(n, m_max)?;
        config.validate()?;
        Self::with_storage(n, m_max, config, crate::owned_buffer(n, m_max)?)
    }

    /// The TAG-K paper's "KF-low" baseline ([`KalmanConfig::LOW`]: `σ_Q = 10⁻³`,
    /// `σ_R = 10⁻⁵`, `P₀ = 10³·I`).
    pub fn kf_low(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Ok(Self::new(n, m_max, KalmanConfig::LOW)?.with_name("KF-low"))
    }

    /// The TAG-K paper's "KF-high" baseline ([`KalmanConfig::HIGH`]: `σ_Q = 10⁻¹`,
    /// `σ_R = 10⁻³`, `P₀ = 10³·I`).
    pub fn kf_high(n: usize, m_max: usize) -> Result<Self, ConfigError> {
        Ok(Self::new(n, m_max, KalmanConfig::HIGH)?.with_name("KF-high"))
    }
}

impl<T: Real, S: Storage<T>> KalmanFilter<T, S> {
    /// Builds a filter of dimension `n` for windows of at most `m_max` rows in `buf` (at
    /// least [`covariance_buffer_len`](crate::covariance_buffer_len)`(n, m_max)` scalars; its
    /// contents are overwritten), with `θ = 0` and `P = p₀·I`. Named `"KF"`. With the
    /// portable kernel ([`Backend::Loops`](crate::Backend::Loops)) a buffer of only
    /// [`compact_covariance_buffer_len`](crate::compact_covariance_buffer_len) scalars is
    /// accepted too, without the information-form fallback (see
    /// [`has_information_fallback`](Self::has_information_fallback)).
    ///
    /// ```
    /// use tagk_baselines::{covariance_buffer_len, KalmanConfig, KalmanFilter, OnlineEstimator};
    /// const LEN: usize = covariance_buffer_len(2, 2);
    /// let mut kf =
    ///     KalmanFilter::<f32, [f32; LEN]>::with_storage(2, 2, KalmanConfig::HIGH, [0.0; LEN])?;
    /// kf.update(&[1.0, 0.0, 0.0, 1.0], &[3.0, -1.0])?;
    /// assert!((kf.estimate()[1] + 1.0).abs() < 1e-4);
    /// # Ok::<(), Box<dyn core::error::Error>>(())
    /// ```
    pub fn with_storage(
        n: usize,
        m_max: usize,
        config: KalmanConfig,
        buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let backend = config.backend.resolve::<T>()?;
        let model = Model {
            q: T::cast(config.sigma_q * config.sigma_q),
            d: T::cast(config.sigma_r * config.sigma_r),
            scale: T::one(),
            p0: T::cast(config.p0),
            max_trace: None,
        };
        Ok(Self {
            config,
            name: "KF",
            filter: BlockFilter::new(n, m_max, backend, model, buf)?,
        })
    }
}

crate::filter::covariance_filter_api!(KalmanFilter, KalmanConfig);
