//! The main demo: the most complete thing tagk does today, on built-in defaults.
//!
//! 1. **Closed-loop payload flights.** A simulated Crazyflie 2.1 flies the paper's reference
//!    trajectories, picks up an unknown payload and drops it, while each estimator (RLS, Kalman
//!    filter, TAG-K as published and TAG-K tuned) feeds an LQR that is redesigned after every
//!    accepted estimate: a small Monte Carlo run of the paper's Table II at all four noise
//!    levels (`examples/noise_sweep.rs` runs the full 500 trials per cell).
//! 2. **Model diagnosis.** A flight with a physical effect hidden in the plant is logged in the
//!    flight-log CSV format; the diagnosis tool compares the rigid-body model with it, says
//!    where it fails and which effect is missing, adds it and shows the error fall.
//!
//! ```text
//! cargo run --release --example demo [-- --trials 20 --out out/demo]
//! ```

use tagk::diagnose::report::{diagnosis_table, report_table};
use tagk::diagnose::{DiagnoseOptions, FlightLog, Model, Signals, add_recommended};
mod common;

use clap::Parser;
use tagk::sim::experiments::{ExperimentOptions, run_noise_sweep};
use tagk::sim::{EffectKind, simulate};

/// Options of the demo.
#[derive(clap::Parser)]
struct DemoArgs {
    /// Closed-loop trials per (noise level, estimator) cell.
    #[arg(long, default_value_t = 20)]
    trials: usize,
    /// Output folder for tables, figures, the flight log and the diagnosis report.
    #[arg(long, default_value = "out/demo")]
    out: std::path::PathBuf,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("demo", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = DemoArgs::parse();
    std::fs::create_dir_all(&args.out)?;

    println!(
        "== 1. Closed-loop payload flights: {} trials per cell ==\n",
        args.trials
    );
    let options = ExperimentOptions {
        trials: Some(args.trials),
        seed: 2025,
        out: Some(args.out.join("flights")),
        threads: None,
    };
    let flights = run_noise_sweep(
        &options,
        tagk::sim::ExperimentProfile::Paper,
        false,
        &mut common::Progress::new(!args.quiet),
    )?;
    common::print_sweep_summary(&flights);

    println!("\n== 2. Model diagnosis on a flight with a hidden effect ==\n");
    let flight = simulate(&common::hidden_effect_flight(
        EffectKind::QuadraticDrag,
        42,
    )?)?;
    // The simulator and the diagnosis tool meet where a user's own data would: a flight log.
    let log_path = args.out.join("flight.csv");
    flight.log.write_csv_path(&log_path)?;
    let log = FlightLog::from_csv_path(&log_path)?;
    println!(
        "logged {} samples to {} (the hidden effect is for the tool to find)\n",
        log.len(),
        log_path.display()
    );
    let signals = Signals::from_log(&log)?;
    let opts = DiagnoseOptions::default();
    let report = add_recommended(&signals, &Model::rigid_body(), &opts)?;
    println!("{}", diagnosis_table(&report.before));
    let Some(missing) = report.with.first().cloned() else {
        println!("the model is adequate: nothing to add");
        return Ok(());
    };
    println!("{}", report_table(&report));
    let html = tagk::diagnose::html::write_report(&report, &args.out.join("report"))?;
    println!(
        "\nfigures and tables: {}; the same diagnosis from the command line: \
         `cargo run --release -- diagnose {} --with {missing}`; report: {}",
        args.out.display(),
        log_path.display(),
        html.display()
    );
    Ok(())
}
