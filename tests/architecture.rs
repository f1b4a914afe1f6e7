//! The layer rules of `ARCHITECTURE.md`, checked against `cargo metadata`: every dependency
//! between workspace crates must be one the table allows, so a crate never reaches up or
//! sideways.

use std::collections::BTreeMap;

mod common;

/// `(crate, layer, allowed normal/build dependencies, additionally allowed dev-dependencies)`,
/// exactly the table of `ARCHITECTURE.md`.
const RULES: &[(&str, u8, &[&str], &[&str])] = &[
    ("tagk-core", 0, &[], &[]),
    ("tagk-baselines", 1, &["tagk-core"], &[]),
    ("tagk-dynamics", 1, &["tagk-core"], &[]),
    ("tagk-mcu", 2, &["tagk-core", "tagk-baselines"], &[]),
    ("tagk-insncount", 2, &["tagk-core", "tagk-baselines"], &[]),
    ("tagk-control", 2, &["tagk-core", "tagk-dynamics"], &[]),
    (
        "tagk-sim",
        3,
        &[
            "tagk-core",
            "tagk-baselines",
            "tagk-dynamics",
            "tagk-control",
        ],
        &[],
    ),
    (
        "tagk-diagnose",
        4,
        &["tagk-core", "tagk-dynamics"],
        &["tagk-sim"],
    ),
    (
        "tagk",
        5,
        &[
            "tagk-core",
            "tagk-baselines",
            "tagk-dynamics",
            "tagk-mcu",
            "tagk-control",
            "tagk-sim",
            "tagk-diagnose",
        ],
        &[],
    ),
];

/// Each workspace member with its workspace dependencies as `(name, kind)`; kind is
/// `"normal"`, `"dev"` or `"build"`.
fn workspace_dependencies() -> BTreeMap<String, Vec<(String, String)>> {
    let packages = common::workspace_packages();
    let members: Vec<String> = packages
        .iter()
        .map(|p| p["name"].as_str().unwrap().to_string())
        .collect();
    packages
        .iter()
        .map(|p| {
            let deps = p["dependencies"]
                .as_array()
                .unwrap()
                .iter()
                .filter(|d| members.iter().any(|m| m == d["name"].as_str().unwrap()))
                .map(|d| {
                    let kind = d["kind"].as_str().unwrap_or("normal").to_string();
                    (d["name"].as_str().unwrap().to_string(), kind)
                })
                .collect();
            (p["name"].as_str().unwrap().to_string(), deps)
        })
        .collect()
}

#[test]
fn every_workspace_crate_has_a_rule() {
    let deps = workspace_dependencies();
    for name in deps.keys() {
        assert!(
            RULES.iter().any(|r| r.0 == name),
            "{name} is not in ARCHITECTURE.md's table (and tests/architecture.rs)"
        );
    }
    for rule in RULES {
        assert!(
            deps.contains_key(rule.0),
            "{} is not a workspace member",
            rule.0
        );
    }
}

#[test]
fn dependencies_follow_the_layers() {
    let deps = workspace_dependencies();
    let layer = |name: &str| RULES.iter().find(|r| r.0 == name).map(|r| r.1);
    let mut violations = Vec::new();
    for (name, list) in &deps {
        let Some(&(_, own_layer, normal, dev)) = RULES.iter().find(|r| r.0 == name) else {
            continue;
        };
        for (dep, kind) in list {
            let allowed =
                normal.contains(&dep.as_str()) || (kind == "dev" && dev.contains(&dep.as_str()));
            let below = layer(dep).is_some_and(|l| l < own_layer);
            if !allowed || !below {
                violations.push(format!("{name} -> {dep} ({kind})"));
            }
        }
    }
    assert!(
        violations.is_empty(),
        "dependencies that break ARCHITECTURE.md's layers: {violations:?}"
    );
}

#[test]
fn the_rules_themselves_point_downwards() {
    for &(name, own, normal, dev) in RULES {
        for dep in normal.iter().chain(dev) {
            let l = RULES.iter().find(|r| r.0 == *dep).map(|r| r.1).unwrap();
            assert!(l < own, "rule {name} -> {dep} does not point down a layer");
        }
    }
}
