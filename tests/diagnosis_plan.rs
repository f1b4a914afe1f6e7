//! The library owns the pipeline (issue #24): a [`DiagnosisPlan`] built by a library user
//! gives the report `tagk diagnose` gives, number for number. The command line adds only the
//! command that reproduces the final model and the next step, which name its flags.

mod common;

use std::path::{Path, PathBuf};

use common::tagk_in;
use tagk::diagnose::{AlignOptions, DiagnosisPlan, FlightLog, KnownMass, Report, Sensor};
use tagk::dynamics::log_input::ColumnMapping;
use tagk::dynamics::vehicle::Vehicle;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-plan-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `tagk simulate`: a 12 s figure-8 at 50 Hz with a hidden linear drag and the paper's medium
/// noise, written to `dir/name` and read back.
fn simulate(dir: &Path, name: &str, seed: u64) -> FlightLog {
    let seed = seed.to_string();
    let flags = [
        "--effect",
        "linear-drag",
        "--noise",
        "medium",
        "--duration",
        "12",
    ];
    let mut args = vec!["simulate", "--seed", &seed, "-o", name];
    args.extend(flags);
    tagk_in(dir, &args);
    FlightLog::from_csv_path(dir.join(name)).unwrap()
}

/// The flight without the samples of `5 s < t < 6 s`: a gap, two segments of 250 and 300
/// samples.
fn with_gap(log: &FlightLog) -> FlightLog {
    let mut cut = FlightLog::new();
    for s in log.samples().filter(|s| !(s.t > 5.0 && s.t < 6.0)) {
        cut.push(&s);
    }
    cut
}

/// `tagk diagnose ARGS --json` as JSON, without what only the command line knows (the
/// command and the next step).
fn cli_json(dir: &Path, args: &[&str]) -> serde_json::Value {
    let mut all = vec!["diagnose"];
    all.extend(args);
    all.extend(["--quiet", "--json", "cli.json"]);
    tagk_in(dir, &all);
    let json = dir.join("cli.json");
    let mut value: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(value["final_model"]["command"].is_string());
    assert!(value["next"].is_object());
    value["final_model"]["command"] = serde_json::Value::Null;
    value["next"] = serde_json::Value::Null;
    value
}

fn json(report: &Report) -> serde_json::Value {
    assert!(report.final_model.command.is_none() && report.next.is_none());
    serde_json::from_str(&report.to_json().unwrap()).unwrap()
}

#[test]
fn the_plan_gives_the_command_line_s_report() {
    let dir = tmpdir("same");
    let (a, b) = (simulate(&dir, "a.csv", 1), simulate(&dir, "b.csv", 2));
    let gap = with_gap(&b);
    gap.write_csv_path(dir.join("gap.csv")).unwrap();
    let mut rotors = a.clone();
    rotors.wrench.clear();
    rotors.write_csv_path(dir.join("rotors.csv")).unwrap();
    let vehicle = || Vehicle::preset("crazyflie-2.1").unwrap();

    // One log, as it is.
    let report = DiagnosisPlan::new().log(a.clone()).run().unwrap();
    assert_eq!(json(&report), cli_json(&dir, &["a.csv"]));

    // One log with a gap, resampled; a known offset instead of the measured ones; the online
    // pass.
    let report = DiagnosisPlan::new()
        .file(dir.join("gap.csv"))
        .resample(0.025)
        .align(AlignOptions {
            shifts: vec![(Sensor::Pose, 0.01)],
            ..AlignOptions::default()
        })
        .online(tagk::diagnose::DEFAULT_ONLINE_STRIDE)
        .run()
        .unwrap();
    assert_eq!(report.sampling[0].segments, 2);
    assert!(report.online.is_some());
    assert_eq!(
        json(&report),
        cli_json(
            &dir,
            &[
                "gap.csv",
                "--resample",
                "0.025",
                "--shift",
                "pose=0.01",
                "--online"
            ]
        )
    );

    // Several logs, one of them with a gap (its segments join as logs of their own); effects
    // by name and a custom one; no alignment.
    let report = DiagnosisPlan::new()
        .named_log("a.csv", a.clone())
        .named_log("b.csv", b)
        .named_log("gap.csv", gap)
        .custom("vv=vx*vy@fx,fy")
        .with_effects(["linear-drag", "vv"])
        .align(AlignOptions {
            auto: false,
            ..AlignOptions::default()
        })
        .max_steps(2)
        .run()
        .unwrap();
    let names: Vec<&str> = report.logs.iter().map(|l| l.log.as_str()).collect();
    assert_eq!(names.len(), 4, "{names:?}");
    assert!(names[2].starts_with("gap.csv (segment 1 of 2"), "{names:?}");
    assert_eq!(
        json(&report),
        cli_json(
            &dir,
            &[
                "a.csv",
                "b.csv",
                "gap.csv",
                "--custom",
                "vv=vx*vy@fx,fy",
                "--with",
                "linear-drag,vv",
                "--no-align",
                "--max-steps",
                "2"
            ]
        )
    );

    // Rotor speeds and no wrench: the vehicle computes it, and gives the mass prior.
    let report = DiagnosisPlan::new()
        .file(dir.join("rotors.csv"))
        .vehicle(vehicle())
        .known_mass(KnownMass::Vehicle)
        .run()
        .unwrap();
    assert_eq!(
        json(&report),
        cli_json(
            &dir,
            &[
                "rotors.csv",
                "--vehicle",
                "crazyflie-2.1",
                "--mass",
                "vehicle"
            ]
        )
    );

    // The shipped foreign flight: three streams through a column mapping.
    let foreign = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/foreign-flight");
    let streams = ["imu.csv", "motors.csv", "mocap.csv"].map(|f| foreign.join(f));
    let plan = DiagnosisPlan::new()
        .columns(ColumnMapping::from_path(foreign.join("map.toml")).unwrap())
        .vehicle(vehicle())
        .streams(&streams)
        .with_effects(["rotor-drag"])
        .read()
        .unwrap();
    let merge = plan.flights().next().unwrap().merge.clone().unwrap();
    assert_eq!(merge.primary, "imu.csv");
    let report = plan.run().unwrap();
    let map = foreign.join("map.toml");
    let mut args = vec!["--columns", map.to_str().unwrap()];
    args.extend(["--vehicle", "crazyflie-2.1", "--with", "rotor-drag"]);
    for s in &streams {
        args.extend(["--stream", s.to_str().unwrap()]);
    }
    assert_eq!(json(&report), cli_json(&dir, &args));
    std::fs::remove_dir_all(&dir).ok();
}
