//! Table III of the TAG-K paper on this machine: per-update time for n in 40..120, m = 30.
//!
//! `cargo run --release --example dimension_sweep -- --help` lists the options; results go to
//! `out/dimension_sweep/` unless `--out` says otherwise. The logic lives in `tagk_sim::experiments`.

use tagk::sim::clap::Parser;
use tagk::sim::experiments::{DimensionSweepArgs, run_dimension_sweep};

fn main() {
    let args = DimensionSweepArgs::parse();
    if let Err(e) = run_dimension_sweep(&args) {
        eprintln!("dimension_sweep: {e}");
        std::process::exit(1);
    }
}
