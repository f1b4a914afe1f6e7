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
//! **Greedy rule** (Bai & Wu 2018, with `r = b − A x`).
//! The threshold is `ε = ½ (max_i (r_i²/‖a_i‖²)/‖r‖² + 1/‖A‖_F²)`.
//! The candidates are `U = {i : r_i² ≥ ε ‖r‖² ‖a_i‖²}`.
//! A row `i ∈ U` is drawn with probability `r_i² / Σ_{j∈U} r_j²`. (The TAG-K paper writes the test
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
//!   Gram matrix `G = A Aᵀ`, built once per window with register-tiled kernels (`m(m+1)/2`
//!   dot products of length `n`, i.e. `m²n` flops), plus `O(m)` branch-free work per
//!   iteration for selection and the residual update. No residual is ever recomputed from
//!   `A`. Computing Gram columns lazily, only for the rows chosen, was measured and
//!   rejected. In a window of 30, greedy selection visits about half of the rows at
//!   `n = 10` and 80 % at `n = 120`; one-at-a-time dot products are latency-bound.
//! - Randomised variants: `2n` flops per iteration (a dot product and an update of `x`), the
//!   row drawn by binary search over cumulative row norms.
//! - Finish: `x̄ = x₀ + Aᵀc̄` (or `x₀ + Aᵀc`): `2mn` flops.
//!
//! Measured on a 2-core AMD EPYC (Zen 4) VM, `f64`, `m = 30` (`cargo bench --bench
//! estimators`): about 1.9 µs per TAG-K update at `n = 10` and 5.4 µs at `n = 120`. Of that,
//! the 30 greedy iterations take about 1.1 µs, and at `n = 120` the Gram matrix about 2.5 µs.
//!
//! # Kernels and bit-identical results
//! The greedy variants run on one of four kernel sets. The set is chosen at run time on
//! x86-64 and at compile time on aarch64. All perform the same floating-point operations in the
//! same order: the order is fixed in the `greedy` module and documented there, and multiplies
//! and adds are never fused. So the same seed gives the same bits on every machine:
//! - portable loops (any target, any scalar; what a Cortex-M7 runs).
//! - x86-64 with AVX2 (`std` feature). For `f64`: the window packed transposed (with the prior
//!   residual from the same loads), the Gram matrix from it along the diagonals of blocks of
//!   four rows, and `x₀ + Aᵀc̄` in `ymm` blocks. For `f32`: 8 × 8 Gram tiles. For both, windows
//!   of up to 32 rows run the greedy loop with the window held in `ymm` registers.
//! - x86-64 with AVX-512F and BMI2: for `f64`, 8 × 8 Gram tiles and the greedy loop in `zmm`
//!   and mask registers (`f32` as with AVX2).
//! - aarch64 (NEON, with or without `std`): the portable Gram loops and, for `f64` and `f32`,
//!   windows of up to 32 rows, the greedy loop in NEON registers.
//!
//! The update never allocates: every buffer is laid out at construction in storage the
//! caller chooses (a `Vec`, an array, or a `&mut [T]` in static memory on a microcontroller).

use core::marker::PhantomData;

use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;

#[cfg(all(target_arch = "aarch64", target_feature = "neon"))]
use crate::aarch64::Neon;
use crate::estimator::{check_window_finite, check_window_shape, validate_estimate};
use crate::greedy::{self, Kernels, Portable, Schedule, Window};
use crate::linalg::{axpy, dot, norm2_and_dot, padded};
#[cfg(all(feature = "std", target_arch = "x86_64"))]
use crate::x86::Avx2;
use crate::{ConfigError, EstimatorError, OnlineEstimator, Real, UpdateInfo};

/// The kernels of [`Kaczmarz::update_on`], for paired timing in one process (the `timegate`
/// of `tagk-insncount`). Every choice computes the same bits.
#[doc(hidden)]
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum KernelChoice {
    /// The portable kernels (what a microcontroller runs).
    Portable,
    /// The kernels [`OnlineEstimator::update`] runs: the CPU and `TAGK_KERNELS` decide.
    Detected,
    /// As `Detected`, but where the detected `f64` Gram kernel is the AVX2 one, the previous
    /// AVX2 Gram kernel (the timing reference).
    PreviousGram,
}

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

/// TAG-K as the paper runs it: its Table II/III configuration, used by the firmware and the
/// experiments.
///
/// It makes `T = m` projections per window and averages the last half (`t_b = ⌊m/2⌋`).
/// It warm-starts from the previous average, with zero tolerance and seed 0. The same
/// value as [`KaczmarzConfig::default`], named so that the paper's setting has one home.
pub fn tagk_paper_config() -> KaczmarzConfig {
    KaczmarzConfig::default()
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
/// needs. It is `2n + 7p + p² + 16` scalars, with `p = m_max` rounded up to a multiple of 8.
/// `p²` holds the Gram matrix; 16 scalars let the work area start on a 64-byte boundary. On
/// x86-64 and aarch64, `n·p` more hold a transposed copy of the window. x86-64 adds 4 more,
/// read past its end by the AVX2 Gram kernel.
///
/// A `const fn`, so firmware can size a static array: `[0.0; kaczmarz_buffer_len(120, 30)]`.
/// Saturates at `usize::MAX` where the length overflows (no buffer is that long, so such sizes
/// are refused); [`checked_kaczmarz_buffer_len`] says so with `None`.
pub const fn kaczmarz_buffer_len(n: usize, m_max: usize) -> usize {
    match checked_kaczmarz_buffer_len(n, m_max) {
        Some(len) => len,
        None => usize::MAX,
    }
}

/// [`kaczmarz_buffer_len`] in checked arithmetic: `None` when the length overflows a `usize`
/// (the constructors then return [`ConfigError::TooLarge`]).
pub const fn checked_kaczmarz_buffer_len(n: usize, m_max: usize) -> Option<usize> {
    /// `?` for `Option` in a `const fn`.
    macro_rules! ok {
        ($e:expr) => {
            match $e {
                Some(v) => v,
                None => return None,
            }
        };
    }
    let p = ok!(crate::linalg::checked_padded(m_max));
    // The transposed copy of a window is only kept where SIMD units are wide (see the Gram
    // kernels).
    let transposed = if crate::linalg::TRANSPOSED_COPY {
        ok!(ok!(n.checked_mul(p)).checked_add(crate::linalg::TRANSPOSED_SLACK))
    } else {
        0
    };
    let len = ok!(n.checked_mul(2));
    let len = ok!(len.checked_add(ok!(p.checked_mul(7))));
    let len = ok!(len.checked_add(ok!(p.checked_mul(p))));
    let len = ok!(len.checked_add(ALIGN_SLACK));
    len.checked_add(transposed)
}

/// A zeroed heap buffer of `len` scalars for an estimator of dimension `n` and capacity `m`,
/// or [`ConfigError::TooLarge`] when the allocation is refused (`Vec::try_reserve_exact`:
/// too many bytes for one allocation, or the heap cannot give them) instead of aborting.
/// Every heap constructor of the workspace's estimators allocates through it.
///
/// # Errors
/// [`ConfigError::TooLarge`] `{ n, m }` when the allocation is refused.
#[cfg(feature = "alloc")]
pub fn zeroed_buffer<T: Real>(
    len: usize,
    n: usize,
    m: usize,
) -> Result<alloc::vec::Vec<T>, ConfigError> {
    let mut buf = alloc::vec::Vec::new();
    buf.try_reserve_exact(len)
        .map_err(|_| ConfigError::TooLarge { n, m })?;
    buf.resize(len, T::zero());
    Ok(buf)
}

/// Whether the final check that the new estimate is finite visits every entry branch-free,
/// or stops at the first non-finite one. The first is a vectorisable pass, for hosts with wide
/// SIMD units. The second suits microcontrollers: their Table III instruction counts were
/// taken with it. The answer is the same either way.
const FINITE_CHECK_BRANCH_FREE: bool = cfg!(any(target_arch = "x86_64", target_arch = "aarch64"));

/// Scalars skipped at most to start the per-update work area on a 64-byte boundary (a cache
/// line, and the width of an AVX-512 register): 16 `f32` or 8 `f64`.
const ALIGN_SLACK: usize = 16;

/// Storage for an estimator's buffers: anything that derefs to a mutable slice.
pub trait Storage<T>: AsRef<[T]> + AsMut<[T]> {}
impl<T, S: AsRef<[T]> + AsMut<[T]>> Storage<T> for S {}

/// The Kaczmarz kernel shared by the four variants; use the aliases [`RandomizedKaczmarz`],
/// [`TailAveragedKaczmarz`], [`GreedyKaczmarz`] and [`TagK`].
///
/// `GREEDY` selects rows by Bai & Wu's rule instead of by row norm; `AVERAGE` reports the tail
/// average instead of the last iterate. Both are resolved at compile time.
///
/// `Clone` when the storage is (a `Vec` or an array: the clone continues with the same
/// estimate and the same random stream; a borrowed `&mut [T]` cannot be duplicated). Only the
/// estimate and the generator persist between updates; the rest of the buffer is per-update
/// scratch, so a clone whose buffer lands at another alignment behaves identically.
#[derive(Clone)]
pub struct Kaczmarz<T: Real, S: Storage<T>, const GREEDY: bool, const AVERAGE: bool> {
    config: KaczmarzConfig,
    n: usize,
    m_max: usize,
    buf: S,
    rng: ChaCha8Rng,
    _scalar: PhantomData<T>,
}

impl<T: Real, S: Storage<T>, const GREEDY: bool, const AVERAGE: bool> core::fmt::Debug
    for Kaczmarz<T, S, GREEDY, AVERAGE>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Kaczmarz")
            .field("greedy", &GREEDY)
            .field("average", &AVERAGE)
            .field("config", &self.config)
            .field("n", &self.n)
            .field("m_max", &self.m_max)
            .field("estimate", &&self.buf.as_ref()[..self.n])
            .finish_non_exhaustive()
    }
}

/// Randomised Kaczmarz (Strohmer & Vershynin 2009): rows drawn with probability `‖a_i‖²/‖A‖_F²`.
pub type RandomizedKaczmarz<T, S> = Kaczmarz<T, S, false, false>;
/// Tail-averaged randomised Kaczmarz (TARK): RK reporting the average of the iterates after the burn-in.
pub type TailAveragedKaczmarz<T, S> = Kaczmarz<T, S, false, true>;
/// Greedy randomised Kaczmarz (GRK, Bai & Wu 2018).
pub type GreedyKaczmarz<T, S> = Kaczmarz<T, S, true, false>;
/// TAG-K: greedy row selection (GRK) plus tail averaging, warm-started from the previous average.
///
/// # Examples
///
/// Recover `θ` from a stream of consistent windows, and check it against the exact solution.
/// The same seed gives the same bits; a rejected window changes nothing.
///
/// ```
/// use tagk_core::{EstimatorError, KaczmarzConfig, OnlineEstimator, TagK};
///
/// // θ = (2, −1) seen through windows of 3 rows; row k of window w is (cos φ, sin φ).
/// let theta = [2.0, -1.0];
/// let window = |w: usize| -> (Vec<f64>, Vec<f64>) {
///     let mut a = Vec::new();
///     let mut b = Vec::new();
///     for k in 0..3 {
///         let phi = 0.7 * (3 * w + k) as f64;
///         a.extend([phi.cos(), phi.sin()]);
///         b.push(phi.cos() * theta[0] + phi.sin() * theta[1]);
///     }
///     (a, b)
/// };
/// let config = KaczmarzConfig::default().with_seed(42);
/// let mut est = TagK::<f64, Vec<f64>>::new(2, 3, config)?;
/// let mut twin = TagK::<f64, Vec<f64>>::new(2, 3, config)?;
/// for w in 0..200 {
///     let (a, b) = window(w);
///     let info = est.update(&a, &b)?;
///     assert_eq!(info.rows, 3);
///     twin.update(&a, &b)?;
/// }
/// // The windows are consistent, so the estimate reaches θ itself.
/// for (e, t) in est.estimate().iter().zip(&theta) {
///     assert!((e - t).abs() < 1e-9, "{e} vs {t}");
/// }
/// assert_eq!(est.estimate(), twin.estimate()); // same seed, same bits
///
/// // A window with a NaN is refused with a typed error and leaves θ̂ as it was.
/// let before = est.estimate().to_vec();
/// let refused = est.update(&[f64::NAN, 0.0], &[1.0]);
/// assert!(matches!(refused, Err(EstimatorError::NonFiniteRegressor { row: 0, .. })));
/// assert_eq!(est.estimate(), &before[..]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
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
    prefix: &'a mut [T],
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
        let needed =
            checked_kaczmarz_buffer_len(n, m_max).ok_or(ConfigError::TooLarge { n, m: m_max })?;
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

    /// [`OnlineEstimator::update`] on the kernels `kernels`, for paired timing of the kernels
    /// in one process. Every choice computes the same bits.
    ///
    /// # Errors
    /// As [`OnlineEstimator::update`].
    #[doc(hidden)]
    pub fn update_on(
        &mut self,
        kernels: KernelChoice,
        a: &[T],
        b: &[T],
    ) -> Result<UpdateInfo, EstimatorError> {
        match kernels {
            KernelChoice::Portable => self.run(Portable, a, b),
            KernelChoice::Detected => self.update(a, b),
            KernelChoice::PreviousGram => {
                #[cfg(all(feature = "std", target_arch = "x86_64"))]
                if let Some(k) = Avx2::detect() {
                    // SAFETY: `k` proves that the CPU supports AVX2.
                    return unsafe { self.run_avx2(k.with_previous_gram(), a, b) };
                }
                self.update(a, b)
            }
        }
    }

    /// The buffer's views. The estimate, the only state kept between updates, comes first, so a
    /// storage that moves keeps it. The work area after it starts on a 64-byte boundary wherever
    /// the storage is. Its `p`-sized arrays come first, so every one of them is aligned, and the
    /// Gram rows too.
    fn parts(buf: &mut S, n: usize, m_max: usize) -> Parts<'_, T> {
        let m = padded(m_max);
        let (estimate, rest) = buf.as_mut().split_at_mut(n);
        let skip = rest.as_ptr().align_offset(64).min(ALIGN_SLACK);
        let rest = &mut rest[skip..];
        let (gram, rest) = rest.split_at_mut(m * m);
        let (norm2, rest) = rest.split_at_mut(m);
        let (inv_norm2, rest) = rest.split_at_mut(m);
        let (resid, rest) = rest.split_at_mut(m);
        let (coef, rest) = rest.split_at_mut(m);
        let (coef_avg, rest) = rest.split_at_mut(m);
        let (scratch, rest) = rest.split_at_mut(m);
        let (prefix, rest) = rest.split_at_mut(m);
        let (transposed, rest) = if crate::linalg::TRANSPOSED_COPY {
            rest.split_at_mut(n * m + crate::linalg::TRANSPOSED_SLACK)
        } else {
            rest.split_at_mut(0)
        };
        let work = &mut rest[..n];
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
            prefix,
        }
    }

    /// [`Self::run`] compiled for AVX2 with the AVX2 kernels: the same operations in the same
    /// order (separate multiplies and adds, never fused), so results are bit-identical to the
    /// portable path.
    #[cfg(all(feature = "std", target_arch = "x86_64"))]
    #[target_feature(enable = "avx2")]
    fn run_avx2(&mut self, k: Avx2, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        self.run(k, a, b)
    }

    #[inline(always)]
    fn run<K: Kernels<T>>(&mut self, k: K, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        let n = self.n;
        let m = check_window_shape(n, self.m_max, a, b)?;
        let (t_total, t_b) = self.config.schedule(m);
        let tol = T::cast(self.config.tolerance);
        let tol2 = tol * tol;
        // The generator's position, restored if the update fails after drawing (cheaper than
        // working on a copy of its state).
        let rng_start = self.rng.get_word_pos();
        let rng = &mut self.rng;
        let p = Self::parts(&mut self.buf, n, self.m_max);

        let pm = padded(m);

        // Setup: row norms and the prior residual r = b − A x₀ (zero-padded to `pm` entries).
        if GREEDY {
            // The greedy variants need nearly every Gram entry anyway (they visit most rows of
            // a window), so the full matrix is built at once; its diagonal holds the norms.
            k.gram_and_residual(a, b, p.estimate, n, m, p.transposed, p.gram, p.resid);
            if !k.gram_diagonal(p.gram, pm, m, p.norm2) {
                for i in 0..m {
                    p.norm2[i] = p.gram[i * pm + i];
                }
            }
        } else {
            for i in 0..m {
                let (nn, ax) = norm2_and_dot(&a[i * n..(i + 1) * n], p.estimate);
                p.norm2[i] = nn;
                p.resid[i] = b[i] - ax;
            }
        }
        // Every norm and prior residual finite (a branch-free pass, then the error path)?
        let finite = p.norm2[..m]
            .iter()
            .zip(&p.resid[..m])
            .fold(true, |ok, (nn, r)| ok & nn.is_finite() & r.is_finite());
        if !finite {
            check_window_finite(n, a, b)?;
            // Finite entries whose squares overflow: name the first such row.
            let row = (0..m)
                .find(|&i| !(p.norm2[i].is_finite() && p.resid[i].is_finite()))
                .unwrap_or(0);
            return Err(EstimatorError::NonFiniteRegressor { row, col: 0 });
        }
        // Branch-free, vectorisable passes over the padded window: reciprocal norms, zero rows
        // and padding made inert (a zero row carries no information: never chosen, never
        // divided by), coefficients cleared, ‖A‖_F² in eight lane sums (norms are never
        // negative, so unusable rows add exact zeros); or the kernel set's own pass, the same
        // bits (`Kernels::prepare`).
        let (fro2, rnorm2, max_ratio) = if let Some((fro2, rnorm2, max_ratio)) =
            k.prepare(m, pm, p.norm2, p.inv_norm2, p.resid, p.coef, p.coef_avg)
        {
            if fro2 <= T::zero() {
                return Err(EstimatorError::NoUsableRow);
            }
            (fro2, rnorm2, max_ratio)
        } else {
            p.norm2[m..pm].fill(T::zero());
            p.resid[m..pm].fill(T::zero());
            // (Slices of `pm` entries each: no bounds check in the loop, which the compiler
            // then vectorises.)
            let (norm2, inv_norm2, resid) =
                (&p.norm2[..pm], &mut p.inv_norm2[..pm], &mut p.resid[..pm]);
            let (coef, coef_avg) = (&mut p.coef[..pm], &mut p.coef_avg[..pm]);
            for i in 0..pm {
                let nn = norm2[i];
                let usable = nn > T::zero();
                let inv = T::one() / nn;
                inv_norm2[i] = if usable { inv } else { T::zero() };
                resid[i] = if usable { resid[i] } else { T::zero() };
                coef[i] = T::zero();
                coef_avg[i] = T::zero();
            }
            let fro2 = greedy::lane_sum(&p.norm2[..pm]);
            if fro2 <= T::zero() {
                return Err(EstimatorError::NoUsableRow);
            }
            let (rnorm2, max_ratio) = greedy::residual_stats(&p.resid[..pm], &p.inv_norm2[..pm]);
            (fro2, rnorm2, max_ratio)
        };
        if !fro2.is_finite() || !rnorm2.is_finite() {
            return Err(EstimatorError::Diverged);
        }
        let prior_residual_norm = rnorm2.sqrt().as_f64();

        let schedule = Schedule {
            t_total,
            t_b,
            tol2,
            half_inv_fro2: T::cast(0.5) * (T::one() / fro2),
        };

        let mut iterations = 0;
        let mut converged = rnorm2 <= tol2;
        if GREEDY {
            let window = Window {
                p: pm,
                resid: &mut *p.resid,
                inv_norm2: &*p.inv_norm2,
                gram: &*p.gram,
                coef: &mut *p.coef,
                coef_avg: &mut *p.coef_avg,
                weights: &mut *p.scratch,
                prefix: &mut *p.prefix,
            };
            (iterations, converged) =
                k.iterate::<AVERAGE>(window, rnorm2, max_ratio, schedule, rng);
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
                    let mut rnorm2 = T::zero();
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
                let target = T::cast(greedy::uniform(rng)) * cum;
                let i = sample_cumulative(&p.scratch[..m], p.norm2, target);
                let row = &a[i * n..(i + 1) * n];
                let alpha = (b[i] - dot(row, p.work)) * p.inv_norm2[i];
                axpy(alpha, row, p.work);
                p.coef[i] += alpha;
                if AVERAGE {
                    p.coef_avg[i] += alpha * schedule.weight(iterations);
                }
            }
        }

        // Finish: x = x₀ + Aᵀc (last iterate) or x̄ = x₀ + Aᵀc̄ (tail average), into `work`.
        if GREEDY || AVERAGE {
            let coef: &[T] = if AVERAGE { p.coef_avg } else { p.coef };
            p.work.copy_from_slice(p.estimate);
            // The rows used (nonzero coefficient), row by row, accumulated in registers: on
            // x86-64 by the kernel set (AVX2 has its own), elsewhere by the portable loop
            // called directly (the code the Cortex-M7's reference counts were taken with).
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            k.add_combination(p.work, a, coef, n, m);
            #[cfg(not(all(feature = "std", target_arch = "x86_64")))]
            crate::linalg::add_combination(p.work, a, coef, n, m);
        }
        let finite = if FINITE_CHECK_BRANCH_FREE {
            p.work.iter().fold(true, |ok, v| ok & v.is_finite())
        } else {
            !p.work.iter().any(|v| !v.is_finite())
        };
        if !finite {
            rng.set_word_pos(rng_start);
            return Err(EstimatorError::Diverged);
        }
        p.estimate.copy_from_slice(p.work);
        Ok(UpdateInfo {
            rows: m,
            iterations,
            prior_residual_norm,
            converged,
        })
    }
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
        if let Some(k) = Avx2::detect() {
            // SAFETY: `k` proves that the CPU supports AVX2.
            return unsafe { self.run_avx2(k, a, b) };
        }
        #[cfg(all(target_arch = "aarch64", target_feature = "neon"))]
        if greedy::requested() != greedy::Requested::Portable {
            return self.run(Neon, a, b);
        }
        self.run(Portable, a, b)
    }

    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        validate_estimate(self.n, estimate)?;
        let n = self.n;
        self.buf.as_mut()[..n].copy_from_slice(estimate);
        self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
        Ok(())
    }

    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        if tolerance >= 0.0 && tolerance.is_finite() {
            self.config.tolerance = tolerance;
            true
        } else {
            false
        }
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, const GREEDY: bool, const AVERAGE: bool>
    Kaczmarz<T, alloc::vec::Vec<T>, GREEDY, AVERAGE>
{
    /// Builds an estimator of dimension `n` for windows of at most `m_max` rows, with its
    /// buffers on the heap (allocated once, here). The initial estimate is zero.
    ///
    /// # Errors
    /// As [`Kaczmarz::with_storage`]; [`ConfigError::TooLarge`] when the buffer's length
    /// overflows or its allocation is refused (no abort).
    pub fn new(n: usize, m_max: usize, config: KaczmarzConfig) -> Result<Self, ConfigError> {
        crate::check_dimensions(n, m_max)?;
        config.validate()?;
        let len =
            checked_kaczmarz_buffer_len(n, m_max).ok_or(ConfigError::TooLarge { n, m: m_max })?;
        Self::with_storage(n, m_max, config, zeroed_buffer(len, n, m_max)?)
    }
}

#[cfg(all(
    test,
    feature = "std",
    any(
        target_arch = "x86_64",
        all(target_arch = "aarch64", target_feature = "neon")
    )
))]
mod tests {
    use super::*;
    #[cfg(target_arch = "aarch64")]
    use crate::aarch64::Neon as Fast;
    use crate::greedy::Portable;
    #[cfg(target_arch = "x86_64")]
    use crate::x86::Avx2 as Fast;
    use rand_core::Rng;
    use std::vec;
    use std::vec::Vec;

    fn value(rng: &mut ChaCha8Rng) -> f64 {
        greedy::uniform(rng) * 2.0 - 1.0
    }

    /// One update on the SIMD kernels `k`.
    fn run_fast<T: Real, const G: bool, const A: bool>(
        e: &mut Kaczmarz<T, Vec<T>, G, A>,
        k: Fast,
        a: &[T],
        b: &[T],
    ) -> Result<UpdateInfo, EstimatorError> {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `k` proves AVX2 support.
        return unsafe { e.run_avx2(k, a, b) };
        #[cfg(target_arch = "aarch64")]
        return e.run(k, a, b);
    }

    /// The SIMD kernels must reproduce the portable ones bit for bit: the portable ones are what
    /// a microcontroller runs. Cases: window sizes that change between calls, zero rows,
    /// tolerances and iteration counts beyond one pass, in `f64` and `f32`, fixed shapes and
    /// twelve random ones with n in 10..=120. On x86-64 the kernels detected run (AVX-512 where
    /// the CPU has it), and the AVX2 ones forced, with the AVX2 Gram tiles and with the previous
    /// AVX2 Gram kernel. On aarch64 the NEON ones run.
    #[test]
    fn simd_and_portable_kernels_give_the_same_bits() {
        #[cfg(target_arch = "x86_64")]
        let kernels = {
            let Some(detected) = Fast::detect() else {
                std::eprintln!(
                    "no AVX2 on this CPU (or TAGK_KERNELS=portable): nothing to compare"
                );
                return;
            };
            [
                detected.without_avx512(),
                detected.without_avx512().with_previous_gram(),
                detected,
            ]
        };
        #[cfg(target_arch = "aarch64")]
        let kernels = [Neon];
        for k in kernels {
            compare_with_portable::<f64>(k);
            compare_with_portable::<f32>(k);
        }
    }

    fn compare_with_portable<T: Real>(k: Fast) {
        let mut data = ChaCha8Rng::seed_from_u64(7);
        // Fixed shapes, then random ones of the robot range: n in 10..=120, m_max in 1..=40.
        let mut shapes = ChaCha8Rng::seed_from_u64(29);
        let random: Vec<(usize, usize)> = (0..12)
            .map(|_| {
                let n = 10 + (shapes.next_u64() % 111) as usize;
                (n, 1 + (shapes.next_u64() % 40) as usize)
            })
            .collect();
        for (n, m_max) in [
            (1, 1),
            (3, 5),
            (10, 30),
            (13, 9),
            (40, 17),
            (120, 30),
            (7, 64),
        ]
        .into_iter()
        .chain(random)
        {
            for (iterations, tolerance) in [
                (Iterations::OnePass, 0.0),
                (Iterations::Fixed(3 * m_max), 0.0),
                (Iterations::OnePass, 0.05),
            ] {
                let cfg = KaczmarzConfig::default()
                    .with_seed(data.next_u64())
                    .with_iterations(iterations)
                    .with_tolerance(tolerance);
                let mut portable = TagK::<T, Vec<T>>::new(n, m_max, cfg).unwrap();
                let mut fast = TagK::<T, Vec<T>>::new(n, m_max, cfg).unwrap();
                let mut grk_portable = GreedyKaczmarz::<T, Vec<T>>::new(n, m_max, cfg).unwrap();
                let mut grk_fast = GreedyKaczmarz::<T, Vec<T>>::new(n, m_max, cfg).unwrap();
                let theta: Vec<f64> = (0..n).map(|_| value(&mut data)).collect();
                for w in 0..10 {
                    let m = 1 + (w * 7 + 3) % m_max;
                    let mut a: Vec<f64> = (0..m * n).map(|_| value(&mut data)).collect();
                    if w % 3 == 1 && m > 1 {
                        a[..n].fill(0.0); // a zero row
                    }
                    let b: Vec<f64> = (0..m)
                        .map(|i| {
                            let ax: f64 = (0..n).map(|c| a[i * n + c] * theta[c]).sum();
                            ax + 1e-2 * value(&mut data)
                        })
                        .collect();
                    let (a, b): (Vec<T>, Vec<T>) = (
                        a.iter().map(|&v| T::cast(v)).collect(),
                        b.iter().map(|&v| T::cast(v)).collect(),
                    );
                    let want = portable.run(Portable, &a, &b).unwrap();
                    let got = run_fast(&mut fast, k, &a, &b).unwrap();
                    assert_eq!(
                        want,
                        got,
                        "{} n={n} m={m} window {w}",
                        core::any::type_name::<T>()
                    );
                    let same = |x: &[T], y: &[T]| {
                        x.iter()
                            .zip(y)
                            .all(|(p, q)| p.as_f64().to_bits() == q.as_f64().to_bits())
                    };
                    assert!(
                        same(portable.estimate(), fast.estimate()),
                        "TAG-K n={n} m={m} window {w}"
                    );
                    grk_portable.run(Portable, &a, &b).unwrap();
                    run_fast(&mut grk_fast, k, &a, &b).unwrap();
                    assert!(
                        same(grk_portable.estimate(), grk_fast.estimate()),
                        "GRK n={n} m={m} window {w}"
                    );
                }
                assert_ne!(portable.estimate(), vec![T::zero(); n].as_slice());
            }
        }
    }
}
