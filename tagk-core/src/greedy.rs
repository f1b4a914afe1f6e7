//! The greedy iterations of GRK and TAG-K on one window, behind a small kernel interface
//! ([`Kernels`]). A portable implementation serves every target and scalar. SIMD ones serve
//! x86-64 (`x86.rs`) and aarch64 (`aarch64.rs`). Without AVX-512, their greedy loops are one
//! loop over eight-lane chunks (`lanes.rs`).
//!
//! Every floating-point operation happens in an order fixed here, and every implementation
//! follows it, so a microcontroller, a host without AVX2 and a host with AVX-512 compute the
//! same bits. The order is chosen for short dependency chains on 8-lane SIMD units:
//!
//! - Vectors of the window (residual `r`, row norms, coefficients) are padded with zeros to
//!   `p = padded(m)` entries, a multiple of 8. They are handled as chunks of 8 lanes. The Gram
//!   matrix is `p × p` with row stride `p`: rows `≥ m` unspecified, zero in columns `≥ m`.
//! - `S = Σ_j r_j²` runs over eight partial sums (`j mod 8`), each in order of `j`.
//!   Eight accumulators fit a Cortex-M7's registers. They combine as `t_l = s_l + s_{l+4}`,
//!   then `(t₀ + t₂) + (t₁ + t₃)`. And `M = max_j r_j² · (1/‖a_j‖²)`.
//! - Threshold `θ = M · ½ + S · (½/‖A‖_F²)`; candidate weights `w_j = r_j²` where
//!   `r_j² · (1/‖a_j‖²) ≥ θ`, else 0 (Bai & Wu's set, multiplied through by `‖r‖²`).
//! - Rows are sampled in lane-major order: lane `l = j mod 8` first, then chunk
//!   `c = j div 8`. This needs no shuffles down the chunks.
//!   - Running sums `V_{c,l} = V_{c−1,l} + w_{8c+l}` (`V_{0,l} = w_l`).
//!   - The lane totals `T_l = V_{last,l}` are scanned across lanes in three steps
//!     `x_l ← x_l + x_{l−d}`, `d = 1, 2, 4` (lanes `l ≥ d`, from the values before the step).
//!   - Running sums `P_{c,l} = x_{l−1} + V_{c,l}` (`l ≥ 1`; `P_{c,0} = V_{c,0}`); total `x_7`.
//! - With `target = u · total`, `u ∈ [0, 1)`, the row drawn is the first in that order with
//!   `w_j > 0` and `P_j > target`. On round-off it is the last in that order with `w_j > 0`.
//!   If every weight is zero, it is the first `j` of largest ratio.
//! - `α = r_i · (1/‖a_i‖²)`; `r ← r − α g_i` is a multiply then a subtraction (never fused),
//!   then `r_i ← 0` exactly.

use rand_chacha::ChaCha8Rng;
use rand_core::Rng;

use crate::Real;

/// Lanes per chunk of the window vectors.
pub(crate) const LANES: usize = 8;

/// The kernels the environment variable `TAGK_KERNELS` asks for (read once per process, with
/// the `std` feature): `portable`, `avx2` (x86-64: no AVX-512 even where the CPU has it), or
/// anything else / unset for the best the CPU supports. Every choice computes the same bits;
/// the variable exists to measure and compare the kernels on one machine.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(
    not(any(
        all(feature = "std", target_arch = "x86_64"),
        all(target_arch = "aarch64", target_feature = "neon")
    )),
    allow(dead_code)
)]
pub(crate) enum Requested {
    /// The best kernels the CPU supports.
    Best,
    /// At most AVX2 on x86-64 (no AVX-512).
    Avx2,
    /// The portable kernels.
    Portable,
}

/// What `TAGK_KERNELS` asks for (see [`Requested`]).
#[cfg(feature = "std")]
#[cfg_attr(
    not(any(
        all(feature = "std", target_arch = "x86_64"),
        all(target_arch = "aarch64", target_feature = "neon")
    )),
    allow(dead_code)
)]
pub(crate) fn requested() -> Requested {
    static CHOICE: std::sync::OnceLock<Requested> = std::sync::OnceLock::new();
    *CHOICE.get_or_init(|| match std::env::var("TAGK_KERNELS").as_deref() {
        Ok("portable") => Requested::Portable,
        Ok("avx2") => Requested::Avx2,
        _ => Requested::Best,
    })
}

/// Without `std` there is no environment: the best kernels.
#[cfg(not(feature = "std"))]
#[cfg_attr(
    not(any(
        all(feature = "std", target_arch = "x86_64"),
        all(target_arch = "aarch64", target_feature = "neon")
    )),
    allow(dead_code)
)]
pub(crate) fn requested() -> Requested {
    Requested::Best
}

/// One window's state for the greedy iterations. Every vector has `p` entries (a multiple of
/// 8), zero from `m` on; `gram` is `p × p` with row stride `p`.
pub(crate) struct Window<'a, T> {
    /// Padded row count.
    pub p: usize,
    /// Residual `r = b − A x` of the current iterate.
    pub resid: &'a mut [T],
    /// `1/‖a_j‖²`, zero for zero rows.
    pub inv_norm2: &'a [T],
    /// The Gram matrix `A Aᵀ`.
    pub gram: &'a [T],
    /// Coefficients `c` of the iterate `x = x₀ + Aᵀc`.
    pub coef: &'a mut [T],
    /// Coefficients `c̄` of the tail average `x̄ = x₀ + Aᵀc̄`.
    pub coef_avg: &'a mut [T],
    /// Scratch: candidate weights (`p` entries).
    pub weights: &'a mut [T],
    /// Scratch: their prefix sums (`p` entries).
    pub prefix: &'a mut [T],
}

/// The iteration schedule of one window.
#[derive(Clone, Copy)]
pub(crate) struct Schedule<T> {
    /// Iterations `T`.
    pub t_total: usize,
    /// Burn-in `t_b < T`.
    pub t_b: usize,
    /// Squared residual tolerance.
    pub tol2: T,
    /// `½/‖A‖_F²`.
    pub half_inv_fro2: T,
}

impl<T: Real> Schedule<T> {
    /// Weight of a step taken at iteration `s` (1-based) in the average of `x_{t_b+1..T}`:
    /// the step is part of every iterate from `max(s, t_b + 1)` on.
    #[inline(always)]
    pub fn weight(&self, s: usize) -> T {
        let first = if s > self.t_b { s } else { self.t_b + 1 };
        T::cast((self.t_total - first + 1) as f64) / T::cast((self.t_total - self.t_b) as f64)
    }

    /// Bai & Wu's threshold `θ = M · ½ + S · (½/‖A‖_F²)`.
    #[inline(always)]
    pub fn threshold(&self, rnorm2: T, max_ratio: T) -> T {
        max_ratio * T::cast(0.5) + rnorm2 * self.half_inv_fro2
    }
}

/// A uniform draw in `[0, 1)` from one 32-bit word of the generator (a resolution of
/// `2⁻³²` of the total weight, far below anything a window of rows can tell apart, at half
/// the generator's work of a 53-bit draw).
#[inline(always)]
pub(crate) fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    unit(rng.next_u32())
}

/// A random word as a uniform number in `[0, 1)`.
#[inline(always)]
fn unit(word: u32) -> f64 {
    f64::from(word) * (1.0 / (1u64 << 32) as f64)
}

/// The uniform draws of one window, taken from the generator in batches (so a SIMD loop does
/// not call out per iteration) and handed out one per iteration that needs one. The generator
/// ends exactly where one-at-a-time draws would have left it.
pub(crate) struct Draws<'a> {
    rng: &'a mut ChaCha8Rng,
    buf: [f64; DRAW_BATCH],
    next: usize,
    len: usize,
    /// Draws the window can still need after this batch.
    left: usize,
    /// Generator position (in 32-bit words) before this batch.
    start: u128,
}

/// Draws taken from the generator at a time.
const DRAW_BATCH: usize = 32;

impl<'a> Draws<'a> {
    /// At most `most` draws will be asked for.
    #[inline(always)]
    pub fn new(rng: &'a mut ChaCha8Rng, most: usize) -> Self {
        Self {
            start: 0,
            rng,
            buf: [0.0; DRAW_BATCH],
            next: 0,
            len: 0,
            left: most,
        }
    }

    /// The next draw.
    #[inline(always)]
    pub fn next(&mut self) -> f64 {
        if self.next == self.len {
            self.refill();
        }
        self.next += 1;
        self.buf[self.next - 1]
    }

    // Cold on x86-64: once per 32 draws, and out of the SIMD loops' way (their registers need
    // not be saved around it on the common path). Elsewhere as it was: the Cortex-M7's
    // instruction counts are a reference.
    #[cfg_attr(target_arch = "x86_64", cold)]
    #[inline(never)]
    fn refill(&mut self) {
        self.len = self.left.clamp(1, DRAW_BATCH);
        self.left -= self.len.min(self.left);
        self.start = self.rng.get_word_pos();
        // One bulk copy out of the generator's buffer: the same words, in the same order, as
        // `len` calls of `next_u32`.
        let mut bytes = [0u8; 4 * DRAW_BATCH];
        self.rng.fill_bytes(&mut bytes[..4 * self.len]);
        for (u, b) in self.buf[..self.len].iter_mut().zip(bytes.chunks_exact(4)) {
            *u = unit(u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        }
        self.next = 0;
    }

    /// Returns the unused draws of the batch to the generator (each draw is one word).
    #[inline(always)]
    pub fn finish(self) {
        if self.next < self.len {
            self.rng.set_word_pos(self.start + self.next as u128);
        }
    }
}

/// The batch interface of [`Draws`]: only the eight-lane loop of `lanes.rs` (AVX2 and NEON)
/// takes a window's draws at once, so elsewhere (the Cortex-M7, builds without `std`) these
/// are unused.
#[cfg_attr(
    not(any(
        all(feature = "std", target_arch = "x86_64"),
        all(target_arch = "aarch64", target_feature = "neon")
    )),
    allow(dead_code)
)]
impl Draws<'_> {
    /// Takes every draw the window can need from the generator now, when they fit one batch
    /// (`1 ≤ most ≤ DRAW_BATCH`), and says whether it did. These are the same words a first
    /// [`Draws::next`] would take (nothing else draws meanwhile). A SIMD loop then reads its
    /// `k`-th draw with [`Draws::prefilled`], without a check per iteration. It records how many
    /// it took with [`Draws::taken`] before [`Draws::finish`]. That returns the rest, all of them
    /// if none was taken.
    #[inline(always)]
    pub fn prefill(&mut self) -> bool {
        let fits = (1..=DRAW_BATCH).contains(&self.left) && self.len == 0;
        if fits {
            self.refill();
        }
        fits
    }

    /// Draw `k` of a batch [`Draws::prefill`] took.
    ///
    /// # Safety
    /// `prefill` returned `true` and `k` is below the `most` of [`Draws::new`].
    #[inline(always)]
    pub unsafe fn prefilled(&self, k: usize) -> f64 {
        // SAFETY: the batch holds `most` draws (the caller's promise).
        unsafe { *self.buf.get_unchecked(k) }
    }

    /// Records that the first `k` draws of a prefilled batch were taken.
    #[inline(always)]
    pub fn taken(&mut self, k: usize) {
        self.next = k.min(self.len);
    }
}

/// The per-window kernels. Implementations must follow the arithmetic order in the module
/// documentation to the last bit.
pub(crate) trait Kernels<T: Real>: Copy {
    /// `G = A Aᵀ` and `r = b − A x`.
    ///
    /// `G` is `p × p` with stride `p`: rows `< m` exact and zero in columns `≥ m`, rows `≥ m`
    /// unspecified. Each entry is summed in order of the column index `k`.
    /// `r` has `p` entries, zero from `m` on, each product summed as [`crate::linalg::dot`]
    /// does. `at` is scratch of `n·p` entries (and
    /// `linalg::TRANSPOSED_SLACK` more, which may be read).
    #[allow(clippy::too_many_arguments)]
    fn gram_and_residual(
        self,
        a: &[T],
        b: &[T],
        x: &[T],
        n: usize,
        m: usize,
        at: &mut [T],
        gram: &mut [T],
        resid: &mut [T],
    );

    /// The row norms `‖a_i‖² = G_ii` for `i < m` into `norm2`, from the `pm × pm` Gram
    /// matrix `gram` (stride `pm`), where the kernel set has its own loop: `false` (the
    /// default) leaves it to the estimator's portable loop.
    #[inline(always)]
    fn gram_diagonal(self, _gram: &[T], _pm: usize, _m: usize, _norm2: &mut [T]) -> bool {
        false
    }

    /// The estimator's setup passes over the padded window (`pm` entries each, a multiple of
    /// 8), where the kernel set has its own. They start from finite norms and prior residuals of
    /// the `m` rows. Entries `≥ m` of `norm2` and `resid` are zeroed. `inv_norm2 = 1/‖a_i‖²`
    /// where `‖a_i‖² > 0` and zero elsewhere; the residual is zeroed there too. The coefficients
    /// are cleared. Returns `‖A‖_F²` (as [`lane_sum`]) and the residual's statistics (as
    /// [`residual_stats`]): the bits of the estimator's portable passes. `None` (the default)
    /// leaves them to those passes.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn prepare(
        self,
        _m: usize,
        _pm: usize,
        _norm2: &mut [T],
        _inv_norm2: &mut [T],
        _resid: &mut [T],
        _coef: &mut [T],
        _coef_avg: &mut [T],
    ) -> Option<(T, T, T)> {
        None
    }

    /// `x ← x + Aᵀc` for the row-major `m × n` window `a`, over the rows with a nonzero
    /// coefficient, each entry summed in order of those rows exactly as
    /// [`crate::linalg::add_combination`] does (which is the default). Only x86-64 calls it
    /// (elsewhere the estimator calls the portable loop directly).
    #[cfg_attr(not(all(feature = "std", target_arch = "x86_64")), allow(dead_code))]
    #[inline(always)]
    fn add_combination(self, x: &mut [T], a: &[T], coef: &[T], n: usize, m: usize) {
        crate::linalg::add_combination(x, a, coef, n, m);
    }

    /// The greedy iterations (GRK's selection; with `AVERAGE`, TAG-K's tail-average
    /// coefficients too) from a residual with statistics `(rnorm2, max_ratio)`.
    /// Returns `(iterations, converged)`.
    fn iterate<const AVERAGE: bool>(
        self,
        w: Window<'_, T>,
        rnorm2: T,
        max_ratio: T,
        s: Schedule<T>,
        rng: &mut ChaCha8Rng,
    ) -> (usize, bool);
}

/// The reference kernels: plain loops in the documented order (LLVM vectorises some of them).
#[derive(Clone, Copy)]
pub(crate) struct Portable;

impl<T: Real> Kernels<T> for Portable {
    #[inline(always)]
    fn gram_and_residual(
        self,
        a: &[T],
        b: &[T],
        x: &[T],
        n: usize,
        m: usize,
        at: &mut [T],
        gram: &mut [T],
        resid: &mut [T],
    ) {
        // Two tilings of the same sums, chosen for the target: an 8-wide tile over a
        // transposed copy of A where SIMD units are wide (x86-64, aarch64), a 2 × 4 tile on
        // the rows where registers are few (a Cortex-M7 FPU has sixteen).
        if crate::linalg::GRAM_FROM_TRANSPOSED {
            crate::linalg::transpose_padded(a, n, m, at);
            crate::linalg::gram_transposed(at, n, m, gram);
        } else {
            crate::linalg::gram_rows(a, n, m, gram);
        }
        crate::linalg::residual_rows(a, n, m, x, b, resid);
    }

    #[inline(always)]
    fn iterate<const AVERAGE: bool>(
        self,
        w: Window<'_, T>,
        rnorm2: T,
        max_ratio: T,
        s: Schedule<T>,
        rng: &mut ChaCha8Rng,
    ) -> (usize, bool) {
        iterate_portable::<T, AVERAGE>(w, rnorm2, max_ratio, s, rng)
    }
}

/// `(Σ_j r_j², max_j r_j²/‖a_j‖²)` over `p` entries (a multiple of 8), in the documented order.
#[inline(always)]
pub(crate) fn residual_stats<T: Real>(r: &[T], inv_norm2: &[T]) -> (T, T) {
    let mut sum = [T::zero(); LANES];
    let mut best = T::zero();
    for (rc, ic) in r.chunks_exact(LANES).zip(inv_norm2.chunks_exact(LANES)) {
        for l in 0..LANES {
            let r2 = rc[l] * rc[l];
            sum[l] += r2;
            let v = r2 * ic[l];
            best = if v > best { v } else { best };
        }
    }
    let t: [T; 4] = core::array::from_fn(|l| sum[l] + sum[l + 4]);
    ((t[0] + t[2]) + (t[1] + t[3]), best)
}

/// `Σ_j v_j` over `p` entries (a multiple of 8) in the order of [`residual_stats`]' sum.
#[inline(always)]
pub(crate) fn lane_sum<T: Real>(v: &[T]) -> T {
    let mut sum = [T::zero(); LANES];
    for c in v.chunks_exact(LANES) {
        for l in 0..LANES {
            sum[l] += c[l];
        }
    }
    let t: [T; 4] = core::array::from_fn(|l| sum[l] + sum[l + 4]);
    (t[0] + t[2]) + (t[1] + t[3])
}

/// Candidate weights into `w` and their running sums in the sampling order into `prefix`
/// (documented order); returns the total.
#[inline(always)]
fn candidates<T: Real>(r: &[T], inv_norm2: &[T], threshold: T, w: &mut [T], prefix: &mut [T]) -> T {
    let p = w.len();
    let (r, inv_norm2, prefix) = (&r[..p], &inv_norm2[..p], &mut prefix[..p]);
    for j in 0..p {
        let r2 = r[j] * r[j];
        w[j] = if r2 * inv_norm2[j] >= threshold {
            r2
        } else {
            T::zero()
        };
    }
    lane_major_prefix(w, prefix)
}

/// The running sums of the weights `w` (`p` entries, a multiple of 8) in the sampling order
/// (documented order) into `prefix`; returns the total.
#[inline(always)]
pub(crate) fn lane_major_prefix<T: Real>(w: &[T], prefix: &mut [T]) -> T {
    let p = w.len();
    let prefix = &mut prefix[..p];
    // Down the chunks, lane by lane: V_{c,l} = V_{c−1,l} + w_{8c+l}.
    prefix[..LANES].copy_from_slice(&w[..LANES]);
    for c in 1..p / LANES {
        for l in 0..LANES {
            prefix[LANES * c + l] = prefix[LANES * (c - 1) + l] + w[LANES * c + l];
        }
    }
    // Across the lanes: the in-chunk scan of the lane totals, shifted by one lane.
    let mut x: [T; LANES] = core::array::from_fn(|l| prefix[p - LANES + l]);
    for d in [1, 2, 4] {
        let old = x;
        for l in d..LANES {
            x[l] = old[l] + old[l - d];
        }
    }
    for c in 0..p / LANES {
        for l in 1..LANES {
            prefix[LANES * c + l] = x[l - 1] + prefix[LANES * c + l];
        }
    }
    x[LANES - 1]
}

/// The row drawn for `target` (documented order: lanes, then chunks), `None` if every
/// weight is zero.
#[inline(always)]
pub(crate) fn draw_row<T: Real>(w: &[T], prefix: &[T], target: T) -> Option<usize> {
    let chunks = w.len() / LANES;
    let mut last_positive = None;
    for l in 0..LANES {
        for c in 0..chunks {
            let j = LANES * c + l;
            if w[j] > T::zero() {
                if prefix[j] > target {
                    return Some(j);
                }
                last_positive = Some(j);
            }
        }
    }
    last_positive
}

/// The index of the largest `r_j²/‖a_j‖²` (the first, on ties; 0 if all are zero).
pub(crate) fn argmax_ratio<T: Real>(r: &[T], inv_norm2: &[T]) -> usize {
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

/// The portable greedy loop (see [`Kernels::iterate`]).
#[inline(always)]
pub(crate) fn iterate_portable<T: Real, const AVERAGE: bool>(
    w: Window<'_, T>,
    mut rnorm2: T,
    mut max_ratio: T,
    s: Schedule<T>,
    rng: &mut ChaCha8Rng,
) -> (usize, bool) {
    let p = w.p;
    let (r, inv_norm2) = (&mut w.resid[..p], &w.inv_norm2[..p]);
    let mut draws = Draws::new(rng, s.t_total);
    let mut iterations = 0;
    let mut converged = rnorm2 <= s.tol2;
    while !converged && iterations < s.t_total {
        iterations += 1;
        let threshold = s.threshold(rnorm2, max_ratio);
        let total = candidates(
            r,
            inv_norm2,
            threshold,
            &mut w.weights[..p],
            &mut w.prefix[..p],
        );
        let chosen = if total > T::zero() {
            let target = T::cast(draws.next()) * total;
            draw_row(&w.weights[..p], &w.prefix[..p], target)
        } else {
            None
        };
        // Round-off emptied the candidate set: the largest ratio always qualifies.
        let i = chosen.unwrap_or_else(|| argmax_ratio(r, inv_norm2));
        let alpha = r[i] * inv_norm2[i];
        w.coef[i] += alpha;
        if AVERAGE {
            w.coef_avg[i] += alpha * s.weight(iterations);
        }
        // r ← r − α A a_i = r − α G e_i; the projection zeroes r_i exactly.
        let g = &w.gram[i * p..(i + 1) * p];
        for j in 0..p {
            r[j] -= alpha * g[j];
        }
        r[i] = T::zero();
        (rnorm2, max_ratio) = residual_stats(r, inv_norm2);
        converged = rnorm2 <= s.tol2;
    }
    draws.finish();
    (iterations, converged)
}
