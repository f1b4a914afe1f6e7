//! The noise-free truth of a flight (`SimConfig::record_truth`): recording it changes no bit of
//! the flight, its effect wrenches add up to the wrench acting, and with ideal sensors it
//! reproduces the log to the discretisation of the logged angular acceleration, for every
//! effect of the vocabulary.

use tagk_dynamics::nalgebra::{Quaternion, UnitQuaternion, Vector3};
use tagk_dynamics::{GRAVITY_WORLD, newton_euler};
use tagk_sim::plant_effects::{MotorLag, TimeDelay};
use tagk_sim::{
    Adaptation, EffectKind, FlightStack, FlightTruth, LogRate, Payload, PayloadSchedule,
    PayloadShape, PlantEffects, Sensing, SimConfig, SimOutput, TrajectoryKind, simulate,
};

/// A 6 s flight with a payload fixed from t = 0, the oracle controller and a turning heading.
fn config(effects: PlantEffects, sensing: Sensing, seed: u64) -> SimConfig {
    SimConfig {
        trajectory: TrajectoryKind::ALL[seed as usize % 5],
        duration: 6.0,
        seed,
        sensing,
        yaw_rate: 0.3,
        payload: PayloadSchedule::Fixed(vec![Payload {
            mass: 0.006,
            offset: [0.004, -0.003, 0.002],
            shape: PayloadShape::PointMass,
            attach_time: 0.0,
            remove_time: None,
        }]),
        effects,
        adaptation: Adaptation::Oracle,
        altitude: effects.ground_effect.map(|_| 0.06),
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    }
}

/// Every plant effect of the vocabulary at once (a 10 ms lag, a one-sample delay).
fn every_effect() -> PlantEffects {
    let mut e = EffectKind::ALL
        .into_iter()
        .try_fold(PlantEffects::none(), |e, k| e.with(k))
        .unwrap();
    e.motor_lag = Some(MotorLag {
        time_constant: 0.01,
    });
    e
}

fn bits(out: &SimOutput) -> Vec<u64> {
    let l = &out.log;
    let mut v: Vec<u64> = l.t.iter().map(|x| x.to_bits()).collect();
    let mut push = |xs: &[f64]| v.extend(xs.iter().map(|x| x.to_bits()));
    for i in 0..l.len() {
        push(&l.position[i]);
        push(&l.velocity[i]);
        push(&l.attitude[i]);
        push(&l.omega[i]);
        push(&l.wrench[i]);
        if let Some(a) = &l.accel {
            push(&a[i]);
        }
        if let Some(a) = &l.omega_dot {
            push(&a[i]);
        }
        if let Some(w) = &l.rotor_speeds {
            push(&w[i]);
        }
    }
    push(&out.tracking_errors);
    v
}

/// The flight and its log are the same bits with and without the truth, for the ideal and the
/// realistic sensors, every effect at once, the physics-rate log and the motor telemetry.
#[test]
fn recording_the_truth_changes_no_bit_of_the_flight() {
    let cases: Vec<SimConfig> = vec![
        config(PlantEffects::none(), Sensing::ideal(), 1),
        config(every_effect(), Sensing::realistic(), 2),
        SimConfig {
            log_rate: LogRate::Physics,
            ..config(every_effect(), Sensing::realistic(), 3)
        },
        SimConfig {
            flight_stack: FlightStack::realistic(),
            ..config(every_effect(), Sensing::realistic_calibrated(), 4)
        },
    ];
    for (i, cfg) in cases.into_iter().enumerate() {
        let without = simulate(&cfg).unwrap();
        let with = simulate(&SimConfig {
            record_truth: true,
            ..cfg.clone()
        })
        .unwrap();
        assert!(without.truth.is_none(), "case {i}");
        let truth = with.truth.as_ref().expect("recorded");
        assert_eq!(truth.samples.len(), with.log.len(), "case {i}");
        assert!(!with.log.is_empty());
        assert_eq!(bits(&without), bits(&with), "case {i}");
        // Debug strings: NaN metrics (no estimator) are equal there.
        assert_eq!(
            format!("{:?}", without.metrics),
            format!("{:?}", with.metrics),
            "case {i}"
        );
        assert_eq!(without.events, with.events, "case {i}");
        for (s, t) in truth.samples.iter().zip(&with.log.t) {
            assert_eq!(s.t.to_bits(), t.to_bits(), "case {i}");
        }
    }
}

/// `reference_trajectory` draws the path the flight flies.
#[test]
fn the_reference_trajectory_is_the_one_flown() {
    for seed in 0..5 {
        let cfg = config(PlantEffects::none(), Sensing::realistic(), seed);
        assert_eq!(
            cfg.reference_trajectory().unwrap(),
            simulate(&cfg).unwrap().trajectory
        );
    }
}

/// The largest `|residual|` over the samples, forces relative to the truth's RMS force and
/// torques to its RMS torque: `[forces, torques]`.
fn worst(truth: &FlightTruth, residual: impl Fn(usize) -> [f64; 6]) -> [f64; 2] {
    let n = truth.samples.len() as f64;
    let rms = |r: std::ops::Range<usize>| {
        (truth
            .samples
            .iter()
            .map(|s| r.clone().map(|c| s.wrench[c].powi(2)).sum::<f64>())
            .sum::<f64>()
            / n)
            .sqrt()
    };
    let (f, t) = (rms(0..3), rms(3..6));
    let mut out = [0.0f64; 2];
    for i in 0..truth.samples.len() {
        for (c, r) in residual(i).iter().enumerate() {
            let k = usize::from(c >= 3);
            out[k] = out[k].max(r.abs() / if k == 0 { f } else { t });
        }
    }
    out
}

/// The effect wrenches add up: `wrench = logged_actuator_wrench + Σ effect_wrenches` to
/// rounding (1e-12 of the force and torque scales), likewise on the log's terms, and `wrench =
/// Y θ` of the true motion at the instant.
#[test]
fn the_effect_wrenches_add_up_to_the_wrench_acting() {
    for (seed, log_rate) in [(5, LogRate::Control), (6, LogRate::Physics)] {
        let cfg = SimConfig {
            record_truth: true,
            log_rate,
            ..config(every_effect(), Sensing::realistic(), seed)
        };
        let out = simulate(&cfg).unwrap();
        let truth = out.truth.unwrap();
        assert_eq!(truth.effects, EffectKind::ALL.to_vec());
        for logged in [false, true] {
            let sum = worst(&truth, |i| {
                let s = &truth.samples[i];
                let (total, parts) = if logged {
                    (&s.logged_wrench, &s.logged_effect_wrenches)
                } else {
                    (&s.wrench, &s.effect_wrenches)
                };
                std::array::from_fn(|c| {
                    total[c] - s.logged_actuator_wrench[c] - parts.iter().map(|w| w[c]).sum::<f64>()
                })
            });
            assert!(sum[0] < 1e-12 && sum[1] < 1e-12, "{sum:?}");
        }
        let motion = worst(&truth, |i| {
            let s = &truth.samples[i];
            let w = newton_euler(
                &s.params,
                &Vector3::from(s.proper_acceleration),
                &Vector3::from(s.body_rate),
                &Vector3::from(s.angular_acceleration),
            )
            .to_array();
            std::array::from_fn(|c| s.wrench[c] - w[c])
        });
        assert!(motion[0] < 1e-12 && motion[1] < 1e-12, "{motion:?}");
        if log_rate == LogRate::Physics {
            let s = &truth.samples[7];
            assert_eq!(s.logged_wrench, s.wrench);
            assert_eq!(s.logged_angular_acceleration, s.angular_acceleration);
        }
        // The payload is part of the body from the start.
        let m = truth.samples[0].params.mass();
        assert!((m - 0.041).abs() < 1e-12, "{m}");
    }
}

/// Ideal sensors: the logged wrench minus `Y θ_true` of the **logged** motion plus the effects'
/// wrenches on the log's terms (they act beside the actuators, `b = Y θ − w`) is what the
/// log's discretisation leaves, for every single effect of the vocabulary at its Crazyflie
/// magnitude (motor lag 20 ms, delay 2 samples, ground effect at 6 cm; a wind without drag
/// brings its implicit rotor drag). What remains: the logged `ω̇` is the interval mean while
/// `a` and `ω` are the midpoint's, and the gyroscopic and first-moment terms (`ω × I ω`,
/// `ω̇ × h`, `h × a`) are not linear over the interval. Measured on the worst sample, relative
/// to the RMS force and torque: forces ≤ 8.5e-7 and torques ≤ 5.9e-4 for every effect but the
/// motor lag, which shapes `ω̇` within the interval: 9.3e-5 and 4.3e-3 (bounds 1e-5 / 1e-3,
/// and 2e-4 / 1e-2 for the lag). The rotor inertia's jumps at each command (no motor lag)
/// reach the forces through `ω̇ × h`: 3.0e-4 and 3.9e-4 (bounds 5e-4 / 1e-3). Without the
/// effects' wrenches the residual is 10× larger or more on some channel.
#[test]
fn with_ideal_sensors_the_truth_reproduces_the_log_for_every_effect() {
    for (seed, kind) in EffectKind::ALL.into_iter().enumerate() {
        let mut effects = PlantEffects::only(kind).unwrap();
        if kind == EffectKind::TimeDelay {
            effects.time_delay = Some(TimeDelay { delay: 0.04 });
        }
        let cfg = SimConfig {
            record_truth: true,
            ..config(effects, Sensing::ideal(), 10 + seed as u64)
        };
        let out = simulate(&cfg).unwrap();
        assert!(!out.metrics.aborted, "{kind}");
        let truth = out.truth.unwrap();
        // A wind without drag effect acts through the implicit rotor drag, listed beside it.
        let listed = if kind == EffectKind::Wind {
            vec![EffectKind::RotorDrag, EffectKind::Wind]
        } else {
            vec![kind]
        };
        assert_eq!(truth.effects, listed);
        let log = &out.log;
        let residual = |with_effect: bool| {
            worst(&truth, |i| {
                let s = &truth.samples[i];
                let [w, x, y, z] = log.attitude[i];
                let q = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
                let accel = q.inverse_transform_vector(
                    &(Vector3::from(log.accel.as_ref().unwrap()[i]) - GRAVITY_WORLD),
                );
                let y = newton_euler(
                    &s.params,
                    &accel,
                    &Vector3::from(log.omega[i]),
                    &Vector3::from(log.omega_dot.as_ref().unwrap()[i]),
                )
                .to_array();
                // The effect acts beside the actuators: b = Y θ − w.
                std::array::from_fn(|c| {
                    log.wrench[i][c] - y[c]
                        + if with_effect {
                            s.logged_effect_wrenches.iter().map(|w| w[c]).sum::<f64>()
                        } else {
                            0.0
                        }
                })
            })
        };
        let with = residual(true);
        let without = residual(false);
        let bound = match kind {
            EffectKind::MotorLag => [2e-4, 1e-2],
            // The jumps at each command: the differenced gyro sees them in `ω̇`, the force rows
            // take them through `ω̇ × h`, the midpoint accelerometer does not.
            EffectKind::RotorInertia => [5e-4, 1e-3],
            _ => [1e-5, 1e-3],
        };
        assert!(with[0] < bound[0] && with[1] < bound[1], "{kind}: {with:?}");
        assert!(
            without[0] > 10.0 * with[0].max(1e-6) || without[1] > 10.0 * with[1],
            "{kind}: the effect is invisible: {without:?} vs {with:?}"
        );
    }
}
