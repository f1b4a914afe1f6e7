//! The paper presets on quadrotor-shaped windows (the Newton–Euler regressor of
//! docs/CONVENTIONS.md §3, Crazyflie parameters of §4, windows of 5 frames → A is 30 × 10), with
//! a payload attached part-way through.

mod common;

use common::*;
use tagk_baselines::{KalmanConfig, KalmanFilter, OnlineEstimator, Rls};

type M3 = [[f64; 3]; 3];

fn skew(x: [f64; 3]) -> M3 {
    [[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]]
}

fn mat_mul(a: M3, b: M3) -> M3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                c[i][j] += a[i][k] * b[k][j];
            }
        }
    }
    c
}

/// `L(ω)` with `I ω = L(ω) [I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]`.
fn l_map(w: [f64; 3]) -> [[f64; 6]; 3] {
    [
        [w[0], w[1], 0.0, w[2], 0.0, 0.0],
        [0.0, w[0], w[1], 0.0, w[2], 0.0],
        [0.0, 0.0, 0.0, w[0], w[1], w[2]],
    ]
}

/// The 6 × 10 regressor (row-major) for proper acceleration `a`, rate `w`, rate derivative `dw`.
fn regressor(a: [f64; 3], w: [f64; 3], dw: [f64; 3]) -> Vec<f64> {
    let mut y = vec![0.0; 60];
    let (sdw, sw, sa) = (skew(dw), skew(w), skew(a));
    let sw2 = mat_mul(sw, sw);
    let (ldw, lw) = (l_map(dw), l_map(w));
    for r in 0..3 {
        y[r * 10] = a[r];
        for c in 0..3 {
            y[r * 10 + 1 + c] = sdw[r][c] + sw2[r][c];
            y[(3 + r) * 10 + 1 + c] = -sa[r][c];
        }
        for c in 0..6 {
            let mut v = ldw[r][c];
            for k in 0..3 {
                v += sw[r][k] * lw[k][c];
            }
            y[(3 + r) * 10 + 4 + c] = v;
        }
    }
    y
}

/// Crazyflie parameters, plus an optional point payload of mass `mp` at `c` (body frame).
fn theta(payload: Option<(f64, [f64; 3])>) -> [f64; 10] {
    let mut t = [
        0.035, 0.0, 0.0, 0.0, 1.66e-5, 0.83e-6, 1.66e-5, 0.72e-6, 1.8e-6, 2.93e-5,
    ];
    if let Some((mp, c)) = payload {
        let c2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        t[0] += mp;
        for k in 0..3 {
            t[1 + k] += mp * c[k];
        }
        // I_O += mp (cᵀc 1 − c cᵀ), in the order xx, xy, yy, xz, yz, zz.
        t[4] += mp * (c2 - c[0] * c[0]);
        t[5] -= mp * c[0] * c[1];
        t[6] += mp * (c2 - c[1] * c[1]);
        t[7] -= mp * c[0] * c[2];
        t[8] -= mp * c[1] * c[2];
        t[9] += mp * (c2 - c[2] * c[2]);
    }
    t
}

/// `count` windows of 5 frames at 50 Hz along a smooth manoeuvre (peak ~0.5 rad/s), the
/// payload attached from window `attach` on; measurements exact.
fn flight(count: usize, attach: usize) -> (Vec<Window>, Vec<[f64; 10]>) {
    let mut g = rng(12);
    let mut t = 0.0f64;
    let mut stream = Vec::new();
    let mut truth = Vec::new();
    for k in 0..count {
        let th = theta((k >= attach).then_some((0.4 * 0.035, [0.25 * 0.0325, 0.0, 0.0])));
        let mut a = Vec::new();
        for _ in 0..5 {
            t += 0.02;
            let acc = [
                0.3 * (1.3 * t).sin() + 0.01 * random_vec(&mut g, 1, 1.0)[0],
                0.3 * (0.7 * t).cos(),
                9.81 + 0.2 * (2.1 * t).sin(),
            ];
            let w = [
                0.5 * (0.9 * t).sin(),
                0.4 * (1.1 * t).cos(),
                0.3 * (0.5 * t).sin(),
            ];
            let dw = [
                0.45 * (0.9 * t).cos(),
                -0.44 * (1.1 * t).sin(),
                0.15 * (0.5 * t).cos(),
            ];
            a.extend(regressor(acc, w, dw));
        }
        let b = a
            .chunks(10)
            .map(|row| row.iter().zip(&th).map(|(x, p)| x * p).sum())
            .collect();
        stream.push(Window { a, b });
        truth.push(th);
    }
    (stream, truth)
}

fn error(est: &[f64], truth: &[f64; 10]) -> f64 {
    est.iter()
        .zip(truth)
        .map(|(e, t)| (e - t) * (e - t))
        .sum::<f64>()
        .sqrt()
}

#[test]
fn presets_track_a_payload_change_without_numerical_failure() {
    let attach = 20;
    let (stream, truth) = flight(60, attach);
    let mut ests: Vec<Box<dyn OnlineEstimator<f64>>> = vec![
        Box::new(Rls::rls_low(10, 30).unwrap()),
        Box::new(Rls::rls_high(10, 30).unwrap()),
        Box::new(KalmanFilter::kf_low(10, 30).unwrap()),
        Box::new(KalmanFilter::kf_high(10, 30).unwrap()),
    ];
    let mut errors = vec![Vec::new(); ests.len()];
    for (w, th) in stream.iter().zip(&truth) {
        for (e, errs) in ests.iter_mut().zip(errors.iter_mut()) {
            e.update(&w.a, &w.b)
                .unwrap_or_else(|err| panic!("{}: {err}", e.name()));
            errs.push(error(e.estimate(), th));
        }
    }
    // Before the payload every preset has converged (exact data).
    for (e, errs) in ests.iter().zip(&errors) {
        assert!(
            errs[attach - 1] < 1e-5,
            "{}: {:e}",
            e.name(),
            errs[attach - 1]
        );
    }
    // The payload (14 g) moves θ by ~1.4e-2; the Kalman filters re-converge within the flight.
    // (RLS, whose implicit measurement variance is λ ≈ 1 N², is still ~1e-2 off after 40
    // windows: that slowness is what the paper's comparison shows, not a numerical issue.)
    for (e, errs) in ests.iter().zip(&errors).skip(2) {
        assert!(errs[59] < 1e-5, "{}: {:e}", e.name(), errs[59]);
        assert!(errs[59] < 0.1 * errs[attach], "{}", e.name());
    }
    for errs in &errors[..2] {
        assert!(errs.iter().all(|v| v.is_finite()));
    }
}

#[test]
fn kf_low_first_window_covariance_is_accurate() {
    // The first KF-low window takes P from 10³·I to ~1e-13 in the mass direction: the
    // block covariance update cancels completely there, so the information-form fallback
    // must produce it. Compared with an independent information-form step, relative to the
    // size of P itself (not of the prior).
    let (stream, _) = flight(1, 100);
    let cfg = KalmanConfig::LOW;
    let mut kf = KalmanFilter::kf_low(10, 30).unwrap();
    let mut reference = InformationKf::new(10, cfg.sigma_q, cfg.sigma_r, cfg.p0);
    kf.update(&stream[0].a, &stream[0].b).unwrap();
    reference.step(&stream[0]);
    for k in 0..10 {
        let got = kf.covariance()[k * 10 + k];
        let want = reference.p[(k, k)];
        assert!(
            got > 0.0 && (got / want - 1.0).abs() < 1e-6,
            "P[{k}][{k}] = {got:e}, expected {want:e}"
        );
    }
}
