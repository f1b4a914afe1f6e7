//! Issue #25's proof on a public benchmark's layout: a simulated Crazyflie flight written as one
//! CSV `t, x, y, z, qx, qy, qz, qw, vx, vy, vz, wx, wy, wz, ax, ay, az` with `ax..az` the
//! **world-frame specific force** (+9.81 m/s² on z at hover), the rotor speeds in eRPM
//! (`m1_erpm..m4_erpm`, 7 pole pairs), `Vbat`, empty `*_poses` columns and `True/False` status
//! columns, the quaternion scaled to norm 1.013. Read with the mapping of
//! docs/COLUMN_MAPPING.md ("A public benchmark's layout", the file
//! `examples/data/benchmark-layout/map.toml`) and diagnosed with the vehicle, it gives the
//! simulator's mass within 2 %; read naively (`ax..az` as `p̈`) it is refused, naming the
//! cause. The renormalised quaternion and the unread columns are reported in the terminal, the
//! JSON and the HTML report.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::cli::diagnose::{DiagnoseArgs, diagnose_log, read_log};
use tagk::diagnose::{DiagnoseError, FlightLog};
use tagk::dynamics::GRAVITY_WORLD;
use tagk::dynamics::log_input::InputError;
use tagk::dynamics::quadrotor::CRAZYFLIE_MASS;
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind,
};

/// The mapping the docs give for this layout (the test reads the shipped file, and checks that
/// the docs quote it verbatim).
const MAPPING: &str = include_str!("../examples/data/benchmark-layout/map.toml");

/// The motors' pole pairs the mapping assumes.
const POLE_PAIRS: f64 = 7.0;

/// The norm the benchmark's quaternions have.
const QUATERNION_NORM: f64 = 1.013;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-benchmark-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 25 s figure-8 of the Crazyflie with rotor drag in the plant and the paper's medium sensor
/// noise (seed 3), as the simulator logs it (with its accelerations).
fn simulate() -> FlightLog {
    simulate_seed(3)
}

/// [`simulate`] with another seed.
fn simulate_seed(seed: u64) -> FlightLog {
    let config = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: PlantEffects::only(EffectKind::RotorDrag).unwrap(),
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    let out = tagk::sim::simulate(&config).expect("simulation runs");
    assert!(!out.metrics.aborted);
    out.log
}

/// Writes `log` in the benchmark's layout as `dir/flight.csv` (the mapping next to it as
/// `map.toml`, with `mapping`'s text); returns the log's path.
fn write_benchmark(log: &FlightLog, dir: &Path, mapping: &str) -> PathBuf {
    let erpm = 30.0 / std::f64::consts::PI * POLE_PAIRS;
    let accel = log
        .accel
        .as_ref()
        .expect("the simulator logs accelerations");
    let speeds = log
        .rotor_speeds
        .as_ref()
        .expect("the simulator logs rotor speeds");
    let mut text = String::from(
        "t,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz,ax,ay,az,m1_erpm,m2_erpm,m3_erpm,m4_erpm,Vbat,\
         body_poses,target_poses,is_flying,is_tracking\n",
    );
    for i in 0..log.len() {
        let (p, v, q, w) = (
            log.position[i],
            log.velocity[i],
            log.attitude[i],
            log.omega[i],
        );
        // The world-frame specific force f_w = p̈ − g_w.
        let f: Vec<f64> = (0..3).map(|k| accel[i][k] - GRAVITY_WORLD[k]).collect();
        let s = QUATERNION_NORM;
        let mut cells: Vec<String> = [
            log.t[i],
            p[0],
            p[1],
            p[2],
            q[1] * s,
            q[2] * s,
            q[3] * s,
            q[0] * s,
            v[0],
            v[1],
            v[2],
            w[0],
            w[1],
            w[2],
            f[0],
            f[1],
            f[2],
        ]
        .iter()
        .chain(&speeds[i].map(|x| x * erpm))
        .chain(&[4.1 - 0.01 * log.t[i]])
        .map(|x| format!("{x:e}"))
        .collect();
        cells.extend(["", "", "True", if i % 7 == 0 { "False" } else { "True" }].map(String::from));
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    let path = dir.join("flight.csv");
    std::fs::write(&path, text).unwrap();
    std::fs::write(dir.join("map.toml"), mapping).unwrap();
    path
}

fn args(dir: &Path, log: &Path) -> DiagnoseArgs {
    let mut args = DiagnoseArgs::new(log);
    args.columns = Some(dir.join("map.toml"));
    args.vehicle = Some("crazyflie-2.1".into());
    args.quiet = true;
    args
}

#[test]
fn the_docs_quote_the_shipped_mapping() {
    let doc = include_str!("../docs/COLUMN_MAPPING.md");
    let section = doc
        .split("## A public benchmark's layout")
        .nth(1)
        .expect("the section");
    assert!(
        section.contains(&format!("```toml\n{MAPPING}```")),
        "docs/COLUMN_MAPPING.md quotes examples/data/benchmark-layout/map.toml verbatim"
    );
}

#[test]
fn a_benchmark_flight_gives_the_simulators_mass_within_2_percent() {
    let dir = tmpdir("mass");
    let log = write_benchmark(&simulate(), &dir, MAPPING);
    let args = args(&dir, &log);
    let (read, merge) = read_log(&args).unwrap();
    let merge = merge.expect("read through the mapping");
    assert!(
        (merge.quaternion_renormalised.unwrap() - (QUATERNION_NORM - 1.0)).abs() < 1e-9,
        "{merge:?}"
    );
    assert_eq!(read.extra.len(), 1);
    assert_eq!(read.extra[0].0, "vbat");
    let unread: Vec<&str> = merge
        .unread_columns
        .iter()
        .map(|u| u.column.as_str())
        .collect();
    assert_eq!(
        unread,
        ["body_poses", "target_poses", "is_flying", "is_tracking"]
    );
    let report = diagnose_log(&read, &args).unwrap();
    let m = report.final_diagnosis().parameters[0].value;
    let error = (m - CRAZYFLIE_MASS).abs() / CRAZYFLIE_MASS;
    eprintln!(
        "fitted mass {m:.5} kg, simulator {CRAZYFLIE_MASS} kg: {:.2} %; final model {}",
        100.0 * error,
        report.final_model.label
    );
    assert!(error < 0.02, "fitted mass {m} kg vs {CRAZYFLIE_MASS} kg");
}

#[test]
fn the_naive_mapping_is_refused_naming_the_specific_force() {
    let dir = tmpdir("naive");
    let naive: String = MAPPING
        .lines()
        .filter(|l| !l.starts_with("accel ="))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_ne!(naive, MAPPING);
    let log = write_benchmark(&simulate(), &dir, &naive);
    let e = read_log(&args(&dir, &log)).unwrap_err();
    assert!(
        matches!(
            e,
            DiagnoseError::Input(InputError::AccelLooksLikeSpecificForce { mean_z, .. })
                if (mean_z - 9.81).abs() < 0.2
        ),
        "{e:?}"
    );
    // The command line says so on its standard error and fails.
    let stderr = common::tagk_fails_in(
        &dir,
        &[
            "diagnose",
            "--columns",
            "map.toml",
            "--vehicle",
            "crazyflie-2.1",
            "flight.csv",
        ],
    );
    assert!(
        stderr.contains("flight.csv: the columns read as the world acceleration ax, ay, az (p̈)")
            && stderr.contains("most likely the world-frame specific force")
            && stderr.contains("`[frames] accel = \"specific-force\"`"),
        "{stderr}"
    );
}

#[test]
fn the_renormalised_quaternion_and_the_unread_columns_are_in_terminal_json_and_html() {
    let dir = tmpdir("outputs");
    write_benchmark(&simulate(), &dir, MAPPING);
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args([
            "diagnose",
            "--columns",
            "map.toml",
            "--vehicle",
            "crazyflie-2.1",
            "flight.csv",
            "--json",
            "out.json",
            "--report",
            "rep",
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let warning = "warning: the quaternions of flight.csv were divided by their norm \
                   (normalize_quaternion): the largest |‖q‖ − 1| was 0.0130";
    let unread = "not read (unmapped, not numeric): body_poses (flight.csv, line 2: ``)";
    assert!(stdout.contains(warning), "{stdout}");
    assert!(stdout.contains(unread), "{stdout}");
    assert!(stdout.contains("stream flight.csv: 50.0 Hz, "), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out.json")).unwrap()).unwrap();
    let input = &json["inputs"][0];
    assert_eq!(input["primary"], "flight.csv");
    assert!((input["quaternion_renormalised"].as_f64().unwrap() - 0.013).abs() < 1e-9);
    assert_eq!(
        input["warnings"][0].as_str().unwrap(),
        warning.trim_start_matches("warning: ")
    );
    assert_eq!(input["unread_columns"][2]["column"], "is_flying");
    assert_eq!(input["unread_columns"][2]["value"], "True");
    assert_eq!(input["streams"][0]["stream"], "flight.csv");
    let html = std::fs::read_to_string(dir.join("rep/index.html")).unwrap();
    assert!(
        html.contains("warning: the quaternions of flight.csv were divided by their norm"),
        "no warning in the HTML report"
    );
    assert!(html.contains("<h2 id=\"inputs\">Inputs</h2>"));
    assert!(html.contains("<td>flight.csv</td><td>50.0</td>"));
    // Several flights: each one's warnings in the terminal, under its name.
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let second = write_benchmark(&simulate_seed(4), &other, MAPPING);
    std::fs::copy(second, dir.join("second.csv")).unwrap();
    let stdout = common::tagk_in(
        &dir,
        &[
            "diagnose",
            "--columns",
            "map.toml",
            "--vehicle",
            "crazyflie-2.1",
            "flight.csv",
            "second.csv",
        ],
    );
    for name in ["flight.csv", "second.csv"] {
        let line = format!("{name}: warning: the quaternions of {name} were divided by their norm");
        assert!(stdout.contains(&line), "{stdout}");
    }
}
