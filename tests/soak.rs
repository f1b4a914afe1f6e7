//! The soak example (`examples/soak.rs`) shortened: every estimator over a few payload steps
//! with outliers and rank-deficient stretches stays finite, keeps a bounded covariance and
//! comes back within tolerance after each step.

#[allow(dead_code)]
#[path = "../examples/soak.rs"]
mod soak;

use soak::{CYCLE, soak, soak_with_progress, subjects};

#[test]
fn every_estimator_survives_a_short_soak() {
    // Four payload steps (attach, drop, attach, drop) and four rank-deficient stretches.
    let updates = 4 * CYCLE + CYCLE / 2;
    for (name, mut subject) in subjects(11) {
        let r = soak(&mut subject, updates, 11);
        assert_eq!(r.non_finite, 0, "{name}: {r:?}");
        assert_eq!(r.steps, 4, "{name}: {r:?}");
        if let Some(tr) = r.max_trace {
            assert!(tr.is_finite() && tr <= 1e4 * 1.000_001, "{name}: {r:?}");
        }
        assert_eq!(r.recovered, r.steps, "{name}: {r:?}");
    }
}

/// Without the guard, RLS-high's covariance winds up over a long rank-deficient stretch; the
/// guard holds its trace at `p₀ n` (it shrinks `P` uniformly, so the excited directions learn
/// more slowly too: the example prints the cost).
#[test]
fn the_windup_guard_bounds_the_covariance_of_rls_high() {
    let mut by_name = subjects(3);
    let mut trace_of = |name: &str| {
        let (_, subject) = by_name.iter_mut().find(|(n, _)| n == name).unwrap();
        soak::windup(subject, 600, 3).0
    };
    let free = trace_of("RLS-high");
    let guarded = trace_of("RLS-high+guard");
    assert!(free > 1e6, "{free:e}");
    assert!(guarded <= 1e4 * (1.0 + 1e-9), "{guarded:e}");
}

/// The progress callback counts every update once, and the soak's result is the same with it.
#[test]
fn the_soak_progress_counts_every_update() {
    for updates in [1, 1024, 2500] {
        let (_, mut plain) = subjects(5).swap_remove(0);
        let (_, mut observed) = subjects(5).swap_remove(0);
        let mut counted = 0;
        let r = soak_with_progress(&mut observed, updates, 5, |n| counted += n);
        assert_eq!(counted, updates);
        assert_eq!(r, soak(&mut plain, updates, 5));
    }
}
