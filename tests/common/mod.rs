//! Helpers shared by the root package's integration tests.

use std::path::Path;
use std::process::Command;

/// Runs the `tagk` binary in `dir` and returns its standard output (panics, with its standard
/// error, if it fails).
pub fn tagk_in(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_tagk"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tagk {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}
