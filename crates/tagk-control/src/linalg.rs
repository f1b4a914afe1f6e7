//! Small dense kernels that work in place on any nalgebra storage, so that the
//! Riccati solvers do not allocate inside their loops (nalgebra's `Cholesky` and
//! `LU` consume their argument, which would allocate for `DMatrix`).

use nalgebra::{Dim, Matrix, RawStorage, StorageMut};

/// Cholesky factorisation in place: on success the lower triangle of `m` holds `L`
/// with `m = L Lᵀ` (the strict upper triangle is left untouched and never read).
/// Returns `false` if `m` is not (numerically) positive definite.
pub(crate) fn cholesky_in_place<D: Dim, S: StorageMut<f64, D, D>>(
    m: &mut Matrix<f64, D, D, S>,
) -> bool {
    let n = m.nrows();
    for j in 0..n {
        let mut d = m[(j, j)];
        for k in 0..j {
            let ljk = m[(j, k)];
            d -= ljk * ljk;
        }
        // `!(d > 0)` also rejects NaN.
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let ljj = d.sqrt();
        m[(j, j)] = ljj;
        for i in (j + 1)..n {
            let mut s = m[(i, j)];
            for k in 0..j {
                s -= m[(i, k)] * m[(j, k)];
            }
            m[(i, j)] = s / ljj;
        }
    }
    true
}

/// Solves `L Lᵀ X = B` in place (`B` is overwritten by `X`), with `L` from
/// [`cholesky_in_place`].
pub(crate) fn cholesky_solve_in_place<D, C, S1, S2>(
    l: &Matrix<f64, D, D, S1>,
    b: &mut Matrix<f64, D, C, S2>,
) where
    D: Dim,
    C: Dim,
    S1: RawStorage<f64, D, D>,
    S2: StorageMut<f64, D, C>,
{
    let n = l.nrows();
    for col in 0..b.ncols() {
        for i in 0..n {
            let mut s = b[(i, col)];
            for k in 0..i {
                s -= l[(i, k)] * b[(k, col)];
            }
            b[(i, col)] = s / l[(i, i)];
        }
        for i in (0..n).rev() {
            let mut s = b[(i, col)];
            for k in (i + 1)..n {
                s -= l[(k, i)] * b[(k, col)];
            }
            b[(i, col)] = s / l[(i, i)];
        }
    }
}

/// LU factorisation with partial pivoting in place (`P m = L U`, unit lower `L`
/// below the diagonal, `U` on and above). `piv[k]` is the row swapped with row `k`
/// at step `k`. Returns `false` if a pivot is zero or not finite.
pub(crate) fn lu_in_place<D: Dim, S: StorageMut<f64, D, D>>(
    m: &mut Matrix<f64, D, D, S>,
    piv: &mut [usize],
) -> bool {
    let n = m.nrows();
    debug_assert!(piv.len() >= n);
    for k in 0..n {
        let mut p = k;
        let mut best = m[(k, k)].abs();
        for i in (k + 1)..n {
            let v = m[(i, k)].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        piv[k] = p;
        if p != k {
            m.swap_rows(k, p);
        }
        let inv = 1.0 / m[(k, k)];
        for i in (k + 1)..n {
            m[(i, k)] *= inv;
        }
        for j in (k + 1)..n {
            let mkj = m[(k, j)];
            if mkj != 0.0 {
                for i in (k + 1)..n {
                    let lik = m[(i, k)];
                    m[(i, j)] -= lik * mkj;
                }
            }
        }
    }
    true
}

/// Solves `m X = B` in place with the factors of [`lu_in_place`].
pub(crate) fn lu_solve_in_place<D, C, S1, S2>(
    lu: &Matrix<f64, D, D, S1>,
    piv: &[usize],
    b: &mut Matrix<f64, D, C, S2>,
) where
    D: Dim,
    C: Dim,
    S1: RawStorage<f64, D, D>,
    S2: StorageMut<f64, D, C>,
{
    let n = lu.nrows();
    for (k, &p) in piv.iter().enumerate().take(n) {
        if p != k {
            b.swap_rows(k, p);
        }
    }
    for col in 0..b.ncols() {
        // Forward substitution with the unit lower factor (column oriented).
        for k in 0..n {
            let bk = b[(k, col)];
            if bk != 0.0 {
                for i in (k + 1)..n {
                    b[(i, col)] -= lu[(i, k)] * bk;
                }
            }
        }
        // Back substitution with the upper factor (column oriented).
        for k in (0..n).rev() {
            let xk = b[(k, col)] / lu[(k, k)];
            b[(k, col)] = xk;
            if xk != 0.0 {
                for i in 0..k {
                    b[(i, col)] -= lu[(i, k)] * xk;
                }
            }
        }
    }
}

/// Frobenius norm of `a − b`.
pub(crate) fn frobenius_diff<R, C, S1, S2>(a: &Matrix<f64, R, C, S1>, b: &Matrix<f64, R, C, S2>) -> f64
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
        assert!(cholesky_in_place(&mut l));
        let lower = l.lower_triangle();
        assert!((lower * lower.transpose() - a).norm() < 1e-14);
        let x_true = Matrix3x2::new(1.0, -2.0, 0.5, 3.0, -1.5, 0.25);
        let mut b = a * x_true;
        cholesky_solve_in_place(&l, &mut b);
        assert!((b - x_true).norm() < 1e-13);
    }

    #[test]
    fn cholesky_rejects_indefinite_and_nan() {
        let mut a = Matrix3::new(1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert!(!cholesky_in_place(&mut a));
        let mut b = Matrix3::identity();
        b[(1, 1)] = f64::NAN;
        assert!(!cholesky_in_place(&mut b));
    }

    #[test]
    fn lu_solves_against_nalgebra_reference() {
        // Needs pivoting: zero leading entry.
        let a = SMatrix::<f64, 4, 4>::new(
            0.0, 2.0, 1.0, -1.0, 3.0, 1.0, 0.0, 2.0, 1.0, -1.0, 4.0, 0.5, 2.0, 0.0, 1.0, 3.0,
        );
        let x_true = SMatrix::<f64, 4, 2>::new(1.0, 2.0, -1.0, 0.5, 3.0, -2.0, 0.25, 1.0);
        let mut b = a * x_true;
        let mut lu = a;
        let mut piv = [0usize; 4];
        assert!(lu_in_place(&mut lu, &mut piv));
        lu_solve_in_place(&lu, &piv, &mut b);
        assert!((b - x_true).norm() < 1e-12, "{}", (b - x_true).norm());

        let ad = DMatrix::from_column_slice(4, 4, a.as_slice());
        let mut lud = ad.clone();
        let mut bd = DMatrix::from_column_slice(4, 2, (a * x_true).as_slice());
        assert!(lu_in_place(&mut lud, &mut piv));
        lu_solve_in_place(&lud, &piv, &mut bd);
        assert!((bd - DMatrix::from_column_slice(4, 2, x_true.as_slice())).norm() < 1e-12);
    }

    #[test]
    fn lu_rejects_singular() {
        let a = Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 0.0);
        let mut lu = a;
        let mut piv = [0usize; 3];
        assert!(!lu_in_place(&mut lu, &mut piv));
    }
}
