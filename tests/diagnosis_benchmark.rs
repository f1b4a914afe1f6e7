//! A slice of the diagnosis benchmark (issue #24) in CI: a few short flights end to end
//! (draw, fly with the truth, diagnose as `tagk diagnose` does, score), run twice — on this
//! thread and on a rayon pool — for the same bits, with every field of the scores filled.
//! It checks the machinery and its determinism; the targets are measured by the example
//! (`cargo run --release --example diagnosis_benchmark`, the README's generated table).

use rayon::prelude::*;
use tagk::diagnosis_benchmark::{
    BenchmarkOptions, FlightResult, GroundTruth, Summary, draw_flight, run_flight,
};

/// Flights of the slice (the quick run's flights).
const FLIGHTS: usize = 8;

fn options() -> BenchmarkOptions {
    BenchmarkOptions {
        quick: true,
        ..BenchmarkOptions::default()
    }
}

fn json(results: &[FlightResult]) -> String {
    serde_json::to_string(results).expect("scores serialise")
}

#[test]
fn a_slice_of_the_benchmark_runs_end_to_end_deterministically() {
    let options = options();
    let start = std::time::Instant::now();
    let serial: Vec<FlightResult> = (0..FLIGHTS).map(|i| run_flight(&options, i).0).collect();
    let elapsed = start.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let parallel: Vec<FlightResult> = pool.install(|| {
        (0..FLIGHTS)
            .into_par_iter()
            .map(|i| run_flight(&options, i).0)
            .collect()
    });
    // Same seed, same scores, whatever the thread.
    assert_eq!(json(&serial), json(&parallel));
    eprintln!("{FLIGHTS} flights in {elapsed:.1} s on one thread");

    for r in &serial {
        let spec = r.spec.as_ref().expect("drawn");
        assert_eq!(spec, &draw_flight(&options, r.index).unwrap());
        let Some(score) = &r.score else {
            // A failure is recorded, never a panic; the slice's flights all fly.
            panic!("flight {} failed: {:?}", r.index, r.failure);
        };
        assert!(
            r.failure.is_none() && r.samples >= 200,
            "flight {}",
            r.index
        );
        assert_eq!(score.sensing, spec.sensing);
        assert_eq!(score.known_mass, spec.known_mass);
        assert!(score.noise.iter().all(|s| s.is_finite() && *s > 0.0));
        // Every hidden plant effect is a true effect, in the vocabulary's order, then the
        // sensor truths.
        let plant: Vec<&str> = score
            .effects
            .iter()
            .map(|e| e.name.as_str())
            .filter(|n| tagk::dynamics::EffectKind::from_name(n).is_some())
            .collect();
        assert_eq!(
            plant,
            spec.hidden.iter().map(String::as_str).collect::<Vec<_>>()
        );
        for e in &score.effects {
            assert!(e.strength.is_finite() && e.strength >= 0.0, "{e:?}");
            assert_eq!(e.detectable, e.strength >= options.detectable);
            assert!(!e.found || e.found_in_family, "{e:?}");
            assert_eq!(e.reported_as.is_some(), e.found_in_family, "{e:?}");
        }
        for c in &score.coefficients {
            assert!(c.truth.is_finite(), "{c:?}");
            if let Some(est) = c.estimate {
                assert!(est.is_finite() && c.relative_error.is_some_and(f64::is_finite));
            }
            assert_eq!(c.covered.is_some(), c.interval.is_some(), "{c:?}");
        }
        for f in &score.false_effects {
            assert!(score.final_effects.contains(f));
        }
        assert!(score.mass_true > 0.0 && score.mass_identifiable > 0.0);
        assert!(score.mass_estimate.is_finite() && score.mass_error.is_finite());
        assert!(score.inertia_error.iter().all(|x| x.is_finite()));
        // Right: the expected verdict, or either verdict in the gray zone.
        assert_eq!(
            score.adequate_right,
            score.adequate_reported == score.adequate_expected
                || (score.adequate_expected_by_effects && score.adequate_gray)
        );
        assert_eq!(
            score.adequate_expected,
            score.adequate_expected_by_effects && score.at_true_noise
        );
        assert!(!score.stopped.is_empty());
    }
    let summary = Summary::of(&options, &serial);
    assert_eq!(summary.flights, FLIGHTS);
    let table = summary.markdown();
    for row in &summary.targets {
        assert!(table.contains(&row.name), "{}", row.name);
    }
    assert_eq!(summary.by_sensing.len(), 3);
}

/// The ground truth of a flight without any effect and with ideal sensors: every channel's
/// noise is the resolution floor (the discretisation stays below it on forces) or close to
/// it, and there is no true effect to find.
#[test]
fn an_ideal_clean_flight_has_nothing_to_find() {
    let options = options();
    let spec = (0..200)
        .map(|i| draw_flight(&options, i).unwrap())
        .find(|s| s.hidden.is_empty() && s.sensing == tagk::sim::SensingProfile::Ideal)
        .expect("a clean ideal flight among the draws");
    let output = tagk::sim::simulate(&spec.sim_config()).unwrap();
    let truth = GroundTruth::of_flight(&spec, &output, options.detectable).unwrap();
    assert!(truth.effects.is_empty(), "{:?}", truth.effects);
    for c in 0..3 {
        assert_eq!(
            truth.noise[c], truth.resolution[c],
            "{:?}",
            truth.residual_rms
        );
    }
    for c in 3..6 {
        assert!(truth.noise[c] < 3.0 * truth.resolution[c], "{:?}", truth);
    }
}

/// The benchmark's own noise estimate reproduces the log from the truth: with ideal sensors
/// and each single effect of the vocabulary (Crazyflie magnitudes; a 20 ms lag, a 2-sample
/// delay, the ground effect at 6 cm, the thrust gain with the known mass), the residual
/// `b − Y θ + Σ w_e` on the logged signals is far below the resolution floor on every
/// channel. Measured (RMS over the floor, worst channel): 2e-5 to 1.3e-4 for every effect but
/// the motor lag, the rotor inertia and the rotor imbalance. The lag and the rotor inertia
/// shape `ω̇` within the logged interval: 7.6e-2 for the lag, 1.8e-2 (on `fx`) for the rotor
/// inertia's jumps at each command (the differenced gyro sees them, the midpoint
/// accelerometer does not). The rotor imbalance measured 2.5e-3. Bounds 1e-3, 0.2 and 5e-3.
/// Without the effect's wrench the residual would be its strength times the floor.
#[test]
fn with_ideal_sensors_the_noise_is_the_floor_for_every_effect() {
    use tagk::dynamics::EffectKind;
    use tagk::sim::PlantEffects;
    use tagk::sim::plant_effects::TimeDelay;
    let options = options();
    for (i, kind) in EffectKind::ALL.into_iter().enumerate() {
        let mut spec = draw_flight(&options, 40 + i).unwrap();
        spec.sensing = tagk::sim::SensingProfile::Ideal;
        spec.effects = PlantEffects::only(kind).unwrap();
        if kind == EffectKind::TimeDelay {
            spec.effects.time_delay = Some(TimeDelay { delay: 0.04 });
        }
        spec.altitude = (kind == EffectKind::GroundEffect).then_some(0.06);
        spec.known_mass = kind == EffectKind::ThrustGain;
        spec.hidden = vec![kind.name().to_string()];
        let output = tagk::sim::simulate(&spec.sim_config()).unwrap();
        assert!(!output.metrics.aborted, "{kind}");
        let truth = GroundTruth::of_flight(&spec, &output, options.detectable).unwrap();
        let ratio: Vec<f64> = (0..6)
            .map(|c| truth.residual_rms[c] / truth.resolution[c])
            .collect();
        // The rotor imbalance (a 10 % weak rotor, the largest torque of any default effect):
        // measured 2.5e-3 on the torques; why it exceeds the others is not investigated.
        let bound = match kind {
            EffectKind::MotorLag | EffectKind::RotorInertia => 0.2,
            EffectKind::RotorImbalance => 5e-3,
            _ => 1e-3,
        };
        assert!(
            ratio.iter().all(|r| *r <= bound),
            "{kind}: residual over the floor {ratio:?}"
        );
        let own = truth
            .effects
            .iter()
            .find(|e| e.name == kind.name())
            .unwrap();
        assert!(own.max_strength > 0.1, "{kind}: {own:?}");
    }
}

/// The accelerometer's offset the diagnosis measures against the velocity
/// (`tagk_diagnose::accel_offset::measure`) is the simulator's bias: on the first realistic
/// (uncalibrated) flights of the default seed, each axis within 4 of its standard errors of
/// the truth, and the vertical one to better than 0.2 % of g (what the mass needs).
#[test]
fn the_accelerometer_offset_against_the_velocity_is_the_simulators_bias() {
    let options = BenchmarkOptions::default();
    let mut checked = 0;
    for index in 0..60 {
        let spec = draw_flight(&options, index).unwrap();
        if spec.sensing != tagk::sim::SensingProfile::Realistic {
            continue;
        }
        let output = tagk::sim::simulate(&spec.sim_config()).unwrap();
        if output.metrics.aborted {
            continue;
        }
        let truth = output.truth.as_ref().unwrap().accel_bias;
        let (b, covariance, _) =
            tagk::diagnose::accel_offset::measure(&output.log).expect("measured");
        for j in 0..3 {
            let se = covariance[(j, j)].sqrt();
            assert!(
                (b[j] - truth[j]).abs() <= 4.0 * se,
                "flight {index}, axis {j}: {} against {} (se {se})",
                b[j],
                truth[j]
            );
        }
        assert!((b[2] - truth[2]).abs() < 0.002 * 9.81, "flight {index}");
        checked += 1;
        if checked == 5 {
            break;
        }
    }
    assert_eq!(checked, 5);
}
