//! The compact buffer (`compact_covariance_buffer_len`): the same bits as the full buffer on
//! every window the information-form fallback does not touch, a typed refusal that changes
//! nothing on the windows it would redo, and the sizes the constructors ask for.

mod common;

use common::*;
use tagk_baselines::{
    Backend, ConfigError, EstimatorError, KalmanConfig, KalmanFilter, OnlineEstimator, Rls,
    RlsConfig, WindupGuard, compact_covariance_buffer_len, covariance_buffer_len,
};

fn kf(n: usize, m: usize, cfg: KalmanConfig, len: usize) -> KalmanFilter<f64, Vec<f64>> {
    KalmanFilter::with_storage(n, m, cfg.with_backend(Backend::Loops), vec![0.0; len]).unwrap()
}

fn rls(n: usize, m: usize, cfg: RlsConfig, len: usize) -> Rls<f64, Vec<f64>> {
    Rls::with_storage(n, m, cfg.with_backend(Backend::Loops), vec![0.0; len]).unwrap()
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn sizes() {
    for (n, m) in [(1, 1), (10, 30), (120, 30)] {
        assert_eq!(
            covariance_buffer_len(n, m),
            2 * n * n + 4 * n + 2 * m * n + m * m + 3 * m
        );
        assert_eq!(
            compact_covariance_buffer_len(n, m),
            n * n + 3 * n + 2 * m * n + m * m + 3 * m
        );
    }
    // Table III's largest case: the compact buffer is n + m scalars above the former
    // tagk-mcu copy's n² + 2n + 2mn + m² + 2m.
    assert_eq!(compact_covariance_buffer_len(120, 30), 22_950);
    assert_eq!(covariance_buffer_len(120, 30), 37_470);
}

#[test]
fn the_buffer_length_selects_the_layout_and_short_buffers_are_typed_errors() {
    let (n, m) = (4, 3);
    let (full, compact) = (
        covariance_buffer_len(n, m),
        compact_covariance_buffer_len(n, m),
    );
    let loops = KalmanConfig::LOW.with_backend(Backend::Loops);
    for (len, fallback) in [
        (full + 5, true),
        (full, true),
        (full - 1, false),
        (compact, false),
    ] {
        let f = KalmanFilter::<f64, _>::with_storage(n, m, loops, vec![0.0; len]).unwrap();
        assert_eq!(f.has_information_fallback(), fallback, "{len}");
        let r = Rls::<f32, _>::with_storage(n, m, RlsConfig::LOW, vec![0.0; len]).unwrap();
        assert_eq!(r.has_information_fallback(), fallback, "{len}");
    }
    assert_eq!(
        KalmanFilter::<f64, _>::with_storage(n, m, loops, vec![0.0; compact - 1]).err(),
        Some(ConfigError::BufferTooSmall {
            needed: compact,
            found: compact - 1
        })
    );
    // The faer backend computes its posterior in the second copy of P: full buffer only.
    let faer = RlsConfig::LOW.with_backend(Backend::Faer);
    assert_eq!(
        Rls::<f64, _>::with_storage(n, m, faer, vec![0.0; full - 1]).err(),
        Some(ConfigError::BufferTooSmall {
            needed: full,
            found: full - 1
        })
    );
    assert!(
        KalmanFilter::new(n, m, KalmanConfig::LOW)
            .unwrap()
            .has_information_fallback()
    );
}

#[test]
fn compact_and_full_buffers_give_the_same_bits_on_ordinary_windows() {
    let (n, m) = (8, 5);
    let mut g = rng(21);
    let theta = random_vec(&mut g, n, 1.0);
    let stream = windows(&mut g, n, m, 40, &theta, 0.01, false);
    let (full, compact) = (
        covariance_buffer_len(n, m),
        compact_covariance_buffer_len(n, m),
    );
    let guard = RlsConfig::HIGH.with_windup_guard(WindupGuard::MaxTrace(1e3 * n as f64));
    for cfg in [RlsConfig::LOW, RlsConfig::HIGH, guard] {
        let (mut a, mut b) = (rls(n, m, cfg, full), rls(n, m, cfg, compact));
        for w in &stream {
            a.update(&w.a, &w.b).unwrap();
            b.update(&w.a, &w.b).unwrap();
            assert_eq!(bits(a.estimate()), bits(b.estimate()));
            assert_eq!(bits(a.covariance()), bits(b.covariance()));
        }
    }
    for cfg in [KalmanConfig::HIGH, KalmanConfig::LOW.with_sigma_r(1e-2)] {
        let (mut a, mut b) = (kf(n, m, cfg, full), kf(n, m, cfg, compact));
        for w in &stream {
            a.update(&w.a, &w.b).unwrap();
            b.update(&w.a, &w.b).unwrap();
            assert_eq!(bits(a.estimate()), bits(b.estimate()));
            assert_eq!(bits(a.covariance()), bits(b.covariance()));
        }
    }
}

#[test]
fn windows_the_fallback_would_redo_are_refused_and_change_nothing() {
    // The two fallback cases of tests/kalman.rs: a singular innovation covariance (n = 1,
    // m = 2) and a covariance update that cancels (n = 1, m = 1), after one ordinary window.
    let cases: [(usize, &[f64], &[f64]); 2] = [
        (2, &[-732.3426145117926, 903.542071796805], &[1.5, -2.0]),
        (1, &[-751.6620697903775], &[0.25]),
    ];
    for (m, a, b) in cases {
        let (full, compact) = (
            covariance_buffer_len(1, m),
            compact_covariance_buffer_len(1, m),
        );
        let mut with = kf(1, m, KalmanConfig::LOW, full);
        let mut without = kf(1, m, KalmanConfig::LOW, compact);
        let warm = vec![1e-4; m];
        with.update(&warm, &vec![0.1; m]).unwrap();
        without.update(&warm, &vec![0.1; m]).unwrap();
        let (theta, p) = (bits(without.estimate()), bits(without.covariance()));
        assert_eq!(bits(with.estimate()), theta);
        with.update(a, b).unwrap();
        assert!(matches!(
            without.update(a, b),
            Err(EstimatorError::NumericalFailure(_))
        ));
        assert_eq!(bits(without.estimate()), theta);
        assert_eq!(bits(without.covariance()), p);
        // It carries on from the kept state like a filter that never saw the window.
        let mut fresh = kf(1, m, KalmanConfig::LOW, compact);
        fresh.update(&warm, &vec![0.1; m]).unwrap();
        let small = vec![1e-4; m];
        fresh.update(&small, &vec![0.2; m]).unwrap();
        without.update(&small, &vec![0.2; m]).unwrap();
        assert_eq!(bits(without.estimate()), bits(fresh.estimate()));
        assert_eq!(bits(without.covariance()), bits(fresh.covariance()));
    }
}
