//! The READMEs' Table II blocks equal what the committed code prints for their stated seeds
//! (issue #14: the tables cannot drift from the code). The real vehicles' blocks use issue #27's
//! headline layout (`table_ii_markdown`). `scripts/table2.sh` writes the blocks;
//! this test recomputes, in-process, every block of at most [`MAX_TRIALS`] trials per cell
//! (the 500-trial tables take minutes: `scripts/table2.sh --check` covers them).

use std::str::FromStr;

use tagk::sim::ExperimentProfile;
use tagk::sim::experiments::{table_ii_estimators_for, table_ii_markdown, table_ii_sweep};

/// Blocks with more trials per cell are left to `scripts/table2.sh --check`.
const MAX_TRIALS: usize = 20;

struct Block {
    file: &'static str,
    profile: ExperimentProfile,
    seed: u64,
    trials: usize,
    /// A `curve=gain` block (success over the integral gain), not a table.
    curve: bool,
    text: String,
}

fn blocks(file: &'static str) -> Vec<Block> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let doc = std::fs::read_to_string(&path).expect("README");
    let mut out = Vec::new();
    let mut lines = doc.lines();
    while let Some(line) = lines.next() {
        let Some(args) = line
            .strip_prefix("<!-- table2 ")
            .and_then(|l| l.strip_suffix(" -->"))
        else {
            continue;
        };
        let value = |key: &str| {
            args.split(' ')
                .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
                .unwrap_or_else(|| panic!("{file}: `{line}` lacks {key}="))
                .to_string()
        };
        let mut text = String::new();
        for l in lines.by_ref() {
            if l == "<!-- /table2 -->" {
                break;
            }
            text.push_str(l);
            text.push('\n');
        }
        out.push(Block {
            file,
            profile: ExperimentProfile::from_str(&value("profile")).expect("profile"),
            seed: value("seed").parse().expect("seed"),
            trials: value("trials").parse().expect("trials"),
            curve: args.split(' ').any(|kv| kv == "curve=gain"),
            text,
        });
    }
    out
}

#[test]
fn readme_tables_equal_what_the_code_prints() {
    let all: Vec<Block> = ["README.md", "tagk-sim/README.md"]
        .into_iter()
        .flat_map(blocks)
        .collect();
    let small: Vec<&Block> = all
        .iter()
        .filter(|b| b.trials <= MAX_TRIALS && !b.curve)
        .collect();
    assert!(
        !small.is_empty(),
        "no Table II block of at most {MAX_TRIALS} trials to check"
    );
    for b in small {
        let result = table_ii_sweep(
            b.profile,
            table_ii_estimators_for(b.profile),
            b.trials,
            b.seed,
        )
        .run()
        .expect("sweep");
        assert_eq!(
            table_ii_markdown(b.profile, &result),
            b.text,
            "{}: the table of profile {} seed {} trials {} differs from what the code prints \
             (run scripts/table2.sh)",
            b.file,
            b.profile,
            b.seed,
            b.trials
        );
    }
}
