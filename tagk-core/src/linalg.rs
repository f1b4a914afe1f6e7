//! Small dense vector kernels written so the compiler vectorises them.
//!
//! Floating-point reductions are not reassociated by the compiler, so a naive `sum` of products
//! runs one add at a time. These kernels keep four independent partial sums, which LLVM maps
//! onto SIMD lanes on the host and which keeps the FPU pipeline full on a Cortex-M7.
//! The summation order is fixed, so results are bit-identical from run to run.

use crate::Real;
pub use crate::error::NotPositiveDefinite;

/// `xᵀy` for equal-length slices (extra entries of the longer slice are ignored).
///
/// Summation order: four interleaved partial sums over the first `4⌊len/4⌋` entries, combined
/// as `(s₀ + s₂) + (s₁ + s₃)`, then the remaining entries added in order.
/// `dot4` sums in the same order, so a value does not depend on which kernel computed it.
#[inline(always)]
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
    let mut sum = (acc[0] + acc[2]) + (acc[1] + acc[3]);
    for (p, q) in xr.iter().zip(yr) {
        sum = p.mul_add_fast(*q, sum);
    }
    sum
}

/// `[xᵀr₀, xᵀr₁, xᵀr₂, xᵀr₃]`: four dot products sharing one pass over `x`.
///
/// Sixteen independent partial sums keep the multiply and add units busy instead of waiting
/// on one accumulator; the result is bit-identical to four calls of [`dot`]. All slices must
/// have at least `x.len()` entries.
#[inline]
#[cfg(test)]
pub(crate) fn dot4<T: Real>(x: &[T], rows: [&[T]; 4]) -> [T; 4] {
    let len = x.len();
    let r = rows.map(|row| &row[..len]);
    let mut acc = [[T::zero(); 4]; 4];
    let full = len - len % 4;
    let mut k = 0;
    while k < full {
        let xs: [T; 4] = [x[k], x[k + 1], x[k + 2], x[k + 3]];
        for q in 0..4 {
            let rq = &r[q][k..k + 4];
            for l in 0..4 {
                acc[q][l] = xs[l].mul_add_fast(rq[l], acc[q][l]);
            }
        }
        k += 4;
    }
    let mut out = [T::zero(); 4];
    for q in 0..4 {
        let mut sum = (acc[q][0] + acc[q][2]) + (acc[q][1] + acc[q][3]);
        for kk in full..len {
            sum = x[kk].mul_add_fast(r[q][kk], sum);
        }
        out[q] = sum;
    }
    out
}

/// The Gram matrix `G = A Aᵀ` of a row-major `m × n` matrix.
///
/// It is written as a full symmetric `m × m` row-major matrix into `gram` (at least `m²`
/// entries). `dot4` tiles cover the upper triangle: `m(m+1)/2` dot products of length `n`.
#[cfg(test)]
pub(crate) fn gram<T: Real>(a: &[T], n: usize, m: usize, gram: &mut [T]) {
    for i in 0..m {
        let ai = &a[i * n..(i + 1) * n];
        let mut j = i;
        while j + 4 <= m {
            let g = dot4(
                ai,
                [
                    &a[j * n..],
                    &a[(j + 1) * n..],
                    &a[(j + 2) * n..],
                    &a[(j + 3) * n..],
                ],
            );
            for q in 0..4 {
                gram[i * m + j + q] = g[q];
                gram[(j + q) * m + i] = g[q];
            }
            j += 4;
        }
        while j < m {
            let g = dot(ai, &a[j * n..(j + 1) * n]);
            gram[i * m + j] = g;
            gram[j * m + i] = g;
            j += 1;
        }
    }
}

/// `out[i] = a_iᵀx` for the `m` rows of a row-major `m × n` matrix (`x` has `n` entries).
#[cfg(test)]
pub(crate) fn mat_vec<T: Real>(a: &[T], n: usize, m: usize, x: &[T], out: &mut [T]) {
    let mut i = 0;
    while i + 4 <= m {
        let v = dot4(
            x,
            [
                &a[i * n..],
                &a[(i + 1) * n..],
                &a[(i + 2) * n..],
                &a[(i + 3) * n..],
            ],
        );
        out[i..i + 4].copy_from_slice(&v);
        i += 4;
    }
    while i < m {
        out[i] = dot(x, &a[i * n..(i + 1) * n]);
        i += 1;
    }
}

/// `(xᵀx, xᵀy)` in one pass over `x`: a row's squared norm and its product with an estimate.
#[inline(always)]
pub(crate) fn norm2_and_dot<T: Real>(x: &[T], y: &[T]) -> (T, T) {
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

/// `m` rounded up to a multiple of 8: the row stride of the transposed, padded regressor.
pub(crate) const fn padded(m: usize) -> usize {
    m.div_ceil(8) * 8
}

/// [`padded`], or `None` when the rounded size overflows a `usize`.
pub(crate) const fn checked_padded(m: usize) -> Option<usize> {
    m.div_ceil(8).checked_mul(8)
}

/// Whether the portable kernels build the Gram matrix from a transposed copy of the window
/// or from its rows. The first is `transpose_padded`, then `gram_transposed`: 8-wide tiles for
/// wide SIMD units (x86-64). The second is `gram_rows`: 2 × 4 tiles for few registers (a
/// Cortex-M7). On aarch64 the NEON kernels take the transposed path themselves. The two give
/// the same bits.
pub(crate) const GRAM_FROM_TRANSPOSED: bool = cfg!(target_arch = "x86_64");

/// Whether the estimators' buffers hold a transposed copy of the window (`n · p` scalars):
/// where a Gram kernel reads one (x86-64, aarch64).
pub(crate) const TRANSPOSED_COPY: bool = cfg!(any(target_arch = "x86_64", target_arch = "aarch64"));

/// Scalars readable past the transposed copy. On x86-64 the AVX2 Gram kernel's vectors along
/// the diagonals read up to three entries past a row of `Aᵀ`, the last row's from here. What
/// they read only lands in entries of `G` written again afterwards.
pub(crate) const TRANSPOSED_SLACK: usize = if cfg!(target_arch = "x86_64") { 4 } else { 0 };

/// Writes `Aᵀ` of a row-major `m × n` matrix into `at` as an `n × stride` row-major matrix
/// (`stride = padded(m)`), zero in the padding columns.
#[inline(always)]
#[cfg_attr(
    not(any(target_arch = "x86_64", target_arch = "aarch64")),
    allow(dead_code)
)]
pub(crate) fn transpose_padded<T: Real>(a: &[T], n: usize, m: usize, at: &mut [T]) {
    let stride = padded(m);
    let (m4, n4) = (m - m % 4, n - n % 4);
    // 4 × 4 tiles: four loads of four, four stores of four.
    let mut j = 0;
    while j < m4 {
        let mut k = 0;
        while k < n4 {
            let tile: [[T; 4]; 4] = core::array::from_fn(|p| {
                let row = &a[(j + p) * n + k..(j + p) * n + k + 4];
                [row[0], row[1], row[2], row[3]]
            });
            for q in 0..4 {
                let out = &mut at[(k + q) * stride + j..(k + q) * stride + j + 4];
                out.copy_from_slice(&[tile[0][q], tile[1][q], tile[2][q], tile[3][q]]);
            }
            k += 4;
        }
        for k in n4..n {
            for p in 0..4 {
                at[k * stride + j + p] = a[(j + p) * n + k];
            }
        }
        j += 4;
    }
    for k in 0..n {
        let row = &mut at[k * stride..(k + 1) * stride];
        for jj in m4..m {
            row[jj] = a[jj * n + k];
        }
        row[m..].fill(T::zero());
    }
}

/// The Gram matrix `G = A Aᵀ` from the transposed, padded regressor `at` of
/// `transpose_padded`, written full and symmetric into `gram` as a `p × p` row-major matrix
/// with `p = padded(m)` (zero outside the leading `m × m` block).
///
/// A 4 × 8 register-blocked outer-product kernel over the upper-triangle blocks: each step
/// loads an 8-vector, broadcasts four scalars and performs 32 multiply-adds into eight
/// independent accumulator vectors, with no horizontal reductions. `G_ij = Σ_k a_ik a_jk` is
/// summed in order of `k`; `G_ij` and `G_ji` are the same value.
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) fn gram_transposed<T: Real>(at: &[T], n: usize, m: usize, gram: &mut [T]) {
    let p = padded(m);
    let (at, gram) = (&at[..n * p], &mut gram[..p * p]);
    let mut bi = 0;
    while bi < p {
        // 4 × 8 blocks from the 8-aligned column block containing row `bi` onwards: the upper
        // triangle plus a few entries below it, which agree bit for bit with their mirror
        // images (the products commute and the sums run in the same order).
        let mut bj = bi - bi % 8;
        while bj < p {
            let mut acc = [[T::zero(); 8]; 4];
            for row in at.chunks_exact(p) {
                let u = [row[bi], row[bi + 1], row[bi + 2], row[bi + 3]];
                let v: [T; 8] = core::array::from_fn(|q| row[bj + q]);
                for s in 0..4 {
                    for q in 0..8 {
                        acc[s][q] = u[s].mul_add_fast(v[q], acc[s][q]);
                    }
                }
            }
            // Row segments and their mirror images.
            for (q, acc_q) in acc.iter().enumerate() {
                gram[(bi + q) * p + bj..(bi + q) * p + bj + 8].copy_from_slice(acc_q);
            }
            for l in 0..8 {
                gram[(bj + l) * p + bi..(bj + l) * p + bi + 4]
                    .copy_from_slice(&[acc[0][l], acc[1][l], acc[2][l], acc[3][l]]);
            }
            bj += 8;
        }
        bi += 4;
    }
}

/// The Gram matrix `G = A Aᵀ` of a row-major `m × n` matrix, directly from the rows. It is
/// written full and symmetric into `gram` as a `p × p` row-major matrix with `p = padded(m)`,
/// zero outside the leading `m × m` block. The kernel uses 2 × 4 register tiles: eight
/// accumulators fit the sixteen double registers of a Cortex-M7 FPU without spilling.
///
/// Every entry is `Σ_k a_ik a_jk` accumulated in order of `k`, exactly as in
/// `gram_transposed`: the two kernels return the same bits, so a microcontroller and a host
/// agree to the last bit.
pub fn gram_rows<T: Real>(a: &[T], n: usize, m: usize, gram: &mut [T]) {
    let p = padded(m);
    // Row pairs; for each, column blocks of four from its diagonal on, edges in smaller tiles.
    let mut bi = 0;
    while bi < m {
        let mut bj = bi;
        while bj < m {
            match (m - bi >= 2, (m - bj).min(4)) {
                (true, 4) => gram_tile::<T, 2, 4>(a, n, p, bi, bj, gram),
                (true, 3) => gram_tile::<T, 2, 3>(a, n, p, bi, bj, gram),
                (true, 2) => gram_tile::<T, 2, 2>(a, n, p, bi, bj, gram),
                (true, _) => gram_tile::<T, 2, 1>(a, n, p, bi, bj, gram),
                (false, 4) => gram_tile::<T, 1, 4>(a, n, p, bi, bj, gram),
                (false, 3) => gram_tile::<T, 1, 3>(a, n, p, bi, bj, gram),
                (false, 2) => gram_tile::<T, 1, 2>(a, n, p, bi, bj, gram),
                (false, _) => gram_tile::<T, 1, 1>(a, n, p, bi, bj, gram),
            }
            bj += 4;
        }
        bi += 2;
    }
    // Zero padding: the last columns of the leading rows, then the last rows.
    for i in 0..m {
        gram[i * p + m..(i + 1) * p].fill(T::zero());
    }
    gram[m * p..p * p].fill(T::zero());
}

/// One `P × Q` tile of [`gram_rows`]: rows `bi..bi+P` against rows `bj..bj+Q`, written to
/// both triangles of a Gram matrix with row stride `p`.
#[inline(always)]
fn gram_tile<T: Real, const P: usize, const Q: usize>(
    a: &[T],
    n: usize,
    p: usize,
    bi: usize,
    bj: usize,
    gram: &mut [T],
) {
    let u: [&[T]; P] = core::array::from_fn(|s| &a[(bi + s) * n..(bi + s + 1) * n]);
    let v: [&[T]; Q] = core::array::from_fn(|q| &a[(bj + q) * n..(bj + q + 1) * n]);
    let mut acc = [[T::zero(); Q]; P];
    for k in 0..n {
        let y: [T; Q] = core::array::from_fn(|q| v[q][k]);
        for s in 0..P {
            let x = u[s][k];
            for q in 0..Q {
                acc[s][q] = x.mul_add_fast(y[q], acc[s][q]);
            }
        }
    }
    for (s, acc_s) in acc.iter().enumerate() {
        for (q, &g) in acc_s.iter().enumerate() {
            gram[(bi + s) * p + bj + q] = g;
            gram[(bj + q) * p + bi + s] = g;
        }
    }
}

/// `out[j] = b_j − a_jᵀx` for the `m` rows of a row-major `m × n` matrix, each product
/// summed as [`dot`] does; `out` needs `padded(m)` entries, and the padding ones are set to
/// zero. Inlined on x86-64, where the AVX2 kernels call it from code compiled for AVX2 (out
/// of line it would run the baseline SSE2 code); elsewhere as it was (the Cortex-M7's
/// instruction counts are a reference).
#[cfg_attr(target_arch = "x86_64", inline(always))]
pub(crate) fn residual_rows<T: Real>(a: &[T], n: usize, m: usize, x: &[T], b: &[T], out: &mut [T]) {
    for j in 0..m {
        out[j] = b[j] - dot(&a[j * n..(j + 1) * n], x);
    }
    out[m..padded(m)].fill(T::zero());
}

/// `x ← x + Aᵀc` for a row-major `m × n` matrix `A`, over the rows with a nonzero
/// coefficient. Each entry is summed in order of those rows, exactly as calls of [`axpy`]
/// would (`x_k ← a_ik c_i + x_k`). The loops are interchanged, so each block of entries of `x`
/// stays in registers instead of making a round trip through memory per row. The rows used
/// are found through bit masks (one branch per 64 rows and block, not per row).
#[inline(always)]
pub(crate) fn add_combination<T: Real>(x: &mut [T], a: &[T], coef: &[T], n: usize, m: usize) {
    let (x, a, coef) = (&mut x[..n], &a[..m * n], &coef[..m]);
    let mut k = 0;
    // Blocks of 32 entries (independent chains to overlap), then of 8, then single entries.
    while k + 32 <= n {
        combination_block::<T, 32>(x, a, coef, n, k);
        k += 32;
    }
    while k + 8 <= n {
        combination_block::<T, 8>(x, a, coef, n, k);
        k += 8;
    }
    while k < n {
        combination_block::<T, 1>(x, a, coef, n, k);
        k += 1;
    }
}

/// Entries `k..k+B` of [`add_combination`].
#[inline(always)]
fn combination_block<T: Real, const B: usize>(
    x: &mut [T],
    a: &[T],
    coef: &[T],
    n: usize,
    k: usize,
) {
    let mut acc: [T; B] = core::array::from_fn(|l| x[k + l]);
    for (chunk, cs) in coef.chunks(64).enumerate() {
        let mut used = cs.iter().enumerate().fold(0u64, |bits, (q, &c)| {
            bits | (u64::from(c != T::zero()) << q)
        });
        while used != 0 {
            let i = 64 * chunk + used.trailing_zeros() as usize;
            used &= used - 1;
            let (c, row) = (coef[i], &a[i * n + k..i * n + k + B]);
            for l in 0..B {
                acc[l] = row[l].mul_add_fast(c, acc[l]);
            }
        }
    }
    x[k..k + B].copy_from_slice(&acc);
}

/// `y ← y + α x`.
#[inline(always)]
pub fn axpy<T: Real>(alpha: T, x: &[T], y: &mut [T]) {
    let len = y.len().min(x.len());
    let (x, y) = (&x[..len], &mut y[..len]);
    for k in 0..len {
        y[k] = x[k].mul_add_fast(alpha, y[k]);
    }
}

/// In-place Cholesky factorisation `A = L Lᵀ` of the `n × n` symmetric positive definite
/// matrix in the leading `n²` entries of `a` (row-major). It is the one factorisation of the
/// workspace. The RLS/Kalman block update, its information-form fallback and the Riccati
/// solvers of `tagk-control` all use it.
///
/// Only the lower triangle is read, and `L` overwrites it; the strict upper triangle is left
/// as it was. Cholesky–Crout, column by column: `l_jj = √(a_jj − Σ_{k<j} l_jk²)`, then
/// `l_ij = (a_ij − Σ_{k<j} l_ik l_jk) / l_jj` for the rows below (multiplied by the reciprocal
/// `1 / l_jj`). The diagonal's sums use [`dot`]; rows below the pivot are processed four at a
/// time with one in-order accumulator each, so they share the loads of row `j` (the last
/// `(n − j − 1) mod 4` rows use [`dot`]). The order is fixed: the result is the same bits on
/// every machine. Cost: `n³/6` multiply-adds, no allocation.
///
/// # Errors
/// [`NotPositiveDefinite`] if a pivot `a_jj − Σ l_jk²` is not positive and finite: the matrix
/// is indefinite or singular to working precision, or holds a NaN or an infinity (a non-finite
/// entry reaches some later pivot). `a` is then partly overwritten.
pub fn cholesky_in_place<T: Real>(a: &mut [T], n: usize) -> Result<(), NotPositiveDefinite> {
    let a = &mut a[..n * n];
    for j in 0..n {
        let (head, tail) = a.split_at_mut((j + 1) * n);
        let rowj = &mut head[j * n..];
        let djj = rowj[j] - dot(&rowj[..j], &rowj[..j]);
        if !(djj > T::zero() && djj.is_finite()) {
            return Err(NotPositiveDefinite { pivot: j });
        }
        let ljj = djj.sqrt();
        rowj[j] = ljj;
        let inv = T::one() / ljj;
        let lj = &head[j * n..j * n + j];
        let mut rows = tail.chunks_exact_mut(4 * n);
        for quad in &mut rows {
            let (r0, rest) = quad.split_at_mut(n);
            let (r1, rest) = rest.split_at_mut(n);
            let (r2, r3) = rest.split_at_mut(n);
            let (mut a0, mut a1, mut a2, mut a3) = (T::zero(), T::zero(), T::zero(), T::zero());
            for (k, &l) in lj.iter().enumerate() {
                a0 += r0[k] * l;
                a1 += r1[k] * l;
                a2 += r2[k] * l;
                a3 += r3[k] * l;
            }
            r0[j] = (r0[j] - a0) * inv;
            r1[j] = (r1[j] - a1) * inv;
            r2[j] = (r2[j] - a2) * inv;
            r3[j] = (r3[j] - a3) * inv;
        }
        for r in rows.into_remainder().chunks_exact_mut(n) {
            r[j] = (r[j] - dot(&r[..j], lj)) * inv;
        }
    }
    Ok(())
}

/// `inv_diag[j] = 1 / l_jj` for the factor `L` of [`cholesky_in_place`] (`n × n`,
/// row-major): the reciprocals the triangular solves multiply by.
pub fn reciprocal_diagonal<T: Real>(l: &[T], n: usize, inv_diag: &mut [T]) {
    for (j, inv) in inv_diag[..n].iter_mut().enumerate() {
        *inv = T::one() / l[j * n + j];
    }
}

/// Solves `L y = x` in place (forward substitution): `y_j = (x_j − Σ_{k<j} l_jk y_k) / l_jj`,
/// one [`dot`] per row, for the factor `L` of [`cholesky_in_place`] (`n × n`, row-major
/// lower triangle) and its [`reciprocal_diagonal`] `inv_diag`. `x` has `n` entries.
#[inline]
pub fn solve_lower_in_place<T: Real>(l: &[T], n: usize, inv_diag: &[T], x: &mut [T]) {
    for j in 0..n {
        let acc = x[j] - dot(&l[j * n..j * n + j], &x[..j]);
        x[j] = acc * inv_diag[j];
    }
}

/// Solves `Lᵀ z = y` in place (back substitution, column-oriented so that it reads rows of
/// `L`): `z_i = y_i / l_ii`, then `y_k −= l_ik z_i` for `k < i`. Same arguments as
/// [`solve_lower_in_place`].
#[inline]
pub fn solve_lower_transpose_in_place<T: Real>(l: &[T], n: usize, inv_diag: &[T], x: &mut [T]) {
    for i in (0..n).rev() {
        let zi = x[i] * inv_diag[i];
        x[i] = zi;
        axpy(-zi, &l[i * n..i * n + i], &mut x[..i]);
    }
}

/// Solves `A z = x` in place with `A = L Lᵀ` from [`cholesky_in_place`]: both triangular
/// solves. Same arguments as [`solve_lower_in_place`].
pub fn cholesky_solve_in_place<T: Real>(l: &[T], n: usize, inv_diag: &[T], x: &mut [T]) {
    solve_lower_in_place(l, n, inv_diag, x);
    solve_lower_transpose_in_place(l, n, inv_diag, x);
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
    extern crate std;
    use std::vec;
    use std::vec::Vec;

    /// `A = M Mᵀ + n I` for a deterministic `M`: symmetric positive definite.
    fn spd(n: usize) -> Vec<f64> {
        let mdat: Vec<f64> = (0..n * n)
            .map(|k| ((k * 7919 % 113) as f64 / 56.5) - 1.0)
            .collect();
        let mut a = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                let s: f64 = (0..n).map(|k| mdat[i * n + k] * mdat[j * n + k]).sum();
                a[i * n + j] = s + if i == j { n as f64 } else { 0.0 };
            }
        }
        a
    }

    #[test]
    fn cholesky_reconstructs_the_matrix() {
        for n in [1, 2, 3, 4, 5, 8, 9, 30] {
            let a = spd(n);
            let mut l = a.clone();
            cholesky_in_place(&mut l, n).unwrap();
            // L L^T against A, computed independently (plain triple loop, lower triangle of L).
            let mut worst = 0.0f64;
            for i in 0..n {
                for j in 0..=i {
                    let s: f64 = (0..=j).map(|k| l[i * n + k] * l[j * n + k]).sum();
                    worst = worst.max((s - a[i * n + j]).abs() / a[i * n + i]);
                }
                // The strict upper triangle is untouched.
                for j in i + 1..n {
                    assert_eq!(l[i * n + j], a[i * n + j]);
                }
            }
            assert!(worst < 1e-13, "n = {n}: relative error {worst}");
        }
    }

    #[test]
    fn cholesky_solves_a_known_system() {
        let n = 9;
        let a = spd(n);
        let x_true: Vec<f64> = (0..n).map(|i| i as f64 * 0.5 - 2.0).collect();
        let mut x: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|k| a[i * n + k] * x_true[k]).sum())
            .collect();
        let mut l = a.clone();
        cholesky_in_place(&mut l, n).unwrap();
        let mut inv = vec![0.0; n];
        reciprocal_diagonal(&l, n, &mut inv);
        cholesky_solve_in_place(&l, n, &inv, &mut x);
        for (x, t) in x.iter().zip(&x_true) {
            assert!((x - t).abs() < 1e-12, "{x} vs {t}");
        }
        // In f32 too, to single-precision accuracy.
        let mut l32: Vec<f32> = a.iter().map(|&v| v as f32).collect();
        let mut x32: Vec<f32> = (0..n)
            .map(|i| (0..n).map(|k| a[i * n + k] * x_true[k]).sum::<f64>() as f32)
            .collect();
        cholesky_in_place(&mut l32, n).unwrap();
        let mut inv32 = vec![0.0f32; n];
        reciprocal_diagonal(&l32, n, &mut inv32);
        cholesky_solve_in_place(&l32, n, &inv32, &mut x32);
        for (x, t) in x32.iter().zip(&x_true) {
            assert!((f64::from(*x) - t).abs() < 1e-4, "{x} vs {t}");
        }
    }

    #[test]
    fn cholesky_rejects_indefinite_and_non_finite() {
        let mut indefinite = vec![1.0, 0.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(
            cholesky_in_place(&mut indefinite, 3),
            Err(NotPositiveDefinite { pivot: 1 })
        );
        let mut singular = vec![1.0, 0.0, 1.0, 1.0];
        assert_eq!(
            cholesky_in_place(&mut singular, 2),
            Err(NotPositiveDefinite { pivot: 1 })
        );
        for bad in [f64::NAN, f64::INFINITY] {
            let mut a = spd(6);
            a[5 * 6 + 2] = bad;
            assert_eq!(
                cholesky_in_place(&mut a, 6),
                Err(NotPositiveDefinite { pivot: 5 })
            );
            let mut a = spd(6);
            a[0] = bad;
            assert!(cholesky_in_place(&mut a, 6).is_err());
        }
    }

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
    fn dot4_gram_and_mat_vec_are_bit_identical_to_dot() {
        let (m, n) = (7, 11);
        let a: [f64; 77] = core::array::from_fn(|i| ((i * 7 % 13) as f64 - 6.0) * 0.31);
        let x: [f64; 11] = core::array::from_fn(|i| (i as f64).cos());
        let mut g = [0.0; 49];
        gram(&a, n, m, &mut g);
        let mut ax = [0.0; 7];
        mat_vec(&a, n, m, &x, &mut ax);
        for i in 0..m {
            let ai = &a[i * n..(i + 1) * n];
            assert_eq!(ax[i].to_bits(), dot(&x, ai).to_bits());
            for j in 0..m {
                let aj = &a[j * n..(j + 1) * n];
                assert_eq!(g[i * m + j].to_bits(), dot(ai, aj).to_bits());
                let naive: f64 = ai.iter().zip(aj).map(|(p, q)| p * q).sum();
                assert!((g[i * m + j] - naive).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn gram_and_residual_match_naive_sums() {
        for (m, n) in [(1, 1), (3, 2), (7, 11), (8, 4), (30, 10)] {
            let a: [f64; 300] = core::array::from_fn(|i| ((i * 7 % 13) as f64 - 6.0) * 0.31);
            let a = &a[..m * n];
            let x: [f64; 11] = core::array::from_fn(|i| (i as f64).cos());
            let b: [f64; 30] = core::array::from_fn(|i| (i as f64 * 0.7).sin());
            let mut at = [0.0; 11 * 32];
            transpose_padded(a, n, m, &mut at);
            let mut g = [f64::NAN; 1024];
            gram_transposed(&at, n, m, &mut g);
            let p = padded(m);
            let mut r = [0.0; 32];
            residual_rows(a, n, m, &x[..n], &b[..m], &mut r);
            for i in 0..m {
                let ai = &a[i * n..(i + 1) * n];
                let ax: f64 = ai.iter().zip(&x).map(|(p, q)| p * q).sum();
                assert!((r[i] - (b[i] - ax)).abs() < 1e-12);
                for j in 0..m {
                    let aj = &a[j * n..(j + 1) * n];
                    let naive: f64 = ai.iter().zip(aj).map(|(p, q)| p * q).sum();
                    assert!((g[i * p + j] - naive).abs() < 1e-12, "{m}x{n} G[{i}][{j}]");
                    assert_eq!(g[i * p + j].to_bits(), g[j * p + i].to_bits());
                }
            }
            for i in 0..p {
                for j in 0..p {
                    if i >= m || j >= m {
                        assert_eq!(g[i * p + j], 0.0, "{m}x{n} padding G[{i}][{j}]");
                    }
                }
            }
        }
    }

    #[test]
    fn row_major_and_transposed_kernels_give_the_same_bits() {
        for (m, n) in [(1, 1), (2, 3), (5, 7), (9, 4), (30, 10), (30, 13)] {
            let a: Vec<f64> = (0..m * n)
                .map(|i| ((i * 7919 % 997) as f64 / 498.5) - 1.0)
                .collect();
            let mut at = vec![0.0; n * padded(m)];
            transpose_padded(&a, n, m, &mut at);
            let p = padded(m);
            // Stale values in the buffers, as left by a larger window.
            let (mut g1, mut g2) = (vec![7.0; p * p], vec![7.0; p * p]);
            gram_transposed(&at, n, m, &mut g1);
            gram_rows(&a, n, m, &mut g2);
            for k in 0..p * p {
                assert_eq!(g1[k].to_bits(), g2[k].to_bits(), "{m}x{n} G entry {k}");
            }
        }
    }

    #[test]
    fn add_combination_matches_axpy_over_the_used_rows_bit_for_bit() {
        for (m, n) in [(1, 1), (3, 8), (30, 10), (7, 19), (30, 120), (130, 9)] {
            let a: Vec<f64> = (0..m * n)
                .map(|i| ((i * 7919 % 997) as f64 / 498.5) - 1.0)
                .collect();
            let c: Vec<f64> = (0..m).map(|i| (i as f64 * 0.7).sin()).collect();
            let x0: Vec<f64> = (0..n).map(|k| (k as f64).cos()).collect();
            let mut c = c;
            c[m / 2] = 0.0; // an unused row
            let mut want = x0.clone();
            for i in (0..m).filter(|&i| c[i] != 0.0) {
                axpy(c[i], &a[i * n..(i + 1) * n], &mut want);
            }
            let mut got = x0.clone();
            add_combination(&mut got, &a, &c, n, m);
            for k in 0..n {
                assert_eq!(got[k].to_bits(), want[k].to_bits(), "{m}x{n} entry {k}");
            }
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
