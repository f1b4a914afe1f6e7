//! The greedy loop of [`crate::greedy::iterate_portable`], written once over chunks of eight
//! lanes ([`Lanes8`]).
//!
//! It serves the SIMD units without AVX-512's masks and 512-bit registers.
//! On AVX2 a chunk is two `ymm` in `f64`, one in `f32`.
//! On NEON it is four `q` registers in `f64`, two in `f32`.
//!
//! A chunk of eight lanes is exactly a chunk of the documented order (see the `greedy`
//! module). So every operation below is one of the portable loop's, lane for lane, in the same
//! order. Multiplies and adds stay separate (never fused); sums keep the same association;
//! comparisons are the same. The squares `r_j²`, ratios `r_j²/‖a_j‖²` and reciprocal norms of
//! a window of up to 32 rows stay in registers (or the compiler's spill slots) across the
//! iterations. The residual is stored once per iteration and read once by the next update. The
//! row choice is a bit scan over lane masks instead of a search through memory.

use rand_chacha::ChaCha8Rng;

use crate::Real;
use crate::greedy::{Draws, LANES, Schedule, Window, argmax_ratio};

/// Chunks a window may have for [`iterate_chunks`] (`p ≤ 32`, windows of up to 32 rows).
pub(crate) const MAX_CHUNKS: usize = 4;

/// Entries of a [`Lanes8::keep_table`]: all-ones bit patterns except a zero at
/// [`KEEP_ZERO`], so that the eight entries from `KEEP_ZERO − i + 8c` mask out lane `i` of
/// chunk `c` and nothing else.
pub(crate) const KEEP_LEN: usize = 2 * LANES * MAX_CHUNKS;
/// Where the zero of a keep table sits.
pub(crate) const KEEP_ZERO: usize = LANES * MAX_CHUNKS;

/// A keep table of `f64` (see [`KEEP_LEN`]): `r & keep` zeroes one lane exactly (`+0`).
pub(crate) static KEEP_F64: [f64; KEEP_LEN] = {
    let mut t = [f64::from_bits(u64::MAX); KEEP_LEN];
    t[KEEP_ZERO] = 0.0;
    t
};
/// A keep table of `f32` (see [`KEEP_LEN`]).
pub(crate) static KEEP_F32: [f32; KEEP_LEN] = {
    let mut t = [f32::from_bits(u32::MAX); KEEP_LEN];
    t[KEEP_ZERO] = 0.0;
    t
};

/// `LANE_MAJOR_U64[c][l] = 1 << (4l + c)`: the bit of row `8c + l` in lane-major order, for
/// [`Lanes8::lane_major_bits`] of 64-bit lanes (AND with a lane mask, OR across chunks).
#[cfg_attr(not(target_arch = "aarch64"), allow(dead_code))] // AVX2 packs its masks instead
pub(crate) static LANE_MAJOR_U64: [[u64; LANES]; MAX_CHUNKS] = {
    let mut t = [[0u64; LANES]; MAX_CHUNKS];
    let mut c = 0;
    while c < MAX_CHUNKS {
        let mut l = 0;
        while l < LANES {
            t[c][l] = 1 << (4 * l + c);
            l += 1;
        }
        c += 1;
    }
    t
};
/// [`LANE_MAJOR_U64`] for 32-bit lanes.
pub(crate) static LANE_MAJOR_U32: [[u32; LANES]; MAX_CHUNKS] = {
    let mut t = [[0u32; LANES]; MAX_CHUNKS];
    let mut c = 0;
    while c < MAX_CHUNKS {
        let mut l = 0;
        while l < LANES {
            t[c][l] = 1 << (4 * l + c);
            l += 1;
        }
        c += 1;
    }
    t
};

/// Eight lanes of a SIMD unit. Every method is a lane-wise IEEE-754 operation (or a bit
/// operation) with the semantics written next to it; implementations must be
/// `#[inline(always)]` and are only ever called from functions compiled for the instruction
/// set they use.
pub(crate) trait Lanes8: Copy {
    /// The scalar of a lane.
    type T: Real;

    /// Whether [`iterate_chunks`] keeps the residual negated in memory, `−r`.
    ///
    /// Then its update `−r + α g` is an add with the residual as a memory operand (x86),
    /// instead of a load and a subtraction. On a load/store architecture it gains nothing.
    const NEGATED_RESIDUAL: bool = false;

    /// Eight scalars from `p`.
    ///
    /// # Safety
    /// `p` must be valid for reading eight scalars.
    unsafe fn load(p: *const Self::T) -> Self;
    /// Eight scalars to `p`.
    ///
    /// # Safety
    /// `p` must be valid for writing eight scalars.
    unsafe fn store(self, p: *mut Self::T);
    /// `x` in every lane.
    fn splat(x: Self::T) -> Self;
    /// Lane 0.
    fn first(self) -> Self::T;
    /// `self + o`.
    fn add(self, o: Self) -> Self;
    /// `self − o`.
    fn sub(self, o: Self) -> Self;
    /// `+0 − self`: the negation, up to the sign of a zero.
    #[inline(always)]
    fn neg(self) -> Self {
        Self::splat(Self::T::cast(0.0)).sub(self)
    }
    /// `self · o`.
    fn mul(self, o: Self) -> Self;
    /// Bitwise `self & o` (with a keep table's entries: lanes kept or set to `+0`).
    fn and(self, o: Self) -> Self;
    /// `if self > best { self } else { best }` (so a NaN in `self` keeps `best`).
    fn max_onto(self, best: Self) -> Self;
    /// All-ones lanes where `self ≥ t`, zero elsewhere (false on NaN).
    fn ge_mask(self, t: Self) -> Self;
    /// All-ones lanes where `self > t`, zero elsewhere (false on NaN).
    fn gt_mask(self, t: Self) -> Self;
    /// The lane masks of `C` chunks as bits in lane-major order: bit `4l + c` set when lane
    /// `l` of `masks[c]` is (see [`LANE_MAJOR_U64`]).
    fn lane_major_bits<const C: usize>(masks: &[Self; C]) -> u32;
    /// Lane `l` takes lane `l − D` (`D ∈ {1, 2, 4}`), lanes below `D` take `+0`.
    fn shift<const D: usize>(self) -> Self;
    /// `self + self.shift::<4>()` for lanes that are never `−0` (the lanes below 4 add `+0`,
    /// which leaves any other value's bits as they are, so an implementation may skip it).
    #[inline(always)]
    fn add_shift4(self) -> Self {
        self.add(self.shift::<4>())
    }
    /// Lane 7 in every lane.
    fn broadcast_last(self) -> Self;
    /// In every lane: `t_l = x_l + x_{l+4}`, then `(t₀ + t₂) + (t₁ + t₃)` (the documented sum).
    fn sum_all(self) -> Self;
    /// In every lane: the largest lane (no lane may be NaN).
    fn max_all(self) -> Self;
    /// The keep table of this scalar.
    fn keep_table() -> &'static [Self::T; KEEP_LEN];
}

/// The documented in-chunk scan `x_l ← x_l + x_{l−d}`, `d = 1, 2, 4`. Lanes below `d` add
/// `+0` instead of nothing, which changes no bit: they hold sums of weights, never `−0`.
#[inline(always)]
fn scan8<V: Lanes8>(x: V) -> V {
    let x = x.add(x.shift::<1>());
    let x = x.add(x.shift::<2>());
    x.add_shift4()
}

/// The greedy loop of [`crate::greedy::iterate_portable`] on a window of `p = 8C ≤ 32` rows
/// held in chunks of [`Lanes8`]: the same operations in the same order, the same bits.
///
/// # Safety
/// Must be inlined into a function compiled for `V`'s instruction set.
#[inline(always)]
pub(crate) unsafe fn iterate_chunks<V: Lanes8, const C: usize, const AVERAGE: bool>(
    w: Window<'_, V::T>,
    mut rnorm2: V::T,
    max_ratio: V::T,
    s: Schedule<V::T>,
    rng: &mut ChaCha8Rng,
) -> (usize, bool) {
    let p = LANES * C;
    assert!(
        C <= MAX_CHUNKS
            && w.p == p
            && w.resid.len() >= p
            && w.inv_norm2.len() >= p
            && w.gram.len() >= p * p
            && w.coef.len() >= p
            && w.coef_avg.len() >= p
    );
    let (rp, ip, gp) = (w.resid.as_mut_ptr(), w.inv_norm2.as_ptr(), w.gram.as_ptr());
    let keep = V::keep_table().as_ptr();
    // SAFETY (every pointer access below): below p entries of the residual and the reciprocal
    // norms, below p² of the Gram matrix, below KEEP_LEN of the keep table (checked above).
    // Squares r_j² and ratios r_j²/‖a_j‖² of the current residual; the residual itself lives
    // in memory (stored every iteration, read once per iteration by the update).
    // (Loops, not `array::from_fn`: a closure the compiler leaves out of line is not compiled
    // for the SIMD instruction set.)
    // With `V::NEGATED_RESIDUAL` the residual in memory is `−r` during the iterations (the
    // same squares; `α = (−(−r_i))/‖a_i‖²` exactly; only signs of zero residuals can differ,
    // which no coefficient sees: a zero α adds nothing to a coefficient, and coefficients
    // start at `+0`).
    let zero = V::splat(V::T::cast(0.0));
    let (mut sq, mut inv, mut ratio) = ([zero; C], [zero; C], [zero; C]);
    for c in 0..C {
        let r = unsafe { V::load(rp.add(LANES * c)) };
        if V::NEGATED_RESIDUAL {
            unsafe { r.neg().store(rp.add(LANES * c)) };
        }
        sq[c] = r.mul(r);
        inv[c] = unsafe { V::load(ip.add(LANES * c)) };
        ratio[c] = sq[c].mul(inv[c]);
    }
    let half = V::splat(V::T::cast(0.5));
    let half_inv_fro2 = V::splat(s.half_inv_fro2);

    let mut sum_v = V::splat(rnorm2);
    let mut max_v = V::splat(max_ratio);
    let mut draws = Draws::new(rng, s.t_total);
    let mut iterations = 0;
    let mut converged = rnorm2 <= s.tol2;
    // A window's draws in one batch when they fit (`T ≤ 32`: the AVX2 and NEON windows), read
    // by index: iteration `s` (1-based) takes draw `s − 1 − skipped`, `skipped` counting the
    // iterations that took none (every weight zero), so every index is below `s ≤ T`.
    let prefilled = !converged && draws.prefill();
    let mut skipped = 0;
    while !converged && iterations < s.t_total {
        iterations += 1;
        // θ = M·½ + S·(½/‖A‖_F²), with S and M held in every lane.
        let threshold = max_v.mul(half).add(sum_v.mul(half_inv_fro2));
        // Candidate weights r_j² (where r_j²/‖a_j‖² ≥ θ), their running sums down the chunks,
        // lane by lane, then across the lanes. Rows are drawn among positive weights only (a
        // candidate's weight can be zero when θ underflows to zero).
        let mut weights = [zero; C];
        for c in 0..C {
            weights[c] = ratio[c].ge_mask(threshold).and(sq[c]);
        }
        let (down, before, total) = prefix_chunks(&weights);
        let mut chosen = None;
        if total.first() > V::T::cast(0.0) {
            let u = if prefilled {
                // SAFETY: `iterations − 1 − skipped < T` (see above).
                unsafe { draws.prefilled(iterations - 1 - skipped) }
            } else {
                draws.next()
            };
            let target = V::splat(V::T::cast(u)).mul(total);
            // The first row in lane-major order with P > target, whatever its weight, is the
            // row `pick_chunks` draws when its weight is positive (then it is the first row of
            // positive weight with P > target). It nearly always is: a zero weight leaves the
            // running sum as it was, so a zero-weight row with P > target follows one with the
            // same P earlier in its lane, or starts its lane, where only round-off between the
            // scan across the lanes and the sums down them can put P above the target. Else,
            // and when no row has P > target, `pick_chunks` with the positive masks (weights
            // from the residual in memory, the current one, so the candidate masks need not
            // stay in registers).
            let theta = threshold.first();
            chosen = match first_above(&down, before, target) {
                // SAFETY: j < p entries of each.
                Some(j) if unsafe { positive_in_memory(rp, ip, j, theta) } => Some(j),
                _ => {
                    let mut positive = [zero; C];
                    for (c, positive) in positive.iter_mut().enumerate() {
                        // SAFETY: p entries of each.
                        let (r, inv) =
                            unsafe { (V::load(rp.add(LANES * c)), V::load(ip.add(LANES * c))) };
                        let sq = r.mul(r);
                        *positive = sq.mul(inv).ge_mask(threshold).and(sq).gt_mask(zero);
                    }
                    pick_chunks(&positive, &down, before, target)
                }
            };
        } else {
            skipped += 1;
        }
        // The residual in memory is the current one (stored every iteration).
        // SAFETY: p entries of each, and no other live reference to the residual.
        let i = match chosen {
            Some(i) => i,
            None => unsafe { argmax_in_memory(rp, ip, p) },
        };
        // SAFETY: i < p (a row of the window), and p entries of each (checked above).
        let alpha = unsafe {
            let r = *rp.add(i);
            let r = if V::NEGATED_RESIDUAL { -r } else { r };
            r * *ip.add(i)
        };
        // SAFETY: as above.
        unsafe { *w.coef.get_unchecked_mut(i) += alpha };
        if AVERAGE {
            // In the burn-in the weight is (T − t_b)/(T − t_b) = 1 exactly, and α · 1 = α:
            // the division is skipped, not the bits.
            let step = if iterations > s.t_b {
                alpha * s.weight(iterations)
            } else {
                alpha
            };
            // SAFETY: as above.
            unsafe { *w.coef_avg.get_unchecked_mut(i) += step };
        }
        // r ← r − α G e_i, r_i ← 0, and the statistics of the new residual: squares summed
        // chunk by chunk into eight lane sums (the first chunk's squares are the sums:
        // 0 + x = x, squares are never −0), then across the lanes.
        let a = V::splat(alpha);
        // SAFETY: row i < p of the Gram matrix; KEEP_ZERO − i + 8c + 8 ≤ KEEP_LEN.
        let (g, k) = unsafe { (gp.add(i * p), keep.add(KEEP_ZERO - i)) };
        let mut sum = zero;
        let mut best = zero;
        for c in 0..C {
            // SAFETY: as above.
            let v = unsafe {
                let (rc, gc) = (V::load(rp.add(LANES * c)), V::load(g.add(LANES * c)));
                // −r + α g = −(r − α g) exactly: IEEE-754 rounds symmetrically.
                let v = if V::NEGATED_RESIDUAL {
                    a.mul(gc).add(rc)
                } else {
                    rc.sub(a.mul(gc))
                };
                let v = v.and(V::load(k.add(LANES * c)));
                v.store(rp.add(LANES * c));
                v
            };
            sq[c] = v.mul(v);
            ratio[c] = sq[c].mul(inv[c]);
            best = ratio[c].max_onto(best);
            sum = if c == 0 { sq[c] } else { sum.add(sq[c]) };
        }
        sum_v = sum.sum_all();
        max_v = best.max_all();
        rnorm2 = sum_v.first();
        converged = rnorm2 <= s.tol2;
    }
    if prefilled {
        draws.taken(iterations - skipped);
    }
    draws.finish();
    if V::NEGATED_RESIDUAL {
        for c in 0..C {
            // SAFETY: p entries of the residual.
            unsafe {
                let q = V::load(rp.add(LANES * c));
                q.neg().store(rp.add(LANES * c));
            }
        }
    }
    (iterations, converged)
}

/// The running sums of the weights in the sampling order (documented order): the sums down
/// the chunks `V_{c,l}`, the in-chunk scan of the lane totals shifted by one lane (`x_{l−1}`,
/// `+0` in lane 0) and the total in every lane. `P_{c,l} = x_{l−1} + V_{c,l}`.
#[inline(always)]
pub(crate) fn prefix_chunks<V: Lanes8, const C: usize>(weights: &[V; C]) -> ([V; C], V, V) {
    let mut down = *weights;
    for c in 1..C {
        down[c] = down[c - 1].add(weights[c]);
    }
    let across = scan8(down[C - 1]);
    (down, across.shift::<1>(), across.broadcast_last())
}

/// The row drawn for `target`, in the documented order and by the rule of
/// [`crate::greedy::draw_row`]. The masks of the positive weights are given (all-ones lanes
/// where `w > 0`). The row is the first in lane-major order with a positive weight and
/// `P > target`. On round-off it is the last with a positive weight; `None` if no weight is
/// positive. Rows are drawn among positive weights only. A candidate's weight can be zero when
/// the threshold underflows to zero. Its running sum can still exceed the target by round-off,
/// since the scan across the lanes is not the sequential sum.
#[inline(always)]
pub(crate) fn pick_chunks<V: Lanes8, const C: usize>(
    positive: &[V; C],
    down: &[V; C],
    before: V,
    target: V,
) -> Option<usize> {
    let zero = V::splat(V::T::cast(0.0));
    // Bits in lane-major order (bit 4l + c for row 8c + l).
    let mut hits = [zero; C];
    for c in 0..C {
        hits[c] = positive[c].and(before.add(down[c]).gt_mask(target));
    }
    let hit = V::lane_major_bits(&hits);
    if hit != 0 {
        Some(lane_major_row(hit.trailing_zeros()))
    } else {
        // Round-off: the last positive weight in lane-major order.
        let positive = V::lane_major_bits(positive);
        (positive != 0).then(|| lane_major_row(31 - positive.leading_zeros()))
    }
}

/// The row of bit `4l + c` of [`Lanes8::lane_major_bits`]: `8c + l`.
#[inline(always)]
fn lane_major_row(bit: u32) -> usize {
    LANES * (bit as usize % 4) + bit as usize / 4
}

/// The first row in lane-major order with `P > target` (`P_{c,l} = before_l + down_{c,l}`, as
/// in [`pick_chunks`]), whatever its weight; `None` if there is none.
#[inline(always)]
pub(crate) fn first_above<V: Lanes8, const C: usize>(
    down: &[V; C],
    before: V,
    target: V,
) -> Option<usize> {
    let zero = V::splat(V::T::cast(0.0));
    let mut hits = [zero; C];
    for c in 0..C {
        hits[c] = before.add(down[c]).gt_mask(target);
    }
    let hit = V::lane_major_bits(&hits);
    (hit != 0).then(|| lane_major_row(hit.trailing_zeros()))
}

/// Whether row `j`'s weight is positive, from the residual and reciprocal norms in memory by
/// the loop's own operations: `r_j²·(1/‖a_j‖²) ≥ θ` (a candidate) and `r_j² > 0`.
///
/// # Safety
/// `r` and `inv_norm2` must be valid for reading `j + 1` scalars.
#[inline(always)]
unsafe fn positive_in_memory<T: Real>(
    r: *const T,
    inv_norm2: *const T,
    j: usize,
    theta: T,
) -> bool {
    // SAFETY: the caller's promise.
    let (r, inv) = unsafe { (*r.add(j), *inv_norm2.add(j)) };
    let sq = r * r;
    sq * inv >= theta && sq > T::cast(0.0)
}

/// [`argmax_ratio`] over the residual and reciprocal norms in memory, out of line: the loop
/// calls it only when every weight is zero, and inlined the compiler would keep copies of the
/// residual's lanes ready for it on every iteration.
///
/// # Safety
/// `r` and `inv_norm2` must be valid for reading `p` scalars, and not written meanwhile.
#[cold]
#[inline(never)]
unsafe fn argmax_in_memory<T: Real>(r: *const T, inv_norm2: *const T, p: usize) -> usize {
    // SAFETY: the caller's promise.
    unsafe {
        argmax_ratio(
            core::slice::from_raw_parts(r, p),
            core::slice::from_raw_parts(inv_norm2, p),
        )
    }
}

/// [`iterate_chunks`] for a window of `chunks ≤ 4` chunks.
///
/// # Safety
/// As [`iterate_chunks`].
#[inline(always)]
pub(crate) unsafe fn iterate_any<V: Lanes8, const AVERAGE: bool>(
    chunks: usize,
    w: Window<'_, V::T>,
    rnorm2: V::T,
    max_ratio: V::T,
    s: Schedule<V::T>,
    rng: &mut ChaCha8Rng,
) -> (usize, bool) {
    // SAFETY: the caller's promise.
    unsafe {
        match chunks {
            1 => iterate_chunks::<V, 1, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            2 => iterate_chunks::<V, 2, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            3 => iterate_chunks::<V, 3, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            _ => iterate_chunks::<V, 4, AVERAGE>(w, rnorm2, max_ratio, s, rng),
        }
    }
}
