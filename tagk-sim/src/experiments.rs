//! The experiments behind the root `examples/` (each example only parses its arguments and
//! calls the `run_*` function here): configuration, the Monte Carlo sweep, printed table,
//! CSV/JSON results and PNG/SVG figures in an output folder.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::SimError;
use crate::estimators::{EstimatorKind, EstimatorSpec};
use crate::monte_carlo::{Capture, Sweep, SweepResult};
use crate::plot::{LineChart, Path3, Series, cdf, line_chart, path_chart_3d};
use crate::sim::{Adaptation, NoiseLevel, PayloadSchedule, SimConfig, simulate};
use crate::trajectory::TrajectoryKind;

/// Options every experiment takes.
#[derive(Debug, Clone, clap::Args)]
pub struct CommonArgs {
    /// Trials per (noise level, estimator) cell (each experiment has its own default).
    #[arg(long)]
    pub trials: Option<usize>,
    /// Base seed.
    #[arg(long, default_value_t = 2025)]
    pub seed: u64,
    /// Output folder (default `out/<experiment>/`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rayon threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

impl CommonArgs {
    fn out_dir(&self, name: &str) -> Result<PathBuf, SimError> {
        let dir = self
            .out
            .clone()
            .unwrap_or_else(|| Path::new("out").join(name));
        std::fs::create_dir_all(&dir)?;
        Ok(dir)
    }

    fn run_sweep(&self, sweep: &Sweep) -> Result<SweepResult, SimError> {
        match self.threads {
            Some(n) => rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()?
                .install(|| sweep.run()),
            None => sweep.run(),
        }
    }
}

/// The TAG-K variant this crate recommends: column-equilibrated windows, noise-aware
/// stopping at 3σ and only the actuated rows (see the README's study).
pub fn tagk_tuned() -> EstimatorSpec {
    tuned(EstimatorKind::TagK)
}

/// [`tagk_tuned`]'s options applied to any estimator kind.
pub fn tuned(kind: EstimatorKind) -> EstimatorSpec {
    EstimatorSpec::new(kind)
        .with_scaling()
        .with_noise_tolerance(3.0)
        .with_actuated_rows_only()
}

/// Table II's estimators: the paper's five, plus [`tagk_tuned`].
pub fn table_ii_estimators() -> Vec<EstimatorSpec> {
    let mut v: Vec<EstimatorSpec> = EstimatorKind::TABLE_II
        .iter()
        .map(|k| EstimatorSpec::new(*k))
        .collect();
    v.push(tagk_tuned());
    v
}

/// Payload attach and removal times of the error-over-time experiments [s].
const EVENTS: [f64; 2] = [5.0, 13.0];

/// A sweep at one noise level with the payload attached and removed at [`EVENTS`] and the
/// mean parameter-error curve captured (Fig. 3 and Fig. 4b).
fn error_curve_sweep(estimators: Vec<EstimatorSpec>, c: &CommonArgs, noise: NoiseLevel) -> Sweep {
    let mut sweep = Sweep::new(estimators, c.trials.unwrap_or(100), c.seed);
    sweep.noise_levels = vec![noise];
    sweep.base.payload = PayloadSchedule::ProtocolAt {
        attach: EVENTS[0],
        remove: EVENTS[1],
    };
    sweep.capture = Capture {
        traces: 0,
        error_curve: true,
    };
    sweep.progress = !c.quiet;
    sweep
}

/// Plots the mean parameter error over time of `cells` (control step `dt` [s]) with the
/// payload events marked, as `parameter_error_time.{png,svg}` in `dir`.
fn parameter_error_chart<'a>(
    dir: &Path,
    title: String,
    cells: impl Iterator<Item = &'a crate::CellSummary>,
    dt: f64,
) -> Result<(), SimError> {
    line_chart(
        &dir.join("parameter_error_time"),
        &LineChart {
            title,
            x_label: "time [s]".into(),
            y_label: "|theta_hat - theta|".into(),
            log_y: true,
            series: cells
                .map(|c| Series {
                    label: c.label.clone(),
                    points: c
                        .error_curve
                        .iter()
                        .enumerate()
                        .map(|(i, e)| (i as f64 * dt, *e))
                        .collect(),
                })
                .collect(),
            markers: EVENTS.to_vec(),
        },
    )
}

/// Arguments of `noise_sweep` (Table II).
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Table II: every estimator x 4 noise levels, closed-loop Monte Carlo")]
pub struct NoiseSweepArgs {
    /// Common options (default 500 trials per cell).
    #[command(flatten)]
    pub common: CommonArgs,
    /// Only the paper's five estimators (4 × 5 × 500 = 10 000 trials by default), without the
    /// tuned TAG-K row.
    #[arg(long)]
    pub paper_only: bool,
}

fn by_noise(result: &SweepResult, f: impl Fn(&crate::CellSummary) -> f64) -> Vec<Series> {
    let mut labels: Vec<String> = Vec::new();
    for c in &result.cells {
        if !labels.contains(&c.label) {
            labels.push(c.label.clone());
        }
    }
    labels
        .iter()
        .map(|l| Series {
            label: l.clone(),
            points: result
                .cells
                .iter()
                .filter(|c| &c.label == l)
                .enumerate()
                .map(|(i, c)| (i as f64, f(c)))
                .collect(),
        })
        .collect()
}

fn cdf_series(result: &SweepResult, noise: NoiseLevel) -> Vec<Series> {
    result
        .cells
        .iter()
        .filter(|c| c.noise == noise)
        .map(|c| Series {
            label: c.label.clone(),
            points: cdf(&c.position_errors),
        })
        .collect()
}

fn write_common(result: &SweepResult, dir: &Path) -> Result<(), SimError> {
    result.write_csv(&dir.join("table.csv"))?;
    result.write_json(&dir.join("results.json"))?;
    std::fs::write(dir.join("table.md"), result.markdown())?;
    Ok(())
}

/// Runs Table II: prints the table and writes `table.csv`, `table.md`, `results.json` and
/// figures (metric vs noise level, position-error CDFs) to the output folder.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_noise_sweep(args: &NoiseSweepArgs) -> Result<SweepResult, SimError> {
    let c = &args.common;
    let dir = c.out_dir("noise_sweep")?;
    let mut estimators = table_ii_estimators();
    if args.paper_only {
        estimators.pop();
    }
    let mut sweep = Sweep::new(estimators, c.trials.unwrap_or(500), c.seed);
    sweep.progress = !c.quiet;
    let result = c.run_sweep(&sweep)?;
    println!(
        "Table II: {} trials per cell, {} cells, {:.1} s on {} threads",
        result.trials,
        result.cells.len(),
        result.elapsed_s,
        result.threads
    );
    print!("{}", result.table());
    write_common(&result, &dir)?;
    let x = "noise level (0 none, 1 low, 2 medium, 3 high)";
    for (name, title, ylab, log, f) in [
        (
            "position_error",
            "Mean position error",
            "position error [cm]",
            true,
            (|c: &crate::CellSummary| c.position_error_cm) as fn(&crate::CellSummary) -> f64,
        ),
        ("success", "Success rate", "success [%]", false, |c| {
            c.success_pct
        }),
        ("aborted", "Abort rate", "aborted [%]", false, |c| {
            c.aborted_pct
        }),
        (
            "parameter_error",
            "Parameter error",
            "|theta_hat - theta|",
            true,
            |c| c.parameter_error,
        ),
        (
            "t1_error",
            "(t+1) error",
            "|theta_hat - theta| after event",
            true,
            |c| c.t1_error,
        ),
    ] {
        line_chart(
            &dir.join(name),
            &LineChart {
                title: title.into(),
                x_label: x.into(),
                y_label: ylab.into(),
                log_y: log,
                series: by_noise(&result, f),
                markers: vec![],
            },
        )?;
    }
    for noise in NoiseLevel::ALL {
        line_chart(
            &dir.join(format!("cdf_{}", noise.name())),
            &LineChart {
                title: format!("Position-error CDF, noise {}", noise.name()),
                x_label: "mean position error of a trial [cm]".into(),
                y_label: "fraction of trials (aborted excluded)".into(),
                log_y: false,
                series: cdf_series(&result, noise),
                markers: vec![],
            },
        )?;
    }
    println!("results in {}", dir.display());
    Ok(result)
}

/// Arguments of `single_trial` (Fig. 3).
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Fig. 3: one figure-8 trial per estimator, error over time, position CDF")]
pub struct SingleTrialArgs {
    /// Common options (default 100 trials for the averaged curves and CDFs).
    #[command(flatten)]
    pub common: CommonArgs,
    /// Noise level.
    #[arg(long, value_enum, default_value_t = NoiseLevel::None)]
    pub noise: NoiseLevel,
}

/// Runs Fig. 3: (a) the 3-D path of every estimator on one figure-8 trial with payload
/// events (and aborts) marked, (b) the parameter error over time averaged over trials
/// (events at 5 s and 13 s), (c) the CDF of position error.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_single_trial(args: &SingleTrialArgs) -> Result<SweepResult, SimError> {
    let c = &args.common;
    let dir = c.out_dir("single_trial")?;
    let estimators = table_ii_estimators();
    // (a) One trial, every estimator.
    let mut paths = Vec::new();
    let mut reference = None;
    for spec in &estimators {
        let cfg = SimConfig {
            seed: c.seed,
            trajectory: TrajectoryKind::Figure8,
            noise: args.noise,
            adaptation: Adaptation::Estimator(*spec),
            payload: PayloadSchedule::ProtocolAt {
                attach: EVENTS[0],
                remove: EVENTS[1],
            },
            record_trace: true,
            ..SimConfig::default()
        };
        let out = simulate(&cfg)?;
        let pts: Vec<(f64, f64, f64)> = out
            .trace
            .iter()
            .map(|t| (t.position[0], t.position[1], t.position[2]))
            .collect();
        let mut marks: Vec<(f64, f64, f64)> = out
            .events
            .iter()
            .filter_map(|e| pts.get(e.step).copied())
            .collect();
        if out.metrics.aborted
            && let Some(p) = pts.last()
        {
            marks.push(*p);
        }
        println!(
            "{:<26} position error {:.3} cm, success {}, aborted {}",
            spec.label(),
            out.metrics.position_error_cm,
            out.metrics.success,
            out.metrics.aborted
        );
        if reference.is_none() {
            reference = Some(Path3 {
                label: "reference".into(),
                points: out
                    .trace
                    .iter()
                    .map(|t| (t.reference[0], t.reference[1], t.reference[2]))
                    .collect(),
                marks: vec![],
            });
        }
        paths.push(Path3 {
            label: spec.label(),
            points: pts,
            marks,
        });
    }
    if let Some(r) = reference {
        paths.insert(0, r);
    }
    path_chart_3d(
        &dir.join("paths_3d"),
        "Figure-8 trial: paths (x: payload events, aborts)",
        &paths,
    )?;
    // (b), (c) Averaged over trials.
    let mut sweep = error_curve_sweep(estimators, c, args.noise);
    sweep.trajectory = Some(TrajectoryKind::Figure8);
    let result = c.run_sweep(&sweep)?;
    print!("{}", result.table());
    write_common(&result, &dir)?;
    parameter_error_chart(
        &dir,
        format!(
            "Parameter error over time (mean of {} trials)",
            result.trials
        ),
        result.cells.iter(),
        sweep.base.control_dt,
    )?;
    line_chart(
        &dir.join("position_error_cdf"),
        &LineChart {
            title: "Position-error CDF".into(),
            x_label: "mean position error of a trial [cm]".into(),
            y_label: "fraction of trials (aborted excluded)".into(),
            log_y: false,
            series: cdf_series(&result, args.noise),
            markers: vec![],
        },
    )?;
    println!("results in {}", dir.display());
    Ok(result)
}

/// Arguments of `early_adaptation` (Fig. 4a).
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Fig. 4a: baselines with their first post-event estimate replaced by TAG-K's")]
pub struct EarlyAdaptationArgs {
    /// Common options (default 200 trials per cell).
    #[command(flatten)]
    pub common: CommonArgs,
    /// Noise level.
    #[arg(long, value_enum, default_value_t = NoiseLevel::None)]
    pub noise: NoiseLevel,
}

/// Runs Fig. 4a: every baseline alone and with early TAG-K adaptation; position-error CDFs
/// before and after, and the table.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_early_adaptation(args: &EarlyAdaptationArgs) -> Result<SweepResult, SimError> {
    let c = &args.common;
    let dir = c.out_dir("early_adaptation")?;
    let tuned = tagk_tuned();
    let mut estimators = Vec::new();
    for k in [
        EstimatorKind::RlsLow,
        EstimatorKind::RlsHigh,
        EstimatorKind::KfLow,
        EstimatorKind::KfHigh,
    ] {
        let base = EstimatorSpec::new(k);
        estimators.push(base);
        let mut early = base.with_early_tagk();
        early.burn_in = tuned.burn_in;
        estimators.push(early);
    }
    let mut sweep = Sweep::new(estimators, c.trials.unwrap_or(200), c.seed);
    sweep.noise_levels = vec![args.noise];
    sweep.progress = !c.quiet;
    let result = c.run_sweep(&sweep)?;
    print!("{}", result.table());
    write_common(&result, &dir)?;
    line_chart(
        &dir.join("position_error_cdf"),
        &LineChart {
            title: "Position-error CDF: baselines alone and with early TAG-K".into(),
            x_label: "mean position error of a trial [cm]".into(),
            y_label: "fraction of trials (aborted excluded)".into(),
            log_y: false,
            series: cdf_series(&result, args.noise),
            markers: vec![],
        },
    )?;
    println!("results in {}", dir.display());
    Ok(result)
}

/// Arguments of `kaczmarz_ablation` (Fig. 4b and the burn-in sweep).
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Fig. 4b: RK, TARK, GRK, TAG-K across payload events; TAG-K burn-in sweep")]
pub struct KaczmarzAblationArgs {
    /// Common options (default 100 trials per cell).
    #[command(flatten)]
    pub common: CommonArgs,
    /// Noise level.
    #[arg(long, value_enum, default_value_t = NoiseLevel::Medium)]
    pub noise: NoiseLevel,
    /// Run the Kaczmarz variants in the paper's form (SI units, no stopping tolerance)
    /// instead of the tuned form.
    #[arg(long)]
    pub paper_form: bool,
}

/// Runs Fig. 4b (parameter error over time of RK, TARK, GRK, TAG-K, events at 5 s and 13 s)
/// and the TAG-K burn-in sweep `t_b/T ∈ {0, 0.25, 0.5, 0.75, 0.9}`.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_kaczmarz_ablation(args: &KaczmarzAblationArgs) -> Result<SweepResult, SimError> {
    let c = &args.common;
    let dir = c.out_dir("kaczmarz_ablation")?;
    let form = |k: EstimatorKind| {
        let s = EstimatorSpec::new(k);
        if args.paper_form { s } else { tuned(k) }
    };
    let mut estimators: Vec<EstimatorSpec> =
        EstimatorKind::KACZMARZ.iter().map(|k| form(*k)).collect();
    for b in [0.0, 0.25, 0.75, 0.9] {
        estimators.push(form(EstimatorKind::TagK).with_burn_in(b));
    }
    let sweep = error_curve_sweep(estimators, c, args.noise);
    let result = c.run_sweep(&sweep)?;
    print!("{}", result.table());
    write_common(&result, &dir)?;
    parameter_error_chart(
        &dir,
        format!(
            "Kaczmarz variants across payload events ({} trials)",
            result.trials
        ),
        result.cells.iter().take(4),
        sweep.base.control_dt,
    )?;
    let burn: Vec<(f64, &crate::CellSummary)> = result
        .cells
        .iter()
        .filter(|c| c.estimator.kind == EstimatorKind::TagK)
        .map(|c| (c.estimator.burn_in, c))
        .collect();
    let mut burn_sorted = burn.clone();
    burn_sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!("burn-in sweep (TAG-K):");
    for (b, c) in &burn_sorted {
        println!(
            "  t_b = {:.2} T: position {:.3} cm, parameter error {:.3e}, (t+1) {:.3e}, success {:.1} %",
            b, c.position_error_cm, c.parameter_error, c.t1_error, c.success_pct
        );
    }
    line_chart(
        &dir.join("burn_in_sweep"),
        &LineChart {
            title: "TAG-K burn-in sweep".into(),
            x_label: "burn-in t_b / T".into(),
            y_label: "mean parameter error".into(),
            log_y: true,
            series: vec![
                Series {
                    label: "parameter error".into(),
                    points: burn_sorted
                        .iter()
                        .map(|(b, c)| (*b, c.parameter_error))
                        .collect(),
                },
                Series {
                    label: "(t+1) error".into(),
                    points: burn_sorted.iter().map(|(b, c)| (*b, c.t1_error)).collect(),
                },
            ],
            markers: vec![],
        },
    )?;
    println!("results in {}", dir.display());
    Ok(result)
}

/// Arguments of `dimension_sweep` (Table III).
#[derive(Debug, Clone, clap::Parser)]
#[command(about = "Table III: per-update time for n in 40..120, m = 30, synthetic windows")]
pub struct DimensionSweepArgs {
    /// Output folder (default `out/dimension_sweep/`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Updates timed per (estimator, n).
    #[arg(long, default_value_t = 2000)]
    pub updates: usize,
    /// Seed of the synthetic windows.
    #[arg(long, default_value_t = 2024)]
    pub seed: u64,
}

/// One row of Table III.
#[derive(Debug, Clone, Serialize)]
pub struct TimingRow {
    /// Estimator.
    pub estimator: String,
    /// Parameter dimension.
    pub n: usize,
    /// Window rows.
    pub m: usize,
    /// Median update time [µs].
    pub median_us: f64,
    /// 95th percentile [µs].
    pub p95_us: f64,
}

fn build_n(
    kind: EstimatorKind,
    n: usize,
    m: usize,
) -> Result<Box<dyn tagk_core::OnlineEstimator<f64> + Send>, SimError> {
    use tagk_baselines::{KalmanFilter, Rls};
    use tagk_core::{KaczmarzConfig, TagK};
    Ok(match kind {
        EstimatorKind::RlsLow => Box::new(Rls::rls_low(n, m)?),
        EstimatorKind::RlsHigh => Box::new(Rls::rls_high(n, m)?),
        EstimatorKind::KfLow => Box::new(KalmanFilter::kf_low(n, m)?),
        EstimatorKind::KfHigh => Box::new(KalmanFilter::kf_high(n, m)?),
        _ => Box::new(TagK::<f64, Vec<f64>>::new(
            n,
            m,
            KaczmarzConfig::default().with_seed(1),
        )?),
    })
}

/// Runs Table III on this machine: per-update wall-clock time (median, P95) of RLS, KF and
/// TAG-K for `n ∈ {40, 60, 80, 100, 120}`, `m = 30`, on the bench's synthetic windows (one
/// thread). Writes `table.csv`, `table.json` and a figure.
///
/// # Errors
/// I/O or plotting errors.
pub fn run_dimension_sweep(args: &DimensionSweepArgs) -> Result<Vec<TimingRow>, SimError> {
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join("dimension_sweep"));
    std::fs::create_dir_all(&dir)?;
    let m = 30;
    let kinds = [
        EstimatorKind::RlsLow,
        EstimatorKind::KfLow,
        EstimatorKind::TagK,
    ];
    let mut rows = Vec::new();
    for n in [40, 60, 80, 100, 120] {
        let stream = tagk_core::SyntheticWindows::for_table(n, m).take_windows(64);
        for kind in kinds {
            let mut est = build_n(kind, n, m)?;
            let mut times = crate::metrics::UpdateTimes::new();
            for i in 0..args.updates.max(1) {
                let (a, b) = &stream[i % stream.len()];
                let t = Instant::now();
                let r = est.update(a, b);
                let us = t.elapsed().as_secs_f64() * 1e6;
                r?;
                times.record(us);
            }
            rows.push(TimingRow {
                estimator: match kind {
                    EstimatorKind::RlsLow => "RLS".into(),
                    EstimatorKind::KfLow => "KF".into(),
                    _ => "TAG-K".into(),
                },
                n,
                m,
                median_us: times.median(),
                p95_us: times.p95(),
            });
        }
    }
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
    let mut w = csv::Writer::from_path(dir.join("table.csv"))?;
    for r in &rows {
        w.serialize(r)?;
    }
    w.flush()?;
    std::fs::write(dir.join("table.json"), serde_json::to_string_pretty(&rows)?)?;
    let names = ["RLS", "KF", "TAG-K"];
    line_chart(
        &dir.join("update_time"),
        &LineChart {
            title: format!("Per-update time, m = {m} (median)"),
            x_label: "parameter dimension n".into(),
            y_label: "update time [us]".into(),
            log_y: true,
            series: names
                .iter()
                .map(|nm| Series {
                    label: (*nm).into(),
                    points: rows
                        .iter()
                        .filter(|r| r.estimator == *nm)
                        .map(|r| (r.n as f64, r.median_us))
                        .collect(),
                })
                .collect(),
            markers: vec![],
        },
    )?;
    println!("results in {}", dir.display());
    Ok(rows)
}
