//! Property tests: finiteness, transactional errors, determinism.

use proptest::prelude::*;
use tagk_core::{
    GreedyKaczmarz, KaczmarzConfig, OnlineEstimator, RandomizedKaczmarz, TagK, TailAveragedKaczmarz,
};

const N: usize = 6;
const M: usize = 8;

fn window() -> impl Strategy<Value = (Vec<f64>, Vec<f64>)> {
    (1usize..=M).prop_flat_map(|m| {
        (
            prop::collection::vec(prop_oneof![Just(0.0), -1e3f64..1e3, -1e-3f64..1e-3], m * N),
            prop::collection::vec(-1e3f64..1e3, m),
        )
    })
}

fn all(seed: u64) -> Vec<Box<dyn OnlineEstimator<f64>>> {
    let c = KaczmarzConfig::default().with_seed(seed);
    vec![
        Box::new(RandomizedKaczmarz::<f64, Vec<f64>>::new(N, M, c).unwrap()),
        Box::new(TailAveragedKaczmarz::<f64, Vec<f64>>::new(N, M, c).unwrap()),
        Box::new(GreedyKaczmarz::<f64, Vec<f64>>::new(N, M, c).unwrap()),
        Box::new(TagK::<f64, Vec<f64>>::new(N, M, c).unwrap()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn estimates_stay_finite(windows in prop::collection::vec(window(), 1..12), seed in any::<u64>()) {
        for mut est in all(seed) {
            for (a, b) in &windows {
                let _ = est.update(a, b);
                prop_assert!(est.estimate().iter().all(|v| v.is_finite()), "{}", est.name());
            }
        }
    }

    #[test]
    fn a_rejected_window_changes_nothing(
        windows in prop::collection::vec(window(), 1..6),
        bad_index in any::<prop::sample::Index>(),
        bad_value in prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)],
        seed in any::<u64>(),
    ) {
        for (mut est, mut twin) in all(seed).into_iter().zip(all(seed)) {
            let (a0, b0) = &windows[0];
            let _ = est.update(a0, b0);
            let _ = twin.update(a0, b0);
            let mut bad = a0.clone();
            let k = bad_index.index(bad.len());
            bad[k] = bad_value;
            let before = est.estimate().to_vec();
            prop_assert!(est.update(&bad, b0).is_err());
            prop_assert_eq!(est.estimate(), &before[..]);
            // The random generator was not advanced either: est and twin stay in lockstep.
            for (a, b) in &windows[1..] {
                let r1 = est.update(a, b);
                let r2 = twin.update(a, b);
                prop_assert_eq!(r1, r2);
                prop_assert_eq!(est.estimate(), twin.estimate());
            }
        }
    }

    #[test]
    fn same_seed_same_bits(windows in prop::collection::vec(window(), 1..8), seed in any::<u64>()) {
        for (mut e1, mut e2) in all(seed).into_iter().zip(all(seed)) {
            for (a, b) in &windows {
                let _ = e1.update(a, b);
                let _ = e2.update(a, b);
            }
            let bits1: Vec<u64> = e1.estimate().iter().map(|v| v.to_bits()).collect();
            let bits2: Vec<u64> = e2.estimate().iter().map(|v| v.to_bits()).collect();
            prop_assert_eq!(bits1, bits2);
            // And reset re-seeds: replaying after a reset reproduces the same result.
            let end = e1.estimate().to_vec();
            e1.reset(&[0.0; N]).unwrap();
            for (a, b) in &windows {
                let _ = e1.update(a, b);
            }
            prop_assert_eq!(e1.estimate(), &end[..]);
        }
    }
}
