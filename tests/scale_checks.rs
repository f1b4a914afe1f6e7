//! Issue #25, items 2 and 3: a valid simulator log with one mistake in it is told in plain
//! words.
//!
//! The mistakes: a gyro in rad/s read as deg/s, an accelerometer in g read as m/s², a velocity
//! in mm/s, swapped rotor spins in the vehicle file, one glitch in `fz`.
//! Each gives a typed error, or the glitch is excluded and named in the terminal, the JSON and
//! the HTML report.
//! The checks stay silent on valid logs: several seeds of realistic logs here, and the
//! diagnosis benchmark's 300 flights in the release-only measurement at the end.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::diagnose::glitches::screen;
use tagk::diagnose::scales::{Severity, check_log};
use tagk::diagnose::{DiagnoseError, DiagnosisPlan, FlightLog};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-scales-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A short simulated flight (10 s at 100 Hz) in `dir/flight.csv`.
fn simulate(dir: &Path, extra: &[&str]) -> FlightLog {
    let mut args = vec!["simulate", "--duration", "10", "-o", "flight.csv"];
    args.extend_from_slice(extra);
    common::tagk_in(dir, &args);
    FlightLog::from_csv_path(dir.join("flight.csv")).unwrap()
}

/// `tagk diagnose` in `dir`: success, standard output and standard error.
fn diagnose(dir: &Path, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

/// The scale error of running the plan on `log`.
fn scale_error(log: FlightLog) -> (String, String) {
    match DiagnosisPlan::new().log(log).max_steps(0).run() {
        Err(DiagnoseError::ScaleMismatch { check, message }) => (check, message),
        other => panic!(
            "expected a scale mismatch, got {:?}",
            other.map(|r| r.adequate)
        ),
    }
}

#[test]
fn a_gyro_in_rad_s_read_as_deg_s_is_named() {
    let dir = tmpdir("gyro");
    let mut log = simulate(&dir, &[]);
    for w in &mut log.omega {
        *w = w.map(|x| x.to_radians());
    }
    let (check, message) = scale_error(log.clone());
    assert_eq!(check, "gyro");
    assert!(message.contains("rad/s mapped as deg/s"), "{message}");
    // Accepted: the diagnosis goes on, and the finding is in the report.
    let report = DiagnosisPlan::new()
        .log(log)
        .max_steps(0)
        .accept_scales(true)
        .run()
        .unwrap();
    assert_eq!(report.scale_checks.len(), 1, "{:?}", report.scale_checks);
    assert_eq!(report.scale_checks[0].severity, Severity::Accepted);
}

/// Without a vehicle file, on the README's realistic example, gyro unit mistakes are named.
///
/// That log's gyro noise hid the attitude's rate from a comparison of rates (correlation
/// 0.24). A gyro in rad/s mapped as deg/s, and one in deg/s mapped as rad/s, are named by the
/// gyro's rotation over windows.
#[test]
fn a_gyro_unit_mistake_is_named_on_a_realistic_log_without_a_vehicle() {
    let dir = tmpdir("gyro-realistic");
    let log = simulate(&dir, common::README_REALISTIC);
    assert_eq!(check_log("", &log, None), []);
    for (factor, cause) in [
        (1f64.to_radians(), "rad/s mapped as deg/s"),
        (1f64.to_degrees(), "deg/s mapped as rad/s"),
    ] {
        let mut wrong = log.clone();
        for w in &mut wrong.omega {
            *w = w.map(|x| x * factor);
        }
        let (check, message) = scale_error(wrong);
        assert_eq!(check, "gyro");
        assert!(message.contains(cause), "{message}");
    }
}

/// A log in the project's own format whose `ax..az` hold the world-frame specific force is
/// refused.
///
/// A public benchmark stores them so: `p̈ − g`, +9.81 m/s² on z at hover. The log is refused
/// with the cause before the fit, as a mapped log is by its reader.
#[test]
fn a_native_log_with_the_specific_force_in_ax_az_is_refused() {
    let dir = tmpdir("native-sf");
    let mut log = simulate(&dir, &["--sensing", "realistic", "--seed", "8"]);
    for a in log.accel.as_mut().unwrap() {
        a[2] += 9.80665;
    }
    log.write_csv_path(dir.join("sf.csv")).unwrap();
    let (ok, _, err) = diagnose(&dir, &["sf.csv", "--quiet"]);
    assert!(!ok);
    assert!(err.contains("error (specific-force)"), "{err}");
    assert!(
        err.contains("most likely the world-frame specific force"),
        "{err}"
    );
    assert!(err.contains("accel = \"specific-force\""), "{err}");
    // The valid log reads.
    assert!(FlightLog::from_csv_path(dir.join("flight.csv")).is_ok());
}

#[test]
fn an_accelerometer_in_g_read_as_m_s2_is_named_and_accepted_on_request() {
    let dir = tmpdir("accel");
    let mut log = simulate(&dir, &["--sensing", "realistic", "--seed", "3"]);
    for a in log.accel.as_mut().unwrap() {
        *a = a.map(|x| x / 9.80665);
    }
    log.write_csv_path(dir.join("g.csv")).unwrap();
    let (ok, _, err) = diagnose(&dir, &["g.csv", "--quiet"]);
    assert!(!ok);
    assert!(err.contains("error (accelerometer)"), "{err}");
    assert!(err.contains("an acceleration in g mapped as m/s²"), "{err}");
    assert!(err.contains("--accept-scales"), "{err}");
    // With the flag: reported in the terminal, the JSON and the HTML report.
    let (ok, out, err) = diagnose(
        &dir,
        &[
            "g.csv",
            "--accept-scales",
            "--max-steps",
            "0",
            "--json",
            "d.json",
            "--report",
            "html",
        ],
    );
    assert!(ok, "{err}");
    assert!(
        out.contains("scale check: accepted (accelerometer)"),
        "{out}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d.json")).unwrap()).unwrap();
    assert_eq!(json["scale_checks"][0]["check"], "accelerometer");
    assert_eq!(json["scale_checks"][0]["severity"], "accepted");
    let html = std::fs::read_to_string(dir.join("html/index.html")).unwrap();
    assert!(html.contains("id=\"scale-findings\""), "no scale section");
    assert!(html.contains("an acceleration in g mapped as m/s²"));
}

#[test]
fn a_velocity_in_mm_s_is_named() {
    let dir = tmpdir("velocity");
    let mut log = simulate(&dir, &["--sensing", "realistic", "--seed", "4"]);
    for v in &mut log.velocity {
        *v = v.map(|x| 1000.0 * x);
    }
    let (check, message) = scale_error(log);
    assert_eq!(check, "velocity");
    assert!(message.contains("mm/s mapped as m/s"), "{message}");
}

#[test]
fn swapped_rotor_spins_in_the_vehicle_file_are_named() {
    let dir = tmpdir("spins");
    let log = simulate(&dir, &["--sensing", "realistic", "--yaw-rate", "0.3"]);
    // The rotor speeds only: the wrench comes from the vehicle file.
    let mut rotors_only = log.clone();
    rotors_only.wrench.clear();
    rotors_only.write_csv_path(dir.join("rotors.csv")).unwrap();
    let preset = common::tagk_in(&dir, &["vehicle", "show", "crazyflie-2.1"]);
    let swapped = preset
        .replace("spin = \"cw\"", "spin = \"tmp\"")
        .replace("spin = \"ccw\"", "spin = \"cw\"")
        .replace("spin = \"tmp\"", "spin = \"ccw\"");
    assert_ne!(swapped, preset);
    std::fs::write(dir.join("swapped.toml"), swapped).unwrap();
    let (ok, _, err) = diagnose(
        &dir,
        &["rotors.csv", "--vehicle", "swapped.toml", "--quiet"],
    );
    assert!(!ok);
    assert!(err.contains("error (yaw-torque)"), "{err}");
    assert!(err.contains("rotor spins"), "{err}");
    assert!(err.contains("`spin` keys"), "{err}");
    // The preset itself raises nothing.
    let (ok, _, err) = diagnose(
        &dir,
        &[
            "rotors.csv",
            "--vehicle",
            "crazyflie-2.1",
            "--quiet",
            "--max-steps",
            "0",
        ],
    );
    assert!(ok, "{err}");
}

/// A realistic flight with one glitch in `fz`: `value` at sample 299 (of 500).
fn glitch_report(dir: &Path, value: &str) -> (String, serde_json::Value, String) {
    simulate(dir, &["--effect", "linear-drag", "--sensing", "realistic"]);
    let text = std::fs::read_to_string(dir.join("flight.csv")).unwrap();
    let header = text.lines().next().unwrap();
    let fz = header.split(',').position(|c| c == "fz").unwrap();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(k, line)| {
            if k == 300 {
                let mut cells: Vec<&str> = line.split(',').collect();
                cells[fz] = value;
                cells.join(",")
            } else {
                line.to_string()
            }
        })
        .collect();
    std::fs::write(dir.join("glitch.csv"), lines.join("\n") + "\n").unwrap();
    let (ok, out, err) = diagnose(
        dir,
        &[
            "glitch.csv",
            "--json",
            "d.json",
            "--report",
            "html",
            "--max-steps",
            "1",
        ],
    );
    assert!(ok, "{err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(dir.join("html/index.html")).unwrap();
    (out, json, html)
}

#[test]
fn one_glitch_of_30_n_in_fz_is_excluded_and_named() {
    let dir = tmpdir("glitch30");
    let clean = DiagnosisPlan::new()
        .file(dir.join("flight.csv"))
        .max_steps(1);
    let (out, json, html) = glitch_report(&dir, "30");
    assert!(out.contains("glitches: 1 sample excluded"), "{out}");
    assert!(
        out.contains("fz = 30 N at glitch.csv:301 (t = 5.990 s, sample 299;"),
        "{out}"
    );
    assert_eq!(json["glitches"][0]["channel"], "fz");
    assert_eq!(json["glitches"][0]["sample"], 299);
    assert_eq!(json["glitches"][0]["line"], 301);
    assert_eq!(json["glitches"][0]["file"], "glitch.csv");
    assert!(html.contains("id=\"glitch-list\""));
    assert!(html.contains("fz = 30 N at glitch.csv:301 (t = 5.990 s"));
    // The mass is the clean log's, within its interval.
    let clean = clean.run().unwrap();
    let m = |p: &serde_json::Value| p["before"]["parameters"][0]["value"].as_f64().unwrap();
    let m_clean = clean.before.parameters[0].value;
    let se = clean.before.parameters[0].std_error.unwrap();
    assert!(
        (m(&json) - m_clean).abs() < 3.0 * se,
        "{} vs {m_clean} ± {se}",
        m(&json)
    );
}

#[test]
fn one_glitch_of_1e300_in_fz_is_excluded_and_named() {
    let dir = tmpdir("glitch300");
    let (out, json, html) = glitch_report(&dir, "1e300");
    assert!(out.contains("fz = 1.000e300 N at glitch.csv:301"), "{out}");
    assert!(html.contains("fz = 1.000e300 N at glitch.csv:301"));
    let m = json["before"]["parameters"][0]["value"].as_f64().unwrap();
    assert!((0.03..0.04).contains(&m), "mass {m}");
    let floor = json["noise_floor"]["rms"][2].as_f64().unwrap();
    assert!(floor.is_finite() && floor < 1.0, "fz noise floor {floor}");
}

#[test]
fn realistic_logs_raise_no_scale_finding_and_no_glitch() {
    let dir = tmpdir("clean");
    for seed in ["1", "2", "5"] {
        let log = simulate(
            &dir,
            &[common::README_REALISTIC, &["--seed", seed]].concat(),
        );
        assert_eq!(screen("", &log), [], "seed {seed}");
        let findings = check_log("", &log, Some(0.035));
        assert_eq!(findings, [], "seed {seed}");
    }
}

/// The diagnosis benchmark's flights (all 300; `TAGK_SCALE_FLIGHTS` for fewer): every check's
/// findings and the glitches counted, none allowed. Release only (about a minute).
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "release only: cargo test --release --test scale_checks"
)]
fn the_benchmark_flights_raise_no_scale_error_and_no_glitch() {
    use tagk::diagnosis_benchmark::{BenchmarkOptions, GroundTruth, draw_flight};
    let flights: usize = std::env::var("TAGK_SCALE_FLIGHTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300);
    let options = BenchmarkOptions::default();
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    let (mut checked, mut glitches, mut samples) = (0usize, 0usize, 0usize);
    let mut errors = Vec::new();
    for index in 0..flights {
        let spec = draw_flight(&options, index).unwrap();
        let Ok(output) = tagk::sim::simulate(&spec.sim_config()) else {
            continue;
        };
        if output.metrics.aborted {
            continue;
        }
        let Ok(truth) = GroundTruth::of_flight(&spec, &output, options.detectable) else {
            continue;
        };
        let mass = spec.known_mass.then_some(truth.mass);
        // As the plan does: the streams aligned before the checks.
        let (log, _) =
            tagk::diagnose::align_streams_owned(output.log, &Default::default()).unwrap();
        checked += 1;
        samples += log.len();
        let found = screen("", &log);
        glitches += found.len();
        for g in &found {
            errors.push(format!("flight {index}: glitch {}", g.text()));
        }
        for f in check_log("", &log, mass) {
            *counts
                .entry(format!("{} {:?}", f.check, f.severity))
                .or_default() += 1;
            if f.severity == Severity::Error {
                errors.push(format!("flight {index}: {}", f.text()));
            } else {
                println!("flight {index} ({:?}): {}", spec.sensing, f.text());
            }
        }
    }
    println!("{checked} flights, {samples} samples: {glitches} glitches; findings {counts:?}");
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

#[test]
fn a_mass_or_an_inertia_far_from_the_vehicle_file_is_named() {
    let dir = tmpdir("vehicle");
    let log = simulate(&dir, &["--sensing", "realistic", "--seed", "6"]);
    // A known mass ten times the thrust's: the thrust check.
    let err = DiagnosisPlan::new()
        .log(log.clone())
        .known_mass(0.35)
        .max_steps(0)
        .run()
        .unwrap_err();
    match err {
        DiagnoseError::ScaleMismatch { check, message } => {
            assert_eq!(check, "thrust", "{message}");
            assert!(message.contains("the mass 0.35 kg"), "{message}");
        }
        other => panic!("{other}"),
    }
    // A vehicle file whose mass and inertia are 10× and 74× the body's: the fit's checks.
    let preset = common::tagk_in(&dir, &["vehicle", "show", "crazyflie-2.1"]);
    let heavy = preset.replace("mass = 0.035", "mass = 0.35").replace(
        "inertia = [1.66e-5, 8.3e-7, 1.66e-5, 7.2e-7, 1.8e-6, 2.93e-5]",
        "inertia = [1.23e-3, 8.3e-7, 1.23e-3, 7.2e-7, 1.8e-6, 2.17e-3]",
    );
    assert_ne!(heavy, preset);
    std::fs::write(dir.join("heavy.toml"), heavy).unwrap();
    let vehicle = tagk::dynamics::vehicle::Vehicle::from_path(dir.join("heavy.toml")).unwrap();
    let report = DiagnosisPlan::new()
        .log(log)
        .vehicle(vehicle)
        .max_steps(0)
        .accept_scales(true)
        .run()
        .unwrap();
    let checks: Vec<&str> = report
        .scale_checks
        .iter()
        .map(|f| f.check.as_str())
        .collect();
    assert!(checks.contains(&"thrust"), "{checks:?}");
    assert!(checks.contains(&"mass"), "{checks:?}");
    assert!(checks.contains(&"inertia"), "{checks:?}");
    let inertia = report
        .scale_checks
        .iter()
        .find(|f| f.check == "inertia")
        .unwrap();
    assert!(inertia.message.contains("I_xx"), "{}", inertia.message);
    assert_eq!(inertia.severity, Severity::Accepted);
}
