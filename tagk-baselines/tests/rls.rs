//! RLS against independent batch least-squares solutions, and its covariance wind-up.

mod common;

use common::*;
use tagk_baselines::{Backend, EstimatorError, OnlineEstimator, Rls, RlsConfig, WindupGuard};

fn check_against_batch(n: usize, m_max: usize, lambda: f64, backend: Backend, seed: u64) {
    let mut g = rng(seed);
    let theta_true = random_vec(&mut g, n, 2.0);
    let theta0 = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, m_max, 25, &theta_true, 0.1, false);
    let p0 = 10.0;
    let cfg = RlsConfig::default()
        .with_lambda(lambda)
        .with_p0(p0)
        .with_backend(backend);
    let mut rls = Rls::new(n, m_max, cfg).unwrap();
    rls.reset(&theta0).unwrap();
    for (k, w) in stream.iter().enumerate() {
        let info = rls.update(&w.a, &w.b).unwrap();
        assert_eq!(info.rows, w.rows());
        assert_eq!(info.iterations, 1);
        if k % 6 == 5 || k + 1 == stream.len() {
            let (theta, cov) = weighted_batch_ls(n, &stream[..=k], lambda, p0, &theta0);
            let e = rel_err(rls.estimate(), &theta);
            assert!(
                e < 1e-9,
                "n={n} λ={lambda} {backend:?} window {k}: θ error {e:e}"
            );
            // nalgebra is column-major; P is symmetric, so compare with the transpose's data.
            let c = rel_err(rls.covariance(), cov.transpose().as_slice());
            assert!(
                c < 1e-9,
                "n={n} λ={lambda} {backend:?} window {k}: P error {c:e}"
            );
        }
    }
}

#[test]
fn lambda_one_equals_regularised_batch_least_squares() {
    for backend in BACKENDS {
        for (n, m_max) in [(1, 3), (3, 2), (10, 30), (40, 30)] {
            check_against_batch(n, m_max, 1.0, backend, 11 + n as u64);
        }
    }
}

#[test]
fn forgetting_equals_exponentially_weighted_batch_least_squares() {
    for backend in BACKENDS {
        for lambda in [0.99, 0.9] {
            for (n, m_max) in [(3, 2), (10, 30), (40, 30)] {
                check_against_batch(n, m_max, lambda, backend, 101 + n as u64);
            }
        }
    }
}

#[test]
fn presets_have_the_paper_settings_and_names() {
    let low = Rls::rls_low(10, 30).unwrap();
    let high = Rls::rls_high(10, 30).unwrap();
    let custom = Rls::new(10, 30, RlsConfig::default()).unwrap();
    assert_eq!(
        (low.name(), low.config().lambda, low.config().p0),
        ("RLS-low", 0.99, 1e3)
    );
    assert_eq!(
        (high.name(), high.config().lambda, high.config().p0),
        ("RLS-high", 0.96, 1e3)
    );
    assert_eq!(custom.name(), "RLS");
    assert_eq!(low.config().windup_guard, WindupGuard::None);
    for est in [&low, &high] {
        assert_eq!((est.dim(), est.capacity()), (10, 30));
        assert!(est.estimate().iter().all(|&v| v == 0.0));
        for (k, &v) in est.covariance().iter().enumerate() {
            assert_eq!(v, if k % 11 == 0 { 1e3 } else { 0.0 });
        }
    }
}

#[test]
fn update_info_reports_the_prior_residual_over_nonzero_rows() {
    let n = 4;
    let mut g = rng(3);
    let theta = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, 6, 5, &theta, 0.05, true);
    for backend in BACKENDS {
        let mut rls = Rls::new(n, 7, RlsConfig::default().with_backend(backend)).unwrap();
        for w in &stream {
            // Add a zero row whose measurement must not count in the residual.
            let mut a = w.a.clone();
            a.extend([0.0; 4]);
            let mut b = w.b.clone();
            b.push(100.0);
            let prev = rls.estimate().to_vec();
            let expected =
                w.a.chunks(n)
                    .zip(&w.b)
                    .map(|(row, bi)| {
                        let r = bi - row.iter().zip(&prev).map(|(x, t)| x * t).sum::<f64>();
                        r * r
                    })
                    .sum::<f64>()
                    .sqrt();
            let info = rls.update(&a, &b).unwrap();
            assert_eq!(info.rows, 7);
            assert!((info.prior_residual_norm - expected).abs() <= 1e-12 * expected.max(1.0));
            assert!(!info.converged);
        }
    }
}

#[test]
fn zero_rows_change_nothing() {
    let n = 5;
    let mut g = rng(8);
    let theta = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, 4, 10, &theta, 0.1, true);
    for backend in BACKENDS {
        let cfg = RlsConfig::LOW.with_backend(backend);
        let mut plain = Rls::new(n, 8, cfg).unwrap();
        let mut padded = Rls::new(n, 8, cfg).unwrap();
        for w in &stream {
            plain.update(&w.a, &w.b).unwrap();
            // Interleave zero rows (with arbitrary measurements) between the real ones.
            let mut a = Vec::new();
            let mut b = Vec::new();
            for (row, bi) in w.a.chunks(n).zip(&w.b) {
                a.extend_from_slice(row);
                b.push(*bi);
                a.extend(std::iter::repeat_n(0.0, n));
                b.push(-7.0);
            }
            padded.update(&a, &b).unwrap();
        }
        assert!(rel_err(padded.estimate(), plain.estimate()) < 1e-12);
        assert!(rel_err(padded.covariance(), plain.covariance()) < 1e-12);
    }
}

#[test]
fn backends_agree() {
    let (n, m) = (30, 30);
    let mut g = rng(21);
    let theta = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, m, 40, &theta, 0.01, false);
    let mut loops = Rls::new(n, m, RlsConfig::HIGH.with_backend(Backend::Loops)).unwrap();
    let mut faer = Rls::new(n, m, RlsConfig::HIGH.with_backend(Backend::Faer)).unwrap();
    assert_eq!(Rls::rls_high(n, m).unwrap().backend(), Backend::Faer);
    for w in &stream {
        loops.update(&w.a, &w.b).unwrap();
        faer.update(&w.a, &w.b).unwrap();
    }
    assert!(rel_err(faer.estimate(), loops.estimate()) < 1e-10);
    assert!(rel_err(faer.covariance(), loops.covariance()) < 1e-10);
}

/// Windows whose rows all point along `dir`: only one direction of θ is excited.
fn one_direction_windows(dir: &[f64], count: usize, theta: &[f64]) -> Vec<Window> {
    let n = dir.len();
    (0..count)
        .map(|k| {
            let scales = [1.0 + 0.1 * (k % 3) as f64, -0.5];
            let a: Vec<f64> = scales
                .iter()
                .flat_map(|s| dir.iter().map(move |d| s * d))
                .collect();
            let b = a
                .chunks(n)
                .map(|row| row.iter().zip(theta).map(|(x, t)| x * t).sum())
                .collect();
            Window { a, b }
        })
        .collect()
}

#[test]
fn covariance_winds_up_under_poor_excitation() {
    let dir = [1.0, 1.0, 0.0, 0.0];
    let theta = [0.5, 0.25, -1.0, 2.0];
    let stream = one_direction_windows(&dir, 300, &theta);
    let mut rls = Rls::new(4, 2, RlsConfig::HIGH).unwrap();
    let mut traces = vec![rls.covariance_trace()];
    for w in &stream {
        rls.update(&w.a, &w.b).unwrap();
        traces.push(rls.covariance_trace());
    }
    // Unexcited directions grow by 1/λ per window: trace(P) ≈ 3 p₀ λ^(−k).
    for k in 2..traces.len() {
        assert!(traces[k] > traces[k - 1], "trace fell at window {k}");
    }
    let expected = 3.0 * 1e3 * 0.96f64.powi(-300);
    assert!(
        (traces[300] / expected - 1.0).abs() < 1e-6,
        "{} vs {expected}",
        traces[300]
    );
    assert!(traces[300] > 1e5 * traces[0]);

    // Without bound: with stronger forgetting P overflows, and the update is then refused
    // with the state kept.
    let mut fast = Rls::new(2, 2, RlsConfig::default().with_lambda(0.5)).unwrap();
    let stream = one_direction_windows(&[1.0, 0.0], 1100, &[1.0, 2.0]);
    let mut refused = None;
    for (k, w) in stream.iter().enumerate() {
        let before = (fast.estimate().to_vec(), fast.covariance().to_vec());
        match fast.update(&w.a, &w.b) {
            Ok(_) => {}
            Err(e) => {
                assert_eq!(e, EstimatorError::Diverged);
                assert_eq!(
                    (fast.estimate().to_vec(), fast.covariance().to_vec()),
                    before
                );
                refused = Some(k);
                break;
            }
        }
    }
    // p₀ 2^k exceeds f64::MAX (≈ 2^1024) near k = 1014.
    let k = refused.expect("the covariance should overflow");
    assert!((1000..1030).contains(&k), "overflow at window {k}");
    assert!(fast.covariance_trace().is_finite());
}

#[test]
fn trace_guard_bounds_the_covariance() {
    let dir = [1.0, 1.0, 0.0, 0.0];
    let theta = [0.5, 0.25, -1.0, 2.0];
    let bound = 4.0 * 1e3;
    let cfg = RlsConfig::HIGH.with_windup_guard(WindupGuard::MaxTrace(bound));
    for backend in BACKENDS {
        let mut rls = Rls::new(4, 2, cfg.with_backend(backend)).unwrap();
        for w in &one_direction_windows(&dir, 2000, &theta) {
            rls.update(&w.a, &w.b).unwrap();
            assert!(rls.covariance_trace() <= bound * (1.0 + 1e-12));
        }
        // Still learns the excited combination θ₀ + θ₁ = 0.75.
        let est = rls.estimate();
        assert!((est[0] + est[1] - 0.75).abs() < 1e-6, "{est:?}");
        // The guarded covariance stays symmetric positive definite (Cholesky succeeds).
        let p = nalgebra::DMatrix::from_row_slice(4, 4, rls.covariance());
        assert_eq!(p, p.transpose());
        assert!(p.cholesky().is_some());
    }
    // The guard is off in the presets: the same stream winds up past the bound.
    let mut plain = Rls::rls_high(4, 2).unwrap();
    for w in &one_direction_windows(&dir, 50, &theta) {
        plain.update(&w.a, &w.b).unwrap();
    }
    assert!(plain.covariance_trace() > bound);
}
