//! The front end on the new user's problem of issue #14: three parameters of very different
//! magnitudes, windows whose columns differ by three orders of magnitude (median per-window
//! condition number ≈ 3000), a stream of noisy windows. Raw TAG-K stalls far from the truth;
//! the same TAG-K behind the front end (column scales from a prior guess within 10 %, the
//! noise-aware stop) comes within 10× of batch least squares on the same data, computed
//! independently here with nalgebra's SVD.

use nalgebra::{DMatrix, DVector};
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use tagk_core::{
    FrontEnd, FrontEndConfig, KaczmarzConfig, OnlineEstimator, TagK, scales_from_prior,
};

/// The true parameters: a mass-like, a first-moment-like and an inertia-like value in units
/// that make their columns differ by orders of magnitude.
const THETA: [f64; 3] = [1.0, 30.0, 2000.0];
/// A prior guess within 10 % of each parameter (what a user knows before flying).
const PRIOR: [f64; 3] = [1.08, 27.5, 2008.0];
/// Typical magnitude of each column of `A`.
const COLUMN_SCALES: [f64; 3] = [1.0, 0.03, 4.5e-4];
/// Measurement noise σ of `b`.
const SIGMA: f64 = 1.2e-5;
const ROWS: usize = 10;
const WINDOWS: usize = 200;
/// Independent streams (seeds 1..=SEEDS): one batch least-squares error is itself a random
/// draw, so the means are compared.
const SEEDS: u64 = 8;

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller.
    let u1 = uniform(rng).max(1e-300);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// The windows `(A, b)`, `b = A θ + v`.
fn windows(seed: u64) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..WINDOWS)
        .map(|_| {
            let mut a = Vec::with_capacity(ROWS * 3);
            let mut b = Vec::with_capacity(ROWS);
            for _ in 0..ROWS {
                let row: Vec<f64> = COLUMN_SCALES
                    .iter()
                    .map(|c| c * (1.0 + gaussian(&mut rng)))
                    .collect();
                b.push(
                    row.iter().zip(&THETA).map(|(x, t)| x * t).sum::<f64>()
                        + SIGMA * gaussian(&mut rng),
                );
                a.extend(row);
            }
            (a, b)
        })
        .collect()
}

fn error(estimate: &[f64]) -> f64 {
    estimate
        .iter()
        .zip(&THETA)
        .map(|(e, t)| (e - t) * (e - t))
        .sum::<f64>()
        .sqrt()
}

fn condition(a: &[f64]) -> f64 {
    let sv = DMatrix::from_row_slice(ROWS, 3, a).singular_values();
    sv.max() / sv.min()
}

/// Batch least squares on every window stacked (nalgebra SVD).
fn batch_least_squares(ws: &[(Vec<f64>, Vec<f64>)]) -> Vec<f64> {
    let a: Vec<f64> = ws.iter().flat_map(|(a, _)| a.iter().copied()).collect();
    let b: Vec<f64> = ws.iter().flat_map(|(_, b)| b.iter().copied()).collect();
    let a = DMatrix::from_row_slice(b.len(), 3, &a);
    let b = DVector::from_vec(b);
    let x = a.svd(true, true).solve(&b, 1e-14).expect("svd solve");
    x.iter().copied().collect()
}

fn run<E: OnlineEstimator<f64>>(est: &mut E, ws: &[(Vec<f64>, Vec<f64>)]) -> f64 {
    est.reset(&PRIOR).expect("reset");
    for (a, b) in ws {
        est.update(a, b).expect("update");
    }
    error(est.estimate())
}

#[test]
fn wrapped_tagk_comes_within_ten_times_of_batch_least_squares() {
    let (mut ls_sum, mut wrapped_sum) = (0.0, 0.0);
    for seed in 1..=SEEDS {
        let ws = windows(seed);
        let mut kappas: Vec<f64> = ws.iter().map(|(a, _)| condition(a)).collect();
        kappas.sort_by(f64::total_cmp);
        let median_kappa = kappas[kappas.len() / 2];
        let ls = error(&batch_least_squares(&ws));

        let mut raw = TagK::<f64, Vec<f64>>::new(3, ROWS, KaczmarzConfig::default()).unwrap();
        let raw_error = run(&mut raw, &ws);

        let mut scales = [0.0; 3];
        scales_from_prior(&PRIOR, 1e-12, &mut scales).unwrap();
        let config = FrontEndConfig {
            row_noise: SIGMA,
            stop_multiple: 1.0,
            average_horizon: 50,
            ..FrontEndConfig::default()
        };
        let inner = TagK::<f64, Vec<f64>>::new(3, ROWS, KaczmarzConfig::default()).unwrap();
        let mut wrapped = FrontEnd::new(inner, &scales, config).unwrap();
        let wrapped_error = run(&mut wrapped, &ws);
        println!(
            "seed {seed}: median per-window kappa {median_kappa:.0}, batch LS {ls:.2e}, raw TAG-K {raw_error:.3}, wrapped TAG-K {wrapped_error:.2e}"
        );
        assert!((1000.0..10_000.0).contains(&median_kappa), "{median_kappa}");
        assert!(raw_error > 1000.0 * ls, "raw {raw_error} vs LS {ls}");
        ls_sum += ls;
        wrapped_sum += wrapped_error;
    }
    let (ls_mean, wrapped_mean) = (ls_sum / SEEDS as f64, wrapped_sum / SEEDS as f64);
    println!("mean over {SEEDS} streams: batch LS {ls_mean:.2e}, wrapped TAG-K {wrapped_mean:.2e}");
    assert!(
        wrapped_mean <= 10.0 * ls_mean,
        "wrapped {wrapped_mean} vs LS {ls_mean}"
    );
}
