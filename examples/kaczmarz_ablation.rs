//! Fig. 4b of the TAG-K paper: RK, TARK, GRK, TAG-K across payload events, and a burn-in sweep.
//!
//! `cargo run --release --example kaczmarz_ablation -- --help` lists the options; results go
//! to `out/kaczmarz_ablation/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.

mod common;

use clap::Parser;
use tagk::cli::noise_parser;
use tagk::sim::NoiseLevel;
use tagk::sim::experiments::run_kaczmarz_ablation;

/// Fig. 4b: RK, TARK, GRK, TAG-K across payload events; TAG-K burn-in sweep.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Common options (default 100 trials per cell).
    #[command(flatten)]
    common: common::CommonArgs,
    /// Noise level.
    #[arg(long, value_parser = noise_parser(), default_value = "medium")]
    noise: NoiseLevel,
    /// Run the Kaczmarz variants in the paper's form (SI units, no stopping tolerance)
    /// instead of the tuned form.
    #[arg(long)]
    paper_form: bool,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args: Args = common::parse_args(tagk::sim::experiments::ERROR_CURVE_TRIALS);
    let mut progress = args.common.progress();
    match run_kaczmarz_ablation(
        &args.common.options(),
        args.noise,
        args.paper_form,
        &mut progress,
    ) {
        Ok(report) => {
            common::print_table(&report.sweep);
            println!("burn-in sweep (TAG-K):");
            for (b, c) in &report.burn_in {
                println!(
                    "  t_b = {:.2} T: position {:.3} cm, parameter error {:.3e}, (t+1) {:.3e}, success {:.1} %",
                    b, c.position_error_cm, c.parameter_error, c.t1_error, c.success_pct
                );
            }
            common::print_results_dir(&report.sweep);
        }
        Err(e) => {
            eprintln!("kaczmarz_ablation: {e}");
            std::process::exit(1);
        }
    }
}
