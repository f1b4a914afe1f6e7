//! Change detection on an estimator's own residual, and adaptation on a fresh post-event
//! window, for any [`OnlineEstimator`].
//!
//! # The test
//! Rows `i` of a window belong to channels `c(i) = i mod C` (for a rigid body's wrench, `C = 6`:
//! `f_x … τ_z`). [`ChangeDetector`] measures each channel's mean squared prior residual
//! `σ̂_c²` on quiet data (a warm-up, then a running mean over the checks that do not alarm). A
//! check of rows `i` with prior residuals `r_i = b_i − a_i θ̂` computes
//!
//! ```text
//! s = Σ_i r_i² / σ̂_c(i)²        (rows of weight 0 left out; ν rows counted)
//! ```
//!
//! While the parameters stay put and the residuals are Gaussian with those variances, `s` is
//! χ² with `ν` degrees of freedom. The check alarms when `s` exceeds the χ²(ν) upper
//! [`false_alarm`](DetectorConfig::false_alarm) point ([`chi_square_quantile`]): the design
//! false-alarm probability of one check. No knowledge of when an event happens is used.
//!
//! # The reaction
//! [`EventTriggered`] wraps an estimator with the detector. On an alarm it restarts the
//! estimator at once ([`reset`](OnlineEstimator::reset) to its estimate, covariances back to
//! their initial value). The window that alarmed may mix rows from before and after the event,
//! so it is not used. The next window is fresh: every row comes after the alarm. On it the
//! first post-event estimate is solved directly ([`EventTriggered::first_estimate`]):
//!
//! ```text
//! θ = θ̂ + δ,  δ = argmin Σ_i w_i r_i² / σ̂_c(i)² + Σ_j δ_j² / s_j²
//! ```
//!
//! with `s_j` the typical size of a change of parameter `j` (the prior of a jump). It is the
//! maximum a posteriori estimate of one fresh window, with the measured noise of its rows. The
//! estimator is reset to `θ` and then updated on the window as usual.

use crate::kaczmarz::Storage;
use crate::{ConfigError, EstimatorError, OnlineEstimator, Real, UpdateInfo, linalg};
use num_traits::Float;

/// Most channels a [`ChangeDetector`] tells apart (its state is fixed-size arrays).
pub const MAX_CHANNELS: usize = 16;

/// `z` with `P(N(0, 1) > z) = p` for `0 < p < 1`: Acklam's rational approximation
/// (relative error below 1.2e-9).
pub fn normal_upper_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    // The lower quantile of q = 1 − p is the upper quantile of p.
    let q = 1.0 - p;
    let tail = |t: f64| {
        let u = (-2.0 * t.ln()).sqrt();
        (((((C[0] * u + C[1]) * u + C[2]) * u + C[3]) * u + C[4]) * u + C[5])
            / ((((D[0] * u + D[1]) * u + D[2]) * u + D[3]) * u + 1.0)
    };
    if q < 0.02425 {
        tail(q)
    } else if q > 1.0 - 0.02425 {
        -tail(1.0 - q)
    } else {
        let u = q - 0.5;
        let r = u * u;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * u
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// `P(χ²_ν > x)` for an even `ν ≤ 400`: `e^{−x/2} Σ_{i < ν/2} (x/2)^i / i!`, summed in logs.
fn chi_square_survival_even(dof: usize, x: f64) -> f64 {
    let h = 0.5 * x;
    if h <= 0.0 {
        return 1.0;
    }
    let (mut log_term, mut sum) = (-h, 0.0);
    for i in 0..dof / 2 {
        if i > 0 {
            log_term += h.ln() - (i as f64).ln();
        }
        sum += log_term.exp();
    }
    sum.min(1.0)
}

/// The upper `alpha` point of the χ² distribution with `dof` degrees of freedom: `x` with
/// `P(χ²_dof > x) = alpha` (`0 < alpha < 1`, `dof ≥ 1`). Exact (bisection on the closed-form
/// tail) for an even `dof ≤ 400`; otherwise the Wilson–Hilferty approximation
/// `ν (1 − 2/(9ν) + z √(2/(9ν)))³`, within a few per cent of the exact point at `α ≥ 1e-6`.
/// `NaN` for arguments out of range.
pub fn chi_square_quantile(dof: usize, alpha: f64) -> f64 {
    if dof == 0 || !(alpha > 0.0 && alpha < 1.0) {
        return f64::NAN;
    }
    let nu = dof as f64;
    let z = normal_upper_quantile(alpha);
    let c = 2.0 / (9.0 * nu);
    let wh = nu * (1.0 - c + z * c.sqrt()).max(0.0).powi(3);
    if dof % 2 == 1 || dof > 400 {
        return wh;
    }
    let (mut lo, mut hi) = (0.0, (2.0 * wh).max(nu + 60.0));
    while chi_square_survival_even(dof, hi) > alpha {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi_square_survival_even(dof, mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Settings of a [`ChangeDetector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorConfig {
    /// `α`: the design probability that one check alarms while nothing changed
    /// (`0 < α < 0.5`; default `1e-4`).
    pub false_alarm: f64,
    /// `C`: channels; row `i` of a window is channel `i mod C` (1 ≤ C ≤ [`MAX_CHANNELS`];
    /// default 6, a rigid body's wrench).
    pub channels: usize,
    /// Checks that only measure the noise, before the first alarm can fire (≥ 1; default 10).
    pub warmup: usize,
    /// After the warm-up, each channel's mean square is a running mean over its last (up to)
    /// this many rows of quiet checks (≥ 1; default 500).
    pub horizon: usize,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            false_alarm: 1e-4,
            channels: 6,
            warmup: 10,
            horizon: 500,
        }
    }
}

impl DetectorConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ConfigError::InvalidParameter`] for a value out of its range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |name, value: f64, reason| {
            Err(ConfigError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        if !(self.false_alarm > 0.0 && self.false_alarm < 0.5) {
            return bad("false_alarm", self.false_alarm, "must be in (0, 0.5)");
        }
        if self.channels == 0 || self.channels > MAX_CHANNELS {
            return bad("channels", self.channels as f64, "must be in 1..=16");
        }
        if self.warmup == 0 {
            return bad("warmup", 0.0, "must be at least 1");
        }
        if self.horizon == 0 {
            return bad("horizon", 0.0, "must be at least 1");
        }
        Ok(())
    }
}

/// What one check found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Check {
    /// `s = Σ r_i² / σ̂_c(i)²` (dimensionless; `+∞` when a channel with zero measured noise
    /// has a residual).
    pub statistic: f64,
    /// `ν`: rows counted (weight above 0).
    pub dof: usize,
    /// The χ²(ν) upper `α` point the statistic is compared to (`NaN` for `ν = 0`).
    pub threshold: f64,
    /// Whether the check alarmed.
    pub alarm: bool,
    /// Whether the warm-up was over (no alarm can fire before).
    pub calibrated: bool,
}

/// A χ² test of prior residuals against their measured per-channel noise (see the
/// [module docs](self)). Allocation-free, fixed size.
#[derive(Debug, Clone, PartialEq)]
pub struct ChangeDetector {
    config: DetectorConfig,
    /// `σ̂_c²`: measured mean square of each channel's residual.
    mean_square: [f64; MAX_CHANNELS],
    /// Rows folded into each channel's mean square.
    rows: [usize; MAX_CHANNELS],
    checks: usize,
    alarms: usize,
    /// Whether the noise is given, not measured.
    known: bool,
    /// The previous check was quiet (an alarm needs a quiet check before it).
    quiet: bool,
}

impl ChangeDetector {
    /// A detector that measures the noise of the rows during its warm-up.
    ///
    /// # Errors
    /// A bad configuration.
    pub fn new(config: DetectorConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            mean_square: [0.0; MAX_CHANNELS],
            rows: [0; MAX_CHANNELS],
            checks: 0,
            alarms: 0,
            known: false,
            quiet: true,
        })
    }

    /// A detector with the noise of each channel given (`sigma[c]`, standard deviations in the
    /// rows' units, one per channel): no warm-up, no measurement.
    ///
    /// # Errors
    /// A bad configuration, or `sigma` without one positive finite value per channel.
    pub fn with_known_noise(config: DetectorConfig, sigma: &[f64]) -> Result<Self, ConfigError> {
        let mut d = Self::new(config)?;
        if sigma.len() != config.channels {
            return Err(ConfigError::BufferTooSmall {
                needed: config.channels,
                found: sigma.len(),
            });
        }
        for (c, s) in sigma.iter().enumerate() {
            if !(*s > 0.0 && s.is_finite()) {
                return Err(ConfigError::InvalidParameter {
                    name: "sigma",
                    value: *s,
                    reason: "must be positive and finite",
                });
            }
            d.mean_square[c] = s * s;
        }
        d.known = true;
        Ok(d)
    }

    /// The configuration.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// `σ̂_c`: the measured (or given) noise of each channel, in the rows' units.
    pub fn noise(&self) -> [f64; MAX_CHANNELS] {
        self.mean_square.map(Float::sqrt)
    }

    /// Checks done so far.
    pub fn checks(&self) -> usize {
        self.checks
    }

    /// Alarms so far.
    pub fn alarms(&self) -> usize {
        self.alarms
    }

    /// Whether the warm-up is over.
    pub fn calibrated(&self) -> bool {
        self.known || self.checks >= self.config.warmup
    }

    /// Tests prior residuals `residuals[i]` (row `i`, channel `i mod C`) with row weights
    /// `weights` (`None`: all 1; rows of weight 0 are left out). A quiet check after the
    /// warm-up (and every warm-up check) refines the measured noise. An alarm needs the check
    /// before it to be quiet, so one change alarms once.
    pub fn check(&mut self, residuals: &[f64], weights: Option<&[f64]>) -> Check {
        self.check_rows(residuals.iter().enumerate().map(|(i, r)| {
            let used = weights.is_none_or(|w| w.get(i).is_some_and(|w| *w > 0.0));
            (*r, used)
        }))
    }

    /// [`check`](Self::check) over `(residual, used)` pairs, row by row.
    pub fn check_rows<I: Iterator<Item = (f64, bool)> + Clone>(&mut self, rows: I) -> Check {
        let channels = self.config.channels;
        let (mut statistic, mut dof) = (0.0, 0usize);
        for (i, (r, used)) in rows.clone().enumerate() {
            if !used {
                continue;
            }
            dof += 1;
            let ms = self.mean_square[i % channels];
            statistic += if ms > 0.0 {
                r * r / ms
            } else if r == 0.0 {
                0.0
            } else {
                f64::INFINITY
            };
        }
        let calibrated = self.calibrated();
        let threshold = if dof > 0 {
            chi_square_quantile(dof, self.config.false_alarm)
        } else {
            f64::NAN
        };
        // Above the threshold, or not comparable (a NaN residual).
        let below = matches!(
            statistic.partial_cmp(&threshold),
            Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal)
        );
        let exceeds = calibrated && dof > 0 && !below;
        let alarm = exceeds && self.quiet;
        self.quiet = !exceeds;
        if alarm {
            self.alarms += 1;
        }
        if !self.known && !exceeds {
            let horizon = if calibrated {
                self.config.horizon
            } else {
                usize::MAX
            };
            for (i, (r, used)) in rows.enumerate() {
                if !used || !r.is_finite() {
                    continue;
                }
                let c = i % channels;
                self.rows[c] += 1;
                let k = self.rows[c].min(horizon) as f64;
                self.mean_square[c] += (r * r - self.mean_square[c]) / k;
            }
        }
        self.checks += 1;
        Check {
            statistic,
            dof,
            threshold,
            alarm,
            calibrated,
        }
    }
}

/// Length of the buffer an [`EventTriggered`] of dimension `n` and window capacity `m_max`
/// needs: `n² + 4 n + m_max` scalars. `None` on overflow.
pub const fn checked_event_triggered_buffer_len(n: usize, m_max: usize) -> Option<usize> {
    let Some(n2) = n.checked_mul(n) else {
        return None;
    };
    let Some(four_n) = n.checked_mul(4) else {
        return None;
    };
    let Some(x) = n2.checked_add(four_n) else {
        return None;
    };
    x.checked_add(m_max)
}

/// An [`OnlineEstimator`] with a [`ChangeDetector`] on its prior residual and a direct first
/// estimate on the first fresh window after an alarm (see the [module docs](self)).
///
/// The trait's [`update`](OnlineEstimator::update) checks each window, drops a window that
/// alarms and solves the next one directly. A caller that sees rows more often than it updates
/// (every sample, say) can call [`check`](Self::check) on each sample and
/// [`first_estimate`](Self::first_estimate) on the first fresh window itself.
///
/// # Examples
///
/// A step in the parameters is detected on its first window and tracked on the next.
///
/// ```
/// use tagk_core::{DetectorConfig, EventTriggered, KaczmarzConfig, OnlineEstimator, TagK};
///
/// let window = |theta: [f64; 2], w: usize| -> (Vec<f64>, Vec<f64>) {
///     let (mut a, mut b) = (Vec::new(), Vec::new());
///     for k in 0..4 {
///         let phi = 1.1 * (4 * w + k) as f64;
///         let noise = 1e-3 * (3.7 * (4 * w + k) as f64).sin();
///         a.extend([phi.cos(), phi.sin()]);
///         b.push(phi.cos() * theta[0] + phi.sin() * theta[1] + noise);
///     }
///     (a, b)
/// };
/// let config = DetectorConfig { channels: 1, ..DetectorConfig::default() };
/// let tagk = TagK::<f64, Vec<f64>>::new(2, 4, KaczmarzConfig::default())?;
/// let mut est = EventTriggered::new(tagk, &[1.0, 1.0], config)?;
/// // Start near the parameters: the warm-up measures the noise, not a transient.
/// est.reset(&[1.0, 2.0])?;
/// for w in 0..50 {
///     let (a, b) = window([1.0, 2.0], w);
///     est.update(&a, &b)?;
/// }
/// assert_eq!(est.detector().alarms(), 0);
/// let (a, b) = window([1.5, 2.0], 50);
/// est.update(&a, &b)?;
/// assert!(est.is_pending() && est.detector().alarms() == 1);
/// let (a, b) = window([1.5, 2.0], 51);
/// est.update(&a, &b)?;
/// assert!((est.estimate()[0] - 1.5).abs() < 1e-2);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct EventTriggered<T: Real, E: OnlineEstimator<T>, S: Storage<T>> {
    inner: E,
    detector: ChangeDetector,
    n: usize,
    m_max: usize,
    buf: S,
    pending: bool,
    _scalar: core::marker::PhantomData<T>,
}

impl<T: Real, E: OnlineEstimator<T> + core::fmt::Debug, S: Storage<T>> core::fmt::Debug
    for EventTriggered<T, E, S>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("EventTriggered")
            .field("inner", &self.inner)
            .field("detector", &self.detector)
            .field("pending", &self.pending)
            .finish_non_exhaustive()
    }
}

/// Disjoint views of the buffer.
struct Parts<'a, T> {
    change_scales: &'a mut [T],
    normal: &'a mut [T],
    rhs: &'a mut [T],
    inv_diag: &'a mut [T],
    theta: &'a mut [T],
    residual: &'a mut [T],
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> EventTriggered<T, E, S> {
    /// Wraps `inner` with a detector of `config`. `change_scales` (`n` positive values, the
    /// estimate's units) are the typical sizes `s_j` of a change of each parameter. Caller
    /// storage of at least `n² + 4 n + m_max` scalars
    /// ([`checked_event_triggered_buffer_len`]).
    ///
    /// # Errors
    /// A bad configuration, a short buffer, or scales that are not `n` positive finite values.
    pub fn with_storage(
        inner: E,
        change_scales: &[T],
        config: DetectorConfig,
        mut buf: S,
    ) -> Result<Self, ConfigError> {
        let detector = ChangeDetector::new(config)?;
        let (n, m_max) = (inner.dim(), inner.capacity());
        let needed = checked_event_triggered_buffer_len(n, m_max)
            .ok_or(ConfigError::TooLarge { n, m: m_max })?;
        let found = buf.as_ref().len();
        if found < needed {
            return Err(ConfigError::BufferTooSmall { needed, found });
        }
        if change_scales.len() != n {
            return Err(ConfigError::BufferTooSmall {
                needed: n,
                found: change_scales.len(),
            });
        }
        if let Some(s) = change_scales
            .iter()
            .find(|s| !(**s > T::zero() && s.is_finite()))
        {
            return Err(ConfigError::InvalidParameter {
                name: "change scale",
                value: s.as_f64(),
                reason: "every scale must be positive and finite",
            });
        }
        buf.as_mut().fill(T::zero());
        let mut e = Self {
            inner,
            detector,
            n,
            m_max,
            buf,
            pending: false,
            _scalar: core::marker::PhantomData,
        };
        Self::parts(&mut e.buf, n, m_max)
            .change_scales
            .copy_from_slice(change_scales);
        Ok(e)
    }

    fn parts(buf: &mut S, n: usize, m_max: usize) -> Parts<'_, T> {
        let (change_scales, rest) = buf.as_mut().split_at_mut(n);
        let (normal, rest) = rest.split_at_mut(n * n);
        let (rhs, rest) = rest.split_at_mut(n);
        let (inv_diag, rest) = rest.split_at_mut(n);
        let (theta, rest) = rest.split_at_mut(n);
        Parts {
            change_scales,
            normal,
            rhs,
            inv_diag,
            theta,
            residual: &mut rest[..m_max],
        }
    }

    /// Replaces the detector (for example by one with known noise,
    /// [`ChangeDetector::with_known_noise`]); its channels must match the rows' layout.
    pub fn with_detector(mut self, detector: ChangeDetector) -> Self {
        self.detector = detector;
        self
    }

    /// The wrapped estimator.
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// The wrapped estimator, mutably (to feed it windows the caller weights itself).
    pub fn inner_mut(&mut self) -> &mut E {
        &mut self.inner
    }

    /// The detector.
    pub fn detector(&self) -> &ChangeDetector {
        &self.detector
    }

    /// Whether an alarm awaits its fresh window.
    pub fn is_pending(&self) -> bool {
        self.pending
    }

    /// Checks rows `(a, b)` (weights as in [`ChangeDetector::check`]) against the current
    /// estimate without updating it. On an alarm the estimator is restarted at its estimate
    /// and the next [`first_estimate`](Self::first_estimate) is awaited.
    ///
    /// # Errors
    /// The window's errors ([`validate_window`](crate::validate_window)), or the estimator's
    /// refusal to restart.
    pub fn check(
        &mut self,
        a: &[T],
        b: &[T],
        weights: Option<&[T]>,
    ) -> Result<Check, EstimatorError> {
        let (n, m_max) = (self.n, self.m_max);
        let m = crate::validate_window(n, m_max, a, b)?;
        let p = Self::parts(&mut self.buf, n, m_max);
        let x = self.inner.estimate();
        for i in 0..m {
            p.residual[i] = b[i] - linalg::dot(&a[i * n..(i + 1) * n], x);
        }
        let residual = &p.residual[..m];
        let check = self
            .detector
            .check_rows(residual.iter().enumerate().map(|(i, r)| {
                let used = weights.is_none_or(|w| w.get(i).is_some_and(|w| *w > T::zero()));
                (r.as_f64(), used)
            }));
        if check.alarm {
            p.theta.copy_from_slice(self.inner.estimate());
            self.inner.reset(p.theta)?;
            self.pending = true;
        }
        Ok(check)
    }

    /// The first post-event estimate from one fresh window `(a, b)` (weights as in
    /// [`ChangeDetector::check`]): `θ̂ + δ` with `δ` the change that best explains its prior
    /// residual under the measured row noise and the prior change scales (see the
    /// [module docs](self)). The estimator is reset to it; the caller then feeds the window
    /// as usual. Clears the pending alarm.
    ///
    /// # Errors
    /// The window's errors, or a normal matrix that is not positive definite (the estimate
    /// then stays as it was).
    pub fn first_estimate(
        &mut self,
        a: &[T],
        b: &[T],
        weights: Option<&[T]>,
    ) -> Result<(), EstimatorError> {
        let (n, m_max) = (self.n, self.m_max);
        let m = crate::validate_window(n, m_max, a, b)?;
        let channels = self.detector.config.channels;
        let ms = self.detector.mean_square;
        let p = Self::parts(&mut self.buf, n, m_max);
        let x = self.inner.estimate();
        p.normal.fill(T::zero());
        p.rhs.fill(T::zero());
        for i in 0..m {
            let w = weights.map_or(T::one(), |w| w[i]);
            let var = ms[i % channels];
            if w.is_nan() || w <= T::zero() || var.is_nan() || var <= 0.0 {
                continue;
            }
            let wi = w / T::cast(var);
            let row = &a[i * n..(i + 1) * n];
            let r = b[i] - linalg::dot(row, x);
            for j in 0..n {
                let aj = wi * row[j];
                for (k, ak) in row[..=j].iter().enumerate() {
                    p.normal[j * n + k] += aj * *ak;
                }
                p.rhs[j] += aj * r;
            }
        }
        for j in 0..n {
            let s = p.change_scales[j];
            p.normal[j * n + j] += T::one() / (s * s);
        }
        linalg::cholesky_in_place(p.normal, n)
            .map_err(|_| EstimatorError::NumericalFailure("first estimate: normal matrix"))?;
        linalg::reciprocal_diagonal(p.normal, n, p.inv_diag);
        linalg::cholesky_solve_in_place(p.normal, n, p.inv_diag, p.rhs);
        for ((t, xj), dj) in p.theta.iter_mut().zip(x).zip(p.rhs.iter()) {
            *t = *xj + *dj;
        }
        if !p.theta.iter().all(|v| v.is_finite()) {
            return Err(EstimatorError::Diverged);
        }
        self.inner.reset(p.theta)?;
        self.pending = false;
        Ok(())
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, E: OnlineEstimator<T>> EventTriggered<T, E, alloc::vec::Vec<T>> {
    /// [`EventTriggered::with_storage`] with its buffer on the heap (allocated once, here).
    ///
    /// # Errors
    /// As [`EventTriggered::with_storage`].
    pub fn new(inner: E, change_scales: &[T], config: DetectorConfig) -> Result<Self, ConfigError> {
        let (n, m) = (inner.dim(), inner.capacity());
        let len = checked_event_triggered_buffer_len(n, m).ok_or(ConfigError::TooLarge { n, m })?;
        let buf = crate::kaczmarz::zeroed_buffer(len, n, m)?;
        Self::with_storage(inner, change_scales, config, buf)
    }
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> OnlineEstimator<T> for EventTriggered<T, E, S> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn dim(&self) -> usize {
        self.n
    }

    fn capacity(&self) -> usize {
        self.m_max
    }

    fn estimate(&self) -> &[T] {
        self.inner.estimate()
    }

    /// A fresh window after an alarm: [`first_estimate`](Self::first_estimate), then the
    /// estimator's update. Otherwise: [`check`](Self::check); a window that alarms is dropped
    /// (it may mix the parameters before and after), any other goes to the estimator.
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        if self.pending {
            self.first_estimate(a, b, None)?;
            return self.inner.update(a, b);
        }
        let check = self.check(a, b, None)?;
        if check.alarm {
            return Ok(UpdateInfo {
                rows: b.len(),
                iterations: 0,
                prior_residual_norm: f64::NAN,
                converged: false,
            });
        }
        self.inner.update(a, b)
    }

    /// Resets the estimator; the detector keeps its measured noise, and a pending alarm is
    /// dropped.
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        self.inner.reset(estimate)?;
        self.pending = false;
        Ok(())
    }

    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        self.inner.set_tolerance(tolerance)
    }
}
