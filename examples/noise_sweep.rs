//! Table II of the TAG-K paper: RLS-low/high, KF-low/high, TAG-K x 4 noise levels.
//!
//! `cargo run --release --example noise_sweep -- --help` lists the options; results go to
//! `out/noise_sweep/` unless `--out` says otherwise. The logic lives in `tagk_sim::experiments`.

use tagk::sim::clap::Parser;
use tagk::sim::experiments::{NoiseSweepArgs, run_noise_sweep};

fn main() {
    let args = NoiseSweepArgs::parse();
    if let Err(e) = run_noise_sweep(&args) {
        eprintln!("noise_sweep: {e}");
        std::process::exit(1);
    }
}
