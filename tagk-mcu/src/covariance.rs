//! Allocation-free recursive least squares with forgetting ([`Rls`]) and a random-walk Kalman
//! filter ([`KalmanFilter`]) over caller-provided storage: the baselines of the TAG-K paper.
//!
//! Both are the same block covariance update with different constants, so they share one
//! kernel. For a window `A θ ≈ b` (`A` is `m × n`) and covariance `P` (`n × n`):
//!
//! | step | RLS (forgetting `λ`) | KF (random walk `σ_Q`, noise `σ_R`) |
//! |---|---|---|
//! | predict | `P̃ = P` | `P̃ = P + σ_Q² I` |
//! | innovation covariance | `S = A P̃ Aᵀ + λ I` | `S = A P̃ Aᵀ + σ_R² I` |
//! | gain | `K = P̃ Aᵀ S⁻¹` | same |
//! | estimate | `θ ← θ + K (b − A θ)` | same |
//! | covariance | `P ← (P̃ − K A P̃) / λ` | `P ← P̃ − K A P̃` |
//!
//! `S` is factored by Cholesky, `S = L Lᵀ` (an `S` that is not positive definite is a typed
//! [`EstimatorError::NumericalFailure`]). With `W = A P̃` and `Z = Wᵀ L⁻ᵀ` (`n × m`), the gain
//! never has to be formed: `K (b − Aθ) = Z · L⁻¹(b − Aθ)` and `K A P̃ = Z Zᵀ`. The covariance
//! update `P̃ − Z Zᵀ` is computed on the upper triangle and mirrored, so `P` stays exactly
//! symmetric (the symmetrised form of the update; the Joseph form would cost `n³`).
//!
//! # Cost per update
//! `W = A P̃`: `m n²` multiply-adds; `S`: `m² n / 2`; Cholesky: `m³ / 6`; `Z`: `n m² / 2`;
//! `Z Zᵀ` (upper triangle): `m n² / 2`. About `1.5 m n² + m² n` in total, against TAG-K's
//! `≈ m² n / 2 + 3 m n`: the covariance is what makes the baselines quadratic in `n`.
//!
//! # Storage
//! `θ` (`n`), a candidate `θ` (`n`), `P` (`n²`), `W` and `Z` (`m_max n` each), `S`/`L`
//! (`m_max²`), and two vectors of length `m_max`: [`covariance_buffer_len`] scalars in all.
//! Every update validates the window and computes the new `θ` and `P` in scratch space before
//! touching the state, so a refused window leaves the filter exactly as it was.

use tagk_core::linalg::{axpy, dot};
use tagk_core::{
    ConfigError, EstimatorError, OnlineEstimator, Real, Storage, UpdateInfo, validate_estimate,
    validate_window,
};

/// Length of the buffer an [`Rls`] or [`KalmanFilter`] of dimension `n` and window capacity
/// `m_max` needs: `n² + 2n + 2·m_max·n + m_max² + 2·m_max` scalars.
///
/// A `const fn`, so firmware can size a static array: `[0.0; covariance_buffer_len(120, 30)]`.
pub const fn covariance_buffer_len(n: usize, m_max: usize) -> usize {
    n * n + 2 * n + 2 * m_max * n + m_max * m_max + 2 * m_max
}

/// Recursive least squares settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor `λ ∈ (0, 1]` applied once per window (dimensionless).
    pub forgetting: f64,
    /// Initial covariance `P₀ = p0 · I` (units of `θ²`), also restored by `reset`.
    pub p0: f64,
    /// The name reported by [`OnlineEstimator::name`].
    pub label: &'static str,
}

impl RlsConfig {
    /// The paper's RLS-low: `λ = 0.99`, `P₀ = 10³ I`.
    pub const fn low() -> Self {
        Self {
            forgetting: 0.99,
            p0: 1e3,
            label: "RLS-low",
        }
    }

    /// The paper's RLS-high: `λ = 0.96`, `P₀ = 10³ I`.
    pub const fn high() -> Self {
        Self {
            forgetting: 0.96,
            p0: 1e3,
            label: "RLS-high",
        }
    }

    /// Checks every setting; called by the constructors.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.forgetting > 0.0 && self.forgetting <= 1.0) {
            return Err(ConfigError::InvalidParameter {
                name: "forgetting",
                value: self.forgetting,
                reason: "the forgetting factor must lie in (0, 1]",
            });
        }
        check_p0(self.p0)
    }
}

impl Default for RlsConfig {
    fn default() -> Self {
        Self::low()
    }
}

/// Random-walk Kalman filter settings: `θ_{k+1} = θ_k + w`, `w ~ N(0, σ_Q² I)`, and
/// `b = A θ + v`, `v ~ N(0, σ_R² I)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KfConfig {
    /// Process noise standard deviation `σ_Q` per window (units of `θ`), `≥ 0`.
    pub process_std: f64,
    /// Measurement noise standard deviation `σ_R` (units of `b`), `> 0`.
    pub measurement_std: f64,
    /// Initial covariance `P₀ = p0 · I` (units of `θ²`), also restored by `reset`.
    pub p0: f64,
    /// The name reported by [`OnlineEstimator::name`].
    pub label: &'static str,
}

impl KfConfig {
    /// The paper's KF-low: `σ_Q = 10⁻³`, `σ_R = 10⁻⁵`, `P₀ = 10³ I`.
    pub const fn low() -> Self {
        Self {
            process_std: 1e-3,
            measurement_std: 1e-5,
            p0: 1e3,
            label: "KF-low",
        }
    }

    /// The paper's KF-high: `σ_Q = 10⁻¹`, `σ_R = 10⁻³`, `P₀ = 10³ I`.
    pub const fn high() -> Self {
        Self {
            process_std: 1e-1,
            measurement_std: 1e-3,
            p0: 1e3,
            label: "KF-high",
        }
    }

    /// Checks every setting; called by the constructors.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.process_std >= 0.0 && self.process_std.is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "process_std",
                value: self.process_std,
                reason: "the process noise must be finite and non-negative",
            });
        }
        if !(self.measurement_std > 0.0 && self.measurement_std.is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "measurement_std",
                value: self.measurement_std,
                reason: "the measurement noise must be finite and positive",
            });
        }
        check_p0(self.p0)
    }
}

impl Default for KfConfig {
    fn default() -> Self {
        Self::low()
    }
}

fn check_p0(p0: f64) -> Result<(), ConfigError> {
    if !(p0 > 0.0 && p0.is_finite()) {
        return Err(ConfigError::InvalidParameter {
            name: "p0",
            value: p0,
            reason: "the initial covariance scale must be finite and positive",
        });
    }
    Ok(())
}

/// The constants that turn the shared block update into RLS or the Kalman filter.
#[derive(Debug, Clone, Copy)]
struct Constants<T> {
    /// Added to `P`'s diagonal before the update (`σ_Q²`; 0 for RLS).
    process: T,
    /// Added to `S`'s diagonal (`λ` for RLS, `σ_R²` for the KF).
    measurement: T,
    /// Multiplies the updated covariance (`1/λ` for RLS, 1 for the KF).
    scale: T,
    /// `P₀`'s diagonal.
    p0: T,
}

/// The block covariance update shared by [`Rls`] and [`KalmanFilter`].
struct BlockFilter<T: Real, S: Storage<T>> {
    n: usize,
    m_max: usize,
    consts: Constants<T>,
    buf: S,
}

/// Disjoint views of a [`BlockFilter`]'s buffer.
struct Parts<'a, T> {
    theta: &'a mut [T],
    candidate: &'a mut [T],
    p: &'a mut [T],
    w: &'a mut [T],
    z: &'a mut [T],
    s: &'a mut [T],
    y: &'a mut [T],
    inv_diag: &'a mut [T],
}

impl<T: Real, S: Storage<T>> BlockFilter<T, S> {
    fn new(n: usize, m_max: usize, consts: Constants<T>, buf: S) -> Result<Self, ConfigError> {
        tagk_core::check_dimensions(n, m_max)?;
        let needed = covariance_buffer_len(n, m_max);
        let found = buf.as_ref().len();
        if found < needed {
            return Err(ConfigError::BufferTooSmall { needed, found });
        }
        let mut filter = Self {
            n,
            m_max,
            consts,
            buf,
        };
        filter.buf.as_mut().fill(T::zero());
        filter.reset_covariance();
        Ok(filter)
    }

    fn parts(&mut self) -> Parts<'_, T> {
        let (n, m) = (self.n, self.m_max);
        let rest = self.buf.as_mut();
        let (theta, rest) = rest.split_at_mut(n);
        let (candidate, rest) = rest.split_at_mut(n);
        let (p, rest) = rest.split_at_mut(n * n);
        let (w, rest) = rest.split_at_mut(m * n);
        let (z, rest) = rest.split_at_mut(m * n);
        let (s, rest) = rest.split_at_mut(m * m);
        let (y, rest) = rest.split_at_mut(m);
        let inv_diag = &mut rest[..m];
        Parts {
            theta,
            candidate,
            p,
            w,
            z,
            s,
            y,
            inv_diag,
        }
    }

    fn estimate(&self) -> &[T] {
        &self.buf.as_ref()[..self.n]
    }

    /// The covariance `P`, row-major `n × n`.
    fn covariance(&self) -> &[T] {
        let n = self.n;
        &self.buf.as_ref()[2 * n..2 * n + n * n]
    }

    fn reset_covariance(&mut self) {
        let n = self.n;
        let p0 = self.consts.p0;
        let p = self.parts().p;
        p.fill(T::zero());
        for i in 0..n {
            p[i * n + i] = p0;
        }
    }

    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        validate_estimate(self.n, estimate)?;
        self.parts().theta.copy_from_slice(estimate);
        self.reset_covariance();
        Ok(())
    }

    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        let n = self.n;
        let m = validate_window(n, self.m_max, a, b)?;
        let Constants {
            process: q,
            measurement: r,
            scale,
            ..
        } = self.consts;
        let Parts {
            theta,
            candidate,
            p,
            w,
            z,
            s,
            y,
            inv_diag,
        } = self.parts();

        // W = A P̃ with P̃ = P + qI: row j of W is P̃ a_j (P is symmetric).
        for j in 0..m {
            let aj = &a[j * n..(j + 1) * n];
            let wj = &mut w[j * n..(j + 1) * n];
            for (i, wji) in wj.iter_mut().enumerate() {
                *wji = dot(&p[i * n..(i + 1) * n], aj);
            }
            if q != T::zero() {
                axpy(q, aj, wj);
            }
        }

        // S = A P̃ Aᵀ + r I (lower triangle, stride m), then S = L Lᵀ in place.
        for j in 0..m {
            let wj = &w[j * n..(j + 1) * n];
            for k in 0..=j {
                s[j * m + k] = dot(wj, &a[k * n..(k + 1) * n]);
            }
            s[j * m + j] += r;
        }
        for j in 0..m {
            for k in 0..=j {
                let acc = s[j * m + k] - dot(&s[j * m..j * m + k], &s[k * m..k * m + k]);
                if !acc.is_finite() {
                    return Err(EstimatorError::Diverged);
                }
                if k == j {
                    if acc <= T::zero() {
                        return Err(EstimatorError::NumericalFailure(
                            "the innovation covariance is not positive definite",
                        ));
                    }
                    let d = acc.sqrt();
                    s[j * m + j] = d;
                    inv_diag[j] = T::one() / d;
                } else {
                    s[j * m + k] = acc * inv_diag[k];
                }
            }
        }

        // y = L⁻¹ (b − A θ), and the prior residual norm.
        let mut rnorm2 = T::zero();
        for j in 0..m {
            let e = b[j] - dot(&a[j * n..(j + 1) * n], theta);
            rnorm2 += e * e;
            y[j] = e;
        }
        forward_substitute(m, s, inv_diag, &mut y[..m]);

        // Z = Wᵀ L⁻ᵀ, row-major n × m: row i is L⁻¹ (column i of W).
        for i in 0..n {
            let zi = &mut z[i * m..(i + 1) * m];
            for (j, zij) in zi.iter_mut().enumerate() {
                *zij = w[j * n + i];
            }
            forward_substitute(m, s, inv_diag, zi);
        }

        // Candidate θ + Z y, and a bound on the new covariance, before committing anything.
        let mut zmax = T::zero();
        for i in 0..n {
            let zi = &z[i * m..(i + 1) * m];
            candidate[i] = theta[i] + dot(zi, &y[..m]);
            zmax = zmax.max(dot(zi, zi));
        }
        if candidate.iter().any(|v| !v.is_finite()) {
            return Err(EstimatorError::Diverged);
        }
        // |(Z Zᵀ)_il| ≤ max_i ‖z_i‖², so (|P| + q + max ‖z_i‖²)·scale bounds every new entry.
        let mut pmax = T::zero();
        for i in 0..n {
            for v in &p[i * n + i..(i + 1) * n] {
                pmax = pmax.max(v.abs());
            }
        }
        let two = T::one() + T::one();
        if !((pmax + q + zmax) * scale * two).is_finite() {
            return Err(EstimatorError::Diverged);
        }

        // Commit: θ, then P ← (P̃ − Z Zᵀ)·scale on the upper triangle, mirrored.
        theta.copy_from_slice(candidate);
        for i in 0..n {
            let zi = &z[i * m..(i + 1) * m];
            let pii = p[i * n + i] + q - dot(zi, zi);
            p[i * n + i] = pii * scale;
            for l in i + 1..n {
                let v = (p[i * n + l] - dot(zi, &z[l * m..(l + 1) * m])) * scale;
                p[i * n + l] = v;
                p[l * n + i] = v;
            }
        }

        Ok(UpdateInfo {
            rows: m,
            iterations: 1,
            prior_residual_norm: rnorm2.sqrt().as_f64(),
            converged: false,
        })
    }
}

/// Solves `L x = v` in place for the lower-triangular `L` stored row-major with stride `m` in
/// `l`, with its diagonal's reciprocals in `inv_diag`.
#[inline]
fn forward_substitute<T: Real>(m: usize, l: &[T], inv_diag: &[T], v: &mut [T]) {
    for j in 0..m {
        let acc = v[j] - dot(&l[j * m..j * m + j], &v[..j]);
        v[j] = acc * inv_diag[j];
    }
}

/// Block recursive least squares with exponential forgetting, over caller-provided storage.
///
/// After windows `1..N` it holds the weighted least-squares estimate
/// `argmin_θ Σ_k λ^{N−k} ‖b_k − A_k θ‖² + λ^N (θ − θ₀)ᵀ P₀⁻¹ (θ − θ₀)` and
/// `P = (Σ_k λ^{N−k} A_kᵀ A_k + λ^N P₀⁻¹)⁻¹`. See the [module docs](self) for the update.
///
/// ```
/// use tagk_mcu::{covariance_buffer_len, OnlineEstimator, Rls, RlsConfig};
/// const LEN: usize = covariance_buffer_len(2, 2);
/// let mut rls = Rls::<f64, [f64; LEN]>::with_storage(2, 2, RlsConfig::low(), [0.0; LEN])?;
/// rls.update(&[1.0, 0.0, 0.0, 1.0], &[3.0, -1.0])?;
/// assert!((rls.estimate()[0] - 3.0).abs() < 1e-2);
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
pub struct Rls<T: Real, S: Storage<T>> {
    filter: BlockFilter<T, S>,
    config: RlsConfig,
}

impl<T: Real, S: Storage<T>> Rls<T, S> {
    /// Builds an RLS estimator of dimension `n` for windows of at most `m_max` rows in storage
    /// of at least [`covariance_buffer_len`]`(n, m_max)` scalars; `θ = 0`, `P = P₀`.
    pub fn with_storage(
        n: usize,
        m_max: usize,
        config: RlsConfig,
        buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let consts = Constants {
            process: T::zero(),
            measurement: T::cast(config.forgetting),
            scale: T::cast(1.0 / config.forgetting),
            p0: T::cast(config.p0),
        };
        Ok(Self {
            filter: BlockFilter::new(n, m_max, consts, buf)?,
            config,
        })
    }

    /// The configuration this estimator was built with.
    pub fn config(&self) -> &RlsConfig {
        &self.config
    }

    /// The covariance `P` (row-major `n × n`, exactly symmetric; units of `θ²`).
    pub fn covariance(&self) -> &[T] {
        self.filter.covariance()
    }

    /// The storage, handed back.
    pub fn into_storage(self) -> S {
        self.filter.buf
    }
}

/// Random-walk Kalman filter over caller-provided storage. See the [module docs](self).
///
/// ```
/// use tagk_mcu::{covariance_buffer_len, KalmanFilter, KfConfig, OnlineEstimator};
/// const LEN: usize = covariance_buffer_len(2, 2);
/// let mut kf = KalmanFilter::<f32, [f32; LEN]>::with_storage(2, 2, KfConfig::low(), [0.0; LEN])?;
/// kf.update(&[1.0, 0.0, 0.0, 1.0], &[3.0, -1.0])?;
/// assert!((kf.estimate()[1] + 1.0).abs() < 1e-4);
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
pub struct KalmanFilter<T: Real, S: Storage<T>> {
    filter: BlockFilter<T, S>,
    config: KfConfig,
}

impl<T: Real, S: Storage<T>> KalmanFilter<T, S> {
    /// Builds a Kalman filter of dimension `n` for windows of at most `m_max` rows in storage
    /// of at least [`covariance_buffer_len`]`(n, m_max)` scalars; `θ = 0`, `P = P₀`.
    pub fn with_storage(
        n: usize,
        m_max: usize,
        config: KfConfig,
        buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let consts = Constants {
            process: T::cast(config.process_std * config.process_std),
            measurement: T::cast(config.measurement_std * config.measurement_std),
            scale: T::one(),
            p0: T::cast(config.p0),
        };
        Ok(Self {
            filter: BlockFilter::new(n, m_max, consts, buf)?,
            config,
        })
    }

    /// The configuration this filter was built with.
    pub fn config(&self) -> &KfConfig {
        &self.config
    }

    /// The covariance `P` (row-major `n × n`, exactly symmetric; units of `θ²`).
    pub fn covariance(&self) -> &[T] {
        self.filter.covariance()
    }

    /// The storage, handed back.
    pub fn into_storage(self) -> S {
        self.filter.buf
    }
}

macro_rules! delegate_online_estimator {
    ($ty:ident) => {
        impl<T: Real, S: Storage<T>> OnlineEstimator<T> for $ty<T, S> {
            fn name(&self) -> &str {
                self.config.label
            }
            fn dim(&self) -> usize {
                self.filter.n
            }
            fn capacity(&self) -> usize {
                self.filter.m_max
            }
            fn estimate(&self) -> &[T] {
                self.filter.estimate()
            }
            fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
                self.filter.update(a, b)
            }
            fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
                self.filter.reset(estimate)
            }
        }
    };
}

delegate_online_estimator!(Rls);
delegate_online_estimator!(KalmanFilter);
