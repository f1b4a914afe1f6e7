//! Invariants over random inputs: finite estimates, determinism, untouched state on error.

mod common;

use common::BACKENDS;
use common::filters::Filter;
use proptest::prelude::*;
use tagk_baselines::{KalmanConfig, KalmanFilter, Rls, RlsConfig, WindupGuard};

/// Windows of `n` columns: each `(a, b)` with `1..=m_max` rows, entries in `[-scale, scale]`.
fn arb_windows(
    n: usize,
    m_max: usize,
    scale: f64,
) -> impl Strategy<Value = Vec<(Vec<f64>, Vec<f64>)>> {
    prop::collection::vec(
        (1..=m_max).prop_flat_map(move |m| {
            (
                prop::collection::vec(-scale..=scale, m * n),
                prop::collection::vec(-scale..=scale, m),
            )
        }),
        1..8,
    )
}

fn make(kind: usize, backend: usize, n: usize, m_max: usize) -> Box<dyn Filter> {
    let backend = BACKENDS[backend];
    match kind {
        0 => Box::new(Rls::new(n, m_max, RlsConfig::LOW.with_backend(backend)).unwrap()),
        1 => Box::new(Rls::new(n, m_max, RlsConfig::HIGH.with_backend(backend)).unwrap()),
        2 => Box::new(
            Rls::new(
                n,
                m_max,
                RlsConfig::HIGH
                    .with_windup_guard(WindupGuard::MaxTrace(1e3 * n as f64))
                    .with_backend(backend),
            )
            .unwrap(),
        ),
        3 => {
            Box::new(KalmanFilter::new(n, m_max, KalmanConfig::LOW.with_backend(backend)).unwrap())
        }
        _ => {
            Box::new(KalmanFilter::new(n, m_max, KalmanConfig::HIGH.with_backend(backend)).unwrap())
        }
    }
}

/// A stream of windows `(a, b)`.
type Stream = Vec<(Vec<f64>, Vec<f64>)>;

/// `(filter kind, backend, n, m_max, windows)`.
fn scenario() -> impl Strategy<Value = (usize, usize, usize, usize, Stream)> {
    (0usize..5, 0usize..2, 1usize..=12, 1usize..=12).prop_flat_map(|(kind, backend, n, m_max)| {
        (
            Just(kind),
            Just(backend),
            Just(n),
            Just(m_max),
            arb_windows(n, m_max, 1e3),
        )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn estimates_stay_finite_on_sane_inputs((kind, backend, n, m_max, stream) in scenario()) {
        let mut f = make(kind, backend, n, m_max);
        for (a, b) in &stream {
            let before = f.snapshot();
            match f.update(a, b) {
                Ok(info) => prop_assert_eq!(info.rows, b.len()),
                Err(e) => {
                    // Only a window of zero rows may be refused (proptest rarely makes one).
                    prop_assert_eq!(e, tagk_baselines::EstimatorError::NoUsableRow, "{}", f.name());
                    prop_assert_eq!(f.snapshot(), before);
                }
            }
            prop_assert!(f.estimate().iter().all(|v| v.is_finite()), "{}", f.name());
            prop_assert!(f.cov().iter().all(|v| v.is_finite()), "{}", f.name());
            for k in 0..n {
                prop_assert!(f.cov()[k * n + k] > 0.0);
            }
        }
    }

    #[test]
    fn updates_are_deterministic((kind, backend, n, m_max, stream) in scenario()) {
        let mut f = make(kind, backend, n, m_max);
        let mut g = make(kind, backend, n, m_max);
        for (a, b) in &stream {
            let rf = f.update(a, b);
            let rg = g.update(a, b);
            prop_assert_eq!(rf, rg);
        }
        let (tf, pf) = f.snapshot();
        let (tg, pg) = g.snapshot();
        prop_assert!(tf.iter().zip(&tg).all(|(x, y)| x.to_bits() == y.to_bits()));
        prop_assert!(pf.iter().zip(&pg).all(|(x, y)| x.to_bits() == y.to_bits()));
    }

    #[test]
    fn a_corrupted_window_changes_nothing(
        (kind, backend, n, m_max, stream) in scenario(),
        pick in any::<prop::sample::Index>(),
        poison in prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY]),
        in_b in any::<bool>(),
    ) {
        let mut f = make(kind, backend, n, m_max);
        let (a0, b0) = &stream[0];
        let _ = f.update(a0, b0);
        let (mut a, mut b) = stream[stream.len() - 1].clone();
        if in_b {
            let i = pick.index(b.len());
            b[i] = poison;
        } else {
            let i = pick.index(a.len());
            a[i] = poison;
        }
        let before = f.snapshot();
        prop_assert!(f.update(&a, &b).is_err());
        prop_assert_eq!(f.snapshot(), before);
    }
}
