//! The diagnosis benchmark of issue #24: simulator flights drawn at random from a seed (path,
//! yaw rate, duration, sensing profile, a payload, 0–3 hidden effects with realistic
//! magnitudes), each diagnosed as `tagk diagnose LOG` does and scored against the simulator's
//! noise-free truth; the table of the targets on stdout.
//!
//! Run: `cargo run --release --example diagnosis_benchmark [-- --flights 300 --json out.json]`
//! (`-- --help` lists the options and their defaults; `--quick` runs a handful of short
//! flights). What is drawn and how each flight is scored: the docs of
//! `tagk::diagnosis_benchmark`.

mod common;

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;
use tagk::diagnosis_benchmark::{
    BenchmarkOptions, DEFAULT_DETECTABLE, DEFAULT_FLIGHTS, DEFAULT_SEED, FlightResult,
    QUICK_FLIGHTS, Summary, replay_flight, run_flight,
};

/// Markers of the generated block in a README (`--readme`).
const BEGIN: &str = "<!-- diagnosis-benchmark: begin";
const END: &str = "<!-- diagnosis-benchmark: end -->";

/// The diagnosis benchmark of issue #24: random simulator flights with hidden effects,
/// diagnosed and scored against the simulator's truth.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Flights [default: 300, or 8 with --quick].
    #[arg(long)]
    flights: Option<usize>,
    /// Seed of every flight.
    #[arg(long, default_value_t = DEFAULT_SEED)]
    seed: u64,
    /// Detectability threshold D: an effect is detectable when its largest channel RMS, after
    /// the rigid body absorbed what it can, is at least D times the channel's noise.
    #[arg(long, default_value_t = DEFAULT_DETECTABLE)]
    detectable: f64,
    /// Short flights (8–12 s; 8 of them unless --flights is given): a quick check of the
    /// machinery.
    #[arg(long)]
    quick: bool,
    /// Write every flight's draw and score, and the summary, as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Write the tables as Markdown to this file.
    #[arg(long, value_name = "FILE")]
    markdown: Option<PathBuf>,
    /// Rewrite the generated benchmark block of this README (between the markers
    /// `<!-- diagnosis-benchmark: begin … -->` and `<!-- diagnosis-benchmark: end -->`).
    #[arg(long, value_name = "FILE")]
    readme: Option<PathBuf>,
    /// Rayon threads [default: all cores]. The results are the same bits at any count.
    #[arg(long)]
    threads: Option<usize>,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
    /// Fly only flight N again, write its log as CSV to `--log` (default `flight-N.csv`) and
    /// print its draw and the `tagk diagnose` command that reproduces its diagnosis.
    #[arg(long, value_name = "N")]
    replay: Option<usize>,
    /// The CSV file of `--replay`.
    #[arg(long, value_name = "FILE", requires = "replay")]
    log: Option<PathBuf>,
}

fn main() -> std::process::ExitCode {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    tagk::cli::terminal::exit_code("diagnosis_benchmark", run())
}

/// The example; an error is printed once by `main`.
fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = <Args as clap::Parser>::parse();
    if !(args.detectable.is_finite() && args.detectable > 0.0) {
        return Err(format!("--detectable {}: must be positive", args.detectable).into());
    }
    let options = BenchmarkOptions {
        seed: args.seed,
        detectable: args.detectable,
        quick: args.quick,
    };
    if let Some(index) = args.replay {
        let flight = replay_flight(&options, index)
            .map_err(|f| format!("flight {index}: {} failed: {}", f.stage, f.message))?;
        let path = args
            .log
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("flight-{index}.csv")));
        flight.log.write_csv_path(&path)?;
        println!("{}", serde_json::to_string_pretty(&flight.spec)?);
        println!("{}", flight.diagnose_command(&path.display().to_string()));
        return Ok(());
    }
    let flights = args.flights.unwrap_or(if args.quick {
        QUICK_FLIGHTS
    } else {
        DEFAULT_FLIGHTS
    });
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = args.threads {
        pool = pool.num_threads(t);
    }
    let pool = pool.build()?;
    let bar = common::Progress::counting(!args.quiet, flights as u64, "flights");
    let simulate_us = AtomicU64::new(0);
    let diagnose_us = AtomicU64::new(0);
    let start = Instant::now();
    let results: Vec<FlightResult> = pool.install(|| {
        (0..flights)
            .into_par_iter()
            .map(|i| {
                let (result, timings) = run_flight(&options, i);
                simulate_us.fetch_add((timings.simulate * 1e6) as u64, Ordering::Relaxed);
                diagnose_us.fetch_add((timings.diagnose * 1e6) as u64, Ordering::Relaxed);
                bar.inc();
                result
            })
            .collect()
    });
    bar.finish();
    let wall = start.elapsed().as_secs_f64();
    let summary = Summary::of(&options, &results);
    let table = summary.markdown();
    print!("{table}");
    let per = |us: &AtomicU64| us.load(Ordering::Relaxed) as f64 * 1e-6 / flights.max(1) as f64;
    eprintln!(
        "{flights} flights in {wall:.1} s on {} threads; per flight: simulate {:.3} s, diagnose {:.3} s (means, each flight on one thread)",
        pool.current_num_threads(),
        per(&simulate_us),
        per(&diagnose_us)
    );
    for r in &results {
        if let Some(f) = &r.failure {
            eprintln!("flight {}: {} failed: {}", r.index, f.stage, f.message);
        }
    }
    let mut flags = Vec::new();
    if args.quick {
        flags.push("--quick".to_string());
    }
    if let Some(n) = args.flights {
        flags.push(format!("--flights {n}"));
    }
    if args.seed != DEFAULT_SEED {
        flags.push(format!("--seed {}", args.seed));
    }
    if args.detectable != DEFAULT_DETECTABLE {
        flags.push(format!("--detectable {}", args.detectable));
    }
    let mut command = "cargo run --release --example diagnosis_benchmark".to_string();
    if !flags.is_empty() {
        command = format!("{command} -- {}", flags.join(" "));
    }
    if let Some(path) = &args.json {
        let json = serde_json::json!({
            "command": command,
            "summary": summary,
            "flights": results,
        });
        std::fs::write(path, serde_json::to_string_pretty(&json)?)?;
    }
    if let Some(path) = &args.markdown {
        std::fs::write(path, &table)?;
    }
    if let Some(path) = &args.readme {
        let text = std::fs::read_to_string(path)?;
        let (Some(b), Some(e)) = (text.find(BEGIN), text.find(END)) else {
            return Err(format!("{}: no `{BEGIN} … -->` … `{END}` block", path.display()).into());
        };
        let after_begin = text[b..].find("-->").map_or(e, |k| b + k + 3);
        if after_begin > e {
            return Err(format!("{}: malformed benchmark markers", path.display()).into());
        }
        let block = format!(
            "\n\n`{}` ({wall:.0} s on {} threads):\n\n{table}\n",
            command,
            pool.current_num_threads()
        );
        let updated = format!("{}{block}{}", &text[..after_begin], &text[e..]);
        std::fs::write(path, updated)?;
    }
    Ok(())
}
