//! Fig. 4a of the TAG-K paper: baselines with their first post-event estimate replaced by TAG-K's.
//!
//! `cargo run --release --example early_adaptation -- --help` lists the options; results go
//! to `out/early_adaptation/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.

mod common;

use clap::Parser;
use tagk::cli::noise_parser;
use tagk::sim::NoiseLevel;
use tagk::sim::experiments::run_early_adaptation;

/// Fig. 4a: baselines with their first post-event estimate replaced by TAG-K's.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Common options (default 200 trials per cell).
    #[command(flatten)]
    common: common::CommonArgs,
    /// Noise level.
    #[arg(long, value_parser = noise_parser(), default_value = "none")]
    noise: NoiseLevel,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args: Args = common::parse_args(tagk::sim::experiments::EARLY_ADAPTATION_TRIALS);
    let mut progress = args.common.progress();
    match run_early_adaptation(&args.common.options(), args.noise, &mut progress) {
        Ok(report) => {
            common::print_table(&report);
            common::print_results_dir(&report);
        }
        Err(e) => {
            eprintln!("early_adaptation: {e}");
            std::process::exit(1);
        }
    }
}
