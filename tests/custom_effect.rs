//! `examples/custom_effect.rs` checked: a user-defined effect (an elastic tether), flown by
//! the simulator in closed loop through `PlantEffect`, is not found by the built-in
//! candidates, is ranked first and recommended once registered as an `Effect`, and adding it
//! cuts the force residual and recovers the stiffness.

#[path = "../examples/custom_effect.rs"]
#[allow(dead_code)]
mod custom_effect;

use custom_effect::{STIFFNESS, TETHER, diagnose_tether, tethered_log};

#[test]
fn a_user_defined_tether_is_found_and_removed() {
    let log = tethered_log(&TETHER, 15.0, 5).unwrap();
    let outcome = diagnose_tether(&log, &TETHER).unwrap();

    assert!(
        outcome
            .builtins_only
            .ranking
            .iter()
            .all(|c| c.effect != "tether")
    );
    let before = &outcome.report.before;
    assert_eq!(before.ranking[0].effect, "tether", "{}", before.verdict);
    assert_eq!(before.recommended.as_deref(), Some("tether"));

    let after = outcome.report.after.as_ref().expect("the tether was added");
    let k = after.effects[0].coefficients[0].value;
    assert!(
        (k - STIFFNESS).abs() < 0.01 * STIFFNESS,
        "fitted stiffness {k} N/m, true {STIFFNESS}"
    );
    let change = outcome.report.change.as_ref().unwrap();
    for c in &change[..2] {
        assert!(
            c.rms_reduction >= 0.5,
            "{}: RMS {:.3e} -> {:.3e}",
            c.name,
            c.rms_before,
            c.rms_after
        );
    }
}
