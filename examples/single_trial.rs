//! Fig. 3 of the TAG-K paper: paths of one figure-8 trial, parameter error over time, position-error CDF.
//!
//! `cargo run --release --example single_trial -- --help` lists the options; results go to
//! `out/single_trial/` unless `--out` says otherwise. The logic lives in `tagk_sim::experiments`.

use tagk::sim::clap::Parser;
use tagk::sim::experiments::{SingleTrialArgs, run_single_trial};

fn main() {
    let args = SingleTrialArgs::parse();
    if let Err(e) = run_single_trial(&args) {
        eprintln!("single_trial: {e}");
        std::process::exit(1);
    }
}
