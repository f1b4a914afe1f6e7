//! Reads a flight log (the project's CSV format) and prints its size, how it is sampled (gaps
//! where and how long, irregular steps) and the time and memory the reader took: the reader's
//! share of a `tagk diagnose` run.
//!
//! ```text
//! cargo run --release --example log_sampling -- flight.csv
//! /usr/bin/time -v target/release/examples/log_sampling flight.csv   # peak memory
//! ```

use std::path::PathBuf;

use tagk::dynamics::log::FlightLog;

/// Reads a flight log (the project's CSV format) and prints its size, how it is sampled (gaps,
/// irregular steps) and the time the reader took.
#[derive(Debug, clap::Parser)]
struct Args {
    /// The flight log (CSV, docs/CONVENTIONS.md §6).
    log: PathBuf,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args = <Args as clap::Parser>::parse();
    let path = args.log.display().to_string();
    let start = std::time::Instant::now();
    let log = match FlightLog::from_csv_path(&path) {
        Ok(log) => log,
        Err(e) => return tagk::cli::terminal::report_error("log_sampling", &e),
    };
    let read = start.elapsed().as_secs_f64();
    let columns = 20
        + 3 * usize::from(log.accel.is_some())
        + 3 * usize::from(log.omega_dot.is_some())
        + 4 * usize::from(log.rotor_speeds.is_some())
        + log.extra.len();
    println!(
        "{path}: {} rows, {columns} columns ({:.0} MB of f64) read in {read:.2} s",
        log.len(),
        (log.len() * columns * 8) as f64 / 1e6
    );
    println!("{}", log.sampling());
    std::process::ExitCode::SUCCESS
}
