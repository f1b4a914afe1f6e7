//! Table II of the TAG-K paper: RLS-low/high, KF-low/high, TAG-K x 4 noise levels.
//!
//! `cargo run --release --example noise_sweep -- --help` lists the options; results go to
//! `out/noise_sweep/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.

mod common;

use clap::Parser;
use tagk::sim::ExperimentProfile;
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
    /// Sensing and actuation profile: `paper` (ideal, the paper's setting) or `realistic`
    /// (a Crazyflie's sensors and actuators; see `tagk_sim::ExperimentProfile`).
    #[arg(long, default_value = "realistic")]
    profile: ExperimentProfile,
    /// Print only the accuracy table as Markdown (every column a function of the seeds; what
    /// `scripts/table2.sh` puts in the READMEs).
    #[arg(long)]
    markdown: bool,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args: Args = common::parse_args(tagk::sim::experiments::NOISE_SWEEP_TRIALS);
    let mut progress = args.common.progress();
    match run_noise_sweep(
        &args.common.options(),
        args.profile,
        args.paper_only,
        &mut progress,
    ) {
        Ok(report) if args.markdown => {
            let r = &report.result;
            eprintln!(
                "Table II, profile {}: {} trials per cell, {} cells, {:.1} s on {} threads",
                args.profile,
                r.trials,
                r.cells.len(),
                r.elapsed_s,
                r.threads
            );
            print!("{}", r.markdown_accuracy());
        }
        Ok(report) => {
            println!("profile {}", args.profile);
            common::print_sweep_summary(&report);
        }
        Err(e) => {
            eprintln!("noise_sweep: {e}");
            std::process::exit(1);
        }
    }
}
