//! The change detector (issue #27, item 4) on synthetic residuals: its χ² thresholds against
//! tabulated values, its false-alarm rate over many seeds against the design value, its delay
//! on a step, and the wrapper's first post-event estimate against an independent solve
//! (nalgebra) of the same problem.

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};
use tagk_core::{
    ChangeDetector, DetectorConfig, EventTriggered, KaczmarzConfig, OnlineEstimator, TagK,
    chi_square_quantile,
};

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = uniform(rng).max(1e-300);
    let u2 = uniform(rng);
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[test]
fn thresholds_match_the_chi_square_tables() {
    // Upper points of χ² (Abramowitz & Stegun, table 26.8), and ν = 2's closed form −2 ln α.
    for (dof, alpha, table, tol) in [
        (2, 1e-4, -2.0 * 1e-4f64.ln(), 1e-9),
        (4, 1e-3, 18.467, 1e-3),
        (4, 0.05, 9.488, 1e-3),
        (20, 1e-3, 45.315, 1e-3),
        (20, 0.05, 31.410, 1e-3),
        // Odd ν: Wilson–Hilferty, a few per cent.
        (1, 1e-3, 10.828, 0.05),
        (5, 0.05, 11.070, 0.02),
        (21, 1e-3, 46.797, 0.02),
    ] {
        let x = chi_square_quantile(dof, alpha);
        assert!(
            ((x - table) / table).abs() < tol,
            "ν {dof}, α {alpha}: {x} vs {table}"
        );
    }
    assert!(chi_square_quantile(0, 0.1).is_nan());
    assert!(chi_square_quantile(3, 1.5).is_nan());
}

/// Rows per check (a frame's actuated rows) and their noise, channel by channel.
const SIGMA: [f64; 4] = [2e-3, 3e-5, 3e-5, 1e-5];

fn residuals(rng: &mut ChaCha8Rng, shift: f64) -> [f64; 4] {
    std::array::from_fn(|c| SIGMA[c] * (shift + gaussian(rng)))
}

/// Alarms and checks over `seeds` streams of `checks` checks each, with known or measured noise.
fn false_alarms(alpha: f64, known: bool, seeds: u64, checks: usize) -> (usize, usize) {
    let config = DetectorConfig {
        false_alarm: alpha,
        channels: 4,
        warmup: 200,
        horizon: 2000,
    };
    let (mut alarms, mut total) = (0, 0);
    for seed in 0..seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut d = if known {
            ChangeDetector::with_known_noise(config, &SIGMA).unwrap()
        } else {
            ChangeDetector::new(config).unwrap()
        };
        for _ in 0..checks {
            let r = residuals(&mut rng, 0.0);
            let c = d.check(&r, None);
            if c.calibrated {
                total += 1;
                // Exceedances, counted whether or not the quiet-before rule lets them alarm.
                alarms += usize::from(c.statistic > c.threshold);
            }
        }
    }
    (alarms, total)
}

#[test]
fn the_false_alarm_rate_is_the_design_rate() {
    let alpha = 1e-3;
    for known in [true, false] {
        let (alarms, total) = false_alarms(alpha, known, 50, 4000);
        let expected = alpha * total as f64;
        let rate = alarms as f64 / total as f64;
        println!(
            "{} noise: {alarms} alarms in {total} checks, rate {rate:.2e} (design {alpha:.0e})",
            if known { "known" } else { "measured" }
        );
        // Binomial: 4 standard deviations either side; the measured noise adds the error of
        // its own estimate (a running mean of 2000 rows), which fattens the tail a little.
        let slack = if known { 4.0 } else { 8.0 };
        assert!(
            (alarms as f64 - expected).abs() < slack * expected.sqrt(),
            "{alarms} vs {expected}"
        );
    }
}

#[test]
fn a_step_is_detected_on_its_first_check() {
    let config = DetectorConfig {
        false_alarm: 1e-4,
        channels: 4,
        warmup: 200,
        horizon: 2000,
    };
    let (mut first, mut later, mut missed, mut early) = (0, 0, 0, 0);
    for seed in 0..1000u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut d = ChangeDetector::new(config).unwrap();
        let step_at = 300;
        let mut alarm_at = None;
        for k in 0..step_at + 20 {
            // A step of 5 noise standard deviations on every row from check `step_at` on.
            let shift = if k >= step_at { 5.0 } else { 0.0 };
            if d.check(&residuals(&mut rng, shift), None).alarm && alarm_at.is_none() {
                alarm_at = Some(k);
            }
        }
        match alarm_at {
            Some(k) if k < step_at => early += 1,
            Some(k) if k == step_at => first += 1,
            Some(_) => later += 1,
            None => missed += 1,
        }
    }
    println!(
        "5σ step: {first} on its first check, {later} later, {missed} missed, {early} false alarms before"
    );
    // Non-central χ²(4, λ = 100) above the 1e-4 point (23.5): all but a handful.
    assert!(first >= 990, "{first}");
    assert_eq!(missed, 0);
    // 100 checks × 1000 streams at α = 1e-4: about 10 false alarms expected before the step.
    assert!(early <= 30, "{early}");
}

/// Windows of 6 rows (cos φ, sin φ, 1) with noise `sigma` on b.
fn window(theta: [f64; 3], w: usize, sigma: f64, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>) {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let phi = 0.77 * (6 * w + k) as f64;
        let row = [phi.cos(), phi.sin(), 1.0];
        a.extend(row);
        b.push(row.iter().zip(&theta).map(|(x, t)| x * t).sum::<f64>() + sigma * gaussian(rng));
    }
    (a, b)
}

#[test]
fn the_first_estimate_is_the_map_estimate_of_the_fresh_window() {
    let sigma = 1e-2;
    let scales = [1.0, 1.0, 0.5];
    let after = [1.4, 2.0, 0.8];
    let err = |x: &[f64]| {
        after
            .iter()
            .zip(x)
            .map(|(t, e)| (t - e) * (t - e))
            .sum::<f64>()
            .sqrt()
    };
    let (mut own_sum, mut map_sum) = (0.0, 0.0);
    let seeds = 20;
    for seed in 0..seeds {
        let config = DetectorConfig {
            channels: 1,
            warmup: 20,
            ..DetectorConfig::default()
        };
        let tagk = TagK::<f64, Vec<f64>>::new(3, 6, KaczmarzConfig::default()).unwrap();
        let mut est = EventTriggered::new(tagk, &scales, config).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for w in 0..100 {
            let (a, b) = window([1.0, 2.0, 0.5], w, sigma, &mut rng);
            est.update(&a, &b).unwrap();
        }
        let (a, b) = window(after, 100, sigma, &mut rng);
        est.update(&a, &b).unwrap();
        assert!(est.is_pending(), "seed {seed}");
        // The independent answer: θ̂ + (AᵀA/σ̂² + S⁻²)⁻¹ Aᵀ(b − A θ̂)/σ̂², nalgebra's LU.
        let (a, b) = window(after, 101, sigma, &mut rng);
        let before = est.estimate().to_vec();
        let var = est.detector().noise()[0].powi(2);
        let am = DMatrix::from_row_slice(6, 3, &a);
        let r = DVector::from_vec(b.clone()) - &am * DVector::from_vec(before.clone());
        let mut normal = am.transpose() * &am / var;
        for j in 0..3 {
            normal[(j, j)] += 1.0 / (scales[j] * scales[j]);
        }
        let delta = normal.lu().solve(&(am.transpose() * r / var)).unwrap();
        est.first_estimate(&a, &b, None).unwrap();
        for j in 0..3 {
            assert!(
                (est.estimate()[j] - (before[j] + delta[j])).abs() < 1e-12,
                "{j}: {:?} vs {}",
                est.estimate(),
                before[j] + delta[j]
            );
        }
        assert!(!est.is_pending());
        // TAG-K's own first update from the same estimate, on the same window.
        let mut own = TagK::<f64, Vec<f64>>::new(3, 6, KaczmarzConfig::default()).unwrap();
        own.reset(&before).unwrap();
        own.update(&a, &b).unwrap();
        own_sum += err(own.estimate());
        map_sum += err(est.estimate());
    }
    let (own_mean, map_mean) = (own_sum / seeds as f64, map_sum / seeds as f64);
    println!(
        "first post-event estimate error, mean of {seeds}: TAG-K {own_mean:.2e}, MAP {map_mean:.2e}"
    );
    assert!(map_mean < 0.6 * own_mean, "{map_mean} vs {own_mean}");
}

proptest! {
    /// Without an alarm, the wrapper changes nothing: its estimates are the bare estimator's,
    /// bit for bit, whatever the stream.
    #[test]
    fn without_alarms_the_wrapper_is_transparent(seed in 0u64..1000, windows in 1usize..60) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let cfg = KaczmarzConfig::default().with_seed(seed);
        let mut bare = TagK::<f64, Vec<f64>>::new(3, 6, cfg).unwrap();
        let inner = TagK::<f64, Vec<f64>>::new(3, 6, cfg).unwrap();
        // Known noise far above the data's: no check can alarm.
        let config = DetectorConfig { channels: 1, ..DetectorConfig::default() };
        let det = ChangeDetector::with_known_noise(config, &[1e6]).unwrap();
        let mut wrapped = EventTriggered::new(inner, &[1.0; 3], config)
            .unwrap()
            .with_detector(det);
        for w in 0..windows {
            let (a, b) = window([1.0, -1.0, 0.3], w, 1e-3, &mut rng);
            bare.update(&a, &b).unwrap();
            wrapped.update(&a, &b).unwrap();
            prop_assert_eq!(bare.estimate(), wrapped.estimate());
        }
        prop_assert_eq!(wrapped.detector().alarms(), 0);
    }
}
