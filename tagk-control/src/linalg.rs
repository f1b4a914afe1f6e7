//! Small dense kernels on contiguous column-major slices. The Riccati solvers use them so
//! they do not allocate inside their loops: nalgebra's `Cholesky` and `LU` consume their
//! argument, which allocates for `DMatrix`. Nor do they pay for bounds checks in the inner
//! loops: every inner loop is an `axpy` or a dot product over contiguous memory. The Cholesky
//! factorisation and its solves are tagk-core's (`tagk_core::linalg`), the one implementation
//! of the workspace.

use nalgebra::{Dim, Matrix, RawStorage, StorageMut};
use tagk_core::linalg::{
    cholesky_solve_in_place as cholesky_solve, reciprocal_diagonal, solve_lower_in_place,
    solve_lower_transpose_in_place,
};

/// `y[i] -= a[i] * s` over equal-length slices.
#[inline(always)]
fn axpy_neg(y: &mut [f64], a: &[f64], s: f64) {
    for (yi, ai) in y.iter_mut().zip(a) {
        *yi -= ai * s;
    }
}

/// Runs `f` with an `n`-long scratch slice: on the stack for the small systems of this crate
/// (`n ≤ 32`), on the heap otherwise.
#[inline(always)]
fn with_scratch<R>(n: usize, f: impl FnOnce(&mut [f64]) -> R) -> R {
    let mut small = [0.0; 32];
    if n <= small.len() {
        f(&mut small[..n])
    } else {
        f(&mut vec![0.0; n])
    }
}

/// Cholesky factorisation in place of the `n×n` symmetric column-major `a` by the
/// workspace's one factorisation, [`tagk_core::linalg::cholesky_in_place`]. That routine is
/// row-major. It reads the lower triangle of the row-major view: the **upper** triangle of the
/// column-major `a`, the same values for a symmetric `a`. It writes the factor `L` there. So on
/// success the column-major upper triangle holds `Lᵀ`, with `a = L Lᵀ`. The strict lower
/// triangle is left as it was. Returns `false` if `a` is not (numerically) positive definite
/// or holds non-finite values.
pub(crate) fn cholesky_in_place(a: &mut [f64], n: usize) -> bool {
    debug_assert_eq!(a.len(), n * n);
    tagk_core::linalg::cholesky_in_place(a, n).is_ok()
}

/// Solves `L Y = B` in place (`B` is `n×ncols`, column-major) with the factor of
/// [`cholesky_in_place`].
pub(crate) fn forward_lower_in_place(l: &[f64], n: usize, b: &mut [f64]) {
    with_scratch(n, |inv| {
        reciprocal_diagonal(l, n, inv);
        for col in b.chunks_exact_mut(n) {
            solve_lower_in_place(l, n, inv, col);
        }
    });
}

/// Solves `Lᵀ X = Y` in place (`Y` is `n×ncols`, column-major).
pub(crate) fn backward_lower_t_in_place(l: &[f64], n: usize, b: &mut [f64]) {
    with_scratch(n, |inv| {
        reciprocal_diagonal(l, n, inv);
        for col in b.chunks_exact_mut(n) {
            solve_lower_transpose_in_place(l, n, inv, col);
        }
    });
}

/// Solves `L Lᵀ X = B` in place.
pub(crate) fn cholesky_solve_in_place(l: &[f64], n: usize, b: &mut [f64]) {
    with_scratch(n, |inv| {
        reciprocal_diagonal(l, n, inv);
        for col in b.chunks_exact_mut(n) {
            cholesky_solve(l, n, inv, col);
        }
    });
}

/// LU factorisation with partial pivoting in place (`P a = L U`; unit lower `L` below the
/// diagonal, `U` on and above) of the `n×n` column-major `a`. `piv[k]` is the row swapped
/// with row `k` at step `k`. Returns `false` if a pivot is zero or not finite.
pub(crate) fn lu_in_place(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
    // Fast path for the 12-state quadrotor: a constant `n` lets LLVM unroll and vectorise.
    if n == 12 {
        lu_in_place_impl(a, 12, piv)
    } else {
        lu_in_place_impl(a, n, piv)
    }
}

#[inline(always)]
fn lu_in_place_impl(a: &mut [f64], n: usize, piv: &mut [usize]) -> bool {
    debug_assert_eq!(a.len(), n * n);
    let a = &mut a[..n * n];
    for k in 0..n {
        let col_k = &a[k * n..(k + 1) * n];
        let mut p = k;
        let mut best = col_k[k].abs();
        for (i, v) in col_k.iter().enumerate().skip(k + 1) {
            if v.abs() > best {
                best = v.abs();
                p = i;
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        piv[k] = p;
        if p != k {
            for col in a.chunks_exact_mut(n) {
                col.swap(k, p);
            }
        }
        let (left, right) = a.split_at_mut((k + 1) * n);
        let col_k = &mut left[k * n..];
        let inv = 1.0 / col_k[k];
        for v in &mut col_k[k + 1..] {
            *v *= inv;
        }
        let col_k = &*col_k;
        for col_j in right.chunks_exact_mut(n) {
            let ukj = col_j[k];
            if ukj != 0.0 {
                axpy_neg(&mut col_j[k + 1..], &col_k[k + 1..], ukj);
            }
        }
    }
    true
}

/// Solves `a X = B` in place with the factors of [`lu_in_place`], for `B` given
/// **transposed**: `bt` holds `Bᵀ` column-major (`ncols × n`), i.e. row `i` of `B` is the
/// contiguous chunk `bt[i·ncols .. (i+1)·ncols]`. On return `bt` holds `Xᵀ`.
///
/// The substitutions become row operations `row_i −= l_ik · row_k` on contiguous rows of
/// length `ncols` — fewer and longer `axpy`s than column-wise substitution when
/// `ncols ≥ n`.
pub(crate) fn lu_solve_transposed_in_place(lu: &[f64], n: usize, piv: &[usize], bt: &mut [f64]) {
    if n == 0 {
        return;
    }
    let w = bt.len() / n;
    // Fast path for the 12-state quadrotor (constant trip counts).
    if n == 12 && w == 12 {
        lu_solve_transposed_impl(lu, 12, 12, piv, bt)
    } else {
        lu_solve_transposed_impl(lu, n, w, piv, bt)
    }
}

#[inline(always)]
fn lu_solve_transposed_impl(lu: &[f64], n: usize, w: usize, piv: &[usize], bt: &mut [f64]) {
    debug_assert_eq!(lu.len(), n * n);
    let lu = &lu[..n * n];
    let bt = &mut bt[..n * w];
    for (k, &p) in piv.iter().enumerate().take(n) {
        if p != k {
            let (lo, hi) = bt.split_at_mut(p * w);
            lo[k * w..(k + 1) * w].swap_with_slice(&mut hi[..w]);
        }
    }
    // Forward substitution with the unit lower factor: row_i −= L[i,k] row_k, k < i.
    for i in 1..n {
        let (done, rest) = bt.split_at_mut(i * w);
        let row_i = &mut rest[..w];
        for k in 0..i {
            let lik = lu[k * n + i];
            axpy_neg(row_i, &done[k * w..(k + 1) * w], lik);
        }
    }
    // Back substitution with the upper factor: row_i = (row_i − Σ_{k>i} U[i,k] row_k) / U[i,i].
    for i in (0..n).rev() {
        let (head, done) = bt.split_at_mut((i + 1) * w);
        let row_i = &mut head[i * w..];
        for k in (i + 1)..n {
            let uik = lu[k * n + i];
            axpy_neg(row_i, &done[(k - i - 1) * w..(k - i) * w], uik);
        }
        let inv = 1.0 / lu[i * n + i];
        for v in row_i.iter_mut() {
            *v *= inv;
        }
    }
}

/// Frobenius norm of `a − b`.
pub(crate) fn frobenius_diff<R, C, S1, S2>(
    a: &Matrix<f64, R, C, S1>,
    b: &Matrix<f64, R, C, S2>,
) -> f64
where
    R: Dim,
    C: Dim,
    S1: RawStorage<f64, R, C>,
    S2: RawStorage<f64, R, C>,
{
    a.iter()
        .zip(b.iter())
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Replaces a square matrix by its symmetric part `(M + Mᵀ)/2`.
pub(crate) fn symmetrize<D: Dim, S: StorageMut<f64, D, D>>(m: &mut Matrix<f64, D, D, S>) {
    let n = m.nrows();
    for j in 0..n {
        for i in (j + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// Largest `|m_ij − m_ji|`.
pub(crate) fn max_asymmetry<D: Dim, S: RawStorage<f64, D, D>>(m: &Matrix<f64, D, D, S>) -> f64 {
    let n = m.nrows();
    let mut worst = 0.0_f64;
    for j in 0..n {
        for i in (j + 1)..n {
            worst = worst.max((m[(i, j)] - m[(j, i)]).abs());
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, Matrix3, Matrix3x2, SMatrix};

    #[test]
    fn cholesky_reconstructs_and_solves() {
        let a = Matrix3::new(4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0);
        let mut l = a;
        assert!(cholesky_in_place(l.as_mut_slice(), 3));
        // The factor is in the upper triangle (as Lᵀ, see `cholesky_in_place`).
        let lower = l.upper_triangle().transpose();
        assert!((lower * lower.transpose() - a).norm() < 1e-14);
        let x_true = Matrix3x2::new(1.0, -2.0, 0.5, 3.0, -1.5, 0.25);
        let mut b = a * x_true;
        cholesky_solve_in_place(l.as_slice(), 3, b.as_mut_slice());
        assert!((b - x_true).norm() < 1e-13);
        // The two halves separately: L⁻¹ then L⁻ᵀ.
        let mut y = a * x_true;
        forward_lower_in_place(l.as_slice(), 3, y.as_mut_slice());
        assert!((lower * y - a * x_true).norm() < 1e-13);
        backward_lower_t_in_place(l.as_slice(), 3, y.as_mut_slice());
        assert!((y - x_true).norm() < 1e-13);
    }

    #[test]
    fn cholesky_rejects_indefinite_and_nan() {
        let mut a = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(!cholesky_in_place(a.as_mut_slice(), 3));
        let mut b = Matrix3::identity();
        b[(1, 1)] = f64::NAN;
        assert!(!cholesky_in_place(b.as_mut_slice(), 3));
    }

    #[test]
    fn lu_solves_against_known_solution() {
        // Needs pivoting: zero leading entry.
        let a = SMatrix::<f64, 4, 4>::new(
            0.0, 2.0, 1.0, -1.0, 3.0, 1.0, 0.0, 2.0, 1.0, -1.0, 4.0, 0.5, 2.0, 0.0, 1.0, 3.0,
        );
        let x_true = SMatrix::<f64, 4, 2>::new(1.0, 2.0, -1.0, 0.5, 3.0, -2.0, 0.25, 1.0);
        let mut bt = (a * x_true).transpose();
        let mut lu = a;
        let mut piv = [0usize; 4];
        assert!(lu_in_place(lu.as_mut_slice(), 4, &mut piv));
        lu_solve_transposed_in_place(lu.as_slice(), 4, &piv, bt.as_mut_slice());
        assert!((bt.transpose() - x_true).norm() < 1e-12);

        let mut lud = DMatrix::from_column_slice(4, 4, a.as_slice());
        let mut btd = DMatrix::from_column_slice(2, 4, (a * x_true).transpose().as_slice());
        assert!(lu_in_place(lud.as_mut_slice(), 4, &mut piv));
        lu_solve_transposed_in_place(lud.as_slice(), 4, &piv, btd.as_mut_slice());
        let x_d = DMatrix::from_column_slice(2, 4, x_true.transpose().as_slice());
        assert!((btd - x_d).norm() < 1e-12);
    }

    #[test]
    fn transposed_solve_matches() {
        let a = SMatrix::<f64, 4, 4>::new(
            0.0, 2.0, 1.0, -1.0, 3.0, 1.0, 0.0, 2.0, 1.0, -1.0, 4.0, 0.5, 2.0, 0.0, 1.0, 3.0,
        );
        let x_true = SMatrix::<f64, 4, 6>::from_fn(|i, j| (i as f64 + 1.0) * 0.5 - j as f64);
        let mut bt = (a * x_true).transpose();
        let mut lu = a;
        let mut piv = [0usize; 4];
        assert!(lu_in_place(lu.as_mut_slice(), 4, &mut piv));
        lu_solve_transposed_in_place(lu.as_slice(), 4, &piv, bt.as_mut_slice());
        assert!((bt.transpose() - x_true).norm() < 1e-12);
    }

    #[test]
    fn lu_rejects_singular() {
        let a = Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 0.0);
        let mut lu = a;
        let mut piv = [0usize; 3];
        assert!(!lu_in_place(lu.as_mut_slice(), 3, &mut piv));
    }

    #[test]
    fn symmetry_helpers() {
        let mut m = Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0);
        assert_eq!(max_asymmetry(&m), 4.0);
        symmetrize(&mut m);
        assert_eq!(m, Matrix3::new(1.0, 3.0, 5.0, 3.0, 5.0, 7.0, 5.0, 7.0, 9.0));
        assert!((frobenius_diff(&m, &Matrix3::zeros()) - m.norm()).abs() < 1e-15);
    }
}
