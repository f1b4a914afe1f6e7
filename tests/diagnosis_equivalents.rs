//! Equivalent effects (issue #24, item 4): after the staircase, each added effect is swapped
//! for every other candidate within the final model, and a candidate that explains the data
//! as well is reported beside it. Checked on two benchmark flights against a fit of the
//! swapped model from scratch (`--with`), which takes another path than the swap's.

use tagk::cli::diagnose::{DiagnoseArgs, KnownMass, diagnose_owned_log};
use tagk::diagnose::Report;
use tagk::diagnosis_benchmark::{BenchmarkOptions, replay_flight};

fn options() -> BenchmarkOptions {
    BenchmarkOptions {
        seed: 7,
        quick: true,
        ..BenchmarkOptions::default()
    }
}

/// `tagk diagnose` on flight `index` of the quick benchmark, with the effects `with` given.
fn diagnose(index: usize, with: &[&str]) -> Report {
    let flight = replay_flight(&options(), index).expect("the flight flies");
    let mut args = DiagnoseArgs::new("flight.csv");
    args.mass = flight.known_mass.map(KnownMass::Kg);
    args.quiet = true;
    args.with = with.iter().map(|s| s.to_string()).collect();
    diagnose_owned_log(flight.log, &args).expect("the diagnosis runs")
}

/// The held-out gain of a model over the rigid body, in noise units: the sum over channels
/// of `n (rigid² − model²) / noise²` (the score the search compares).
fn gain(report: &Report, model: &Report) -> f64 {
    let rigid = &report.before;
    let after = model.after.as_ref().expect("a model was given");
    let n = rigid.samples as f64;
    (0..6)
        .filter(|&c| report.noise_floor.rms[c] > 0.0)
        .map(|c| {
            n * (rigid.held_out_rms[c].powi(2) - after.held_out_rms[c].powi(2))
                / report.noise_floor.rms[c].powi(2)
        })
        .sum()
}

#[test]
fn a_drag_law_the_data_cannot_tell_from_another_is_reported_beside_it() {
    // A realistic flight with a linear drag of strength 2: found as a rotor drag, whose
    // form differs only through the thrust's small changes.
    let report = diagnose(27, &[]);
    assert_eq!(report.final_model.effects, ["rotor-drag"]);
    let e = report
        .equivalents
        .iter()
        .find(|e| e.effect == "rotor-drag" && e.alternative == "linear-drag")
        .unwrap_or_else(|| panic!("{:?}", report.equivalents));
    assert!((e.gain - e.alternative_gain).abs() <= 2.0 * e.gain.max(1.0).sqrt());
    // Fitted from scratch, the two models explain the data alike.
    let rotor = gain(&report, &diagnose(27, &["rotor-drag"]));
    let linear = gain(&report, &diagnose(27, &["linear-drag"]));
    assert!(rotor > 100.0, "{rotor}");
    assert!(
        (rotor - linear).abs() <= 2.0 * rotor.max(linear).sqrt(),
        "rotor drag {rotor}, linear drag {linear}"
    );
    assert!(
        tagk::diagnose::staircase_table(&report).contains("linear-drag in place of rotor-drag")
    );
}

#[test]
fn a_drag_law_the_data_tell_apart_has_no_equivalent() {
    // A noise-free flight with a strong rotor drag and a ground effect.
    let report = diagnose(3, &[]);
    assert_eq!(report.final_model.effects, ["rotor-drag", "ground-effect"]);
    assert!(report.equivalents.is_empty(), "{:?}", report.equivalents);
    // Fitted from scratch, the linear drag in its place leaves clearly more.
    let rotor = gain(&report, &diagnose(3, &["rotor-drag", "ground-effect"]));
    let linear = gain(&report, &diagnose(3, &["linear-drag", "ground-effect"]));
    assert!(
        rotor - linear > 2.0 * rotor.sqrt(),
        "rotor drag {rotor}, linear drag {linear}"
    );
}

#[test]
fn the_stop_reason_agrees_with_the_verdict() {
    for index in [3, 27] {
        let report = diagnose(index, &[]);
        assert_eq!(
            report.adequate,
            report.stopped.starts_with("adequate"),
            "flight {index}: {}",
            report.stopped
        );
    }
}
