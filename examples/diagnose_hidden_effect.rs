//! The diagnosis loop end to end on a simulated flight with a hidden effect.
//!
//! 1. Fly the simulated Crazyflie (tagk-sim) for 25 s with quadratic drag switched ON in the
//!    plant, the paper's medium sensor noise, and log it as a CSV flight log.
//! 2. Compare the rigid-body model with the log: fit % and residual RMS per wrench channel.
//! 3. See where it fails and which effect is missing (blocked cross-validation ranking).
//! 4. Add the recommended effect and watch the error fall: before/after table.
//!
//! Run: `cargo run --release --example diagnose_hidden_effect [-- --out OUT_DIR]` (with
//! `--out` it also writes the CSV log, the JSON and the HTML report there; `-- --help` lists
//! the options).

use tagk::diagnose::{
    DiagnoseOptions, FlightLog, Model, Signals, add_recommended, diagnosis_table, report_table,
};
mod common;

use tagk::sim::{EffectKind, simulate};

/// The diagnosis loop end to end on a simulated 25 s Crazyflie flight with quadratic drag
/// hidden in the plant: compare, find what is missing, add it, watch the error fall.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Seed of the simulated flight.
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// Also write the CSV log, the JSON and the HTML report into this folder (default: write
    /// nothing).
    #[arg(long, value_name = "DIR")]
    out: Option<std::path::PathBuf>,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("diagnose_hidden_effect", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = <Args as clap::Parser>::parse();
    let out_dir = args.out;

    // 1. A flight with a hidden effect.
    let config = common::hidden_effect_flight(EffectKind::QuadraticDrag, args.seed)?;
    let flight = simulate(&config)?;
    // The simulator hands its samples over as a user's data would arrive: a CSV flight log.
    let mut csv = Vec::new();
    flight.log.write_csv(&mut csv)?;
    let log = FlightLog::from_csv_reader(csv.as_slice())?;
    println!(
        "simulated {} samples with a hidden effect (which one? let the tool tell)\n",
        log.len()
    );

    // 2 + 3. Compare, where it fails, what is missing; 4. add the recommended effect and watch
    // the error fall (the ranking is recomputed for the new model).
    let signals = Signals::from_log(&log)?;
    let opts = DiagnoseOptions::default();
    let report = add_recommended(&signals, &Model::rigid_body(), &opts)?;
    println!("{}", diagnosis_table(&report.before));
    if report.after.is_none() {
        println!("the model is adequate: nothing to add");
        return Ok(());
    }
    println!("{}", report_table(&report));
    if let Some(dir) = out_dir {
        std::fs::create_dir_all(&dir)?;
        std::fs::write(dir.join("flight.csv"), &csv)?;
        std::fs::write(dir.join("diagnosis.json"), report.to_json()?)?;
        let html = tagk::diagnose::html::write_report(&report, &dir.join("report"))?;
        println!(
            "wrote {}, diagnosis.json and {}",
            dir.join("flight.csv").display(),
            html.display()
        );
    }
    Ok(())
}
