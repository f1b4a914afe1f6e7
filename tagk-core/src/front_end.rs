//! A front end for any [`OnlineEstimator`]: column scaling from a prior, row weights, a
//! noise-aware stop and event-aware windows, in one allocation-free wrapper.
//!
//! # When it matters
//! The estimators see raw windows `A θ ≈ b`. That is fine when every column of `A` has the
//! same order of magnitude. It is not when parameters of different units share a window, such
//! as a mass in kg next to an inertia in kg m². The per-window condition number then reaches
//! the thousands. A Kaczmarz method moves `θ̂` along the rows, so it barely moves the
//! parameters of small columns. One pass per window then leaves errors orders of magnitude
//! above batch least squares on the same data. `tagk-core/tests/front_end.rs` shows it: a
//! 3-parameter problem with per-window `κ ≈ 3000`, raw TAG-K against batch least squares and
//! the wrapped TAG-K. The recursive filters are scale-invariant in exact arithmetic, but not
//! in their noise model, so the front end helps them less. Its event-aware windows help all
//! of them.
//!
//! # What it does, per window
//! 1. **Column scaling** `D = diag(d)`: the estimator sees `A D` and estimates `D⁻¹ θ`;
//!    [`estimate`](OnlineEstimator::estimate) and [`reset`](OnlineEstimator::reset) stay in the
//!    caller's units. Choose `d_j` as the typical magnitude of parameter `j` (from a prior
//!    guess, [`scales_from_prior`]), so that every column of `A D` has the units and order of
//!    the measurement.
//! 2. **Row weights** `w_i ≥ 0` ([`FrontEnd::update_weighted`]): row `i` enters as
//!    `√w_i (a_i, b_i)`. A weight below 1 makes a noisy or weak row count less without
//!    dropping the information it carries (a weight of 0 drops it). For the recursive filters
//!    this is weighted least squares; for the greedy Kaczmarz variants a projection onto a row
//!    does not depend on its scale, so the weight acts through the row's selection probability
//!    (`∝ r_i²`) and the greedy threshold.
//! 3. **Noise floor** of the rows used: `σ √(Σ w_i)` with `σ` =
//!    [`FrontEndConfig::row_noise`], the standard deviation of one row's measurement noise
//!    (units of `b`): the expected norm of the residual `b − A θ` at the true `θ`.
//! 4. **Event-aware window**: when the prior residual `‖b − A θ̂‖` exceeds
//!    [`event_multiple`](FrontEndConfig::event_multiple) times the floor, the parameters have
//!    probably changed within or before this window. [`block_rows`](FrontEndConfig::block_rows)
//!    may be set to the rows of one sample (6 for a rigid body). Then the window is
//!    **shortened** to its rows from the first block whose own residual exceeds the same
//!    multiple of its own floor. The blocks before it still fit the old parameters and would
//!    pull the estimate back. On the first such window after a quiet one, the estimator is
//!    **restarted**: [`reset`](OnlineEstimator::reset) to its current estimate, with
//!    covariances back to their initial value, so a filter adapts at once.
//! 5. **Noise-aware stop**: an iterative estimator (the Kaczmarz family) stops a window's
//!    iterations once `‖r‖ ≤` [`stop_multiple`](FrontEndConfig::stop_multiple) `×` floor
//!    ([`OnlineEstimator::set_tolerance`]): projecting further would fit the noise. Estimators
//!    without such a stop ignore it.
//!
//! 6. **Averaging across windows** (optional, [`average_horizon`](FrontEndConfig::average_horizon)):
//!    the reported estimate is the running mean of the last window estimates since the last
//!    event, the cross-window counterpart of TAG-K's tail average.
//!
//! The wrapper itself is an [`OnlineEstimator`], so it goes wherever an estimator does. It
//! never allocates: its buffers (`4n + m_max (n + 1)` scalars, [`front_end_buffer_len`]) live
//! in storage the caller chooses, as the Kaczmarz estimators' do.

use crate::estimator::validate_window;
use crate::kaczmarz::Storage;
use crate::{ConfigError, EstimatorError, OnlineEstimator, Real, UpdateInfo};

/// Length of the buffer a [`FrontEnd`] of dimension `n` and window capacity `m_max` needs:
/// `4n + m_max (n + 1)` scalars (scales, estimate, scratch, average, the transformed window).
/// Saturates at `usize::MAX` where the length overflows (such sizes are refused);
/// [`checked_front_end_buffer_len`] says so with `None`.
pub const fn front_end_buffer_len(n: usize, m_max: usize) -> usize {
    match checked_front_end_buffer_len(n, m_max) {
        Some(len) => len,
        None => usize::MAX,
    }
}

/// [`front_end_buffer_len`] in checked arithmetic: `None` when the length overflows a
/// `usize` (the constructors then return [`ConfigError::TooLarge`]).
pub const fn checked_front_end_buffer_len(n: usize, m_max: usize) -> Option<usize> {
    let Some(four_n) = n.checked_mul(4) else {
        return None;
    };
    let Some(n1) = n.checked_add(1) else {
        return None;
    };
    let Some(window) = m_max.checked_mul(n1) else {
        return None;
    };
    four_n.checked_add(window)
}

/// Column scales from a prior guess `prior` of the parameters: `d_j = max(|prior_j|, floor)`
/// written to `out` (`floor > 0` stands in for parameters whose prior is zero or tiny; pick
/// the magnitude such a parameter would typically have).
///
/// # Errors
/// [`ConfigError::BufferTooSmall`] when `out` is shorter than `prior`;
/// [`ConfigError::InvalidParameter`] for a floor that is not positive and finite or a
/// non-finite prior.
pub fn scales_from_prior<T: Real>(prior: &[T], floor: T, out: &mut [T]) -> Result<(), ConfigError> {
    if out.len() < prior.len() {
        return Err(ConfigError::BufferTooSmall {
            needed: prior.len(),
            found: out.len(),
        });
    }
    if !(floor > T::zero() && floor.is_finite()) {
        return Err(ConfigError::InvalidParameter {
            name: "scale floor",
            value: floor.as_f64(),
            reason: "must be positive and finite",
        });
    }
    for (d, p) in out.iter_mut().zip(prior) {
        if !p.is_finite() {
            return Err(ConfigError::InvalidParameter {
                name: "prior",
                value: p.as_f64(),
                reason: "must be finite",
            });
        }
        *d = p.abs().max(floor);
    }
    Ok(())
}

/// The front end's settings (every one off by default: a [`FrontEnd`] with unit scales and the
/// default configuration feeds the estimator the window it was given).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrontEndConfig {
    /// `σ`: standard deviation of one row's measurement noise, in the units of `b` (before
    /// weighting). The noise floor of a window is `σ √(Σ w_i)`. Required (positive) by the
    /// event detection; `0` turns the stop into "stop only on an exact fit".
    pub row_noise: f64,
    /// `κ_stop`: iterative estimators stop once `‖b − A θ̂‖ ≤ κ_stop · floor` (0: off; 3 is
    /// the simulator's choice, about the 99.9 % point of the noise's norm for large windows).
    pub stop_multiple: f64,
    /// `κ_event`: a window whose prior residual exceeds `κ_event · floor` is an event (0: off).
    /// It must sit well above the noise (the residual at the true θ is about one floor) and
    /// above what the model leaves unexplained (biases, unmodelled effects): 5–10.
    pub event_multiple: f64,
    /// Rows of one sample (a block that is kept or dropped together when an event shortens the
    /// window; 6 for a rigid body's wrench). 0: events restart the estimator but never shorten
    /// the window.
    pub block_rows: usize,
    /// `H`: report the running mean of the estimator's last (up to) `H` window estimates
    /// instead of the last one (0 or 1: off). Between events the parameters are constant. So the
    /// mean keeps the noise of one window's fit from reaching the estimate: its error falls as
    /// `1/√k` over `k ≤ H` windows. An event (or a reset) restarts the mean, so it never blends
    /// parameters from before and after. The update is `x̄ ← x̄ + (x − x̄)/min(k, H)`.
    pub average_horizon: usize,
}

impl FrontEndConfig {
    /// Checks every setting.
    ///
    /// # Errors
    /// [`ConfigError::InvalidParameter`] for a negative or non-finite value, or event detection
    /// without a positive `row_noise`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, value) in [
            ("row_noise", self.row_noise),
            ("stop_multiple", self.stop_multiple),
            ("event_multiple", self.event_multiple),
        ] {
            if !(value >= 0.0 && value.is_finite()) {
                return Err(ConfigError::InvalidParameter {
                    name,
                    value,
                    reason: "must be finite and non-negative",
                });
            }
        }
        if self.event_multiple > 0.0 && self.row_noise <= 0.0 {
            return Err(ConfigError::InvalidParameter {
                name: "row_noise",
                value: self.row_noise,
                reason: "event detection needs a positive row noise (the floor it compares to)",
            });
        }
        Ok(())
    }

    /// The noise floor `σ √(weight_sum)` of rows whose weights sum to `weight_sum`.
    pub fn noise_floor(&self, weight_sum: f64) -> f64 {
        self.row_noise * num_traits::Float::sqrt(weight_sum)
    }
}

/// What one front-end update did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrontEndInfo {
    /// The wrapped estimator's report (rows: those fed to it).
    pub update: UpdateInfo,
    /// `‖b − A θ̂_prev‖₂` of the whole weighted window, before the update (units of `b`).
    pub prior_residual_norm: f64,
    /// The noise floor of the whole weighted window (units of `b`).
    pub noise_floor: f64,
    /// Whether the window was an event (prior residual above `κ_event` floors).
    pub event: bool,
    /// Whether the estimator was restarted (first event window after a quiet one).
    pub restarted: bool,
    /// Index of the first row fed to the estimator (rows before it were dropped as
    /// pre-event; 0 when the whole window was used).
    pub first_row: usize,
}

/// An [`OnlineEstimator`] behind the front end described in the [module docs](self).
///
/// # Examples
///
/// A mass \[kg\] beside an inertia \[kg m²\]: columns three orders of magnitude apart. With
/// column scales from a prior guess, TAG-K reaches both parameters, which raw TAG-K does not.
/// A jump in the parameters is flagged as an event, the estimator restarts, and the new values
/// are reached too.
///
/// ```
/// use tagk_core::{FrontEnd, FrontEndConfig, KaczmarzConfig, OnlineEstimator, TagK};
/// use tagk_core::scales_from_prior;
///
/// // Window w: 4 rows (g_k, α_k), b = g m + α I, with g ≈ 10 m/s² and |α| ≤ 10⁴ rad/s².
/// let window = |theta: [f64; 2], w: usize| -> (Vec<f64>, Vec<f64>) {
///     let (mut a, mut b) = (Vec::new(), Vec::new());
///     for k in 0..4 {
///         let phase = 1.3 * (4 * w + k) as f64;
///         let row = [10.0 + 2.0 * phase.sin(), 1.0e4 * phase.cos()];
///         a.extend(row);
///         b.push(row[0] * theta[0] + row[1] * theta[1]);
///     }
///     (a, b)
/// };
/// let prior = [0.03, 2.0e-5]; // m [kg], I [kg m²]
/// let mut scales = [0.0; 2];
/// scales_from_prior(&prior, 1e-9, &mut scales)?;
/// let config = FrontEndConfig { row_noise: 1e-9, event_multiple: 8.0, ..Default::default() };
/// let inner = TagK::<f64, Vec<f64>>::new(2, 4, KaczmarzConfig::default())?;
/// let mut fe = FrontEnd::new(inner, &scales, config)?;
/// fe.reset(&prior)?;
/// let mut raw = TagK::<f64, Vec<f64>>::new(2, 4, KaczmarzConfig::default())?;
/// raw.reset(&prior)?;
///
/// let theta = [0.035, 2.5e-5];
/// for w in 0..100 {
///     let (a, b) = window(theta, w);
///     fe.update(&a, &b)?;
///     raw.update(&a, &b)?;
/// }
/// // The data are exact: both parameters to 1e-9 relative, whatever their units.
/// let relative = |e: &[f64], t: &[f64; 2]| (0..2).map(|j| ((e[j] - t[j]) / t[j]).abs()).fold(0.0, f64::max);
/// assert!(relative(fe.estimate(), &theta) < 1e-9);
/// // Raw TAG-K still misses by more than 1 % (it barely moves the small column's parameter).
/// assert!(relative(raw.estimate(), &theta) > 1e-2);
///
/// // A payload: the first window after it is an event and restarts the estimator.
/// let heavier = [0.045, 3.0e-5];
/// let (a, b) = window(heavier, 100);
/// fe.update(&a, &b)?;
/// let info = fe.last().expect("an update ran");
/// assert!(info.event && info.restarted);
/// for w in 101..200 {
///     let (a, b) = window(heavier, w);
///     fe.update(&a, &b)?;
/// }
/// assert!(relative(fe.estimate(), &heavier) < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct FrontEnd<T: Real, E: OnlineEstimator<T>, S: Storage<T>> {
    inner: E,
    config: FrontEndConfig,
    n: usize,
    m_max: usize,
    buf: S,
    /// The previous window was not an event.
    quiet: bool,
    /// Windows in the running mean since the last restart.
    averaged: usize,
    last: Option<FrontEndInfo>,
    _scalar: core::marker::PhantomData<T>,
}

impl<T: Real, E: OnlineEstimator<T> + core::fmt::Debug, S: Storage<T>> core::fmt::Debug
    for FrontEnd<T, E, S>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FrontEnd")
            .field("inner", &self.inner)
            .field("config", &self.config)
            .field("scales", &self.scales())
            .finish_non_exhaustive()
    }
}

/// Disjoint views of the buffer.
struct Parts<'a, T> {
    scales: &'a mut [T],
    estimate: &'a mut [T],
    scratch: &'a mut [T],
    average: &'a mut [T],
    a: &'a mut [T],
    b: &'a mut [T],
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> FrontEnd<T, E, S> {
    /// Wraps `inner` (its dimension `n` and capacity `m_max`) with column scales `scales`
    /// (`n` positive values, [`scales_from_prior`]) in caller storage of at least
    /// [`front_end_buffer_len`]`(n, m_max)` scalars. The estimate is `inner`'s, scaled back.
    ///
    /// # Errors
    /// A bad configuration, a buffer that is too short, or scales that are not `n` positive
    /// finite values.
    pub fn with_storage(
        inner: E,
        scales: &[T],
        config: FrontEndConfig,
        mut buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let (n, m_max) = (inner.dim(), inner.capacity());
        let needed =
            checked_front_end_buffer_len(n, m_max).ok_or(ConfigError::TooLarge { n, m: m_max })?;
        let found = buf.as_ref().len();
        if found < needed {
            return Err(ConfigError::BufferTooSmall { needed, found });
        }
        if scales.len() != n {
            return Err(ConfigError::BufferTooSmall {
                needed: n,
                found: scales.len(),
            });
        }
        if let Some(d) = scales.iter().find(|d| !(**d > T::zero() && d.is_finite())) {
            return Err(ConfigError::InvalidParameter {
                name: "column scale",
                value: d.as_f64(),
                reason: "every scale must be positive and finite",
            });
        }
        buf.as_mut().fill(T::zero());
        let mut fe = Self {
            inner,
            config,
            n,
            m_max,
            buf,
            quiet: true,
            averaged: 0,
            last: None,
            _scalar: core::marker::PhantomData,
        };
        let p = Self::parts(&mut fe.buf, n, m_max);
        p.scales.copy_from_slice(scales);
        fe.refresh_estimate();
        fe.averaged = 0;
        Ok(fe)
    }

    fn parts(buf: &mut S, n: usize, m_max: usize) -> Parts<'_, T> {
        let (scales, rest) = buf.as_mut().split_at_mut(n);
        let (estimate, rest) = rest.split_at_mut(n);
        let (scratch, rest) = rest.split_at_mut(n);
        let (average, rest) = rest.split_at_mut(n);
        let (a, rest) = rest.split_at_mut(m_max * n);
        Parts {
            scales,
            estimate,
            scratch,
            average,
            a,
            b: &mut rest[..m_max],
        }
    }

    /// Folds the inner estimate into the running mean (restarted when `averaged == 0`) and
    /// sets `estimate = D · mean` (`D ·` inner estimate without averaging).
    fn refresh_estimate(&mut self) {
        let p = Self::parts(&mut self.buf, self.n, self.m_max);
        let x = self.inner.estimate();
        let horizon = self.config.average_horizon;
        if horizon > 1 {
            self.averaged += 1;
            let k = T::cast(self.averaged.min(horizon) as f64);
            for (a, x) in p.average.iter_mut().zip(x) {
                *a += (*x - *a) / k;
            }
        } else {
            p.average.copy_from_slice(x);
        }
        for ((e, d), a) in p.estimate.iter_mut().zip(&*p.scales).zip(&*p.average) {
            *e = *d * *a;
        }
    }

    /// The column scales `d`.
    pub fn scales(&self) -> &[T] {
        &self.buf.as_ref()[..self.n]
    }

    /// The configuration.
    pub fn config(&self) -> &FrontEndConfig {
        &self.config
    }

    /// The wrapped estimator (its estimate is in scaled units, `D⁻¹ θ̂`).
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// What the last successful update did (`None` before the first one or after a reset).
    pub fn last(&self) -> Option<&FrontEndInfo> {
        self.last.as_ref()
    }

    /// Incorporates one window `A θ ≈ b` with row weights `weights` (`None`: every weight 1);
    /// see the [module docs](self) for the steps.
    ///
    /// # Errors
    /// The window's errors ([`validate_window`]), [`EstimatorError::InvalidWeight`], or the
    /// wrapped estimator's. A failed update leaves the estimate as it was; if it fails after an
    /// event restarted the estimator, the estimator's covariances stay restarted.
    pub fn update_weighted(
        &mut self,
        a: &[T],
        b: &[T],
        weights: Option<&[T]>,
    ) -> Result<FrontEndInfo, EstimatorError> {
        let (n, m_max) = (self.n, self.m_max);
        let m = validate_window(n, m_max, a, b)?;
        if let Some(w) = weights {
            if w.len() != m {
                return Err(EstimatorError::InvalidWeight { row: m });
            }
            if let Some(row) = w.iter().position(|x| !(*x >= T::zero() && x.is_finite())) {
                return Err(EstimatorError::InvalidWeight { row });
            }
        }
        let weight = |i: usize| weights.map_or(T::one(), |w| w[i]);
        let p = Self::parts(&mut self.buf, n, m_max);
        // The transformed window √w_i (a_i D, b_i) and its prior residual, in place of b.
        let x = self.inner.estimate();
        let mut total = 0.0f64;
        let mut weight_sum = 0.0f64;
        for i in 0..m {
            let sw = weight(i).sqrt();
            let row = &mut p.a[i * n..(i + 1) * n];
            let mut ax = T::zero();
            for j in 0..n {
                row[j] = sw * (a[i * n + j] * p.scales[j]);
                ax += row[j] * x[j];
            }
            p.b[i] = sw * b[i];
            let r = (p.b[i] - ax).as_f64();
            total += r * r;
            weight_sum += weight(i).as_f64();
        }
        let prior_residual_norm = num_traits::Float::sqrt(total);
        let noise_floor = self.config.noise_floor(weight_sum);
        let kappa_e = self.config.event_multiple;
        let event = kappa_e > 0.0 && prior_residual_norm > kappa_e * noise_floor;
        let mut first_row = 0;
        if event && self.config.block_rows > 0 {
            let k = self.config.block_rows;
            let mut start = 0;
            while start < m {
                let end = (start + k).min(m);
                let (mut r2, mut ws) = (0.0f64, 0.0f64);
                for i in start..end {
                    let ax = crate::linalg::dot(&p.a[i * n..(i + 1) * n], x);
                    let r = (p.b[i] - ax).as_f64();
                    r2 += r * r;
                    ws += weight(i).as_f64();
                }
                if num_traits::Float::sqrt(r2) > kappa_e * self.config.noise_floor(ws) {
                    first_row = start;
                    break;
                }
                start = end;
            }
            if start >= m {
                first_row = 0;
            }
        }
        let used_weight: f64 = (first_row..m).map(|i| weight(i).as_f64()).sum();
        if self.config.stop_multiple > 0.0 {
            self.inner
                .set_tolerance(self.config.stop_multiple * self.config.noise_floor(used_weight));
        }
        let restarted = event && self.quiet;
        if restarted {
            p.scratch.copy_from_slice(self.inner.estimate());
            self.inner.reset(p.scratch)?;
        }
        if event {
            self.averaged = 0;
        }
        let update = self
            .inner
            .update(&p.a[first_row * n..m * n], &p.b[first_row..m])?;
        self.quiet = !event;
        self.refresh_estimate();
        let info = FrontEndInfo {
            update,
            prior_residual_norm,
            noise_floor,
            event,
            restarted,
            first_row,
        };
        self.last = Some(info);
        Ok(info)
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, E: OnlineEstimator<T>> FrontEnd<T, E, alloc::vec::Vec<T>> {
    /// [`FrontEnd::with_storage`] with its buffer on the heap (allocated once, here).
    ///
    /// # Errors
    /// As [`FrontEnd::with_storage`]; [`ConfigError::TooLarge`] when the buffer's length
    /// overflows or its allocation is refused (no abort).
    pub fn new(inner: E, scales: &[T], config: FrontEndConfig) -> Result<Self, ConfigError> {
        let (n, m) = (inner.dim(), inner.capacity());
        let len = checked_front_end_buffer_len(n, m).ok_or(ConfigError::TooLarge { n, m })?;
        let buf = crate::kaczmarz::zeroed_buffer(len, n, m)?;
        Self::with_storage(inner, scales, config, buf)
    }
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> OnlineEstimator<T> for FrontEnd<T, E, S> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn dim(&self) -> usize {
        self.n
    }

    fn capacity(&self) -> usize {
        self.m_max
    }

    /// The estimate in the caller's units, `D · θ̂_inner`.
    fn estimate(&self) -> &[T] {
        &self.buf.as_ref()[self.n..2 * self.n]
    }

    /// [`FrontEnd::update_weighted`] with every weight 1.
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        self.update_weighted(a, b, None).map(|i| i.update)
    }

    /// Resets the wrapped estimator to `D⁻¹ estimate` (`estimate` in the caller's units).
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        crate::validate_estimate(self.n, estimate)?;
        let p = Self::parts(&mut self.buf, self.n, self.m_max);
        for ((s, e), d) in p.scratch.iter_mut().zip(estimate).zip(&*p.scales) {
            *s = *e / *d;
        }
        self.inner.reset(p.scratch)?;
        self.quiet = true;
        self.last = None;
        self.averaged = 0;
        self.refresh_estimate();
        // The reset estimate is not a window's: the first update replaces it in the mean.
        self.averaged = 0;
        Ok(())
    }

    /// Sets the wrapped estimator's tolerance (overwritten by every update when
    /// [`FrontEndConfig::stop_multiple`] is set).
    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        self.inner.set_tolerance(tolerance)
    }
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use crate::{KaczmarzConfig, TagK};
    use alloc::vec::Vec;

    fn window(theta: &[f64; 2], rows: &[[f64; 2]]) -> (Vec<f64>, Vec<f64>) {
        let a: Vec<f64> = rows.iter().flatten().copied().collect();
        let b = rows
            .iter()
            .map(|r| r[0] * theta[0] + r[1] * theta[1])
            .collect();
        (a, b)
    }

    fn tagk() -> TagK<f64, Vec<f64>> {
        TagK::new(2, 6, KaczmarzConfig::default().with_seed(3)).unwrap()
    }

    #[test]
    fn unit_scales_and_default_config_feed_the_window_unchanged() {
        let mut plain = tagk();
        let mut wrapped = FrontEnd::new(tagk(), &[1.0, 1.0], FrontEndConfig::default()).unwrap();
        let rows = [[1.0, 0.5], [0.2, -1.0], [0.7, 0.3], [-0.4, 0.9]];
        for k in 0..5 {
            let (a, b) = window(&[1.0 + k as f64, -2.0], &rows);
            plain.update(&a, &b).unwrap();
            wrapped.update(&a, &b).unwrap();
            assert_eq!(plain.estimate(), wrapped.estimate());
        }
    }

    #[test]
    fn an_event_drops_the_pre_event_blocks_and_restarts() {
        let config = FrontEndConfig {
            row_noise: 1e-6,
            event_multiple: 5.0,
            block_rows: 2,
            ..FrontEndConfig::default()
        };
        let mut fe = FrontEnd::new(tagk(), &[1.0, 1.0], config).unwrap();
        fe.reset(&[1.0, 2.0]).unwrap();
        // Two blocks of the old parameters, then one of the new.
        let rows = [
            [1.0, 0.5],
            [0.2, -1.0],
            [0.7, 0.3],
            [-0.4, 0.9],
            [0.6, 0.1],
            [0.3, 0.8],
        ];
        let (mut a, mut b) = window(&[1.0, 2.0], &rows);
        let (a2, b2) = window(&[1.5, 2.0], &rows);
        a[8..].copy_from_slice(&a2[8..]);
        b[4..].copy_from_slice(&b2[4..]);
        let info = fe.update_weighted(&a, &b, None).unwrap();
        assert!(info.event && info.restarted);
        assert_eq!(info.first_row, 4);
        assert_eq!(info.update.rows, 2);
    }

    #[test]
    fn a_rejected_window_keeps_the_previous_estimate() {
        // A huge first scale: a finite window overflows once scaled, and the wrapped estimator
        // rejects it.
        let mut fe = FrontEnd::new(tagk(), &[1e300, 1.0], FrontEndConfig::default()).unwrap();
        let rows = [[1e-300, 0.5], [2e-300, -1.0], [1e-300, 0.3]];
        let (a, b) = window(&[1e300, 2.0], &rows);
        fe.update(&a, &b).unwrap();
        let before = fe.estimate().to_vec();
        let mut overflow = a.clone();
        overflow[0] = 1e10;
        assert!(matches!(
            fe.update(&overflow, &b),
            Err(EstimatorError::NonFiniteRegressor { .. })
        ));
        assert_eq!(fe.estimate(), &before[..]);
        let mut nan = b.clone();
        nan[1] = f64::NAN;
        assert_eq!(
            fe.update(&a, &nan),
            Err(EstimatorError::NonFiniteMeasurement { row: 1 })
        );
        assert_eq!(fe.estimate(), &before[..]);
    }

    #[test]
    fn bad_weights_are_typed_errors_and_change_nothing() {
        let mut fe = FrontEnd::new(tagk(), &[2.0, 0.5], FrontEndConfig::default()).unwrap();
        fe.reset(&[1.0, 1.0]).unwrap();
        let (a, b) = window(&[1.0, 2.0], &[[1.0, 0.5], [0.2, -1.0]]);
        assert_eq!(
            fe.update_weighted(&a, &b, Some(&[1.0, -1.0])),
            Err(EstimatorError::InvalidWeight { row: 1 })
        );
        assert_eq!(
            fe.update_weighted(&a, &b, Some(&[1.0])),
            Err(EstimatorError::InvalidWeight { row: 2 })
        );
        assert_eq!(fe.estimate(), &[1.0, 1.0]);
        let cfg = FrontEndConfig {
            event_multiple: 3.0,
            ..FrontEndConfig::default()
        };
        assert!(FrontEnd::new(tagk(), &[1.0, 1.0], cfg).is_err());
        assert!(FrontEnd::new(tagk(), &[1.0, 0.0], FrontEndConfig::default()).is_err());
    }
}
