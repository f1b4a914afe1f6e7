//! `tagk diagnose` end to end on a simulator log written to CSV: terminal run, JSON keys,
//! HTML report (opened in headless Chromium when it is installed), typed errors, `--help`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::cli::diagnose::{DiagnoseArgs, plan, run_diagnose};
use tagk::diagnose::{DiagnoseError, EffectKind as Vocabulary, FlightLog};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind,
};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-diagnose-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 25 s figure-8 flight with quadratic drag hidden (seed 3, medium noise), written by the
/// simulator's log writer.
fn write_drag_log(dir: &Path) -> PathBuf {
    write_drag_log_seeded(dir, 3, "drag.csv")
}

/// [`write_drag_log`] with another seed, written to `dir/name`.
fn write_drag_log_seeded(dir: &Path, seed: u64, name: &str) -> PathBuf {
    let config = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: 25.0,
        seed,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: PlantEffects::only(EffectKind::QuadraticDrag).unwrap(),
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    let out = tagk::sim::simulate(&config).expect("simulation runs");
    assert!(!out.metrics.aborted);
    let path = dir.join(name);
    out.log.write_csv_path(&path).unwrap();
    path
}

#[test]
fn json_has_the_documented_keys_before_and_after() {
    let dir = tmpdir("json");
    let log = write_drag_log(&dir);
    let mut args = DiagnoseArgs::new(&log);
    args.with = vec!["quadratic-drag".into()];
    args.json = Some(dir.join("out.json"));
    args.online = true;
    args.quiet = true;
    run_diagnose(&args).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out.json")).unwrap()).unwrap();
    // Final model (after adding quadratic drag): adequate.
    assert!(v["recommended"].is_null(), "{}", v["recommended"]);
    for part in [&v, &v["before"], &v["after"]] {
        let ch = part["channels"].as_array().unwrap();
        assert_eq!(ch.len(), 6);
        for c in ch {
            assert!(c["name"].is_string());
            assert!(c["rms"].is_number());
            assert!(c.get("fit_percent").is_some());
        }
        for r in part["ranking"].as_array().unwrap() {
            assert!(r["effect"].is_string());
            assert!(r["reduction"].is_number());
        }
    }
    assert_eq!(v["before"]["recommended"], "quadratic-drag");
    assert_eq!(v["with"][0], "quadratic-drag");
    let change = v["change"].as_array().unwrap();
    assert!(change[0]["rms_after"].as_f64().unwrap() < change[0]["rms_before"].as_f64().unwrap());
    assert!(v["online"]["updates"].as_u64().unwrap() > 10);
}

#[test]
fn bad_log_reports_line_and_column() {
    let dir = tmpdir("bad");
    let path = dir.join("bad.csv");
    std::fs::write(&path, "t,px\n0,0\n").unwrap();
    let err = run_diagnose(&DiagnoseArgs::new(&path)).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("line 1") && msg.contains("py"), "{msg}");
}

#[test]
fn unknown_effect_is_a_typed_error() {
    let dir = tmpdir("unknown");
    let log = write_drag_log(&dir);
    let mut args = DiagnoseArgs::new(&log);
    args.with = vec!["anti-gravity".into()];
    args.quiet = true;
    assert!(matches!(
        run_diagnose(&args),
        Err(DiagnoseError::UnknownEffect(_))
    ));
}

/// `--with` takes the vocabulary's aliases; a `--custom` effect must name columns the log has;
/// a mass must be positive; the same effect twice is refused.
#[test]
fn effect_names_aliases_and_custom_columns_are_checked() {
    let dir = tmpdir("plan");
    let path = write_drag_log(&dir);
    let log = FlightLog::from_csv_path(&path).unwrap();
    let mut args = DiagnoseArgs::new(&path);
    args.with = vec!["Wrench_Bias".into(), "delay".into()];
    let p = plan(&args, &log).unwrap();
    let names: Vec<&str> = p.with.iter().map(|e| e.name()).collect();
    assert_eq!(
        names,
        [Vocabulary::BodyBias.name(), Vocabulary::TimeDelay.name()]
    );
    args.with = vec!["body-bias".into(), "bias".into()];
    let err = tagk::cli::diagnose::diagnose_log(&log, &args).unwrap_err();
    assert!(matches!(err, DiagnoseError::InvalidModel(_)), "{err}");

    let mut args = DiagnoseArgs::new(&path);
    args.custom = vec!["vbat=vbat*fz@fz".into()];
    let err = plan(&args, &log).unwrap_err();
    assert!(
        matches!(&err, DiagnoseError::UnknownColumn { effect, column, available }
            if effect == "vbat" && column == "vbat" && available.contains("vx")),
        "{err}"
    );
    let mut args = DiagnoseArgs::new(&path);
    args.custom = vec!["thrust=fz*fz@fz".into()];
    args.with = vec!["thrust".into()];
    assert_eq!(plan(&args, &log).unwrap().with[0].name(), "thrust");

    let mut args = DiagnoseArgs::new(&path);
    args.mass = Some((-0.035).into());
    assert!(matches!(
        plan(&args, &log),
        Err(DiagnoseError::InvalidModel(_))
    ));
    let mut args = DiagnoseArgs::new(&path);
    args.airframe_radius = Some(0.0);
    assert!(matches!(
        plan(&args, &log),
        Err(DiagnoseError::InvalidOption {
            field: "airframe_radius",
            ..
        })
    ));
}

/// `tagk diagnose --help` lists every built-in effect with its summary.
#[test]
fn help_lists_the_effects_with_their_summaries() {
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["diagnose", "--help"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for kind in Vocabulary::ALL {
        assert!(help.contains(kind.name()), "{help}");
        assert!(help.contains(kind.summary()), "{help}");
    }
}

/// Every `--help` is plain terminal text: no rustdoc markup (backticks, intra-doc links,
/// escaped unit brackets); `diagnose --help` defines both fit measures of its tables.
#[test]
fn help_is_plain_text_and_defines_the_fit_measures() {
    for sub in [
        &["--help"][..],
        &["diagnose", "--help"],
        &["simulate", "--help"],
        &["compare", "--help"],
        &["vehicle", "--help"],
        &["vehicle", "show", "--help"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
            .args(sub)
            .output()
            .unwrap();
        assert!(out.status.success());
        let help = String::from_utf8_lossy(&out.stdout);
        for markup in ["`", "\\[", "[`", "\\]"] {
            assert!(!help.contains(markup), "{markup} in {sub:?}:\n{help}");
        }
    }
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["diagnose", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    for line in tagk::diagnose::FIT_MEASURES.lines() {
        assert!(help.contains(line), "{line} not in\n{help}");
    }
}

/// The terminal report's fit measure is defined on every channel (the force channels whose
/// measurement is constant too), a `--with` run prints the starting model once with a compact
/// before/after table (not the rigid body's section again), and every report ends with the
/// next command to run: on the terminal and in the HTML.
#[test]
fn reports_end_with_the_next_command_and_define_a_fit_on_every_channel() {
    let dir = tmpdir("next");
    let log = write_drag_log(&dir);
    let run = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
            .arg("diagnose")
            .arg(&log)
            .args(extra)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let plain = run(&[]);
    let lines: Vec<&str> = plain.lines().filter(|l| !l.trim().is_empty()).collect();
    let n = lines.len();
    assert!(lines[n - 2].starts_with("next ("), "{plain}");
    assert!(
        lines[n - 1].starts_with("  tagk diagnose ") && lines[n - 1].contains("--with"),
        "{plain}"
    );
    // err % has a number on every channel of the first table, fit % is n/a on fx and fy.
    for ch in ["fx", "fy", "fz", "tx", "ty", "tz"] {
        let row = plain
            .lines()
            .find(|l| l.starts_with(ch))
            .unwrap_or_else(|| panic!("no {ch} row in\n{plain}"));
        let err: f64 = row
            .split_whitespace()
            .nth(2)
            .unwrap()
            .parse()
            .unwrap_or_else(|_| panic!("no err % in {row}"));
        assert!(err.is_finite() && err > 0.0, "{row}");
    }
    // The wording matches the numbers: a candidate that raises the held-out residual is
    // called worse, whatever else it is, and ten times the residual reads as a factor.
    for line in plain.lines().filter(|l| l.contains(": held-out residual ")) {
        let change = line.split(": held-out residual ").nth(1).unwrap();
        if change.starts_with('+') || change.starts_with('×') {
            assert!(
                line.contains("worse: it raises the held-out residual"),
                "{line}"
            );
        }
        let percent: Option<f64> = change
            .split(' ')
            .next()
            .and_then(|p| p.trim_start_matches('+').parse().ok());
        assert!(percent.is_none_or(|p| p < 1000.0), "{line}");
    }
    let report = dir.join("report");
    let with = run(&[
        "--with",
        "quadratic-drag",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(with.matches("=== model").count(), 1, "{with}");
    assert_eq!(with.matches("parameters (± 1 s.e.)").count(), 1, "{with}");
    assert!(with.contains("err % before  err % after"), "{with}");
    let last = with.lines().rfind(|l| !l.trim().is_empty()).unwrap();
    assert!(
        last.starts_with("  tagk diagnose ") && last.contains("--online"),
        "{with}"
    );
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    let next = html
        .find("id=\"next-command\"")
        .expect("the next command in the HTML");
    assert!(html[next..].contains("--online"));
    assert!(
        !html[next..].contains("<h2"),
        "the next command is the last section"
    );
    assert!(!html.contains('`'), "a literal backtick in the HTML");
    // resid's panels for every diagnosed model: 6 autocorrelations and 6 cross-correlations,
    // each with its confidence band.
    let models = html.matches("<h3>Residual autocorrelation</h3>").count();
    assert!(models >= 2, "before and after");
    assert_eq!(
        html.matches("autocorrelation of residual").count(),
        6 * models
    );
    assert_eq!(html.matches("class=\"band\"").count(), 12 * models);
}

/// Writes the HTML report and opens it in headless Chromium (`apt-get install -y chromium`).
/// Skips with a message when Chromium is not installed.
#[test]
fn html_report_renders_in_headless_chromium() {
    let dir = tmpdir("html");
    let log = write_drag_log(&dir);
    let mut args = DiagnoseArgs::new(&log);
    args.with = vec!["quadratic-drag".into()];
    args.report = Some(dir.join("report"));
    args.quiet = true;
    run_diagnose(&args).unwrap();
    let file = dir.join("report").join("index.html");
    let html = std::fs::read_to_string(&file).unwrap();
    assert!(html.contains("<svg") && html.contains("class=\"failure\"") || html.contains("<svg"));
    assert!(html.contains("id=\"before-after\""));
    let Some(chromium) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| {
            Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        eprintln!(
            "SKIPPED: chromium not installed (apt-get install -y chromium); the HTML was written but not rendered"
        );
        return;
    };
    let profile = dir.join("profile");
    let out = headless(chromium, &profile, &["--dump-dom".into()], &file);
    let dom = String::from_utf8_lossy(&out.stdout);
    // The browser parsed the document: its DOM carries our title, the SVG plots and the table.
    assert!(dom.contains("id=\"title\""), "no title in the rendered DOM");
    assert!(
        dom.matches("<svg").count() >= 12,
        "too few SVG plots rendered"
    );
    assert!(dom.contains("before-after"));
    let shot = dir.join("shot.png");
    headless(
        chromium,
        &profile,
        &[
            "--window-size=1400,2000".into(),
            format!("--screenshot={}", shot.display()),
        ],
        &file,
    );
    let png = std::fs::read(&shot).unwrap();
    assert!(
        png.len() > 10_000 && png.starts_with(b"\x89PNG"),
        "screenshot too small"
    );
}

/// Runs headless Chromium on `file` with `extra` flags; panics with its stderr if it fails.
fn headless(chromium: &str, profile: &Path, extra: &[String], file: &Path) -> std::process::Output {
    let mut args: Vec<String> = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--no-first-run",
    ]
    .map(String::from)
    .to_vec();
    args.push(format!("--user-data-dir={}", profile.display()));
    args.extend_from_slice(extra);
    args.push(format!("file://{}", file.display()));
    let out = Command::new(chromium).args(&args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The staircase in the JSON and on the terminal: `recommended` is the first step, `steps`
/// has the starting model and one entry per added effect (per channel: held-out RMS, floor,
/// change), `final_model` names the effects and the command that reproduces it — and that
/// command, run, reproduces the final model with nothing left to add.
#[test]
fn the_staircase_is_in_the_json_and_its_command_reproduces_it() {
    let dir = tmpdir("staircase");
    let log = write_drag_log(&dir);
    let mut args = DiagnoseArgs::new(&log);
    args.json = Some(dir.join("out.json"));
    args.quiet = true;
    run_diagnose(&args).unwrap();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out.json")).unwrap()).unwrap();
    let steps = v["steps"].as_array().unwrap();
    assert!(steps.len() >= 2, "{}", v["steps"]);
    assert!(steps[0]["effect"].is_null());
    assert_eq!(steps[1]["effect"], v["recommended"]);
    for step in steps {
        let ch = step["channels"].as_array().unwrap();
        assert_eq!(ch.len(), 6);
        for c in ch {
            assert!(c["held_out_rms"].as_f64().unwrap() > 0.0);
            assert!(c["floor"].as_f64().unwrap() > 0.0);
            assert!(c["change"].is_number());
        }
        assert_eq!(step["held_out_rms"].as_array().unwrap().len(), 6);
    }
    let effects: Vec<String> = v["final_model"]["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap().to_string())
        .collect();
    assert!(!effects.is_empty());
    let command = v["final_model"]["command"].as_str().unwrap();
    assert!(
        command.ends_with(&format!("--with {}", effects.join(","))),
        "{command}"
    );
    assert!(v["noise_floor"]["rms"].as_array().unwrap().len() == 6);
    assert!(v["stopped"].is_string());
    // The command reproduces the final model: with its effects, nothing is left to add.
    let mut again = DiagnoseArgs::new(&log);
    again.with = effects;
    again.json = Some(dir.join("again.json"));
    again.quiet = true;
    run_diagnose(&again).unwrap();
    let w: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("again.json")).unwrap()).unwrap();
    assert!(w["recommended"].is_null(), "{}", w["stopped"]);
    // The terminal shows the staircase and the command.
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg(&log)
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("=== stepwise:"), "{text}");
    assert!(text.contains("reproduce it: tagk diagnose"), "{text}");
}

/// Several logs on the command line are diagnosed jointly, each beside the joint verdict;
/// a bad `--noise-floor` is a typed error naming the option.
#[test]
fn several_logs_on_the_command_line_and_a_bad_noise_floor() {
    let dir = tmpdir("several");
    let a = write_drag_log(&dir);
    // Another flight of the vehicle (the same data twice is refused: tests/cli_mistakes.rs).
    let b = write_drag_log_seeded(&dir, 4, "second.csv");
    let text = common::tagk_in(
        &dir,
        &["diagnose", a.to_str().unwrap(), b.to_str().unwrap()],
    );
    assert!(text.contains("=== each log alone"), "{text}");
    assert!(text.contains("agrees"), "{text}");
    let mut args = DiagnoseArgs::new(&a);
    args.noise_floor = Some(vec![1e-3, 1e-3, -1.0, 1e-5, 1e-5, 1e-5]);
    let err = run_diagnose(&args).unwrap_err();
    assert!(
        matches!(
            err,
            DiagnoseError::InvalidOption {
                field: "noise_floor",
                ..
            }
        ),
        "{err}"
    );
}

/// The report's residual-against-signal plots are partial-residual plots: the residual of the
/// rigid body against the recommended candidate's own regressor column on each channel, which
/// lines up (a line with the coefficient as slope) where the speed magnitude drew a loop.
#[test]
fn partial_residuals_line_up_with_the_missing_column() {
    let dir = tmpdir("partial");
    let log = FlightLog::from_csv_path(write_drag_log(&dir)).unwrap();
    let mut args = DiagnoseArgs::new(dir.join("drag.csv"));
    args.quiet = true;
    let report = tagk::cli::diagnose::diagnose_log(&log, &args).unwrap();
    let d = &report.before;
    let top = &d.ranking[0].effect;
    let fx = d
        .partial_residuals
        .iter()
        .find(|p| p.channel == 0)
        .expect("a partial residual on fx");
    assert_eq!(&fx.effect, top);
    assert!(fx.x.len() <= 1200 && fx.x.len() == fx.y.len() && fx.x.len() > 100);
    let corr = |x: &[f64], y: &[f64]| {
        let n = x.len() as f64;
        let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
        let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
        let syy: f64 = y.iter().map(|b| (b - my).powi(2)).sum();
        sxy / (sxx * syy).sqrt()
    };
    let along_column = corr(&fx.x, &fx.y).abs();
    assert!(
        along_column > 0.9,
        "residual fx against {}: |r| = {along_column}",
        fx.column
    );
    // The old plot: the same residual against the horizontal speed magnitude.
    let (_, speed) = d.top_driver.as_ref().unwrap();
    let step = speed.len().div_ceil(1200).max(1);
    let s: Vec<f64> = speed.iter().step_by(step).copied().collect();
    let against_speed = corr(&s, &fx.y).abs();
    assert!(
        against_speed < along_column,
        "{against_speed} vs {along_column}"
    );
    let html = tagk::diagnose::html::render(&report);
    assert!(
        html.contains(&format!("vs column {} of {top}", fx.column)),
        "no partial-residual plot"
    );
}

/// `--custom` takes an expression, `--window` keeps a time window and `--validate` scores the
/// models on a second flight: on the terminal, in the JSON (new keys) and in the HTML; the
/// help documents the three.
#[test]
fn expressions_windows_and_validation_from_the_command_line() {
    let dir = tmpdir("expr");
    let log = write_drag_log(&dir);
    let second = write_drag_log_seeded(&dir, 4, "second.csv");
    let json = dir.join("out.json");
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .arg("diagnose")
        .arg(&log)
        .args(["--custom", "drag_x=vbx*abs(vbx)@fx", "--with", "drag_x"])
        .args(["--window", "2..20", "--max-steps", "0", "--validate"])
        .arg(&second)
        .arg("--json")
        .arg(&json)
        .arg("--report")
        .arg(dir.join("html"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("validation on"), "{stdout}");
    assert!(
        stdout.contains("windows kept (log time): 2..20 s"),
        "{stdout}"
    );
    // The command that reproduces the model keeps the window, the validation log and the
    // quoted expression.
    assert!(stdout.contains("--window 2..20"), "{stdout}");
    assert!(stdout.contains("'drag_x=vbx*abs(vbx)@fx'"), "{stdout}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["windows"][0][0].as_f64(), Some(2.0));
    let steps = v["validation"]["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 2, "rigid body, then the --with model");
    assert_eq!(steps[1]["rms"].as_array().unwrap().len(), 6);
    let samples = v["before"]["samples"].as_u64().unwrap();
    assert!(
        samples <= 901 && samples > 850,
        "{samples} samples in 2..20 s at 50 Hz"
    );
    let html = std::fs::read_to_string(dir.join("html").join("index.html")).unwrap();
    assert!(html.contains("<h2>Validation on"), "no validation section");
    // A bad window and a unit mistake are typed errors naming what is wrong.
    let run = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_tagk"))
            .arg("diagnose")
            .arg(&log)
            .args(extra)
            .output()
            .unwrap()
    };
    let bad = run(&["--window", "20..2"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("20..2"));
    let bad = run(&["--custom", "oops=vx+wx@fx"]);
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("oops") && err.contains("different units"),
        "{err}"
    );
    let help = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(["diagnose", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for needle in ["--window", "--validate", "d(COL)", "abs(vbx)"] {
        assert!(help.contains(needle), "{needle} not in help");
    }
}
