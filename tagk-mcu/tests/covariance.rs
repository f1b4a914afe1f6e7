//! RLS and the Kalman filter against independent computations with nalgebra: the batch
//! weighted least-squares solution (RLS) and a textbook Kalman filter with an explicit gain
//! and Joseph-form covariance update; plus typed errors and transactional failures.

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use tagk_mcu::{
    ConfigError, EstimatorError, KalmanConfig, KalmanFilter, OnlineEstimator, Rls, RlsConfig,
    covariance_buffer_len,
};

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    ((rng.next_u64() >> 11) as f64) / (1u64 << 53) as f64 * 2.0 - 1.0
}

/// `count` windows of `m × n` (row-major) with `b = A θ + noise`.
fn windows(seed: u64, n: usize, m: usize, count: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let theta: Vec<f64> = (0..n).map(|_| uniform(&mut rng)).collect();
    (0..count)
        .map(|_| {
            let a: Vec<f64> = (0..m * n).map(|_| uniform(&mut rng)).collect();
            let b = (0..m)
                .map(|i| {
                    let dot: f64 = (0..n).map(|j| a[i * n + j] * theta[j]).sum();
                    dot + 0.01 * uniform(&mut rng)
                })
                .collect();
            (a, b)
        })
        .collect()
}

fn max_rel_diff(x: &[f64], y: &[f64]) -> f64 {
    let scale = y.iter().fold(1e-300f64, |s, v| s.max(v.abs()));
    x.iter()
        .zip(y)
        .fold(0.0f64, |d, (a, b)| d.max((a - b).abs()))
        / scale
}

/// Batch solution of `min Σ_k λ^{N−k}‖b_k − A_k θ‖² + λ^N θᵀ P₀⁻¹ θ` and
/// `P = (λ^N P₀⁻¹ + Σ_k λ^{N−k} A_kᵀ A_k)⁻¹`.
fn batch_rls(
    n: usize,
    m: usize,
    lambda: f64,
    p0: f64,
    ws: &[(Vec<f64>, Vec<f64>)],
) -> (Vec<f64>, Vec<f64>) {
    let big_n = ws.len() as i32;
    let mut info = DMatrix::<f64>::identity(n, n) * (lambda.powi(big_n) / p0);
    let mut rhs = DVector::<f64>::zeros(n);
    for (k, (a, b)) in ws.iter().enumerate() {
        let w = lambda.powi(big_n - 1 - k as i32);
        let a = DMatrix::from_row_slice(m, n, a);
        let b = DVector::from_column_slice(b);
        info += a.transpose() * &a * w;
        rhs += a.transpose() * b * w;
    }
    let p = info
        .clone()
        .try_inverse()
        .expect("information matrix is invertible");
    let theta = info.lu().solve(&rhs).expect("solvable");
    (theta.as_slice().to_vec(), p.transpose().as_slice().to_vec())
}

#[test]
fn rls_equals_batch_weighted_least_squares() {
    let (n, m) = (7, 4);
    let config = RlsConfig {
        lambda: 0.9,
        p0: 10.0,
        ..RlsConfig::LOW
    };
    let ws = windows(1, n, m, 6);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut rls = Rls::with_storage(n, m, config, &mut buf[..]).unwrap();
    for k in 0..ws.len() {
        rls.update(&ws[k].0, &ws[k].1).unwrap();
        let (theta, p) = batch_rls(n, m, 0.9, 10.0, &ws[..=k]);
        assert!(
            max_rel_diff(rls.estimate(), &theta) < 1e-10,
            "θ after window {k}"
        );
        assert!(
            max_rel_diff(rls.covariance(), &p) < 1e-10,
            "P after window {k}"
        );
    }
}

#[test]
fn rls_in_f32_tracks_the_f64_batch_solution() {
    let (n, m) = (7, 4);
    let ws = windows(2, n, m, 6);
    let mut buf = vec![0.0f32; covariance_buffer_len(n, m)];
    let mut rls = Rls::with_storage(n, m, RlsConfig::LOW, &mut buf[..]).unwrap();
    for (a, b) in &ws {
        let a: Vec<f32> = a.iter().map(|&v| v as f32).collect();
        let b: Vec<f32> = b.iter().map(|&v| v as f32).collect();
        rls.update(&a, &b).unwrap();
    }
    let (theta, _) = batch_rls(n, m, 0.99, 1e3, &ws);
    let est: Vec<f64> = rls.estimate().iter().map(|&v| f64::from(v)).collect();
    assert!(max_rel_diff(&est, &theta) < 1e-3, "{est:?} vs {theta:?}");
}

/// Textbook random-walk Kalman filter: predict, gain with an explicit `S⁻¹`, Joseph update.
fn textbook_kf(
    n: usize,
    m: usize,
    q: f64,
    r: f64,
    p0: f64,
    ws: &[(Vec<f64>, Vec<f64>)],
) -> (Vec<f64>, Vec<f64>) {
    let mut theta = DVector::<f64>::zeros(n);
    let mut p = DMatrix::<f64>::identity(n, n) * p0;
    for (a, b) in ws {
        let a = DMatrix::from_row_slice(m, n, a);
        let b = DVector::from_column_slice(b);
        p += DMatrix::identity(n, n) * (q * q);
        let s = &a * &p * a.transpose() + DMatrix::identity(m, m) * (r * r);
        let k = &p * a.transpose() * s.try_inverse().expect("S is invertible");
        theta += &k * (b - &a * &theta);
        let i_ka = DMatrix::identity(n, n) - &k * &a;
        p = &i_ka * &p * i_ka.transpose() + &k * k.transpose() * (r * r);
    }
    (theta.as_slice().to_vec(), p.transpose().as_slice().to_vec())
}

#[test]
fn kalman_filter_equals_the_textbook_filter() {
    let (n, m) = (6, 3);
    let config = KalmanConfig {
        sigma_q: 0.05,
        sigma_r: 0.1,
        p0: 5.0,
        ..KalmanConfig::LOW
    };
    let ws = windows(3, n, m, 8);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut kf = KalmanFilter::with_storage(n, m, config, &mut buf[..]).unwrap();
    for k in 0..ws.len() {
        kf.update(&ws[k].0, &ws[k].1).unwrap();
        let (theta, p) = textbook_kf(n, m, 0.05, 0.1, 5.0, &ws[..=k]);
        assert!(
            max_rel_diff(kf.estimate(), &theta) < 1e-10,
            "θ after window {k}"
        );
        assert!(
            max_rel_diff(kf.covariance(), &p) < 1e-10,
            "P after window {k}"
        );
    }
}

#[test]
fn kf_low_matches_the_textbook_filter_in_f64() {
    let (n, m) = (10, 5);
    let ws = windows(4, n, m, 5);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut kf = KalmanFilter::with_storage(n, m, KalmanConfig::LOW, &mut buf[..]).unwrap();
    for (a, b) in &ws {
        kf.update(a, b).unwrap();
    }
    let (theta, _) = textbook_kf(n, m, 1e-3, 1e-5, 1e3, &ws);
    assert!(
        max_rel_diff(kf.estimate(), &theta) < 1e-6,
        "{:?} vs {theta:?}",
        kf.estimate()
    );
}

#[test]
fn kf_low_in_f32_is_refused_with_a_typed_error_and_keeps_its_state() {
    // P₀/σ_R² = 10¹³ is beyond single precision: once a window has pinned some directions
    // down to ~σ_R², round-off in P exceeds them and S stops being positive definite.
    let (n, m) = (8, 6);
    let ws = windows(5, n, m, 6);
    let mut buf = vec![0.0f32; covariance_buffer_len(n, m)];
    let mut kf = KalmanFilter::with_storage(n, m, KalmanConfig::LOW, &mut buf[..]).unwrap();
    let mut failure = None;
    for (a, b) in &ws {
        let a: Vec<f32> = a.iter().map(|&v| v as f32).collect();
        let b: Vec<f32> = b.iter().map(|&v| v as f32).collect();
        let (theta, p) = (kf.estimate().to_vec(), kf.covariance().to_vec());
        if let Err(e) = kf.update(&a, &b) {
            assert_eq!(kf.estimate(), &theta[..]);
            assert_eq!(kf.covariance(), &p[..]);
            failure = Some(e);
            break;
        }
    }
    assert!(
        matches!(failure, Some(EstimatorError::NumericalFailure(_))),
        "{failure:?}"
    );
}

#[test]
fn reset_restores_the_prior() {
    let (n, m) = (4, 3);
    let ws = windows(6, n, m, 2);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut rls = Rls::with_storage(n, m, RlsConfig::LOW, &mut buf[..]).unwrap();
    rls.update(&ws[0].0, &ws[0].1).unwrap();
    rls.reset(&[1.0, 2.0, 3.0, 4.0]).unwrap();
    assert_eq!(rls.estimate(), &[1.0, 2.0, 3.0, 4.0]);
    for i in 0..n {
        for j in 0..n {
            let expected = if i == j { 1e3 } else { 0.0 };
            assert_eq!(rls.covariance()[i * n + j], expected);
        }
    }
    assert_eq!(
        rls.reset(&[1.0, 2.0]),
        Err(EstimatorError::DimensionMismatch {
            expected: 4,
            found: 2
        })
    );
    assert_eq!(
        rls.reset(&[1.0, f64::NAN, 0.0, 0.0]),
        Err(EstimatorError::NonFiniteEstimate { index: 1 })
    );
}

#[test]
fn bad_windows_are_typed_errors() {
    let (n, m) = (3, 2);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut kf = KalmanFilter::with_storage(n, m, KalmanConfig::LOW, &mut buf[..]).unwrap();
    assert_eq!(kf.update(&[], &[]), Err(EstimatorError::EmptyWindow));
    assert_eq!(
        kf.update(&[0.0; 9], &[0.0; 3]),
        Err(EstimatorError::WindowTooLarge {
            rows: 3,
            capacity: 2
        })
    );
    assert!(matches!(
        kf.update(&[0.0; 5], &[0.0; 2]),
        Err(EstimatorError::ShapeMismatch { .. })
    ));
    assert_eq!(
        kf.update(&[1.0, 0.0, f64::INFINITY, 0.0, 1.0, 0.0], &[1.0, 1.0]),
        Err(EstimatorError::NonFiniteRegressor { row: 0, col: 2 })
    );
    assert_eq!(
        kf.update(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0], &[1.0, f64::NAN]),
        Err(EstimatorError::NonFiniteMeasurement { row: 1 })
    );
    assert_eq!(kf.estimate(), &[0.0; 3]);
}

#[test]
fn an_overflowing_update_is_refused_and_changes_nothing() {
    let (n, m) = (2, 1);
    let mut buf = vec![0.0; covariance_buffer_len(n, m)];
    let mut rls = Rls::with_storage(n, m, RlsConfig::LOW, &mut buf[..]).unwrap();
    rls.update(&[1.0, 0.0], &[2.0]).unwrap();
    let (theta, p) = (rls.estimate().to_vec(), rls.covariance().to_vec());
    let err = rls.update(&[1e300, 1e300], &[1e300]).unwrap_err();
    assert!(
        matches!(
            err,
            EstimatorError::Diverged | EstimatorError::NumericalFailure(_)
        ),
        "{err:?}"
    );
    assert_eq!(rls.estimate(), &theta[..]);
    assert_eq!(rls.covariance(), &p[..]);
}

#[test]
fn invalid_configurations_are_typed_errors() {
    let ok = covariance_buffer_len(3, 2);
    let rls = |cfg: RlsConfig, n: usize, m: usize, len: usize| {
        Rls::<f64, Vec<f64>>::with_storage(n, m, cfg, vec![0.0; len]).err()
    };
    assert_eq!(
        rls(RlsConfig::LOW, 0, 2, ok),
        Some(ConfigError::ZeroDimension)
    );
    assert_eq!(
        rls(RlsConfig::LOW, 3, 0, ok),
        Some(ConfigError::ZeroCapacity)
    );
    assert_eq!(
        rls(RlsConfig::LOW, 3, 2, ok - 1),
        Some(ConfigError::BufferTooSmall {
            needed: ok,
            found: ok - 1
        })
    );
    for bad in [0.0, -0.5, 1.5, f64::NAN] {
        let cfg = RlsConfig {
            lambda: bad,
            ..RlsConfig::LOW
        };
        assert!(matches!(
            rls(cfg, 3, 2, ok),
            Some(ConfigError::InvalidParameter { name: "lambda", .. })
        ));
    }
    let cfg = RlsConfig {
        p0: 0.0,
        ..RlsConfig::LOW
    };
    assert!(matches!(
        rls(cfg, 3, 2, ok),
        Some(ConfigError::InvalidParameter { name: "p0", .. })
    ));
    let kf = |cfg: KalmanConfig| {
        KalmanFilter::<f64, Vec<f64>>::with_storage(3, 2, cfg, vec![0.0; ok]).err()
    };
    let cfg = KalmanConfig {
        sigma_r: 0.0,
        ..KalmanConfig::LOW
    };
    assert!(matches!(
        kf(cfg),
        Some(ConfigError::InvalidParameter {
            name: "sigma_r",
            ..
        })
    ));
    let cfg = KalmanConfig {
        sigma_q: f64::INFINITY,
        ..KalmanConfig::LOW
    };
    assert!(matches!(
        kf(cfg),
        Some(ConfigError::InvalidParameter {
            name: "sigma_q",
            ..
        })
    ));
    assert_eq!(kf(KalmanConfig::HIGH), None);
}

fn window(n: usize, m_max: usize) -> impl Strategy<Value = (Vec<f64>, Vec<f64>)> {
    (1..=m_max).prop_flat_map(move |m| {
        (
            prop::collection::vec(prop_oneof![Just(0.0), -10.0f64..10.0], m * n),
            prop::collection::vec(-10.0f64..10.0, m),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn covariance_stays_exactly_symmetric_and_failures_change_nothing(
        ws in prop::collection::vec(window(5, 4), 1..8),
        kalman in any::<bool>(),
    ) {
        let (n, m) = (5, 4);
        let mut buf = vec![0.0; covariance_buffer_len(n, m)];
        let check = |est: &mut dyn OnlineEstimator<f64>| -> Result<(), TestCaseError> {
            for (a, b) in &ws {
                let before = est.estimate().to_vec();
                match est.update(a, b) {
                    Ok(info) => {
                        prop_assert_eq!(info.rows, b.len());
                        prop_assert!(est.estimate().iter().all(|v| v.is_finite()));
                    }
                    Err(_) => prop_assert_eq!(est.estimate(), &before[..]),
                }
            }
            Ok(())
        };
        let p = if kalman {
            let mut kf = KalmanFilter::with_storage(n, m, KalmanConfig::HIGH, &mut buf[..]).unwrap();
            check(&mut kf)?;
            kf.covariance().to_vec()
        } else {
            let mut rls = Rls::with_storage(n, m, RlsConfig::LOW, &mut buf[..]).unwrap();
            check(&mut rls)?;
            rls.covariance().to_vec()
        };
        for i in 0..n {
            prop_assert!(p[i * n + i] > 0.0);
            for j in 0..n {
                prop_assert_eq!(p[i * n + j].to_bits(), p[j * n + i].to_bits());
            }
        }
    }
}
