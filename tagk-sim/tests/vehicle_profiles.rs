//! Issue #27: the identifiable-θ scoring, the real vehicles' rotor sensing and the tuning
//! procedures, each checked against an independent computation.

use nalgebra::{DMatrix, DVector, Quaternion, UnitQuaternion, Vector3};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use tagk_dynamics::{GRAVITY_WORLD, rigid_body_regressor};
use tagk_sim::plant_effects::ThrustGain;
use tagk_sim::sim::rotor_sensing::{BrushedPwm, ErpmTelemetry};
use tagk_sim::tuning::{measure_row_noise, tune};
use tagk_sim::{
    Adaptation, EstimatorKind, EstimatorSpec, ExperimentProfile, NoiseLevel, PayloadSchedule,
    PlantEffects, SimConfig, TrajectoryKind, simulate,
};

/// The closed form: with a thrust-coefficient error ε the scored parameters are θ/(1+ε).
#[test]
fn identifiable_parameters_are_theta_over_one_plus_epsilon() {
    let eps = -0.1;
    let cfg = SimConfig {
        effects: PlantEffects {
            thrust_gain: Some(ThrustGain {
                relative_error: eps,
            }),
            ..PlantEffects::none()
        },
        ..SimConfig::default()
    };
    let theta = cfg.vehicle.params.to_array();
    let id = cfg.identifiable_params(&cfg.vehicle.params).to_array();
    for (t, i) in theta.iter().zip(id) {
        assert!(
            (i - t / 0.9).abs() <= 1e-15 * t.abs().max(1e-12),
            "{i} vs {t}/0.9"
        );
    }
    assert_eq!(SimConfig::default().identifiable_scale(), 1.0);
}

/// Independently of the scoring code: batch least squares on a noise-free flight with ε = −0.1
/// recovers θ/(1+ε), not θ (mass and first moment; the inertia is weakly excited).
#[test]
fn batch_least_squares_on_the_flight_finds_the_identifiable_parameters() {
    let eps = -0.1;
    let cfg = SimConfig {
        duration: 8.0,
        seed: 3,
        trajectory: TrajectoryKind::Figure8,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        effects: PlantEffects {
            thrust_gain: Some(ThrustGain {
                relative_error: eps,
            }),
            ..PlantEffects::none()
        },
        record_log: true,
        ..SimConfig::default()
    };
    let out = simulate(&cfg).unwrap();
    let log = &out.log;
    let acc = log.accel.as_ref().unwrap();
    let dw = log.omega_dot.as_ref().unwrap();
    let n = log.len();
    let mut a = DMatrix::<f64>::zeros(6 * n, 10);
    let mut b = DVector::<f64>::zeros(6 * n);
    for k in 0..n {
        let q = log.attitude[k];
        let r = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
        let prop = r.inverse_transform_vector(&(Vector3::from(acc[k]) - GRAVITY_WORLD));
        let y = rigid_body_regressor(&prop, &Vector3::from(log.omega[k]), &Vector3::from(dw[k]));
        for i in 0..6 {
            for j in 0..10 {
                a[(6 * k + i, j)] = y[(i, j)];
            }
            b[6 * k + i] = log.wrench[k][i];
        }
    }
    let x = a.svd(true, true).solve(&b, 1e-12).unwrap();
    let m = cfg.vehicle.params.mass();
    assert!(
        (x[0] - m / (1.0 + eps)).abs() < 2e-3 * m,
        "LS mass {} vs m/(1+ε) {}",
        x[0],
        m / (1.0 + eps)
    );
    assert!((x[0] - m).abs() > 0.1 * m, "LS mass {} vs m {m}", x[0]);
    let id = cfg.identifiable_params(&cfg.vehicle.params).to_array();
    for j in 1..4 {
        assert!((x[j] - id[j]).abs() < 2e-3 * m * 0.0325, "h[{j}] {}", x[j]);
    }
}

/// A brushed Crazyflie's speed command steps by max/255 (8-bit PWM), measured from the
/// quantiser's output; its battery reading's relative σ is σ_V / V, measured from draws.
#[test]
fn brushed_pwm_step_and_voltage_noise_are_the_stated_ones() {
    let pwm = BrushedPwm::crazyflie(0.01);
    let max = 2500.0;
    let mut levels: Vec<f64> = (0..20_000)
        .map(|i| pwm.quantise(1500.0 + 200.0 * i as f64 / 20_000.0, max))
        .collect();
    levels.dedup();
    let steps: Vec<f64> = levels.windows(2).map(|w| w[1] - w[0]).collect();
    let expected = max / 255.0;
    assert!(steps.len() > 10);
    for s in steps {
        assert!((s - expected).abs() < 1e-9, "step {s} vs {expected}");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let draws: Vec<f64> = (0..40_000).map(|_| pwm.voltage_factor(&mut rng)).collect();
    let mean = draws.iter().sum::<f64>() / draws.len() as f64;
    let sd = (draws.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / draws.len() as f64).sqrt();
    let stated = pwm.battery_noise / pwm.battery_voltage;
    assert!((sd / stated - 1.0).abs() < 0.03, "σ {sd} vs {stated}");
    assert!((mean - 1.0).abs() < 4.0 * stated / 200.0);
}

/// eRPM telemetry: readings on a 1/rate grid, the period in whole µs (9-bit mantissa), and the
/// period's σ √(jitter² + 1 µs²/12), each measured from the model's output.
#[test]
fn erpm_rate_step_and_noise_are_the_stated_ones() {
    let e = ErpmTelemetry::crazyflie_brushless();
    // Rate: the distinct reading times over 50 ms of 0.1 ms queries.
    let mut times: Vec<f64> = (0..500).map(|i| e.reading_time(i as f64 * 1e-4)).collect();
    times.dedup();
    for w in times.windows(2) {
        assert!((w[1] - w[0] - 1.0 / e.rate).abs() < 1e-12);
    }
    assert_eq!(times.len(), 50);
    // Step: without jitter, every reading's period is a whole number of µs below 512 µs.
    let quiet = ErpmTelemetry { jitter: 0.0, ..e };
    let pp = f64::from(e.pole_pairs);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut periods: Vec<f64> = (0..5000)
        .map(|i| {
            let w = quiet.read(1800.0 + 300.0 * i as f64 / 5000.0, &mut rng);
            std::f64::consts::TAU / (pp * w) / 1e-6
        })
        .collect();
    for p in &periods {
        assert!((p - p.round()).abs() < 1e-6, "period {p} µs");
    }
    periods.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let step = periods
        .windows(2)
        .map(|w| (w[0] - w[1]).abs())
        .fold(f64::MAX, f64::min);
    assert!((step - 1.0).abs() < 1e-6, "period step {step} µs");
    // A long period (a slow motor) needs a shift: steps of 2 µs above 511 µs.
    let slow = quiet.read(std::f64::consts::TAU / (pp * 700e-6), &mut rng);
    let p_slow = std::f64::consts::TAU / (pp * slow) / 1e-6;
    assert!(
        (p_slow / 2.0 - (p_slow / 2.0).round()).abs() < 1e-6,
        "{p_slow}"
    );
    // Noise: the read period's σ at hover.
    let w0 = 1930.0;
    let reads: Vec<f64> = (0..40_000)
        .map(|_| std::f64::consts::TAU / (pp * e.read(w0, &mut rng)))
        .collect();
    let mean = reads.iter().sum::<f64>() / reads.len() as f64;
    let sd = (reads.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / reads.len() as f64).sqrt();
    let stated = (e.jitter.powi(2) + 1e-12 / 12.0).sqrt();
    assert!((sd / stated - 1.0).abs() < 0.05, "σ {sd} vs {stated}");
}

/// In flight, the brushless profile's logged rotor speeds are eRPM readings: every one a
/// whole number of µs of electrical period (measured from the simulated log).
#[test]
fn the_brushless_flight_logs_quantised_erpm() {
    let mut cfg = SimConfig {
        duration: 2.0,
        seed: 5,
        adaptation: Adaptation::Nominal,
        payload: PayloadSchedule::None,
        record_log: true,
        ..SimConfig::default()
    };
    ExperimentProfile::Cf21Brushless.apply(&mut cfg);
    let out = simulate(&cfg).unwrap();
    let pp = f64::from(ErpmTelemetry::crazyflie_brushless().pole_pairs);
    let speeds = out.log.rotor_speeds.as_ref().unwrap();
    assert!(!speeds.is_empty());
    for s in speeds {
        for w in s {
            let p = std::f64::consts::TAU / (pp * w) / 1e-6;
            assert!((p - p.round()).abs() < 1e-6, "period {p} µs");
        }
    }
}

/// The vehicles' noise levels change what the estimator sees: the IMU's white noise scales
/// with the level's vibration factor 1, 2, 3, 6 (medium: the profile's own figure).
#[test]
fn the_vehicles_noise_levels_scale_the_imu_noise() {
    let mut cfg = SimConfig::default();
    ExperimentProfile::Cf21.apply(&mut cfg);
    let medium = cfg
        .flight_stack
        .sensing_at(&cfg.sensing, NoiseLevel::Medium);
    assert_eq!(medium.accel_noise, cfg.sensing.accel_noise);
    for (level, k) in NoiseLevel::ALL.into_iter().zip([1.0, 2.0, 3.0, 6.0]) {
        let s = cfg.flight_stack.sensing_at(&cfg.sensing, level);
        assert!((s.accel_noise / cfg.sensing.accel_noise - k / 3.0).abs() < 1e-12);
        assert!((s.gyro_noise / cfg.sensing.gyro_noise - k / 3.0).abs() < 1e-12);
    }
    // The old profiles keep their σ's at every level.
    let mut old = SimConfig::default();
    ExperimentProfile::Realistic.apply(&mut old);
    let s = old.flight_stack.sensing_at(&old.sensing, NoiseLevel::High);
    assert_eq!(s.accel_noise, old.sensing.accel_noise);
}

/// The tuning procedure is a function of its seed: run twice, the same scores and choice; the
/// row noise measured twice, the same bits.
#[test]
fn the_tuning_procedure_is_deterministic() {
    let candidates = vec![
        tagk_sim::estimators::tuned_front_end(EstimatorKind::KfLow),
        tagk_sim::estimators::tuned_front_end(EstimatorKind::TagK),
    ];
    let a = tune(ExperimentProfile::Cf21Brushless, candidates.clone(), 2, 7).unwrap();
    let b = tune(ExperimentProfile::Cf21Brushless, candidates, 2, 7).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.scores.len(), 2);
    let r1 = measure_row_noise(ExperimentProfile::Cf21, NoiseLevel::Low, 7, 2).unwrap();
    let r2 = measure_row_noise(ExperimentProfile::Cf21, NoiseLevel::Low, 7, 2).unwrap();
    assert_eq!(r1, r2);
    assert!(r1.force_z > 0.0 && r1.torque.iter().all(|t| *t > 0.0));
    assert!(tune(ExperimentProfile::Cf21, Vec::<EstimatorSpec>::new(), 2, 7).is_err());
}
