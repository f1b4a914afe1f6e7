//! NEON kernels of the greedy iterations on aarch64 (NEON is part of the base instruction
//! set there, so they are chosen at compile time, with or without `std`).
//!
//! The Gram matrix and the residual come from the portable loops; the greedy loop is the
//! eight-lane loop of the `lanes` module, `f64` as four `q` registers per chunk and `f32` as
//! two. Same operations in the same order as [`crate::greedy::Portable`] (multiplies and adds
//! separate, never fused), so estimates are bit-identical to x86-64's and a microcontroller's.

use core::any::TypeId;
use core::arch::aarch64::*;

use rand_chacha::ChaCha8Rng;

use crate::Real;
use crate::greedy::{Kernels, LANES, Portable, Schedule, Window, iterate_portable};
use crate::lanes::{KEEP_F32, KEEP_F64, KEEP_LEN, Lanes8, MAX_CHUNKS, iterate_chunks};

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
        Portable.gram_and_residual(a, b, x, n, m, at, gram, resid)
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
    unsafe {
        match chunks {
            1 => iterate_chunks::<V, 1, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            2 => iterate_chunks::<V, 2, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            3 => iterate_chunks::<V, 3, AVERAGE>(w, rnorm2, max_ratio, s, rng),
            _ => iterate_chunks::<V, 4, AVERAGE>(w, rnorm2, max_ratio, s, rng),
        }
    }
}

/// Eight `f64` lanes as four NEON `q` registers (lanes 0–1, 2–3, 4–5, 6–7).
#[derive(Clone, Copy)]
struct F64x8([float64x2_t; 4]);

/// Eight `f32` lanes as two NEON `q` registers (lanes 0–3, 4–7).
#[derive(Clone, Copy)]
struct F32x8([float32x4_t; 2]);

/// Lane `l` of a mask register contributes bit `l` (then `2l`, `4l`, … across registers).
const BITS_F64: [[u64; 2]; 4] = [[1, 2], [4, 8], [16, 32], [64, 128]];
/// As [`BITS_F64`], four lanes a register.
const BITS_F32: [[u32; 4]; 2] = [[1, 2, 4, 8], [16, 32, 64, 128]];

impl F64x8 {
    #[inline(always)]
    fn map(self, o: Self, f: impl Fn(float64x2_t, float64x2_t) -> float64x2_t) -> Self {
        Self(core::array::from_fn(|q| f(self.0[q], o.0[q])))
    }
    /// Bits of four lane masks (all-ones or zero per lane).
    #[inline(always)]
    fn bits(m: [uint64x2_t; 4]) -> u8 {
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            let mut acc = vdupq_n_u64(0);
            for (q, mq) in m.iter().enumerate() {
                acc = vorrq_u64(acc, vandq_u64(*mq, vld1q_u64(BITS_F64[q].as_ptr())));
            }
            vaddvq_u64(acc) as u8
        }
    }
}

impl F32x8 {
    #[inline(always)]
    fn map(self, o: Self, f: impl Fn(float32x4_t, float32x4_t) -> float32x4_t) -> Self {
        Self(core::array::from_fn(|q| f(self.0[q], o.0[q])))
    }
    /// Bits of two lane masks (all-ones or zero per lane).
    #[inline(always)]
    fn bits(m: [uint32x4_t; 2]) -> u8 {
        // SAFETY: NEON is baseline on aarch64.
        unsafe {
            let lo = vandq_u32(m[0], vld1q_u32(BITS_F32[0].as_ptr()));
            let hi = vandq_u32(m[1], vld1q_u32(BITS_F32[1].as_ptr()));
            vaddvq_u32(vorrq_u32(lo, hi)) as u8
        }
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
    fn select_ge(self, t: Self, v: Self) -> Self {
        Self(core::array::from_fn(|q| unsafe {
            vreinterpretq_f64_u64(vandq_u64(
                vcgeq_f64(self.0[q], t.0[q]),
                vreinterpretq_u64_f64(v.0[q]),
            ))
        }))
    }
    #[inline(always)]
    fn gt_bits(self, t: Self) -> u8 {
        Self::bits(core::array::from_fn(|q| unsafe {
            vcgtq_f64(self.0[q], t.0[q])
        }))
    }
    #[inline(always)]
    fn gt_gt_bits(self, t: Self, prefix: Self, target: Self) -> u8 {
        Self::bits(core::array::from_fn(|q| unsafe {
            vandq_u64(
                vcgtq_f64(self.0[q], t.0[q]),
                vcgtq_f64(prefix.0[q], target.0[q]),
            )
        }))
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
    fn select_ge(self, t: Self, v: Self) -> Self {
        Self(core::array::from_fn(|q| unsafe {
            vreinterpretq_f32_u32(vandq_u32(
                vcgeq_f32(self.0[q], t.0[q]),
                vreinterpretq_u32_f32(v.0[q]),
            ))
        }))
    }
    #[inline(always)]
    fn gt_bits(self, t: Self) -> u8 {
        Self::bits(core::array::from_fn(|q| unsafe {
            vcgtq_f32(self.0[q], t.0[q])
        }))
    }
    #[inline(always)]
    fn gt_gt_bits(self, t: Self, prefix: Self, target: Self) -> u8 {
        Self::bits(core::array::from_fn(|q| unsafe {
            vandq_u32(
                vcgtq_f32(self.0[q], t.0[q]),
                vcgtq_f32(prefix.0[q], target.0[q]),
            )
        }))
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
