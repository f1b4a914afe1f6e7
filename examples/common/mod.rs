//! What the experiment examples share: the common flags, the progress bar (a
//! `SweepObserver`), and the printing of results. The experiments themselves live in
//! `tagk::sim::experiments` and print nothing.
#![allow(dead_code)]

use std::path::PathBuf;

use tagk::sim::experiments::{ExperimentOptions, ExperimentReport};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, SimError,
};

/// Options every experiment takes.
#[derive(Debug, Clone, clap::Args)]
pub struct CommonArgs {
    /// Trials per (noise level, estimator) cell (each experiment has its own default).
    #[arg(long)]
    pub trials: Option<usize>,
    /// Base seed.
    #[arg(long, default_value_t = 2025)]
    pub seed: u64,
    /// Output folder [default: out/EXPERIMENT/].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rayon threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Parses the example's arguments, with `--help` showing this experiment's default number of
/// trials (`trials_default`, one of the `tagk::sim::experiments::*_TRIALS` constants).
pub fn parse_args<A: clap::Parser>(trials_default: usize) -> A {
    let command = A::command().mut_arg("trials", |a| {
        a.help(format!(
            "Trials per (noise level, estimator) cell [default: {trials_default}]"
        ))
    });
    let matches = command.get_matches();
    A::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

impl CommonArgs {
    /// The experiment options these flags describe.
    pub fn options(&self) -> ExperimentOptions {
        ExperimentOptions {
            trials: self.trials,
            seed: self.seed,
            out: self.out.clone(),
            threads: self.threads,
        }
    }

    /// A progress bar on stderr, hidden with `--quiet`.
    pub fn progress(&self) -> Progress {
        Progress::new(!self.quiet)
    }
}

/// The progress bar on stderr (a sweep observer, or over any count; hidden with `--quiet`
/// and when stderr is not a terminal).
pub use tagk::cli::progress::Progress;

/// Prints a sweep's table and where its files went (the common tail of every experiment).
pub fn print_table(report: &ExperimentReport) {
    print!("{}", report.result.table());
}

/// Prints `results in DIR`.
pub fn print_results_dir(report: &ExperimentReport) {
    println!("results in {}", report.dir.display());
}

/// Prints a Table II sweep: its size and run time, the table, and where its files went.
pub fn print_sweep_summary(report: &ExperimentReport) {
    let r = &report.result;
    println!(
        "Table II: {} trials per cell, {} cells, {:.1} s on {} threads",
        r.trials,
        r.cells.len(),
        r.elapsed_s,
        r.threads
    );
    print_table(report);
    print_results_dir(report);
}

/// The flight of the diagnosis demos: 25 s on the default trajectory with one plant effect
/// hidden, the paper's medium noise, no payload, no adaptation, logged.
pub fn hidden_effect_flight(effect: EffectKind, seed: u64) -> Result<SimConfig, SimError> {
    Ok(SimConfig {
        duration: 25.0,
        seed,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: PlantEffects::only(effect)?,
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    })
}
