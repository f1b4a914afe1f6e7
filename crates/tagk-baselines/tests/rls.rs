//! RLS against independent batch least-squares solutions.

mod common;

use common::*;
use tagk_baselines::{OnlineEstimator, Rls, RlsConfig};

fn check_against_batch(n: usize, m_max: usize, lambda: f64, backend: tagk_baselines::Backend, seed: u64) {
    let mut g = rng(seed);
    let theta_true = random_vec(&mut g, n, 2.0);
    let theta0 = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, m_max, 25, &theta_true, 0.1, false);
    let p0 = 10.0;
    let cfg = RlsConfig::default().with_lambda(lambda).with_p0(p0).with_backend(backend);
    let mut rls = Rls::new(n, m_max, cfg).unwrap();
    rls.reset(&theta0).unwrap();
    for (k, w) in stream.iter().enumerate() {
        rls.update(&w.a, &w.b).unwrap();
        if k % 6 == 5 || k + 1 == stream.len() {
            let (theta, cov) = weighted_batch_ls(n, &stream[..=k], lambda, p0, &theta0);
            let e = rel_err(rls.estimate(), &theta);
            assert!(e < 1e-9, "n={n} λ={lambda} {backend:?} window {k}: θ error {e:e}");
            let c = rel_err(rls.covariance(), cov.transpose().as_slice());
            assert!(c < 1e-9, "n={n} λ={lambda} {backend:?} window {k}: P error {c:e}");
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
