//! Fig. 3 of the TAG-K paper: paths of one figure-8 trial, parameter error over time, position-error CDF.
//!
//! `cargo run --release --example single_trial -- --help` lists the options; results go to
//! `out/single_trial/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.

mod common;

use clap::Parser;
use tagk::cli::noise_parser;
use tagk::sim::NoiseLevel;
use tagk::sim::experiments::run_single_trial;

/// Fig. 3: one figure-8 trial per estimator, error over time, position CDF.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Common options (default 100 trials for the averaged curves and CDFs).
    #[command(flatten)]
    common: common::CommonArgs,
    /// Noise level.
    #[arg(long, value_parser = noise_parser(), default_value = "none")]
    noise: NoiseLevel,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args: Args = common::parse_args(tagk::sim::experiments::ERROR_CURVE_TRIALS);
    let mut progress = args.common.progress();
    match run_single_trial(&args.common.options(), args.noise, &mut progress) {
        Ok(report) => {
            for (label, m) in &report.trials {
                println!(
                    "{:<26} position error {:.3} cm, success {}, aborted {}",
                    label, m.position_error_cm, m.success, m.aborted
                );
            }
            common::print_table(&report.sweep);
            common::print_results_dir(&report.sweep);
        }
        Err(e) => {
            eprintln!("single_trial: {e}");
            std::process::exit(1);
        }
    }
}
