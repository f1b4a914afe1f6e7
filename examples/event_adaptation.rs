//! Adaptation at once (issue #27, item 4): estimators with and without the change detector on
//! their own residual, in the closed-loop simulator's `realistic` profile.
//!
//! `cargo run --release --example event_adaptation -- --help` lists the options. Rows: the
//! tuned TAG-K of Table II (its front end's event windows at 5 noise floors); the same with the
//! change detector (`tagk_core::EventTriggered`: χ² test of every frame against the measured
//! noise of its rows, restart, first estimate solved on a fresh 2-frame window); the same with
//! the learning layer (`tagk_core::Accumulate`), without and with the detector; a tuned KF-low without and
//! with the detector; `nominal` and `oracle`. Columns: success (Table II's rule: 1 cm, 2 s
//! after each event), lost flights, position error over all flights, detection (events with an
//! alarm within 1 s), mean delay from the event to its alarm, false alarms per flight (alarms
//! with no event in the second before them).

use clap::Parser;
use tagk::sim::estimators::{tagk_tuned_realistic, tuned};
use tagk::sim::experiments::table_ii_sweep;
use tagk::sim::{EstimatorKind, EstimatorSpec, ExperimentProfile, SimOutput, SweepObserver};

/// Estimators with and without the change detector, closed loop, `realistic` profile.
#[derive(Debug, Clone, Parser)]
struct Args {
    /// Trials per (noise level, estimator) cell.
    #[arg(long, default_value_t = 100)]
    trials: usize,
    /// Base seed (the README's evaluation seeds are 2025 and 2026).
    #[arg(long, default_value_t = 2025)]
    seed: u64,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Control steps after an event within which an alarm counts as its detection (1 s at 50 Hz).
const DETECTION_WINDOW: usize = 50;

/// Per cell: events, detected events, the sum of their delays [steps], false alarms, flights.
#[derive(Debug, Clone, Copy, Default)]
struct Alarms {
    events: usize,
    detected: usize,
    delay_steps: usize,
    false_alarms: usize,
    flights: usize,
}

/// Progress on stderr, and the alarms of every trial folded per cell.
struct Observer {
    progress: tagk::cli::progress::Progress,
    cells: Vec<Alarms>,
}

impl SweepObserver for Observer {
    fn trial_finished(&self, done: usize, total: usize) {
        self.progress.trial_finished(done, total);
    }

    fn fold_trial(&mut self, cell: usize, _trial: usize, output: &SimOutput) {
        let c = &mut self.cells[cell];
        c.flights += 1;
        let steps: Vec<usize> = output.events.iter().map(|e| e.step).collect();
        for &e in &steps {
            // Events too close to the flight's end to judge are left out.
            if e + DETECTION_WINDOW > output.tracking_errors.len() {
                continue;
            }
            c.events += 1;
            if let Some(a) = output
                .alarms
                .iter()
                .find(|&&a| a >= e && a < e + DETECTION_WINDOW)
            {
                c.detected += 1;
                c.delay_steps += a - e;
            }
        }
        c.false_alarms += output
            .alarms
            .iter()
            .filter(|&&a| !steps.iter().any(|&e| a >= e && a < e + DETECTION_WINDOW))
            .count();
    }

    fn sweep_finished(&mut self) {
        self.progress.sweep_finished();
    }
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args = Args::parse();
    let estimators: Vec<EstimatorSpec> = vec![
        tagk_tuned_realistic(),
        tagk_tuned_realistic().with_change_detector(),
        tagk_tuned_realistic().with_learning(),
        tagk_tuned_realistic()
            .with_change_detector()
            .with_learning(),
        tuned(EstimatorKind::KfLow),
        tuned(EstimatorKind::KfLow).with_change_detector(),
    ];
    let sweep = table_ii_sweep(
        ExperimentProfile::Realistic,
        estimators,
        args.trials,
        args.seed,
    );
    let columns = sweep.estimators.len() + sweep.references.len();
    let mut observer = Observer {
        progress: tagk::cli::progress::Progress::new(!args.quiet),
        cells: vec![Alarms::default(); sweep.noise_levels.len() * columns],
    };
    let result = match sweep.run_with(&mut observer) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("event_adaptation: {e}");
            std::process::exit(1);
        }
    };
    println!(
        "profile realistic, seed {}, {} trials per cell, {:.1} s on {} threads",
        args.seed, result.trials, result.elapsed_s, result.threads
    );
    println!(
        "{:<8} {:<52} {:>9} {:>6} {:>9} {:>9} {:>10} {:>12}",
        "noise",
        "estimator",
        "success%",
        "lost%",
        "pos. cm",
        "detected%",
        "delay ms",
        "false/flight"
    );
    for (cell, c) in result.cells.iter().enumerate() {
        let a = observer.cells[cell];
        let (detected, delay, false_rate) = if matches!(
            c.adaptation,
            tagk::sim::Adaptation::Estimator(s) if s.change_detector
        ) {
            (
                format!("{:.1}", 100.0 * a.detected as f64 / a.events.max(1) as f64),
                format!(
                    "{:.0}",
                    1000.0 * 0.02 * a.delay_steps as f64 / a.detected.max(1) as f64
                ),
                format!("{:.2}", a.false_alarms as f64 / a.flights.max(1) as f64),
            )
        } else {
            ("-".into(), "-".into(), "-".into())
        };
        println!(
            "{:<8} {:<52} {:>9.1} {:>6.1} {:>9.2} {:>9} {:>10} {:>12}",
            c.noise.name(),
            c.label,
            c.success_pct,
            c.aborted_pct,
            c.position_error_all_cm,
            detected,
            delay,
            false_rate
        );
    }
}
