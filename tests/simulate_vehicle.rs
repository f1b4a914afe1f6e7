//! `tagk simulate --vehicle FILE` flies the file's vehicle: a heavier quadrotor (60 g,
//! `k_f = 4e-8`, 4 cm arms) flown with realistic sensing hovers on the file's rotors (mean
//! logged thrust `m g` within 3 %), and `tagk diagnose --vehicle FILE` recovers the file's
//! mass within 1 %. A vehicle the simulator cannot fly (a thrust curve with a constant term, no
//! mass) is refused with an error naming the key.

use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::cli::diagnose::{DiagnoseArgs, diagnose_log};
use tagk::diagnose::FlightLog;

/// The heavier vehicle's mass \[kg\].
const MASS: f64 = 0.06;

const ROTORS: &str = r#"
[[rotor]]
position = [0.04, -0.04, 0.0]
spin = "cw"

[[rotor]]
position = [-0.04, -0.04, 0.0]
spin = "ccw"

[[rotor]]
position = [-0.04, 0.04, 0.0]
spin = "cw"

[[rotor]]
position = [0.04, 0.04, 0.0]
spin = "ccw"
"#;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-simvehicle-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_vehicle(dir: &Path, name: &str, keys: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, format!("{keys}\n{ROTORS}")).unwrap();
    path
}

fn simulate(vehicle: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args([
            "simulate",
            "--sensing",
            "realistic",
            "--seed",
            "3",
            "--vehicle",
        ])
        .arg(vehicle)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn a_heavier_vehicle_file_is_flown_and_its_mass_diagnosed() {
    let dir = tmpdir("heavy");
    let heavy = write_vehicle(
        &dir,
        "heavy",
        &format!(
            "max_rotor_speed = 2500.0\nk_f = 4.0e-8\nk_m = 1.2e-9\nmass = {MASS}\n\
             inertia = [3.0e-5, 0.0, 3.2e-5, 0.0, 0.0, 5.5e-5]\nairframe_radius = 0.05"
        ),
    );
    let log_path = dir.join("heavy.csv");
    let out = simulate(&heavy, &log_path);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // Hover thrust: the rotors of the file carry the file's weight.
    let log = FlightLog::from_csv_path(&log_path).unwrap();
    let mean_fz = log.wrench.iter().map(|w| w[2]).sum::<f64>() / log.len() as f64;
    let weight = MASS * 9.81;
    assert!(
        (mean_fz / weight - 1.0).abs() < 0.03,
        "mean logged thrust {mean_fz} N against the weight {weight} N"
    );
    // The logged wrench is the file's rotor map of the logged rotor speeds.
    let vehicle = tagk::dynamics::vehicle::Vehicle::from_path(&heavy).unwrap();
    let w = vehicle.wrench_from_rotor_speeds(&log.rotor_speeds.as_ref().unwrap()[100]);
    assert!((w.force.z - log.wrench[100][2]).abs() < 1e-12 * w.force.z);

    let mut args = DiagnoseArgs::new(&log_path);
    args.vehicle = Some(heavy.display().to_string());
    args.quiet = true;
    let report = diagnose_log(&log, &args).unwrap();
    let m = report.before.parameters[0].value;
    assert!(
        (m / MASS - 1.0).abs() < 0.01,
        "diagnosed mass {m} kg, the file's {MASS} kg"
    );
}

#[test]
fn a_vehicle_the_simulator_cannot_fly_is_refused_by_name() {
    let dir = tmpdir("refused");
    let cases = [
        (
            "affine",
            "max_rotor_speed = 2500.0\nthrust_curve = [0.01, 0.0, 4e-8]\nk_m = 1.2e-9\n\
             mass = 0.06\ninertia = [3.0e-5, 0.0, 3.2e-5, 0.0, 0.0, 5.5e-5]",
            "thrust_curve",
        ),
        (
            "massless",
            "max_rotor_speed = 2500.0\nk_f = 4e-8\nk_m = 1.2e-9",
            "`mass`",
        ),
    ];
    for (name, keys, needle) in cases {
        let path = write_vehicle(&dir, name, keys);
        let out = simulate(&path, &dir.join(format!("{name}.csv")));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name}");
        assert!(stderr.contains(needle), "{name}: {stderr}");
        assert!(!dir.join(format!("{name}.csv")).exists(), "{name}");
    }
}
