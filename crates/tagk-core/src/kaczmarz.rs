//! The Kaczmarz family: RK, TARK, GRK and TAG-K, one kernel behind four names.
//!
//! Every variant projects the current iterate onto the hyperplane of one window row,
//! `x ← x + (b_i − a_iᵀx)/‖a_i‖² · a_i`, and differs only in how the row is chosen and what is
//! reported:
//!
//! | type | row selection | estimate |
//! |---|---|---|
//! | [`RandomizedKaczmarz`] (RK) | `i` with probability `‖a_i‖²/‖A‖_F²` (Strohmer & Vershynin) | last iterate |
//! | [`TailAveragedKaczmarz`] (TARK) | as RK | average of the iterates after the burn-in |
//! | [`GreedyKaczmarz`] (GRK) | Bai & Wu's greedy rule (below) | last iterate |
//! | [`TagK`] (TAG-K) | as GRK | average of the iterates after the burn-in |
//!
//! **Greedy rule** (Bai & Wu 2018, with `r = b − A x`):
//! `ε = ½ (max_i (r_i²/‖a_i‖²)/‖r‖² + 1/‖A‖_F²)`, candidates `U = {i : r_i² ≥ ε ‖r‖² ‖a_i‖²}`,
//! and `i ∈ U` drawn with probability `r_i² / Σ_{j∈U} r_j²`. (The TAG-K paper writes the test
//! without squares; the squared form is the dimensionally consistent one used here.)
//!
//! **Tail averaging.** With `T` iterations and burn-in `t_b`, the estimate is
//! `x̄ = (1/(T − t_b)) Σ_{t=t_b+1}^{T} x_t`. When an update stops early at `t' < T` because
//! `‖r‖ ≤ tolerance`, the remaining iterates equal `x_{t'}` and the average is taken as if
//! they had been run. Every variant warm-starts each window from its previous estimate
//! (the averaged one for TARK and TAG-K).
//!
//! # Cost per update (window `m × n`, `T` iterations)
//! The iterate is kept as `x = x₀ + Aᵀc`, so a projection only changes one coefficient `c_i`
//! and the tail average only needs averaged coefficients `c̄` (O(1) per iteration).
//! - Setup, all variants: one pass over `A` for `‖a_i‖²` and `r = b − A x₀`: `2mn` flops.
//! - Greedy variants: the residual is updated incrementally, `r ← r − α G e_i`, through the
//!   Gram matrix `G = A Aᵀ`, built once per window from its upper triangle with register-tiled
//!   kernels (`m(m+1)/2` dot products of length `n`, i.e. `m²n` flops), plus `O(m)` branch-free
//!   work per iteration for selection and the residual update. No residual is ever recomputed
//!   from `A`. (Computing Gram columns lazily, only for the rows chosen, was measured and
//!   rejected: greedy selection visits about half of the rows at `n = 10` and 80 % at
//!   `n = 120` in a window of 30, and one-at-a-time dot products are latency-bound.)
//! - Randomised variants: `2n` flops per iteration (a dot product and an update of `x`), the
//!   row drawn by binary search over cumulative row norms.
//! - Finish: `x̄ = x₀ + Aᵀc̄` (or `x₀ + Aᵀc`): `2mn` flops.
//!
//! The update never allocates: every buffer is laid out at construction in storage the
//! caller chooses (a `Vec`, an array, or a `&mut [T]` in static memory on a microcontroller).

use core::marker::PhantomData;

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};

use crate::estimator::{check_window_finite, check_window_shape, validate_estimate};
use crate::linalg::{axpy, dot, norm2_and_dot, padded};
#[cfg(not(target_arch = "x86_64"))]
use crate::linalg::{gram_rows, residual_rows};
#[cfg(target_arch = "x86_64")]
use crate::linalg::{gram_transposed, residual_transposed, transpose_padded};
use crate::{ConfigError, EstimatorError, OnlineEstimator, Real, UpdateInfo};

/// How many projections an update performs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Iterations {
    /// `T = m`, one pass's worth for the window at hand (the TAG-K paper's choice).
    #[default]
    OnePass,
    /// A fixed `T`, whatever the window size.
    Fixed(usize),
}

/// How many leading iterates the tail average skips (ignored by RK and GRK).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BurnIn {
    /// `t_b = ⌊f · T⌋` for a fraction `f ∈ [0, 1)`.
    Fraction(f64),
    /// A fixed `t_b`. If a window's `T` is not larger (a short window with
    /// [`Iterations::OnePass`]), `t_b = T − 1`: only the last iterate is averaged.
    Fixed(usize),
}

impl Default for BurnIn {
    fn default() -> Self {
        BurnIn::Fraction(0.5)
    }
}

/// Configuration shared by the Kaczmarz family, validated by every constructor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KaczmarzConfig {
    /// Projections per window (default: one pass, `T = m`).
    pub iterations: Iterations,
    /// Burn-in before tail averaging (default: half of the iterations).
    pub burn_in: BurnIn,
    /// Stop a window's iterations once `‖b − A x‖₂ ≤ tolerance` (measurement units; default
    /// `0`, which stops only on an exact fit). The greedy variants check every iteration at no
    /// extra cost; the randomised ones, which do not track the residual, check at the start
    /// and then once every `m` iterations (a full residual costs `mn`).
    pub tolerance: f64,
    /// Seed of the ChaCha8 generator behind every random choice.
    pub seed: u64,
}

impl Default for KaczmarzConfig {
    fn default() -> Self {
        Self {
            iterations: Iterations::OnePass,
            burn_in: BurnIn::default(),
            tolerance: 0.0,
            seed: 0,
        }
    }
}

impl KaczmarzConfig {
    /// Sets the iteration count.
    pub fn with_iterations(mut self, iterations: Iterations) -> Self {
        self.iterations = iterations;
        self
    }
    /// Sets the burn-in.
    pub fn with_burn_in(mut self, burn_in: BurnIn) -> Self {
        self.burn_in = burn_in;
        self
    }
    /// Sets the residual tolerance.
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }
    /// Sets the seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Checks every setting; called by the constructors.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if let Iterations::Fixed(0) = self.iterations {
            return Err(ConfigError::ZeroIterations);
        }
        match self.burn_in {
            BurnIn::Fraction(f) if !(0.0..1.0).contains(&f) => {
                return Err(ConfigError::InvalidParameter {
                    name: "burn_in",
                    value: f,
                    reason: "a burn-in fraction must lie in [0, 1)",
                });
            }
            BurnIn::Fixed(t_b) => {
                if let Iterations::Fixed(t) = self.iterations
                    && t_b >= t
                {
                    return Err(ConfigError::BurnInTooLarge {
                        burn_in: t_b,
                        iterations: t,
                    });
                }
            }
            _ => {}
        }
        if !(self.tolerance >= 0.0 && self.tolerance.is_finite()) {
            return Err(ConfigError::InvalidParameter {
                name: "tolerance",
                value: self.tolerance,
                reason: "the tolerance must be finite and non-negative",
            });
        }
        Ok(())
    }

    /// `(T, t_b)` for a window of `m` rows.
    fn schedule(&self, m: usize) -> (usize, usize) {
        let t = match self.iterations {
            Iterations::OnePass => m,
            Iterations::Fixed(t) => t,
        };
        let t_b = match self.burn_in {
            BurnIn::Fraction(f) => (f * t as f64) as usize,
            BurnIn::Fixed(t_b) => t_b,
        };
        (t, t_b.min(t - 1))
    }
}

/// Length of the buffer a Kaczmarz estimator of dimension `n` and window capacity `m_max`
/// needs: `2n + 6p + p² + p/4` scalars with `p = m_max` rounded up to a multiple of 8 (`p²`
/// holds the Gram matrix), plus `n·p` on x86-64 for a transposed copy of the window.
///
/// A `const fn`, so firmware can size a static array: `[0.0; kaczmarz_buffer_len(120, 30)]`.
pub const fn kaczmarz_buffer_len(n: usize, m_max: usize) -> usize {
    let p = padded(m_max);
    // The transposed copy of a window is only kept on x86-64 (see the Gram kernels).
    let transposed = if cfg!(target_arch = "x86_64") {
        n * p
    } else {
        0
    };
    2 * n + 6 * p + p * p + p / 4 + transposed
}

/// Storage for an estimator's buffers: anything that derefs to a mutable slice.
pub trait Storage<T>: AsRef<[T]> + AsMut<[T]> {}
impl<T, S: AsRef<[T]> + AsMut<[T]>> Storage<T> for S {}

/// The Kaczmarz kernel shared by the four variants; use the aliases [`RandomizedKaczmarz`],
/// [`TailAveragedKaczmarz`], [`GreedyKaczmarz`] and [`TagK`].
///
/// `GREEDY` selects rows by Bai & Wu's rule instead of by row norm; `AVERAGE` reports the tail
/// average instead of the last iterate. Both are resolved at compile time.
pub struct Kaczmarz<T: Real, S: Storage<T>, const GREEDY: bool, const AVERAGE: bool> {
    config: KaczmarzConfig,
    n: usize,
    m_max: usize,
    buf: S,
    rng: ChaCha8Rng,
    _scalar: PhantomData<T>,
}

/// Randomised Kaczmarz (Strohmer & Vershynin 2009): rows drawn with probability `‖a_i‖²/‖A‖_F²`.
pub type RandomizedKaczmarz<T, S> = Kaczmarz<T, S, false, false>;
/// Tail-averaged randomised Kaczmarz (TARK): RK reporting the average of the iterates after the burn-in.
pub type TailAveragedKaczmarz<T, S> = Kaczmarz<T, S, false, true>;
/// Greedy randomised Kaczmarz (GRK, Bai & Wu 2018).
pub type GreedyKaczmarz<T, S> = Kaczmarz<T, S, true, false>;
/// TAG-K: greedy row selection (GRK) plus tail averaging, warm-started from the previous average.
pub type TagK<T, S> = Kaczmarz<T, S, true, true>;

/// Disjoint views of the buffer.
struct Parts<'a, T> {
    estimate: &'a mut [T],
    work: &'a mut [T],
    norm2: &'a mut [T],
    inv_norm2: &'a mut [T],
    resid: &'a mut [T],
    coef: &'a mut [T],
    coef_avg: &'a mut [T],
    scratch: &'a mut [T],
    gram: &'a mut [T],
    transposed: &'a mut [T],
    block_sums: &'a mut [T],
}

impl<T: Real, S: Storage<T>, const GREEDY: bool, const AVERAGE: bool>
    Kaczmarz<T, S, GREEDY, AVERAGE>
{
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows, in
    /// caller-provided storage of at least [`kaczmarz_buffer_len`]`(n, m_max)` scalars.
    /// The initial estimate is zero.
    pub fn with_storage(
        n: usize,
        m_max: usize,
        config: KaczmarzConfig,
        mut buf: S,
    ) -> Result<Self, ConfigError> {
        crate::check_dimensions(n, m_max)?;
        config.validate()?;
        let needed = kaczmarz_buffer_len(n, m_max);
        let found = buf.as_ref().len();
        if found < needed {
            return Err(ConfigError::BufferTooSmall { needed, found });
        }
        buf.as_mut().fill(T::zero());
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            n,
            m_max,
            buf,
            _scalar: PhantomData,
        })
    }

    /// The configuration this estimator was built with.
    pub fn config(&self) -> &KaczmarzConfig {
        &self.config
    }

    /// The storage, handed back (for example to reuse a static buffer).
    pub fn into_storage(self) -> S {
        self.buf
    }

    fn parts(&mut self) -> Parts<'_, T> {
        let (n, m) = (self.n, padded(self.m_max));
        let rest = self.buf.as_mut();
        let (estimate, rest) = rest.split_at_mut(n);
        let (work, rest) = rest.split_at_mut(n);
        let (norm2, rest) = rest.split_at_mut(m);
        let (inv_norm2, rest) = rest.split_at_mut(m);
        let (resid, rest) = rest.split_at_mut(m);
        let (coef, rest) = rest.split_at_mut(m);
        let (coef_avg, rest) = rest.split_at_mut(m);
        let (scratch, rest) = rest.split_at_mut(m);
        let (gram, rest) = rest.split_at_mut(m * m);
        let (block_sums, rest) = rest.split_at_mut(m / 4);
        let transposed = if cfg!(target_arch = "x86_64") {
            &mut rest[..n * m]
        } else {
            &mut rest[..0]
        };
        Parts {
            estimate,
            work,
            norm2,
            inv_norm2,
            resid,
            coef,
            coef_avg,
            scratch,
            gram,
            transposed,
            block_sums,
        }
    }

    /// A uniform draw in `[0, 1)` with 53 random bits.
    #[inline]
    fn uniform(rng: &mut ChaCha8Rng) -> T {
        T::cast((rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
    }

    /// [`Self::run`] compiled for AVX2: the same operations in the same order (separate
    /// multiplies and adds, never fused), so results are bit-identical to the portable path.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    unsafe fn run_avx2(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        self.run(a, b)
    }

    #[inline(always)]
    fn run(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        let n = self.n;
        let m = check_window_shape(n, self.m_max, a, b)?;
        let (t_total, t_b) = self.config.schedule(m);
        let tol = T::cast(self.config.tolerance);
        let tol2 = tol * tol;
        // Work on a copy of the generator: it is committed only if the update succeeds.
        let mut rng = self.rng.clone();
        let p = self.parts();

        // Setup: row norms and the prior residual r = b − A x₀.
        if GREEDY {
            // The greedy variants need nearly every Gram entry anyway (they visit most rows of
            // a window), so the full matrix is built at once with a register-tiled kernel; its
            // diagonal holds the squared row norms. Two tilings of the same sums, chosen for
            // the target: an 8-wide tile over a transposed copy of A where SIMD units are wide
            // (x86-64), a 2 × 4 tile on the rows where registers are few (a Cortex-M7 FPU has
            // sixteen). Both give the same bits.
            #[cfg(target_arch = "x86_64")]
            {
                transpose_padded(a, n, m, p.transposed);
                gram_transposed(p.transposed, n, m, p.gram);
                residual_transposed(p.transposed, n, m, p.estimate, b, p.resid);
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                gram_rows(a, n, m, p.gram);
                residual_rows(a, n, m, p.estimate, b, p.resid);
            }
            for i in 0..m {
                p.norm2[i] = p.gram[i * m + i];
            }
        } else {
            for i in 0..m {
                let (nn, ax) = norm2_and_dot(&a[i * n..(i + 1) * n], p.estimate);
                p.norm2[i] = nn;
                p.resid[i] = b[i] - ax;
            }
        }
        let mut fro2 = T::zero();
        let mut rnorm2 = T::zero();
        for i in 0..m {
            let nn = p.norm2[i];
            let r = p.resid[i];
            if !(nn.is_finite() && r.is_finite()) {
                check_window_finite(n, a, b)?;
                // Finite entries whose squares overflow.
                return Err(EstimatorError::NonFiniteRegressor { row: i, col: 0 });
            }
            if nn > T::zero() {
                p.inv_norm2[i] = T::one() / nn;
                p.resid[i] = r;
                fro2 += nn;
                rnorm2 += r * r;
            } else {
                // A zero row carries no information: never chosen, never divided by.
                p.inv_norm2[i] = T::zero();
                p.resid[i] = T::zero();
            }
            p.coef[i] = T::zero();
            p.coef_avg[i] = T::zero();
        }
        if fro2 <= T::zero() {
            return Err(EstimatorError::NoUsableRow);
        }
        if !fro2.is_finite() || !rnorm2.is_finite() {
            return Err(EstimatorError::Diverged);
        }
        let prior_residual_norm = rnorm2.sqrt().as_f64();

        // Weight of a step taken at iteration s (1-based) in the tail average of x_{t_b+1..T}.
        let tail_len = T::cast((t_total - t_b) as f64);
        let weight = |s: usize| -> T {
            let first = if s > t_b { s } else { t_b + 1 };
            T::cast((t_total - first + 1) as f64) / tail_len
        };

        let mut iterations = 0;
        let mut converged = rnorm2 <= tol2;
        if GREEDY {
            let inv_fro2 = T::one() / fro2;
            let half = T::cast(0.5);
            let mut max_ratio = residual_stats(&p.resid[..m], &p.inv_norm2[..m]).1;
            while !converged && iterations < t_total {
                iterations += 1;
                // Bai & Wu: candidates satisfy r_j² ≥ ε‖r‖²‖a_j‖² with
                // ε‖r‖² = ½ (max_j r_j²/‖a_j‖² + ‖r‖²/‖A‖_F²): no division needed.
                let threshold = half * (max_ratio + rnorm2 * inv_fro2);
                let total = candidate_weights(
                    &p.resid[..m],
                    &p.norm2[..m],
                    threshold,
                    &mut p.scratch[..m],
                    &mut p.block_sums[..m.div_ceil(4)],
                );
                let i = if total > T::zero() {
                    let target = Self::uniform(&mut rng) * total;
                    sample_blocks(&p.scratch[..m], &p.block_sums[..m.div_ceil(4)], target)
                } else {
                    // Round-off emptied the candidate set; the largest ratio always qualifies.
                    argmax_ratio(&p.resid[..m], &p.inv_norm2[..m])
                };
                let alpha = p.resid[i] * p.inv_norm2[i];
                p.coef[i] += alpha;
                if AVERAGE {
                    p.coef_avg[i] += alpha * weight(iterations);
                }
                // r ← r − α A a_i = r − α G e_i; the projection zeroes r_i exactly.
                (rnorm2, max_ratio) = project_residual(
                    &mut p.resid[..m],
                    &p.gram[i * m..(i + 1) * m],
                    &p.inv_norm2[..m],
                    alpha,
                    i,
                );
                converged = rnorm2 <= tol2;
            }
        } else {
            // Cumulative row norms for sampling i ∝ ‖a_i‖².
            let mut cum = T::zero();
            for i in 0..m {
                cum += p.norm2[i];
                p.scratch[i] = cum;
            }
            p.work.copy_from_slice(p.estimate);
            let check_every = m;
            while !converged && iterations < t_total {
                if iterations > 0 && tol > T::zero() && iterations % check_every == 0 {
                    rnorm2 = T::zero();
                    for i in 0..m {
                        if p.norm2[i] > T::zero() {
                            let r = b[i] - dot(&a[i * n..(i + 1) * n], p.work);
                            rnorm2 += r * r;
                        }
                    }
                    if rnorm2 <= tol2 {
                        converged = true;
                        break;
                    }
                }
                iterations += 1;
                let target = Self::uniform(&mut rng) * cum;
                let i = sample_cumulative(&p.scratch[..m], p.norm2, target);
                let row = &a[i * n..(i + 1) * n];
                let alpha = (b[i] - dot(row, p.work)) * p.inv_norm2[i];
                axpy(alpha, row, p.work);
                p.coef[i] += alpha;
                if AVERAGE {
                    p.coef_avg[i] += alpha * weight(iterations);
                }
            }
        }

        // Finish: x = x₀ + Aᵀc (last iterate) or x̄ = x₀ + Aᵀc̄ (tail average), into `work`.
        if GREEDY || AVERAGE {
            let coef: &[T] = if AVERAGE { p.coef_avg } else { p.coef };
            p.work.copy_from_slice(p.estimate);
            for i in 0..m {
                if coef[i] != T::zero() {
                    axpy(coef[i], &a[i * n..(i + 1) * n], p.work);
                }
            }
        }
        if p.work.iter().any(|v| !v.is_finite()) {
            return Err(EstimatorError::Diverged);
        }
        p.estimate.copy_from_slice(p.work);
        self.rng = rng;
        Ok(UpdateInfo {
            rows: m,
            iterations,
            prior_residual_norm,
            converged,
        })
    }
}

/// `(Σ r_j², max_j r_j²/‖a_j‖²)` with four partial sums (`1/‖a_j‖²` precomputed, zero for
/// zero rows).
#[inline(always)]
fn residual_stats<T: Real>(r: &[T], inv_norm2: &[T]) -> (T, T) {
    let len = r.len();
    let inv_norm2 = &inv_norm2[..len];
    let full = len - len % 4;
    let mut sum = [T::zero(); 4];
    let mut best = [T::zero(); 4];
    let mut j = 0;
    while j < full {
        for l in 0..4 {
            let r2 = r[j + l] * r[j + l];
            sum[l] += r2;
            let v = r2 * inv_norm2[j + l];
            best[l] = if v > best[l] { v } else { best[l] };
        }
        j += 4;
    }
    let mut s = (sum[0] + sum[2]) + (sum[1] + sum[3]);
    let mut m = best[0].max(best[1]).max(best[2].max(best[3]));
    for j in full..len {
        let r2 = r[j] * r[j];
        s += r2;
        m = m.max(r2 * inv_norm2[j]);
    }
    (s, m)
}

/// `r ← r − α g` with `r_i` set to exactly zero, returning the new
/// `(Σ r_j², max_j r_j²/‖a_j‖²)` from the same pass.
#[inline(always)]
fn project_residual<T: Real>(r: &mut [T], g: &[T], inv_norm2: &[T], alpha: T, i: usize) -> (T, T) {
    let g = &g[..r.len()];
    for j in 0..r.len() {
        r[j] -= alpha * g[j];
    }
    r[i] = T::zero();
    residual_stats(r, inv_norm2)
}

/// Candidate weights `w_j = r_j²` where `r_j² ≥ threshold·‖a_j‖²`, else 0, into `w`; sums of
/// each block of four into `block_sums`; returns the total (the sum of the block sums, in order).
#[inline(always)]
fn candidate_weights<T: Real>(
    r: &[T],
    norm2: &[T],
    threshold: T,
    w: &mut [T],
    block_sums: &mut [T],
) -> T {
    let len = w.len();
    let (r, norm2) = (&r[..len], &norm2[..len]);
    for j in 0..len {
        let r2 = r[j] * r[j];
        w[j] = if r2 >= threshold * norm2[j] {
            r2
        } else {
            T::zero()
        };
    }
    let mut total = T::zero();
    for (b, bs) in block_sums.iter_mut().enumerate() {
        let end = (4 * b + 4).min(len);
        let mut s = T::zero();
        for v in &w[4 * b..end] {
            s += *v;
        }
        *bs = s;
        total += s;
    }
    total
}

/// Draws index `j` with probability `w_j / Σ w`: finds the block whose running sum passes
/// `target`, then the entry inside it. Only entries of positive weight can be returned.
#[inline(always)]
fn sample_blocks<T: Real>(w: &[T], block_sums: &[T], target: T) -> usize {
    let mut acc = T::zero();
    let last_block = block_sums.len() - 1;
    let mut b = 0;
    while b < last_block && acc + block_sums[b] <= target {
        acc += block_sums[b];
        b += 1;
    }
    // Inside the block: the first entry whose running sum passes the target; if round-off
    // keeps every running sum at or below it, the last entry of positive weight.
    let start = 4 * b;
    let end = (start + 4).min(w.len());
    let mut chosen = None;
    for (j, &wj) in w.iter().enumerate().take(end).skip(start) {
        if wj > T::zero() {
            chosen = Some(j);
            acc += wj;
            if acc > target {
                break;
            }
        }
    }
    match chosen {
        Some(j) => j,
        // An empty last block cannot be reached unless round-off pushed the target past every
        // block: take the last entry of positive weight anywhere.
        None => w.iter().rposition(|v| *v > T::zero()).unwrap_or(0),
    }
}

/// The index of the largest `r_j²/‖a_j‖²` (the first, on ties).
fn argmax_ratio<T: Real>(r: &[T], inv_norm2: &[T]) -> usize {
    let mut best = T::zero();
    let mut arg = 0;
    for (j, (p, q)) in r.iter().zip(inv_norm2).enumerate() {
        let v = *p * *p * *q;
        if v > best {
            best = v;
            arg = j;
        }
    }
    arg
}

/// Index `i` with `cum[i-1] ≤ target < cum[i]` among rows of positive weight.
#[inline]
fn sample_cumulative<T: Real>(cum: &[T], norm2: &[T], target: T) -> usize {
    let i = cum.partition_point(|&c| c <= target);
    let mut i = i.min(cum.len() - 1);
    // Guard against landing on a zero row at the very end through round-off.
    while norm2[i] <= T::zero() && i > 0 {
        i -= 1;
    }
    i
}

impl<T: Real, S: Storage<T>, const GREEDY: bool, const AVERAGE: bool> OnlineEstimator<T>
    for Kaczmarz<T, S, GREEDY, AVERAGE>
{
    fn name(&self) -> &str {
        match (GREEDY, AVERAGE) {
            (false, false) => "RK",
            (false, true) => "TARK",
            (true, false) => "GRK",
            (true, true) => "TAG-K",
        }
    }

    fn dim(&self) -> usize {
        self.n
    }

    fn capacity(&self) -> usize {
        self.m_max
    }

    fn estimate(&self) -> &[T] {
        &self.buf.as_ref()[..self.n]
    }

    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: AVX2 support was detected at run time just above.
            return unsafe { self.run_avx2(a, b) };
        }
        self.run(a, b)
    }

    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        validate_estimate(self.n, estimate)?;
        let n = self.n;
        self.buf.as_mut()[..n].copy_from_slice(estimate);
        self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
        Ok(())
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, const GREEDY: bool, const AVERAGE: bool>
    Kaczmarz<T, alloc::vec::Vec<T>, GREEDY, AVERAGE>
{
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows, with its
    /// buffers on the heap (allocated once, here). The initial estimate is zero.
    pub fn new(n: usize, m_max: usize, config: KaczmarzConfig) -> Result<Self, ConfigError> {
        Self::with_storage(
            n,
            m_max,
            config,
            alloc::vec![T::zero(); kaczmarz_buffer_len(n, m_max)],
        )
    }
}
