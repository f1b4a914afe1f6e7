//! The `realistic` profile's flight stack (issue #14): each setting checked against an
//! independent computation or a flight without it, and the `paper` stack leaving flights as
//! they were.

use nalgebra::Vector3;
use tagk_dynamics::InertialParams;
use tagk_sim::plant_effects::ThrustGain;
use tagk_sim::sim::{REALISTIC_ROTOR_TELEMETRY_SAMPLES, check_payload, check_payload_within};
use tagk_sim::*;

/// A payload-free 20 s flight of the nominal controller with a thrust coefficient 5 % low.
fn weak_rotor_flight(stack: FlightStack) -> SimOutput {
    let config = SimConfig {
        seed: 3,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        effects: PlantEffects {
            thrust_gain: Some(ThrustGain {
                relative_error: -0.05,
            }),
            ..PlantEffects::none()
        },
        flight_stack: stack,
        ..SimConfig::default()
    };
    simulate(&config).expect("flight")
}

/// Mean tracking error over the last 5 s of a flight \[m\].
fn late_error(out: &SimOutput) -> f64 {
    let e = &out.tracking_errors;
    let tail = &e[e.len() - 250..];
    tail.iter().sum::<f64>() / tail.len() as f64
}

/// Integral action removes the steady sag a 5 % thrust deficit leaves under the bare LQR: the
/// late tracking error falls at least threefold.
#[test]
fn integral_action_removes_the_thrust_error_sag() {
    let bare = late_error(&weak_rotor_flight(FlightStack::paper()));
    let with_integral = late_error(&weak_rotor_flight(FlightStack {
        position_integral_gain: 0.5,
        position_integral_limit: 0.05,
        ..FlightStack::paper()
    }));
    assert!(bare > 2e-3, "bare LQR sag {bare}");
    assert!(with_integral < bare / 3.0, "{with_integral} vs {bare}");
}

/// The `paper` stack is the default and leaves a flight bit-identical to one that never heard
/// of it (the same configuration through `ExperimentProfile::Paper`).
#[test]
fn paper_stack_is_the_default() {
    assert_eq!(SimConfig::default().flight_stack, FlightStack::paper());
    let mut config = SimConfig {
        seed: 11,
        ..SimConfig::default()
    };
    let a = simulate(&config).expect("flight");
    ExperimentProfile::Paper.apply(&mut config);
    let b = simulate(&config).expect("flight");
    assert_eq!(a.tracking_errors, b.tracking_errors);
    assert_eq!(
        ExperimentProfile::Realistic.flight_stack(),
        FlightStack::realistic()
    );
}

/// The point-mass completion returns an estimate that is the nominal vehicle plus a point mass
/// unchanged (up to rounding), whatever inertia the estimator reported; with no added mass it
/// keeps the nominal inertia and takes the estimate's mass and first moment.
#[test]
fn point_mass_completion_matches_the_parallel_axis_theorem() {
    let stack = FlightStack::realistic();
    let nominal = SimConfig::default().vehicle.params;
    let payload = InertialParams::point_mass(0.015, Vector3::new(0.004, -0.006, 0.003));
    let truth = nominal + payload;
    // The estimator's inertia columns are off; mass and first moment are right.
    let mut wrong = truth.to_array();
    for v in &mut wrong[4..] {
        *v *= 3.0;
    }
    let completed = stack.controller_params(&InertialParams::from_array(wrong), &nominal);
    for (c, t) in completed.to_array().iter().zip(truth.to_array()) {
        assert!((c - t).abs() <= 1e-15 + 1e-12 * t.abs(), "{c} vs {t}");
    }
    // A lighter estimate: nominal inertia, the estimate's mass and first moment.
    let mut light = nominal.to_array();
    light[0] *= 0.9;
    light[1] = 1e-4;
    let completed = stack.controller_params(&InertialParams::from_array(light), &nominal);
    let c = completed.to_array();
    assert_eq!(c[0], light[0]);
    assert_eq!(c[1], 1e-4);
    assert_eq!(&c[4..], &nominal.to_array()[4..]);
    // Off, the estimate as it is.
    let e = InertialParams::from_array(wrong);
    assert_eq!(FlightStack::paper().controller_params(&e, &nominal), e);
}

/// Averaging `n` telemetry readings divides the rotor-speed σ by `√n` and leaves every other
/// figure; one reading leaves the profile bit for bit.
#[test]
fn averaged_telemetry_divides_the_rotor_speed_sigma() {
    let s = Sensing::realistic();
    let seen = FlightStack::realistic().sensing_seen(&s);
    let n = f64::from(REALISTIC_ROTOR_TELEMETRY_SAMPLES);
    assert!((seen.rotor_speed_noise * n.sqrt() - s.rotor_speed_noise).abs() < 1e-12);
    assert_eq!(
        Sensing {
            rotor_speed_noise: s.rotor_speed_noise,
            ..seen
        },
        s
    );
    assert_eq!(FlightStack::paper().sensing_seen(&s), s);
}

/// The payload check within a fraction of the maximum thrust: 1 is the paper's check; a
/// payload that needs most of the thrust passes at 1 and fails at a tighter limit.
#[test]
fn thrust_margin_rejects_what_the_weaker_rotors_cannot_lift() {
    let vehicle = SimConfig::default().vehicle;
    let heavy = Payload {
        mass: 0.5 * vehicle.params.mass(),
        offset: [0.0, 0.0, 0.0],
        shape: PayloadShape::PointMass,
        attach_time: 5.0,
        remove_time: None,
    };
    assert!(check_payload(&vehicle, &heavy).is_ok());
    assert!(check_payload_within(&vehicle, &heavy, 1.0).is_ok());
    // 1.5 m g over four rotors is about 90 % of the maximum thrust.
    assert!(matches!(
        check_payload_within(&vehicle, &heavy, 0.8),
        Err(SimError::PayloadBeyondThrust { .. })
    ));
}

/// Bad flight-stack settings are typed errors, not panics.
#[test]
fn bad_settings_are_rejected() {
    for stack in [
        FlightStack {
            position_integral_gain: -1.0,
            ..FlightStack::paper()
        },
        FlightStack {
            position_integral_limit: f64::NAN,
            ..FlightStack::paper()
        },
        FlightStack {
            hover_thrust_limit: 1.5,
            ..FlightStack::paper()
        },
        FlightStack {
            rotor_telemetry_samples: 0,
            ..FlightStack::paper()
        },
    ] {
        let config = SimConfig {
            flight_stack: stack,
            ..SimConfig::default()
        };
        assert!(matches!(
            simulate(&config),
            Err(SimError::InvalidParameter { .. })
        ));
    }
}

/// The `realistic` profile's oracle flies every trial of a small probe without an abort and
/// within the 1 cm success rule (the bare LQR lost 16-22 % of them).
#[test]
fn realistic_oracle_does_not_abort() {
    for trial in 0..6 {
        let mut config = SimConfig {
            seed: trial_seed(99, 0, trial),
            adaptation: Adaptation::Oracle,
            trajectory: TrajectoryKind::ALL[trial % 5],
            ..SimConfig::default()
        };
        ExperimentProfile::Realistic.apply(&mut config);
        let out = simulate(&config).expect("flight");
        assert!(!out.metrics.aborted, "trial {trial} aborted");
        assert!(out.metrics.settled, "trial {trial} not settled");
    }
}

/// Nuisance body-force columns: a flight with them runs, reports θ's ten entries to the
/// controller and the tables, and names the option in the label.
#[test]
fn force_bias_columns_fly() {
    let spec = EstimatorSpec::new(EstimatorKind::TagK).with_force_bias();
    assert_eq!(spec.unknowns(), 13);
    assert!(spec.label().contains("force bias"));
    let config = SimConfig {
        seed: 5,
        adaptation: Adaptation::Estimator(spec),
        ..SimConfig::default()
    };
    let out = simulate(&config).expect("flight");
    assert!(!out.updates.is_empty());
    assert!(out.updates.iter().all(|u| u.estimate.len() == 10));
}
