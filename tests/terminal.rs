//! What a user meets on the terminal (issue #30, item 1): every example and every `tagk`
//! command answers `--help` and `-h` at once; a closed stdout (`| head -1`) ends the program
//! quietly (no panic, no exit code 101); an error's message is printed once.
//!
//! The examples are run from the binaries Cargo builds next to this test
//! (`target/PROFILE/examples/`): `cargo test` builds them before running the tests.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-terminal-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The name of every example (`examples/*.rs`).
fn example_names() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let path = e.unwrap().path();
            (path.extension()? == "rs").then(|| path.file_stem()?.to_str().map(str::to_string))?
        })
        .collect();
    names.sort();
    names
}

/// The built binary of example `name` (next to this test's own folder).
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile = exe.parent().and_then(Path::parent).unwrap();
    let path = profile
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.is_file(),
        "{} is not built: run the whole `cargo test` (it builds the examples) or \
         `cargo build --examples` with this profile first",
        path.display()
    );
    path
}

/// Runs `cmd` to its end, killing it after `limit` (a `--help` that starts the work would
/// otherwise run for minutes).
fn run_within(mut cmd: Command, limit: Duration) -> Output {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            let out = child.wait_with_output().unwrap();
            panic!(
                "{cmd:?} still ran after {limit:?}: {}",
                String::from_utf8_lossy(&out.stdout)
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().unwrap()
}

/// Every example answers `--help` and `-h` with a usage text and exit code 0, without
/// starting its work (`soak` ran for minutes, `log_sampling` read `--help` as a file).
#[test]
fn every_example_answers_help_without_working() {
    let names = example_names();
    assert!(names.len() >= 14, "{names:?}");
    let dir = tmpdir("help");
    for name in &names {
        let exe = example(name);
        for flag in ["--help", "-h"] {
            let mut cmd = Command::new(&exe);
            cmd.arg(flag).current_dir(&dir);
            let out = run_within(cmd, Duration::from_secs(20));
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{name} {flag}: {:?} {}",
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(stdout.contains("Usage:"), "{name} {flag}: {stdout}");
            assert!(stdout.contains("-h, --help"), "{name} {flag}: {stdout}");
        }
    }
    // Nothing was written: no work started.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
}

#[test]
fn every_tagk_command_answers_help() {
    let dir = tmpdir("tagk-help");
    for args in [
        &["--help"][..],
        &["-h"],
        &["simulate", "--help"],
        &["diagnose", "-h"],
        &["compare", "--help"],
        &["vehicle", "--help"],
    ] {
        let out = common::tagk_output(&dir, args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "tagk {args:?}: {:?}", out.status);
        assert!(stdout.contains("Usage:"), "tagk {args:?}: {stdout}");
    }
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
}

/// Runs `cmd` with its stdout a pipe whose reader has gone before the program starts: the
/// program must end without a panic (Rust's `println!` panics on a broken pipe, exit code
/// 101).
fn assert_quiet_on_closed_pipe(mut cmd: Command) {
    let (reader, writer) = std::io::pipe().unwrap();
    // The reader is closed before the program runs: its first line meets a broken pipe.
    drop(reader);
    let out = cmd
        .stdin(Stdio::null())
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_ne!(out.status.code(), Some(101), "{cmd:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{cmd:?}: {stderr}");
    assert!(!stderr.contains("Broken pipe"), "{cmd:?}: {stderr}");
    assert!(out.status.success(), "{cmd:?}: {:?} {stderr}", out.status);
}

#[test]
fn a_closed_stdout_ends_tagk_quietly() {
    let dir = tmpdir("pipe");
    let tagk = env!("CARGO_BIN_EXE_tagk");
    let mut show = Command::new(tagk);
    show.args(["vehicle", "show", "crazyflie-2.1"])
        .current_dir(&dir);
    assert_quiet_on_closed_pipe(show);
    let mut simulate = Command::new(tagk);
    simulate
        .args(["simulate", "--duration", "5", "-o", "f.csv"])
        .current_dir(&dir);
    assert_quiet_on_closed_pipe(simulate);
    // The log was written before the summary line met the closed pipe.
    assert!(dir.join("f.csv").is_file());
    let mut diagnose = Command::new(tagk);
    diagnose.args(["diagnose", "f.csv"]).current_dir(&dir);
    assert_quiet_on_closed_pipe(diagnose);
}

#[test]
fn a_closed_stdout_ends_an_example_quietly() {
    let mut cmd = Command::new(example("track_step_change"));
    cmd.args(["--windows", "6"]);
    assert_quiet_on_closed_pipe(cmd);
}

/// Several error paths of `tagk`: the message appears once (not again as its own "caused
/// by"), no line is repeated, and the exit code is 1, not a panic's 101.
#[test]
fn each_error_message_is_printed_once() {
    let dir = tmpdir("errors");
    common::tagk_in(&dir, &["simulate", "--duration", "5", "-o", "good.csv"]);
    let text = std::fs::read_to_string(dir.join("good.csv")).unwrap();
    let mut bad: Vec<String> = text.lines().map(str::to_string).collect();
    // Row 5's second cell made unreadable.
    let mut cells: Vec<String> = bad[4].split(',').map(str::to_string).collect();
    cells[1] = "oops".into();
    bad[4] = cells.join(",");
    std::fs::write(dir.join("bad.csv"), bad.join("\n")).unwrap();
    std::fs::write(dir.join("bad.toml"), "mass = ]\n").unwrap();
    std::fs::write(dir.join("map.toml"), "garbage = 1\n").unwrap();
    std::fs::write(dir.join("vehicle.toml"), "k_f = -1\nmass = 0.03\n").unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["diagnose", "missing.csv"], "missing.csv"),
        (&["diagnose", "bad.csv"], "`oops` is not a number"),
        (
            &["diagnose", "good.csv", "--columns", "map.toml"],
            "garbage",
        ),
        (&["compare", "good.csv", "--model", "bad.toml"], "bad.toml"),
        (
            &["simulate", "--model", "bad.toml", "-o", "x.csv"],
            "bad.toml",
        ),
        (
            &["diagnose", "good.csv", "--vehicle", "vehicle.toml"],
            "vehicle.toml",
        ),
    ];
    for (args, needle) in cases {
        let out = common::tagk_output(&dir, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "tagk {args:?}: {stderr}");
        assert!(stderr.starts_with("tagk: "), "tagk {args:?}: {stderr}");
        assert_eq!(stderr.matches(needle).count(), 1, "tagk {args:?}: {stderr}");
        // The message and each cause: none holds another (a repeated message).
        let parts: Vec<&str> = stderr
            .trim_start_matches("tagk: ")
            .split("\n  caused by: ")
            .map(str::trim)
            .collect();
        for (i, a) in parts.iter().enumerate() {
            for (j, b) in parts.iter().enumerate() {
                assert!(
                    i == j || !a.contains(b),
                    "tagk {args:?}: repeated: {stderr}"
                );
            }
        }
    }
}
