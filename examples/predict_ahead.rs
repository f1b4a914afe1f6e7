//! Predict ahead with the identified model: the README's error-vs-horizon table.
//!
//! 1. Fly the simulated Crazyflie for 25 s with linear drag hidden in the plant and the
//!    paper's medium noise, and diagnose the log: the staircase rigid body → + effects.
//! 2. Keep one model file per staircase step (`ModelFile::steps`).
//! 3. Fly a second flight (another seed: another path phase, start and noise) and predict it
//!    k steps ahead with each model from every sample (`k_step_prediction`).
//! 4. Print the mean errors per horizon as a Markdown table between markers.
//!
//! Run: `cargo run --release --example predict_ahead` (`-- --help` lists the options).

mod common;

use tagk::diagnose::{
    DiagnosisPlan, ModelContext, ModelFile, Signals, default_horizons, k_step_prediction,
};
use tagk::sim::{EffectKind, simulate};

/// The README's table of k-step prediction errors: each staircase step's model, identified
/// on one flight, predicting another.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Seed of the flight the model is identified on (the scored flight has the next seed).
    #[arg(long, default_value_t = 42)]
    seed: u64,
    /// Longest horizon [steps].
    #[arg(long, default_value_t = 50)]
    horizon: usize,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("predict_ahead", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = <Args as clap::Parser>::parse();
    let fly = |seed| -> Result<_, Box<dyn std::error::Error>> {
        let config = common::hidden_effect_flight(EffectKind::LinearDrag, seed)?;
        Ok(simulate(&config)?.log)
    };
    let report = DiagnosisPlan::new().log(fly(args.seed)?).run()?;
    let models = ModelFile::steps(&report, &ModelContext::default());
    let scored = Signals::from_log(&fly(args.seed + 1)?)?;
    let horizons = default_horizons(args.horizon);
    let predictions = models
        .iter()
        .map(|m| k_step_prediction(&scored, m, &horizons))
        .collect::<Result<Vec<_>, _>>()?;
    println!("<!-- predict-ahead:begin -->");
    println!(
        "Identified on seed {}, predicting seed {} (25 s, medium noise, linear drag hidden). Mean error norms; one column per staircase model:",
        args.seed,
        args.seed + 1
    );
    for (k, m) in models.iter().enumerate() {
        println!("{}. `{}`", k + 1, m.label);
    }
    println!();
    let quantities = [
        "position (m)",
        "velocity (m/s)",
        "attitude (rad)",
        "body rate (rad/s)",
    ];
    let mut header = String::from("| h | t (s) |");
    let mut rule = String::from("|---:|---:|");
    for q in quantities {
        for k in 0..models.len() {
            header.push_str(&format!(" {q} {} |", k + 1));
            rule.push_str("---:|");
        }
    }
    println!("{header}\n{rule}");
    for (row, h) in horizons.iter().enumerate() {
        let e0 = &predictions[0].horizons[row];
        let mut line = format!("| {h} | {:.2} |", *h as f64 * e0.dt);
        for q in 0..4 {
            for p in &predictions {
                let e = &p.horizons[row];
                let v = [e.position, e.velocity, e.attitude, e.body_rate][q];
                line.push_str(&format!(" {v:.2e} |"));
            }
        }
        println!("{line}");
    }
    println!("<!-- predict-ahead:end -->");
    Ok(())
}
