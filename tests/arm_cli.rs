//! `tagk diagnose LOG --robot …`: the joint-torque diagnosis end to end on the shipped UR5
//! log, and its typed errors (a malformed log names file, line and column; a missing URDF
//! is named).

mod common;

use std::path::{Path, PathBuf};

use common::{tagk_fails_in, tagk_in};

const LOG: &str = "examples/data/arm/ur5.csv";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-arm-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The shipped log hides viscous and Coulomb friction and a 1.2 kg payload
/// (examples/arm_log.rs): all three are found, the residual falls to the noise.
#[test]
fn ur5_log_end_to_end() {
    let dir = scratch("e2e");
    let json = dir.join("arm.json");
    let out = tagk_in(
        root(),
        &[
            "diagnose",
            LOG,
            "--robot",
            "ur5",
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert!(out.contains("recommended: "), "{out}");
    assert!(out.contains("base parameters: 36 of 60"), "{out}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut found: Vec<&str> = v["final_model"]["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap())
        .collect();
    found.sort();
    assert_eq!(found, ["coulomb-friction", "payload", "viscous-friction"]);
    assert_eq!(v["steps"][0]["effect"], serde_json::Value::Null);
    assert_eq!(v["recommended"], v["steps"][1]["effect"]);
    let last = v["steps"].as_array().unwrap().last().unwrap();
    for j in last["joints"].as_array().unwrap() {
        assert!(j["ratio_to_noise"].as_f64().unwrap() < 1.2, "{j}");
    }
    // The payload's mass: 1.2 kg inside its interval.
    let m = v["final_model"]["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "payload Δm")
        .expect("the payload's mass is identifiable");
    let ci = m["confidence_interval"].as_array().unwrap();
    assert!(
        ci[0].as_f64().unwrap() <= 1.2 && 1.2 <= ci[1].as_f64().unwrap(),
        "{m}"
    );
    std::fs::remove_dir_all(dir).ok();
}

/// The shipped log is what the committed generator writes.
#[test]
fn shipped_log_is_the_generators_output() {
    let exe = Path::new(env!("CARGO_BIN_EXE_tagk"))
        .parent()
        .unwrap()
        .join("examples")
        .join(format!("arm_log{}", std::env::consts::EXE_SUFFIX));
    let dir = scratch("gen");
    let out = dir.join("ur5.csv");
    let status = std::process::Command::new(&exe)
        .arg(&out)
        .status()
        .unwrap_or_else(|e| panic!("{}: {e} (cargo test builds the examples)", exe.display()));
    assert!(status.success());
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(root().join(LOG)).unwrap(),
        "regenerate with: cargo run --release --example arm_log -- {LOG}"
    );
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn malformed_log_names_file_line_and_column() {
    let dir = scratch("bad");
    let text = std::fs::read_to_string(root().join(LOG)).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    // Line 5 of the file, column tau3 (the 16th field).
    let mut cells: Vec<String> = lines[4].split(',').map(String::from).collect();
    cells[15] = "12..5".into();
    lines[4] = cells.join(",");
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let err = tagk_fails_in(
        root(),
        &["diagnose", bad.to_str().unwrap(), "--robot", "ur5"],
    );
    assert!(err.contains("bad.csv"), "{err}");
    assert!(err.contains("line 5"), "{err}");
    assert!(err.contains("`tau3`"), "{err}");
    // A missing column is named too.
    let no_dq = text.replacen("dq4,", "dq_four,", 1);
    std::fs::write(&bad, no_dq).unwrap();
    let err = tagk_fails_in(
        root(),
        &["diagnose", bad.to_str().unwrap(), "--robot", "ur5"],
    );
    assert!(err.contains("dq4"), "{err}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn missing_urdf_and_wrong_robot_are_named() {
    let err = tagk_fails_in(root(), &["diagnose", LOG, "--robot", "no/such/arm.urdf"]);
    assert!(err.contains("no/such/arm.urdf"), "{err}");
    assert!(err.contains("no such URDF file"), "{err}");
    assert!(err.contains("ur5, panda"), "{err}");
    // The UR5's log is not the planar arm's.
    let err = tagk_fails_in(root(), &["diagnose", LOG, "--robot", "planar_2link"]);
    assert!(err.contains("6 joints"), "{err}");
    // The quadrotor's options do not apply.
    let err = tagk_fails_in(
        root(),
        &["diagnose", LOG, "--robot", "ur5", "--with", "wind"],
    );
    assert!(err.contains("cannot be used with"), "{err}");
}
