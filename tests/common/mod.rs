//! Helpers shared by the root package's integration tests.

// Each test crate includes this module and uses only some of it.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the `tagk` binary in `dir` with `args`.
pub fn tagk_output(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// Runs the `tagk` binary in `dir` and returns its standard output (panics, with its standard
/// error, if it fails).
pub fn tagk_in(dir: &Path, args: &[&str]) -> String {
    let out = tagk_output(dir, args);
    assert!(
        out.status.success(),
        "tagk {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Runs the `tagk` binary in `dir`, which must fail, and returns its standard error (panics,
/// with its standard output, if it succeeds).
pub fn tagk_fails_in(dir: &Path, args: &[&str]) -> String {
    let out = tagk_output(dir, args);
    assert!(
        !out.status.success(),
        "tagk {args:?} succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8(out.stderr).unwrap()
}

/// The README's realistic example: the plant's effects and the sensing, as `tagk simulate`
/// arguments (README, "On the README's realistic example").
pub const README_REALISTIC: &[&str] = &[
    "--effect",
    "linear-drag",
    "--effect",
    "motor-lag",
    "--sensing",
    "realistic",
    "--yaw-rate",
    "0.3",
];

/// `tagk diagnose` of the shipped foreign flight (`examples/data/foreign-flight`): its
/// mapping, the vehicle and its three streams.
pub const FOREIGN_FLIGHT: &[&str] = &[
    "diagnose",
    "--columns",
    "map.toml",
    "--vehicle",
    "crazyflie-2.1",
    "--stream",
    "imu.csv",
    "--stream",
    "motors.csv",
    "--stream",
    "mocap.csv",
];

/// [`FOREIGN_FLIGHT`] with the vehicle `vehicle` (a preset's name or a vehicle file).
pub fn foreign_flight_with(vehicle: &str) -> Vec<&str> {
    let mut args = FOREIGN_FLIGHT.to_vec();
    let k = args.iter().position(|a| *a == "--vehicle").unwrap();
    args[k + 1] = vehicle;
    args
}

/// `cargo metadata --no-deps --offline` of the workspace: its own packages, as JSON.
pub fn workspace_packages() -> Vec<serde_json::Value> {
    let out = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args([
            "metadata",
            "--no-deps",
            "--format-version",
            "1",
            "--offline",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    meta["packages"].as_array().expect("a package list").clone()
}
