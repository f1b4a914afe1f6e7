//! Table III of the TAG-K paper on this machine: per-update time for n in 40..120, m = 30.
//!
//! `cargo run --release --example dimension_sweep -- --help` lists the options; results go
//! to `out/dimension_sweep/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags and prints.

use std::path::PathBuf;

use clap::Parser;
use tagk::sim::experiments::run_dimension_sweep_with_progress;

/// Table III: per-update time for n in 40..120, m = 30, synthetic windows.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Output folder [default: out/dimension_sweep/].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Updates timed per (estimator, n).
    #[arg(long, default_value_t = 2000)]
    updates: usize,
    /// Seed of the synthetic windows (accepted for compatibility: the Table III windows are
    /// generated from their own fixed seed).
    #[arg(long, default_value_t = 2024)]
    seed: u64,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args = Args::parse();
    let bar = tagk::cli::progress::Progress::counting(!args.quiet, 0, "(estimator, n) pairs");
    let result = run_dimension_sweep_with_progress(args.out.as_deref(), args.updates, |d, t| {
        bar.set(d as u64, t as u64);
    });
    bar.finish();
    match result {
        Ok((rows, dir)) => {
            println!(
                "{:<8} {:>5} {:>4} {:>12} {:>12}",
                "estimator", "n", "m", "median [us]", "P95 [us]"
            );
            for r in &rows {
                println!(
                    "{:<8} {:>5} {:>4} {:>12.2} {:>12.2}",
                    r.estimator, r.n, r.m, r.median_us, r.p95_us
                );
            }
            println!("results in {}", dir.display());
        }
        Err(e) => {
            eprintln!("dimension_sweep: {e}");
            std::process::exit(1);
        }
    }
}
