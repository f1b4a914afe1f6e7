//! The crates are ready for the registry, as `cargo metadata` reads their manifests:
//!
//! - every publishable crate has a description, a licence, a README that ships in it,
//!   keywords, categories, the workspace's `rust-version`, and `documentation` on docs.rs (there
//!   is no public repository yet, so there is no `repository` or `homepage` either);
//! - a crate with optional features tells docs.rs to build them (`[package.metadata.docs.rs]`);
//! - a crate README links nothing outside its crate (`../…`), since only the crate is packed;
//! - `tagk-insncount` is not publishable, and CONTRIBUTING.md packs the workspace without it;
//! - tagk-dynamics without its default features needs neither urdf-rs nor toml;
//! - CI checks the MSRV the manifests declare, and CHANGELOG.md has the current version.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

mod common;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cargo() -> String {
    std::env::var("CARGO").unwrap_or_else(|_| "cargo".into())
}

/// `cargo metadata --no-deps`: the workspace's own packages.
fn packages() -> Vec<Value> {
    common::workspace_packages()
}

/// `publish = false` reads as an empty registry list.
fn publishable(p: &Value) -> bool {
    !matches!(p["publish"].as_array(), Some(list) if list.is_empty())
}

fn crate_dir(p: &Value) -> PathBuf {
    Path::new(p["manifest_path"].as_str().unwrap())
        .parent()
        .unwrap()
        .to_path_buf()
}

fn workspace_rust_version() -> String {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    manifest
        .lines()
        .find_map(|l| l.strip_prefix("rust-version = \""))
        .and_then(|r| r.strip_suffix('"'))
        .expect("[workspace.package] rust-version")
        .to_string()
}

#[test]
fn every_publishable_crate_has_its_registry_metadata() {
    let packages = packages();
    let rust_version = workspace_rust_version();
    let mut problems = Vec::new();
    let mut published = 0;
    for p in &packages {
        let name = p["name"].as_str().unwrap();
        if !publishable(p) {
            continue;
        }
        published += 1;
        for key in [
            "description",
            "license",
            "readme",
            "documentation",
            "rust_version",
        ] {
            if p[key].as_str().is_none_or(|v| v.trim().is_empty()) {
                problems.push(format!("{name}: no `{key}`"));
            }
        }
        let docs = format!("https://docs.rs/{name}");
        if p["documentation"].as_str() != Some(docs.as_str()) {
            problems.push(format!("{name}: documentation should be {docs}"));
        }
        // No public repository yet: a placeholder address is worse than none.
        for key in ["repository", "homepage"] {
            if !p[key].is_null() {
                problems.push(format!(
                    "{name}: `{key}` = {} but the project has no public repository yet \
                     (CONTRIBUTING.md, Publishing)",
                    p[key]
                ));
            }
        }
        if p["rust_version"].as_str() != Some(rust_version.as_str()) {
            problems.push(format!("{name}: rust-version is not the workspace's"));
        }
        for key in ["keywords", "categories"] {
            if p[key].as_array().is_none_or(|a| a.is_empty()) {
                problems.push(format!("{name}: no `{key}`"));
            }
        }
        if let Some(readme) = p["readme"].as_str() {
            let path = crate_dir(p).join(readme);
            if !path.starts_with(crate_dir(p)) || !path.is_file() {
                problems.push(format!(
                    "{name}: README {readme} is not a file of the crate"
                ));
            }
        }
        // Features beyond the defaults: docs.rs builds only the defaults unless told.
        // The defaults and every feature they enable (`std` enables `alloc`).
        let features = p["features"].as_object().unwrap();
        let mut defaults: Vec<&str> = features
            .keys()
            .filter(|f| *f == "default")
            .map(String::as_str)
            .collect();
        let mut i = 0;
        while i < defaults.len() {
            for f in features[defaults[i]]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(Value::as_str)
            {
                if features.contains_key(f) && !defaults.contains(&f) {
                    defaults.push(f);
                }
            }
            i += 1;
        }
        let optional: Vec<&String> = features
            .keys()
            .filter(|f| !defaults.contains(&f.as_str()))
            .collect();
        let docs_rs = &p["metadata"]["docs"]["rs"];
        let all = docs_rs["all-features"].as_bool() == Some(true);
        let listed: Vec<&str> = docs_rs["features"]
            .as_array()
            .map(|l| l.iter().filter_map(Value::as_str).collect())
            .unwrap_or_default();
        for f in optional {
            if !all && !listed.contains(&f.as_str()) {
                problems.push(format!(
                    "{name}: feature `{f}` is off by default and missing from \
                     [package.metadata.docs.rs]"
                ));
            }
        }
    }
    assert_eq!(published, 8, "the eight publishable crates");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn crate_readmes_link_nothing_outside_their_crate() {
    let mut problems = Vec::new();
    for p in packages().iter().filter(|p| publishable(p)) {
        let dir = crate_dir(p);
        if dir == root() {
            continue; // the root README is the repository's own page
        }
        let readme = dir.join(p["readme"].as_str().unwrap());
        let text = std::fs::read_to_string(&readme).unwrap();
        for (i, line) in text.lines().enumerate() {
            for pattern in ["](../", "]: ../", "](/", "]: /"] {
                if line.contains(pattern) {
                    problems.push(format!("{}:{}: {line}", readme.display(), i + 1));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_instruction_counter_is_not_published_and_packing_leaves_it_out() {
    let packages = packages();
    let insncount = packages
        .iter()
        .find(|p| p["name"] == "tagk-insncount")
        .expect("tagk-insncount is a member");
    assert!(!publishable(insncount));
    let contributing = std::fs::read_to_string(root().join("CONTRIBUTING.md")).unwrap();
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    let command = "cargo package --workspace --exclude tagk-insncount";
    assert!(contributing.contains(command), "CONTRIBUTING.md: {command}");
    assert!(ci.contains(command), ".ci/run: {command}");
}

#[test]
fn ci_checks_the_declared_msrv_and_the_changelog_has_this_version() {
    let rust_version = workspace_rust_version();
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    assert!(
        ci.contains(&format!("msrv={rust_version}")),
        ".ci/run should check rust-version {rust_version}"
    );
    let changelog = std::fs::read_to_string(root().join("CHANGELOG.md")).unwrap();
    assert!(changelog.contains("## [Unreleased]"));
    let version = env!("CARGO_PKG_VERSION");
    assert!(
        changelog.contains(&format!("## [{version}]")),
        "CHANGELOG.md has no section for {version}"
    );
}

#[test]
fn tagk_dynamics_without_defaults_leaves_out_urdf_and_toml() {
    let out = Command::new(cargo())
        .current_dir(root())
        .args([
            "tree",
            "--offline",
            "-p",
            "tagk-dynamics",
            "--no-default-features",
            "-e",
            "normal",
            "--prefix",
            "none",
        ])
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tree = String::from_utf8_lossy(&out.stdout);
    for heavy in [
        "urdf-rs ",
        "regex ",
        "toml ",
        "serde-xml-rs ",
        "quick-xml ",
        "RustyXML ",
    ] {
        assert!(
            !tree.lines().any(|l| l.starts_with(heavy)),
            "{heavy}in tagk-dynamics --no-default-features:\n{tree}"
        );
    }
    assert!(tree.lines().any(|l| l.starts_with("nalgebra ")));
}
