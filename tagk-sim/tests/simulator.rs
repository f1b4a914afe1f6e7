//! Physics, measurement, configuration and driver tests of tagk-sim.

use nalgebra::{UnitQuaternion, Vector3};
use tagk_dynamics::{InertialParams, QuadrotorModel, rigid_body_regressor};
use tagk_sim::metrics::{UpdateTimes, group_errors, is_success, parameter_error};
use tagk_sim::plant_effects::{GroundEffect, LinearDrag, MotorLag, RotorDrag};
use tagk_sim::sim::{prioritise_attitude, tracking_weights};
use tagk_sim::trajectory::{PEAK_RATE, PEAK_SPEED, ReferenceSample};
use tagk_sim::*;

fn payload_body() -> InertialParams {
    QuadrotorModel::crazyflie_2_1()
        .params
        .with_point_mass(0.014, Vector3::new(0.008, -0.004, 0.002))
}

/// Energy `½ m |v_c|² + ½ ωᵀ I_C ω + m g z_c` and world angular momentum about the centre of
/// mass `R I_C ω`, computed from the state directly (not through the simulator's dynamics).
fn invariants(p: &InertialParams, s: &PlantState) -> (f64, Vector3<f64>) {
    let c = p.com();
    let r = s.attitude.to_rotation_matrix();
    let v_c = s.velocity + r * s.body_rate.cross(&c);
    let z_c = (s.position + r * c).z;
    let ic = p.inertia_com();
    let e = 0.5 * p.mass() * v_c.norm_squared()
        + 0.5 * s.body_rate.dot(&(ic * s.body_rate))
        + p.mass() * 9.81 * z_c;
    (e, r * (ic * s.body_rate))
}

#[test]
fn free_flight_conserves_energy_and_angular_momentum() {
    let params = payload_body();
    let state = PlantState {
        position: Vector3::new(0.1, -0.2, 1.0),
        velocity: Vector3::new(0.3, 0.1, 2.0),
        attitude: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
        body_rate: Vector3::new(3.0, -2.0, 5.0),
        rotor_speeds: [0.0; 4],
    };
    let mut plant = Plant::new(
        QuadrotorModel::crazyflie_2_1(),
        params,
        PlantEffects::none(),
        state,
    )
    .unwrap();
    let (e0, l0) = invariants(&params, plant.state());
    for _ in 0..1000 {
        plant.step(&[0.0; 4], 1e-3);
    }
    let (e1, l1) = invariants(&params, plant.state());
    // Kinetic energy scale ~ ½ m v² ≈ 0.07 J; RK4 at 1 ms over 1 s keeps ~1e-10.
    assert!((e1 - e0).abs() < 1e-9, "energy drift {}", e1 - e0);
    assert!(
        (l1 - l0).norm() < 1e-10 * l0.norm().max(1e-9) + 1e-13,
        "L drift {}",
        (l1 - l0).norm()
    );
    // The body really tumbled: the attitude moved far from its start.
    assert!(plant.state().attitude.angle_to(&state.attitude) > 0.5);
}

#[test]
fn hover_holds_with_true_parameters() {
    let model = QuadrotorModel::crazyflie_2_1();
    let params = payload_body();
    let target = Vector3::new(0.0, 0.0, 1.0);
    let mut plant = Plant::new(
        model,
        params,
        PlantEffects::none(),
        PlantState::at_rest(target + Vector3::new(0.01, -0.01, 0.01)),
    )
    .unwrap();
    let controller = Controller::new(&model, &params, tracking_weights(), 0.02).unwrap();
    let reference = ReferenceSample {
        position: target,
        velocity: Vector3::zeros(),
        acceleration: Vector3::zeros(),
        yaw: 0.0,
        yaw_rate: 0.0,
    };
    for _ in 0..250 {
        let s = plant.state();
        let measured = tagk_control::QuadrotorState {
            position: s.position,
            velocity: s.velocity,
            attitude: s.attitude,
            body_rate: s.body_rate,
        };
        let cmd = controller.rotor_speeds(&measured, &reference);
        for _ in 0..10 {
            plant.step(&cmd, 0.002);
        }
    }
    let err = (plant.state().position - target).norm();
    assert!(err < 1e-3, "hover error {err} m");
    assert!(plant.state().velocity.norm() < 1e-3);
}

#[test]
fn ideal_measured_wrench_equals_regressor_times_true_parameters() {
    let model = QuadrotorModel::crazyflie_2_1();
    let params = payload_body();
    let state = PlantState {
        position: Vector3::new(0.0, 0.0, 1.0),
        velocity: Vector3::new(0.2, -0.1, 0.05),
        attitude: UnitQuaternion::from_euler_angles(0.1, 0.05, -0.3),
        body_rate: Vector3::new(0.7, -1.1, 0.4),
        rotor_speeds: [0.0; 4],
    };
    let plant = Plant::new(model, params, PlantEffects::none(), state).unwrap();
    let cmd = [1100.0, 1250.0, 1180.0, 1020.0];
    let acc = plant.accelerations(&cmd);
    let y = rigid_body_regressor(&acc.proper, &state.body_rate, &acc.angular);
    let b = model.wrench_from_rotor_speeds(&cmd).to_array();
    let yt = y * nalgebra::SVector::<f64, 10>::from_column_slice(params.as_slice());
    for i in 0..6 {
        let scale: f64 = if i < 3 { 1.0 } else { 1e-3 };
        assert!(
            (yt[i] - b[i]).abs() < 1e-14 * scale.max(b[i].abs()),
            "row {i}: {} vs {}",
            yt[i],
            b[i]
        );
    }
}

#[test]
fn logged_frames_satisfy_the_regressor_in_closed_loop() {
    let cfg = SimConfig {
        duration: 8.0,
        seed: 3,
        adaptation: Adaptation::Oracle,
        record_log: true,
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    assert_eq!(out.log.len(), 400);
    let nominal = cfg.vehicle.params;
    let mut worst: f64 = 0.0;
    for s in out.log.samples() {
        let truth = out
            .events
            .iter()
            .rev()
            .find(|e| e.time < s.t)
            .map_or(nominal, |e| InertialParams::from_array(e.params));
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            s.attitude[0],
            s.attitude[1],
            s.attitude[2],
            s.attitude[3],
        ));
        let a = q.inverse_transform_vector(
            &(Vector3::from(s.accel.unwrap()) - tagk_dynamics::GRAVITY_WORLD),
        );
        let y = rigid_body_regressor(
            &a,
            &Vector3::from(s.omega),
            &Vector3::from(s.omega_dot.unwrap()),
        );
        let yt = y * nalgebra::SVector::<f64, 10>::from_column_slice(truth.as_slice());
        // Force rows against the thrust, torque rows against the gravity torque scale.
        for i in 0..6 {
            let scale: f64 = if i < 3 { 0.3 } else { 3e-4 };
            worst = worst.max((yt[i] - s.wrench[i]).abs() / scale);
        }
    }
    // Only the midpoint sampling and the differenced gyro separate b from Y θ.
    assert!(worst < 1e-3, "worst relative residual {worst}");
}

#[test]
fn payload_attach_changes_theta_as_computed_by_hand() {
    let payload = Payload {
        mass: 0.014,
        offset: [0.008, -0.004, 0.002],
        shape: PayloadShape::PointMass,
        attach_time: 1.0,
        remove_time: Some(2.0),
    };
    let cfg = SimConfig {
        duration: 3.0,
        payload: PayloadSchedule::Fixed(vec![payload]),
        adaptation: Adaptation::Oracle,
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    assert_eq!(out.events.len(), 2);
    // Hand computation: m' = m + m_p, h' = m_p c, I' = I + m_p (|c|² 1 − c cᵀ).
    let expected = [
        0.035 + 0.014,
        0.014 * 0.008,
        0.014 * -0.004,
        0.014 * 0.002,
        1.66e-5 + 0.014 * (0.004f64.powi(2) + 0.002f64.powi(2)),
        0.83e-6 - 0.014 * (0.008 * -0.004),
        1.66e-5 + 0.014 * (0.008f64.powi(2) + 0.002f64.powi(2)),
        0.72e-6 - 0.014 * (0.008 * 0.002),
        1.8e-6 - 0.014 * (-0.004 * 0.002),
        2.93e-5 + 0.014 * (0.008f64.powi(2) + 0.004f64.powi(2)),
    ];
    for (got, want) in out.events[0].params.iter().zip(&expected) {
        assert!((got - want).abs() < 1e-15, "{got} vs {want}");
    }
    assert!(out.events[0].attach && !out.events[1].attach);
    assert!((out.events[0].time - 1.0).abs() < 1e-12);
    for (got, want) in out.events[1]
        .params
        .iter()
        .zip(cfg.vehicle.params.as_slice())
    {
        assert!((got - want).abs() < 1e-15);
    }
}

#[test]
fn bad_configurations_are_rejected_with_typed_errors() {
    let mut cfg = SimConfig::default();
    cfg.vehicle.params = InertialParams::from_array([
        -0.035, 0.0, 0.0, 0.0, 1.66e-5, 0.0, 1.66e-5, 0.0, 0.0, 2.93e-5,
    ]);
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::NonPositiveMass { .. })
    ));

    let cfg = SimConfig {
        duration: 0.0,
        ..SimConfig::default()
    };
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::InvalidDuration { .. })
    ));

    let mut cfg = SimConfig {
        altitude: Some(f64::NAN),
        ..SimConfig::default()
    };
    assert!(matches!(
        cfg.validate(),
        Err(SimError::InvalidParameter {
            name: "altitude",
            ..
        })
    ));
    cfg.altitude = None;
    cfg.gate.max_com_offset = 0.0;
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::InvalidParameter {
            name: "gate.max_com_offset",
            ..
        })
    ));

    let heavy = Payload {
        mass: 0.03,
        offset: [0.0, 0.0, 0.0],
        shape: PayloadShape::PointMass,
        attach_time: 1.0,
        remove_time: None,
    };
    let cfg = SimConfig {
        payload: PayloadSchedule::Fixed(vec![heavy]),
        ..SimConfig::default()
    };
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::PayloadBeyondThrust { .. })
    ));

    let negative = Payload {
        mass: -0.01,
        ..heavy
    };
    let cfg = SimConfig {
        payload: PayloadSchedule::Fixed(vec![negative]),
        ..SimConfig::default()
    };
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::NonPositiveMass { .. })
    ));

    let cfg = SimConfig {
        physics_dt: 0.005,
        ..SimConfig::default()
    };
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::InvalidParameter { .. })
    ));

    let mut cfg = SimConfig::default();
    cfg.effects.motor_lag = Some(MotorLag {
        time_constant: -1.0,
    });
    assert!(matches!(
        simulate(&cfg),
        Err(SimError::InvalidParameter { .. })
    ));
}

#[test]
fn trajectories_respect_the_peak_speed_and_rate() {
    use rand_chacha::rand_core::SeedableRng;
    for kind in TrajectoryKind::ALL {
        for seed in 0..5 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let t = Trajectory::random(kind, 20.0, None, &mut rng).unwrap();
            assert!(t.rate > 0.1 && t.rate <= PEAK_RATE);
            let mut peak: f64 = 0.0;
            for i in 0..=2000 {
                peak = peak.max(t.sample(i as f64 * 0.01).velocity.norm());
            }
            assert!(peak <= PEAK_SPEED, "{kind:?} peak {peak}");
            assert!(peak > 0.2, "{kind:?} too slow: {peak}");
            // Starts from rest.
            assert!(t.sample(0.0).velocity.norm() < 1e-3);
        }
    }
}

#[test]
fn effects_follow_their_formulas() {
    let g = GroundEffect::crazyflie();
    assert!((g.thrust_ratio(g.rotor_radius) - 16.0 / 15.0).abs() < 1e-12);
    assert!((g.thrust_ratio(1.0) - 1.0).abs() < 1e-4);
    let fx = PlantEffects::only(EffectKind::RotorDrag).unwrap();
    let q = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
    let hubs = QuadrotorModel::crazyflie_2_1().rotor_positions;
    let at_rest = Vector3::zeros();
    // World velocity +x is body −y after a 90° yaw; equal rotor speeds, no body rate: the
    // body-origin form, and no moment.
    let w = fx.extra_wrench(
        &Vector3::new(1.0, 0.0, 0.0),
        &q,
        &at_rest,
        &[1000.0; 4],
        &hubs,
    );
    let k = RotorDrag::crazyflie().coefficients;
    assert!((w.force - Vector3::new(0.0, k[1] * 4000.0, 0.0)).norm() < 1e-15);
    assert!(w.torque.norm() < 1e-20);
    // Plain linear drag does not depend on the rotor speeds.
    let lin = PlantEffects::only(EffectKind::LinearDrag).unwrap();
    let f = lin
        .extra_wrench(
            &Vector3::new(1.0, 0.0, 0.0),
            &q,
            &at_rest,
            &[1000.0; 4],
            &hubs,
        )
        .force;
    let d = LinearDrag::crazyflie().coefficients;
    assert!((f - Vector3::new(0.0, d[1], 0.0)).norm() < 1e-15);
    let te = PlantEffects::only(EffectKind::ThrustGain).unwrap();
    assert!((te.thrust_multiplier(1.0) - 0.9).abs() < 1e-15);
    for kind in PlantEffects::supported() {
        let e = PlantEffects::only(kind).unwrap();
        assert!(!e.is_ideal());
        e.validate().unwrap();
        // Each effect changes a flight relative to the ideal plant.
        let cfg = |effects| SimConfig {
            duration: 2.0,
            altitude: Some(0.05),
            payload: PayloadSchedule::None,
            adaptation: Adaptation::Nominal,
            effects,
            record_log: true,
            ..SimConfig::default()
        };
        let a = simulate(&cfg(PlantEffects::none())).unwrap();
        let b = simulate(&cfg(e)).unwrap();
        if kind == EffectKind::TimeDelay {
            // The same flight; the logged wrench stream lags the motion by one 20 ms step.
            assert_eq!(a.log.position, b.log.position);
            assert_eq!(b.log.wrench[0], a.log.wrench[0]);
            assert_eq!(&b.log.wrench[1..], &a.log.wrench[..a.log.len() - 1]);
            let (ra, rb) = (a.log.rotor_speeds.unwrap(), b.log.rotor_speeds.unwrap());
            assert_eq!(&rb[1..], &ra[..ra.len() - 1]);
        } else if kind == EffectKind::TelemetryLag {
            // The same flight; the logged rotor speeds are the ideal flight's through the
            // telemetry filter (`TelemetryLag::reported`, run over the whole series).
            assert_eq!(a.log.position, b.log.position);
            let (ra, rb) = (a.log.rotor_speeds.unwrap(), b.log.rotor_speeds.unwrap());
            let lag = e.telemetry_lag.unwrap();
            let expected = lag.reported(&ra, SimConfig::default().control_dt);
            assert_ne!(rb, ra);
            for (x, y) in rb.iter().zip(&expected) {
                for r in 0..4 {
                    assert!((x[r] - y[r]).abs() <= 1e-9 * y[r].abs(), "{x:?} {y:?}");
                }
            }
        } else {
            assert_ne!(
                a.log.position.last().unwrap(),
                b.log.position.last().unwrap(),
                "{kind:?}"
            );
        }
    }
    // Commands are held over each 20 ms interval and samples sit at the midpoints: a 15 ms
    // delay reaches back into the previous interval.
    let half = PlantEffects {
        time_delay: Some(tagk_sim::plant_effects::TimeDelay { delay: 0.015 }),
        ..PlantEffects::none()
    };
    let cfg = SimConfig {
        duration: 1.0,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        effects: half,
        record_log: true,
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    let ideal = simulate(&SimConfig {
        effects: PlantEffects::none(),
        ..cfg
    })
    .unwrap();
    assert_eq!(out.log.wrench[5], ideal.log.wrench[4]);
}

#[test]
fn attitude_priority_keeps_torque_differences() {
    let out = prioritise_attitude([0.15, 0.12, 0.10, 0.13], 0.14);
    let d = |u: [f64; 4]| [u[0] - u[1], u[1] - u[2], u[2] - u[3]];
    let (a, b) = (d(out), d([0.15, 0.12, 0.10, 0.13]));
    for i in 0..3 {
        assert!((a[i] - b[i]).abs() < 1e-15);
    }
    assert!((out[0] - 0.14).abs() < 1e-15);
    // Infeasible spread: clipped.
    let out = prioritise_attitude([0.2, -0.1, 0.0, 0.0], 0.14);
    assert!(out.iter().all(|t| (0.0..=0.14).contains(t)));
}

#[test]
fn metrics_match_direct_computation() {
    let truth = payload_body();
    let mut est = truth.to_array();
    est[0] += 0.0035;
    est[1] += 3e-5;
    est[2] -= 4e-5;
    est[4] *= 1.1;
    let pe = parameter_error(&est, &truth);
    let direct = (0.0035f64.powi(2)
        + 3e-5f64.powi(2)
        + 4e-5f64.powi(2)
        + (0.1 * truth.as_slice()[4]).powi(2))
    .sqrt();
    assert!((pe - direct).abs() < 1e-15);
    let g = group_errors(&est, &truth, 0.0325);
    assert!((g.mass - 0.0035 / 0.049).abs() < 1e-12);
    assert!((g.first_moment - 5e-5 / (0.049 * 0.0325)).abs() < 1e-9);
    assert!(g.inertia > 0.0 && g.inertia < 0.1);
    let errs = [0.01; 30];
    assert!(is_success(&errs, &[5], false));
    let mut bad = errs;
    bad[15] = 0.06;
    assert!(!is_success(&bad, &[5], false));
    assert!(is_success(&bad, &[6], false));
    let mut h = UpdateTimes::new();
    let mut v: Vec<f64> = (1..=1000).map(|i| i as f64 * 0.37).collect();
    for x in &v {
        h.record(*x);
    }
    v.sort_by(f64::total_cmp);
    assert!((h.median() / v[499] - 1.0).abs() < 0.011);
    assert!((h.p95() / v[949] - 1.0).abs() < 0.011);
}

#[test]
fn log_csv_has_the_conventions_header() {
    let cfg = SimConfig {
        duration: 0.5,
        record_log: true,
        payload: PayloadSchedule::None,
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    let mut buf = Vec::new();
    out.log.write_csv(&mut buf).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,px,py,pz,vx,vy,vz,qw,qx,qy,qz,wx,wy,wz,fx,fy,fz,tx,ty,tz,ax,ay,az,dwx,dwy,dwz,w1,w2,w3,w4"
    );
    assert_eq!(lines.count(), 25);
    let mut rev = out.log.clone();
    rev.t.reverse();
    assert!(matches!(
        rev.write_csv(Vec::new()),
        Err(LogError::NonIncreasingTime { line: 3, .. })
    ));
}

// Thread counts need the rayon driver (the root package enables it for the workspace).
#[cfg(feature = "parallel")]
#[test]
fn sweep_is_identical_at_one_and_two_threads() {
    let mut sweep = Sweep::new(
        vec![
            EstimatorSpec::new(EstimatorKind::TagK),
            EstimatorSpec::new(EstimatorKind::KfHigh),
        ],
        3,
        11,
    );
    sweep.noise_levels = vec![NoiseLevel::None, NoiseLevel::High];
    sweep.base.duration = 7.0;
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| sweep.run())
            .unwrap()
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.threads, 1);
    assert_eq!(b.threads, 2);
    assert_eq!(a.cells.len(), 4);
    for (x, y) in a.cells.iter().zip(&b.cells) {
        assert_eq!(x.trials, 3);
        let same = |p: f64, q: f64| (p.is_nan() && q.is_nan()) || p == q;
        assert!(same(x.position_error_cm, y.position_error_cm));
        assert!(same(x.parameter_error, y.parameter_error));
        assert!(same(x.t1_error, y.t1_error));
        assert_eq!(x.success_pct, y.success_pct);
        assert_eq!(x.aborted_pct, y.aborted_pct);
        assert_eq!(x.position_errors.len(), y.position_errors.len());
        for (p, q) in x.position_errors.iter().zip(&y.position_errors) {
            assert!(same(*p, *q));
        }
    }
    let table = a.table();
    assert!(table.contains("TAG-K") && table.contains("KF-high"));
    assert!(Sweep::new(vec![], 3, 0).run().is_err());
}

/// Counts the progress reports and records the order in which trials are folded.
#[cfg(feature = "parallel")]
#[derive(Default)]
struct Recorder {
    finished: std::sync::atomic::AtomicUsize,
    folded: Vec<(usize, usize)>,
    ended: bool,
}

#[cfg(feature = "parallel")]
impl SweepObserver for Recorder {
    fn trial_finished(&self, done: usize, total: usize) {
        assert!(done >= 1 && done <= total);
        self.finished
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
    fn fold_trial(&mut self, cell: usize, trial: usize, output: &SimOutput) {
        // The error curves ask every trial for its trace.
        assert!(!output.trace.is_empty());
        self.folded.push((cell, trial));
    }
    fn sweep_finished(&mut self) {
        self.ended = true;
    }
}

// Thread counts need the rayon driver (the root package enables it for the workspace).
#[cfg(feature = "parallel")]
#[test]
fn observers_see_every_trial_in_trial_order_at_any_thread_count() {
    let mut sweep = Sweep::new(
        vec![
            EstimatorSpec::new(EstimatorKind::TagK),
            EstimatorSpec::new(EstimatorKind::RlsLow),
        ],
        3,
        4,
    );
    sweep.noise_levels = vec![NoiseLevel::Medium];
    sweep.base.duration = 6.0;
    sweep.base.payload = PayloadSchedule::ProtocolAt {
        attach: 2.0,
        remove: 4.0,
    };
    let run = |threads| {
        let mut curves = ErrorCurves::new();
        let mut traces = Traces::first(1);
        let mut recorder = Recorder::default();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| sweep.run_with(&mut (&mut recorder, (&mut curves, &mut traces))))
            .unwrap();
        (curves, traces, recorder)
    };
    let (c1, t1, r1) = run(1);
    let (c2, t2, r2) = run(2);
    // Trial-major job order, folded in that order.
    let expected: Vec<(usize, usize)> = (0..3).flat_map(|t| (0..2).map(move |c| (c, t))).collect();
    for r in [&r1, &r2] {
        assert_eq!(r.folded, expected);
        assert_eq!(r.finished.load(std::sync::atomic::Ordering::Relaxed), 6);
        assert!(r.ended);
    }
    for cell in 0..2 {
        let (a, b) = (c1.curve(cell), c2.curve(cell));
        assert_eq!(a.len(), 300);
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
        assert_eq!(t1.of_cell(cell).len(), 1);
        assert_eq!(t1.of_cell(cell), t2.of_cell(cell));
    }
    // The curve is the mean of the trials' traces, computed here from the traces directly.
    let mut direct = Traces::first(3);
    sweep.run_with(&mut direct).unwrap();
    let mean0: f64 = direct
        .of_cell(0)
        .iter()
        .map(|t| t[0].parameter_error)
        .sum::<f64>()
        / 3.0;
    assert!((c1.curve(0)[0] - mean0).abs() <= 1e-15 * mean0.abs());
}

#[cfg(feature = "plot")]
#[test]
fn figures_render_with_the_embedded_font() {
    let dir = std::env::temp_dir().join(format!("tagk-sim-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let chart = plot::LineChart {
        title: "test".into(),
        x_label: "x".into(),
        y_label: "y".into(),
        log_y: true,
        series: vec![plot::ChartSeries {
            label: "a".into(),
            points: vec![(0.0, 1.0), (1.0, 10.0)],
        }],
        markers: vec![0.5],
        ..Default::default()
    };
    plot::line_chart(&dir.join("c"), &chart).unwrap();
    assert!(std::fs::metadata(dir.join("c.png")).unwrap().len() > 1000);
    let svg = std::fs::read_to_string(dir.join("c.svg")).unwrap();
    assert!(svg.contains("test"));
    // A categorical axis labels its categories; Unicode symbols survive; the PNG is drawn at
    // twice the SVG's size (1800 px wide: 300 dpi at 6 in).
    let categorical = plot::LineChart {
        title: "categories".into(),
        x_label: "noise level".into(),
        y_label: "‖Δθ‖₂ [µs]".into(),
        series: vec![
            plot::ChartSeries {
                label: "same".into(),
                points: vec![(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)],
            },
            plot::ChartSeries {
                label: "same again".into(),
                points: vec![(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)],
            },
        ],
        x_categories: vec!["none".into(), "low".into(), "medium".into()],
        ..Default::default()
    };
    plot::line_chart(&dir.join("k"), &categorical).unwrap();
    let svg = std::fs::read_to_string(dir.join("k.svg")).unwrap();
    for label in ["none", "low", "medium", "‖Δθ‖₂ [µs]", "same again"] {
        assert!(svg.contains(label), "{label} missing");
    }
    let png = std::fs::read(dir.join("k.png")).unwrap();
    // PNG header: width and height as big-endian u32 at bytes 16..24.
    let width = u32::from_be_bytes(png[16..20].try_into().unwrap());
    assert_eq!(width, 900 * plot::PNG_SCALE);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn tuned_tagk_identifies_the_payload_in_closed_loop() {
    let cfg = SimConfig {
        seed: 5,
        adaptation: Adaptation::Estimator(estimators::tagk_tuned()),
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    assert!(out.metrics.success && !out.metrics.aborted);
    assert_eq!(out.events.len(), 2);
    // Just before the removal the estimate carries the payload's mass to within 2 %.
    let before_removal = out
        .updates
        .iter()
        .rev()
        .find(|u| u.time < out.events[1].time)
        .unwrap();
    let m_true = before_removal.truth[0];
    assert!(m_true > 0.035 * 1.29);
    assert!((before_removal.estimate[0] - m_true).abs() < 0.02 * m_true);
    assert!(out.updates.iter().filter(|u| u.accepted).count() > 40);
}
