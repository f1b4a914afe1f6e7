//! DARE solvers against closed forms and independent methods.

mod common;

use nalgebra::{DMatrix, Matrix1, Matrix2, SMatrix};
use proptest::prelude::*;
use tagk_control::{
    DareError, DareOptions, dare_residual, solve_dare, solve_dare_cold, solve_dare_sda,
};

fn tight() -> DareOptions {
    DareOptions {
        tolerance: 1e-14,
        max_iterations: 1_000_000,
    }
}

/// Positive root of `b²p² + (r(1 − a²) − q b²) p − q r = 0` (the scalar DARE multiplied by
/// `r + b²p`), in the cancellation-free form `2c / (−β + √(β² − 4αc))` when `β > 0`.
fn scalar_dare_closed_form(a: f64, b: f64, q: f64, r: f64) -> f64 {
    let alpha = b * b;
    let beta = r * (1.0 - a * a) - q * b * b;
    let c = -q * r;
    let disc = (beta * beta - 4.0 * alpha * c).sqrt();
    if beta > 0.0 {
        2.0 * c / (-beta - disc)
    } else {
        (-beta + disc) / (2.0 * alpha)
    }
}

#[test]
fn scalar_dare_matches_closed_form() {
    for &(a, b, q, r) in &[
        (0.5, 1.0, 1.0, 1.0),
        (1.2, 0.3, 2.0, 0.1), // open-loop unstable
        (1.0, 1.0, 1.0, 1.0), // integrator: p = (1 + √5)/2
        (0.9, 2.0, 1e-3, 10.0),
    ] {
        let p_exact = scalar_dare_closed_form(a, b, q, r);
        let (am, bm, qm, rm) = (
            Matrix1::new(a),
            Matrix1::new(b),
            Matrix1::new(q),
            Matrix1::new(r),
        );
        let it = solve_dare_cold(&am, &bm, &qm, &rm, &tight()).unwrap();
        let sda = solve_dare_sda(&am, &bm, &qm, &rm, &tight()).unwrap();
        for p in [it.p[(0, 0)], sda.p[(0, 0)]] {
            assert!(
                (p - p_exact).abs() <= 1e-12 * p_exact,
                "{a} {b} {q} {r}: {p} vs {p_exact}"
            );
        }
        let k_exact = p_exact * a * b / (r + b * b * p_exact);
        assert!((it.k[(0, 0)] - k_exact).abs() <= 1e-12 * k_exact.abs());
    }
    // The golden ratio case, by hand.
    let golden = 0.5 * (1.0 + 5f64.sqrt());
    assert!((scalar_dare_closed_form(1.0, 1.0, 1.0, 1.0) - golden).abs() < 1e-15);
}

/// Double integrator sampled at T = 0.1 s, Q = I, R = 1.
fn double_integrator() -> (Matrix2<f64>, SMatrix<f64, 2, 1>, Matrix2<f64>, Matrix1<f64>) {
    let t = 0.1;
    (
        Matrix2::new(1.0, t, 0.0, 1.0),
        SMatrix::<f64, 2, 1>::from_column_slice(&[0.5 * t * t, t]),
        Matrix2::identity(),
        Matrix1::new(1.0),
    )
}

fn to_d<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_column_slice(R, C, m.as_slice())
}

#[test]
fn double_integrator_matches_two_independent_methods() {
    let (a, b, q, r) = double_integrator();
    let (ad, bd, qd, rd) = (to_d(&a), to_d(&b), to_d(&q), to_d(&r));
    // Independent 1: stable invariant subspace of the symplectic matrix.
    let p_symp = common::symplectic_eigenvector_solution(&ad, &bd, &qd, &rd);
    // Independent 2: Kleinman–Hewer from a stabilising PD gain (poles of A − BK inside).
    let k0 = DMatrix::from_row_slice(1, 2, &[1.0, 1.5]);
    let p_kh = common::kleinman_hewer(&ad, &bd, &qd, &rd, &k0);
    assert!((&p_symp - &p_kh).norm() < 1e-9 * p_kh.norm());

    let it = solve_dare_cold(&a, &b, &q, &r, &tight()).unwrap();
    let sda = solve_dare_sda(&a, &b, &q, &r, &tight()).unwrap();
    for p in [&it.p, &sda.p] {
        let err = (to_d(p) - &p_kh).norm() / p_kh.norm();
        assert!(err < 1e-10, "relative error {err}");
    }
    assert!(it.residual < 1e-12 && sda.residual < 1e-12);
    // Closed loop stable.
    let acl = a - b * it.k;
    assert!(acl.complex_eigenvalues().iter().all(|l| l.norm() < 1.0));
    // A few doubling steps replace many Riccati steps.
    assert!(
        sda.iterations * 4 < it.iterations,
        "{} vs {}",
        sda.iterations,
        it.iterations
    );
}

#[test]
fn dynamic_and_static_paths_agree() {
    let (a, b, q, r) = double_integrator();
    let s = solve_dare_cold(&a, &b, &q, &r, &DareOptions::default()).unwrap();
    let d = solve_dare_cold(
        &to_d(&a),
        &to_d(&b),
        &to_d(&q),
        &to_d(&r),
        &DareOptions::default(),
    )
    .unwrap();
    assert_eq!(s.iterations, d.iterations);
    assert!((to_d(&s.p) - &d.p).norm() <= 1e-12 * d.p.norm());
    let sd = solve_dare_sda(
        &to_d(&a),
        &to_d(&b),
        &to_d(&q),
        &to_d(&r),
        &DareOptions::default(),
    )
    .unwrap();
    assert!((to_d(&s.p) - &sd.p).norm() <= 1e-9 * d.p.norm());
}

#[test]
fn warm_start_at_the_solution_converges_at_once() {
    let (a, b, q, r) = double_integrator();
    let s = solve_dare_cold(&a, &b, &q, &r, &tight()).unwrap();
    let again = solve_dare(&a, &b, &q, &r, &s.p, &DareOptions::default()).unwrap();
    assert_eq!(again.iterations, 1);
    let res = dare_residual(&a, &b, &q, &r, &s.p).unwrap();
    assert!(res < 1e-13);
    // A wrong P has a large residual.
    assert!(dare_residual(&a, &b, &q, &r, &(s.p * 1.1)).unwrap() > 1e-3);
}

#[test]
fn typed_errors() {
    let (a, b, q, r) = double_integrator();
    let (ad, bd, qd, rd) = (to_d(&a), to_d(&b), to_d(&q), to_d(&r));
    let opts = DareOptions::default();
    // Shape mismatch (only possible with dynamic sizes).
    let bad_b = DMatrix::<f64>::zeros(3, 1);
    assert!(matches!(
        solve_dare_cold(&ad, &bad_b, &qd, &rd, &opts),
        Err(DareError::ShapeMismatch { what: "B", .. })
    ));
    let bad_r = DMatrix::<f64>::identity(2, 2);
    assert!(matches!(
        solve_dare_sda(&ad, &bd, &qd, &bad_r, &opts),
        Err(DareError::ShapeMismatch { what: "R", .. })
    ));
    let bad_p0 = DMatrix::<f64>::zeros(3, 3);
    assert!(matches!(
        solve_dare(&ad, &bd, &qd, &rd, &bad_p0, &opts),
        Err(DareError::ShapeMismatch { what: "P0", .. })
    ));
    // Non-finite.
    let mut a_nan = a;
    a_nan[(0, 1)] = f64::NAN;
    assert!(matches!(
        solve_dare_cold(&a_nan, &b, &q, &r, &opts),
        Err(DareError::NonFinite { what: "A" })
    ));
    // Q indefinite.
    let q_bad = Matrix2::new(1.0, 0.0, 0.0, -0.5);
    match solve_dare_cold(&a, &b, &q_bad, &r, &opts) {
        Err(DareError::QNotPositiveSemidefinite { min_eigenvalue }) => {
            assert!((min_eigenvalue + 0.5).abs() < 1e-12)
        }
        other => panic!("{other:?}"),
    }
    // Q PSD but singular is fine.
    let q_psd = Matrix2::new(1.0, 0.0, 0.0, 0.0);
    assert!(solve_dare_cold(&a, &b, &q_psd, &r, &opts).is_ok());
    // R not PD.
    assert!(matches!(
        solve_dare_sda(&a, &b, &q, &Matrix1::new(0.0), &opts),
        Err(DareError::RNotPositiveDefinite { .. })
    ));
    // Q not symmetric.
    assert!(matches!(
        solve_dare_cold(&a, &b, &Matrix2::new(1.0, 0.5, 0.0, 1.0), &r, &opts),
        Err(DareError::NotSymmetric { what: "Q", .. })
    ));
    // Iteration cap.
    let capped = DareOptions {
        tolerance: 1e-12,
        max_iterations: 3,
    };
    assert!(matches!(
        solve_dare_cold(&a, &b, &q, &r, &capped),
        Err(DareError::NotConverged { iterations: 3, .. })
    ));
    // Not stabilisable: unstable mode without input → P grows without bound.
    let a_unstab = Matrix2::new(1.5, 0.0, 0.0, 0.5);
    let b_unstab = SMatrix::<f64, 2, 1>::new(0.0, 1.0);
    let res = solve_dare_cold(&a_unstab, &b_unstab, &q, &r, &opts);
    assert!(
        matches!(
            res,
            Err(DareError::Diverged { .. } | DareError::NotConverged { .. })
        ),
        "{res:?}"
    );
    let res = solve_dare_sda(&a_unstab, &b_unstab, &q, &r, &opts);
    assert!(res.is_err(), "{res:?}");
    // An indefinite warm start that breaks R + BᵀPB.
    let p0 = Matrix2::new(-1e6, 0.0, 0.0, -1e6);
    assert!(matches!(
        solve_dare(&a, &b, &q, &r, &p0, &opts),
        Err(DareError::Breakdown { iteration: 1 })
    ));
}

fn random_system(
    seed: [f64; 16],
) -> (
    SMatrix<f64, 3, 3>,
    SMatrix<f64, 3, 2>,
    SMatrix<f64, 3, 3>,
    Matrix2<f64>,
) {
    let a = SMatrix::<f64, 3, 3>::from_fn(|i, j| 1.2 * seed[3 * i + j] / 3f64.sqrt());
    let b = SMatrix::<f64, 3, 2>::from_fn(|i, j| seed[9 + 2 * i + j]);
    let c = SMatrix::<f64, 3, 3>::from_fn(|i, j| {
        if i == j {
            1.0
        } else {
            0.3 * seed[(i + j) % 16]
        }
    });
    let q = c.transpose() * c;
    let l = Matrix2::new(1.0 + seed[15].abs(), 0.0, 0.2, 0.5);
    let r = l * l.transpose();
    (a, b, q, r)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// Random (generically stabilisable) systems: both solvers agree, P is symmetric PSD, the
    /// residual is tiny, the closed loop is stable, and the Riccati identity
    /// P = A_cᵀPA_c + Q + KᵀRK holds (an independent algebraic rearrangement).
    #[test]
    fn random_systems(seed in prop::array::uniform16(-1.0f64..1.0)) {
        let (a, b, q, r) = random_system(seed);
        // Skip nearly uncontrollable draws (controllability Gramian-ish test).
        let ctrb = nalgebra::SMatrix::<f64, 3, 6>::from_columns(&[
            b.column(0).into_owned(), b.column(1).into_owned(),
            (a * b).column(0).into_owned(), (a * b).column(1).into_owned(),
            (a * a * b).column(0).into_owned(), (a * a * b).column(1).into_owned(),
        ]);
        prop_assume!(ctrb.singular_values().min() > 0.05);
        let it = solve_dare_cold(&a, &b, &q, &r, &tight()).unwrap();
        let sda = solve_dare_sda(&a, &b, &q, &r, &tight()).unwrap();
        prop_assert!((it.p - sda.p).norm() <= 1e-8 * it.p.norm());
        prop_assert!(it.residual < 1e-12 && sda.residual < 1e-12);
        prop_assert!(it.p.symmetric_eigenvalues().min() > -1e-10 * it.p.norm());
        let acl = a - b * it.k;
        prop_assert!(acl.complex_eigenvalues().iter().all(|l| l.norm() < 1.0));
        let joseph = acl.transpose() * it.p * acl + q + it.k.transpose() * r * it.k;
        prop_assert!((joseph - it.p).norm() <= 1e-9 * it.p.norm());
        // Warm start from a perturbed solution converges to the same P.
        let p0 = it.p * 1.3 + SMatrix::<f64, 3, 3>::identity();
        let warm = solve_dare(&a, &b, &q, &r, &p0, &tight()).unwrap();
        prop_assert!((warm.p - it.p).norm() <= 1e-9 * it.p.norm());
    }
}
