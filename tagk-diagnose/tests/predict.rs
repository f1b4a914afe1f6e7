//! k-step prediction (`tagk compare`), checked against independent computations: the closed
//! form of a torque-free symmetric top in free fall, a tiny explicit integrator written here,
//! a hand computation of MATLAB's fit %, and simulator logs with a hidden linear drag.
#![allow(clippy::needless_range_loop)]
mod common;

use nalgebra::{Matrix3, Matrix6, Rotation3, UnitQuaternion, Vector3, Vector6};
use tagk_diagnose::model_file::ModelCoefficient;
use tagk_diagnose::{
    BodyState, CONSTANT_RATE, Comparison, EffectKind, FlightLog, LogSample, Model, ModelContext,
    ModelEffect, ModelFile, ModelPrediction, Predictor, Signals, builtin, builtin_effects,
    constant_rate_prediction, fit_percent, k_step_prediction, predict_logs,
};
use tagk_dynamics::GRAVITY_WORLD;

const DT: f64 = 0.01;

fn sample(t: f64, s: &BodyState, wrench: [f64; 6]) -> LogSample {
    let q = s.attitude;
    LogSample {
        t,
        position: s.position.into(),
        velocity: s.velocity.into(),
        attitude: [q.w, q.i, q.j, q.k],
        omega: s.omega.into(),
        wrench,
        accel: None,
        omega_dot: None,
        rotor_speeds: None,
    }
}

/// `[v]×`.
fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    v.cross_matrix()
}

#[test]
fn a_free_symmetric_top_follows_its_closed_form() {
    // Torque-free symmetric top (I1 = I2 ≠ I3, centre of mass at the origin) in free fall:
    // p = p0 + v0 t + g t²/2; R(t) = exp(t μ [l̂]×) R0 exp(−t Ω [e3]×) with L = R0 I ω0,
    // μ = |L| / I1, Ω = (I3 − I1) ω3 / I1; ω(t) = Rᵀ L / I1 − Ω e3 (body frame).
    let (m, i1, i3) = (0.035, 1.6e-5, 2.9e-5);
    let inertia = Matrix3::from_diagonal(&Vector3::new(i1, i1, i3));
    let r0 = Rotation3::from_euler_angles(0.3, -0.2, 0.7);
    let w0 = Vector3::new(1.5, -0.8, 6.0);
    let (p0, v0) = (Vector3::new(0.1, 0.2, 3.0), Vector3::new(0.5, -0.3, 1.0));
    let l = r0 * (inertia * w0);
    let mu = l.norm() / i1;
    let big_omega = (i3 - i1) * w0.z / i1;
    let state = |t: f64| {
        let a = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(l), mu * t);
        let b = Rotation3::from_axis_angle(&Vector3::z_axis(), -big_omega * t);
        let r = a * r0 * b;
        BodyState {
            position: p0 + v0 * t + 0.5 * GRAVITY_WORLD * t * t,
            velocity: v0 + GRAVITY_WORLD * t,
            attitude: UnitQuaternion::from_rotation_matrix(&r),
            omega: r.inverse() * l / i1 - big_omega * Vector3::z(),
        }
    };
    let mut log = FlightLog::new();
    for k in 0..400 {
        let t = k as f64 * DT;
        log.push(&sample(t, &state(t), [0.0; 6]));
    }
    let s = Signals::from_log(&log).unwrap();
    let model = ModelFile::rigid_body([m, 0.0, 0.0, 0.0, i1, 0.0, i1, 0.0, 0.0, i3]);
    let p = k_step_prediction(&s, &model, &[1, 10, 50]).unwrap();
    for e in &p.horizons {
        eprintln!("{e:?}");
    }
    for e in &p.horizons {
        assert!(e.position < 1e-12, "h {}: position {:e} m", e.h, e.position);
        assert!(
            e.velocity < 1e-12,
            "h {}: velocity {:e} m/s",
            e.h,
            e.velocity
        );
        // RK4's truncation at |ω| ≈ 6 rad/s: (|ω| dt)⁵ / 120 ≈ 6e-9 rad a step.
        let h = e.h as f64;
        assert!(
            e.attitude < 2e-9 * h,
            "h {}: attitude {:e} rad",
            e.h,
            e.attitude
        );
        assert!(
            e.body_rate < 1e-8 * h,
            "h {}: rate {:e} rad/s",
            e.h,
            e.body_rate
        );
        assert!((e.dt - DT).abs() < 1e-15, "{}", e.dt);
    }
}

/// The body of the driven case: a centre of mass off the origin and a full inertia.
const THETA: [f64; 10] = [
    0.035, 3.5e-5, -2.1e-5, 1.4e-5, 1.7e-5, 0.8e-6, 1.6e-5, 0.7e-6, 1.8e-6, 2.9e-5,
];
/// Linear drag `d_x, d_y, d_z` \[N s/m\].
const DRAG: [f64; 3] = [0.012, 0.009, 0.02];

/// The actuators' wrench held over the step starting at `t`: a varying force, and the torque
/// `c × f` that keeps the off-centre thrust from spinning the body up, plus a small varying
/// torque.
fn input(t: f64) -> [f64; 6] {
    let m = THETA[0];
    let f = Vector3::new(
        0.01 * (1.3 * t).sin(),
        0.02 * (0.7 * t).cos(),
        m * 9.81 + 0.05 * (2.0 * t).sin(),
    );
    let c = Vector3::new(THETA[1], THETA[2], THETA[3]) / m;
    let tau = c.cross(&f)
        + Vector3::new(
            2e-6 * (3.0 * t).sin(),
            -1e-6 * (2.0 * t).cos(),
            1e-6 * t.sin(),
        );
    [f.x, f.y, f.z, tau.x, tau.y, tau.z]
}

/// The reference's own rigid body: `M [a; ω̇] = [f − ω×(ω×h); τ − ω×(Iω)]` with the spatial
/// inertia `M = [[m 1, −[h]×], [[h]×, I]]`, solved by nalgebra's LU; drag `−D Rᵀ v`.
fn reference_derivative(x: &[f64; 13], u: &[f64; 6], drag: &[f64; 3]) -> [f64; 13] {
    let m = THETA[0];
    let h = Vector3::new(THETA[1], THETA[2], THETA[3]);
    let i = Matrix3::new(
        THETA[4], THETA[5], THETA[7], THETA[5], THETA[6], THETA[8], THETA[7], THETA[8], THETA[9],
    );
    let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(x[6], x[7], x[8], x[9]));
    let r = q.to_rotation_matrix();
    let v = Vector3::new(x[3], x[4], x[5]);
    let w = Vector3::new(x[10], x[11], x[12]);
    let vb = r.inverse() * v;
    let f = Vector3::new(
        u[0] - drag[0] * vb.x,
        u[1] - drag[1] * vb.y,
        u[2] - drag[2] * vb.z,
    );
    let tau = Vector3::new(u[3], u[4], u[5]);
    let mut big = Matrix6::zeros();
    big.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(Matrix3::identity() * m));
    big.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(&h)));
    big.fixed_view_mut::<3, 3>(3, 0).copy_from(&skew(&h));
    big.fixed_view_mut::<3, 3>(3, 3).copy_from(&i);
    let rhs_f = f - w.cross(&w.cross(&h));
    let rhs_t = tau - w.cross(&(i * w));
    let rhs = Vector6::new(rhs_f.x, rhs_f.y, rhs_f.z, rhs_t.x, rhs_t.y, rhs_t.z);
    let sol = big.lu().solve(&rhs).unwrap();
    let a = Vector3::new(sol[0], sol[1], sol[2]);
    let acc = r * a + GRAVITY_WORLD;
    // q̇ = ½ q ⊗ (0, ω), written out.
    let (qw, qx, qy, qz) = (x[6], x[7], x[8], x[9]);
    let qd = [
        0.5 * (-qx * w.x - qy * w.y - qz * w.z),
        0.5 * (qw * w.x + qy * w.z - qz * w.y),
        0.5 * (qw * w.y - qx * w.z + qz * w.x),
        0.5 * (qw * w.z + qx * w.y - qy * w.x),
    ];
    [
        x[3], x[4], x[5], acc.x, acc.y, acc.z, qd[0], qd[1], qd[2], qd[3], sol[3], sol[4], sol[5],
    ]
}

/// One explicit RK4 step of the reference, the quaternion normalised after it.
fn reference_step(x: &[f64; 13], u: &[f64; 6], dt: f64, drag: &[f64; 3]) -> [f64; 13] {
    let add = |a: &[f64; 13], k: &[f64; 13], s: f64| -> [f64; 13] {
        std::array::from_fn(|j| a[j] + s * k[j])
    };
    let k1 = reference_derivative(x, u, drag);
    let k2 = reference_derivative(&add(x, &k1, dt / 2.0), u, drag);
    let k3 = reference_derivative(&add(x, &k2, dt / 2.0), u, drag);
    let k4 = reference_derivative(&add(x, &k3, dt), u, drag);
    let mut y: [f64; 13] =
        std::array::from_fn(|j| x[j] + dt / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]));
    let n = (y[6] * y[6] + y[7] * y[7] + y[8] * y[8] + y[9] * y[9]).sqrt();
    for v in &mut y[6..10] {
        *v /= n;
    }
    y
}

fn state_of(x: &[f64; 13]) -> BodyState {
    BodyState {
        position: Vector3::new(x[0], x[1], x[2]),
        velocity: Vector3::new(x[3], x[4], x[5]),
        attitude: UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            x[6], x[7], x[8], x[9],
        )),
        omega: Vector3::new(x[10], x[11], x[12]),
    }
}

fn drag_effect() -> ModelEffect {
    ModelEffect {
        name: "linear-drag".into(),
        spec: None,
        scanned: None,
        coefficients: ["d_x", "d_y", "d_z"]
            .iter()
            .zip(DRAG)
            .map(|(n, d)| ModelCoefficient {
                name: n.to_string(),
                unit: "N s/m".into(),
                value: d,
                std_error: None,
                interval: None,
            })
            .collect(),
    }
}

#[test]
fn a_driven_body_with_drag_matches_an_independent_fine_integrator() {
    // The log is the reference integrated at dt/100 with each sample's wrench held.
    let q0 = UnitQuaternion::from_euler_angles(0.1, -0.05, 0.4);
    let mut x = [
        0.0, 0.0, 1.0, 0.8, -0.4, 0.1, q0.w, q0.i, q0.j, q0.k, 0.5, -0.3, 0.8,
    ];
    let mut log = FlightLog::new();
    let mut max_rate: f64 = 0.0;
    for k in 0..300 {
        let t = k as f64 * DT;
        let u = input(t);
        log.push(&sample(t, &state_of(&x), u));
        max_rate = max_rate.max(state_of(&x).omega.norm());
        for _ in 0..100 {
            x = reference_step(&x, &u, DT / 100.0, &DRAG);
        }
    }
    let s = Signals::from_log(&log).unwrap();
    let mut model = ModelFile::rigid_body(THETA);
    model.effects.push(drag_effect());
    let p = k_step_prediction(&s, &model, &[1, 5, 50]).unwrap();
    for e in &p.horizons {
        eprintln!("{e:?}");
    }
    eprintln!("max body rate {max_rate:.2} rad/s");
    for e in &p.horizons {
        // RK4's truncation at the log's step, growing with the horizon.
        let h = e.h as f64;
        assert!(
            e.position < 5e-10 * h,
            "h {}: position {:e} m",
            e.h,
            e.position
        );
        assert!(
            e.velocity < 2e-9 * h,
            "h {}: velocity {:e} m/s",
            e.h,
            e.velocity
        );
        assert!(
            e.attitude < 5e-10 * h,
            "h {}: attitude {:e} rad",
            e.h,
            e.attitude
        );
        assert!(
            e.body_rate < 2e-9 * h,
            "h {}: rate {:e} rad/s",
            e.h,
            e.body_rate
        );
        let fit = e.fit.position.unwrap();
        assert!(fit > 99.99, "h {}: fit {fit} %", e.h);
    }
    // Without the drag the same model drifts: the test sees the effect.
    let rigid = ModelFile::rigid_body(THETA);
    let q = k_step_prediction(&s, &rigid, &[50]).unwrap();
    assert!(
        q.horizons[0].velocity > 1e3 * p.horizons[2].velocity,
        "{} vs {}",
        q.horizons[0].velocity,
        p.horizons[2].velocity
    );
}

#[test]
fn fit_percent_is_matlabs_definition() {
    // y = 1, 2, 3 (mean 2, ‖y − ȳ‖ = √2), ŷ = 1, 2, 4 (‖y − ŷ‖ = 1): 100 (1 − 1/√2).
    let fit = fit_percent(&[[1.0], [2.0], [3.0]], &[[1.0], [2.0], [4.0]]).unwrap();
    assert!((fit - 29.289_321_881_345_25).abs() < 1e-12, "{fit}");
    // Two components stacked: y = (0,1), (2,3); ŷ = (0,1), (2,5). Means 1, 2: spread
    // 1 + 1 + 1 + 1 = 4, error 4: 100 (1 − 2/2) = 0.
    let fit = fit_percent(&[[0.0, 1.0], [2.0, 3.0]], &[[0.0, 1.0], [2.0, 5.0]]).unwrap();
    assert!(fit.abs() < 1e-12, "{fit}");
    assert_eq!(fit_percent(&[[1.0], [1.0]], &[[1.0], [2.0]]), None);
}

#[test]
fn the_prediction_fit_agrees_with_fit_percent_on_its_own_predictions() {
    // h = 1 on the top's log shifted far from the origin (Welford sums against the direct
    // two-pass formula, computed here from a second, hand-run prediction).
    let q0 = UnitQuaternion::from_euler_angles(0.2, 0.1, -0.3);
    let mut x = [
        1e3, -2e3, 50.0, 0.8, -0.4, 0.1, q0.w, q0.i, q0.j, q0.k, 0.5, -0.3, 0.8,
    ];
    let mut log = FlightLog::new();
    let mut states = Vec::new();
    for k in 0..250 {
        let t = k as f64 * DT;
        let u = input(t);
        log.push(&sample(t, &state_of(&x), u));
        states.push(x);
        for _ in 0..10 {
            x = reference_step(&x, &u, DT / 10.0, &DRAG);
        }
    }
    let s = Signals::from_log(&log).unwrap();
    // A wrong model (no drag): a fit % away from 100. The hand predictions: the reference
    // without drag, from each logged state, one log step in 100 substeps.
    let model = ModelFile::rigid_body(THETA);
    let p = k_step_prediction(&s, &model, &[1]).unwrap();
    let mut y = Vec::new();
    let mut yhat = Vec::new();
    for i in 0..states.len() - 1 {
        let u = input(i as f64 * DT);
        let mut xi = states[i];
        for _ in 0..100 {
            xi = reference_step(&xi, &u, DT / 100.0, &[0.0; 3]);
        }
        y.push([states[i + 1][3], states[i + 1][4], states[i + 1][5]]);
        yhat.push([xi[3], xi[4], xi[5]]);
    }
    let hand = fit_percent(&y, &yhat).unwrap();
    let lib = p.horizons[0].fit.velocity.unwrap();
    assert!(hand < 99.9, "{hand}");
    assert!(
        (hand - lib).abs() < 1e-3 * (100.0 - hand),
        "{hand} vs {lib}"
    );
}

#[test]
fn state_driven_effects_give_their_own_columns_at_the_logged_state() {
    // A simulator log with rotor speeds (rotor drag and wind at the hubs) and one without
    // (the body-origin forms).
    let mut with_rotors = common::sim_log(Some(EffectKind::LinearDrag), 3);
    let mut without = with_rotors.clone();
    without.rotor_speeds = None;
    with_rotors.extra.clear();
    for log in [with_rotors, without] {
        let s = Signals::from_log(&log).unwrap();
        for effect in builtin_effects() {
            if effect.check(&s).is_err() {
                continue;
            }
            let param = effect.scan().map(|sc| sc.grid[sc.grid.len() / 2]);
            let columns = effect.columns(&s, param);
            for i in (0..s.len()).step_by(97) {
                let r = tagk_dynamics::log::attitude_quaternion(&log.attitude[i]);
                let state = BodyState {
                    position: Vector3::from(log.position[i]),
                    velocity: r * s.velocity_body[i],
                    attitude: r,
                    omega: Vector3::from(log.omega[i]),
                };
                let Some(at) = effect.columns_at(&s, i, &state, param) else {
                    continue;
                };
                assert_eq!(at.len(), columns.len(), "{}", effect.name());
                if effect.name() == tagk_diagnose::ACCEL_BIAS {
                    // A sensor error: no force on the body.
                    assert!(at.iter().flatten().all(|x| *x == 0.0));
                    continue;
                }
                for (col, w) in columns.iter().zip(&at) {
                    for c in 0..6 {
                        let expected = col.data[c].as_ref().map_or(0.0, |v| v[i]);
                        let scale = expected.abs().max(1e-3);
                        assert!(
                            (w[c] - expected).abs() <= 1e-12 * scale,
                            "{} column {} channel {c} sample {i}: {} vs {expected}",
                            effect.name(),
                            col.name,
                            w[c]
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn on_a_simulator_log_with_hidden_drag_the_true_model_predicts_far_better() {
    // Noise-free simulator log (50 Hz), linear drag hidden.
    let mut config = common::config(Some(EffectKind::LinearDrag), 5);
    config.noise = tagk_sim::NoiseLevel::None;
    config.record_truth = true;
    let drag = config.effects.linear_drag.as_ref().unwrap().coefficients;
    let out = tagk_sim::simulate(&config).unwrap();
    let truth = out.truth.as_ref().unwrap();
    let s = Signals::from_log(&out.log).unwrap();
    // The true models: the simulator's own parameters, with and without its drag.
    let theta = truth.samples[0].params.to_array();
    let rigid_true = ModelFile::rigid_body(theta);
    let mut drag_true = ModelFile::rigid_body(theta);
    drag_true.effects.push(ModelEffect {
        coefficients: drag_effect()
            .coefficients
            .into_iter()
            .zip(drag)
            .map(|(c, d)| ModelCoefficient { value: d, ..c })
            .collect(),
        ..drag_effect()
    });
    // The fitted models: the rigid body, and the rigid body + linear drag.
    let rigid_fit = Model::rigid_body().fit(&s).unwrap();
    let drag_fit = Model::rigid_body()
        .with_ref(builtin(EffectKind::LinearDrag).unwrap())
        .fit(&s)
        .unwrap();
    let file =
        |fit: &tagk_diagnose::Fit| ModelFile::from_fit(fit, &fit.effects, &ModelContext::default());
    let horizons = [1, 10, 50];
    let run = |m: &ModelFile| k_step_prediction(&s, m, &horizons).unwrap();
    let [p_rigid, p_drag, f_rigid, f_drag] = [
        run(&rigid_true),
        run(&drag_true),
        run(&file(&rigid_fit)),
        run(&file(&drag_fit)),
    ];
    for (name, p) in [
        ("true rigid", &p_rigid),
        ("true + drag", &p_drag),
        ("fitted rigid", &f_rigid),
        ("fitted + drag", &f_drag),
    ] {
        for e in &p.horizons {
            eprintln!(
                "{name:>13} h {:>2}: {:.3e} m {:.3e} m/s {:.3e} rad {:.3e} rad/s",
                e.h, e.position, e.velocity, e.attitude, e.body_rate
            );
        }
    }
    // h = 1 with the true model: the simulator's own RK4 at 2 ms against one RK4 step of
    // 20 ms, nothing else.
    let h1 = &p_drag.horizons[0];
    // The overlay at h = 1 of the true model follows the log sample by sample, component by
    // component; its mean error norms are the horizon's.
    let o = predict_logs(
        std::slice::from_ref(&s),
        Predictor::Model(&drag_true),
        &[1],
        &[1, 50],
    )
    .unwrap();
    assert_eq!(o.overlays.len(), 2);
    let o1 = &o.overlays[0];
    assert_eq!((o1.h, o1.log), (1, 0));
    assert_eq!(o1.t.len(), o1.error.position.len());
    assert!(
        o1.t.len() > s.len() * 9 / 10,
        "{} of {}",
        o1.t.len(),
        s.len()
    );
    // The first 0.1 s are the simulator's start (its first control step): left out of the
    // sample-by-sample check, kept in the mean. The body rate's bound is the log's: its
    // wrench is held over a 20 ms step, the simulator's is not.
    for (q, tol) in [1.5e-5, 3e-3, 5e-4, 0.1].into_iter().enumerate() {
        let worst = o1
            .logged
            .of(q)
            .iter()
            .zip(o1.predicted.of(q))
            .zip(&o1.t)
            .filter(|(_, t)| **t >= 0.1)
            .flat_map(|((a, b), _)| (0..3).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0_f64, f64::max);
        let peak = o1.peak(q).unwrap();
        eprintln!(
            "overlay h=1 quantity {q}: worst component difference {worst:e}, peak {:e} at {} s",
            peak.error, peak.t
        );
        assert!(worst < tol, "quantity {q}: {worst:e}");
        let mean = o1.error.of(q).iter().sum::<f64>() / o1.t.len() as f64;
        let from_horizon = [h1.position, h1.velocity, h1.attitude, h1.body_rate][q];
        assert!(
            (mean - from_horizon).abs() <= 1e-12 * from_horizon.max(1e-300),
            "{mean} vs {from_horizon}"
        );
    }
    // Each overlay point is the logged sample at its time.
    for (k, t) in o1.t.iter().enumerate().step_by(50) {
        let i = s.t.iter().position(|x| x == t).unwrap();
        assert_eq!(o1.logged.position[k], out.log.position[i]);
        assert_eq!(o1.logged.body_rate[k], out.log.omega[i]);
    }
    assert!(h1.position < 1e-6, "h=1 position {:e} m", h1.position);
    assert!(h1.velocity < 1e-4, "h=1 velocity {:e} m/s", h1.velocity);
    assert!(h1.attitude < 1e-5, "h=1 attitude {:e} rad", h1.attitude);
    assert!(h1.body_rate < 1e-3, "h=1 rate {:e} rad/s", h1.body_rate);
    for (truth_model, fitted) in [(&p_rigid, &p_drag), (&f_rigid, &f_drag)] {
        let (a, b) = (&truth_model.horizons[2], &fitted.horizons[2]);
        assert!(
            b.position * 5.0 < a.position,
            "{} vs {}",
            b.position,
            a.position
        );
        assert!(
            b.velocity * 5.0 < a.velocity,
            "{} vs {}",
            b.velocity,
            a.velocity
        );
    }
}

/// A log of `state(t)` sampled every `DT` for `n` samples, no wrench.
fn log_of(n: usize, state: impl Fn(f64) -> BodyState) -> FlightLog {
    let mut log = FlightLog::new();
    for k in 0..n {
        let t = k as f64 * DT;
        log.push(&sample(t, &state(t), [0.0; 6]));
    }
    log
}

#[test]
fn the_constant_rate_reference_is_exact_on_a_constant_rate_flight() {
    // Closed form: ω constant in the body, R(t) = R0 exp(t [ω]×), v constant, p linear. The
    // yaw turns through ±π several times (4 s at 2 rad/s about a tilted axis).
    let w = Vector3::new(0.4, -0.3, 2.0);
    let q0 = UnitQuaternion::from_euler_angles(0.2, -0.1, 2.9);
    let (p0, v0) = (Vector3::new(1.0, -2.0, 1.5), Vector3::new(0.3, 0.2, -0.1));
    let state = |t: f64| BodyState {
        position: p0 + v0 * t,
        velocity: v0,
        attitude: q0
            * UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(w), w.norm() * t),
        omega: w,
    };
    let s = Signals::from_log(&log_of(400, state)).unwrap();
    let p = constant_rate_prediction(&s, &[1, 10, 50]).unwrap();
    for e in &p.horizons {
        eprintln!("{e:?}");
        assert!(e.position < 1e-12, "h {}: {:e} m", e.h, e.position);
        assert!(e.velocity < 1e-12, "h {}: {:e} m/s", e.h, e.velocity);
        assert!(e.attitude < 1e-9, "h {}: {:e} rad", e.h, e.attitude);
        assert!(e.body_rate < 1e-12, "h {}: {:e} rad/s", e.h, e.body_rate);
    }
    // The rigid body of a flat disc spins about another axis: the test can tell them apart.
    let disc = ModelFile::rigid_body([0.03, 0.0, 0.0, 0.0, 1e-5, 0.0, 1e-5, 0.0, 0.0, 2e-5]);
    let r = k_step_prediction(&s, &disc, &[50]).unwrap();
    assert!(r.horizons[0].attitude > 1e-3, "{:?}", r.horizons[0]);
    // The overlay: the logged Euler angles unwrapped (no jump of 2π), the predicted ones on them.
    let o = predict_logs(
        std::slice::from_ref(&s),
        Predictor::ConstantRate,
        &[1],
        &[50],
    )
    .unwrap();
    let ov = &o.overlays[0];
    assert_eq!(ov.t.len(), 400 - 50);
    let yaw: Vec<f64> = ov.logged.attitude.iter().map(|a| a[2]).collect();
    assert!(yaw.windows(2).all(|w| (w[1] - w[0]).abs() < 0.1));
    assert!(
        yaw.last().unwrap() - yaw[0] > 4.0,
        "{} → {}",
        yaw[0],
        yaw.last().unwrap()
    );
    for (a, b) in ov.logged.attitude.iter().zip(&ov.predicted.attitude) {
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-9, "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn the_constant_rate_reference_misses_half_a_t_squared_under_constant_acceleration() {
    // p = p0 + v0 t + a t²/2, v = v0 + a t, attitude fixed, ω = 0: from t0 the held velocity
    // misses p(t0 + τ) by a τ²/2 and v by a τ, τ = k dt, whatever t0.
    let a = Vector3::new(0.6, -0.2, 1.1);
    let (p0, v0) = (Vector3::new(0.0, 1.0, 2.0), Vector3::new(-0.5, 0.4, 0.0));
    let q0 = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
    let state = |t: f64| BodyState {
        position: p0 + v0 * t + 0.5 * a * t * t,
        velocity: v0 + a * t,
        attitude: q0,
        omega: Vector3::zeros(),
    };
    let s = Signals::from_log(&log_of(300, state)).unwrap();
    let horizons = [1, 7, 50];
    let p = predict_logs(
        std::slice::from_ref(&s),
        Predictor::ConstantRate,
        &horizons,
        &[7],
    )
    .unwrap();
    for e in &p.horizons {
        let tau = e.h as f64 * DT;
        let (dp, dv) = (0.5 * a.norm() * tau * tau, a.norm() * tau);
        eprintln!(
            "h {}: {:e} vs {dp:e} m, {:e} vs {dv:e} m/s",
            e.h, e.position, e.velocity
        );
        assert!(
            (e.position - dp).abs() < 1e-9 * dp,
            "h {}: {} vs {dp}",
            e.h,
            e.position
        );
        assert!(
            (e.velocity - dv).abs() < 1e-9 * dv,
            "h {}: {} vs {dv}",
            e.h,
            e.velocity
        );
        assert!(e.attitude < 1e-12 && e.body_rate == 0.0, "{e:?}");
    }
    // The overlay at h = 7: each prediction is the closed form from 7 steps earlier.
    let ov = &p.overlays[0];
    for (k, t) in ov.t.iter().enumerate() {
        let t0 = t - 7.0 * DT;
        let start = state(t0);
        let expected = start.position + start.velocity * (7.0 * DT);
        for c in 0..3 {
            assert!((ov.predicted.position[k][c] - expected[c]).abs() < 1e-12);
            assert!((ov.predicted.velocity[k][c] - start.velocity[c]).abs() < 1e-12);
        }
    }
}

#[test]
fn a_comparison_with_overlays_round_trips_through_json_and_html() {
    let a = Vector3::new(0.6, -0.2, 1.1);
    let state = |t: f64| BodyState {
        position: 0.5 * a * t * t,
        velocity: a * t,
        attitude: UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3 * t),
        omega: Vector3::new(0.0, 0.0, 0.3),
    };
    let s = Signals::from_log(&log_of(200, state)).unwrap();
    let logs = std::slice::from_ref(&s);
    let model = ModelFile::rigid_body(THETA);
    let with = |overlays: &[usize]| Comparison {
        models: vec![
            ModelPrediction::new(
                "m.toml",
                predict_logs(logs, Predictor::Model(&model), &[1, 10], overlays).unwrap(),
            ),
            ModelPrediction::new(
                CONSTANT_RATE,
                predict_logs(logs, Predictor::ConstantRate, &[1, 10], overlays).unwrap(),
            ),
        ],
    };
    let c = with(&[2, 10]);
    let json: serde_json::Value = serde_json::from_str(&c.to_json().unwrap()).unwrap();
    let keys = |v: &serde_json::Value| {
        let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
        k.sort();
        k
    };
    assert_eq!(keys(&json), ["models"]);
    let m1 = &json["models"][1];
    assert_eq!(m1["model"], CONSTANT_RATE);
    assert_eq!(keys(m1), ["horizons", "model", "overlays"]);
    assert_eq!(m1["horizons"].as_array().unwrap().len(), 2);
    let o = &m1["overlays"][1];
    assert_eq!(
        keys(o),
        ["dt", "error", "h", "log", "logged", "predicted", "t"]
    );
    assert_eq!(
        keys(&o["logged"]),
        ["attitude", "body_rate", "position", "velocity"]
    );
    assert_eq!(o["h"], 10);
    // serde_json reads floats to within an ulp or so (no `float_roundtrip` feature).
    let back: Vec<f64> = serde_json::from_value(o["t"].clone()).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * a.abs().max(1.0);
    assert_eq!(back.len(), c.models[1].overlays[1].t.len());
    assert!(
        back.iter()
            .zip(&c.models[1].overlays[1].t)
            .all(|(a, b)| close(*a, *b))
    );
    let rate: Vec<[f64; 3]> = serde_json::from_value(o["predicted"]["body_rate"].clone()).unwrap();
    let ours = &c.models[1].overlays[1].predicted.body_rate;
    assert_eq!(rate.len(), ours.len());
    assert!(
        rate.iter()
            .zip(ours)
            .all(|(a, b)| (0..3).all(|k| close(a[k], b[k])))
    );
    // The series are written one per line, the rest as before.
    let text = c.to_json().unwrap();
    assert!(text.lines().count() < 200, "{} lines", text.lines().count());
    assert!(text.contains("\n          \"h\": 1,\n"), "{}", &text[..400]);
    // Without overlays, the old shape exactly.
    let plain: serde_json::Value = serde_json::from_str(&with(&[]).to_json().unwrap()).unwrap();
    assert_eq!(keys(&plain["models"][0]), ["horizons", "model"]);
    // The page: the error plots, then per horizon 4 error-over-time and 12 overlay plots.
    let html = tagk_diagnose::html::render_comparison(&c);
    assert_eq!(html.matches("<svg").count(), 4 + 2 * 16);
    assert!(html.contains("id=\"overlay-h2\"") && html.contains("id=\"overlay-h10\""));
    assert!(html.contains("body rate r [rad/s], h = 10"));
    let table = c.table();
    assert!(table.contains("constant-rate (reference"), "{table}");
    assert_eq!(table.matches("\nh   10 ").count(), 2, "{table}");
    // The logged rate is constant: the constant-rate reference has no body-rate error.
    assert_eq!(c.models[1].overlays[1].peak(3).unwrap().error, 0.0);
    // A zero overlay horizon is refused.
    assert!(predict_logs(logs, Predictor::ConstantRate, &[1], &[0]).is_err());
}
