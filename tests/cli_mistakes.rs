//! Mistakes a user makes on the command line of `tagk diagnose` (issue #25).
//!
//! - printed commands that must be safe to paste;
//! - outputs that cannot be written;
//! - a mass out of any physical range;
//! - several logs that are the same data or not the same vehicle;
//! - errors printed once.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::tagk_in;
use tagk::cli::diagnose::{DiagnoseArgs, KnownMass, run_diagnose};
use tagk::diagnose::DiagnoseError;
use tagk::diagnose::format::shell_join;

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-mistakes-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `tagk simulate`: a 12 s figure-8 at 50 Hz with a hidden linear drag and medium noise,
/// written to `dir/name`.
fn simulate(dir: &Path, name: &str, seed: u64, extra: &[&str]) -> PathBuf {
    let seed = seed.to_string();
    let mut args = vec![
        "simulate",
        "--seed",
        &seed,
        "-o",
        name,
        "--effect",
        "linear-drag",
        "--noise",
        "medium",
        "--duration",
        "12",
    ];
    args.extend(extra);
    tagk_in(dir, &args);
    dir.join(name)
}

/// Names a shell would otherwise run or split: `;`, `$(…)`, backticks, quotes, spaces,
/// newlines, globs.
const NASTY: [&str; 7] = [
    "a;touch pwned1.csv",
    "$(touch pwned2).csv",
    "`touch pwned3`.csv",
    "it's \"quoted\".csv",
    "with space.csv",
    "new\nline.csv",
    "*.csv",
];

/// What `sh` makes of `command`'s arguments: each printed by `printf '%s\0'` in `dir`.
fn shell_words(dir: &Path, command: &str) -> Vec<String> {
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!("printf '%s\\0' {command}"))
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    text.split_terminator('\0').map(str::to_string).collect()
}

/// Every argument of the printed command — log names, streams, the mapping, the vehicle, a
/// custom specification, shifts — splits back exactly (by `shlex` and by `sh` itself), and
/// pasting it runs nothing.
#[test]
fn printed_commands_round_trip_through_a_shell_and_run_nothing() {
    let dir = tmpdir("quote");
    let mut args = DiagnoseArgs::new(NASTY[0]);
    args.logs = NASTY.iter().map(PathBuf::from).collect();
    args.columns = Some(PathBuf::from("map $(touch pwned4).toml"));
    args.vehicle = Some("veh'icle; touch pwned5".into());
    args.custom = vec!["vbat=vbat*fz@fz".into(), "x=`touch pwned6`@fz".into()];
    args.shift = vec!["pose=-0.012".into(), "gyro=$(touch pwned7)".into()];
    args.mass = Some(KnownMass::Kg(0.035));
    let effects = vec!["linear-drag".to_string(), "wind".to_string()];
    let expected = args.command_args(&effects);
    let command = args.command_for(&effects);
    assert_eq!(
        shlex::split(&command).as_ref(),
        Some(&expected),
        "{command}"
    );
    assert_eq!(shell_words(&dir, &command), expected, "{command}");
    // Safe arguments stay readable.
    assert!(command.contains(" --with linear-drag,wind"), "{command}");
    assert!(command.contains(" --shift pose=-0.012 "), "{command}");
    assert!(command.contains(" --mass 0.035 "), "{command}");
    let created: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(created.is_empty(), "the shell ran something: {created:?}");
    // The empty argument is quoted too (otherwise it would vanish).
    assert_eq!(shell_join(["a", "", "b"]), "a '' b");
    assert_eq!(
        shlex::split(&shell_join(["a", "", "b"])),
        Some(vec!["a".into(), String::new(), "b".into()])
    );
}

/// The commands in the terminal, the JSON and the HTML report of a real run on a log whose
/// name would run a command quote it; the JSON's commands split back to the log's name.
#[test]
fn reproduce_and_next_commands_are_quoted_in_every_output() {
    let dir = tmpdir("quote-run");
    let name = "flight $(touch pwned) it's.csv";
    let log = simulate(&dir, name, 3, &[]);
    let json = dir.join("out.json");
    let report = dir.join("report dir");
    let path = |p: &Path| p.to_str().unwrap().to_string();
    let (log_path, json_path, report_path) = (path(&log), path(&json), path(&report));
    let text = tagk_in(
        &dir,
        &[
            "diagnose",
            &log_path,
            "--json",
            &json_path,
            "--report",
            &report_path,
        ],
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let log_arg = log.to_string_lossy().into_owned();
    for key in [&v["final_model"]["command"], &v["next"]["command"]] {
        let command = key.as_str().unwrap();
        let words = shlex::split(command).unwrap();
        assert_eq!(
            words[..3],
            ["tagk", "diagnose", log_arg.as_str()],
            "{command}"
        );
        assert!(text.contains(command), "terminal lacks {command}\n{text}");
    }
    let next = shlex::split(v["next"]["command"].as_str().unwrap()).unwrap();
    let at = next.iter().position(|w| w == "--report").unwrap();
    assert_eq!(next[at + 1], report.to_string_lossy());
    let html = std::fs::read_to_string(report.join(tagk::diagnose::html::REPORT_FILE)).unwrap();
    let quoted = tagk::diagnose::format::shell_quote(&log_arg)
        .replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;");
    assert!(html.contains(&quoted), "the HTML lacks {quoted}");
    assert!(!dir.join("pwned").exists());
}

/// `--mass 1e-300` (or 1e9) is no vehicle's mass: refused as an option error naming the flag,
/// before the log is read; the library's plan refuses it too.
#[test]
fn a_mass_outside_any_physical_range_is_refused() {
    use tagk::diagnose::{DiagnosisPlan, KNOWN_MASS_RANGE};
    for mass in [1e-300, 5e-5, 2e4, 1e9] {
        let mut args = DiagnoseArgs::new("no-such-log.csv");
        args.mass = Some(KnownMass::Kg(mass));
        let err = run_diagnose(&args).unwrap_err();
        assert!(
            matches!(err, DiagnoseError::InvalidOption { field: "mass", .. }),
            "{mass}: {err:?}"
        );
        assert!(err.to_string().contains("--mass"), "{err}");
        let err = DiagnosisPlan::new()
            .known_mass(mass)
            .validate()
            .unwrap_err();
        assert!(
            matches!(err, DiagnoseError::InvalidOption { field: "mass", .. }),
            "{err:?}"
        );
    }
    for mass in [KNOWN_MASS_RANGE[0], 0.035, 1.5, KNOWN_MASS_RANGE[1]] {
        DiagnosisPlan::new().known_mass(mass).validate().unwrap();
    }
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["diagnose", "no-such-log.csv", "--mass", "1e-300"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("`--mass 1e-300`"), "{stderr}");
}

/// A `--json` into a missing directory or a `--report` onto a file fails before the log is
/// read: the error names the destination, not the (missing) log.
#[test]
fn output_destinations_are_checked_before_any_work() {
    let dir = tmpdir("outputs");
    let mut args = DiagnoseArgs::new(dir.join("no-such-log.csv"));
    args.json = Some(dir.join("no-such-dir").join("out.json"));
    let err = run_diagnose(&args).unwrap_err();
    assert!(matches!(err, DiagnoseError::Output { .. }), "{err:?}");
    assert!(err.to_string().contains("no-such-dir"), "{err}");
    args.json = Some(dir.clone());
    let err = run_diagnose(&args).unwrap_err();
    assert!(err.to_string().contains("is a directory"), "{err}");
    args.json = None;
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    args.report = Some(file.join("sub"));
    let err = run_diagnose(&args).unwrap_err();
    assert!(matches!(err, DiagnoseError::Output { .. }), "{err:?}");
    assert!(err.to_string().contains("--report"), "{err}");
    // Valid destinations: the error is then the missing log's.
    args.report = Some(dir.join("report"));
    args.json = Some(dir.join("out.json"));
    let err = run_diagnose(&args).unwrap_err();
    assert!(err.to_string().contains("no-such-log.csv"), "{err}");
    assert!(dir.join("report").is_dir());
}

/// An error and its cause are printed once: a bad cell's message (`file: line N, column …`)
/// is not repeated as its own "caused by".
#[test]
fn each_error_is_printed_once() {
    let dir = tmpdir("once");
    let log = simulate(&dir, "good.csv", 3, &[]);
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let cells: Vec<&str> = lines[4].split(',').collect();
    let mut cells: Vec<String> = cells.iter().map(|c| c.to_string()).collect();
    cells[1] = "oops".into();
    lines[4] = cells.join(",");
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let stderr = common::tagk_fails_in(&dir, &["diagnose", "bad.csv"]);
    assert_eq!(
        stderr.matches("`oops` is not a number").count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("line 5"), "{stderr}");
}

/// Runs `tagk diagnose` on `logs` in `dir` with `--json` and `--report`: the exit status, the
/// terminal, the standard error, the JSON and the HTML.
fn diagnose_all(dir: &Path, logs: &[&Path]) -> (bool, String, String, serde_json::Value, String) {
    diagnose_all_with(dir, logs, &[])
}

/// [`diagnose_all`] with `extra` arguments.
fn diagnose_all_with(
    dir: &Path,
    logs: &[&Path],
    extra: &[&str],
) -> (bool, String, String, serde_json::Value, String) {
    let json = dir.join("out.json");
    let report = dir.join("report");
    let _ = std::fs::remove_file(&json);
    let _ = std::fs::remove_dir_all(&report);
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .args(logs)
        .arg("--json")
        .arg(&json)
        .arg("--report")
        .arg(&report)
        .args(extra)
        .output()
        .unwrap();
    let v = std::fs::read_to_string(&json)
        .map(|t| serde_json::from_str(&t).unwrap())
        .unwrap_or(serde_json::Value::Null);
    let html =
        std::fs::read_to_string(report.join(tagk::diagnose::html::REPORT_FILE)).unwrap_or_default();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        v,
        html,
    )
}

/// The same file twice, or two files with identical samples, are refused (counted twice, one
/// flight would narrow every interval by √2), naming both.
#[test]
fn the_same_data_twice_is_refused() {
    let dir = tmpdir("twice");
    let a = simulate(&dir, "a.csv", 3, &[]);
    let copy = dir.join("copy.csv");
    std::fs::copy(&a, &copy).unwrap();
    let (ok, _, stderr, ..) = diagnose_all(&dir, &[&a, &a]);
    assert!(!ok);
    assert!(stderr.contains("a.csv is given twice"), "{stderr}");
    assert!(stderr.contains("√2"), "{stderr}");
    let (ok, _, stderr, ..) = diagnose_all(&dir, &[&a, &copy]);
    assert!(!ok);
    assert!(
        stderr.contains("a.csv and ") && stderr.contains("copy.csv hold the same data"),
        "{stderr}"
    );
    // Refused before the fit: the JSON is not written.
    assert!(!dir.join("out.json").exists());
}

/// A heavier vehicle among three logs: a 17 g payload on a 35 g body, from take-off.
///
/// It is named with its own mass and interval against the others' and left out of the joint
/// fit. Its `agrees` is false in the terminal, the JSON and the HTML. The joint mass is the others'.
#[test]
fn a_heavier_vehicle_among_three_logs_is_named_and_not_blended() {
    let dir = tmpdir("heavier");
    let a = simulate(&dir, "a.csv", 3, &[]);
    let b = simulate(&dir, "b.csv", 4, &[]);
    let payload = [
        "--payload",
        "fixed",
        "--payload-mass",
        "0.017",
        "--payload-offset",
        "0,0,0",
        "--attach",
        "0",
    ];
    let heavy = simulate(&dir, "heavy.csv", 5, &payload);
    let (ok, text, stderr, v, html) = diagnose_all(&dir, &[&a, &b, &heavy]);
    assert!(ok, "{stderr}");
    let logs = v["logs"].as_array().unwrap();
    assert_eq!(logs.len(), 3);
    let heavy_v = &logs[2];
    assert_eq!(heavy_v["agrees"], false, "{heavy_v}");
    assert_eq!(heavy_v["excluded"], true, "{heavy_v}");
    let mass = heavy_v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "mass")
        .unwrap();
    assert_eq!(mass["consistent"], false, "{mass}");
    let m = mass["value"].as_f64().unwrap();
    assert!((m - 0.052).abs() < 0.005, "{mass}");
    let others = mass["others"].as_f64().unwrap();
    assert!((others - 0.035).abs() < 0.003, "{mass}");
    for l in &logs[..2] {
        assert_eq!(l["excluded"], false, "{l}");
    }
    let note = heavy_v["note"].as_str().unwrap();
    assert!(
        note.contains("mass") && note.contains("not blended"),
        "{note}"
    );
    assert!(
        text.contains("DISAGREES: log ") && text.contains("not blended"),
        "{text}"
    );
    assert!(html.contains("not blended"), "the HTML lacks the note");
    // The joint fit is the two others': its mass is theirs, not a blend.
    let joint = v["final_diagnosis"]["parameters"]
        .as_array()
        .or(v["before"]["parameters"].as_array())
        .unwrap()
        .iter()
        .find(|p| p["name"] == "m")
        .map(|p| p["value"].as_f64().unwrap())
        .unwrap();
    assert!((joint - 0.035).abs() < 0.003, "joint mass {joint}");
}

/// One of three logs with its velocity in mm/s (mapped as m/s): the scale check names it
/// before the fit; with the scales accepted, its drag coefficient is 1000× off, it is named,
/// left out, and does not "agree".
#[test]
fn a_log_with_its_velocity_in_mm_per_s_is_named() {
    let dir = tmpdir("mm");
    let a = simulate(&dir, "a.csv", 3, &[]);
    let b = simulate(&dir, "b.csv", 4, &[]);
    let c = simulate(&dir, "c.csv", 5, &[]);
    let mut log = tagk::diagnose::FlightLog::from_csv_path(&c).unwrap();
    for v in &mut log.velocity {
        for x in v.iter_mut() {
            *x *= 1000.0;
        }
    }
    let mm = dir.join("mm.csv");
    log.write_csv_path(&mm).unwrap();
    let (ok, _, stderr, _, _) = diagnose_all(&dir, &[&a, &b, &mm]);
    assert!(!ok && stderr.contains("mm/s mapped as m/s?"), "{stderr}");
    let (ok, text, stderr, v, html) = diagnose_all_with(&dir, &[&a, &b, &mm], &["--accept-scales"]);
    assert!(ok, "{stderr}");
    let logs = v["logs"].as_array().unwrap();
    assert_eq!(logs[2]["agrees"], false, "{}", logs[2]);
    assert_eq!(logs[2]["excluded"], true, "{}", logs[2]);
    let drag = logs[2]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| {
            p["name"].as_str().unwrap().starts_with("linear-drag") && p["consistent"] == false
        })
        .unwrap_or_else(|| panic!("{}", logs[2]));
    let ratio = drag["others"].as_f64().unwrap() / drag["value"].as_f64().unwrap();
    assert!(ratio > 300.0, "{drag}");
    assert!(
        text.contains("mm.csv") && text.contains("not blended"),
        "{text}"
    );
    assert!(html.contains("not blended"));
}

/// Two logs of two vehicle states: neither can be preferred, so the joint fit is refused
/// with both logs' masses named.
#[test]
fn two_logs_of_two_vehicle_states_are_refused() {
    let dir = tmpdir("two-states");
    let a = simulate(&dir, "a.csv", 3, &[]);
    let payload = [
        "--payload",
        "fixed",
        "--payload-mass",
        "0.017",
        "--payload-offset",
        "0,0,0",
        "--attach",
        "0",
    ];
    let heavy = simulate(&dir, "heavy.csv", 5, &payload);
    let (ok, _, stderr, ..) = diagnose_all(&dir, &[&a, &heavy]);
    assert!(!ok);
    assert!(
        stderr.contains("not blended") && stderr.contains("heavy.csv: mass"),
        "{stderr}"
    );
}

/// Issue #25: a log in the project's format with text, booleans and empty cells in a column
/// outside the format. The column is not read and is reported (terminal, JSON). The fit is
/// the same as without it, and a custom effect naming it is told why it is missing.
#[test]
fn text_in_a_native_log_s_own_column_is_not_read_and_is_reported() {
    let dir = tmpdir("native-unread");
    let log = simulate(&dir, "good.csv", 3, &[]);
    let text = std::fs::read_to_string(&log).unwrap();
    let mut out = String::new();
    for (i, l) in text.lines().enumerate() {
        let (status, temp) = match i {
            0 => ("status".to_string(), "temp".to_string()),
            i if i % 3 == 0 => (String::new(), format!("{}", 20.0 + i as f64 * 1e-3)),
            i if i % 2 == 0 => ("True".into(), format!("{}", 20.0 + i as f64 * 1e-3)),
            _ => ("False".into(), format!("{}", 20.0 + i as f64 * 1e-3)),
        };
        out.push_str(&format!("{l},{status},{temp}\n"));
    }
    std::fs::write(dir.join("extra.csv"), out).unwrap();
    let stdout = tagk_in(&dir, &["diagnose", "extra.csv", "--json", "extra.json"]);
    assert!(
        stdout.contains("not read (unmapped, not numeric): status (extra.csv, line 2: `False`)"),
        "{stdout}"
    );
    // The numeric extra column is kept: no mention of it.
    assert!(!stdout.contains("temp ("), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("extra.json")).unwrap()).unwrap();
    let unread = &json["inputs"][0]["unread_columns"];
    assert_eq!(unread.as_array().map(Vec::len), Some(1), "{unread}");
    assert_eq!(unread[0]["column"], "status");
    assert_eq!(unread[0]["line"], 2);
    // The same fit as the file without the column.
    tagk_in(&dir, &["diagnose", "good.csv", "--json", "good.json"]);
    let good: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("good.json")).unwrap()).unwrap();
    assert_eq!(
        json["final_model"]["effects"],
        good["final_model"]["effects"]
    );
    assert_eq!(json["steps"], good["steps"]);
    // A custom effect naming it says why it is not there.
    let stderr = common::tagk_fails_in(
        &dir,
        &[
            "diagnose",
            "extra.csv",
            "--quiet",
            "--custom",
            "st=status*fz@fz",
        ],
    );
    assert!(
        stderr.contains(
            "custom effect `st`: the column `status` of extra.csv was not read as a signal: its \
             cell on line 2 is `False`, not a number"
        ),
        "{stderr}"
    );
}
