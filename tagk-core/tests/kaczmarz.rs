//! Behavioural tests of the Kaczmarz family against independent computations.

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use tagk_core::{
    BurnIn, EstimatorError, GreedyKaczmarz, Iterations, KaczmarzConfig, OnlineEstimator,
    RandomizedKaczmarz, TagK, TailAveragedKaczmarz,
};

type Heap = Vec<f64>;

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The kernel's draws: one 32-bit word each.
fn draw(rng: &mut ChaCha8Rng) -> f64 {
    f64::from(rng.next_u32()) * (1.0 / (1u64 << 32) as f64)
}

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let u1 = uniform(rng).max(1e-300);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn random_matrix(rng: &mut ChaCha8Rng, m: usize, n: usize) -> Vec<f64> {
    (0..m * n).map(|_| gauss(rng)).collect()
}

fn mat_vec(a: &[f64], x: &[f64]) -> Vec<f64> {
    a.chunks(x.len())
        .map(|row| row.iter().zip(x).map(|(p, q)| p * q).sum())
        .collect()
}

fn dist(x: &[f64], y: &[f64]) -> f64 {
    x.iter()
        .zip(y)
        .map(|(p, q)| (p - q).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Least-squares solution by the normal equations with Gaussian elimination (independent of
/// the crate's code); fine for the small, well-conditioned systems used here.
fn least_squares(a: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let m = b.len();
    let mut g = vec![0.0; n * (n + 1)];
    for i in 0..n {
        for j in 0..n {
            g[i * (n + 1) + j] = (0..m).map(|k| a[k * n + i] * a[k * n + j]).sum();
        }
        g[i * (n + 1) + n] = (0..m).map(|k| a[k * n + i] * b[k]).sum();
    }
    for c in 0..n {
        let p = (c..n)
            .max_by(|&x, &y| {
                g[x * (n + 1) + c]
                    .abs()
                    .total_cmp(&g[y * (n + 1) + c].abs())
            })
            .unwrap();
        for k in 0..=n {
            g.swap(c * (n + 1) + k, p * (n + 1) + k);
        }
        for r in 0..n {
            if r != c {
                let f = g[r * (n + 1) + c] / g[c * (n + 1) + c];
                for k in 0..=n {
                    g[r * (n + 1) + k] -= f * g[c * (n + 1) + k];
                }
            }
        }
    }
    (0..n)
        .map(|i| g[i * (n + 1) + n] / g[i * (n + 1) + i])
        .collect()
}

/// A straightforward reference: explicit iterate, full residual recomputed every iteration,
/// explicit running sum of the tail iterates. Draws random numbers exactly like the kernel.
#[allow(clippy::too_many_arguments)]
fn reference(
    greedy: bool,
    average: bool,
    a: &[f64],
    b: &[f64],
    n: usize,
    x0: &[f64],
    t: usize,
    t_b: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let m = b.len();
    let norms: Vec<f64> = a.chunks(n).map(|r| r.iter().map(|v| v * v).sum()).collect();
    let fro2: f64 = norms.iter().sum();
    let mut x = x0.to_vec();
    let mut sum = vec![0.0; n];
    for s in 1..=t {
        let r: Vec<f64> = (0..m)
            .map(|i| {
                b[i] - a[i * n..(i + 1) * n]
                    .iter()
                    .zip(&x)
                    .map(|(p, q)| p * q)
                    .sum::<f64>()
            })
            .collect();
        let i = if greedy {
            let rn2: f64 = r.iter().map(|v| v * v).sum();
            let maxr = (0..m).map(|i| r[i] * r[i] / norms[i]).fold(0.0, f64::max);
            let eps = 0.5 * (maxr / rn2 + 1.0 / fro2);
            let w: Vec<f64> = (0..m)
                .map(|i| {
                    if r[i] * r[i] >= eps * rn2 * norms[i] {
                        r[i] * r[i]
                    } else {
                        0.0
                    }
                })
                .collect();
            let total: f64 = w.iter().sum();
            let target = draw(rng) * total;
            // The kernel's sampling order: lane-major over chunks of eight rows
            // (rows 0, 8, 16, …, then 1, 9, 17, …).
            let order = (0..8).flat_map(|l| (0..m.div_ceil(8)).map(move |c| 8 * c + l));
            let mut acc = 0.0;
            let mut pick = m - 1;
            for k in order.filter(|&k| k < m) {
                acc += w[k];
                if acc > target && w[k] > 0.0 {
                    pick = k;
                    break;
                }
            }
            pick
        } else {
            let target = draw(rng) * fro2;
            let mut acc = 0.0;
            let mut pick = m - 1;
            for (k, nk) in norms.iter().enumerate() {
                acc += nk;
                if acc > target {
                    pick = k;
                    break;
                }
            }
            pick
        };
        let alpha = r[i] / norms[i];
        for k in 0..n {
            x[k] += alpha * a[i * n + k];
        }
        if s > t_b {
            for k in 0..n {
                sum[k] += x[k];
            }
        }
    }
    if average {
        sum.iter().map(|v| v / (t - t_b) as f64).collect()
    } else {
        x
    }
}

fn config(seed: u64, t: usize, t_b: usize) -> KaczmarzConfig {
    KaczmarzConfig::default()
        .with_seed(seed)
        .with_iterations(Iterations::Fixed(t))
        .with_burn_in(BurnIn::Fixed(t_b))
}

#[test]
fn every_variant_matches_the_naive_reference() {
    let (m, n, t, t_b) = (30, 10, 30, 12);
    for seed in 0..20u64 {
        let mut data = ChaCha8Rng::seed_from_u64(1000 + seed);
        let a = random_matrix(&mut data, m, n);
        let b: Vec<f64> = (0..m).map(|_| gauss(&mut data)).collect(); // inconsistent
        let x0: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
        let cfg = config(seed, t, t_b);
        let check = |greedy: bool, average: bool, est: &mut dyn OnlineEstimator<f64>| {
            est.reset(&x0).unwrap();
            est.update(&a, &b).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let want = reference(greedy, average, &a, &b, n, &x0, t, t_b, &mut rng);
            let err = dist(est.estimate(), &want);
            assert!(
                err < 1e-9 * (1.0 + dist(&want, &vec![0.0; n])),
                "{}: {err}",
                est.name()
            );
        };
        check(
            false,
            false,
            &mut RandomizedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap(),
        );
        check(
            false,
            true,
            &mut TailAveragedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap(),
        );
        check(
            true,
            false,
            &mut GreedyKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap(),
        );
        check(true, true, &mut TagK::<f64, Heap>::new(n, m, cfg).unwrap());
    }
}

#[test]
fn every_variant_converges_on_consistent_overdetermined_systems() {
    let (m, n) = (30, 10);
    for seed in 0..5u64 {
        let mut data = ChaCha8Rng::seed_from_u64(seed);
        let theta: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
        let a = random_matrix(&mut data, m, n);
        let b = mat_vec(&a, &theta);
        let cfg = KaczmarzConfig::default().with_seed(seed);
        let mut ests: Vec<Box<dyn OnlineEstimator<f64>>> = vec![
            Box::new(RandomizedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap()),
            Box::new(TailAveragedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap()),
            Box::new(GreedyKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap()),
            Box::new(TagK::<f64, Heap>::new(n, m, cfg).unwrap()),
        ];
        for est in &mut ests {
            for _ in 0..400 {
                est.update(&a, &b).unwrap();
            }
            let err = dist(est.estimate(), &theta);
            assert!(err < 1e-8, "{} did not converge: error {err}", est.name());
        }
    }
}

#[test]
fn greedy_needs_fewer_projections_than_randomized() {
    let (m, n) = (30, 10);
    let (mut total_rk, mut total_grk) = (0usize, 0usize);
    for seed in 0..200u64 {
        let mut data = ChaCha8Rng::seed_from_u64(7_000 + seed);
        let theta: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
        // Rows of unequal scale, as in real regressors.
        let mut a = random_matrix(&mut data, m, n);
        for (i, v) in a.iter_mut().enumerate() {
            *v *= 1.0 + ((i / n) % 5) as f64;
        }
        let b = mat_vec(&a, &theta);
        let bn = b.iter().map(|v| v * v).sum::<f64>().sqrt();
        let cfg = KaczmarzConfig::default()
            .with_seed(seed)
            .with_iterations(Iterations::Fixed(100_000))
            .with_tolerance(1e-6 * bn);
        let mut rk = RandomizedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap();
        let mut grk = GreedyKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap();
        let i_rk = rk.update(&a, &b).unwrap();
        let i_grk = grk.update(&a, &b).unwrap();
        assert!(i_rk.converged && i_grk.converged);
        total_rk += i_rk.iterations;
        total_grk += i_grk.iterations;
    }
    let (mean_rk, mean_grk) = (total_rk as f64 / 200.0, total_grk as f64 / 200.0);
    assert!(
        mean_grk < 0.8 * mean_rk,
        "GRK mean projections {mean_grk} not clearly below RK's {mean_rk}"
    );
}

/// On a noisy, inconsistent system the iterates wander around the least-squares solution;
/// tail averaging shrinks that spread. Measured as the mean squared distance to the
/// least-squares solution across seeds.
#[test]
fn tail_averaging_lowers_the_spread_on_inconsistent_systems() {
    let (m, n, t, t_b) = (30, 10, 300, 150);
    let mut data = ChaCha8Rng::seed_from_u64(42);
    let theta: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
    let a = random_matrix(&mut data, m, n);
    let b: Vec<f64> = mat_vec(&a, &theta)
        .iter()
        .map(|v| v + 0.3 * gauss(&mut data))
        .collect();
    let x_ls = least_squares(&a, &b, n);
    let mse = |make: &dyn Fn(u64) -> Box<dyn OnlineEstimator<f64>>| -> f64 {
        (0..200u64)
            .map(|seed| {
                let mut est = make(seed);
                est.reset(&theta).unwrap(); // start near the answer; measure the spread only
                est.update(&a, &b).unwrap();
                dist(est.estimate(), &x_ls).powi(2)
            })
            .sum::<f64>()
            / 200.0
    };
    let cfg = |s| config(s, t, t_b);
    let rk = mse(&|s| Box::new(RandomizedKaczmarz::<f64, Heap>::new(n, m, cfg(s)).unwrap()));
    let tark = mse(&|s| Box::new(TailAveragedKaczmarz::<f64, Heap>::new(n, m, cfg(s)).unwrap()));
    let grk = mse(&|s| Box::new(GreedyKaczmarz::<f64, Heap>::new(n, m, cfg(s)).unwrap()));
    let tagk = mse(&|s| Box::new(TagK::<f64, Heap>::new(n, m, cfg(s)).unwrap()));
    assert!(tark < 0.5 * rk, "TARK {tark} vs RK {rk}");
    assert!(tagk < 0.5 * grk, "TAG-K {tagk} vs GRK {grk}");
    // Not asserted, reported: greedy selection keeps returning to the noisiest rows, so GRK's
    // spread exceeds RK's and TAG-K's averaged spread is only comparable to plain RK's.
    println!(
        "mean squared distance to the LS solution: RK {rk:.4} TARK {tark:.4} GRK {grk:.4} TAG-K {tagk:.4}"
    );
}

/// A stream of fresh windows whose true parameters jump: TAG-K tracks the jump faster than TARK.
#[test]
fn tagk_recovers_from_a_step_change_faster_than_tark() {
    let (m, n) = (30, 10);
    let seeds = 100u64;
    let horizon = 6;
    let mut err_tagk = vec![0.0; horizon];
    let mut err_tark = vec![0.0; horizon];
    for seed in 0..seeds {
        let mut data = ChaCha8Rng::seed_from_u64(90_000 + seed);
        let before: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
        let after: Vec<f64> = before.iter().map(|v| v + 2.0 * gauss(&mut data)).collect();
        let windows: Vec<(Vec<f64>, Vec<f64>)> = (0..20 + horizon)
            .map(|k| {
                let a = random_matrix(&mut data, m, n);
                let theta = if k < 20 { &before } else { &after };
                let b = mat_vec(&a, theta)
                    .iter()
                    .map(|v| v + 0.01 * gauss(&mut data))
                    .collect();
                (a, b)
            })
            .collect();
        let cfg = KaczmarzConfig::default().with_seed(seed);
        let mut tagk = TagK::<f64, Heap>::new(n, m, cfg).unwrap();
        let mut tark = TailAveragedKaczmarz::<f64, Heap>::new(n, m, cfg).unwrap();
        for (k, (a, b)) in windows.iter().enumerate() {
            tagk.update(a, b).unwrap();
            tark.update(a, b).unwrap();
            if k >= 20 {
                err_tagk[k - 20] += dist(tagk.estimate(), &after) / seeds as f64;
                err_tark[k - 20] += dist(tark.estimate(), &after) / seeds as f64;
            }
        }
    }
    for k in 0..horizon {
        assert!(
            err_tagk[k] < err_tark[k],
            "window {k} after the step: TAG-K {} vs TARK {}",
            err_tagk[k],
            err_tark[k]
        );
    }
    // And TAG-K has essentially recovered within a few windows.
    let initial = err_tagk[0];
    assert!(err_tagk[horizon - 1] < 0.05 * initial.max(1.0));
}

#[test]
fn zero_rows_are_skipped_and_all_zero_windows_rejected() {
    let (m, n) = (6, 2);
    let theta = [1.5, -0.5];
    let mut a = vec![0.0; m * n];
    a[2] = 1.0; // row 1 = e1
    a[6] = 1.0; // row 3 = e1 + e2
    a[7] = 1.0;
    a[11] = 2.0; // row 5 = 2 e2
    let mut b = mat_vec(&a, &theta);
    b[0] = 5.0; // a zero row with a non-zero measurement: unexplainable, ignored
    let mut est = TagK::<f64, Heap>::new(n, m, KaczmarzConfig::default()).unwrap();
    for _ in 0..100 {
        est.update(&a, &b).unwrap();
    }
    assert!(dist(est.estimate(), &theta) < 1e-10);
    let zero = vec![0.0; m * n];
    let before = est.estimate().to_vec();
    assert_eq!(est.update(&zero, &b), Err(EstimatorError::NoUsableRow));
    assert_eq!(est.estimate(), &before[..]);
}

#[test]
fn bad_windows_give_typed_errors_and_keep_the_estimate() {
    let (m, n) = (4, 3);
    let mut est = TagK::<f64, Heap>::new(n, m, KaczmarzConfig::default()).unwrap();
    est.reset(&[0.1, 0.2, 0.3]).unwrap();
    let before = est.estimate().to_vec();
    let a = vec![1.0; m * n];
    let b = vec![1.0; m];
    let mut bad_a = a.clone();
    bad_a[5] = f64::NAN;
    let mut bad_b = b.clone();
    bad_b[2] = f64::INFINITY;
    let huge = vec![1e300; m * n];
    assert_eq!(
        est.update(&bad_a, &b),
        Err(EstimatorError::NonFiniteRegressor { row: 1, col: 2 })
    );
    assert_eq!(
        est.update(&a, &bad_b),
        Err(EstimatorError::NonFiniteMeasurement { row: 2 })
    );
    assert_eq!(
        est.update(&a[..5], &b[..2]).unwrap_err(),
        EstimatorError::ShapeMismatch {
            expected: 6,
            found: 5,
            rows: 2,
            cols: 3
        }
    );
    assert_eq!(est.update(&[], &[]), Err(EstimatorError::EmptyWindow));
    assert_eq!(
        est.update(&vec![1.0; 5 * n], &[1.0; 5]),
        Err(EstimatorError::WindowTooLarge {
            rows: 5,
            capacity: 4
        })
    );
    assert!(matches!(
        est.update(&huge, &b),
        Err(EstimatorError::NonFiniteRegressor { .. })
    ));
    assert_eq!(
        est.reset(&[1.0]),
        Err(EstimatorError::DimensionMismatch {
            expected: 3,
            found: 1
        })
    );
    assert_eq!(
        est.reset(&[1.0, f64::NAN, 0.0]),
        Err(EstimatorError::NonFiniteEstimate { index: 1 })
    );
    assert_eq!(est.estimate(), &before[..]);
    // And a good window after all that still works from the same state as a fresh estimator.
    let mut fresh = TagK::<f64, Heap>::new(n, m, KaczmarzConfig::default()).unwrap();
    fresh.reset(&before).unwrap();
    est.update(&a, &b).unwrap();
    fresh.update(&a, &b).unwrap();
    assert_eq!(est.estimate(), fresh.estimate());
}

#[test]
fn configuration_is_validated() {
    use tagk_core::ConfigError;
    let d = KaczmarzConfig::default();
    assert_eq!(
        TagK::<f64, Heap>::new(0, 3, d).err(),
        Some(ConfigError::ZeroDimension)
    );
    assert_eq!(
        TagK::<f64, Heap>::new(3, 0, d).err(),
        Some(ConfigError::ZeroCapacity)
    );
    let c = d.with_iterations(Iterations::Fixed(0));
    assert_eq!(
        TagK::<f64, Heap>::new(3, 3, c).err(),
        Some(ConfigError::ZeroIterations)
    );
    let c = d
        .with_iterations(Iterations::Fixed(5))
        .with_burn_in(BurnIn::Fixed(5));
    assert!(matches!(
        TagK::<f64, Heap>::new(3, 3, c),
        Err(ConfigError::BurnInTooLarge { .. })
    ));
    let c = d.with_burn_in(BurnIn::Fraction(1.0));
    assert!(matches!(
        TagK::<f64, Heap>::new(3, 3, c),
        Err(ConfigError::InvalidParameter { .. })
    ));
    let c = d.with_tolerance(-1.0);
    assert!(matches!(
        TagK::<f64, Heap>::new(3, 3, c),
        Err(ConfigError::InvalidParameter { .. })
    ));
    let short = vec![0.0f64; 10];
    assert!(matches!(
        TagK::<f64, Vec<f64>>::with_storage(3, 3, d, short),
        Err(ConfigError::BufferTooSmall { .. })
    ));
}

#[test]
fn f32_and_f64_agree_on_a_well_conditioned_problem() {
    let (m, n) = (30, 10);
    let mut data = ChaCha8Rng::seed_from_u64(3);
    let theta: Vec<f64> = (0..n).map(|_| gauss(&mut data)).collect();
    let a = random_matrix(&mut data, m, n);
    let b = mat_vec(&a, &theta);
    let a32: Vec<f32> = a.iter().map(|&v| v as f32).collect();
    let b32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
    let mut e64 = TagK::<f64, Heap>::new(n, m, KaczmarzConfig::default()).unwrap();
    let mut e32 = TagK::<f32, Vec<f32>>::new(n, m, KaczmarzConfig::default()).unwrap();
    for _ in 0..100 {
        e64.update(&a, &b).unwrap();
        e32.update(&a32, &b32).unwrap();
    }
    let e32w: Vec<f64> = e32.estimate().iter().map(|&v| v as f64).collect();
    assert!(dist(&e32w, &theta) < 1e-4);
    assert!(dist(e64.estimate(), &theta) < 1e-10);
}

#[test]
fn early_stop_counts_as_remaining_iterates() {
    // A consistent square system solved exactly by the first pass: stopping early must give
    // the same average as running on with a stationary iterate.
    let n = 2;
    let a = [1.0, 0.0, 0.0, 1.0];
    let b = [3.0, 4.0];
    let cfg = KaczmarzConfig::default()
        .with_iterations(Iterations::Fixed(10))
        .with_burn_in(BurnIn::Fixed(0))
        .with_tolerance(1e-12);
    let mut est = TagK::<f64, Heap>::new(n, 2, cfg).unwrap();
    let info = est.update(&a, &b).unwrap();
    assert!(info.converged);
    assert_eq!(info.iterations, 2);
    // Iterates: x1 has one coordinate solved, x2..x10 = (3, 4). Average over x1..x10.
    let x = est.estimate();
    // Greedy picks row 1 first (larger residual 4 vs 3, sampled ∝ r²: both are candidates).
    let first_row_one = [(3.0 * 0.0 + 3.0 * 9.0) / 10.0, 4.0];
    let first_row_zero = [3.0, (4.0 * 9.0) / 10.0];
    assert!(
        dist(x, &first_row_one) < 1e-12 || dist(x, &first_row_zero) < 1e-12,
        "{x:?}"
    );
}

/// Estimators with owned storage can move between and be shared across threads, and clone.
#[test]
fn owned_estimators_are_send_sync_clone_debug() {
    fn check<E: Send + Sync + Clone + core::fmt::Debug + 'static>() {}
    check::<tagk_core::TagK<f64, Vec<f64>>>();
    check::<tagk_core::TagK<f32, [f32; tagk_core::kaczmarz_buffer_len(4, 2)]>>();
    check::<tagk_core::GreedyKaczmarz<f64, Vec<f64>>>();
    check::<tagk_core::TailAveragedKaczmarz<f64, Vec<f64>>>();
    check::<tagk_core::RandomizedKaczmarz<f64, Vec<f64>>>();
    check::<tagk_core::KaczmarzConfig>();
    check::<tagk_core::SyntheticWindows>();
}
