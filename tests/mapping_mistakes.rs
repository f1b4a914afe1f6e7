//! Issue #25's table, the rows about mappings and streams.
//!
//! They run on the shipped foreign flight (`examples/data/foreign-flight`, three streams and
//! `map.toml`) with one mistake at a time. `tagk diagnose` refuses with a message naming the
//! cause on its standard error, or warns in the terminal, the JSON and the HTML report.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SHIPPED: &str = "examples/data/foreign-flight";
const FILES: [&str; 4] = ["imu.csv", "motors.csv", "mocap.csv", "map.toml"];

/// A copy of the shipped flight in a fresh folder.
fn copy_shipped(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-mistakes-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join(SHIPPED);
    for f in FILES {
        std::fs::copy(src.join(f), d.join(f)).unwrap();
    }
    d
}

/// Replaces `from` by `to` in `dir/file` (which must contain it).
fn edit(dir: &Path, file: &str, from: &str, to: &str) {
    let p = dir.join(file);
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains(from), "{file} has no `{from}`");
    std::fs::write(p, text.replacen(from, to, 1)).unwrap();
}

/// Rewrites `dir/motors.csv` row by row (the header kept): `f(index, cells)` returns the new
/// row, or `None` to drop it.
fn rewrite_motors(dir: &Path, f: impl Fn(usize, Vec<f64>) -> Option<Vec<f64>>) {
    let p = dir.join("motors.csv");
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for (i, l) in lines.enumerate() {
        let cells: Vec<f64> = l.split(',').map(|c| c.parse().unwrap()).collect();
        if let Some(r) = f(i, cells) {
            let r: Vec<String> = r.iter().map(|x| format!("{x:e}")).collect();
            out.push_str(&r.join(","));
            out.push('\n');
        }
    }
    std::fs::write(p, out).unwrap();
}

/// `tagk diagnose` on the three streams in `dir` with `extra` arguments.
fn diagnose(dir: &Path, extra: &[&str]) -> Output {
    let mut args = common::FOREIGN_FLIGHT.to_vec();
    args.extend(extra);
    Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(&args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// The run fails with `expected` in its standard error.
fn refused(dir: &Path, expected: &str) {
    let out = diagnose(dir, &["--quiet"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted; expected: {expected}");
    assert!(stderr.contains(expected), "{stderr}\nexpected: {expected}");
}

#[test]
fn a_mapped_column_no_stream_has_is_refused_naming_the_key() {
    let dir = copy_shipped("absent");
    edit(
        &dir,
        "map.toml",
        "sfx = \"acc_x\"",
        "sfx = \"no_such_column\"",
    );
    refused(
        &dir,
        "columns.sfx = \"no_such_column\": no stream has this column (imu.csv: time_ms, gyro_x",
    );
}

#[test]
fn a_typo_in_a_unit_key_is_refused_with_the_nearest_key() {
    let dir = copy_shipped("unitkey");
    edit(&dir, "map.toml", "omega = \"deg/s\"", "omgea = \"deg/s\"");
    refused(
        &dir,
        "map.toml: units.omgea: unknown key `omgea`; did you mean `omega`?",
    );
}

#[test]
fn a_typo_in_a_streams_key_is_refused_with_the_nearest_file_name() {
    let dir = copy_shipped("streamkey");
    edit(
        &dir,
        "map.toml",
        "[streams.\"mocap.csv\"]",
        "[streams.\"mocap.cvs\"]",
    );
    refused(
        &dir,
        "streams.\"mocap.cvs\": no stream file is named `mocap.cvs` (the streams: imu.csv, \
         motors.csv, mocap.csv); did you mean `mocap.csv`?",
    );
}

#[test]
fn a_motors_stream_at_1_hz_or_of_2_rows_is_refused() {
    let dir = copy_shipped("slow");
    rewrite_motors(&dir, |i, r| (i % 50 == 0).then_some(r));
    refused(
        &dir,
        "motors.csv: 25 samples at a median step of 1.000 s (1.00 Hz) cannot support the fit of \
         rotor_speeds",
    );
    let dir = copy_shipped("two-rows");
    rewrite_motors(&dir, |i, r| (i == 0 || i == 1249).then_some(r));
    refused(&dir, "motors.csv: 2 samples at a median step of 24.980 s");
}

#[test]
fn a_motors_stream_of_another_flight_is_refused() {
    let dir = copy_shipped("other-flight");
    rewrite_motors(&dir, |_, mut r| {
        r[0] += 130_000.0; // ms
        Some(r)
    });
    refused(
        &dir,
        "motors.csv: its time stamps (130.010 to 154.990 s, offset 0 s) overlap the time base \
         (imu.csv: 0.010 to 24.990 s) over 0.000 s, 0 % of its span, less than 50 %: a wrong \
         offset or time unit, or a stream of another flight",
    );
}

#[test]
fn a_motors_stream_2_s_late_is_warned_about_in_terminal_json_and_html() {
    let dir = copy_shipped("late");
    rewrite_motors(&dir, |_, mut r| {
        r[0] += 2000.0; // ms
        Some(r)
    });
    let out = diagnose(&dir, &["--json", "out.json", "--report", "rep"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let warning = "100 of the time base's 1250 samples (8 %) dropped because of motors.csv \
                   (outside its time range t = 2.010 to 26.990 s, offset 0 s, or in its gaps): \
                   check its clock and offset";
    assert!(stdout.contains(&format!("warning: {warning}")), "{stdout}");
    assert!(
        stdout.contains(
            "stream motors.csv: 50.0 Hz, 1250 samples, t = 2.010 to 26.990 s, offset 0 s, \
             overlap 92 % of the time base, 100 samples dropped"
        ),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out.json")).unwrap()).unwrap();
    let input = &json["inputs"][0];
    assert!(
        input["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w == warning),
        "{input}"
    );
    assert_eq!(input["streams"][1]["stream"], "motors.csv");
    assert_eq!(input["streams"][1]["dropped"], 100);
    let html = std::fs::read_to_string(dir.join("rep/index.html")).unwrap();
    assert!(
        html.contains(&format!("warning: {warning}")),
        "no warning in the HTML"
    );
    // With --quiet the terminal is silent, the JSON still has it.
    let out = diagnose(&dir, &["--quiet", "--json", "quiet.json"]);
    assert!(out.stdout.is_empty());
    let quiet = std::fs::read_to_string(dir.join("quiet.json")).unwrap();
    assert!(quiet.contains("dropped because of motors.csv"));
}

#[test]
fn text_in_an_unmapped_column_is_not_read_and_is_reported() {
    let dir = copy_shipped("unmapped");
    let p = dir.join("imu.csv");
    let text = std::fs::read_to_string(&p).unwrap();
    let mut out = String::new();
    for (i, l) in text.lines().enumerate() {
        let cell = match i {
            0 => "status",
            i if i % 3 == 0 => "",
            i if i % 2 == 0 => "True",
            _ => "False",
        };
        out.push_str(&format!("{l},{cell}\n"));
    }
    std::fs::write(&p, out).unwrap();
    let out = diagnose(&dir, &["--json", "out.json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("not read (unmapped, not numeric): status (imu.csv, line 2: `False`)"),
        "{stdout}"
    );
    let json = std::fs::read_to_string(dir.join("out.json")).unwrap();
    assert!(json.contains("\"unread_columns\""));
    // A custom effect naming it says why it is not there.
    let out = diagnose(&dir, &["--quiet", "--custom", "st=status*fz@fz"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains(
            "custom effect `st`: the column `status` of imu.csv was not read as a signal: its \
             cell on line 2 is `False`, not a number"
        ),
        "{stderr}"
    );
}
