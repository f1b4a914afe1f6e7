//! Issue #25, the glitch screen.
//!
//! A valid simulator log gets a run of three bad `fz` samples, one bad rotor speed and an
//! attitude jump the gyro does not show. Each is named by the file and line the user opens
//! (terminal, JSON, HTML).
//! A merged log names the line of its time base's stream. It says plainly when a channel's
//! line is not known.
//! A quaternion's sign flip is no glitch.
//! Valid logs give none, nor a scale finding: the false-alarm count over 50 realistic flights
//! of different seeds (release only).

mod common;

use std::path::{Path, PathBuf};

use tagk::diagnose::FlightLog;
use tagk::diagnose::glitches::screen;
use tagk::diagnose::scales::check_log;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-glitch-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `text` (a CSV file) with `edit(data row, cells)` applied to each data row.
fn edit_rows(text: &str, edit: impl Fn(usize, &mut Vec<String>, &[&str])) -> String {
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let mut out = vec![text.lines().next().unwrap().to_string()];
    for (k, line) in text.lines().skip(1).enumerate() {
        let mut cells: Vec<String> = line.split(',').map(String::from).collect();
        edit(k, &mut cells, &header);
        out.push(cells.join(","));
    }
    out.join("\n") + "\n"
}

fn col(header: &[&str], name: &str) -> usize {
    header.iter().position(|c| *c == name).unwrap()
}

#[test]
fn a_run_a_rotor_speed_and_an_attitude_jump_are_named_by_file_and_line() {
    let dir = tmpdir("three");
    common::tagk_in(
        &dir,
        &[
            "simulate",
            "--duration",
            "10",
            "--effect",
            "linear-drag",
            "--sensing",
            "realistic",
            "--seed",
            "4",
            "-o",
            "flight.csv",
        ],
    );
    let text = std::fs::read_to_string(dir.join("flight.csv")).unwrap();
    let edited = edit_rows(&text, |k, cells, header| {
        // Rows 200..=202 (lines 202..=204): fz = 30 N.
        if (200..=202).contains(&k) {
            cells[col(header, "fz")] = "30".into();
        }
        // Row 320 (line 322): w2 reads 0 (a dropped telemetry sample).
        if k == 320 {
            cells[col(header, "w2")] = "0".into();
        }
        let q = ["qw", "qx", "qy", "qz"].map(|c| col(header, c));
        // Row 400 (line 402): the attitude turned 0.3 rad about x, then back.
        if k == 400 {
            let [w, x, y, z] = q.map(|j| cells[j].parse::<f64>().unwrap());
            // q ⊗ (cos 0.15, sin 0.15, 0, 0), Hamilton.
            let (c, s) = (0.15f64.cos(), 0.15f64.sin());
            let b = [w * c - x * s, w * s + x * c, y * c + z * s, z * c - y * s];
            for (j, x) in q.iter().zip(b) {
                cells[*j] = format!("{x:e}");
            }
        }
        // Rows 100..110: the quaternion's sign flipped (the same attitude).
        if (100..110).contains(&k) {
            for j in q {
                cells[j] = format!("{:e}", -cells[j].parse::<f64>().unwrap());
            }
        }
    });
    std::fs::write(dir.join("glitch.csv"), edited).unwrap();
    let out = common::tagk_in(
        &dir,
        &[
            "diagnose",
            "glitch.csv",
            "--json",
            "d.json",
            "--report",
            "html",
            "--max-steps",
            "0",
        ],
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d.json")).unwrap()).unwrap();
    let html = std::fs::read_to_string(dir.join("html/index.html")).unwrap();
    let glitches = json["glitches"].as_array().unwrap();
    let found: Vec<(String, u64, u64, u64)> = glitches
        .iter()
        .map(|g| {
            (
                g["channel"].as_str().unwrap().to_string(),
                g["line"].as_u64().unwrap(),
                g["last_line"].as_u64().unwrap(),
                g["samples"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        found,
        [
            ("fz".to_string(), 202, 204, 3),
            ("w2".to_string(), 322, 322, 1),
            ("q".to_string(), 402, 402, 1),
        ],
        "{out}"
    );
    assert!(glitches.iter().all(|g| g["file"] == "glitch.csv"));
    for needle in [
        "fz = up to 30 N at glitch.csv:202-204 (3 samples from t = 4.010 s, sample 200;",
        "w2 = 0 rad/s at glitch.csv:322 (t = 6.410 s, sample 320;",
        "attitude q turns ",
        "rad at glitch.csv:402 (t = 8.010 s, sample 400; the gyro shows",
    ] {
        assert!(out.contains(needle), "{needle} not in\n{out}");
        assert!(html.contains(needle), "{needle} not in the HTML");
    }
    assert!(out.contains("glitches: 5 samples excluded"), "{out}");
}

#[test]
fn a_merged_log_names_the_time_base_line_and_says_when_a_line_is_not_known() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/foreign-flight");
    let dir = tmpdir("merged");
    for f in ["map.toml", "mocap.csv"] {
        std::fs::copy(src.join(f), dir.join(f)).unwrap();
    }
    // The time base (imu.csv, primary): gyro_y 100 deg/s off on row 600 (line 602).
    let imu = std::fs::read_to_string(src.join("imu.csv")).unwrap();
    let imu = edit_rows(&imu, |k, cells, header| {
        if k == 600 {
            let j = col(header, "gyro_y");
            cells[j] = format!("{:e}", cells[j].parse::<f64>().unwrap() + 100.0);
        }
    });
    std::fs::write(dir.join("imu.csv"), imu).unwrap();
    // Another stream (motors.csv): m3_rpm 8000 rpm off on row 300.
    let motors = std::fs::read_to_string(src.join("motors.csv")).unwrap();
    let motors = edit_rows(&motors, |k, cells, header| {
        if k == 300 {
            let j = col(header, "m3_rpm");
            cells[j] = format!("{:e}", cells[j].parse::<f64>().unwrap() + 8000.0);
        }
    });
    std::fs::write(dir.join("motors.csv"), motors).unwrap();
    let out = common::tagk_in(
        &dir,
        &[
            common::FOREIGN_FLIGHT,
            &["--json", "d.json", "--max-steps", "0"],
        ]
        .concat(),
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d.json")).unwrap()).unwrap();
    let glitches = json["glitches"].as_array().unwrap();
    let wy = glitches.iter().find(|g| g["channel"] == "wy").expect(&out);
    assert_eq!(wy["file"], "imu.csv");
    assert_eq!(wy["line"], 602);
    assert!(out.contains("at imu.csv:602 ("), "{out}");
    let w3 = glitches.iter().find(|g| g["channel"] == "w3").expect(&out);
    assert!(w3["line"].is_null());
    assert_eq!(
        w3["line_unknown"],
        "w3 comes from motors.csv, interpolated onto the time base of imu.csv"
    );
    assert!(
        out.contains(
            "line not known: w3 comes from motors.csv, interpolated onto the time base of imu.csv"
        ),
        "{out}"
    );
}

/// The glitches `screen` finds on a log in memory and the scale checks' findings without a
/// vehicle or a mass (none expected), with the log's label.
fn count(label: &str, log: &FlightLog, found: &mut Vec<String>) -> usize {
    let g = screen("", log);
    found.extend(g.iter().map(|g| format!("{label}: {}", g.text())));
    let f = check_log("", log, None);
    found.extend(f.iter().map(|f| format!("{label}: {}", f.text())));
    log.len()
}

/// The false-alarm measurement of the glitch screen and the scale checks (the gyro's among
/// them): 50 realistic simulated flights (seeds 100..150, the README's
/// effects, 20 s each), the README's realistic example and the shipped foreign flight.
/// Release only (about 15 s).
#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "release only: cargo test --release --test glitch_screen"
)]
fn valid_realistic_logs_give_no_glitch_and_no_scale_finding() {
    let dir = tmpdir("valid");
    let mut found = Vec::new();
    let (mut flights, mut samples) = (0, 0);
    for seed in 100..150 {
        let seed = seed.to_string();
        common::tagk_in(
            &dir,
            &[
                &["simulate", "--duration", "20"][..],
                common::README_REALISTIC,
                &["--seed", &seed, "-o", "flight.csv"],
            ]
            .concat(),
        );
        let log = FlightLog::from_csv_path(dir.join("flight.csv")).unwrap();
        samples += count(&format!("seed {seed}"), &log, &mut found);
        flights += 1;
    }
    // The README's realistic example (its default seed and duration).
    common::tagk_in(
        &dir,
        &[
            &["simulate"][..],
            common::README_REALISTIC,
            &["-o", "readme.csv"],
        ]
        .concat(),
    );
    let log = FlightLog::from_csv_path(dir.join("readme.csv")).unwrap();
    samples += count("README", &log, &mut found);
    flights += 1;
    // The shipped foreign flight, merged through its mapping.
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/foreign-flight");
    let out = common::tagk_in(
        &src,
        &[common::FOREIGN_FLIGHT, &["--max-steps", "0"]].concat(),
    );
    assert!(!out.contains("glitches:"), "{out}");
    flights += 1;
    println!(
        "{flights} valid flights, {samples} samples: {} glitches or scale findings",
        found.len()
    );
    assert!(found.is_empty(), "{}", found.join("\n"));
}
