//! Small dense vector kernels written so the compiler vectorises them.
//!
//! Floating-point reductions are not reassociated by the compiler, so a naive `sum` of products
//! runs one add at a time. These kernels keep four independent partial sums, which LLVM maps
//! onto SIMD lanes on the host and which keeps the FPU pipeline full on a Cortex-M7.
//! The summation order is fixed, so results are bit-identical from run to run.

use crate::Real;

/// `xᵀy` for equal-length slices (extra entries of the longer slice are ignored).
#[inline]
pub fn dot<T: Real>(x: &[T], y: &[T]) -> T {
    let len = x.len().min(y.len());
    let (x, y) = (&x[..len], &y[..len]);
    let mut acc = [T::zero(); 4];
    let xc = x.chunks_exact(4);
    let yc = y.chunks_exact(4);
    let (xr, yr) = (xc.remainder(), yc.remainder());
    for (p, q) in xc.zip(yc) {
        acc[0] = p[0].mul_add_fast(q[0], acc[0]);
        acc[1] = p[1].mul_add_fast(q[1], acc[1]);
        acc[2] = p[2].mul_add_fast(q[2], acc[2]);
        acc[3] = p[3].mul_add_fast(q[3], acc[3]);
    }
    let mut tail = T::zero();
    for (p, q) in xr.iter().zip(yr) {
        tail = p.mul_add_fast(*q, tail);
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// `(xᵀx, xᵀy)` in one pass over `x`: a row's squared norm and its product with an estimate.
#[inline]
pub fn norm2_and_dot<T: Real>(x: &[T], y: &[T]) -> (T, T) {
    let len = x.len().min(y.len());
    let (x, y) = (&x[..len], &y[..len]);
    let mut nn = [T::zero(); 4];
    let mut xy = [T::zero(); 4];
    let xc = x.chunks_exact(4);
    let yc = y.chunks_exact(4);
    let (xr, yr) = (xc.remainder(), yc.remainder());
    for (p, q) in xc.zip(yc) {
        for k in 0..4 {
            nn[k] = p[k].mul_add_fast(p[k], nn[k]);
            xy[k] = p[k].mul_add_fast(q[k], xy[k]);
        }
    }
    let (mut tn, mut ty) = (T::zero(), T::zero());
    for (p, q) in xr.iter().zip(yr) {
        tn = p.mul_add_fast(*p, tn);
        ty = p.mul_add_fast(*q, ty);
    }
    (
        (nn[0] + nn[2]) + (nn[1] + nn[3]) + tn,
        (xy[0] + xy[2]) + (xy[1] + xy[3]) + ty,
    )
}

/// `y ← y + α x`.
#[inline]
pub fn axpy<T: Real>(alpha: T, x: &[T], y: &mut [T]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi = xi.mul_add_fast(alpha, *yi);
    }
}

/// Multiply-add written as `a * b + c`.
///
/// Not `f64::mul_add`: without a hardware FMA target feature that call becomes a slow library
/// routine, while `a * b + c` compiles to plain (vectorisable) multiply and add everywhere.
trait MulAddFast: Sized {
    fn mul_add_fast(self, b: Self, c: Self) -> Self;
}

impl<T: Real> MulAddFast for T {
    #[inline(always)]
    fn mul_add_fast(self, b: Self, c: Self) -> Self {
        self * b + c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_naive_sum_for_every_length() {
        for len in 0..23 {
            let x: [f64; 23] = core::array::from_fn(|i| (i as f64 * 0.37).sin());
            let y: [f64; 23] = core::array::from_fn(|i| (i as f64 * 1.3).cos() + 0.1);
            let naive: f64 = x[..len].iter().zip(&y[..len]).map(|(a, b)| a * b).sum();
            assert!((dot(&x[..len], &y[..len]) - naive).abs() < 1e-13);
            let (nn, xy) = norm2_and_dot(&x[..len], &y[..len]);
            let nn_naive: f64 = x[..len].iter().map(|a| a * a).sum();
            assert!((nn - nn_naive).abs() < 1e-13);
            assert!((xy - naive).abs() < 1e-13);
        }
    }

    #[test]
    fn axpy_adds_scaled_vector() {
        let x = [1.0, 2.0, 3.0];
        let mut y = [1.0, 1.0, 1.0];
        axpy(2.0, &x, &mut y);
        assert_eq!(y, [3.0, 5.0, 7.0]);
    }
}
