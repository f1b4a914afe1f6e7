//! The README's realistic example, end to end through the `tagk` binary: a simulated
//! Crazyflie with realistic sensors (an uncalibrated accelerometer among them), a linear drag
//! and a 20 ms motor lag, flown with a yawing heading, then `tagk diagnose`. The diagnosis
//! names the drag and the lag, the lag's time constant within 25 % of 20 ms (its interval
//! reported), the roll and pitch inertia within 10 % of the vehicle's (the yaw inertia said to
//! be biased by the gyro's noise), and nothing else but the accelerometer offset — named as
//! what it is, a sensor error (issue #24's proof). The offset's vertical part, measured against
//! the velocity and removed before the fit, leaves the mass within 1 % of the vehicle's. The
//! README quotes it.

mod common;

use std::path::PathBuf;

use tagk::dynamics::quadrotor::{CRAZYFLIE_INERTIA, CRAZYFLIE_MASS};

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tagk-readme-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_readme_realistic_example_names_the_drag_the_lag_and_the_sensor_offset() {
    let dir = tmpdir("realistic");
    common::tagk_in(
        &dir,
        &[
            &["simulate"][..],
            common::README_REALISTIC,
            &["-o", "flight.csv"],
        ]
        .concat(),
    );
    let text = common::tagk_in(&dir, &["diagnose", "flight.csv", "--json", "d.json"]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("d.json")).unwrap()).unwrap();
    let mut effects: Vec<String> = json["final_model"]["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_str().unwrap().to_string())
        .collect();
    effects.sort();
    assert_eq!(
        effects,
        ["accel-bias", "linear-drag", "motor-lag"],
        "{text}"
    );
    // The sensor offset is named as a sensor error in the first verdict.
    assert!(
        json["before"]["verdict"]
            .as_str()
            .unwrap()
            .contains("accel-bias"),
        "{text}"
    );
    let steps = json["steps"].as_array().unwrap();
    let lag = steps
        .iter()
        .find(|s| s["effect"] == "motor-lag")
        .expect("a motor-lag step");
    let tau = lag["scanned"][1].as_f64().unwrap();
    assert!((tau - 0.020).abs() <= 0.25 * 0.020, "tau {tau}\n{text}");
    let interval = lag["scanned_interval"].as_array().expect("an interval");
    assert!(interval[0].as_f64().unwrap() <= tau && tau <= interval[1].as_f64().unwrap());
    // Roll and pitch inertia within 10 %; the yaw inertia, barely excited at a constant yaw
    // rate, is said to be biased by the noise of the differentiated gyro.
    let last = json["final_diagnosis"]["parameters"].as_array().unwrap();
    assert!(
        json["final_diagnosis"]["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w
                .as_str()
                .unwrap()
                .starts_with("I_zz may be biased towards zero")),
        "{text}"
    );
    // The accelerometer's vertical offset is measured against the velocity and removed
    // before the fit: the mass is the vehicle's (left in, the offset scaled it by 2.5 %).
    let offset = &json["accelerometer_offsets"][0];
    assert!(offset["removed_z"].as_f64().unwrap() != 0.0, "{text}");
    let mass = last[0]["value"].as_f64().unwrap();
    assert!(
        (mass - CRAZYFLIE_MASS).abs() <= 0.01 * CRAZYFLIE_MASS,
        "mass {mass}\n{text}"
    );
    // The final model holds the plant's effects and the sensor's offset: it is at its noise.
    assert_eq!(json["adequate"].as_bool(), Some(true), "{text}");
    for (j, truth) in [(4, CRAZYFLIE_INERTIA[0]), (6, CRAZYFLIE_INERTIA[2])] {
        let value = last[j]["value"].as_f64().unwrap();
        assert!(
            (value - truth).abs() <= 0.10 * truth,
            "{}: {value} against {truth}\n{text}",
            last[j]["name"]
        );
    }
}
