//! Fig. 4a of the TAG-K paper: baselines with their first post-event estimate replaced by TAG-K's.
//!
//! `cargo run --release --example early_adaptation -- --help` lists the options; results go to
//! `out/early_adaptation/` unless `--out` says otherwise. The logic lives in `tagk_sim::experiments`.

use tagk::sim::clap::Parser;
use tagk::sim::experiments::{EarlyAdaptationArgs, run_early_adaptation};

fn main() {
    let args = EarlyAdaptationArgs::parse();
    if let Err(e) = run_early_adaptation(&args) {
        eprintln!("early_adaptation: {e}");
        std::process::exit(1);
    }
}
