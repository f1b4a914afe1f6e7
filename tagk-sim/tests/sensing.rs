//! Sensing profiles through the flight log: the logged noise has the stated σ around a constant
//! seeded bias, the logged wrench is the measured rotor speeds through the nominal mixer, the
//! new random streams leave every other signal bit-identical, and flights are deterministic.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use tagk_sim::*;

/// A 20 s hover-and-track flight without adaptation (the controller never sees the
/// accelerometer or the rotor speeds), logged.
fn flight(seed: u64, sensing: Sensing) -> SimOutput {
    let config = SimConfig {
        seed,
        sensing,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        ..SimConfig::default()
    };
    simulate(&config).expect("flight")
}

fn mean_std(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// Accelerometer and rotor-speed noise do not reach the controller without adaptation, so the
/// flight is the ideal one and the log's difference to it is the sensing alone: body-frame
/// accelerometer error with the stated σ (within 10 % over 1000 samples, 3 axes pooled around
/// each axis's mean) and a constant mean (the bias), rotor-speed error with the stated σ, and
/// the logged wrench exactly the nominal mixer of the logged rotor speeds. Position, velocity,
/// attitude and gyro columns stay bit-identical (the new streams leave the old ones alone).
#[test]
fn logged_accelerometer_and_rotor_speeds_carry_the_profile() {
    let s = Sensing {
        accel_noise: 0.05,
        accel_bias: 0.2,
        rotor_speed_noise: 20.0,
        ..Sensing::ideal()
    };
    let ideal = flight(3, Sensing::ideal());
    let noisy = flight(3, s);
    assert_eq!(ideal.log.len(), noisy.log.len());
    assert_eq!(ideal.tracking_errors, noisy.tracking_errors);
    let vehicle = SimConfig::default().vehicle;
    let mut accel_err = [vec![], vec![], vec![]];
    let mut rotor_err = vec![];
    for (a, b) in ideal.log.samples().zip(noisy.log.samples()) {
        assert_eq!(
            (a.position, a.velocity, a.attitude, a.omega, a.omega_dot),
            (b.position, b.velocity, b.attitude, b.omega, b.omega_dot)
        );
        let q = UnitQuaternion::from_quaternion(Quaternion::new(
            a.attitude[0],
            a.attitude[1],
            a.attitude[2],
            a.attitude[3],
        ));
        let d = q.inverse()
            * (Vector3::from(b.accel.expect("accel")) - Vector3::from(a.accel.expect("accel")));
        for i in 0..3 {
            accel_err[i].push(d[i]);
        }
        let (wa, wb) = (a.rotor_speeds.expect("w"), b.rotor_speeds.expect("w"));
        for i in 0..4 {
            rotor_err.push(wb[i] - wa[i]);
        }
        assert_eq!(
            vehicle.wrench_from_rotor_speeds(&wb).to_array(),
            b.wrench,
            "logged wrench = nominal mixer of the logged rotor speeds"
        );
    }
    let mut means = vec![];
    for e in &accel_err {
        let (m, sd) = mean_std(e);
        assert!((sd / 0.05 - 1.0).abs() < 0.1, "accel std {sd}");
        means.push(m);
    }
    // A constant bias of this flight: its size is that of a σ = 0.2 draw, not noise-sized.
    let bias = Vector3::new(means[0], means[1], means[2]);
    assert!(bias.norm() > 0.02 && bias.norm() < 1.0, "bias {bias}");
    let (m, sd) = mean_std(&rotor_err);
    assert!((sd / 20.0 - 1.0).abs() < 0.1, "rotor-speed std {sd}");
    assert!(m.abs() < 5.0 * 20.0 / (rotor_err.len() as f64).sqrt());
}

/// The same seed flies the same realistic flight bit for bit; another seed differs.
#[test]
fn realistic_flights_are_deterministic() {
    for profile in SensingProfile::SYNTHETIC {
        let a = flight(21, profile.sensing());
        let b = flight(21, profile.sensing());
        assert_eq!(a.tracking_errors, b.tracking_errors);
        let (mut ca, mut cb) = (Vec::new(), Vec::new());
        a.log.write_csv(&mut ca).expect("csv");
        b.log.write_csv(&mut cb).expect("csv");
        assert_eq!(ca, cb, "{profile}");
    }
    let a = flight(21, Sensing::realistic());
    let c = flight(22, Sensing::realistic());
    assert_ne!(a.tracking_errors, c.tracking_errors);
}

/// Realistic sensing still flies: the controller tracks within a few centimetres.
#[test]
fn realistic_sensing_tracks() {
    for seed in 0..3 {
        let out = flight(seed, Sensing::realistic());
        assert!(!out.metrics.aborted, "seed {seed}");
        assert!(
            out.metrics.position_error_cm < 5.0,
            "{}",
            out.metrics.position_error_cm
        );
    }
}

/// Profiles parse by name; bad σ's are typed errors.
#[test]
fn profiles_parse_and_validate() {
    for p in SensingProfile::ALL {
        assert_eq!(p.name().parse::<SensingProfile>().expect("parse"), p);
        p.sensing().validate().expect("valid");
    }
    assert!(matches!(
        "perfect".parse::<SensingProfile>(),
        Err(SimError::Unknown { .. })
    ));
    assert_eq!(Sensing::default(), Sensing::ideal());
    let bad = SimConfig {
        sensing: Sensing::ideal().with_gyro_noise(-1.0),
        ..SimConfig::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(SimError::InvalidParameter {
            name: "sensing.gyro_noise",
            ..
        })
    ));
    let nan = SimConfig {
        sensing: Sensing {
            rotor_speed_noise: f64::NAN,
            ..Sensing::ideal()
        },
        ..SimConfig::default()
    };
    assert!(nan.validate().is_err());
}

/// `cf21-brushless` reads the rotor speeds as the Crazyflie 2.1 Brushless does: on the flight
/// stack it is given, every logged speed is an eRPM reading, a whole number of µs of
/// electrical period at the vehicle profile's pole pairs. Against the truth's noise-free
/// actuator thrust: each speed within half a µs step plus 5 σ of jitter of its period, so the
/// logged thrust `k_f Σ ω²` within twice that relative error; and not the truth itself. The
/// synthetic profiles keep the read-back telemetry.
#[test]
fn the_brushless_sensing_profile_logs_erpm_readings() {
    use tagk_sim::sim::rotor_sensing::{ERPM_PERIOD_JITTER, ERPM_PERIOD_UNIT, RotorSensing};
    let profile = SensingProfile::Cf21Brushless;
    let config = SimConfig {
        seed: 4,
        duration: 4.0,
        sensing: profile.sensing(),
        flight_stack: profile.flight_stack(FlightStack::paper()),
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        record_truth: true,
        ..SimConfig::default()
    };
    let out = simulate(&config).expect("flight");
    let RotorSensing::Erpm(erpm) = config.flight_stack.rotor_sensing else {
        panic!("{:?}", config.flight_stack.rotor_sensing);
    };
    assert_eq!(config.sensing.rotor_speed_noise, 0.0);
    let pp = f64::from(erpm.pole_pairs);
    let speeds = out.log.rotor_speeds.as_ref().expect("rotor speeds");
    let truth = out.truth.expect("truth");
    assert_eq!(speeds.len(), truth.samples.len());
    let fastest = speeds.iter().flatten().fold(0.0f64, |m, w| m.max(*w));
    let shortest = std::f64::consts::TAU / (pp * fastest * 1.05);
    let relative = (0.5 * ERPM_PERIOD_UNIT + 5.0 * ERPM_PERIOD_JITTER) / shortest;
    let mut differs = 0;
    for ((logged, s), b) in speeds.iter().zip(&truth.samples).zip(&out.log.wrench) {
        for w in logged {
            let units = std::f64::consts::TAU / (pp * w) / ERPM_PERIOD_UNIT;
            assert!((units - units.round()).abs() < 1e-6, "period {units} µs");
        }
        let k_f = config.vehicle.k_f;
        let thrust = k_f * logged.iter().map(|w| w * w).sum::<f64>();
        let true_thrust = s.logged_actuator_wrench[2];
        assert!(
            (thrust - b[2]).abs() <= 1e-12 * thrust,
            "{thrust} vs {}",
            b[2]
        );
        assert!(
            (thrust / true_thrust - 1.0).abs() <= relative * (2.0 + relative),
            "thrust {thrust} N, true {true_thrust} N"
        );
        differs += usize::from(thrust != true_thrust);
    }
    assert!(differs > speeds.len() / 2, "{differs} of {}", speeds.len());
    for p in SensingProfile::SYNTHETIC {
        assert_eq!(p.rotor_sensing(), RotorSensing::Telemetry, "{p}");
    }
}
