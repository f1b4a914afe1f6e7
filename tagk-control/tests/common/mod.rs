//! Independent DARE solvers used only as test oracles. They share no code with the crate:
//! nalgebra's own LU / SVD / eigenvalue routines and dense Kronecker-product linear systems.
#![allow(dead_code)]

use nalgebra::{Complex, DMatrix};

/// Kleinman–Hewer policy iteration: from a stabilising `k0`, repeatedly solve the Stein
/// (discrete Lyapunov) equation `P = A_cᵀ P A_c + Q + KᵀRK`, `A_c = A − BK`, exactly via the
/// Kronecker form `(I − A_cᵀ⊗A_cᵀ) vec P = vec(Q + KᵀRK)`, then `K ← (R + BᵀPB)⁻¹BᵀPA`.
/// Converges quadratically to the stabilising solution (Hewer 1971).
pub fn kleinman_hewer(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    k0: &DMatrix<f64>,
) -> DMatrix<f64> {
    let n = a.nrows();
    let mut k = k0.clone();
    let mut p_prev = DMatrix::<f64>::zeros(n, n);
    for _ in 0..60 {
        let ac = a - b * &k;
        let act = ac.transpose();
        let lhs = DMatrix::<f64>::identity(n * n, n * n) - act.kronecker(&act);
        let rhs_m = q + k.transpose() * r * &k;
        let rhs = DMatrix::from_column_slice(n * n, 1, rhs_m.as_slice());
        let vecp = lhs
            .lu()
            .solve(&rhs)
            .expect("Stein system singular: K not stabilising");
        let mut p = DMatrix::from_column_slice(n, n, vecp.as_slice());
        p = 0.5 * (&p + p.transpose());
        let s = r + b.transpose() * &p * b;
        k = s
            .lu()
            .solve(&(b.transpose() * &p * a))
            .expect("R + BᵀPB singular");
        let done = (&p - &p_prev).norm() <= 1e-14 * p.norm();
        p_prev = p;
        if done {
            break;
        }
    }
    p_prev
}

/// Stabilising DARE solution from the stable invariant subspace of the symplectic matrix
/// `Z = [[A + G A⁻ᵀ Q, −G A⁻ᵀ], [−A⁻ᵀ Q, A⁻ᵀ]]`, `G = BR⁻¹Bᵀ` (A invertible):
/// with eigenvectors `[X₁; X₂]` for the `n` eigenvalues inside the unit circle,
/// `P = X₂ X₁⁻¹`. Eigenvectors from the null space of `Z − λI` by complex SVD.
pub fn symplectic_eigenvector_solution(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> DMatrix<f64> {
    let n = a.nrows();
    let a_inv_t = a.clone().try_inverse().expect("A singular").transpose();
    let g = b * r.clone().try_inverse().expect("R singular") * b.transpose();
    let mut z = DMatrix::<f64>::zeros(2 * n, 2 * n);
    z.view_mut((0, 0), (n, n))
        .copy_from(&(a + &g * &a_inv_t * q));
    z.view_mut((0, n), (n, n)).copy_from(&(-(&g * &a_inv_t)));
    z.view_mut((n, 0), (n, n)).copy_from(&(-(&a_inv_t * q)));
    z.view_mut((n, n), (n, n)).copy_from(&a_inv_t);
    let eig = z.complex_eigenvalues();
    let stable: Vec<Complex<f64>> = eig.iter().copied().filter(|l| l.norm() < 1.0).collect();
    assert_eq!(stable.len(), n, "expected n stable eigenvalues, got {eig}");
    let zc = z.map(|v| Complex::new(v, 0.0));
    let mut x = DMatrix::<Complex<f64>>::zeros(2 * n, n);
    for (j, lambda) in stable.iter().enumerate() {
        let shifted = &zc - DMatrix::<Complex<f64>>::identity(2 * n, 2 * n) * *lambda;
        let svd = shifted.svd(false, true);
        let v_t = svd.v_t.expect("v_t requested");
        let (imin, _) = svd
            .singular_values
            .iter()
            .enumerate()
            .min_by(|x, y| x.1.partial_cmp(y.1).unwrap())
            .unwrap();
        let v = v_t.row(imin).adjoint();
        x.column_mut(j).copy_from(&v);
    }
    let x1 = x.rows(0, n).into_owned();
    let x2 = x.rows(n, n).into_owned();
    let p = x2 * x1.try_inverse().expect("X1 singular");
    let imag = p.map(|c| c.im).norm();
    assert!(imag < 1e-8 * p.map(|c| c.re).norm(), "complex P: {imag}");
    p.map(|c| c.re)
}
