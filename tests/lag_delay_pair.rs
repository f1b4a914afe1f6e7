//! A motor lag and a log delay hidden together (issue #24): both found, with the time
//! constant and the delay within their reported 95 % intervals, checked against the
//! simulator's truth. The flights are benchmark flights of the development seeds 7 and 11
//! (ideal sensing, 50 Hz logs), flown again.
//!
//! The simulator lags the motors' command and logs it `d` late. So the wrench acting at `t` is
//! the lag of the log `d` later: a delay of `−d` in the diagnosis's sign. Summed as two
//! separate effects, the pair misses the interaction `(L − 1)(b(t − d) − b)`, about as large
//! as the lag itself on these flights. The scans then stopped on the ridge along which the two
//! trade: flight 194 of seed 7 ended without the lag, flight 295 of seed 11 without either.

use tagk::cli::diagnose::{DiagnoseArgs, KnownMass, diagnose_owned_log};
use tagk::diagnosis_benchmark::{BenchmarkOptions, replay_flight};

/// Flight `index` of seed `seed`: an error per effect of the pair not found, or whose scanned
/// parameter's 95 % interval misses the truth.
fn check(seed: u64, index: usize) -> Vec<String> {
    let options = BenchmarkOptions {
        seed,
        ..BenchmarkOptions::default()
    };
    let flight = replay_flight(&options, index).expect("the flight flies");
    let tau = flight.spec.effects.motor_lag.expect("a lag").time_constant;
    let delay = flight.spec.effects.time_delay.expect("a delay").delay;
    let mut args = DiagnoseArgs::new("flight.csv");
    args.mass = flight.known_mass.map(KnownMass::Kg);
    args.quiet = true;
    let report = diagnose_owned_log(flight.log, &args).expect("the diagnosis runs");
    let last = report.final_diagnosis();
    let mut errors = Vec::new();
    for (name, truth) in [("motor-lag", tau), ("time-delay", -delay)] {
        let Some(e) = last.effects.iter().find(|e| e.effect == name) else {
            errors.push(format!(
                "seed {seed} flight {index}: {name} not found (final {:?})",
                report.final_model.effects
            ));
            continue;
        };
        let value = e.scanned.as_ref().map(|s| s.1);
        match e.scanned_interval {
            Some([lo, hi]) if lo <= truth && truth <= hi => {}
            other => errors.push(format!(
                "seed {seed} flight {index}: {name} {value:?}, interval {other:?}, truth {truth}"
            )),
        }
    }
    errors
}

#[test]
fn a_lag_and_a_delay_together_are_found_within_their_intervals() {
    // Seed 7 flight 194: a 16 ms lag, a 60 ms delay and a linear drag. Seed 11 flights 65
    // and 269: 57 and 36 ms lags, 40–60 ms delays, beside a ground effect or a thrust gain.
    let errors: Vec<String> = [(7, 194), (11, 65), (11, 269)]
        .into_iter()
        .flat_map(|(seed, index)| check(seed, index))
        .collect();
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

/// Seed 11 flight 295 (a 40 ms lag, a 60 ms delay, a ground effect at 5 cm), failing since the
/// ground-effect column acts on the thrust alone. A false `body-bias` (its torque `bias_ty`
/// significant) enters before the timing pair and takes part of its signature. The pair is then
/// found at τ = 0.029 s and a delay of −0.040 s, each interval ending at its estimate (truth
/// 0.040 s and −0.060 s). Run with `cargo test --release --test lag_delay_pair -- --ignored`.
#[test]
#[ignore = "known failure: a false body-bias biases the lag and delay (seed 11 flight 295)"]
fn a_lag_and_a_delay_beside_a_strong_ground_effect_are_found_within_their_intervals() {
    let errors = check(11, 295);
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}
