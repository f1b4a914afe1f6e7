//! A layer that keeps learning on stationary data: the least-squares solution of every window
//! since the last reset, anchored to a fast estimator's estimate.
//!
//! # Why
//! A Kaczmarz estimator projects onto the newest window only. On a stream of noisy windows of
//! constant parameters its error stops falling after a transient: it keeps about one window's
//! worth of noise. Behind a noise-aware stop it stops moving at all once the residual is at the
//! noise floor. Batch least squares on all the windows keeps averaging the noise down as `1/√k`.
//!
//! # What it does
//! [`Accumulate`] wraps any [`OnlineEstimator`] (the fast one, e.g. TAG-K). Each window is fed to
//! it unchanged. Beside it, the layer adds the window's information `Aᵀ A` and `Aᵀ b` to running
//! sums `Λ`, `η` since the last [`reset`](OnlineEstimator::reset). It reports
//!
//! ```text
//! θ̄ = argmin Σ_k ‖b_k − A_k θ‖² + ‖θ − θ_fast‖²_R   ⇔   (Λ + R) θ̄ = η + R θ_fast
//! ```
//!
//! with `R = diag(ρ_j)`, `ρ_j = max(w Λ_jj / k, r₀)` after `k` windows: in every parameter, the fast
//! estimate counts as `w` windows' worth of that parameter's average information
//! ([`AccumulateConfig::anchor_windows`]). Per parameter, so a weakly excited one is weighed
//! against its own information, not the strong ones'. After `k` windows the anchor's share is
//! about `w / k`: `θ̄` becomes batch least squares. Early on, and along directions no window
//! has excited yet, it stays near the fast estimate. The floor `r₀`
//! ([`AccumulateConfig::anchor_precision`]) is the fast estimate's own precision: a direction
//! joins the least squares only once the data carry more information in it.
//!
//! A reset (for example a [`FrontEnd`](crate::FrontEnd)'s restart at an event) clears the sums.
//! For the next [`settle_windows`](AccumulateConfig::settle_windows) windows the layer reports
//! the fast estimate as it is, so the fast estimator's quick reaction to an event is kept; the
//! sums start after that transient. The layer never sees an event by
//! itself: put it inside a front end with event detection, or behind
//! [`EventTriggered`](crate::EventTriggered).
//!
//! The layer does not change the wrapped estimator's updates: they are bit for bit those it
//! makes alone. Cost per window: `m n (n + 1) / 2` multiply-adds for the sums, `n³/6` for one
//! Cholesky factorisation and `2 n²` for the solves, in the portable order (same bits on every
//! machine). Storage: [`accumulate_buffer_len`] scalars, no allocation.

use crate::kaczmarz::Storage;
use crate::{ConfigError, EstimatorError, OnlineEstimator, Real, UpdateInfo, linalg};

/// Length of the buffer an [`Accumulate`] of dimension `n` needs: `2 n² + 4 n` scalars (the
/// sums `Λ` and `η`, the factor, the reported estimate and solve scratch). `None` on overflow.
pub const fn checked_accumulate_buffer_len(n: usize) -> Option<usize> {
    let Some(n2) = n.checked_mul(n) else {
        return None;
    };
    let Some(two_n2) = n2.checked_mul(2) else {
        return None;
    };
    let Some(four_n) = n.checked_mul(4) else {
        return None;
    };
    two_n2.checked_add(four_n)
}

/// [`checked_accumulate_buffer_len`], saturating at `usize::MAX` (such sizes are refused).
pub const fn accumulate_buffer_len(n: usize) -> usize {
    match checked_accumulate_buffer_len(n) {
        Some(len) => len,
        None => usize::MAX,
    }
}

/// Settings of [`Accumulate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccumulateConfig {
    /// `w`: how many windows' worth of average information the fast estimate counts as, per
    /// parameter (`ρ_j = w Λ_jj / k`). Positive. 1 (the default): after `k` windows the
    /// fast estimate weighs about `1 / k` of the answer.
    pub anchor_windows: f64,
    /// `r₀`: the least anchor precision, in every parameter (units of `b²` per unit of the
    /// parameters the layer sees squared; non-negative; default 0). With `σ` the rows' noise
    /// and `s` how far the fast estimate may typically be off, `r₀ = σ² / s²`. It keeps the
    /// directions a few windows barely excite at the fast estimate, where one window's least
    /// squares would fit model errors and noise. After many windows the data outweigh it
    /// wherever they carry more information than `r₀`.
    pub anchor_precision: f64,
    /// Windows after a reset that only the fast estimator sees (the transient): the layer
    /// reports its estimate and starts summing from the next window on (default 5). Right
    /// after an event the fast estimator's own first estimates are the better ones; a few
    /// windows' least squares are not yet.
    pub settle_windows: usize,
}

impl Default for AccumulateConfig {
    fn default() -> Self {
        Self {
            anchor_windows: 1.0,
            anchor_precision: 0.0,
            settle_windows: 5,
        }
    }
}

impl AccumulateConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ConfigError::InvalidParameter`] for an anchor weight that is not positive and finite.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(self.anchor_windows > 0.0 && self.anchor_windows.is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "anchor_windows",
                value: self.anchor_windows,
                reason: "must be positive and finite",
            });
        }
        if !(self.anchor_precision >= 0.0 && self.anchor_precision.is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "anchor_precision",
                value: self.anchor_precision,
                reason: "must be non-negative and finite",
            });
        }
        Ok(())
    }
}

/// An [`OnlineEstimator`] that reports the anchored least-squares solution of every window
/// since its last reset (see the [module docs](self)).
///
/// # Examples
///
/// TAG-K alone keeps about one window's noise. The same TAG-K inside the layer reaches the
/// batch least-squares error, here computed by hand from the normal equations.
///
/// ```
/// use tagk_core::{Accumulate, AccumulateConfig, KaczmarzConfig, OnlineEstimator, TagK};
///
/// let theta = [1.0, -2.0];
/// // Rows (cos φ, sin φ), measurement noise ±0.01 from a fixed pattern.
/// let mut tagk = TagK::<f64, Vec<f64>>::new(2, 4, KaczmarzConfig::default())?;
/// let inner = TagK::<f64, Vec<f64>>::new(2, 4, KaczmarzConfig::default())?;
/// let mut learn = Accumulate::new(inner, AccumulateConfig::default())?;
/// let (mut ata, mut atb) = ([0.0; 4], [0.0; 2]);
/// for w in 0..500 {
///     let (mut a, mut b) = (Vec::new(), Vec::new());
///     for k in 0..4 {
///         let phi = 0.9 * (4 * w + k) as f64;
///         let noise = 0.01 * (2.3 * (4 * w + k) as f64).sin().signum();
///         a.extend([phi.cos(), phi.sin()]);
///         b.push(phi.cos() * theta[0] + phi.sin() * theta[1] + noise);
///         ata[0] += phi.cos() * phi.cos();
///         ata[1] += phi.cos() * phi.sin();
///         ata[3] += phi.sin() * phi.sin();
///         atb[0] += phi.cos() * b[k];
///         atb[1] += phi.sin() * b[k];
///     }
///     tagk.update(&a, &b)?;
///     learn.update(&a, &b)?;
/// }
/// let det = ata[0] * ata[3] - ata[1] * ata[1];
/// let ls = [(ata[3] * atb[0] - ata[1] * atb[1]) / det, (ata[0] * atb[1] - ata[1] * atb[0]) / det];
/// let err = |x: &[f64]| ((x[0] - theta[0]).powi(2) + (x[1] - theta[1]).powi(2)).sqrt();
/// assert!(err(learn.estimate()) < 1.1 * err(&ls) + 1e-6);
/// assert!(err(tagk.estimate()) > 5.0 * err(learn.estimate()));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Accumulate<T: Real, E: OnlineEstimator<T>, S: Storage<T>> {
    inner: E,
    config: AccumulateConfig,
    n: usize,
    buf: S,
    /// Windows in the sums since the last reset.
    windows: usize,
    /// Windows seen since the last reset (summed or not).
    seen: usize,
    _scalar: core::marker::PhantomData<T>,
}

impl<T: Real, E: OnlineEstimator<T> + core::fmt::Debug, S: Storage<T>> core::fmt::Debug
    for Accumulate<T, E, S>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Accumulate")
            .field("inner", &self.inner)
            .field("config", &self.config)
            .field("windows", &self.windows)
            .finish_non_exhaustive()
    }
}

/// Disjoint views of the buffer.
struct Parts<'a, T> {
    lambda: &'a mut [T],
    eta: &'a mut [T],
    factor: &'a mut [T],
    estimate: &'a mut [T],
    rhs: &'a mut [T],
    inv_diag: &'a mut [T],
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> Accumulate<T, E, S> {
    /// Wraps `inner` in caller storage of at least [`accumulate_buffer_len`]`(n)` scalars. The
    /// estimate starts as `inner`'s.
    ///
    /// # Errors
    /// A bad configuration or a buffer that is too short.
    pub fn with_storage(
        inner: E,
        config: AccumulateConfig,
        mut buf: S,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let n = inner.dim();
        let needed = checked_accumulate_buffer_len(n).ok_or(ConfigError::TooLarge {
            n,
            m: inner.capacity(),
        })?;
        let found = buf.as_ref().len();
        if found < needed {
            return Err(ConfigError::BufferTooSmall { needed, found });
        }
        buf.as_mut().fill(T::zero());
        let mut acc = Self {
            inner,
            config,
            n,
            buf,
            windows: 0,
            seen: 0,
            _scalar: core::marker::PhantomData,
        };
        acc.clear();
        Ok(acc)
    }

    fn parts(buf: &mut S, n: usize) -> Parts<'_, T> {
        let (lambda, rest) = buf.as_mut().split_at_mut(n * n);
        let (factor, rest) = rest.split_at_mut(n * n);
        let (eta, rest) = rest.split_at_mut(n);
        let (estimate, rest) = rest.split_at_mut(n);
        let (rhs, rest) = rest.split_at_mut(n);
        Parts {
            lambda,
            eta,
            factor,
            estimate,
            rhs,
            inv_diag: &mut rest[..n],
        }
    }

    /// Empties the sums; the estimate becomes the wrapped estimator's.
    fn clear(&mut self) {
        self.windows = 0;
        self.seen = 0;
        let p = Self::parts(&mut self.buf, self.n);
        p.lambda.fill(T::zero());
        p.eta.fill(T::zero());
        p.estimate.copy_from_slice(self.inner.estimate());
    }

    /// The wrapped (fast) estimator; its estimate is the anchor `θ_fast`.
    pub fn inner(&self) -> &E {
        &self.inner
    }

    /// Windows in the sums since the last reset.
    pub fn windows(&self) -> usize {
        self.windows
    }

    /// The configuration.
    pub fn config(&self) -> &AccumulateConfig {
        &self.config
    }

    /// Solves `(Λ + R) θ̄ = η + R θ_fast` into the estimate. A failed factorisation (sums
    /// that overflowed) reports the fast estimate instead.
    fn solve(&mut self) {
        let n = self.n;
        let p = Self::parts(&mut self.buf, n);
        let x = self.inner.estimate();
        let mut trace = T::zero();
        for j in 0..n {
            trace += p.lambda[j * n + j];
        }
        let k = T::cast(self.windows.max(1) as f64);
        let w = T::cast(self.config.anchor_windows);
        let r0 = T::cast(self.config.anchor_precision);
        // A coordinate the data never reached keeps a tiny anchor, so the system stays definite.
        let floor = T::cast(1e-12) * trace / T::cast(n as f64);
        if !(floor > T::zero() && floor.is_finite()) {
            p.estimate.copy_from_slice(x);
            return;
        }
        p.factor.copy_from_slice(p.lambda);
        for (j, xj) in x.iter().enumerate() {
            let rho = (w * p.lambda[j * n + j].max(floor) / k).max(r0);
            p.factor[j * n + j] += rho;
            p.rhs[j] = p.eta[j] + rho * *xj;
        }
        if linalg::cholesky_in_place(p.factor, n).is_err() {
            p.estimate.copy_from_slice(x);
            return;
        }
        linalg::reciprocal_diagonal(p.factor, n, p.inv_diag);
        linalg::cholesky_solve_in_place(p.factor, n, p.inv_diag, p.rhs);
        if p.rhs.iter().all(|v| v.is_finite()) {
            p.estimate.copy_from_slice(p.rhs);
        } else {
            p.estimate.copy_from_slice(x);
        }
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, E: OnlineEstimator<T>> Accumulate<T, E, alloc::vec::Vec<T>> {
    /// [`Accumulate::with_storage`] with its buffer on the heap (allocated once, here).
    ///
    /// # Errors
    /// As [`Accumulate::with_storage`]; [`ConfigError::TooLarge`] when the allocation is refused.
    pub fn new(inner: E, config: AccumulateConfig) -> Result<Self, ConfigError> {
        let (n, m) = (inner.dim(), inner.capacity());
        let len = checked_accumulate_buffer_len(n).ok_or(ConfigError::TooLarge { n, m })?;
        let buf = crate::kaczmarz::zeroed_buffer(len, n, m)?;
        Self::with_storage(inner, config, buf)
    }
}

impl<T: Real, E: OnlineEstimator<T>, S: Storage<T>> OnlineEstimator<T> for Accumulate<T, E, S> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn dim(&self) -> usize {
        self.n
    }

    fn capacity(&self) -> usize {
        self.inner.capacity()
    }

    /// `θ̄`, the anchored least-squares solution of the windows since the last reset.
    fn estimate(&self) -> &[T] {
        let n = self.n;
        &self.buf.as_ref()[2 * n * n + n..2 * n * n + 2 * n]
    }

    /// Feeds the window to the wrapped estimator, then (after the settling windows) adds it to
    /// the sums and solves. A window the wrapped estimator refuses changes nothing.
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        let info = self.inner.update(a, b)?;
        self.seen += 1;
        if self.seen <= self.config.settle_windows {
            let n = self.n;
            let x = self.inner.estimate();
            Self::parts(&mut self.buf, n).estimate.copy_from_slice(x);
            return Ok(info);
        }
        let n = self.n;
        let p = Self::parts(&mut self.buf, n);
        for (row, bi) in a.chunks_exact(n).zip(b) {
            for i in 0..n {
                let ai = row[i];
                if ai == T::zero() {
                    continue;
                }
                for (j, aj) in row[..=i].iter().enumerate() {
                    p.lambda[i * n + j] += ai * *aj;
                }
                p.eta[i] += ai * *bi;
            }
        }
        // Mirror the lower triangle (the factorisation reads the lower one; keep Λ whole).
        for i in 0..n {
            for j in 0..i {
                p.lambda[j * n + i] = p.lambda[i * n + j];
            }
        }
        self.windows += 1;
        self.solve();
        Ok(info)
    }

    /// Resets the wrapped estimator to `estimate` and empties the sums.
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        self.inner.reset(estimate)?;
        self.clear();
        Ok(())
    }

    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        self.inner.set_tolerance(tolerance)
    }
}
