//! Table II of the TAG-K paper: RLS-low/high, KF-low/high, TAG-K x 4 noise levels.
//!
//! `cargo run --release --example noise_sweep -- --help` lists the options; results go to
//! `out/noise_sweep/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.

mod common;

use clap::Parser;
use tagk::sim::experiments::run_noise_sweep;

/// Table II: every estimator x 4 noise levels, closed-loop Monte Carlo.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Common options (default 500 trials per cell).
    #[command(flatten)]
    common: common::CommonArgs,
    /// Only the paper's five estimators (4 × 5 × 500 = 10 000 trials by default), without the
    /// tuned TAG-K row.
    #[arg(long)]
    paper_only: bool,
}

fn main() {
    let args: Args = common::parse_args(tagk::sim::experiments::NOISE_SWEEP_TRIALS);
    let mut progress = args.common.progress();
    match run_noise_sweep(&args.common.options(), args.paper_only, &mut progress) {
        Ok(report) => {
            common::print_sweep_summary(&report);
        }
        Err(e) => {
            eprintln!("noise_sweep: {e}");
            std::process::exit(1);
        }
    }
}
