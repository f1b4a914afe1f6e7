//! A core that keeps learning (issue #27, item 5): on a stream of noisy windows of constant
//! parameters, TAG-K behind the tuned front end (the simulator's column scales, the 3σ stop,
//! the actuated rows) stops improving, while the same front end around
//! `tagk_core::Accumulate` reaches batch least squares. Batch least squares is computed
//! independently here, with nalgebra's SVD on every row fed.
//!
//! The windows are a rigid body's Newton–Euler rows (docs/CONVENTIONS.md §3) on a smooth
//! flight-like motion: 5 frames at 50 Hz every 0.4 s, as the simulator's estimator sees them.
//! Noise is on the measured wrench only (force rows `m σ_a`, torque rows much smaller), so
//! batch least squares is the efficient estimate the target compares to.

use nalgebra::{DMatrix, DVector, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_core::{
    Accumulate, AccumulateConfig, FrontEnd, FrontEndConfig, KaczmarzConfig, OnlineEstimator, TagK,
};
use tagk_dynamics::front_end::{ACTUATED_CHANNELS, STOP_MULTIPLE, column_scales};
use tagk_dynamics::quadrotor::{CRAZYFLIE_ARM_OFFSET, CRAZYFLIE_INERTIA, CRAZYFLIE_MASS};
use tagk_dynamics::{InertialParams, write_rigid_body_regressor};

const FRAMES: usize = 5;
const ROWS: usize = 6 * FRAMES;
const N: usize = 10;
/// Force-row noise `m σ_a` \[N\] (the realistic profile's accelerometer noise on a Crazyflie).
const SIGMA_FORCE: f64 = CRAZYFLIE_MASS * 0.062;
/// Torque-row noise \[N m\].
const SIGMA_TORQUE: f64 = 2e-5;

fn nominal() -> InertialParams {
    let i = CRAZYFLIE_INERTIA;
    InertialParams::from_array([
        CRAZYFLIE_MASS,
        0.0,
        0.0,
        0.0,
        i[0],
        i[1],
        i[2],
        i[3],
        i[4],
        i[5],
    ])
}

/// The truth: the Crazyflie with a small payload (mass, offset centre of mass, more inertia).
fn truth() -> InertialParams {
    let mut t = nominal().to_array();
    t[0] += 0.006;
    t[1] = 0.041 * 2e-3;
    t[2] = -0.041 * 1.5e-3;
    t[3] = -0.041 * 3e-3;
    t[4] *= 1.2;
    t[6] *= 1.15;
    t[9] *= 1.1;
    InertialParams::from_array(t)
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// `count` windows of a smooth motion (phases drawn from `seed`), the wrench noisy.
fn windows(seed: u64, count: usize, theta: &InertialParams) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let phase: [f64; 6] = std::array::from_fn(|_| rng.random::<f64>() * std::f64::consts::TAU);
    let dt = 0.02;
    (0..count)
        .map(|w| {
            let (mut a, mut b) = (vec![0.0; ROWS * N], vec![0.0; ROWS]);
            for f in 0..FRAMES {
                let t = (20 * w + f) as f64 * dt;
                let s = |k: usize, amp: f64, freq: f64| amp * (freq * t + phase[k]).sin();
                let c = |k: usize, amp: f64, freq: f64| amp * freq * (freq * t + phase[k]).cos();
                let omega = Vector3::new(s(0, 0.6, 1.3), s(1, 0.5, 0.9), s(2, 0.3, 0.5));
                let omega_dot = Vector3::new(c(0, 0.6, 1.3), c(1, 0.5, 0.9), c(2, 0.3, 0.5));
                let accel = Vector3::new(s(3, 0.8, 0.7), s(4, 0.8, 0.8), 9.81 + s(5, 0.4, 1.1));
                let rows = &mut a[6 * f * N..6 * (f + 1) * N];
                write_rigid_body_regressor(&accel, &omega, &omega_dot, rows).unwrap();
                for r in 0..6 {
                    let row = &rows[r * N..(r + 1) * N];
                    let clean: f64 = row.iter().zip(theta.as_slice()).map(|(x, y)| x * y).sum();
                    let sigma = if r < 3 { SIGMA_FORCE } else { SIGMA_TORQUE };
                    b[6 * f + r] = clean + sigma * gaussian(&mut rng);
                }
            }
            (a, b)
        })
        .collect()
}

/// Row weights of the tuned front end: the actuated rows only.
fn weights() -> Vec<f64> {
    (0..ROWS)
        .map(|r| {
            if ACTUATED_CHANNELS.contains(&(r % 6)) {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

/// `‖D⁻¹ (θ̂ − θ)‖`: every parameter relative to its column scale (mass, first moment and
/// inertia alike), and the inertia part alone.
fn errors(estimate: &[f64], theta: &InertialParams, d: &[f64; 10]) -> (f64, f64) {
    let rel: Vec<f64> = (0..N)
        .map(|j| (estimate[j] - theta.as_slice()[j]) / d[j])
        .collect();
    let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
    (norm(&rel), norm(&rel[4..]))
}

/// `‖θ̂ − θ‖₂` in SI units, the simulator's parameter error (mass and first moment dominate).
fn si_error(estimate: &[f64], theta: &InertialParams) -> f64 {
    tagk_sim::metrics::parameter_error(estimate, theta)
}

/// Batch least squares on the actuated rows of `ws` (nalgebra SVD on the scaled columns,
/// mapped back).
fn batch_least_squares(ws: &[(Vec<f64>, Vec<f64>)], d: &[f64; 10]) -> Vec<f64> {
    let mut rows = Vec::new();
    let mut rhs = Vec::new();
    for (a, b) in ws {
        for r in 0..ROWS {
            if ACTUATED_CHANNELS.contains(&(r % 6)) {
                rows.extend((0..N).map(|j| a[r * N + j] * d[j]));
                rhs.push(b[r]);
            }
        }
    }
    let a = DMatrix::from_row_slice(rhs.len(), N, &rows);
    let x = a
        .svd(true, true)
        .solve(&DVector::from_vec(rhs), 0.0)
        .expect("svd solve");
    (0..N).map(|j| x[j] * d[j]).collect()
}

fn front_end_config() -> FrontEndConfig {
    FrontEndConfig {
        row_noise: SIGMA_FORCE,
        stop_multiple: STOP_MULTIPLE,
        event_multiple: 5.0,
        block_rows: 6,
        ..FrontEndConfig::default()
    }
}

/// The layer as the simulator sets it: the fast estimate's precision is one row's noise per
/// unit of a scaled parameter.
fn learning() -> AccumulateConfig {
    AccumulateConfig {
        anchor_precision: SIGMA_FORCE * SIGMA_FORCE,
        ..AccumulateConfig::default()
    }
}

fn tagk() -> TagK<f64, Vec<f64>> {
    TagK::new(N, ROWS, KaczmarzConfig::default()).unwrap()
}

/// Runs `est` on `ws` (weighted as the tuned front end), returning the estimate after each of
/// `marks` windows.
fn run<E: OnlineEstimator<f64>>(
    est: &mut FrontEnd<f64, E, Vec<f64>>,
    ws: &[(Vec<f64>, Vec<f64>)],
    marks: &[usize],
) -> Vec<Vec<f64>> {
    let w = weights();
    est.reset(nominal().as_slice()).unwrap();
    let mut out = Vec::new();
    for (k, (a, b)) in ws.iter().enumerate() {
        est.update_weighted(a, b, Some(&w)).unwrap();
        if marks.contains(&(k + 1)) {
            out.push(est.estimate().to_vec());
        }
    }
    out
}

const SEEDS: u64 = 6;

#[test]
fn the_front_end_around_accumulate_reaches_batch_least_squares() {
    let theta = truth();
    let d = column_scales(&nominal(), CRAZYFLIE_ARM_OFFSET);
    let marks = [200, 2000];
    let (mut ls_sum, mut plain_sum, mut learn_sum) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    let (mut ls_inertia, mut learn_inertia) = (0.0, 0.0);
    let (mut ls_si, mut plain_si, mut learn_si) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    for seed in 1..=SEEDS {
        let ws = windows(seed, 2000, &theta);
        let mut plain = FrontEnd::new(tagk(), &d, front_end_config()).unwrap();
        let mut learn = FrontEnd::new(
            Accumulate::new(tagk(), learning()).unwrap(),
            &d,
            front_end_config(),
        )
        .unwrap();
        let p = run(&mut plain, &ws, &marks);
        let l = run(&mut learn, &ws, &marks);
        for (k, &mark) in marks.iter().enumerate() {
            let ls = batch_least_squares(&ws[..mark], &d);
            let (e_ls, i_ls) = errors(&ls, &theta, &d);
            let (e_p, _) = errors(&p[k], &theta, &d);
            let (e_l, i_l) = errors(&l[k], &theta, &d);
            let (s_ls, s_p, s_l) = (
                si_error(&ls, &theta),
                si_error(&p[k], &theta),
                si_error(&l[k], &theta),
            );
            println!(
                "seed {seed}, {mark} windows, scaled (SI): batch LS {e_ls:.2e} ({s_ls:.2e}; inertia {i_ls:.2e}), FrontEnd(TAG-K) {e_p:.2e} ({s_p:.2e}), FrontEnd(Accumulate(TAG-K)) {e_l:.2e} ({s_l:.2e}; inertia {i_l:.2e})"
            );
            ls_si[k] += s_ls;
            plain_si[k] += s_p;
            learn_si[k] += s_l;
            ls_sum[k] += e_ls;
            plain_sum[k] += e_p;
            learn_sum[k] += e_l;
            if mark == 2000 {
                ls_inertia += i_ls;
                learn_inertia += i_l;
            }
        }
    }
    for (k, mark) in marks.iter().enumerate() {
        println!(
            "mean over {SEEDS} streams after {mark} windows: batch LS {:.2e}, FrontEnd(TAG-K) {:.2e} ({:.0}x), FrontEnd(Accumulate(TAG-K)) {:.2e} ({:.2}x)",
            ls_sum[k] / SEEDS as f64,
            plain_sum[k] / SEEDS as f64,
            plain_sum[k] / ls_sum[k],
            learn_sum[k] / SEEDS as f64,
            learn_sum[k] / ls_sum[k],
        );
        println!(
            "  SI parameter error: batch LS {:.2e}, FrontEnd(TAG-K) {:.2e} ({:.0}x), FrontEnd(Accumulate(TAG-K)) {:.2e} ({:.2}x)",
            ls_si[k] / SEEDS as f64,
            plain_si[k] / SEEDS as f64,
            plain_si[k] / ls_si[k],
            learn_si[k] / SEEDS as f64,
            learn_si[k] / ls_si[k],
        );
    }
    // The target of issue #27: within 2x batch least squares after 2 000 windows.
    assert!(
        learn_sum[1] <= 2.0 * ls_sum[1],
        "{learn_sum:?} vs {ls_sum:?}"
    );
    assert!(learn_si[1] <= 2.0 * ls_si[1], "{learn_si:?} vs {ls_si:?}");
    // The weakly excited inertia is learned too.
    assert!(
        learn_inertia <= 2.0 * ls_inertia,
        "{learn_inertia} vs {ls_inertia}"
    );
    // It keeps learning: ten times the windows, a smaller error.
    assert!(learn_si[1] < 0.5 * learn_si[0], "{learn_si:?}");
    // TAG-K alone does not (the measured contrast the layer is for): no better after 2 000
    // windows than after 200, and well above batch least squares.
    assert!(plain_sum[1] > 0.9 * plain_sum[0], "{plain_sum:?}");
    assert!(
        plain_sum[1] > 2.0 * ls_sum[1],
        "{plain_sum:?} vs {ls_sum:?}"
    );
    assert!(plain_si[1] > 2.0 * ls_si[1], "{plain_si:?} vs {ls_si:?}");
}

#[test]
fn an_event_still_restarts_the_learning_at_once() {
    // 300 windows of the nominal body, then the payload: the front end's event detection
    // restarts the layer, and its estimate follows the new parameters as fast as TAG-K's.
    let d = column_scales(&nominal(), CRAZYFLIE_ARM_OFFSET);
    let (before, after) = (nominal(), truth());
    let (mut plain_sum, mut learn_sum, mut jump_sum) = ([0.0; 3], [0.0; 3], 0.0);
    for seed in 1..=SEEDS {
        let mut ws = windows(seed, 300, &before);
        let post = windows(seed + 100, 30, &after);
        ws.extend(post);
        let mut plain = FrontEnd::new(tagk(), &d, front_end_config()).unwrap();
        let mut learn = FrontEnd::new(
            Accumulate::new(tagk(), learning()).unwrap(),
            &d,
            front_end_config(),
        )
        .unwrap();
        let marks = [301, 303, 330];
        let p = run(&mut plain, &ws, &marks);
        let l = run(&mut learn, &ws, &marks);
        assert!(learn.last().is_some());
        jump_sum += si_error(before.as_slice(), &after);
        for k in 0..marks.len() {
            plain_sum[k] += si_error(&p[k], &after);
            learn_sum[k] += si_error(&l[k], &after);
        }
    }
    println!(
        "after the jump ({:.2e}): FrontEnd(TAG-K) {plain_sum:?}, FrontEnd(Accumulate(TAG-K)) {learn_sum:?} (sums over {SEEDS} streams, windows 1, 3, 30 after)",
        jump_sum / SEEDS as f64
    );
    // One and three windows after the jump, as fast as TAG-K: most of the way.
    assert!(learn_sum[0] < 0.3 * jump_sum, "{learn_sum:?} vs {jump_sum}");
    assert!(
        learn_sum[0] < 1.5 * plain_sum[0],
        "{learn_sum:?} vs {plain_sum:?}"
    );
    assert!(
        learn_sum[1] < 1.5 * plain_sum[1],
        "{learn_sum:?} vs {plain_sum:?}"
    );
    // Thirty windows after, the layer is learning again: below TAG-K.
    assert!(
        learn_sum[2] < plain_sum[2],
        "{learn_sum:?} vs {plain_sum:?}"
    );
}
