//! `tagk simulate` → `tagk diagnose --save-model --save-steps` → `tagk compare`, end to end
//! through the binary: the model files read back, the JSON has exactly the documented keys,
//! and the staircase's final model predicts the flight better than the rigid body.

mod common;

use common::tagk_in;
use tagk::diagnose::ModelFile;

#[test]
fn simulate_diagnose_save_and_compare() {
    let dir = std::env::temp_dir().join(format!("tagk-compare-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    tagk_in(
        &dir,
        &[
            "simulate",
            "--effect",
            "linear-drag",
            "--seed",
            "3",
            "--duration",
            "20",
            "--payload",
            "none",
            "-o",
            "f.csv",
        ],
    );
    tagk_in(
        &dir,
        &[
            "diagnose",
            "f.csv",
            "--vehicle",
            "crazyflie-2.1",
            "--save-model",
            "m.toml",
            "--save-steps",
            "steps",
            "--quiet",
        ],
    );
    let model = ModelFile::from_path(&dir.join("m.toml")).unwrap();
    assert_eq!(model.label, "rigid body + linear-drag");
    assert_eq!(model.logs[0].path, "f.csv");
    assert_eq!(
        model.logs[0].bytes,
        std::fs::metadata(dir.join("f.csv")).unwrap().len()
    );
    assert!(model.vehicle.is_some());
    let mut steps: Vec<String> = std::fs::read_dir(dir.join("steps"))
        .unwrap()
        .map(|e| format!("steps/{}", e.unwrap().file_name().to_string_lossy()))
        .collect();
    steps.sort();
    assert_eq!(
        steps,
        [
            "steps/step-0-rigid-body.toml",
            "steps/step-1-linear-drag.toml"
        ]
    );
    let table = tagk_in(
        &dir,
        &[
            "compare",
            "f.csv",
            "--horizon",
            "20",
            "--json",
            "c.json",
            "--report",
            "c.html",
            "--model",
            &steps[0],
            &steps[1],
        ],
    );
    assert!(table.contains("velocity error [m/s]"), "{table}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("c.json")).unwrap()).unwrap();
    let top: Vec<&String> = json.as_object().unwrap().keys().collect();
    assert_eq!(top, ["models"]);
    let models = json["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[0]["model"], "steps/step-0-rigid-body.toml");
    let mut keys: Vec<&String> = models[0]["horizons"][0]
        .as_object()
        .unwrap()
        .keys()
        .collect();
    keys.sort();
    assert_eq!(
        keys,
        [
            "attitude",
            "body_rate",
            "dt",
            "fit",
            "h",
            "position",
            "velocity"
        ]
    );
    let hs: Vec<u64> = models[0]["horizons"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["h"].as_u64().unwrap())
        .collect();
    assert_eq!(hs, [1, 2, 5, 10, 20]);
    let at20 = |m: usize, q: &str| models[m]["horizons"][4][q].as_f64().unwrap();
    for q in ["position", "velocity"] {
        assert!(
            5.0 * at20(1, q) < at20(0, q),
            "{q}: final {} vs rigid {}",
            at20(1, q),
            at20(0, q)
        );
    }
    let html = std::fs::read_to_string(dir.join("c.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 4);
    std::fs::remove_dir_all(&dir).unwrap();
}
