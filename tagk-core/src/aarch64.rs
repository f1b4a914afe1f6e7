//! NEON kernels of the greedy iterations on aarch64 (NEON is part of the base instruction
//! set there, so they are chosen at compile time, with or without `std`).
//!
//! The Gram matrix is built from a transposed copy of the window in sixteen `q` accumulators.
//! `f64` uses 4 × 8 tiles and computes the prior residual in the transposing pass.
//! `f32` uses 8 × 8 tiles and takes its residual from the portable loop.
//! The greedy loop is the eight-lane loop of the `lanes` module: four `q` registers per chunk
//! in `f64`, two in `f32`. Same operations in the same order as [`crate::greedy::Portable`] (multiplies and adds
//! separate, never fused), so estimates are bit-identical to x86-64's and a microcontroller's.

use core::any::TypeId;
use core::arch::aarch64::*;

use rand_chacha::ChaCha8Rng;

use crate::Real;
use crate::greedy::{Kernels, LANES, Portable, Schedule, Window, iterate_portable};
use crate::lanes::{
    KEEP_F32, KEEP_F64, KEEP_LEN, LANE_MAJOR_U32, LANE_MAJOR_U64, Lanes8, MAX_CHUNKS, iterate_any,
};
use crate::linalg::padded;

/// The NEON kernels (no run-time detection needed: NEON is baseline on aarch64).
#[derive(Clone, Copy)]
pub(crate) struct Neon;

#[inline(always)]
fn is<T: 'static, U: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<U>()
}

/// `s` as `&[U]` when `T` is `U`.
#[inline(always)]
fn same<T: 'static, U: 'static>(s: &[T]) -> &[U] {
    assert!(is::<T, U>());
    // SAFETY: T and U are the same type (checked above), so this is the identity cast.
    unsafe { core::slice::from_raw_parts(s.as_ptr().cast(), s.len()) }
}

/// `s` as `&mut [U]` when `T` is `U`.
#[inline(always)]
fn same_mut<T: 'static, U: 'static>(s: &mut [T]) -> &mut [U] {
    assert!(is::<T, U>());
    // SAFETY: T and U are the same type (checked above), so this is the identity cast.
    unsafe { core::slice::from_raw_parts_mut(s.as_mut_ptr().cast(), s.len()) }
}

/// The window and schedule of scalar `T` as those of `U` (the same type).
#[inline(always)]
fn same_window<T: Real, U: Real>(w: Window<'_, T>, s: Schedule<T>) -> (Window<'_, U>, Schedule<U>) {
    (
        Window {
            p: w.p,
            resid: same_mut(w.resid),
            inv_norm2: same(w.inv_norm2),
            gram: same(w.gram),
            coef: same_mut(w.coef),
            coef_avg: same_mut(w.coef_avg),
            weights: same_mut(w.weights),
            prefix: same_mut(w.prefix),
        },
        Schedule {
            t_total: s.t_total,
            t_b: s.t_b,
            tol2: U::cast(s.tol2.as_f64()),
            half_inv_fro2: U::cast(s.half_inv_fro2.as_f64()),
        },
    )
}

impl<T: Real> Kernels<T> for Neon {
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
        if is::<T, f32>() {
            // The portable order (a transposed copy, then 8 × 8 tiles) in NEON registers.
            let p = padded(m);
            let (at32, gram32): (&mut [f32], &mut [f32]) = (same_mut(at), same_mut(gram));
            assert!(at32.len() >= n * p && gram32.len() >= p * p);
            crate::linalg::transpose_padded(same::<T, f32>(a), n, m, at32);
            // SAFETY: the lengths were checked above.
            unsafe { gram_f32(at32.as_ptr(), n, p, gram32.as_mut_ptr()) };
            crate::linalg::residual_rows(a, n, m, x, b, resid);
            return;
        }
        if !is::<T, f64>() {
            return Portable.gram_and_residual(a, b, x, n, m, at, gram, resid);
        }
        let p = padded(m);
        let (at, gram): (&mut [f64], &mut [f64]) = (same_mut(at), same_mut(gram));
        assert!(at.len() >= n * p && gram.len() >= p * p);
        transpose_and_residual_f64(same(a), same(b), same(x), n, m, at, same_mut(resid));
        let mut bj = 0;
        while bj < m {
            // SAFETY: `at` holds n × p and `gram` p × p entries (checked above), bj + 8 ≤ p.
            unsafe { gram_panel(at.as_ptr(), n, m, p, bj, gram.as_mut_ptr()) };
            bj += LANES;
        }
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
        if w.p > LANES * MAX_CHUNKS {
            return iterate_portable::<T, AVERAGE>(w, rnorm2, max_ratio, s, rng);
        }
        let chunks = w.p / LANES;
        if is::<T, f64>() {
            let (w, s) = same_window::<T, f64>(w, s);
            iterate_neon::<F64x8, AVERAGE>(chunks, w, rnorm2.as_f64(), max_ratio.as_f64(), s, rng)
        } else if is::<T, f32>() {
            let (w, s) = same_window::<T, f32>(w, s);
            let (rnorm2, max_ratio) = (rnorm2.as_f64() as f32, max_ratio.as_f64() as f32);
            iterate_neon::<F32x8, AVERAGE>(chunks, w, rnorm2, max_ratio, s, rng)
        } else {
            iterate_portable::<T, AVERAGE>(w, rnorm2, max_ratio, s, rng)
        }
    }
}

/// `at[k p + j] = a[j n + k]`: the window transposed, `p = padded(m)` columns, zero from `m`
/// on. The same loads give `r_j = b_j − a_jᵀx` (zero from `m` to `p`). Each dot product is
/// summed as [`crate::linalg::dot`] does. Partial sums `s_{k mod 4}` run over the first
/// `4⌊n/4⌋` entries (lanes of two `q` registers). They are combined as
/// `(s₀ + s₂) + (s₁ + s₃)`, then the remaining entries are added in order. Rows go in pairs,
/// as 2 × 2 transposes.
fn transpose_and_residual_f64(
    a: &[f64],
    b: &[f64],
    x: &[f64],
    n: usize,
    m: usize,
    at: &mut [f64],
    resid: &mut [f64],
) {
    let p = padded(m);
    let n4 = n - n % 4;
    assert!(
        a.len() >= m * n && b.len() >= m && x.len() >= n && at.len() >= n * p && resid.len() >= p
    );
    let (ap, xp, tp) = (a.as_ptr(), x.as_ptr(), at.as_mut_ptr());
    let mut j = 0;
    while j < p {
        if j >= m {
            for k in 0..n {
                at[k * p + j] = 0.0;
                at[k * p + j + 1] = 0.0;
            }
            resid[j] = 0.0;
            resid[j + 1] = 0.0;
            j += 2;
            continue;
        }
        let pair = j + 1 < m;
        // SAFETY: NEON is baseline on aarch64; reads rows j (and j + 1 if `pair`) of `a` below
        // column n and `x` below n, writes `at` below n · p (checked above).
        unsafe {
            let r0 = ap.add(j * n);
            let r1 = ap.add((j + usize::from(pair)) * n);
            let load = |k: usize| {
                let q0 = vld1q_f64(r0.add(k));
                let q1 = if pair {
                    vld1q_f64(r1.add(k))
                } else {
                    vdupq_n_f64(0.0)
                };
                vst1q_f64(tp.add(k * p + j), vzip1q_f64(q0, q1));
                vst1q_f64(tp.add((k + 1) * p + j), vzip2q_f64(q0, q1));
                (q0, q1)
            };
            let zero = vdupq_n_f64(0.0);
            let (mut lo0, mut hi0, mut lo1, mut hi1) = (zero, zero, zero, zero);
            let mut k = 0;
            while k < n4 {
                let xlo = vld1q_f64(xp.add(k));
                let xhi = vld1q_f64(xp.add(k + 2));
                let (a0, a1) = load(k);
                lo0 = vaddq_f64(vmulq_f64(a0, xlo), lo0);
                lo1 = vaddq_f64(vmulq_f64(a1, xlo), lo1);
                let (a0, a1) = load(k + 2);
                hi0 = vaddq_f64(vmulq_f64(a0, xhi), hi0);
                hi1 = vaddq_f64(vmulq_f64(a1, xhi), hi1);
                k += 4;
            }
            while k + 2 <= n {
                load(k);
                k += 2;
            }
            if k < n {
                *tp.add(k * p + j) = *r0.add(k);
                *tp.add(k * p + j + 1) = if pair { *r1.add(k) } else { 0.0 };
            }
            let mut sums = [
                vaddvq_f64(vaddq_f64(lo0, hi0)),
                vaddvq_f64(vaddq_f64(lo1, hi1)),
            ];
            for k in n4..n {
                sums[0] = *r0.add(k) * x[k] + sums[0];
                sums[1] = *r1.add(k) * x[k] + sums[1];
            }
            resid[j] = b[j] - sums[0];
            resid[j + 1] = if pair { b[j + 1] - sums[1] } else { 0.0 };
        }
        j += 2;
    }
}

/// The tiles `G[I, J]`, `I ≤ J`, of the panel `J = bj..bj+8` of `G = A Aᵀ` (`f64`) from the
/// transposed window `at` (`n × p`, stride `p`). They are 4 × 8 tiles of sixteen `q`
/// accumulators. Each entry is summed in order of `k` (multiply, then add), as
/// `gram_transposed` does. In the diagonal block, the lower four rows are computed only right
/// of its split (a 4 × 4 tile). Their left quarter is the upper-right one's mirror image: the
/// same products in the same order. Columns from `m` on are padding: they are not computed but
/// written as zeros. Rows from `m` on are left unspecified, as the kernel contract allows.
///
/// # Safety
/// `at` must hold `n · p` and `gram` `p · p` entries, `bj + 8 ≤ p`, `bj < m`.
#[inline(never)]
unsafe fn gram_panel(at: *const f64, n: usize, m: usize, p: usize, bj: usize, gram: *mut f64) {
    // Column pairs holding rows below m, in the panel and in its right half.
    let pairs = ((m - bj).min(8) + 1) / 2;
    let lower = ((m - bj).saturating_sub(4).min(4) + 1) / 2;
    // SAFETY: the caller's promise.
    unsafe {
        match pairs {
            1 => panel_tiles::<1>(at, n, p, bj, gram),
            2 => panel_tiles::<2>(at, n, p, bj, gram),
            3 => panel_tiles::<3>(at, n, p, bj, gram),
            _ => panel_tiles::<4>(at, n, p, bj, gram),
        }
        match lower {
            0 => {}
            1 => lower_tile::<1>(at, n, p, bj, gram),
            _ => lower_tile::<2>(at, n, p, bj, gram),
        }
    }
}

/// The 4-row tiles of [`gram_panel`] over its first `2Q` columns (zeros in the others).
///
/// # Safety
/// As [`gram_panel`].
#[inline(always)]
unsafe fn panel_tiles<const Q: usize>(
    at: *const f64,
    n: usize,
    p: usize,
    bj: usize,
    gram: *mut f64,
) {
    // SAFETY: every access is below n · p of `at` and p · p of `gram` (the caller's promise).
    unsafe {
        let zero = vdupq_n_f64(0.0);
        let mut bi = 0;
        while bi <= bj {
            let c = tile::<Q>(at, n, p, bi, bj);
            for s in 0..4 {
                let row = gram.add((bi + s) * p + bj);
                for q in 0..4 {
                    vst1q_f64(row.add(2 * q), if q < Q { c[s][q] } else { zero });
                }
            }
            // The mirror image, rows bj.. (in the diagonal block only bj+4..), columns
            // bi..bi+4, as 2 × 2 transposes.
            for q in if bi == bj { 2..Q } else { 0..Q } {
                for s in [0, 2] {
                    let (x, y) = (c[s][q], c[s + 1][q]);
                    vst1q_f64(gram.add((bj + 2 * q) * p + bi + s), vzip1q_f64(x, y));
                    vst1q_f64(gram.add((bj + 2 * q + 1) * p + bi + s), vzip2q_f64(x, y));
                }
            }
            bi += 4;
        }
    }
}

/// The lower-right 4 × 4 quarter of [`gram_panel`]'s diagonal block over its first `2Q`
/// columns (zeros in the others).
///
/// # Safety
/// As [`gram_panel`].
#[inline(always)]
unsafe fn lower_tile<const Q: usize>(
    at: *const f64,
    n: usize,
    p: usize,
    bj: usize,
    gram: *mut f64,
) {
    // SAFETY: as in `panel_tiles`.
    unsafe {
        let zero = vdupq_n_f64(0.0);
        let c = tile::<Q>(at, n, p, bj + 4, bj + 4);
        for (s, cs) in c.iter().enumerate() {
            let row = gram.add((bj + 4 + s) * p + bj + 4);
            for q in 0..2 {
                vst1q_f64(row.add(2 * q), if q < Q { cs[q] } else { zero });
            }
        }
    }
}

/// `c[s][q] = Σ_k at[k p + bi + s] · at[k p + bj + 2q .. +2]` for four rows `s` and `2Q`
/// columns, summed in order of `k`.
///
/// # Safety
/// As [`gram_panel`], with `bi + 4 ≤ p` and `bj + 2Q ≤ p`.
#[inline(always)]
unsafe fn tile<const Q: usize>(
    at: *const f64,
    n: usize,
    p: usize,
    bi: usize,
    bj: usize,
) -> [[float64x2_t; Q]; 4] {
    // SAFETY: the caller's promise.
    unsafe {
        let mut c = [[vdupq_n_f64(0.0); Q]; 4];
        // Two values of k per pass (the same order: k, then k + 1), to halve the loop's
        // bookkeeping.
        let mut row = at;
        for _ in 0..n / 2 {
            tile_step(&mut c, row, bi, bj);
            tile_step(&mut c, row.add(p), bi, bj);
            row = row.add(2 * p);
        }
        if n % 2 == 1 {
            tile_step(&mut c, row, bi, bj);
        }
        c
    }
}

/// One `k` of [`tile`], `row` pointing at row `k` of `at`.
///
/// # Safety
/// As [`tile`].
#[inline(always)]
unsafe fn tile_step<const Q: usize>(
    c: &mut [[float64x2_t; Q]; 4],
    row: *const f64,
    bi: usize,
    bj: usize,
) {
    // SAFETY: the caller's promise.
    unsafe {
        let v: [float64x2_t; Q] = core::array::from_fn(|q| vld1q_f64(row.add(bj + 2 * q)));
        let u01 = vld1q_f64(row.add(bi));
        let u23 = vld1q_f64(row.add(bi + 2));
        for q in 0..Q {
            c[0][q] = vaddq_f64(vmulq_laneq_f64::<0>(v[q], u01), c[0][q]);
            c[1][q] = vaddq_f64(vmulq_laneq_f64::<1>(v[q], u01), c[1][q]);
            c[2][q] = vaddq_f64(vmulq_laneq_f64::<0>(v[q], u23), c[2][q]);
            c[3][q] = vaddq_f64(vmulq_laneq_f64::<1>(v[q], u23), c[3][q]);
        }
    }
}

/// `G = A Aᵀ` for `f32` from the transposed window `at` (`n × p`, stride `p`, zero in the
/// padding columns). Each block pair `I ≤ J` of eight rows is an 8 × 8 tile in sixteen `q`
/// accumulators. Each entry is summed in order of `k` (multiply, then add), as
/// `gram_transposed` does. The tile is stored with its mirror image `G[J, I]`: the same
/// products in the same order.
///
/// # Safety
/// `at` must hold `n · p` entries and `gram` `p · p`, `p` a multiple of 8.
#[inline(never)]
unsafe fn gram_f32(at: *const f32, n: usize, p: usize, gram: *mut f32) {
    // SAFETY: every access is below n · p of `at` and p · p of `gram` (bi, bj + 8 ≤ p).
    unsafe {
        let mut bj = 0;
        while bj < p {
            let mut bi = 0;
            while bi <= bj {
                let mut c = [[vdupq_n_f32(0.0); 2]; 8];
                for k in 0..n {
                    let row = at.add(k * p);
                    let v = [vld1q_f32(row.add(bj)), vld1q_f32(row.add(bj + 4))];
                    let u = [vld1q_f32(row.add(bi)), vld1q_f32(row.add(bi + 4))];
                    for h in 0..2 {
                        c[0][h] = vaddq_f32(vmulq_laneq_f32::<0>(v[h], u[0]), c[0][h]);
                        c[1][h] = vaddq_f32(vmulq_laneq_f32::<1>(v[h], u[0]), c[1][h]);
                        c[2][h] = vaddq_f32(vmulq_laneq_f32::<2>(v[h], u[0]), c[2][h]);
                        c[3][h] = vaddq_f32(vmulq_laneq_f32::<3>(v[h], u[0]), c[3][h]);
                        c[4][h] = vaddq_f32(vmulq_laneq_f32::<0>(v[h], u[1]), c[4][h]);
                        c[5][h] = vaddq_f32(vmulq_laneq_f32::<1>(v[h], u[1]), c[5][h]);
                        c[6][h] = vaddq_f32(vmulq_laneq_f32::<2>(v[h], u[1]), c[6][h]);
                        c[7][h] = vaddq_f32(vmulq_laneq_f32::<3>(v[h], u[1]), c[7][h]);
                    }
                }
                for (s, cs) in c.iter().enumerate() {
                    vst1q_f32(gram.add((bi + s) * p + bj), cs[0]);
                    vst1q_f32(gram.add((bi + s) * p + bj + 4), cs[1]);
                }
                if bi < bj {
                    for g in 0..2 {
                        for h in 0..2 {
                            let t = transpose4_f32([
                                c[4 * g][h],
                                c[4 * g + 1][h],
                                c[4 * g + 2][h],
                                c[4 * g + 3][h],
                            ]);
                            for (l, tl) in t.iter().enumerate() {
                                vst1q_f32(gram.add((bj + 4 * h + l) * p + bi + 4 * g), *tl);
                            }
                        }
                    }
                }
                bi += 8;
            }
            bj += 8;
        }
    }
}

/// The transpose of a 4 × 4 block of `f32` held as four row registers.
#[inline(always)]
fn transpose4_f32(r: [float32x4_t; 4]) -> [float32x4_t; 4] {
    // SAFETY: NEON is baseline on aarch64.
    unsafe {
        let t0 = vreinterpretq_f64_f32(vtrn1q_f32(r[0], r[1])); // a0 b0 a2 b2
        let t1 = vreinterpretq_f64_f32(vtrn2q_f32(r[0], r[1])); // a1 b1 a3 b3
        let t2 = vreinterpretq_f64_f32(vtrn1q_f32(r[2], r[3])); // c0 d0 c2 d2
        let t3 = vreinterpretq_f64_f32(vtrn2q_f32(r[2], r[3])); // c1 d1 c3 d3
        [
            vreinterpretq_f32_f64(vtrn1q_f64(t0, t2)),
            vreinterpretq_f32_f64(vtrn1q_f64(t1, t3)),
            vreinterpretq_f32_f64(vtrn2q_f64(t0, t2)),
            vreinterpretq_f32_f64(vtrn2q_f64(t1, t3)),
        ]
    }
}

/// [`iterate_chunks`] for a window of `chunks ≤ 4` chunks.
#[inline(never)]
fn iterate_neon<V: Lanes8, const AVERAGE: bool>(
    chunks: usize,
    w: Window<'_, V::T>,
    rnorm2: V::T,
    max_ratio: V::T,
    s: Schedule<V::T>,
    rng: &mut ChaCha8Rng,
) -> (usize, bool) {
    // SAFETY: NEON is enabled for the whole crate on this target.
    unsafe { iterate_any::<V, AVERAGE>(chunks, w, rnorm2, max_ratio, s, rng) }
}

/// Eight `f64` lanes as four NEON `q` registers (lanes 0–1, 2–3, 4–5, 6–7).
#[derive(Clone, Copy)]
struct F64x8([float64x2_t; 4]);

/// Eight `f32` lanes as two NEON `q` registers (lanes 0–3, 4–7).
#[derive(Clone, Copy)]
struct F32x8([float32x4_t; 2]);

impl F64x8 {
    #[inline(always)]
    fn map(self, o: Self, f: impl Fn(float64x2_t, float64x2_t) -> float64x2_t) -> Self {
        Self(core::array::from_fn(|q| f(self.0[q], o.0[q])))
    }
}

impl F32x8 {
    #[inline(always)]
    fn map(self, o: Self, f: impl Fn(float32x4_t, float32x4_t) -> float32x4_t) -> Self {
        Self(core::array::from_fn(|q| f(self.0[q], o.0[q])))
    }
}

// SAFETY (every block in the two implementations): NEON is baseline on aarch64; pointers are
// the callers' promise.
impl Lanes8 for F64x8 {
    type T = f64;
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        Self(core::array::from_fn(|q| unsafe { vld1q_f64(p.add(2 * q)) }))
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f64) {
        for (q, v) in self.0.iter().enumerate() {
            unsafe { vst1q_f64(p.add(2 * q), *v) };
        }
    }
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Self([unsafe { vdupq_n_f64(x) }; 4])
    }
    #[inline(always)]
    fn first(self) -> f64 {
        unsafe { vgetq_lane_f64::<0>(self.0[0]) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vaddq_f64(a, b) })
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vsubq_f64(a, b) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vmulq_f64(a, b) })
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe {
            vreinterpretq_f64_u64(vandq_u64(
                vreinterpretq_u64_f64(a),
                vreinterpretq_u64_f64(b),
            ))
        })
    }
    #[inline(always)]
    fn max_onto(self, best: Self) -> Self {
        // FMAX would propagate a NaN; the portable loop keeps `best`.
        self.map(best, |v, b| unsafe { vbslq_f64(vcgtq_f64(v, b), v, b) })
    }
    #[inline(always)]
    fn ge_mask(self, t: Self) -> Self {
        self.map(t, |a, b| unsafe { vreinterpretq_f64_u64(vcgeq_f64(a, b)) })
    }
    #[inline(always)]
    fn gt_mask(self, t: Self) -> Self {
        self.map(t, |a, b| unsafe { vreinterpretq_f64_u64(vcgtq_f64(a, b)) })
    }
    #[inline(always)]
    fn lane_major_bits<const C: usize>(masks: &[Self; C]) -> u32 {
        unsafe {
            let mut acc = vdupq_n_u64(0);
            for (c, m) in masks.iter().enumerate() {
                for (q, mq) in m.0.iter().enumerate() {
                    let bits = vld1q_u64(LANE_MAJOR_U64[c].as_ptr().add(2 * q));
                    acc = vorrq_u64(acc, vandq_u64(vreinterpretq_u64_f64(*mq), bits));
                }
            }
            // The bits are disjoint: the sum of the lanes is their union.
            vaddvq_u64(acc) as u32
        }
    }
    #[inline(always)]
    fn shift<const D: usize>(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            let z = vdupq_n_f64(0.0);
            match D {
                1 => Self([
                    vextq_f64::<1>(z, x[0]),
                    vextq_f64::<1>(x[0], x[1]),
                    vextq_f64::<1>(x[1], x[2]),
                    vextq_f64::<1>(x[2], x[3]),
                ]),
                2 => Self([z, x[0], x[1], x[2]]),
                _ => Self([z, z, x[0], x[1]]),
            }
        }
    }
    #[inline(always)]
    fn broadcast_last(self) -> Self {
        Self([unsafe { vdupq_laneq_f64::<1>(self.0[3]) }; 4])
    }
    #[inline(always)]
    fn sum_all(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            // (t₀, t₁) and (t₂, t₃), then (t₀ + t₂, t₁ + t₃), then their sum.
            let t01 = vaddq_f64(x[0], x[2]);
            let t23 = vaddq_f64(x[1], x[3]);
            let u = vaddq_f64(t01, t23);
            Self([vdupq_n_f64(vgetq_lane_f64::<0>(u) + vgetq_lane_f64::<1>(u)); 4])
        }
    }
    #[inline(always)]
    fn max_all(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64 (no lane is NaN).
        unsafe {
            let m = vmaxq_f64(vmaxq_f64(x[0], x[1]), vmaxq_f64(x[2], x[3]));
            Self([vdupq_n_f64(vmaxvq_f64(m)); 4])
        }
    }
    #[inline(always)]
    fn keep_table() -> &'static [f64; KEEP_LEN] {
        &KEEP_F64
    }
}

impl Lanes8 for F32x8 {
    type T = f32;
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        Self(core::array::from_fn(|q| unsafe { vld1q_f32(p.add(4 * q)) }))
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        for (q, v) in self.0.iter().enumerate() {
            unsafe { vst1q_f32(p.add(4 * q), *v) };
        }
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        Self([unsafe { vdupq_n_f32(x) }; 2])
    }
    #[inline(always)]
    fn first(self) -> f32 {
        unsafe { vgetq_lane_f32::<0>(self.0[0]) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vaddq_f32(a, b) })
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vsubq_f32(a, b) })
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe { vmulq_f32(a, b) })
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self.map(o, |a, b| unsafe {
            vreinterpretq_f32_u32(vandq_u32(
                vreinterpretq_u32_f32(a),
                vreinterpretq_u32_f32(b),
            ))
        })
    }
    #[inline(always)]
    fn max_onto(self, best: Self) -> Self {
        // FMAX would propagate a NaN; the portable loop keeps `best`.
        self.map(best, |v, b| unsafe { vbslq_f32(vcgtq_f32(v, b), v, b) })
    }
    #[inline(always)]
    fn ge_mask(self, t: Self) -> Self {
        self.map(t, |a, b| unsafe { vreinterpretq_f32_u32(vcgeq_f32(a, b)) })
    }
    #[inline(always)]
    fn gt_mask(self, t: Self) -> Self {
        self.map(t, |a, b| unsafe { vreinterpretq_f32_u32(vcgtq_f32(a, b)) })
    }
    #[inline(always)]
    fn lane_major_bits<const C: usize>(masks: &[Self; C]) -> u32 {
        unsafe {
            let mut acc = vdupq_n_u32(0);
            for (c, m) in masks.iter().enumerate() {
                for (q, mq) in m.0.iter().enumerate() {
                    let bits = vld1q_u32(LANE_MAJOR_U32[c].as_ptr().add(4 * q));
                    acc = vorrq_u32(acc, vandq_u32(vreinterpretq_u32_f32(*mq), bits));
                }
            }
            // The bits are disjoint: the sum of the lanes is their union.
            vaddvq_u32(acc)
        }
    }
    #[inline(always)]
    fn shift<const D: usize>(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            let z = vdupq_n_f32(0.0);
            match D {
                1 => Self([vextq_f32::<3>(z, x[0]), vextq_f32::<3>(x[0], x[1])]),
                2 => Self([vextq_f32::<2>(z, x[0]), vextq_f32::<2>(x[0], x[1])]),
                _ => Self([z, x[0]]),
            }
        }
    }
    #[inline(always)]
    fn broadcast_last(self) -> Self {
        Self([unsafe { vdupq_laneq_f32::<3>(self.0[1]) }; 2])
    }
    #[inline(always)]
    fn sum_all(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            // t_l = x_l + x_{l+4}, then (t₀ + t₂, t₁ + t₃), then their sum.
            let t = vaddq_f32(x[0], x[1]);
            let u = vadd_f32(vget_low_f32(t), vget_high_f32(t));
            Self([vdupq_n_f32(vget_lane_f32::<0>(u) + vget_lane_f32::<1>(u)); 2])
        }
    }
    #[inline(always)]
    fn max_all(self) -> Self {
        let x = self.0;
        // SAFETY: NEON is baseline on aarch64 (no lane is NaN).
        unsafe { Self([vdupq_n_f32(vmaxvq_f32(vmaxq_f32(x[0], x[1]))); 2]) }
    }
    #[inline(always)]
    fn keep_table() -> &'static [f32; KEEP_LEN] {
        &KEEP_F32
    }
}
