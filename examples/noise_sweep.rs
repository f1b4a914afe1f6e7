//! Table II of the TAG-K paper: the paper's five estimators, the tuned TAG-K and (in the real
//! vehicles' profiles) the fairly tuned baselines, x 4 noise levels.
//!
//! `cargo run --release --example noise_sweep -- --help` lists the options; results go to
//! `out/noise_sweep/` unless `--out` says otherwise. The experiment lives in
//! `tagk::sim::experiments`; this example parses flags, shows progress and prints.
//!
//! Its other modes rerun the committed tuning procedures (issue #27) on the tuning seed:
//! `--tune` (the rows' measured noise and the KF/RLS noise models), `--tune-controller` (the
//! integral gain, on payload-free flights), `--gain-curve` (success over the integral gain).

mod common;

use clap::Parser;
use tagk::sim::experiments::{gain_curve, run_noise_sweep, table_ii_markdown};
use tagk::sim::tuning::{
    TUNING_LEVELS, baseline_candidates, measure_row_noise, tune, tune_integral_gain,
};
use tagk::sim::{EstimatorKind, ExperimentProfile};

/// Table II: every estimator x 4 noise levels, closed-loop Monte Carlo.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Common options (default 500 trials per cell).
    #[command(flatten)]
    common: common::CommonArgs,
    /// Only the paper's five estimators (4 × 5 × 500 = 10 000 trials by default), without the
    /// tuned rows.
    #[arg(long)]
    paper_only: bool,
    /// Sensing and actuation profile: `cf21-brushless` (a Crazyflie 2.1 Brushless, eRPM
    /// telemetry), `cf21` (a brushed Crazyflie 2.1, PWM commands), `realistic` (issue #14's,
    /// 1 kHz averaged telemetry) or `paper` (ideal, the paper's setting); see
    /// `tagk_sim::ExperimentProfile`.
    #[arg(long, default_value = "cf21-brushless")]
    profile: ExperimentProfile,
    /// Print only the table as Markdown (every column a function of the seeds; what
    /// `scripts/table2.sh` puts in the README).
    #[arg(long)]
    markdown: bool,
    /// Rerun the baselines' tuning: measure the rows' noise at the tuning levels, score every
    /// KF and RLS candidate behind the tuned front end, print the chosen ones (use
    /// `--seed 7`, the tuning seed; `--trials` per level, default 60).
    #[arg(long)]
    tune: bool,
    /// Rerun the integral gain's tuning on payload-free `nominal` flights (`--trials` per
    /// level, default 40).
    #[arg(long)]
    tune_controller: bool,
    /// Print success as a curve over the integral gain (Markdown; `--trials` per cell,
    /// default 100, medium noise).
    #[arg(long)]
    gain_curve: bool,
}

fn tune_baselines(args: &Args) -> Result<(), tagk::sim::SimError> {
    let seed = args.common.seed;
    let trials = args.common.trials.unwrap_or(60);
    // The noise at the middle of the tuning levels sets the candidates' σ_R multiples
    // (they are multiples of the stated row noise, so they carry over to every level).
    for level in TUNING_LEVELS {
        let rows = measure_row_noise(args.profile, level, seed, 10)?;
        println!(
            "profile {} level {}: measured σ f_z {:.3e} N, τ {:.3e} / {:.3e} / {:.3e} N m; stated m₀σ_a {:.3e} N",
            args.profile,
            level.name(),
            rows.force_z,
            rows.torque[0],
            rows.torque[1],
            rows.torque[2],
            rows.stated
        );
    }
    let rows = measure_row_noise(args.profile, TUNING_LEVELS[1], seed, 10)?;
    for kind in [EstimatorKind::KfLow, EstimatorKind::RlsLow] {
        let outcome = tune(args.profile, baseline_candidates(kind, &rows), trials, seed)?;
        for (i, s) in outcome.scores.iter().enumerate() {
            println!(
                "{} {:<70} lost {:>5.1} %  position {:.3} cm",
                if i == outcome.chosen { "*" } else { " " },
                s.label,
                s.aborted_pct,
                s.position_error_cm
            );
        }
        println!("chosen: {:?}", outcome.scores[outcome.chosen].spec.filter);
    }
    Ok(())
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args: Args = common::parse_args(tagk::sim::experiments::NOISE_SWEEP_TRIALS);
    if args.tune {
        if let Err(e) = tune_baselines(&args) {
            eprintln!("noise_sweep: {e}");
            std::process::exit(1);
        }
        return;
    }
    if args.tune_controller {
        let gains = [0.25, 0.5, 1.0, 2.0];
        let trials = args.common.trials.unwrap_or(40);
        match tune_integral_gain(args.profile, &gains, trials, args.common.seed) {
            Ok((scores, chosen)) => {
                for (i, s) in scores.iter().enumerate() {
                    println!(
                        "{} k_i {:<5} lost {:>5.1} %  position {:.3} cm",
                        if i == chosen { "*" } else { " " },
                        s.gain,
                        s.aborted_pct,
                        s.position_error_cm
                    );
                }
            }
            Err(e) => {
                eprintln!("noise_sweep: {e}");
                std::process::exit(1);
            }
        }
        return;
    }
    if args.gain_curve {
        let trials = args.common.trials.unwrap_or(100);
        match gain_curve(args.profile, trials, args.common.seed) {
            Ok(table) => print!("{table}"),
            Err(e) => {
                eprintln!("noise_sweep: {e}");
                std::process::exit(1);
            }
        }
        return;
    }
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
            print!("{}", table_ii_markdown(args.profile, r));
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
