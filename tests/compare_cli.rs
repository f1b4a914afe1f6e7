//! `tagk simulate` → `tagk diagnose --save-model --save-steps` → `tagk compare`, end to end
//! through the binary: the model files read back, the JSON has exactly the documented keys,
//! the staircase's final model predicts the flight better than the rigid body and than the
//! constant-rate reference, and the overlays reach the terminal, the JSON and the page.

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
    assert!(table.contains("model 3: constant-rate"), "{table}");
    // The default overlay is at the longest horizon: one summary line per model.
    assert_eq!(
        table.matches("\nh   20 (0.400 s) model ").count(),
        3,
        "{table}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("c.json")).unwrap()).unwrap();
    let top: Vec<&String> = json.as_object().unwrap().keys().collect();
    assert_eq!(top, ["models"]);
    let models = json["models"].as_array().unwrap();
    assert_eq!(models.len(), 3);
    assert_eq!(models[0]["model"], "steps/step-0-rigid-body.toml");
    assert_eq!(models[2]["model"], "constant-rate");
    let mut entry: Vec<&String> = models[0].as_object().unwrap().keys().collect();
    entry.sort();
    // The default overlay is drawn on the page; its series enter the JSON file only when
    // asked for (below).
    assert_eq!(entry, ["horizons", "model"]);
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
        assert!(
            at20(1, q) < at20(2, q),
            "{q}: final {} vs constant-rate {}",
            at20(1, q),
            at20(2, q)
        );
    }
    let html = std::fs::read_to_string(dir.join("c.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 4 + 16);
    assert!(html.contains("id=\"overlay-h20\""));
    // Without the reference and the overlays: the former output exactly.
    let plain = tagk_in(
        &dir,
        &[
            "compare",
            "f.csv",
            "--horizon",
            "20",
            "--no-overlay",
            "--no-baseline",
            "--json",
            "p.json",
            "--report",
            "p.html",
            "--model",
            &steps[0],
        ],
    );
    assert!(
        !plain.contains("constant-rate") && !plain.contains("overlay"),
        "{plain}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("p.json")).unwrap()).unwrap();
    let mut entry: Vec<&String> = json["models"][0].as_object().unwrap().keys().collect();
    entry.sort();
    assert_eq!(entry, ["horizons", "model"]);
    let html = std::fs::read_to_string(dir.join("p.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 4);
    // Two chosen overlay horizons, one beyond the error table's.
    let two = tagk_in(
        &dir,
        &[
            "compare",
            "f.csv",
            "--horizon",
            "20",
            "--overlay",
            "1,30",
            "--json",
            "two.json",
            "--report",
            "two.html",
            "--model",
            &steps[1],
        ],
    );
    assert_eq!(two.matches("\nh    1 (0.020 s) model ").count(), 2, "{two}");
    assert_eq!(two.matches("\nh   30 (0.600 s) model ").count(), 2, "{two}");
    let html = std::fs::read_to_string(dir.join("two.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), 4 + 2 * 16);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("two.json")).unwrap()).unwrap();
    let overlays = json["models"][0]["overlays"].as_array().unwrap();
    let hs: Vec<u64> = overlays.iter().map(|o| o["h"].as_u64().unwrap()).collect();
    assert_eq!(hs, [1, 30]);
    for overlay in overlays {
        let n = overlay["t"].as_array().unwrap().len();
        assert!(n > 900, "{n} overlay samples");
        for side in ["logged", "predicted"] {
            for q in ["position", "velocity", "attitude", "body_rate"] {
                assert_eq!(overlay[side][q].as_array().unwrap().len(), n, "{side} {q}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
