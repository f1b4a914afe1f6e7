//! Logs with rotor speeds instead of the wrench, read with a vehicle description
//! (`tagk diagnose --vehicle`), and the `tagk vehicle` command.
//!
//! Proof: a simulator log (medium noise) written with its rotor speeds `w1..w4` and WITHOUT
//! the wrench columns `fx..tz`:
//! - With a vehicle file whose `k_f` is 15 % too large, `--mass 0.035` recommends
//!   `thrust-gain` (ranked first). Adding it (`--with thrust-gain`) fits the gain
//!   `1/1.15 − 1 = −13.04 %` within ±0.5 points. After that nothing more is recommended.
//! - With the correct vehicle, nothing is recommended. The fitted θ equals the fit of the
//!   original log (with its wrench columns) to 1e-9 relative. The simulator logs the wrench of
//!   its rotor speeds with the same formula, so the wrench is recomputed bit for bit.
//! - A log with a hidden 20 ms motor lag is written without the wrench and read with the
//!   preset. `motor-lag` is ranked first and recommended, acting on the rotor speeds
//!   (thrust ∝ lagged ω²). Its fitted time constant is within a factor 1.5 of 20 ms.
//! - without a vehicle, the log is refused with an error naming the body wrench and the
//!   columns that could provide it.

use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::cli::diagnose::{DiagnoseArgs, KnownMass, diagnose_log, run_diagnose};
use tagk::cli::vehicle::{VehicleArgs, VehicleCommand, run_vehicle};
use tagk::diagnose::{DiagnoseError, EffectKind, FlightLog, LogError, Report};
use tagk::dynamics::quadrotor::CRAZYFLIE_MASS;
use tagk::dynamics::vehicle::{ThrustCurve, Vehicle};
use tagk::sim::{Adaptation, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind};

/// Relative error in `k_f` written into the wrong vehicle file.
const K_F_ERROR: f64 = 0.15;
/// Tolerance on the fitted thrust gain \[1\] (absolute, i.e. ±0.5 percentage points).
const GAIN_TOLERANCE: f64 = 0.005;
/// Tolerance on θ between the original log and the log recomputed from rotor speeds
/// (relative to the largest |θ_k| of its group: mass, first moment, inertia).
const THETA_TOLERANCE: f64 = 1e-9;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-vehicle-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 25 s figure-8 flight, no payload, no plant effect, medium noise (seed 3): the original
/// log (with `fx..tz` and `w1..w4`) and the same log written without the wrench columns.
fn write_logs(dir: &Path) -> (PathBuf, PathBuf) {
    write_logs_with(dir, PlantEffects::none())
}

/// As [`write_logs`], with the given plant effects.
fn write_logs_with(dir: &Path, effects: PlantEffects) -> (PathBuf, PathBuf) {
    let config = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed: 3,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects,
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    let out = tagk::sim::simulate(&config).expect("simulation runs");
    assert!(!out.metrics.aborted);
    assert!(out.log.rotor_speeds.is_some(), "the simulator logs w1..w4");
    let original = dir.join("original.csv");
    out.log.write_csv_path(&original).unwrap();
    let mut stripped = out.log.clone();
    stripped.wrench.clear();
    let rotors_only = dir.join("rotors.csv");
    stripped.write_csv_path(&rotors_only).unwrap();
    let header = std::fs::read_to_string(&rotors_only)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    assert!(header.contains("w1,w2,w3,w4"), "{header}");
    for c in ["fx", "fy", "fz", "tx", "ty", "tz"] {
        assert!(!header.split(',').any(|h| h == c), "{header}");
    }
    (original, rotors_only)
}

fn write_vehicle(dir: &Path, name: &str, k_f_error: f64) -> PathBuf {
    let mut v = Vehicle::crazyflie_2_1();
    v.name = name.to_string();
    if let ThrustCurve::Quadratic { k_f } = &mut v.thrust {
        *k_f *= 1.0 + k_f_error;
    }
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, v.to_toml_string()).unwrap();
    path
}

fn args_for(log: &Path, vehicle: Option<&Path>) -> DiagnoseArgs {
    let mut args = DiagnoseArgs::new(log);
    args.vehicle = vehicle.map(|p| p.display().to_string());
    args.mass = Some(KnownMass::Kg(CRAZYFLIE_MASS));
    args.quiet = true;
    args
}

fn run(log: &Path, vehicle: Option<&Path>) -> Report {
    let args = args_for(log, vehicle);
    diagnose_log(&FlightLog::from_csv_path(log).unwrap(), &args).unwrap()
}

fn theta(r: &Report) -> Vec<f64> {
    r.before.parameters.iter().map(|p| p.value).collect()
}

#[test]
fn wrong_thrust_coefficient_is_named_and_the_right_one_gives_the_same_fit() {
    let dir = tmpdir("proof");
    let (original, rotors_only) = write_logs(&dir);
    let wrong = write_vehicle(&dir, "wrong", K_F_ERROR);
    let right = write_vehicle(&dir, "right", 0.0);

    // Wrong k_f: thrust-gain first and recommended, gain ≈ 1/1.15 − 1.
    let r = run(&rotors_only, Some(&wrong));
    let top = &r.before.ranking[0];
    let gain_name = EffectKind::ThrustGain.name();
    assert_eq!(top.effect, gain_name, "{}", top.explanation);
    assert_eq!(r.before.recommended.as_deref(), Some(gain_name));
    // The ranking's screening coefficient uses the rigid-body fit's channel weights; the
    // refit with the effect added (`--with thrust-gain`, the report's "after") is the fit.
    let screening = top.coefficients[0].value;
    let mut args = args_for(&rotors_only, Some(&wrong));
    args.with = vec![gain_name.into()];
    let refit = diagnose_log(&FlightLog::from_csv_path(&rotors_only).unwrap(), &args).unwrap();
    let after = refit.after.as_ref().expect("thrust-gain added");
    let kappa = after.effects[0].coefficients[0].value;
    let expected = 1.0 / (1.0 + K_F_ERROR) - 1.0;
    eprintln!(
        "wrong k_f (+15 %): thrust gain {kappa:+.5} (screening {screening:+.4}), expected {expected:+.5}"
    );
    assert!(
        (kappa - expected).abs() <= GAIN_TOLERANCE,
        "gain {kappa}, expected {expected} ± {GAIN_TOLERANCE}"
    );
    assert_eq!(after.recommended, None);

    // Right k_f: nothing recommended, θ as from the logged wrench.
    let from_rotors = run(&rotors_only, Some(&right));
    let from_wrench = run(&original, None);
    assert_eq!(from_rotors.before.recommended, None);
    assert_eq!(from_wrench.before.recommended, None);
    let (a, b) = (theta(&from_rotors), theta(&from_wrench));
    assert_eq!(a.len(), 10);
    eprintln!(
        "theta from rotor speeds == theta from the logged wrench, bit for bit: {}",
        a == b
    );
    for group in [0..1, 1..4, 4..10] {
        let scale = b[group.clone()].iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for k in group {
            assert!(
                (a[k] - b[k]).abs() <= THETA_TOLERANCE * scale,
                "theta[{k}]: {} from rotor speeds, {} from the wrench",
                a[k],
                b[k]
            );
        }
    }
    // The preset by name is the same vehicle as the right file.
    let mut args = args_for(&rotors_only, None);
    args.vehicle = Some("crazyflie-2.1".into());
    let by_name = diagnose_log(&FlightLog::from_csv_path(&rotors_only).unwrap(), &args).unwrap();
    assert_eq!(theta(&by_name), a);
}

#[test]
fn motor_lag_acts_on_the_rotor_speeds() {
    let dir = tmpdir("lag");
    let mut effects = PlantEffects::none();
    effects.motor_lag = Some(tagk::sim::plant_effects::MotorLag {
        time_constant: 0.02,
    });
    let (_, rotors_only) = write_logs_with(&dir, effects);
    let mut args = DiagnoseArgs::new(&rotors_only);
    args.vehicle = Some("crazyflie-2.1".into());
    args.quiet = true;
    let r = diagnose_log(&FlightLog::from_csv_path(&rotors_only).unwrap(), &args).unwrap();
    let top = &r.before.ranking[0];
    let lag = EffectKind::MotorLag.name();
    assert_eq!(top.effect, lag, "{}", top.explanation);
    assert_eq!(r.before.recommended.as_deref(), Some(lag));
    let (_, tau, _) = top.scanned.clone().expect("time constant scanned");
    eprintln!("hidden 20 ms motor lag: fitted tau {:.1} ms", 1e3 * tau);
    assert!((0.02 / 1.5..=0.02 * 1.5).contains(&tau), "tau {tau}");
}

#[test]
fn a_log_without_wrench_needs_a_vehicle() {
    let dir = tmpdir("refused");
    let (_, rotors_only) = write_logs(&dir);
    let args = args_for(&rotors_only, None);
    let err = run_diagnose(&args).unwrap_err();
    match &err {
        DiagnoseError::Log(LogError::InFile { path, source }) => {
            assert!(path.ends_with("rotors.csv"), "{path}");
            assert_eq!(
                **source,
                LogError::MissingWrench {
                    has_rotor_speeds: true
                }
            );
        }
        other => panic!("{other:?}"),
    }
    let text = err.to_string();
    for needle in [
        "body wrench",
        "fx,fy,fz,tx,ty,tz",
        "w1,w2,w3,w4",
        "--vehicle",
    ] {
        assert!(text.contains(needle), "{text}");
    }
    // `--mass vehicle` takes the vehicle's prior, and needs a vehicle.
    let mut args = args_for(&rotors_only, None);
    args.mass = Some(KnownMass::Vehicle);
    assert!(matches!(
        run_diagnose(&args),
        Err(DiagnoseError::InvalidOption { field: "mass", .. })
    ));
    args.vehicle = Some("crazyflie-2.1".into());
    args.mass = Some(KnownMass::Vehicle);
    let with_prior = diagnose_log(&FlightLog::from_csv_path(&rotors_only).unwrap(), &args).unwrap();
    args.mass = Some(KnownMass::Kg(CRAZYFLIE_MASS));
    let with_kg = diagnose_log(&FlightLog::from_csv_path(&rotors_only).unwrap(), &args).unwrap();
    assert_eq!(theta(&with_prior), theta(&with_kg));
    // An unknown vehicle is named.
    args.vehicle = Some("no-such-quad".into());
    let e = run_diagnose(&args).unwrap_err().to_string();
    assert!(
        e.contains("no-such-quad") && e.contains("crazyflie-2.1"),
        "{e}"
    );

    // The binary: the same message, and a non-zero exit.
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg(&rotors_only)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("rotors.csv") && stderr.contains("--vehicle"),
        "{stderr}"
    );
}

#[test]
fn vehicle_show_prints_a_template_that_reads_back() {
    let text = run_vehicle(&VehicleArgs {
        command: VehicleCommand::Show {
            name: "crazyflie-2.1".into(),
        },
    })
    .unwrap();
    assert_eq!(
        Vehicle::from_toml_str(&text).unwrap(),
        Vehicle::crazyflie_2_1()
    );
    let list = run_vehicle(&VehicleArgs {
        command: VehicleCommand::List,
    })
    .unwrap();
    assert!(list.contains("crazyflie-2.1"), "{list}");

    // The binary prints the same template; `show FILE` checks a file.
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["vehicle", "show", "crazyflie-2.1"])
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(String::from_utf8_lossy(&out.stdout), text);
    let dir = tmpdir("show");
    let file = dir.join("bad.toml");
    std::fs::write(&file, text.replace("k_f = 2.3e-8", "k_f = 0.0")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["vehicle", "show"])
        .arg(&file)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad.toml") && stderr.contains("`k_f`"),
        "{stderr}"
    );
}
