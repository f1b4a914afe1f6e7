//! Bad input: the right typed error, and the estimate and covariance left exactly as they were.

mod common;

use common::filters::{Filter, all_filters};
use common::*;
use tagk_baselines::{
    ConfigError, EstimatorError, KalmanConfig, KalmanFilter, OnlineEstimator, Rls, RlsConfig,
    WindupGuard,
};

const N: usize = 4;
const M: usize = 5;

/// Every filter, warmed up on a few good windows so that θ ≠ 0 and P ≠ p₀ I.
fn warmed_up() -> Vec<Box<dyn Filter>> {
    let mut g = rng(5);
    let theta = random_vec(&mut g, N, 1.0);
    let warm = windows(&mut g, N, M, 4, &theta, 0.01, true);
    let mut filters = all_filters(N, M);
    for f in filters.iter_mut() {
        for w in &warm {
            f.update(&w.a, &w.b).unwrap();
        }
    }
    filters
}

fn assert_refused(a: &[f64], b: &[f64], expected: EstimatorError) {
    for mut f in warmed_up() {
        let before = f.snapshot();
        let got = f.update(a, b);
        assert_eq!(got, Err(expected), "{}", f.name());
        // Bit-for-bit the same state.
        let after = f.snapshot();
        assert!(
            before
                .0
                .iter()
                .zip(&after.0)
                .all(|(x, y)| x.to_bits() == y.to_bits())
                && before
                    .1
                    .iter()
                    .zip(&after.1)
                    .all(|(x, y)| x.to_bits() == y.to_bits()),
            "{}: state changed after {expected:?}",
            f.name()
        );
    }
}

fn good_window(m: usize) -> (Vec<f64>, Vec<f64>) {
    let a: Vec<f64> = (0..m * N)
        .map(|k| ((k * 7 % 5) as f64 - 2.0) * 0.3 + 0.1)
        .collect();
    let b: Vec<f64> = (0..m).map(|i| i as f64 * 0.1 - 0.2).collect();
    (a, b)
}

#[test]
fn nan_or_infinite_regressor() {
    let (mut a, b) = good_window(3);
    a[2 * N + 1] = f64::NAN;
    assert_refused(
        &a,
        &b,
        EstimatorError::NonFiniteRegressor { row: 2, col: 1 },
    );
    a[2 * N + 1] = 0.0;
    a[N + 3] = f64::NEG_INFINITY;
    assert_refused(
        &a,
        &b,
        EstimatorError::NonFiniteRegressor { row: 1, col: 3 },
    );
}

#[test]
fn nan_or_infinite_measurement() {
    let (a, mut b) = good_window(3);
    b[1] = f64::NAN;
    assert_refused(&a, &b, EstimatorError::NonFiniteMeasurement { row: 1 });
    b[1] = f64::INFINITY;
    assert_refused(&a, &b, EstimatorError::NonFiniteMeasurement { row: 1 });
}

#[test]
fn wrong_shape() {
    let (a, b) = good_window(3);
    assert_refused(
        &a[..3 * N - 1],
        &b,
        EstimatorError::ShapeMismatch {
            expected: 3 * N,
            found: 3 * N - 1,
            rows: 3,
            cols: N,
        },
    );
    assert_refused(
        &a,
        &b[..2],
        EstimatorError::ShapeMismatch {
            expected: 2 * N,
            found: 3 * N,
            rows: 2,
            cols: N,
        },
    );
}

#[test]
fn too_many_rows() {
    let (a, b) = good_window(M + 1);
    assert_refused(
        &a,
        &b,
        EstimatorError::WindowTooLarge {
            rows: M + 1,
            capacity: M,
        },
    );
}

#[test]
fn empty_window() {
    assert_refused(&[], &[], EstimatorError::EmptyWindow);
}

#[test]
fn all_zero_rows() {
    assert_refused(&[0.0; 2 * N], &[1.0, -1.0], EstimatorError::NoUsableRow);
}

#[test]
fn overflowing_residual_is_refused() {
    // Finite entries whose residual b − A θ overflows.
    let a = [1e300, 1e300, 1e300, 1e300];
    assert_refused(&a, &[-1e300], EstimatorError::Diverged);
}

#[test]
fn failed_cholesky_is_a_numerical_failure_and_keeps_the_state() {
    // P₀ = 1e300·I is a valid prior; a window with entries 1e10 makes A P Aᵀ overflow, so the
    // innovation covariance cannot be factorised.
    for backend in BACKENDS {
        let mut rls = Rls::new(
            2,
            2,
            RlsConfig::default().with_p0(1e300).with_backend(backend),
        )
        .unwrap();
        let mut kf = KalmanFilter::new(
            2,
            2,
            KalmanConfig::HIGH.with_p0(1e300).with_backend(backend),
        )
        .unwrap();
        let filters: [&mut dyn Filter; 2] = [&mut rls, &mut kf];
        for f in filters {
            f.reset(&[0.5, -0.5]).unwrap();
            let before = f.snapshot();
            let got = f.update(&[1e10, 1e10], &[1.0]);
            assert!(
                matches!(got, Err(EstimatorError::NumericalFailure(_))),
                "{}: {got:?}",
                f.name()
            );
            assert_eq!(f.snapshot(), before);
            // And the filter still works afterwards.
            f.update(&[1.0, 0.0], &[1.0]).unwrap();
        }
    }
}

#[test]
fn refused_windows_leave_no_trace_in_later_updates() {
    let mut g = rng(17);
    let theta = random_vec(&mut g, N, 1.0);
    let stream = windows(&mut g, N, M, 12, &theta, 0.05, false);
    let mut clean = all_filters(N, M);
    let mut noisy = all_filters(N, M);
    let (bad_a, mut bad_b) = good_window(2);
    bad_b[0] = f64::NAN;
    for w in &stream {
        for (c, d) in clean.iter_mut().zip(noisy.iter_mut()) {
            assert!(d.update(&bad_a, &bad_b).is_err());
            assert!(d.update(&[0.0; N], &[3.0]).is_err());
            c.update(&w.a, &w.b).unwrap();
            d.update(&w.a, &w.b).unwrap();
            assert_eq!(c.snapshot(), d.snapshot(), "{}", c.name());
        }
    }
}

#[test]
fn reset_validates_and_restores_the_prior() {
    for mut f in warmed_up() {
        let before = f.snapshot();
        assert_eq!(
            f.reset(&[1.0; N + 1]),
            Err(EstimatorError::DimensionMismatch {
                expected: N,
                found: N + 1
            })
        );
        assert_eq!(
            f.reset(&[0.0, f64::NAN, 0.0, 0.0]),
            Err(EstimatorError::NonFiniteEstimate { index: 1 })
        );
        assert_eq!(f.snapshot(), before);
        f.reset(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(f.estimate(), &[1.0, 2.0, 3.0, 4.0]);
        let p = f.cov();
        for i in 0..N {
            for j in 0..N {
                assert_eq!(p[i * N + j], if i == j { 1e3 } else { 0.0 });
            }
        }
    }
}

fn invalid(name: &'static str) -> impl Fn(ConfigError) -> bool {
    move |e| matches!(e, ConfigError::InvalidParameter { name: got, .. } if got == name)
}

#[test]
fn configurations_are_validated() {
    assert_eq!(
        Rls::new(0, 3, RlsConfig::LOW).err(),
        Some(ConfigError::ZeroDimension)
    );
    assert_eq!(Rls::rls_low(3, 0).err(), Some(ConfigError::ZeroCapacity));
    assert_eq!(
        KalmanFilter::kf_high(0, 3).err(),
        Some(ConfigError::ZeroDimension)
    );
    assert_eq!(
        KalmanFilter::kf_low(3, 0).err(),
        Some(ConfigError::ZeroCapacity)
    );
    for lambda in [0.0, -0.5, 1.0 + 1e-12, f64::NAN, f64::INFINITY] {
        let e = Rls::new(3, 3, RlsConfig::LOW.with_lambda(lambda))
            .err()
            .unwrap();
        assert!(invalid("lambda")(e), "{lambda}: {e:?}");
    }
    for p0 in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(invalid("p0")(
            Rls::new(3, 3, RlsConfig::LOW.with_p0(p0)).err().unwrap()
        ));
        assert!(invalid("p0")(
            KalmanFilter::new(3, 3, KalmanConfig::LOW.with_p0(p0))
                .err()
                .unwrap()
        ));
    }
    for t in [0.0, -1.0, f64::NAN] {
        let cfg = RlsConfig::LOW.with_windup_guard(WindupGuard::MaxTrace(t));
        assert!(invalid("max_trace")(Rls::new(3, 3, cfg).err().unwrap()));
    }
    for q in [-1e-3, f64::NAN, f64::INFINITY, 1e200] {
        let e = KalmanFilter::new(3, 3, KalmanConfig::LOW.with_sigma_q(q))
            .err()
            .unwrap();
        assert!(invalid("sigma_q")(e), "{q}: {e:?}");
    }
    for r in [0.0, -1e-3, f64::NAN, f64::INFINITY, 1e200, 1e-200] {
        let e = KalmanFilter::new(3, 3, KalmanConfig::LOW.with_sigma_r(r))
            .err()
            .unwrap();
        assert!(invalid("sigma_r")(e), "{r}: {e:?}");
    }
    // The edges that are valid.
    assert!(Rls::new(3, 3, RlsConfig::LOW.with_lambda(1.0)).is_ok());
    assert!(KalmanFilter::new(3, 3, KalmanConfig::LOW.with_sigma_q(0.0)).is_ok());
}
