//! The conventions document `docs/CONVENTIONS.md` ships with the repository and stays true:
//!
//! - every reference to it names the shipped file (`docs/CONVENTIONS.md`), and every section
//!   `§N` cited next to it (or inside it) exists there;
//! - no tracked file points to a folder outside the repository;
//! - its table of effect names is exactly what `EffectKind::ALL` says (run with `TAGK_BLESS=1`
//!   to rewrite the table from the code after changing the vocabulary);
//! - the numbers and names it states (Crazyflie constants, rotor spins, safety gate, metric
//!   thresholds, log columns and limits) are the code's.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use tagk::dynamics::EffectKind;

const CONVENTIONS: &str = "docs/CONVENTIONS.md";
/// This file: it spells the patterns it looks for.
const THIS_FILE: &str = "tests/docs.rs";
/// First line of the generated effect table's block (a comment, followed by the table).
const TABLE_BEGIN: &str = "<!-- effect-table: generated";
/// Last line of the block.
const TABLE_END: &str = "<!-- effect-table: end -->";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The repository's tracked files (`git ls-files`), or, without git, every file outside
/// `target/` and hidden folders.
fn tracked_files() -> Vec<PathBuf> {
    let root = root();
    let out = Command::new("git")
        .arg("-C")
        .arg(&root)
        .args(["ls-files", "-z"])
        .output();
    if let Ok(out) = out
        && out.status.success()
    {
        return out
            .stdout
            .split(|b| *b == 0)
            .filter(|p| !p.is_empty())
            .map(|p| PathBuf::from(String::from_utf8_lossy(p).into_owned()))
            .collect();
    }
    fn walk(root: &Path, dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            let name = e.file_name();
            let name = name.to_string_lossy();
            if name.starts_with('.') || name == "target" {
                continue;
            }
            if path.is_dir() {
                walk(root, &path, out);
            } else if let Ok(rel) = path.strip_prefix(root) {
                out.push(rel.to_path_buf());
            }
        }
    }
    let mut files = Vec::new();
    walk(&root, &root, &mut files);
    files
}

/// `(path, text)` of every tracked UTF-8 text file except this one.
fn text_files() -> Vec<(String, String)> {
    let root = root();
    tracked_files()
        .into_iter()
        .filter_map(|rel| {
            let name = rel.to_string_lossy().replace('\\', "/");
            if name == THIS_FILE {
                return None;
            }
            let text = String::from_utf8(std::fs::read(root.join(&rel)).ok()?).ok()?;
            Some((name, text))
        })
        .collect()
}

/// Section numbers of `docs/CONVENTIONS.md`: `## N. Title` gives `N`, `### N.M Title` gives
/// `N.M`.
fn sections(doc: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in doc.lines() {
        let rest = if let Some(r) = line.strip_prefix("## ") {
            r
        } else if let Some(r) = line.strip_prefix("### ") {
            r
        } else {
            continue;
        };
        let number: String = rest
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.')
            .collect();
        let number = number.trim_end_matches('.');
        if !number.is_empty() {
            found.insert(number.to_string());
        }
    }
    found
}

/// The section numbers cited on a line: each `§N` or `§N.M`, and the upper end of a range
/// written `§1–4` or `§1-4`.
fn cited_sections(line: &str) -> Vec<String> {
    let mut cited = Vec::new();
    let number = |s: &str| -> (String, usize) {
        let digits: String = s
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.')
            .collect();
        let trimmed = digits.trim_end_matches('.').to_string();
        let len = trimmed.len();
        (trimmed, len)
    };
    for (at, _) in line.match_indices('§') {
        let after = &line[at + '§'.len_utf8()..];
        let (n, len) = number(after);
        if n.is_empty() || !n.starts_with(|c: char| c.is_ascii_digit()) {
            continue;
        }
        cited.push(n);
        let rest = &after[len..];
        if let Some(upper) = rest.strip_prefix('–').or_else(|| rest.strip_prefix('-')) {
            let (m, _) = number(upper);
            if !m.is_empty() {
                cited.push(m);
            }
        }
    }
    cited
}

#[test]
fn every_conventions_reference_names_the_shipped_document_and_an_existing_section() {
    let doc = std::fs::read_to_string(root().join(CONVENTIONS))
        .expect("docs/CONVENTIONS.md ships with the repository");
    let known = sections(&doc);
    for n in 1..=9 {
        assert!(
            known.contains(&n.to_string()),
            "section {n} missing: {known:?}"
        );
    }
    let mut problems = Vec::new();
    for (path, text) in text_files() {
        for (i, line) in text.lines().enumerate() {
            let here = format!("{path}:{}", i + 1);
            for (at, _) in line.match_indices("CONVENTIONS") {
                if !line[..at].ends_with("docs/") {
                    problems.push(format!(
                        "{here}: cite the shipped document as `{CONVENTIONS} §N`: {line}"
                    ));
                }
            }
            if path == CONVENTIONS || line.contains("CONVENTIONS") {
                for n in cited_sections(line) {
                    if !known.contains(&n) {
                        problems.push(format!("{here}: §{n} is not a section of {CONVENTIONS}"));
                    }
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn nothing_points_outside_the_repository() {
    let outside = ["../shared", "/work/shared"];
    let mut problems = Vec::new();
    for (path, text) in text_files() {
        // CI's script is the one exception: the machine CI runs on keeps the developers'
        // instruction-counting plugin beside the checkout, and CI hands it to the firmware
        // check. Nothing a user reads or runs depends on it.
        if path == ".ci/run" {
            continue;
        }
        for (i, line) in text.lines().enumerate() {
            for o in outside {
                if line.contains(o) {
                    problems.push(format!("{path}:{}: mentions `{o}`: {line}", i + 1));
                }
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The effect table of `docs/CONVENTIONS.md` §7 as the code defines it.
fn effect_table() -> String {
    let mut table = String::from("| name | also accepted | what it is |\n|---|---|---|\n");
    for kind in EffectKind::ALL {
        let aliases = kind
            .aliases()
            .iter()
            .map(|a| format!("`{a}`"))
            .collect::<Vec<_>>()
            .join(", ");
        let summary = kind.summary().replace('|', "\\|");
        let aliases = if aliases.is_empty() {
            String::new()
        } else {
            format!("{aliases} ")
        };
        table.push_str(&format!("| `{}` | {aliases}| {summary} |\n", kind.name()));
    }
    table
}

#[test]
fn the_effect_table_is_the_code_s_vocabulary() {
    let path = root().join(CONVENTIONS);
    let doc = std::fs::read_to_string(&path).unwrap();
    let begin = doc
        .find(TABLE_BEGIN)
        .expect("the effect table's opening comment");
    let table_start = begin + doc[begin..].find('\n').expect("a line after the comment") + 1;
    let table_end = table_start
        + doc[table_start..]
            .find(TABLE_END)
            .expect("the effect table's closing comment");
    let expected = effect_table();
    if std::env::var_os("TAGK_BLESS").is_some_and(|v| v == "1") {
        let updated = format!("{}{expected}{}", &doc[..table_start], &doc[table_end..]);
        std::fs::write(&path, updated).unwrap();
        return;
    }
    assert_eq!(
        &doc[table_start..table_end],
        expected,
        "the effect table of {CONVENTIONS} §7 differs from EffectKind::ALL; \
         rerun with TAGK_BLESS=1 to rewrite it"
    );
}

#[test]
fn the_checker_reads_section_citations() {
    assert_eq!(cited_sections("see CONVENTIONS §3"), ["3"]);
    assert_eq!(cited_sections("(§2–§4)"), ["2", "4"]);
    assert_eq!(cited_sections("§1–4 and §2.1."), ["1", "4", "2.1"]);
    assert!(cited_sections("as `§N`").is_empty());
    let s = sections("## 1. A\n### 2.1 B\n## Contents\n");
    assert_eq!(s.into_iter().collect::<Vec<_>>(), ["1", "2.1"]);
}

/// The text of section `## N.` of `docs/CONVENTIONS.md`, up to the next `## ` heading.
fn section(doc: &str, n: u32) -> &str {
    let heading = format!("\n## {n}. ");
    let start = doc
        .find(&heading)
        .unwrap_or_else(|| panic!("no section {n}"))
        + 1;
    let end = doc[start + 3..]
        .find("\n## ")
        .map_or(doc.len(), |e| start + 3 + e);
    &doc[start..end]
}

/// Every number written in `text` (tokens of digits, `.`, `e`, `+`, `-`).
fn numbers(text: &str) -> Vec<f64> {
    text.split(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '+' | '-')))
        .filter_map(|t| {
            t.trim_matches(|c| matches!(c, '.' | '-' | '+'))
                .parse()
                .ok()
        })
        .collect()
}

#[test]
fn the_document_states_the_code_s_constants_and_columns() {
    use tagk::dynamics::log::{
        MIN_ROWS, OPTIONAL_COLUMNS, QUATERNION_NORM_TOLERANCE, REQUIRED_COLUMNS,
    };
    use tagk::dynamics::quadrotor::{
        CRAZYFLIE_ARM_OFFSET, CRAZYFLIE_INERTIA, CRAZYFLIE_K_F, CRAZYFLIE_K_M, CRAZYFLIE_MASS,
        CRAZYFLIE_MAX_ROTOR_SPEED, CRAZYFLIE_MOTOR_DISTANCE,
    };
    use tagk::sim::metrics::{ABORT_THRESHOLD, SUCCESS_DELAY_STEPS, SUCCESS_THRESHOLD};

    let doc = std::fs::read_to_string(root().join(CONVENTIONS)).unwrap();
    let states = |n: u32, what: &str, value: f64| {
        let found = numbers(section(&doc, n));
        assert!(
            found
                .iter()
                .any(|x| (x - value).abs() <= 1e-12 * value.abs()),
            "{CONVENTIONS} §{n} should state {what} = {value} (numbers found: {found:?})"
        );
    };
    let gate = tagk::dynamics::SafetyGate::crazyflie();
    states(1, "L_arm", gate.max_com_offset);
    states(1, "alpha", gate.max_inertia_eigenvalue);
    states(2, "g", -tagk::dynamics::GRAVITY_WORLD.z);
    states(4, "mass", CRAZYFLIE_MASS);
    states(4, "L_arm", CRAZYFLIE_ARM_OFFSET);
    states(4, "motor distance", CRAZYFLIE_MOTOR_DISTANCE);
    states(4, "k_f", CRAZYFLIE_K_F);
    states(4, "k_m", CRAZYFLIE_K_M);
    states(4, "largest rotor speed", CRAZYFLIE_MAX_ROTOR_SPEED);
    for (k, i) in CRAZYFLIE_INERTIA.iter().enumerate() {
        states(4, &format!("inertia entry {k}"), *i);
    }
    let spins = tagk::dynamics::QuadrotorModel::crazyflie_2_1().spin_directions;
    let rotor_rows: Vec<&str> = section(&doc, 4)
        .lines()
        .filter(|l| l.starts_with("| M"))
        .collect();
    assert_eq!(rotor_rows.len(), 4, "{rotor_rows:?}");
    for (row, s) in rotor_rows.iter().zip(spins) {
        let sign = if s > 0.0 { "`+1`" } else { "`−1`" };
        assert!(
            row.trim_end()
                .trim_end_matches('|')
                .trim_end()
                .ends_with(sign),
            "{row}"
        );
    }
    states(5, "abort threshold [cm]", 100.0 * ABORT_THRESHOLD);
    states(5, "success threshold [cm]", 100.0 * SUCCESS_THRESHOLD);
    states(
        5,
        "success delay [control steps]",
        SUCCESS_DELAY_STEPS as f64,
    );
    states(6, "quaternion norm tolerance", QUATERNION_NORM_TOLERANCE);
    {
        use tagk::diagnose::{
            ADEQUACY_FACTOR, ADEQUATE_AUTOCORRELATION, CONSISTENCY_TOLERANCE, DiagnoseOptions,
            FLOOR_RESOLUTION, MAX_CONSTANT_FORCE_OF_THRUST, MAX_INFLATION, MAX_MASS_CHANGE,
            MIN_GAIN, WHITENESS_FALSE_ALARM,
        };
        let defaults = DiagnoseOptions::default();
        states(7, "mass change [%]", 100.0 * MAX_MASS_CHANGE);
        states(
            7,
            "constant force of the thrust [%]",
            100.0 * MAX_CONSTANT_FORCE_OF_THRUST,
        );
        states(7, "held-out gain [%]", 100.0 * MIN_GAIN);
        states(7, "variance inflation", MAX_INFLATION);
        states(7, "adequacy factor", ADEQUACY_FACTOR);
        states(7, "adequate autocorrelation", ADEQUATE_AUTOCORRELATION);
        states(7, "whiteness false alarm", WHITENESS_FALSE_ALARM);
        states(7, "consistency tolerance", CONSISTENCY_TOLERANCE);
        states(7, "floor resolution", FLOOR_RESOLUTION);
        states(7, "alpha", defaults.alpha);
        states(7, "folds", defaults.folds as f64);
        states(7, "steps", defaults.max_steps as f64);
    }
    states(6, "fewest rows", MIN_ROWS as f64);
    let log_section = section(&doc, 6);
    for column in REQUIRED_COLUMNS.iter().chain(&OPTIONAL_COLUMNS) {
        assert!(
            log_section.contains(&format!("`{column}`")),
            "{CONVENTIONS} §6 should list the column `{column}`"
        );
    }
}

#[test]
fn the_example_log_rows_are_read_by_the_reader() {
    use tagk::dynamics::log::{FlightLog, LogError, REQUIRED_COLUMNS};
    let doc = std::fs::read_to_string(root().join(CONVENTIONS)).unwrap();
    let log_section = section(&doc, 6);
    let start = log_section
        .find("```text\n")
        .expect("§6 shows an example log")
        + "```text\n".len();
    let end = start + log_section[start..].find("```").unwrap();
    let example = &log_section[start..end];
    assert_eq!(
        example.lines().next(),
        Some(REQUIRED_COLUMNS.join(",").as_str())
    );
    // Every row is valid; only the length (fewer than MIN_ROWS samples) is refused.
    let rows = example.lines().count() - 1;
    assert!(matches!(
        FlightLog::from_csv_reader(example.as_bytes()),
        Err(LogError::TooShort { rows: r, .. }) if r == rows
    ));
}
