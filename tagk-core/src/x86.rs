//! AVX2 and AVX-512 kernels of the greedy iterations on x86-64 (detected at run time).
//!
//! They perform the operations of the portable kernels ([`crate::greedy::Portable`]) in the
//! same order: separate multiplies and adds, never fused. So estimates are bit-identical with
//! and without AVX2, and to a microcontroller's. Only the instructions differ: explicit 4-wide
//! vectors, a register-blocked Gram tile that the compiler would otherwise spill, and a
//! register-resident greedy loop.
//!
//! For windows of up to 32 rows the greedy loop runs in registers. With AVX-512F it uses
//! `zmm` and mask registers ([`iterate_avx512`]). On AVX2 it is the eight-lane loop of the
//! `lanes` module (`f64` as two `ymm` per chunk, `f32` as one). The Gram kernels are `f64` only; `f32` builds its Gram matrix with the portable loops
//! (compiled for AVX2), and other scalar types run the portable kernels throughout.

use core::any::TypeId;
use core::arch::x86_64::*;

use crate::Real;
use rand_chacha::ChaCha8Rng;

use crate::greedy::{
    Draws, Kernels, LANES, Portable, Requested, Schedule, Window, argmax_ratio, iterate_portable,
    requested,
};
use crate::lanes::{KEEP_F32, KEEP_F64, KEEP_LEN, LANE_MAJOR_U32, Lanes8, MAX_CHUNKS, iterate_any};
use crate::linalg::padded;

/// Proof that the CPU supports AVX2: only [`Avx2::detect`] makes one.
#[derive(Clone, Copy)]
pub(crate) struct Avx2 {
    /// The CPU also supports AVX-512F (and BMI2): 8 × 8 Gram tiles and the register-resident
    /// greedy loop.
    avx512f: bool,
    /// Build the Gram matrix with the previous AVX2 kernel ([`GramKernel::Diagonals`]): the
    /// reference of the paired timing check, never chosen by detection.
    previous_gram: bool,
}

impl Avx2 {
    /// `Some` if this CPU supports AVX2 (cached by the standard library after the first call)
    /// and `TAGK_KERNELS` does not ask for the portable kernels; AVX-512 where the CPU has it
    /// and `TAGK_KERNELS` is not `avx2`.
    #[inline]
    pub(crate) fn detect() -> Option<Self> {
        let requested = requested();
        (std::is_x86_feature_detected!("avx2") && requested != Requested::Portable).then(|| Self {
            avx512f: std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("bmi2")
                && requested == Requested::Best,
            previous_gram: false,
        })
    }

    /// The same kernels without the AVX-512F Gram tile (to test both on one machine).
    #[cfg(test)]
    pub(crate) fn without_avx512(self) -> Self {
        Self {
            avx512f: false,
            ..self
        }
    }

    /// The same kernels with the previous AVX2 Gram kernel where the AVX2 one runs (the
    /// reference of the paired timing check).
    pub(crate) fn with_previous_gram(self) -> Self {
        Self {
            previous_gram: !self.avx512f,
            ..self
        }
    }

    /// The `f64` Gram kernel these kernels run.
    fn gram_kernel(self) -> GramKernel {
        match (self.avx512f, self.previous_gram) {
            (true, _) => GramKernel::Avx512Tiles,
            (false, false) => GramKernel::Avx2Tiles,
            (false, true) => GramKernel::Diagonals,
        }
    }
}

#[inline(always)]
fn is<T: 'static, U: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<U>()
}

#[inline(always)]
fn is_f64<T: 'static>() -> bool {
    is::<T, f64>()
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

/// `s` as `&[f64]` when `T` is `f64`.
#[inline(always)]
fn f64s<T: 'static>(s: &[T]) -> &[f64] {
    same(s)
}

/// `s` as `&mut [f64]` when `T` is `f64`.
#[inline(always)]
fn f64s_mut<T: 'static>(s: &mut [T]) -> &mut [f64] {
    same_mut(s)
}

/// The window and schedule of scalar `T` as those of `U` (the same type).
#[inline(always)]
pub(crate) fn same_window<T: Real, U: Real>(
    w: Window<'_, T>,
    s: Schedule<T>,
) -> (Window<'_, U>, Schedule<U>) {
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

impl<T: Real> Kernels<T> for Avx2 {
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
            // The portable order (a transposed copy, then 8 × 8 tiles: one `ymm` of eight
            // `f32` columns per row) in explicit AVX2.
            let p = padded(m);
            let (at32, gram32): (&mut [f32], &mut [f32]) = (same_mut(at), same_mut(gram));
            assert!(at32.len() >= n * p && gram32.len() >= p * p);
            crate::linalg::transpose_padded(same::<T, f32>(a), n, m, at32);
            // SAFETY: `self` proves AVX2 support; the lengths were checked above.
            unsafe {
                gram_f32(at32, n, p, gram32);
                residual_rows_f32(same(a), same(b), same(x), n, m, same_mut(resid));
            }
            return;
        }
        if !is_f64::<T>() {
            return Portable.gram_and_residual(a, b, x, n, m, at, gram, resid);
        }
        // SAFETY: `self` proves AVX2 support, and AVX-512F where it says so.
        unsafe {
            gram_and_residual_f64(
                self.gram_kernel(),
                f64s(a),
                f64s(b),
                f64s(x),
                n,
                m,
                f64s_mut(at),
                f64s_mut(gram),
                f64s_mut(resid),
            )
        }
    }

    #[inline(always)]
    fn prepare(
        self,
        m: usize,
        pm: usize,
        norm2: &mut [T],
        inv_norm2: &mut [T],
        resid: &mut [T],
        coef: &mut [T],
        coef_avg: &mut [T],
    ) -> Option<(T, T, T)> {
        if !is_f64::<T>() {
            return None;
        }
        // SAFETY: `self` proves AVX2 support; the casts are between identical types.
        let (fro2, rnorm2, max_ratio) = unsafe {
            prepare_f64(
                m,
                pm,
                f64s_mut(norm2),
                f64s_mut(inv_norm2),
                f64s_mut(resid),
                f64s_mut(coef),
                f64s_mut(coef_avg),
            )
        };
        Some((T::cast(fro2), T::cast(rnorm2), T::cast(max_ratio)))
    }

    #[inline(always)]
    fn gram_diagonal(self, gram: &[T], pm: usize, m: usize, norm2: &mut [T]) -> bool {
        // No bounds check per row.
        assert!(m <= pm && gram.len() >= pm * pm && norm2.len() >= m);
        let g = gram.as_ptr();
        for (i, nn) in norm2[..m].iter_mut().enumerate() {
            // SAFETY: i · (pm + 1) < pm² (checked above).
            *nn = unsafe { *g.add(i * (pm + 1)) };
        }
        true
    }

    #[inline(always)]
    fn add_combination(self, x: &mut [T], a: &[T], coef: &[T], n: usize, m: usize) {
        if is_f64::<T>() {
            // SAFETY: `self` proves AVX2 support; the casts are between identical types.
            unsafe { add_combination_f64(f64s_mut(x), f64s(a), f64s(coef), n, m) }
        } else {
            crate::linalg::add_combination(x, a, coef, n, m);
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
        // SAFETY: `self` proves AVX2 support, and AVX-512F with BMI2 where it says so; the
        // casts are between identical types.
        unsafe {
            if is::<T, f64>() {
                let (w, s) = same_window::<T, f64>(w, s);
                let (rnorm2, max_ratio) = (rnorm2.as_f64(), max_ratio.as_f64());
                if self.avx512f {
                    match chunks {
                        1 => iterate_avx512::<1, AVERAGE>(w, rnorm2, max_ratio, s, rng),
                        2 => iterate_avx512::<2, AVERAGE>(w, rnorm2, max_ratio, s, rng),
                        3 => iterate_avx512::<3, AVERAGE>(w, rnorm2, max_ratio, s, rng),
                        _ => iterate_avx512::<4, AVERAGE>(w, rnorm2, max_ratio, s, rng),
                    }
                } else {
                    iterate_avx2::<F64x8, AVERAGE>(chunks, w, rnorm2, max_ratio, s, rng)
                }
            } else if is::<T, f32>() {
                let (w, s) = same_window::<T, f32>(w, s);
                let (rnorm2, max_ratio) = (rnorm2.as_f64() as f32, max_ratio.as_f64() as f32);
                iterate_avx2::<F32x8, AVERAGE>(chunks, w, rnorm2, max_ratio, s, rng)
            } else {
                iterate_portable::<T, AVERAGE>(w, rnorm2, max_ratio, s, rng)
            }
        }
    }
}

/// [`iterate_chunks`] compiled for AVX2, for a window of `chunks ≤ 4` chunks.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn iterate_avx2<V: Lanes8, const AVERAGE: bool>(
    chunks: usize,
    w: Window<'_, V::T>,
    rnorm2: V::T,
    max_ratio: V::T,
    s: Schedule<V::T>,
    rng: &mut ChaCha8Rng,
) -> (usize, bool) {
    // SAFETY: compiled for AVX2, which `V`'s instructions need.
    unsafe { iterate_any::<V, AVERAGE>(chunks, w, rnorm2, max_ratio, s, rng) }
}

/// Eight `f64` lanes as two AVX `ymm` registers (lanes 0–3, 4–7).
#[derive(Clone, Copy)]
struct F64x8(__m256d, __m256d);

/// Eight `f32` lanes in one AVX `ymm` register.
#[derive(Clone, Copy)]
struct F32x8(__m256);

// SAFETY (every block in the two implementations): they are only called from functions
// compiled for AVX2 (`iterate_avx2`), and pointers are the callers' promise.
impl Lanes8 for F64x8 {
    type T = f64;
    // (The negated residual measured +38 instructions per update here: the compiler then
    // keeps the stored residual in spill slots for the next iteration instead of reading it
    // back as a memory operand.)
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        unsafe { Self(_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(4))) }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f64) {
        unsafe {
            _mm256_storeu_pd(p, self.0);
            _mm256_storeu_pd(p.add(4), self.1);
        }
    }
    #[inline(always)]
    fn splat(x: f64) -> Self {
        unsafe { Self(_mm256_set1_pd(x), _mm256_set1_pd(x)) }
    }
    #[inline(always)]
    fn first(self) -> f64 {
        unsafe { _mm256_cvtsd_f64(self.0) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        unsafe { Self(_mm256_add_pd(self.0, o.0), _mm256_add_pd(self.1, o.1)) }
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        unsafe { Self(_mm256_sub_pd(self.0, o.0), _mm256_sub_pd(self.1, o.1)) }
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        unsafe { Self(_mm256_mul_pd(self.0, o.0), _mm256_mul_pd(self.1, o.1)) }
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        unsafe { Self(_mm256_and_pd(self.0, o.0), _mm256_and_pd(self.1, o.1)) }
    }
    #[inline(always)]
    fn max_onto(self, best: Self) -> Self {
        // MAXPD returns its second operand when they are unordered or equal.
        unsafe { Self(_mm256_max_pd(self.0, best.0), _mm256_max_pd(self.1, best.1)) }
    }
    #[inline(always)]
    fn ge_mask(self, t: Self) -> Self {
        unsafe {
            Self(
                _mm256_cmp_pd::<_CMP_GE_OQ>(self.0, t.0),
                _mm256_cmp_pd::<_CMP_GE_OQ>(self.1, t.1),
            )
        }
    }
    #[inline(always)]
    fn gt_mask(self, t: Self) -> Self {
        unsafe {
            Self(
                _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, t.0),
                _mm256_cmp_pd::<_CMP_GT_OQ>(self.1, t.1),
            )
        }
    }
    #[inline(always)]
    fn lane_major_bits<const C: usize>(masks: &[Self; C]) -> u32 {
        // The 32 lane masks narrowed to one byte each by three saturating packs (all-ones
        // stays all-ones, zero stays zero): chunk c's halves h and lanes q = 2k + q' land in
        // byte 4c + 2h + q' of 128-bit lane k. A byte shuffle (a 4 × 4 transpose per 64 bits)
        // and a swap of the middle 64-bit quarters put row 8c + l's byte at 4l + c, the
        // lane-major order, and the bytes' sign bits are the answer.
        unsafe {
            let zero = _mm256_setzero_si256();
            let mut words = [zero; 4];
            for (c, w) in words.iter_mut().enumerate().take(C) {
                *w = _mm256_packs_epi32(
                    _mm256_castpd_si256(masks[c].0),
                    _mm256_castpd_si256(masks[c].1),
                );
            }
            let bytes = _mm256_packs_epi16(
                _mm256_packs_epi32(words[0], words[1]),
                _mm256_packs_epi32(words[2], words[3]),
            );
            let transpose = _mm256_setr_epi8(
                0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15, //
                0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15,
            );
            let ordered = _mm256_permute4x64_epi64::<0xd8>(_mm256_shuffle_epi8(bytes, transpose));
            _mm256_movemask_epi8(ordered) as u32
        }
    }
    #[inline(always)]
    fn shift<const D: usize>(self) -> Self {
        unsafe {
            let (lo, hi) = (self.0, self.1);
            match D {
                1 => {
                    // (0, 0, lo0, lo1) and (lo2, lo3, hi0, hi1), then odd lanes from the
                    // unshifted halves: (0, lo0, lo1, lo2) and (lo3, hi0, hi1, hi2).
                    let a = _mm256_permute2f128_pd::<0x08>(lo, lo);
                    let b = _mm256_permute2f128_pd::<0x21>(lo, hi);
                    Self(
                        _mm256_shuffle_pd::<0b0101>(a, lo),
                        _mm256_shuffle_pd::<0b0101>(b, hi),
                    )
                }
                2 => Self(
                    _mm256_permute2f128_pd::<0x08>(lo, lo),
                    _mm256_permute2f128_pd::<0x21>(lo, hi),
                ),
                _ => Self(_mm256_setzero_pd(), lo),
            }
        }
    }
    #[inline(always)]
    fn add_shift4(self) -> Self {
        // Lanes 0–3 as they are (`x + 0 = x`, no lane being `−0`).
        unsafe { Self(self.0, _mm256_add_pd(self.1, self.0)) }
    }
    #[inline(always)]
    fn broadcast_last(self) -> Self {
        unsafe {
            let x = _mm256_permute4x64_pd::<0xff>(self.1);
            Self(x, x)
        }
    }
    #[inline(always)]
    fn sum_all(self) -> Self {
        unsafe {
            let t = _mm256_add_pd(self.0, self.1);
            let u = _mm256_add_pd(t, _mm256_permute2f128_pd::<0x01>(t, t));
            let v = _mm256_add_pd(u, _mm256_permute_pd::<0b0101>(u));
            Self(v, v)
        }
    }
    #[inline(always)]
    fn max_all(self) -> Self {
        unsafe {
            let t = _mm256_max_pd(self.0, self.1);
            let u = _mm256_max_pd(t, _mm256_permute2f128_pd::<0x01>(t, t));
            let v = _mm256_max_pd(u, _mm256_permute_pd::<0b0101>(u));
            Self(v, v)
        }
    }
    #[inline(always)]
    fn keep_table() -> &'static [f64; KEEP_LEN] {
        &KEEP_F64
    }
}

impl Lanes8 for F32x8 {
    type T = f32;
    const NEGATED_RESIDUAL: bool = true;
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        unsafe { Self(_mm256_loadu_ps(p)) }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        unsafe { _mm256_storeu_ps(p, self.0) }
    }
    #[inline(always)]
    fn splat(x: f32) -> Self {
        unsafe { Self(_mm256_set1_ps(x)) }
    }
    #[inline(always)]
    fn first(self) -> f32 {
        unsafe { _mm256_cvtss_f32(self.0) }
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        unsafe { Self(_mm256_add_ps(self.0, o.0)) }
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        unsafe { Self(_mm256_sub_ps(self.0, o.0)) }
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        unsafe { Self(_mm256_mul_ps(self.0, o.0)) }
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        unsafe { Self(_mm256_and_ps(self.0, o.0)) }
    }
    #[inline(always)]
    fn max_onto(self, best: Self) -> Self {
        // MAXPS returns its second operand when they are unordered or equal.
        unsafe { Self(_mm256_max_ps(self.0, best.0)) }
    }
    #[inline(always)]
    fn ge_mask(self, t: Self) -> Self {
        unsafe { Self(_mm256_cmp_ps::<_CMP_GE_OQ>(self.0, t.0)) }
    }
    #[inline(always)]
    fn gt_mask(self, t: Self) -> Self {
        unsafe { Self(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0, t.0)) }
    }
    #[inline(always)]
    fn lane_major_bits<const C: usize>(masks: &[Self; C]) -> u32 {
        unsafe {
            let mut acc = _mm256_setzero_ps();
            for (c, m) in masks.iter().enumerate() {
                let bits = _mm256_loadu_ps(LANE_MAJOR_U32[c].as_ptr().cast::<f32>());
                acc = _mm256_or_ps(acc, _mm256_and_ps(m.0, bits));
            }
            let x = _mm256_castps_si256(acc);
            let y = _mm_or_si128(_mm256_castsi256_si128(x), _mm256_extracti128_si256::<1>(x));
            let z = _mm_or_si128(y, _mm_unpackhi_epi64(y, y));
            _mm_cvtsi128_si32(_mm_or_si128(z, _mm_srli_epi64::<32>(z))) as u32
        }
    }
    #[inline(always)]
    fn shift<const D: usize>(self) -> Self {
        unsafe {
            let x = _mm256_castps_si256(self.0);
            // (0, 0, 0, 0, x0, x1, x2, x3); then each 128-bit half takes its own lanes
            // shifted up by D with the lanes below from the half before it.
            let below = _mm256_permute2x128_si256::<0x08>(x, x);
            let y = match D {
                1 => _mm256_alignr_epi8::<12>(x, below),
                2 => _mm256_alignr_epi8::<8>(x, below),
                _ => below,
            };
            Self(_mm256_castsi256_ps(y))
        }
    }
    #[inline(always)]
    fn broadcast_last(self) -> Self {
        unsafe { Self(_mm256_permutevar8x32_ps(self.0, _mm256_set1_epi32(7))) }
    }
    #[inline(always)]
    fn sum_all(self) -> Self {
        unsafe {
            let t = _mm_add_ps(
                _mm256_castps256_ps128(self.0),
                _mm256_extractf128_ps::<1>(self.0),
            );
            let u = _mm_add_ps(t, _mm_movehl_ps(t, t));
            let v = _mm_add_ss(u, _mm_shuffle_ps::<0b01>(u, u));
            Self(_mm256_broadcastss_ps(v))
        }
    }
    #[inline(always)]
    fn max_all(self) -> Self {
        unsafe {
            let t = _mm_max_ps(
                _mm256_castps256_ps128(self.0),
                _mm256_extractf128_ps::<1>(self.0),
            );
            let u = _mm_max_ps(t, _mm_movehl_ps(t, t));
            let v = _mm_max_ss(u, _mm_shuffle_ps::<0b01>(u, u));
            Self(_mm256_broadcastss_ps(v))
        }
    }
    #[inline(always)]
    fn keep_table() -> &'static [f32; KEEP_LEN] {
        &KEEP_F32
    }
}

/// [`Kernels::prepare`] for `f64`, in one pass of four entries at a time.
///
/// - The padding is masked to zero.
/// - `1/‖a_i‖²` and the residual are set where `‖a_i‖² > 0` (a division, as the portable
///   pass). The coefficients are cleared.
/// - The sums of `‖a_i‖²` and `r_i²` use two vectors each: lanes `j mod 8 < 4` and `≥ 4`.
///   These are the eight lane sums of [`crate::greedy::lane_sum`], each in order of `j`.
///   They are combined as `t_l = s_l + s_{l+4}`, then `(t₀ + t₂) + (t₁ + t₃)`.
/// - The largest ratio `r_i²/‖a_i‖²` is taken lane by lane, then across the lanes. MAXPD
///   keeps the running value on a NaN, as the portable `if v > best` does. A maximum is exact
///   in any order.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn prepare_f64(
    m: usize,
    pm: usize,
    norm2: &mut [f64],
    inv_norm2: &mut [f64],
    resid: &mut [f64],
    coef: &mut [f64],
    coef_avg: &mut [f64],
) -> (f64, f64, f64) {
    assert!(
        m <= pm
            && pm.is_multiple_of(8)
            && norm2.len() >= pm
            && inv_norm2.len() >= pm
            && resid.len() >= pm
            && coef.len() >= pm
            && coef_avg.len() >= pm
    );
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let lanes = _mm256_set_epi64x(3, 2, 1, 0);
    let (mut fro, mut sum, mut best) = ([zero; 2], [zero; 2], zero);
    let mut j = 0;
    while j < pm {
        // Lanes j mod 8 < 4, then ≥ 4.
        for half in 0..2 {
            let j = j + 4 * half;
            // SAFETY: entries j..j+4 < pm of each slice (checked above).
            unsafe {
                // All-ones in the lanes of rows below m.
                let live = _mm256_castsi256_pd(_mm256_cmpgt_epi64(
                    _mm256_set1_epi64x(m as i64 - j as i64),
                    lanes,
                ));
                let nn = _mm256_and_pd(live, _mm256_loadu_pd(norm2.as_ptr().add(j)));
                _mm256_storeu_pd(norm2.as_mut_ptr().add(j), nn);
                let usable = _mm256_cmp_pd::<_CMP_GT_OQ>(nn, zero);
                let inv = _mm256_and_pd(usable, _mm256_div_pd(one, nn));
                let r = _mm256_and_pd(
                    _mm256_and_pd(usable, live),
                    _mm256_loadu_pd(resid.as_ptr().add(j)),
                );
                _mm256_storeu_pd(inv_norm2.as_mut_ptr().add(j), inv);
                _mm256_storeu_pd(resid.as_mut_ptr().add(j), r);
                _mm256_storeu_pd(coef.as_mut_ptr().add(j), zero);
                _mm256_storeu_pd(coef_avg.as_mut_ptr().add(j), zero);
                fro[half] = _mm256_add_pd(fro[half], nn);
                let r2 = _mm256_mul_pd(r, r);
                sum[half] = _mm256_add_pd(sum[half], r2);
                best = _mm256_max_pd(_mm256_mul_pd(r2, inv), best);
            }
        }
        j += 8;
    }
    let total = |s: [__m256d; 2]| {
        let t = _mm256_add_pd(s[0], s[1]);
        let u = _mm_add_pd(_mm256_castpd256_pd128(t), _mm256_extractf128_pd::<1>(t));
        _mm_cvtsd_f64(_mm_add_sd(u, _mm_unpackhi_pd(u, u)))
    };
    let b = _mm_max_pd(
        _mm256_castpd256_pd128(best),
        _mm256_extractf128_pd::<1>(best),
    );
    let b = _mm_max_sd(b, _mm_unpackhi_pd(b, b));
    (total(fro), total(sum), _mm_cvtsd_f64(b))
}

/// Vectors of four `f64` per block of [`add_combination_f64`]: twelve accumulators, one
/// broadcast and one product in sixteen `ymm` registers.
const COMBINATION_VECTORS: usize = 12;

/// `x ← x + Aᵀc` for `f64` in the order of [`crate::linalg::add_combination`]: each entry
/// summed over the rows with a nonzero coefficient in increasing order, `x_k ← a_ik c_i + x_k`
/// (multiply, then add). Blocks of up to 48 entries of `x` stay in `ymm` accumulators. The
/// used rows stream past; bit scans over masks of nonzero coefficients find them. Each row
/// costs one broadcast of `c_i` and, per four entries, a multiply with the row as its memory
/// operand and an add. The last `n mod 4` entries go through masked loads and stores. Lanes
/// past `n` are neither read nor written.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn add_combination_f64(x: &mut [f64], a: &[f64], coef: &[f64], n: usize, m: usize) {
    assert!(x.len() >= n && a.len() >= m * n && coef.len() >= m);
    let mut k = 0;
    while k < n {
        let len = (n - k).min(4 * COMBINATION_VECTORS);
        let (full, tail) = (len / 4, len % 4);
        // SAFETY: entries k..k+len of x and of every row (checked above).
        unsafe {
            if tail == 0 {
                match full {
                    1 => combination_block_f64::<1, false>(x, a, coef, n, m, k, 0),
                    2 => combination_block_f64::<2, false>(x, a, coef, n, m, k, 0),
                    3 => combination_block_f64::<3, false>(x, a, coef, n, m, k, 0),
                    4 => combination_block_f64::<4, false>(x, a, coef, n, m, k, 0),
                    5 => combination_block_f64::<5, false>(x, a, coef, n, m, k, 0),
                    6 => combination_block_f64::<6, false>(x, a, coef, n, m, k, 0),
                    7 => combination_block_f64::<7, false>(x, a, coef, n, m, k, 0),
                    8 => combination_block_f64::<8, false>(x, a, coef, n, m, k, 0),
                    9 => combination_block_f64::<9, false>(x, a, coef, n, m, k, 0),
                    10 => combination_block_f64::<10, false>(x, a, coef, n, m, k, 0),
                    11 => combination_block_f64::<11, false>(x, a, coef, n, m, k, 0),
                    _ => combination_block_f64::<12, false>(x, a, coef, n, m, k, 0),
                }
            } else {
                // `full + 1` vectors, the last one masked (len < 48 here).
                match full {
                    0 => combination_block_f64::<1, true>(x, a, coef, n, m, k, tail),
                    1 => combination_block_f64::<2, true>(x, a, coef, n, m, k, tail),
                    2 => combination_block_f64::<3, true>(x, a, coef, n, m, k, tail),
                    3 => combination_block_f64::<4, true>(x, a, coef, n, m, k, tail),
                    4 => combination_block_f64::<5, true>(x, a, coef, n, m, k, tail),
                    5 => combination_block_f64::<6, true>(x, a, coef, n, m, k, tail),
                    6 => combination_block_f64::<7, true>(x, a, coef, n, m, k, tail),
                    7 => combination_block_f64::<8, true>(x, a, coef, n, m, k, tail),
                    8 => combination_block_f64::<9, true>(x, a, coef, n, m, k, tail),
                    9 => combination_block_f64::<10, true>(x, a, coef, n, m, k, tail),
                    10 => combination_block_f64::<11, true>(x, a, coef, n, m, k, tail),
                    _ => combination_block_f64::<12, true>(x, a, coef, n, m, k, tail),
                }
            }
        }
        k += len;
    }
}

/// Entries `k..k + 4V` of [`add_combination_f64`] (with `TAIL`, the last vector only its first
/// `tail` lanes, `0 < tail < 4`).
///
/// # Safety
/// The CPU must support AVX2; `x`, `a`, `coef` as checked by [`add_combination_f64`], and the
/// block's entries below `n`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn combination_block_f64<const V: usize, const TAIL: bool>(
    x: &mut [f64],
    a: &[f64],
    coef: &[f64],
    n: usize,
    m: usize,
    k: usize,
    tail: usize,
) {
    let full = if TAIL { V - 1 } else { V };
    // SAFETY: the caller's promise: entries k..k + 4·full (+ tail) of x and of the rows.
    unsafe {
        // All-ones in the lanes below `tail`.
        let mask = _mm256_cmpgt_epi64(
            _mm256_set1_epi64x(tail as i64),
            _mm256_set_epi64x(3, 2, 1, 0),
        );
        let xp = x.as_mut_ptr().add(k);
        let mut acc = [_mm256_setzero_pd(); V];
        for (v, acc_v) in acc.iter_mut().enumerate().take(full) {
            *acc_v = _mm256_loadu_pd(xp.add(4 * v));
        }
        if TAIL {
            acc[V - 1] = _mm256_maskload_pd(xp.add(4 * full), mask);
        }
        let mut base = 0;
        while base < m {
            let chunk = &coef[base..m.min(base + 64)];
            let mut used = used_rows_f64(chunk);
            while used != 0 {
                let i = base + used.trailing_zeros() as usize;
                used &= used - 1;
                let c = _mm256_broadcast_sd(coef.get_unchecked(i));
                let row = a.as_ptr().add(i * n + k);
                for (v, acc_v) in acc.iter_mut().enumerate().take(full) {
                    *acc_v =
                        _mm256_add_pd(_mm256_mul_pd(_mm256_loadu_pd(row.add(4 * v)), c), *acc_v);
                }
                if TAIL {
                    let r = _mm256_maskload_pd(row.add(4 * full), mask);
                    acc[V - 1] = _mm256_add_pd(_mm256_mul_pd(r, c), acc[V - 1]);
                }
            }
            base += 64;
        }
        for (v, acc_v) in acc.iter().enumerate().take(full) {
            _mm256_storeu_pd(xp.add(4 * v), *acc_v);
        }
        if TAIL {
            _mm256_maskstore_pd(xp.add(4 * full), mask, acc[V - 1]);
        }
    }
}

/// Bit `q` set where `c[q] ≠ 0` (`c.len() ≤ 64`), four coefficients per comparison.
#[inline(always)]
unsafe fn used_rows_f64(c: &[f64]) -> u64 {
    let mut bits = 0u64;
    let mut q = 0;
    // SAFETY: the caller compiled for AVX2; loads below c.len().
    unsafe {
        while q + 4 <= c.len() {
            let v = _mm256_loadu_pd(c.as_ptr().add(q));
            let nonzero = _mm256_cmp_pd::<_CMP_NEQ_UQ>(v, _mm256_setzero_pd());
            bits |= (_mm256_movemask_pd(nonzero) as u64) << q;
            q += 4;
        }
    }
    while q < c.len() {
        bits |= u64::from(c[q] != 0.0) << q;
        q += 1;
    }
    bits
}

/// `r_j = b_j − a_jᵀx` for the `m` rows of the `f32` window, and `r_j = 0` for `m ≤ j < p`.
/// Each product is summed as [`crate::linalg::dot`] does. Its four interleaved partial sums
/// are the four lanes of one `xmm` accumulator (multiply, then add). They are combined as
/// `(s₀ + s₂) + (s₁ + s₃)`, then the remaining products are added in order.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn residual_rows_f32(a: &[f32], b: &[f32], x: &[f32], n: usize, m: usize, out: &mut [f32]) {
    let p = padded(m);
    assert!(a.len() >= m * n && b.len() >= m && x.len() >= n && out.len() >= p);
    let n4 = n - n % 4;
    for j in 0..m {
        let row = &a[j * n..(j + 1) * n];
        // SAFETY: loads below n of the row and of x (checked above).
        let sum = unsafe {
            let mut acc = _mm_setzero_ps();
            let mut k = 0;
            while k < n4 {
                let prod = _mm_mul_ps(
                    _mm_loadu_ps(row.as_ptr().add(k)),
                    _mm_loadu_ps(x.as_ptr().add(k)),
                );
                acc = _mm_add_ps(prod, acc);
                k += 4;
            }
            let t = _mm_add_ps(acc, _mm_movehl_ps(acc, acc));
            _mm_cvtss_f32(_mm_add_ss(t, _mm_shuffle_ps::<0b01>(t, t)))
        };
        let sum = row[n4..]
            .iter()
            .zip(&x[n4..n])
            .fold(sum, |s, (p, q)| p * q + s);
        out[j] = b[j] - sum;
    }
    out[m..p].fill(0.0);
}

/// Rows per panel: the Gram matrix is built one block column of eight rows at a time.
const PANEL: usize = 8;

/// The `f64` Gram kernel of [`gram_and_residual_f64`]. All three compute the same bits.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum GramKernel {
    /// 8 × 8 tiles of eight `zmm` accumulators, one panel of eight rows at a time (AVX-512F).
    Avx512Tiles,
    /// The same panels as 4 × 8 tiles of eight `ymm` accumulators (AVX2).
    Avx2Tiles,
    /// The previous AVX2 kernel: the whole window transposed, then the upper triangle along
    /// its diagonals ([`gram_avx2`]). Kept as the reference of the paired timing check.
    Diagonals,
}

/// `G = A Aᵀ` (`p × p`) and `r = b − A x` for `f64`, in the order of the portable kernels
/// (every Gram entry summed in order of `k`).
///
/// With AVX-512F the Gram matrix is built GEMM-style, one block of eight rows `J` at a time.
/// The block's rows are packed transposed into `at` (`n × 8`, small enough to stay in L1).
/// Then every 8 × 8 tile `G[I, J]` with `I ≤ J` is computed in eight `zmm` accumulators. Its
/// other factor is broadcast straight from the rows of `A`. `G[J, I]` is written as the
/// transposed tile.
///
/// With AVX2 the panels are the same, packed the same way; the rows after the first panel
/// are all prefetched before the first. Each tile is two 4 × 8 halves in eight `ymm` accumulators (see
/// [`gram_panel_avx2`]): per `k`, two loads and four broadcasts feed eight multiplies and eight
/// adds. The previous AVX2 kernel ([`GramKernel::Diagonals`]) is kept as the timing reference.
///
/// # Safety
/// The CPU must support AVX2, and AVX-512F for [`GramKernel::Avx512Tiles`].
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn gram_and_residual_f64(
    gram_kernel: GramKernel,
    a: &[f64],
    b: &[f64],
    x: &[f64],
    n: usize,
    m: usize,
    at: &mut [f64],
    gram: &mut [f64],
    resid: &mut [f64],
) {
    let p = padded(m);
    assert!(
        a.len() >= m * n
            && b.len() >= m
            && x.len() >= n
            && at.len() >= n * p
            && gram.len() >= p * p
            && resid.len() >= p
    );
    if gram_kernel == GramKernel::Diagonals {
        let mut bj = 0;
        while bj < p {
            // SAFETY: `at` holds n · p entries (checked above), columns bj..bj+8 ≤ p.
            unsafe { pack_panel_f64(a, b, x, n, m, bj, at.as_mut_ptr().add(bj), p, resid) };
            bj += PANEL;
        }
        // SAFETY: the slices were checked above; AVX2 is the caller's promise.
        unsafe { gram_avx2(at, n, m, p, gram) };
        return;
    }
    if gram_kernel == GramKernel::Avx2Tiles {
        // The rows after the first panel, all fetched at once: a window from memory arrives
        // with more loads in flight than one panel ahead gives (paired, AVX2 on a Zen 4
        // EPYC, n = 120: 8.1 against 8.6 µs from memory, the same time from cache).
        prefetch_spread(&a[(PANEL * n).min(m * n)..m * n], n);
    }
    let mut bj = 0;
    while bj < p {
        // SAFETY: the slices were checked above; the CPU features are the caller's promise.
        unsafe {
            pack_panel_f64(a, b, x, n, m, bj, at.as_mut_ptr(), PANEL, resid);
            if gram_kernel == GramKernel::Avx512Tiles {
                // The next panel's rows, fetched into cache while this panel's tiles compute.
                let next = &a[((bj + PANEL) * n).min(m * n)..((bj + 2 * PANEL) * n).min(m * n)];
                gram_panel_avx512(a, n, m, p, bj, at, next, gram);
            } else {
                gram_panel_avx2(a, n, m, p, bj, at, gram);
            }
        }
        bj += PANEL;
    }
    // Rows `≥ m` of G hold products of stand-in rows (see `row_ptr`), which the contract
    // leaves unspecified; columns `≥ m` of the other rows are exact zeros, as the panels are
    // zero there, and mirror images only ever come from rows below `m`.
}
/// Prefetches `data` into L1 (one hint per 64-byte line) before a panel's tiles compute.
/// This is done for rows long enough (`n ≥ 32`) that a window may not be in cache. The hints
/// are cheap next to the loads they save when the window comes from L3 or memory.
#[inline(always)]
fn prefetch_spread(data: &[f64], n: usize) {
    if n < 32 {
        return;
    }
    let mut k = 0;
    while k < data.len() {
        // SAFETY: a prefetch hint never faults; the address is inside `data`.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(data.as_ptr().add(k).cast()) };
        k += 8;
    }
}

/// A pointer to row `i` of `A`, or to row `m − 1` for a padding row (`i ≥ m`), whose products
/// land only in rows `≥ m` of `G`.
#[inline(always)]
fn row_ptr(a: &[f64], n: usize, m: usize, i: usize) -> *const f64 {
    a[i.min(m - 1) * n..].as_ptr()
}

/// `dst[k·stride + l] = a[(bj + l)·n + k]` for `l < 8`: rows `bj..bj+8` of `A` transposed,
/// zero for rows `≥ m`, through 4 × 4 blocks in registers.
///
/// The same loads give the residuals `r_j = b_j − a_jᵀx` of those rows. They are summed as
/// [`crate::linalg::dot`] does: four interleaved partial sums, combined as
/// `(s₀ + s₂) + (s₁ + s₃)`, then the remainder in order. `stride` 8 packs one panel.
/// `stride = p` with `dst` at column `bj` builds the whole transposed window, one panel of
/// columns at a time.
///
/// # Safety
/// The CPU must support AVX2; `a` holds `m × n`, `b` `m`, `x` `n` and `resid` `bj + 8`
/// entries, and `dst` is writable at `k·stride + l` for `k < n`, `l < 8`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn pack_panel_f64(
    a: &[f64],
    b: &[f64],
    x: &[f64],
    n: usize,
    m: usize,
    bj: usize,
    dst: *mut f64,
    stride: usize,
    resid: &mut [f64],
) {
    assert!(a.len() >= m * n && b.len() >= m && x.len() >= n && resid.len() >= bj + 8);
    for half in 0..2 {
        let j = bj + 4 * half;
        let (d, rows) = (dst.wrapping_add(4 * half), m.saturating_sub(j).min(4));
        // SAFETY: rows j..j+rows < m of `a`, `b` and `resid` (checked above); `dst` is the
        // caller's promise.
        unsafe {
            match (stride, rows) {
                (PANEL, 4) => pack_rows_f64::<4, PANEL>(a, b, x, n, j, d, stride, resid),
                (PANEL, 3) => pack_rows_f64::<3, PANEL>(a, b, x, n, j, d, stride, resid),
                (PANEL, 2) => pack_rows_f64::<2, PANEL>(a, b, x, n, j, d, stride, resid),
                (PANEL, 1) => pack_rows_f64::<1, PANEL>(a, b, x, n, j, d, stride, resid),
                (PANEL, _) => pack_rows_f64::<0, PANEL>(a, b, x, n, j, d, stride, resid),
                (16, 4) => pack_rows_f64::<4, 16>(a, b, x, n, j, d, stride, resid),
                (24, 4) => pack_rows_f64::<4, 24>(a, b, x, n, j, d, stride, resid),
                (32, 4) => pack_rows_f64::<4, 32>(a, b, x, n, j, d, stride, resid),
                (_, 4) => pack_rows_f64::<4, 0>(a, b, x, n, j, d, stride, resid),
                (_, 3) => pack_rows_f64::<3, 0>(a, b, x, n, j, d, stride, resid),
                (_, 2) => pack_rows_f64::<2, 0>(a, b, x, n, j, d, stride, resid),
                (_, 1) => pack_rows_f64::<1, 0>(a, b, x, n, j, d, stride, resid),
                _ => pack_rows_f64::<0, 0>(a, b, x, n, j, d, stride, resid),
            }
        }
    }
}

/// Four columns `dst[k·stride + l]`, `l < 4`, of [`pack_panel_f64`] from rows `j..j+R` of `A`
/// (zero columns for `l ≥ R`), and the residuals of those rows; `S` is the stride when known
/// at compile time (`0`: read `stride`).
///
/// # Safety
/// As [`pack_panel_f64`], with `j + R ≤ m`, and `S` is `0` or `stride`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn pack_rows_f64<const R: usize, const S: usize>(
    a: &[f64],
    b: &[f64],
    x: &[f64],
    n: usize,
    j: usize,
    dst: *mut f64,
    stride: usize,
    resid: &mut [f64],
) {
    let stride = if S == 0 { stride } else { S };
    let n4 = n - n % 4;
    // SAFETY: reads rows j..j+R of `a` at columns < n and x below n; writes `dst` rows < n
    // (the caller's promise).
    unsafe {
        let src = a.as_ptr().add(j * n);
        let xp = x.as_ptr();
        let mut acc = [_mm256_setzero_pd(); 4];
        let mut out = dst;
        let mut k = 0;
        while k < n4 {
            let mut rows = [_mm256_setzero_pd(); 4];
            for (r, row) in rows.iter_mut().enumerate().take(R) {
                *row = _mm256_loadu_pd(src.add(r * n + k));
            }
            let xv = _mm256_loadu_pd(xp.add(k));
            for (acc_r, row) in acc.iter_mut().zip(&rows).take(R) {
                *acc_r = _mm256_add_pd(_mm256_mul_pd(*row, xv), *acc_r);
            }
            for (q, col) in transpose4(rows).iter().enumerate() {
                _mm256_storeu_pd(out.add(q * stride), *col);
            }
            out = out.add(4 * stride);
            k += 4;
        }
        // The last `n mod 4` columns: the rows read through a mask (lanes past `n` neither
        // read nor used), transposed like the others, and only their columns stored.
        let tail = n - n4;
        let mut last = [_mm256_setzero_pd(); 4];
        if tail > 0 {
            let mask = _mm256_cmpgt_epi64(
                _mm256_set1_epi64x(tail as i64),
                _mm256_set_epi64x(3, 2, 1, 0),
            );
            let mut rows = [_mm256_setzero_pd(); 4];
            for (r, row) in rows.iter_mut().enumerate().take(R) {
                *row = _mm256_maskload_pd(src.add(r * n + n4), mask);
            }
            last = transpose4(rows);
            for (q, col) in last.iter().enumerate().take(tail) {
                _mm256_storeu_pd(out.add(q * stride), *col);
            }
        }
        // The four rows' residuals side by side: lane q of every accumulator gathered into
        // one vector (a transpose), `(s₀ + s₂) + (s₁ + s₃)`, then the remaining products in
        // order of k, then `b − sum`. Rows `≥ R` come out `+0` (zero rows, zero `b`).
        let s = transpose4(acc);
        let mut sum = _mm256_add_pd(_mm256_add_pd(s[0], s[2]), _mm256_add_pd(s[1], s[3]));
        for (q, col) in last.iter().enumerate().take(tail) {
            let xk = _mm256_broadcast_sd(&*xp.add(n4 + q));
            sum = _mm256_add_pd(sum, _mm256_mul_pd(*col, xk));
        }
        let bp = b.as_ptr().wrapping_add(j);
        let bv = if R == 4 {
            _mm256_loadu_pd(bp)
        } else if R == 0 {
            _mm256_setzero_pd()
        } else {
            let rows =
                _mm256_cmpgt_epi64(_mm256_set1_epi64x(R as i64), _mm256_set_epi64x(3, 2, 1, 0));
            _mm256_maskload_pd(bp, rows)
        };
        _mm256_storeu_pd(resid.as_mut_ptr().add(j), _mm256_sub_pd(bv, sum));
    }
}

/// The tiles `G[I, J]`, `I ≤ J`, of one panel `J = bj..bj+8` with 8 × 8 AVX-512F tiles.
///
/// # Safety
/// The CPU must support AVX-512F; slices as in [`gram_and_residual_f64`].
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
unsafe fn gram_panel_avx512(
    a: &[f64],
    n: usize,
    m: usize,
    p: usize,
    bj: usize,
    panel: &[f64],
    next: &[f64],
    gram: &mut [f64],
) {
    prefetch_spread(next, n);
    let (v, g) = (panel.as_ptr(), gram.as_mut_ptr());
    let mut bi = 0;
    while bi < bj {
        let rows: [*const f64; 8] = core::array::from_fn(|s| row_ptr(a, n, m, bi + s));
        // SAFETY: reads rows of `a` at columns < n and panel rows < n; writes rows and
        // columns < p of `gram` (bi + 8 ≤ p, bj + 8 ≤ p).
        unsafe {
            let mut c = [_mm512_setzero_pd(); 8];
            for k in 0..n {
                let vk = _mm512_loadu_pd(v.add(k * PANEL));
                for (s, cs) in c.iter_mut().enumerate() {
                    let u = _mm512_set1_pd(*rows[s].add(k));
                    *cs = _mm512_add_pd(_mm512_mul_pd(u, vk), *cs);
                }
            }
            for (s, cs) in c.iter().enumerate() {
                _mm512_storeu_pd(g.add((bi + s) * p + bj), *cs);
            }
            for (l, tl) in transpose8(c).iter().enumerate() {
                _mm512_storeu_pd(g.add((bj + l) * p + bi), *tl);
            }
        }
        bi += PANEL;
    }
    // The diagonal block: its upper four rows in full, its lower four only right of the
    // diagonal's 4 × 4 split; the lower-left quarter is the upper-right one transposed.
    let rows: [*const f64; 8] = core::array::from_fn(|s| row_ptr(a, n, m, bj + s));
    // SAFETY: as above, with bi = bj.
    unsafe {
        let mut upper = [_mm512_setzero_pd(); 4];
        let mut lower = [_mm256_setzero_pd(); 4];
        for k in 0..n {
            let vk = _mm512_loadu_pd(v.add(k * PANEL));
            let vr = _mm256_loadu_pd(v.add(k * PANEL + 4));
            for (s, cs) in upper.iter_mut().enumerate() {
                let u = _mm512_set1_pd(*rows[s].add(k));
                *cs = _mm512_add_pd(_mm512_mul_pd(u, vk), *cs);
            }
            for (s, cs) in lower.iter_mut().enumerate() {
                let u = _mm256_set1_pd(*rows[4 + s].add(k));
                *cs = _mm256_add_pd(_mm256_mul_pd(u, vr), *cs);
            }
        }
        for (s, cs) in upper.iter().enumerate() {
            _mm512_storeu_pd(g.add((bj + s) * p + bj), *cs);
        }
        for (s, cs) in lower.iter().enumerate() {
            _mm256_storeu_pd(g.add((bj + 4 + s) * p + bj + 4), *cs);
        }
        let right: [__m256d; 4] = core::array::from_fn(|s| _mm512_extractf64x4_pd::<1>(upper[s]));
        for (l, tl) in transpose4(right).iter().enumerate() {
            _mm256_storeu_pd(g.add((bj + 4 + l) * p + bj), *tl);
        }
    }
}

/// The tiles `G[I, J]`, `I ≤ J`, of one panel `J = bj..bj+8` with AVX2, as
/// [`gram_panel_avx512`] computes them.
///
/// Each block `I` of eight rows above the panel is two 4 × 8 tiles ([`tile_avx2`]); the tile's
/// transpose gives `G[J, I]`. The diagonal block is a 4 × 8 tile for its upper four rows and a
/// 4 × 4 tile right of the diagonal split for its lower four; its lower-left quarter is the
/// upper-right one transposed. Every entry is summed in order of `k` from `+0` (multiply,
/// then add): the bits of the portable kernel.
///
/// # Safety
/// The CPU must support AVX2; slices as in [`gram_and_residual_f64`].
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn gram_panel_avx2(
    a: &[f64],
    n: usize,
    m: usize,
    p: usize,
    bj: usize,
    panel: &[f64],
    gram: &mut [f64],
) {
    assert!(a.len() >= m * n && panel.len() >= n * PANEL && gram.len() >= p * p && bj + 8 <= p);
    let (v, g) = (panel.as_ptr(), gram.as_mut_ptr());
    let rows4 = |i: usize| -> [*const f64; 4] { core::array::from_fn(|s| row_ptr(a, n, m, i + s)) };
    let mut bi = 0;
    while bi < bj {
        for i in [bi, bi + 4] {
            // SAFETY: reads rows of `a` at columns < n and panel rows < n; writes rows and
            // columns < p of `gram` (i + 4 ≤ bj, bj + 8 ≤ p).
            unsafe {
                let c = tile_avx2::<2>(rows4(i), v, n);
                for (s, cs) in c.iter().enumerate() {
                    _mm256_storeu_pd(g.add((i + s) * p + bj), cs[0]);
                    _mm256_storeu_pd(g.add((i + s) * p + bj + 4), cs[1]);
                }
                let quarters = [
                    [c[0][0], c[1][0], c[2][0], c[3][0]],
                    [c[0][1], c[1][1], c[2][1], c[3][1]],
                ];
                for (h, quarter) in quarters.iter().enumerate() {
                    for (l, tl) in transpose4(*quarter).iter().enumerate() {
                        _mm256_storeu_pd(g.add((bj + 4 * h + l) * p + i), *tl);
                    }
                }
            }
        }
        bi += PANEL;
    }
    // SAFETY: as above, with the rows of the panel itself.
    unsafe {
        let upper = tile_avx2::<2>(rows4(bj), v, n);
        let lower = tile_avx2::<1>(rows4(bj + 4), v.add(4), n);
        for (s, cs) in upper.iter().enumerate() {
            _mm256_storeu_pd(g.add((bj + s) * p + bj), cs[0]);
            _mm256_storeu_pd(g.add((bj + s) * p + bj + 4), cs[1]);
        }
        for (s, cs) in lower.iter().enumerate() {
            _mm256_storeu_pd(g.add((bj + 4 + s) * p + bj + 4), cs[0]);
        }
        let right = [upper[0][1], upper[1][1], upper[2][1], upper[3][1]];
        for (l, tl) in transpose4(right).iter().enumerate() {
            _mm256_storeu_pd(g.add((bj + 4 + l) * p + bj), *tl);
        }
    }
}

/// A 4 × 4V tile: `c[s][q]` lane `l` is `Σ_k rows[s][k] · v[k·8 + 4q + l]`, summed in order of
/// `k` from `+0`, multiply then add.
///
/// Per `k`, `V` loads of the panel and four broadcasts from the rows feed `4V` multiplies and
/// `4V` adds. The `4V ≤ 8` accumulators, the `V` panel vectors, a broadcast and a product fit
/// the sixteen `ymm` registers.
///
/// # Safety
/// The CPU must support AVX2; `rows[s]` is readable at `k < n`, `v` at `k·8 + 4V − 1`.
#[inline(always)]
unsafe fn tile_avx2<const V: usize>(
    rows: [*const f64; 4],
    v: *const f64,
    n: usize,
) -> [[__m256d; V]; 4] {
    #[inline(always)]
    unsafe fn step<const V: usize>(
        c: &mut [[__m256d; V]; 4],
        rows: &[*const f64; 4],
        v: *const f64,
        k: usize,
    ) {
        // SAFETY: the caller's promise.
        unsafe {
            let cols: [__m256d; V] =
                core::array::from_fn(|q| _mm256_loadu_pd(v.add(k * PANEL + 4 * q)));
            for (s, cs) in c.iter_mut().enumerate() {
                let u = _mm256_broadcast_sd(&*rows[s].add(k));
                for (acc, col) in cs.iter_mut().zip(&cols) {
                    *acc = _mm256_add_pd(_mm256_mul_pd(u, *col), *acc);
                }
            }
        }
    }
    // SAFETY: the caller's promise.
    unsafe {
        let mut c = [[_mm256_setzero_pd(); V]; 4];
        // k in order, two per pass (less loop overhead per product), then the last if odd.
        let mut k = 0;
        while k + 2 <= n {
            step(&mut c, &rows, v, k);
            step(&mut c, &rows, v, k + 1);
            k += 2;
        }
        if k < n {
            step(&mut c, &rows, v, k);
        }
        c
    }
}

/// `G = A Aᵀ` for `f64` from the transposed window `at` (`n × p`, stride `p`, zero in the
/// columns `≥ m`).
///
/// The work goes per block of four rows `i₀..i₀+4` (`i₀ < m`, a multiple of 4), along the
/// diagonals. The vector `Σ_k at[k, i₀..i₀+4] · at[k, i₀+d..i₀+d+4]` holds
/// `G[i₀ + l, i₀ + l + d]` in lane `l`. One load of `at[k, i₀..]` per `k` is shared by up to
/// twelve diagonals; their factors are the multiplies' memory operands (see
/// [`gram_diagonals`]). Every entry of the upper triangle is computed once. Four diagonals
/// transposed are four row pieces `G[i₀ + l, i₀ + l + d₀..+4]`, stored unaligned. Diagonals
/// `d ≥ m − i₀` only reach columns `≥ m`; they are stored as zeros without computing.
///
/// A row piece that runs past column `p − 1` spills into the first columns of the next row.
/// A vector reaching past `at`'s row reads the next one; the last row's reads the slack past
/// `at` (`linalg::TRANSPOSED_SLACK`). Those lanes only ever land left of a diagonal block or
/// in its lower-left, and are written again below. The last block of a window with
/// `m > p − 4` is computed as row strips instead, since its spill would leave the matrix.
///
/// Then, per block, the lower-left of the diagonal 4 × 4 block comes from the transposes of
/// the blocks above, and so do the 4 × 4 blocks left of it. These are the same products,
/// commuted and summed in the same order: the same bits. Every entry is summed in order of
/// `k` from `+0` (multiply, then add). Columns `≥ m` of rows `< m` are exact zeros. Rows
/// `≥ m` are left unspecified.
///
/// # Safety
/// The CPU must support AVX2; `at` holds `n · p + linalg::TRANSPOSED_SLACK` entries and `gram`
/// `p · p`, `p` a multiple of 8 with `m ≤ p`.
#[target_feature(enable = "avx2")]
unsafe fn gram_avx2(at: &[f64], n: usize, m: usize, p: usize, gram: &mut [f64]) {
    // SAFETY: the caller's promise; the stride is `p` in each call.
    unsafe {
        // The window sizes of a robot's estimator get a compile-time stride (constant
        // displacements, no address arithmetic in the loop); others the run-time one.
        match p {
            8 => gram_avx2_stride::<8>(at, n, m, p, gram),
            16 => gram_avx2_stride::<16>(at, n, m, p, gram),
            24 => gram_avx2_stride::<24>(at, n, m, p, gram),
            32 => gram_avx2_stride::<32>(at, n, m, p, gram),
            _ => gram_avx2_stride::<0>(at, n, m, p, gram),
        }
    }
}

/// Most diagonals [`gram_diagonals`] computes at once (twelve accumulators, the shared
/// factor and a product in sixteen `ymm` registers).
const DIAGONAL_GROUPS: usize = 3;

/// [`gram_avx2`] with the stride `p` known at compile time as `P` (`P = 0`: read `p`).
///
/// # Safety
/// As [`gram_avx2`], and `P` is `0` or `p`.
#[inline(always)]
unsafe fn gram_avx2_stride<const P: usize>(
    at: &[f64],
    n: usize,
    m: usize,
    p: usize,
    gram: &mut [f64],
) {
    let p = if P == 0 { p } else { P };
    assert!(
        at.len() >= n * p + crate::linalg::TRANSPOSED_SLACK
            && gram.len() >= p * p
            && m <= p
            && p % 8 == 0
    );
    let (t, g) = (at.as_ptr(), gram.as_mut_ptr());
    // Diagonals computed in the last group of four of a block (`m − i₀ ≡ m mod 4`).
    let partial = m % 4;
    let mut i0 = 0;
    while i0 < m {
        // SAFETY (this loop): reads of `at` below n · p + 3 (a diagonal d < m − i₀ reads up to
        // column i₀ + d + 3 ≤ p + 2 of its row); writes of `gram` at rows i₀..i₀+4 ≤ p − 4 + 3,
        // columns below p, spilling at most three entries into the next row, < p · p as
        // i₀ + 4 < p here; the last block's strips stay in their rows.
        unsafe {
            if i0 + 4 == p {
                for i in i0..m {
                    let s = i as isize - i0 as isize;
                    gram_strip_avx2::<1, P>(t.add(i0), s, n, p, g.add(i * p + i0));
                }
                break;
            }
            let live = (m - i0).div_ceil(4);
            let mut group = 0;
            while group < live {
                let count = (live - group).min(DIAGONAL_GROUPS);
                let last = if group + count == live { partial } else { 0 };
                let (base, d0) = (t.add(i0), 4 * group);
                let out = g.add(i0 * p + i0 + d0);
                match (count, last) {
                    (1, 0) => gram_diagonals::<1, 0, P>(base, d0, n, p, out),
                    (1, 1) => gram_diagonals::<1, 1, P>(base, d0, n, p, out),
                    (1, 2) => gram_diagonals::<1, 2, P>(base, d0, n, p, out),
                    (1, _) => gram_diagonals::<1, 3, P>(base, d0, n, p, out),
                    (2, 0) => gram_diagonals::<2, 0, P>(base, d0, n, p, out),
                    (2, 1) => gram_diagonals::<2, 1, P>(base, d0, n, p, out),
                    (2, 2) => gram_diagonals::<2, 2, P>(base, d0, n, p, out),
                    (2, _) => gram_diagonals::<2, 3, P>(base, d0, n, p, out),
                    (_, 0) => gram_diagonals::<3, 0, P>(base, d0, n, p, out),
                    (_, 1) => gram_diagonals::<3, 1, P>(base, d0, n, p, out),
                    (_, 2) => gram_diagonals::<3, 2, P>(base, d0, n, p, out),
                    (_, _) => gram_diagonals::<3, 3, P>(base, d0, n, p, out),
                }
                group += count;
            }
            // Diagonals reaching columns ≥ m only: zeros.
            let zero = _mm256_setzero_pd();
            for group in live..(p - i0) / 4 {
                for l in 0..4 {
                    _mm256_storeu_pd(g.add((i0 + l) * p + i0 + l + 4 * group), zero);
                }
            }
        }
        i0 += 4;
    }
    let mut j0 = 0;
    while j0 < m {
        // SAFETY: rows and columns below p of `gram` (j0 + 4 ≤ p).
        unsafe {
            // The diagonal block's lower-left from its upper-right.
            let block: [__m256d; 4] =
                core::array::from_fn(|s| _mm256_loadu_pd(g.add((j0 + s) * p + j0)));
            let mirror = transpose4(block);
            let row = |l: usize| g.add((j0 + l) * p + j0);
            _mm256_storeu_pd(row(1), _mm256_blend_pd::<0b0001>(block[1], mirror[1]));
            _mm256_storeu_pd(row(2), _mm256_blend_pd::<0b0011>(block[2], mirror[2]));
            _mm256_storeu_pd(row(3), _mm256_blend_pd::<0b0111>(block[3], mirror[3]));
            // The mirror images G[c.., j0..j0+4] of the blocks G[j0..j0+4, c..] right of the
            // diagonal block (rows j0.. past m, if any, only reach rows ≥ m of G).
            let mut c = j0 + 4;
            while c < p {
                let block: [__m256d; 4] =
                    core::array::from_fn(|s| _mm256_loadu_pd(g.add((j0 + s) * p + c)));
                for (l, tl) in transpose4(block).iter().enumerate() {
                    _mm256_storeu_pd(g.add((c + l) * p + j0), *tl);
                }
                c += 4;
            }
        }
        j0 += 4;
    }
}

/// Diagonals `d₀..d₀ + 4G` of a block of four rows, stored as `G` row pieces.
///
/// Of the last group only the first `L` are computed if `L > 0`; the others come out as
/// zeros. With `base` at `at + i₀`, lane `l` of diagonal `d` is
/// `Σ_k at[k·p + i₀ + l] · at[k·p + i₀ + l + d]`. It is summed in order of `k` (multiply,
/// then add, from `+0`). `out[l·p + l + 4q + δ]`, with `out` at `G[i₀, i₀ + d₀]`, receives
/// diagonal `d₀ + 4q + δ` of lane `l`.
///
/// # Safety
/// The CPU must support AVX2; `base` is readable at `k·p + d₀ + 4G + 2` for `k < n`, `out`
/// writable at `l·p + l + 4G + 3` for `l < 4`; `P` is `0` or `p`.
#[inline(always)]
unsafe fn gram_diagonals<const G: usize, const L: usize, const P: usize>(
    base: *const f64,
    d0: usize,
    n: usize,
    p: usize,
    out: *mut f64,
) {
    let p = if P == 0 { p } else { P };
    // Diagonals computed.
    let live = if L == 0 { 4 * G } else { 4 * G - 4 + L };
    #[inline(always)]
    unsafe fn step(
        acc: &mut [__m256d; 4 * DIAGONAL_GROUPS],
        row: *const f64,
        d0: usize,
        live: usize,
    ) {
        // SAFETY: the caller's promise.
        unsafe {
            let u = _mm256_loadu_pd(row);
            let shifted = row.add(d0);
            for (q, acc_q) in acc.iter_mut().enumerate().take(live) {
                *acc_q = _mm256_add_pd(_mm256_mul_pd(u, _mm256_loadu_pd(shifted.add(q))), *acc_q);
            }
        }
    }
    // SAFETY: the caller's promise.
    unsafe {
        let mut acc = [_mm256_setzero_pd(); 4 * DIAGONAL_GROUPS];
        let mut row = base;
        // k in order: the first on its own (its products added to one register of zeros,
        // not to a zeroed register per accumulator), then four per pass (written out: the
        // compiler keeps a loop over a longer pass rolled, at three instructions per k), then
        // the rest.
        let rest = n.saturating_sub(1);
        if n > 0 {
            step(&mut acc, row, d0, live);
            row = row.add(p);
        }
        for _ in 0..rest / 4 {
            step(&mut acc, row, d0, live);
            step(&mut acc, row.add(p), d0, live);
            step(&mut acc, row.add(2 * p), d0, live);
            step(&mut acc, row.add(3 * p), d0, live);
            row = row.add(4 * p);
        }
        for _ in 0..rest % 4 {
            step(&mut acc, row, d0, live);
            row = row.add(p);
        }
        for q in 0..G {
            let four = [acc[4 * q], acc[4 * q + 1], acc[4 * q + 2], acc[4 * q + 3]];
            for (l, piece) in transpose4(four).iter().enumerate() {
                _mm256_storeu_pd(out.add(l * p + l + 4 * q), *piece);
            }
        }
    }
}

/// `out[4v + l] = Σ_k at[k·p + i] · at[k·p + c + 4v + l]` for `v < V`, where `cols` points
/// at `at + c` and `s = i − c`.
///
/// The sum runs in order of `k`, multiply then add, in `V` accumulators. Each `k` costs one
/// broadcast; the multiplies read the transposed window as their memory operand. A loop pass
/// covers eight `k`. Both factors come from `at`, so one pointer walks the loop; with `P = p`
/// its displacements are constants.
///
/// # Safety
/// The CPU must support AVX2; `cols` is readable at `k·p + s` and `k·p + 4V − 1` for `k < n`,
/// `out` writable at `4V` entries; `P` is `0` or `p`.
#[inline(always)]
unsafe fn gram_strip_avx2<const V: usize, const P: usize>(
    cols: *const f64,
    s: isize,
    n: usize,
    p: usize,
    out: *mut f64,
) {
    let p = if P == 0 { p } else { P };
    #[inline(always)]
    unsafe fn step<const V: usize>(acc: &mut [__m256d; V], col: *const f64, s: isize) {
        // SAFETY: the caller's promise.
        unsafe {
            let u = _mm256_broadcast_sd(&*col.offset(s));
            for (v, acc_v) in acc.iter_mut().enumerate() {
                *acc_v = _mm256_add_pd(_mm256_mul_pd(u, _mm256_loadu_pd(col.add(4 * v))), *acc_v);
            }
        }
    }
    // SAFETY: the caller's promise.
    unsafe {
        let mut acc = [_mm256_setzero_pd(); V];
        let mut col = cols;
        // k in order: eight per pass, then four, then the rest.
        for _ in 0..n / 8 {
            for q in 0..8 {
                step(&mut acc, col.add(q * p), s);
            }
            col = col.add(8 * p);
        }
        if n % 8 >= 4 {
            for q in 0..4 {
                step(&mut acc, col.add(q * p), s);
            }
            col = col.add(4 * p);
        }
        for _ in 0..n % 4 {
            step(&mut acc, col, s);
            col = col.add(p);
        }
        for (v, acc_v) in acc.iter().enumerate() {
            _mm256_storeu_pd(out.add(4 * v), *acc_v);
        }
    }
}

/// `G = A Aᵀ` for `f32` from the transposed window `at` (`n × p`, stride `p`, zero in the
/// padding columns).
///
/// Each block pair `I ≤ J` of eight rows is an 8 × 8 tile in eight `ymm` accumulators, one
/// per row of `I`. Each entry is summed in order of `k` (multiply, then add), as
/// `gram_transposed` does. The tile is stored with its mirror image `G[J, I]`: the same
/// products in the same order, so the same bits.
///
/// # Safety
/// The CPU must support AVX2; `at` holds `n · p` entries and `gram` `p · p`, `p` a multiple
/// of 8.
#[target_feature(enable = "avx2")]
unsafe fn gram_f32(at: &[f32], n: usize, p: usize, gram: &mut [f32]) {
    let (t, g) = (at.as_ptr(), gram.as_mut_ptr());
    let mut bj = 0;
    while bj < p {
        let mut bi = 0;
        while bi <= bj {
            // SAFETY: reads `at` below n · p, writes `gram` below p · p (bi, bj + 8 ≤ p).
            unsafe {
                let mut c = [_mm256_setzero_ps(); 8];
                for k in 0..n {
                    let row = t.add(k * p);
                    let v = _mm256_loadu_ps(row.add(bj));
                    for (s, cs) in c.iter_mut().enumerate() {
                        let u = _mm256_set1_ps(*row.add(bi + s));
                        *cs = _mm256_add_ps(_mm256_mul_ps(u, v), *cs);
                    }
                }
                for (s, cs) in c.iter().enumerate() {
                    _mm256_storeu_ps(g.add((bi + s) * p + bj), *cs);
                }
                if bi < bj {
                    for (l, tl) in transpose8_ps(c).iter().enumerate() {
                        _mm256_storeu_ps(g.add((bj + l) * p + bi), *tl);
                    }
                }
            }
            bi += 8;
        }
        bj += 8;
    }
}

/// The transpose of an 8 × 8 block of `f32` held as eight row vectors.
#[target_feature(enable = "avx2")]
#[inline]
fn transpose8_ps(r: [__m256; 8]) -> [__m256; 8] {
    // Pairs of rows interleaved, then pairs of pairs, then the 128-bit halves.
    let t: [__m256; 8] = core::array::from_fn(|q| {
        let (a, b) = (r[2 * (q / 2)], r[2 * (q / 2) + 1]);
        if q % 2 == 0 {
            _mm256_unpacklo_ps(a, b)
        } else {
            _mm256_unpackhi_ps(a, b)
        }
    });
    let u: [__m256; 8] = [
        _mm256_shuffle_ps::<0x44>(t[0], t[2]),
        _mm256_shuffle_ps::<0xee>(t[0], t[2]),
        _mm256_shuffle_ps::<0x44>(t[1], t[3]),
        _mm256_shuffle_ps::<0xee>(t[1], t[3]),
        _mm256_shuffle_ps::<0x44>(t[4], t[6]),
        _mm256_shuffle_ps::<0xee>(t[4], t[6]),
        _mm256_shuffle_ps::<0x44>(t[5], t[7]),
        _mm256_shuffle_ps::<0xee>(t[5], t[7]),
    ];
    [
        _mm256_permute2f128_ps::<0x20>(u[0], u[4]),
        _mm256_permute2f128_ps::<0x20>(u[1], u[5]),
        _mm256_permute2f128_ps::<0x20>(u[2], u[6]),
        _mm256_permute2f128_ps::<0x20>(u[3], u[7]),
        _mm256_permute2f128_ps::<0x31>(u[0], u[4]),
        _mm256_permute2f128_ps::<0x31>(u[1], u[5]),
        _mm256_permute2f128_ps::<0x31>(u[2], u[6]),
        _mm256_permute2f128_ps::<0x31>(u[3], u[7]),
    ]
}

/// The transpose of an 8 × 8 block held as eight row vectors.
#[target_feature(enable = "avx512f")]
fn transpose8(r: [__m512d; 8]) -> [__m512d; 8] {
    // Pairs of rows interleaved, then 128-bit lanes of four rows, then 256-bit halves.
    let t: [__m512d; 8] = core::array::from_fn(|q| {
        let (a, b) = (r[2 * (q / 2)], r[2 * (q / 2) + 1]);
        if q % 2 == 0 {
            _mm512_unpacklo_pd(a, b) // a0 b0 a2 b2 a4 b4 a6 b6
        } else {
            _mm512_unpackhi_pd(a, b) // a1 b1 a3 b3 a5 b5 a7 b7
        }
    });
    // Then 128-bit lanes: u[0] = (r0,r1 | r2,r3) pairs of columns 0, 2, 4, 6 in lanes of
    // t[0] and t[2]; the last step joins rows 0-3 with rows 4-7.
    let u: [__m512d; 8] = [
        _mm512_shuffle_f64x2::<0b10_00_10_00>(t[0], t[2]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(t[1], t[3]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(t[0], t[2]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(t[1], t[3]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(t[4], t[6]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(t[5], t[7]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(t[4], t[6]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(t[5], t[7]),
    ];
    [
        _mm512_shuffle_f64x2::<0b10_00_10_00>(u[0], u[4]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(u[1], u[5]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(u[2], u[6]),
        _mm512_shuffle_f64x2::<0b10_00_10_00>(u[3], u[7]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(u[0], u[4]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(u[1], u[5]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(u[2], u[6]),
        _mm512_shuffle_f64x2::<0b11_01_11_01>(u[3], u[7]),
    ]
}

/// The transpose of a 4 × 4 block held as four row vectors.
#[target_feature(enable = "avx2")]
#[inline]
fn transpose4(r: [__m256d; 4]) -> [__m256d; 4] {
    let lo01 = _mm256_unpacklo_pd(r[0], r[1]); // r00 r10 r02 r12
    let hi01 = _mm256_unpackhi_pd(r[0], r[1]); // r01 r11 r03 r13
    let lo23 = _mm256_unpacklo_pd(r[2], r[3]); // r20 r30 r22 r32
    let hi23 = _mm256_unpackhi_pd(r[2], r[3]); // r21 r31 r23 r33
    [
        _mm256_permute2f128_pd(lo01, lo23, 0x20),
        _mm256_permute2f128_pd(hi01, hi23, 0x20),
        _mm256_permute2f128_pd(lo01, lo23, 0x31),
        _mm256_permute2f128_pd(hi01, hi23, 0x31),
    ]
}

/// The greedy loop of [`crate::greedy::iterate_portable`] for `f64` with the window held in
/// AVX-512 registers (`p = 8C ≤ 32`). Residual, squares, ratios, weights and prefix sums stay
/// in `C` registers each across the iterations. So an iteration is one dependency chain of
/// vector operations. It has a single memory read (the Gram row) and no branch on the data
/// except the choice itself. Same operations, same order, same bits as the portable loop.
///
/// # Safety
/// The CPU must support AVX-512F and BMI2.
#[target_feature(enable = "avx512f,bmi2")]
unsafe fn iterate_avx512<const C: usize, const AVERAGE: bool>(
    w: Window<'_, f64>,
    mut rnorm2: f64,
    max_ratio: f64,
    s: Schedule<f64>,
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
    let zero = _mm512_setzero_pd();
    // Held in registers across iterations: r, r²/‖a‖² and 1/‖a‖² (r² is recomputed where
    // needed, which is off the critical path and keeps the loop free of spills).
    // SAFETY: every pointer access is below p entries of its slice (checked above).
    let mut r: [__m512d; C] =
        core::array::from_fn(|c| unsafe { _mm512_loadu_pd(rp.add(LANES * c)) });
    // SAFETY: as above.
    let inv: [__m512d; C] = core::array::from_fn(|c| unsafe { _mm512_loadu_pd(ip.add(LANES * c)) });
    let mut ratio: [__m512d; C] =
        core::array::from_fn(|c| _mm512_mul_pd(_mm512_mul_pd(r[c], r[c]), inv[c]));
    // α_j = r_j/‖a_j‖² of the current residual, read back once the row is known.
    let mut alphas = [0.0f64; LANES * MAX_CHUNKS];
    for c in 0..C {
        // SAFETY: LANES · (c + 1) ≤ LANES · MAX_CHUNKS.
        unsafe {
            _mm512_storeu_pd(
                alphas.as_mut_ptr().add(LANES * c),
                _mm512_mul_pd(r[c], inv[c]),
            )
        };
    }

    let mut sum_v = _mm512_set1_pd(rnorm2);
    let mut max_v = _mm512_set1_pd(max_ratio);
    let mut draws = Draws::new(rng, s.t_total);
    let mut iterations = 0;
    let mut converged = rnorm2 <= s.tol2;
    while !converged && iterations < s.t_total {
        iterations += 1;
        // θ = M·½ + S·(½/‖A‖_F²), with S and M held in every lane.
        let threshold = _mm512_add_pd(
            _mm512_mul_pd(max_v, _mm512_set1_pd(0.5)),
            _mm512_mul_pd(sum_v, _mm512_set1_pd(s.half_inv_fro2)),
        );
        // Candidate weights r_j² (where r_j²/‖a_j‖² ≥ θ), their running sums down the chunks,
        // lane by lane, then across the lanes; the row drawn by the rule of the portable loop
        // (`pick_avx512`: among positive weights only, as `lanes::pick_chunks`).
        let weights: [__m512d; C] = core::array::from_fn(|c| {
            let candidate = _mm512_cmp_pd_mask::<_CMP_GE_OQ>(ratio[c], threshold);
            _mm512_maskz_mul_pd(candidate, r[c], r[c])
        });
        let (down, before, total) = prefix_avx512(&weights);
        let mut chosen = None;
        if _mm512_cvtsd_f64(total) > 0.0 {
            let target = _mm512_mul_pd(_mm512_set1_pd(draws.next()), total);
            chosen = pick_avx512(&weights, &down, before, target);
        }
        let i = chosen.unwrap_or_else(|| {
            let mut inv_norm2 = [0.0f64; LANES * MAX_CHUNKS];
            let mut resid = [0.0f64; LANES * MAX_CHUNKS];
            for c in 0..C {
                // SAFETY: LANES · (c + 1) ≤ LANES · MAX_CHUNKS.
                unsafe {
                    _mm512_storeu_pd(inv_norm2.as_mut_ptr().add(LANES * c), inv[c]);
                    _mm512_storeu_pd(resid.as_mut_ptr().add(LANES * c), r[c]);
                }
            }
            argmax_ratio(&resid[..p], &inv_norm2[..p])
        });
        let alpha = alphas[i];
        w.coef[i] += alpha;
        if AVERAGE {
            w.coef_avg[i] += alpha * s.weight(iterations);
        }
        // r ← r − α G e_i, r_i ← 0, and the statistics of the new residual.
        let a = _mm512_set1_pd(alpha);
        let row = 1u64 << i;
        // SAFETY: row i < p of the p × p Gram matrix.
        let g = unsafe { gp.add(i * p) };
        let mut squares = [zero; MAX_CHUNKS];
        let mut best = zero;
        for c in 0..C {
            // SAFETY: columns below p of row i.
            let gc = unsafe { _mm512_loadu_pd(g.add(LANES * c)) };
            let v = _mm512_sub_pd(r[c], _mm512_mul_pd(a, gc));
            let v = _mm512_mask_mov_pd(v, (row >> (LANES * c)) as u8, zero);
            r[c] = v;
            let r2 = _mm512_mul_pd(v, v);
            ratio[c] = _mm512_mul_pd(r2, inv[c]);
            // SAFETY: LANES · (c + 1) ≤ LANES · MAX_CHUNKS.
            unsafe {
                _mm512_storeu_pd(alphas.as_mut_ptr().add(LANES * c), _mm512_mul_pd(v, inv[c]))
            };
            squares[c] = r2;
            // MAXPD returns its second operand if either is NaN: keep `best`, as the
            // portable `if v > best` does.
            best = _mm512_max_pd(ratio[c], best);
        }
        // Chunk by chunk into the eight lane sums (0 + x = x for the first: squares are
        // never −0).
        let mut sum = squares[0];
        for sq in &squares[1..C] {
            sum = _mm512_add_pd(sum, *sq);
        }
        // Butterflies leave the total in every lane: s_l + s_{l+4}, then (t₀ + t₂) and
        // (t₁ + t₃), then their sum, as the portable loop adds them.
        sum_v = _mm512_add_pd(sum, _mm512_shuffle_f64x2::<0b01_00_11_10>(sum, sum));
        sum_v = _mm512_add_pd(sum_v, _mm512_shuffle_f64x2::<0b10_11_00_01>(sum_v, sum_v));
        sum_v = _mm512_add_pd(sum_v, _mm512_permute_pd::<0b0101_0101>(sum_v));
        max_v = _mm512_max_pd(best, _mm512_shuffle_f64x2::<0b01_00_11_10>(best, best));
        max_v = _mm512_max_pd(max_v, _mm512_shuffle_f64x2::<0b10_11_00_01>(max_v, max_v));
        max_v = _mm512_max_pd(max_v, _mm512_permute_pd::<0b0101_0101>(max_v));
        rnorm2 = _mm512_cvtsd_f64(sum_v);
        converged = rnorm2 <= s.tol2;
    }
    draws.finish();
    for (c, rc) in r.iter().enumerate() {
        // SAFETY: below p entries of the residual.
        unsafe { _mm512_storeu_pd(rp.add(LANES * c), *rc) };
    }
    (iterations, converged)
}

/// The running sums of `C` chunks of weights in the sampling order (as
/// `lanes::prefix_chunks`): the sums down the chunks, the in-chunk scan of the lane totals
/// shifted by one lane (`+0` in lane 0), the total in every lane.
#[target_feature(enable = "avx512f")]
#[inline]
fn prefix_avx512<const C: usize>(weights: &[__m512d; C]) -> ([__m512d; C], __m512d, __m512d) {
    let mut down = *weights;
    for c in 1..C {
        down[c] = _mm512_add_pd(down[c - 1], weights[c]);
    }
    let across = scan8(down[C - 1]);
    let before =
        _mm512_maskz_permutexvar_pd(0xfe, _mm512_setr_epi64(0, 0, 1, 2, 3, 4, 5, 6), across);
    (
        down,
        before,
        _mm512_permutexvar_pd(_mm512_set1_epi64(LANES as i64 - 1), across),
    )
}

/// The row drawn for `target` by the portable loop's rule (`greedy::draw_row`, as
/// `lanes::pick_chunks`).
///
/// It is the first row in lane-major order with a positive weight and a running sum past the
/// target. On round-off it is the last with a positive weight; `None` if none is positive.
/// (A candidate's weight is zero when the threshold underflows to zero and its
/// residual is zero; its running sum can still pass the target by round-off, so candidates are
/// not the rows that may be drawn.)
#[target_feature(enable = "avx512f,bmi2")]
#[inline]
fn pick_avx512<const C: usize>(
    weights: &[__m512d; C],
    down: &[__m512d; C],
    before: __m512d,
    target: __m512d,
) -> Option<usize> {
    let zero = _mm512_setzero_pd();
    let positive: [u8; C] =
        core::array::from_fn(|c| _mm512_cmp_pd_mask::<_CMP_GT_OQ>(weights[c], zero));
    // Bits in lane-major order (bit 4l + c for row 8c + l).
    let mut hit = 0u32;
    for c in 0..C {
        let prefix = _mm512_add_pd(before, down[c]);
        let past = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(prefix, target);
        hit |= _pdep_u32(u32::from(positive[c] & past), LANE_MAJOR << c);
    }
    let row = |bit: u32| LANES * (bit as usize % 4) + bit as usize / 4;
    if hit != 0 {
        Some(row(hit.trailing_zeros()))
    } else {
        // Round-off: the last positive weight in lane-major order.
        let positive = (0..C).fold(0u32, |acc, c| {
            acc | _pdep_u32(u32::from(positive[c]), LANE_MAJOR << c)
        });
        (positive != 0).then(|| row(31 - positive.leading_zeros()))
    }
}

/// Every fourth bit: `pdep` spreads a chunk's 8 lane bits to bits `4l + c`.
const LANE_MAJOR: u32 = 0x1111_1111;

/// The in-chunk prefix sums of the documented order: `x_l ← x_l + x_{l−d}` for `d = 1, 2, 4`,
/// each shift one lane permutation with zeroing (cheaper on Zen 4 than `valignq`, which the
/// compiler turns into `vexpandpd`).
#[target_feature(enable = "avx512f")]
#[inline]
fn scan8(x: __m512d) -> __m512d {
    let by1 = _mm512_setr_epi64(0, 0, 1, 2, 3, 4, 5, 6);
    let by2 = _mm512_setr_epi64(0, 0, 0, 1, 2, 3, 4, 5);
    let by4 = _mm512_setr_epi64(0, 0, 0, 0, 0, 1, 2, 3);
    let x = _mm512_add_pd(x, _mm512_maskz_permutexvar_pd(0xfe, by1, x));
    let x = _mm512_add_pd(x, _mm512_maskz_permutexvar_pd(0xfc, by2, x));
    _mm512_add_pd(x, _mm512_maskz_permutexvar_pd(0xf0, by4, x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::greedy::{draw_row, lane_major_prefix};
    use crate::lanes::{first_above, pick_chunks, prefix_chunks};
    use rand_chacha::rand_core::SeedableRng;
    use rand_core::Rng;
    use std::vec;
    use std::vec::Vec;

    /// The row the eight-lane loop (AVX2) draws for weights `w` (`8C` entries) and `target`:
    /// the first row above the target if its weight is positive, else `pick_chunks` (which
    /// must agree with the shortcut whenever that finds a row).
    #[target_feature(enable = "avx2")]
    unsafe fn draw_lanes<V: Lanes8, const C: usize>(w: &[V::T], target: V::T) -> Option<usize> {
        // SAFETY: 8C entries.
        let weights: [V; C] =
            core::array::from_fn(|c| unsafe { V::load(w.as_ptr().add(LANES * c)) });
        let (down, before, _) = prefix_chunks(&weights);
        let zero = V::splat(V::T::cast(0.0));
        let mut positive = weights;
        for w in positive.iter_mut() {
            *w = w.gt_mask(zero);
        }
        let target = V::splat(target);
        let drawn = pick_chunks(&positive, &down, before, target);
        let shortcut = first_above(&down, before, target).filter(|&j| w[j] > V::T::cast(0.0));
        assert!(
            shortcut.is_none() || shortcut == drawn,
            "{shortcut:?} {drawn:?}"
        );
        shortcut.or(drawn)
    }

    /// The row the AVX-512 loop draws for weights `w` (`8C` entries) and `target`.
    #[target_feature(enable = "avx512f,bmi2")]
    unsafe fn draw_avx512<const C: usize>(w: &[f64], target: f64) -> Option<usize> {
        // SAFETY: 8C entries.
        let weights: [__m512d; C] =
            core::array::from_fn(|c| unsafe { _mm512_loadu_pd(w.as_ptr().add(LANES * c)) });
        let (down, before, _) = prefix_avx512(&weights);
        pick_avx512(&weights, &down, before, _mm512_set1_pd(target))
    }

    /// A kernel's row drawing for one chunk count.
    type Draw<T> = unsafe fn(&[T], T) -> Option<usize>;

    fn by_chunks<T: Real>(w: &[T], f: [Draw<T>; 4], target: T) -> Option<usize> {
        // SAFETY: the caller checked the CPU features.
        unsafe { f[w.len() / LANES - 1](w, target) }
    }

    /// Every kernel set draws the row the portable loop draws (`greedy::draw_row`). That is
    /// the first positive weight in lane-major order whose running sum passes the target, else
    /// the last positive weight. Here a row of weight zero passes the target by round-off, as
    /// a candidate of a threshold that underflowed to zero would. Drawing among candidates
    /// instead of positive weights (the AVX-512 loop's former shortcut) fails here.
    #[test]
    fn every_kernel_draws_the_portable_row() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let avx512 =
            std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("bmi2");
        let e = f64::EPSILON / 2.0;
        // Lane sums 1, 0, 2⁻⁵³, 2⁻⁵³, 0, 1, 0, 0: the scan across the lanes gives
        // x₃ = 1 + 2⁻⁵², the sequential sum up to lane 3 is 1, so row 4 (weight 0) has a
        // running sum 1 + 2⁻⁵² past the target 1; the row drawn is 5.
        let crafted = [1.0, 0.0, e, e, 0.0, 1.0, 0.0, 0.0];
        let mut cases: Vec<(Vec<f64>, f64)> = vec![
            (crafted.to_vec(), 1.0),
            (crafted.to_vec(), 4.0), // past the total: the last positive weight
            (vec![0.0; 8], 0.0),
            ([crafted.to_vec(), vec![0.0; 8]].concat(), 1.0),
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(16);
        for c in 1..=MAX_CHUNKS {
            for _ in 0..300 {
                let w: Vec<f64> = (0..LANES * c)
                    .map(|_| match rng.next_u32() % 4 {
                        0 => 0.0,
                        1 => f64::from(rng.next_u32() % 4) * e,
                        _ => crate::greedy::uniform(&mut rng),
                    })
                    .collect();
                let mut prefix = vec![0.0; w.len()];
                let total = lane_major_prefix(&w, &mut prefix);
                cases.push((w, crate::greedy::uniform(&mut rng) * total));
            }
        }
        let lanes64 = [
            draw_lanes::<F64x8, 1> as Draw<f64>,
            draw_lanes::<F64x8, 2>,
            draw_lanes::<F64x8, 3>,
            draw_lanes::<F64x8, 4>,
        ];
        let lanes32 = [
            draw_lanes::<F32x8, 1> as Draw<f32>,
            draw_lanes::<F32x8, 2>,
            draw_lanes::<F32x8, 3>,
            draw_lanes::<F32x8, 4>,
        ];
        let wide = [
            draw_avx512::<1> as Draw<f64>,
            draw_avx512::<2>,
            draw_avx512::<3>,
            draw_avx512::<4>,
        ];
        for (k, (w, target)) in cases.iter().enumerate() {
            let mut prefix = vec![0.0; w.len()];
            lane_major_prefix(w, &mut prefix);
            let want = draw_row(w, &prefix, *target);
            assert_eq!(
                by_chunks(w, lanes64, *target),
                want,
                "AVX2 f64, case {k}: {w:?} {target}"
            );
            if avx512 {
                assert_eq!(
                    by_chunks(w, wide, *target),
                    want,
                    "AVX-512, case {k}: {w:?} {target}"
                );
            }
            let w32: Vec<f32> = w.iter().map(|&v| v as f32).collect();
            let mut prefix32 = vec![0.0f32; w.len()];
            lane_major_prefix(&w32, &mut prefix32);
            let t32 = *target as f32;
            assert_eq!(
                by_chunks(&w32, lanes32, t32),
                draw_row(&w32, &prefix32, t32),
                "AVX2 f32, case {k}"
            );
        }
        assert_eq!(
            draw_row(
                &crafted,
                &{
                    let mut p = [0.0; 8];
                    lane_major_prefix(&crafted, &mut p);
                    p
                },
                1.0
            ),
            Some(5)
        );
    }

    /// `prepare_f64` against the estimator's portable passes (written out here as
    /// `kaczmarz.rs` runs them), bit for bit: every window height up to 40, zero rows, stale
    /// values in the padding.
    #[test]
    fn avx2_prepare_is_the_portable_pass() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for m in 1..=40 {
            let pm = padded(m);
            let mut value = |zero_every: u32| {
                if rng.next_u32() % zero_every == 0 {
                    0.0
                } else {
                    crate::greedy::uniform(&mut rng) * 3.0
                }
            };
            let norm2: Vec<f64> = (0..pm).map(|_| value(5)).collect();
            let resid: Vec<f64> = (0..pm).map(|_| value(7) - 1.5).collect();
            let (mut n1, mut i1, mut r1, mut c1, mut a1) = (
                norm2.clone(),
                vec![9.0; pm],
                resid.clone(),
                vec![9.0; pm],
                vec![9.0; pm],
            );
            let (mut n2, mut i2, mut r2, mut c2, mut a2) =
                (n1.clone(), i1.clone(), r1.clone(), c1.clone(), a1.clone());
            n1[m..].fill(0.0);
            r1[m..].fill(0.0);
            for i in 0..pm {
                let usable = n1[i] > 0.0;
                i1[i] = if usable { 1.0 / n1[i] } else { 0.0 };
                r1[i] = if usable { r1[i] } else { 0.0 };
                c1[i] = 0.0;
                a1[i] = 0.0;
            }
            let fro2 = crate::greedy::lane_sum(&n1);
            let (rnorm2, max_ratio) = crate::greedy::residual_stats(&r1, &i1);
            let want = (fro2, rnorm2, max_ratio);
            // SAFETY: AVX2 detected above.
            let got = unsafe { prepare_f64(m, pm, &mut n2, &mut i2, &mut r2, &mut c2, &mut a2) };
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                [want.0.to_bits(), want.1.to_bits(), want.2.to_bits()],
                [got.0.to_bits(), got.1.to_bits(), got.2.to_bits()],
                "m={m}"
            );
            for (x, y) in [(&n1, &n2), (&i1, &i2), (&r1, &r2), (&c1, &c2), (&a1, &a2)] {
                assert_eq!(bits(x), bits(y), "m={m}");
            }
        }
    }

    /// With a threshold `θ > 0` the candidates
    /// (`r²·(1/‖a‖²) ≥ θ`) are exactly the rows of positive weight, over squares and reciprocal
    /// norms with zeros, subnormals, infinities and NaNs.
    #[test]
    fn candidates_are_the_positive_weights_when_the_threshold_is_positive() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let special = [
            0.0,
            5e-324,
            1e-300,
            0.5,
            1.0,
            3e300,
            f64::INFINITY,
            f64::NAN,
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..2000 {
            let mut pick = || {
                let k = rng.next_u32() as usize;
                if k.is_multiple_of(3) {
                    special[k / 3 % special.len()]
                } else {
                    crate::greedy::uniform(&mut rng) * 2.0
                }
            };
            let sq: [f64; 8] = core::array::from_fn(|_| pick());
            let inv: [f64; 8] = core::array::from_fn(|_| pick());
            let theta = pick();
            if theta.is_nan() || theta <= 0.0 {
                continue;
            }
            // SAFETY: AVX2 detected above; eight entries each.
            let (candidate, positive) = unsafe { candidate_and_positive(&sq, &inv, theta) };
            assert_eq!(candidate, positive, "sq {sq:?} inv {inv:?} theta {theta}");
        }
    }

    /// The candidate and positive-weight masks of eight lanes, as `iterate_chunks` forms them.
    #[target_feature(enable = "avx2")]
    unsafe fn candidate_and_positive(sq: &[f64; 8], inv: &[f64; 8], theta: f64) -> (u32, u32) {
        // SAFETY: eight entries each.
        let (sq, inv) = unsafe { (F64x8::load(sq.as_ptr()), F64x8::load(inv.as_ptr())) };
        let candidate = sq.mul(inv).ge_mask(F64x8::splat(theta));
        let positive = candidate.and(sq).gt_mask(F64x8::splat(0.0));
        (
            F64x8::lane_major_bits(&[candidate]),
            F64x8::lane_major_bits(&[positive]),
        )
    }

    /// The `f64` packing and Gram kernels (AVX2 tiles, the previous AVX2 diagonals, AVX-512
    /// tiles where the CPU has them) against the portable ones (`transpose_padded`,
    /// `gram_transposed`, `residual_rows`), bit for bit. Every Gram entry is also checked
    /// against a plain loop over `k` (multiply, then add). Window heights go up to 41; widths
    /// around the multiples of 4 and random ones in 10..=120. Compared: rows `< m` of `G` in
    /// full and the `p` residuals. Stale NaNs fill the scratch and the slack past `at`, which
    /// the diagonals read. Sentinels past `G` and `r` must not be written.
    #[test]
    fn simd_gram_and_residual_are_the_portable_bits() {
        use crate::linalg::{TRANSPOSED_SLACK, gram_transposed, residual_rows, transpose_padded};
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut kernels = vec![GramKernel::Avx2Tiles, GramKernel::Diagonals];
        if std::is_x86_feature_detected!("avx512f") {
            kernels.push(GramKernel::Avx512Tiles);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(41);
        let mut value = || crate::greedy::uniform(&mut rng) * 2.0 - 1.0;
        let mut shapes = ChaCha8Rng::seed_from_u64(43);
        for m in 1..=41 {
            let random: [usize; 4] =
                core::array::from_fn(|_| 10 + (shapes.next_u64() % 111) as usize);
            for n in [1, 2, 3, 4, 5, 7, 10, 13, 120].into_iter().chain(random) {
                let p = padded(m);
                let a: Vec<f64> = (0..m * n).map(|_| value()).collect();
                let b: Vec<f64> = (0..m).map(|_| value()).collect();
                let x: Vec<f64> = (0..n).map(|_| value()).collect();
                let mut at = vec![0.0; n * p];
                transpose_padded(&a, n, m, &mut at);
                let mut want_g = vec![0.0; p * p];
                gram_transposed(&at, n, m, &mut want_g);
                let mut want_r = vec![0.0; p];
                residual_rows(&a, n, m, &x, &b, &mut want_r);
                for i in 0..m {
                    for j in 0..m {
                        let plain = (0..n).fold(0.0, |s, k| a[i * n + k] * a[j * n + k] + s);
                        assert_eq!(plain.to_bits(), want_g[i * p + j].to_bits(), "m={m} n={n}");
                    }
                }
                for &kernel in &kernels {
                    let mut at = vec![f64::NAN; n * p + TRANSPOSED_SLACK];
                    let mut g = vec![f64::NAN; p * p + 8];
                    let mut r = vec![f64::NAN; p + 8];
                    g[p * p..].fill(7.0);
                    r[p..].fill(7.0);
                    // SAFETY: AVX2 detected above, AVX-512F where that kernel runs.
                    unsafe {
                        gram_and_residual_f64(
                            kernel,
                            &a,
                            &b,
                            &x,
                            n,
                            m,
                            &mut at,
                            &mut g[..p * p],
                            &mut r[..p],
                        )
                    };
                    for i in 0..m {
                        for j in 0..p {
                            assert_eq!(
                                g[i * p + j].to_bits(),
                                want_g[i * p + j].to_bits(),
                                "{kernel:?} m={m} n={n} G[{i}][{j}]"
                            );
                        }
                    }
                    for j in 0..p {
                        assert_eq!(
                            r[j].to_bits(),
                            want_r[j].to_bits(),
                            "{kernel:?} m={m} n={n} r[{j}]"
                        );
                    }
                    assert!(
                        g[p * p..].iter().chain(&r[p..]).all(|&v| v == 7.0),
                        "{kernel:?} m={m} n={n}"
                    );
                }
            }
        }
    }

    #[test]
    fn f32_transpose_is_a_transpose() {
        if !std::is_x86_feature_detected!("avx2") {
            return;
        }
        let rows: [__m256; 8] = core::array::from_fn(|r| {
            let v: [f32; 8] = core::array::from_fn(|c| (10 * r + c) as f32);
            // SAFETY: reads eight f32 from an array of eight (AVX2 detected above).
            unsafe { _mm256_loadu_ps(v.as_ptr()) }
        });
        // SAFETY: AVX2 detected above.
        let t = unsafe { transpose8_ps(rows) };
        for (c, tc) in t.iter().enumerate() {
            let mut out = [0.0f32; 8];
            // SAFETY: writes eight f32 into an array of eight.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), *tc) };
            let want: [f32; 8] = core::array::from_fn(|r| (10 * r + c) as f32);
            assert_eq!(out, want, "column {c}");
        }
    }

    #[test]
    fn transposes_are_transposes() {
        if !std::is_x86_feature_detected!("avx512f") {
            return;
        }
        let rows: [__m512d; 8] = core::array::from_fn(|r| {
            let v: [f64; 8] = core::array::from_fn(|c| (10 * r + c) as f64);
            // SAFETY: reads eight f64 from an array of eight.
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        });
        // SAFETY: AVX-512F detected above.
        let t = unsafe { transpose8(rows) };
        for (c, tc) in t.iter().enumerate() {
            let mut out = [0.0; 8];
            // SAFETY: writes eight f64 into an array of eight.
            unsafe { _mm512_storeu_pd(out.as_mut_ptr(), *tc) };
            let want: [f64; 8] = core::array::from_fn(|r| (10 * r + c) as f64);
            assert_eq!(out, want, "column {c}");
        }
    }
}
