//! The experiments behind the root `examples/`: configuration, the Monte Carlo sweep, CSV/JSON
//! results and PNG/SVG figures in an output folder. Each `run_*` function returns its results
//! and prints nothing; the examples parse their arguments, attach their observers (a
//! progress bar) and print the results.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::SimError;
use crate::estimators::{EstimatorKind, EstimatorSpec};
pub use crate::estimators::{
    table_ii_estimators, table_ii_estimators_for, tagk_tuned, tagk_tuned_realistic, tuned,
};
use crate::monte_carlo::{ErrorCurves, Sweep, SweepObserver, SweepResult};
use crate::plot::{ChartSeries, LineChart, Path3, cdf_steps, line_chart, path_chart_3d};
use crate::sim::{
    Adaptation, ExperimentProfile, NoiseLevel, PayloadSchedule, SimConfig, TrialMetrics, simulate,
};
use crate::trajectory::TrajectoryKind;

/// Options every experiment takes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExperimentOptions {
    /// Trials per (noise level, estimator) cell (`None`: each experiment's own default).
    pub trials: Option<usize>,
    /// Base seed (default 2025).
    pub seed: u64,
    /// Output folder (`None`: `out/<experiment>/`).
    pub out: Option<PathBuf>,
    /// Rayon threads (`None`: all cores).
    pub threads: Option<usize>,
}

impl Default for ExperimentOptions {
    fn default() -> Self {
        Self {
            trials: None,
            seed: 2025,
            out: None,
            threads: None,
        }
    }
}

/// What a sweep experiment produced: its results and the folder its files went to.
#[derive(Debug, Clone)]
pub struct ExperimentReport {
    /// The sweep's results.
    pub result: SweepResult,
    /// The output folder.
    pub dir: PathBuf,
}

impl ExperimentOptions {
    fn out_dir(&self, name: &str) -> Result<PathBuf, SimError> {
        let dir = self
            .out
            .clone()
            .unwrap_or_else(|| Path::new("out").join(name));
        std::fs::create_dir_all(&dir)?;
        Ok(dir)
    }

    fn run_sweep<O: SweepObserver + ?Sized>(
        &self,
        sweep: &Sweep,
        observer: &mut O,
    ) -> Result<SweepResult, SimError> {
        match self.threads {
            Some(n) => rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()?
                .install(|| sweep.run_with(observer)),
            None => sweep.run_with(observer),
        }
    }
}

/// Payload attach and removal times of the error-over-time experiments \[s\].
const EVENTS: [f64; 2] = [5.0, 13.0];

/// Trials per cell of the error-curve sweeps ([`run_single_trial`], [`run_kaczmarz_ablation`])
/// when [`ExperimentOptions::trials`] is not given.
pub const ERROR_CURVE_TRIALS: usize = 100;
/// Trials per cell of [`run_noise_sweep`] (Table II) when none are given.
pub const NOISE_SWEEP_TRIALS: usize = 500;
/// Trials per cell of [`run_early_adaptation`] when none are given.
pub const EARLY_ADAPTATION_TRIALS: usize = 200;

/// A sweep at one noise level with the payload attached and removed at [`EVENTS`] (Fig. 3
/// and Fig. 4b; run it with an [`ErrorCurves`] observer).
fn error_curve_sweep(
    estimators: Vec<EstimatorSpec>,
    c: &ExperimentOptions,
    noise: NoiseLevel,
) -> Sweep {
    let mut sweep = Sweep::new(estimators, c.trials.unwrap_or(ERROR_CURVE_TRIALS), c.seed);
    sweep.noise_levels = vec![noise];
    sweep.base.payload = PayloadSchedule::ProtocolAt {
        attach: EVENTS[0],
        remove: EVENTS[1],
    };
    sweep
}

/// y-axis label of the parameter-error figures (docs/CONVENTIONS.md §5: the norm over the
/// 10 SI entries of θ).
const PARAMETER_ERROR: &str = "parameter error ‖Δθ‖₂ [SI units]";

/// The mean parameter error over time of each `(label, curve)` (one value per control step
/// `dt` \[s\]), the payload events marked: `parameter_error_time`.
fn parameter_error_chart(title: String, curves: Vec<(String, Vec<f64>)>, dt: f64) -> LineChart {
    LineChart {
        title,
        x_label: "time t [s]".into(),
        y_label: PARAMETER_ERROR.into(),
        log_y: true,
        series: curves
            .into_iter()
            .map(|(label, curve)| ChartSeries {
                label,
                points: curve
                    .iter()
                    .enumerate()
                    .map(|(i, e)| (i as f64 * dt, *e))
                    .collect(),
            })
            .collect(),
        markers: EVENTS.to_vec(),
        ..LineChart::default()
    }
}

/// The labels and mean error curves of the first `cells` cells of `result`.
fn labelled_curves(
    result: &SweepResult,
    curves: &ErrorCurves,
    cells: usize,
) -> Vec<(String, Vec<f64>)> {
    result
        .cells
        .iter()
        .take(cells)
        .enumerate()
        .map(|(i, c)| (c.label.clone(), curves.curve(i)))
        .collect()
}

/// Category names of the noise-level axis: the level and its velocity noise σ in cm/s
/// (`low (0.05)`).
fn noise_categories() -> Vec<String> {
    NoiseLevel::ALL
        .map(|n| {
            let cm_s = format!("{:.3}", n.sigma_velocity() * 100.0);
            let cm_s = cm_s.trim_end_matches('0').trim_end_matches('.');
            format!("{} ({cm_s})", n.name())
        })
        .to_vec()
}

/// x-axis label of the noise-level charts.
const NOISE_AXIS: &str = "noise level (velocity noise σ [cm/s])";

fn by_noise(result: &SweepResult, f: impl Fn(&crate::CellSummary) -> f64) -> Vec<ChartSeries> {
    let mut labels: Vec<String> = Vec::new();
    for c in &result.cells {
        if !labels.contains(&c.label) {
            labels.push(c.label.clone());
        }
    }
    labels
        .iter()
        .map(|l| ChartSeries {
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

/// The position-error CDF of every cell of `result` at one noise level, as steps on a log
/// x axis (the errors of good and failing estimators differ by decades).
fn cdf_chart(title: String, result: &SweepResult, noise: NoiseLevel) -> LineChart {
    let series = result
        .cells
        .iter()
        .filter(|c| c.noise == noise)
        .map(|c| ChartSeries {
            label: c.label.clone(),
            points: cdf_steps(&c.position_errors),
        })
        .collect();
    LineChart {
        title,
        x_label: "mean position error of a trial ē [cm]".into(),
        y_label: "fraction of trials, aborted excluded [–]".into(),
        log_x: true,
        series,
        ..LineChart::default()
    }
}

/// A metric figure of [`run_noise_sweep`]: file stem, title, y-axis label, log axis, value.
type Metric = (
    &'static str,
    &'static str,
    &'static str,
    bool,
    fn(&crate::CellSummary) -> f64,
);

/// The nine figures of [`run_noise_sweep`], by file stem: five metrics against the noise
/// level, then the position-error CDF at each level.
fn noise_sweep_charts(result: &SweepResult) -> Vec<(String, LineChart)> {
    let metrics: [Metric; 5] = [
        (
            "position_error",
            "Mean position error",
            "position error [cm]",
            true,
            |c| c.position_error_cm,
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
            PARAMETER_ERROR,
            true,
            |c| c.parameter_error,
        ),
        (
            "t1_error",
            "(t+1) error: first estimate after an event",
            "(t+1) error ‖Δθ‖₂ [SI units]",
            true,
            |c| c.t1_error,
        ),
    ];
    let mut charts: Vec<(String, LineChart)> = metrics
        .into_iter()
        .map(|(name, title, ylab, log, f)| {
            (
                name.to_string(),
                LineChart {
                    title: title.into(),
                    x_label: NOISE_AXIS.into(),
                    y_label: ylab.into(),
                    log_y: log,
                    series: by_noise(result, f),
                    x_categories: noise_categories(),
                    ..LineChart::default()
                },
            )
        })
        .collect();
    for noise in NoiseLevel::ALL {
        charts.push((
            format!("cdf_{}", noise.name()),
            cdf_chart(
                format!("Position-error CDF, noise {}", noise.name()),
                result,
                noise,
            ),
        ));
    }
    charts
}

/// One cell of `results.json`: the cell's summary and its mean error curve (empty when the
/// experiment did not record one).
#[derive(Serialize)]
struct CellJson<'a> {
    #[serde(flatten)]
    cell: &'a crate::CellSummary,
    error_curve: Vec<f64>,
}

/// `results.json`: the sweep's results with the error curves of `curves` in their cells.
#[derive(Serialize)]
struct ResultJson<'a> {
    cells: Vec<CellJson<'a>>,
    trials: usize,
    seed: u64,
    elapsed_s: f64,
    threads: usize,
}

/// Writes `table.csv`, `results.json` (with the error curves, if any) and `table.md`.
fn write_common(
    result: &SweepResult,
    curves: Option<&ErrorCurves>,
    dir: &Path,
) -> Result<(), SimError> {
    result.write_csv(&dir.join("table.csv"))?;
    let json = ResultJson {
        cells: result
            .cells
            .iter()
            .enumerate()
            .map(|(i, cell)| CellJson {
                cell,
                error_curve: curves.map_or_else(Vec::new, |c| c.curve(i)),
            })
            .collect(),
        trials: result.trials,
        seed: result.seed,
        elapsed_s: result.elapsed_s,
        threads: result.threads,
    };
    let f = std::io::BufWriter::new(std::fs::File::create(dir.join("results.json"))?);
    serde_json::to_writer_pretty(f, &json)?;
    std::fs::write(dir.join("table.md"), result.markdown())?;
    Ok(())
}

/// The Table II sweep of `profile`: `estimators` plus the `nominal` and `oracle` reference
/// columns, 4 noise levels, `trials` per cell from base seed `seed`.
pub fn table_ii_sweep(
    profile: ExperimentProfile,
    estimators: Vec<EstimatorSpec>,
    trials: usize,
    seed: u64,
) -> Sweep {
    let mut sweep = Sweep::new(estimators, trials, seed);
    profile.apply(&mut sweep.base);
    sweep.references = vec![Adaptation::Nominal, Adaptation::Oracle];
    sweep
}

/// The Markdown Table II of `profile` that `scripts/table2.sh` writes: issue #27's headline
/// layout ([`SweepResult::markdown_headline`]) for the real vehicles' profiles, the accuracy
/// layout ([`SweepResult::markdown_accuracy`]) for `paper` and `realistic`.
pub fn table_ii_markdown(profile: ExperimentProfile, result: &SweepResult) -> String {
    if profile.is_vehicle() {
        result.markdown_headline()
    } else {
        result.markdown_accuracy()
    }
}

/// Integral gains of the success curve over the gain ([`gain_curve`]) \[1/s\].
pub const GAIN_CURVE: [f64; 4] = [0.25, 0.5, 1.0, 2.0];

/// Success as a curve over the controller's integral gain (issue #27): for each gain of
/// [`GAIN_CURVE`], the tuned TAG-K, the tuned KF (if `profile` has one), `nominal` and `oracle`
/// at the medium noise level, `trials` each from `seed`. Returns a Markdown table: lost
/// flights and success at each threshold of [`SweepResult::SUCCESS_CURVE_CM`].
///
/// # Errors
/// A sweep's error.
pub fn gain_curve(
    profile: ExperimentProfile,
    trials: usize,
    seed: u64,
) -> Result<String, SimError> {
    let mut estimators = vec![tagk_tuned_realistic()];
    estimators.extend(
        crate::estimators::tuned_baselines(profile)
            .into_iter()
            .filter(|e| e.kind == EstimatorKind::KfLow),
    );
    let mut s = String::from(
        "| k_i \\[1/s\\] | estimator | lost flights % | success % at 0.5 / 1 / 2 / 4 cm |\n|---:|---|---:|---:|\n",
    );
    for gain in GAIN_CURVE {
        let mut sweep = table_ii_sweep(profile, estimators.clone(), trials, seed);
        sweep.noise_levels = vec![NoiseLevel::Medium];
        sweep.base.flight_stack.position_integral_gain = gain;
        let r = sweep.run()?;
        for c in &r.cells {
            let curve: Vec<String> = SweepResult::SUCCESS_CURVE_CM
                .iter()
                .map(|t| format!("{:.1}", c.success_at(*t)))
                .collect();
            s.push_str(&format!(
                "| {gain} | {} | {:.1} | {} |\n",
                c.label,
                c.aborted_pct,
                curve.join(" / ")
            ));
        }
    }
    Ok(s)
}

/// Runs Table II in `profile` (default 500 trials per cell; `paper_only`: the paper's five
/// estimators, without the tuned TAG-K row; the `nominal` and `oracle` reference rows always)
/// and writes `table.csv`, `table.md`, `table_accuracy.md`, `results.json` and figures (metric
/// vs noise level, position-error CDFs) to the output folder.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_noise_sweep<O: SweepObserver + ?Sized>(
    c: &ExperimentOptions,
    profile: ExperimentProfile,
    paper_only: bool,
    observer: &mut O,
) -> Result<ExperimentReport, SimError> {
    let dir = c.out_dir("noise_sweep")?;
    let mut estimators = table_ii_estimators_for(profile);
    if paper_only {
        estimators.truncate(EstimatorKind::TABLE_II.len());
    }
    let sweep = table_ii_sweep(
        profile,
        estimators,
        c.trials.unwrap_or(NOISE_SWEEP_TRIALS),
        c.seed,
    );
    let result = c.run_sweep(&sweep, observer)?;
    write_common(&result, None, &dir)?;
    std::fs::write(
        dir.join("table_accuracy.md"),
        table_ii_markdown(profile, &result),
    )?;
    for (name, chart) in noise_sweep_charts(&result) {
        line_chart(&dir.join(name), &chart)?;
    }
    Ok(ExperimentReport { result, dir })
}

/// What [`run_single_trial`] produced.
#[derive(Debug, Clone)]
pub struct SingleTrialReport {
    /// (a) The one figure-8 trial of every estimator: its label and metrics.
    pub trials: Vec<(String, TrialMetrics)>,
    /// (b), (c) The sweep averaged over trials, and the output folder.
    pub sweep: ExperimentReport,
}

/// Runs Fig. 3 at `noise`:
/// - (a) the 3-D path of every estimator on one figure-8 trial, with payload events (and
///   aborts) marked;
/// - (b) the parameter error over time, averaged over trials (default 100; events at 5 s and
///   13 s);
/// - (c) the CDF of position error.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_single_trial<O: SweepObserver + ?Sized>(
    c: &ExperimentOptions,
    noise: NoiseLevel,
    observer: &mut O,
) -> Result<SingleTrialReport, SimError> {
    let dir = c.out_dir("single_trial")?;
    let estimators = table_ii_estimators();
    // (a) One trial, every estimator.
    let mut trials = Vec::new();
    let mut paths = Vec::new();
    let mut reference = None;
    for spec in &estimators {
        let cfg = SimConfig {
            seed: c.seed,
            trajectory: TrajectoryKind::Figure8,
            noise,
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
        trials.push((spec.label(), out.metrics.clone()));
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
    let mut sweep = error_curve_sweep(estimators, c, noise);
    sweep.trajectory = Some(TrajectoryKind::Figure8);
    let mut curves = ErrorCurves::new();
    let result = c.run_sweep(&sweep, &mut (&mut curves, observer))?;
    write_common(&result, Some(&curves), &dir)?;
    line_chart(
        &dir.join("parameter_error_time"),
        &parameter_error_chart(
            format!(
                "Parameter error over time (mean of {} trials)",
                result.trials
            ),
            labelled_curves(&result, &curves, result.cells.len()),
            sweep.base.control_dt,
        ),
    )?;
    line_chart(
        &dir.join("position_error_cdf"),
        &cdf_chart("Position-error CDF".into(), &result, noise),
    )?;
    Ok(SingleTrialReport {
        trials,
        sweep: ExperimentReport { result, dir },
    })
}

/// Runs Fig. 4a at `noise`: every baseline alone and with early TAG-K adaptation (default 200
/// trials per cell); position-error CDFs before and after, and the table.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_early_adaptation<O: SweepObserver + ?Sized>(
    c: &ExperimentOptions,
    noise: NoiseLevel,
    observer: &mut O,
) -> Result<ExperimentReport, SimError> {
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
    let mut sweep = Sweep::new(
        estimators,
        c.trials.unwrap_or(EARLY_ADAPTATION_TRIALS),
        c.seed,
    );
    sweep.noise_levels = vec![noise];
    let result = c.run_sweep(&sweep, observer)?;
    write_common(&result, None, &dir)?;
    line_chart(
        &dir.join("position_error_cdf"),
        &cdf_chart(
            "Position-error CDF: baselines alone and with early TAG-K".into(),
            &result,
            noise,
        ),
    )?;
    Ok(ExperimentReport { result, dir })
}

/// What [`run_kaczmarz_ablation`] produced.
#[derive(Debug, Clone)]
pub struct KaczmarzAblationReport {
    /// The TAG-K burn-in sweep: `(t_b / T, cell)` by increasing burn-in.
    pub burn_in: Vec<(f64, crate::CellSummary)>,
    /// The sweep and the output folder.
    pub sweep: ExperimentReport,
}

/// Runs Fig. 4b at `noise` (parameter error over time of RK, TARK, GRK, TAG-K, events at 5 s
/// and 13 s, default 100 trials per cell) and the TAG-K burn-in sweep
/// `t_b/T ∈ {0, 0.25, 0.5, 0.75, 0.9}`; `paper_form` runs the Kaczmarz variants in the
/// paper's form (SI units, no stopping tolerance) instead of the tuned form.
///
/// # Errors
/// Configuration, I/O or plotting errors.
pub fn run_kaczmarz_ablation<O: SweepObserver + ?Sized>(
    c: &ExperimentOptions,
    noise: NoiseLevel,
    paper_form: bool,
    observer: &mut O,
) -> Result<KaczmarzAblationReport, SimError> {
    let dir = c.out_dir("kaczmarz_ablation")?;
    let form = |k: EstimatorKind| {
        let s = EstimatorSpec::new(k);
        if paper_form { s } else { tuned(k) }
    };
    let mut estimators: Vec<EstimatorSpec> =
        EstimatorKind::KACZMARZ.iter().map(|k| form(*k)).collect();
    for b in [0.0, 0.25, 0.75, 0.9] {
        estimators.push(form(EstimatorKind::TagK).with_burn_in(b));
    }
    let sweep = error_curve_sweep(estimators, c, noise);
    let mut curves = ErrorCurves::new();
    let result = c.run_sweep(&sweep, &mut (&mut curves, observer))?;
    write_common(&result, Some(&curves), &dir)?;
    line_chart(
        &dir.join("parameter_error_time"),
        &parameter_error_chart(
            format!(
                "Kaczmarz variants across payload events ({} trials)",
                result.trials
            ),
            labelled_curves(&result, &curves, 4),
            sweep.base.control_dt,
        ),
    )?;
    let burn: Vec<(f64, &crate::CellSummary)> = result
        .cells
        .iter()
        .filter_map(|c| match c.adaptation {
            Adaptation::Estimator(spec) if spec.kind == EstimatorKind::TagK => {
                Some((spec.burn_in, c))
            }
            _ => None,
        })
        .collect();
    let mut burn_sorted = burn.clone();
    burn_sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    line_chart(&dir.join("burn_in_sweep"), &burn_in_chart(&burn_sorted))?;
    let burn_in = burn_sorted
        .into_iter()
        .map(|(b, c)| (b, c.clone()))
        .collect();
    Ok(KaczmarzAblationReport {
        burn_in,
        sweep: ExperimentReport { result, dir },
    })
}

/// The TAG-K burn-in sweep: mean and (t+1) parameter error against `t_b / T`.
fn burn_in_chart(burn: &[(f64, &crate::CellSummary)]) -> LineChart {
    LineChart {
        title: "TAG-K burn-in sweep".into(),
        x_label: "burn-in fraction t_b / T [–]".into(),
        y_label: "mean parameter error ‖Δθ‖₂ [SI units]".into(),
        log_y: true,
        series: vec![
            ChartSeries {
                label: "parameter error".into(),
                points: burn.iter().map(|(b, c)| (*b, c.parameter_error)).collect(),
            },
            ChartSeries {
                label: "(t+1) error".into(),
                points: burn.iter().map(|(b, c)| (*b, c.t1_error)).collect(),
            },
        ],
        ..LineChart::default()
    }
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
    /// Median update time \[µs\].
    pub median_us: f64,
    /// 95th percentile \[µs\].
    pub p95_us: f64,
}

/// Runs Table III on this machine: per-update wall-clock time (median, P95) of RLS, KF and
/// TAG-K for `n ∈ {40, 60, 80, 100, 120}`, `m = 30`, on the bench's synthetic windows (one
/// thread), `updates` timed updates per (estimator, n). Writes `table.csv`, `table.json` and
/// a figure to `out` (default `out/dimension_sweep/`); returns the rows and the folder.
///
/// # Errors
/// I/O or plotting errors.
pub fn run_dimension_sweep(
    out: Option<&Path>,
    updates: usize,
) -> Result<(Vec<TimingRow>, PathBuf), SimError> {
    run_dimension_sweep_with_progress(out, updates, |_, _| {})
}

/// [`run_dimension_sweep`], calling `progress(done, total)` after each (estimator, n) pair
/// is timed: `done` of `total` pairs. The rows are the same as without it.
///
/// # Errors
/// As [`run_dimension_sweep`].
pub fn run_dimension_sweep_with_progress(
    out: Option<&Path>,
    updates: usize,
    mut progress: impl FnMut(usize, usize),
) -> Result<(Vec<TimingRow>, PathBuf), SimError> {
    let dir = out.map_or_else(
        || Path::new("out").join("dimension_sweep"),
        Path::to_path_buf,
    );
    std::fs::create_dir_all(&dir)?;
    let m = 30;
    let kinds = [
        EstimatorKind::RlsLow,
        EstimatorKind::KfLow,
        EstimatorKind::TagK,
    ];
    let mut rows = Vec::new();
    let dims = [40, 60, 80, 100, 120];
    let total = dims.len() * kinds.len();
    for n in dims {
        let stream = tagk_core::SyntheticWindows::for_table(n, m).take_windows(64);
        for kind in kinds {
            let mut est = crate::estimators::build_kind(
                kind,
                n,
                crate::estimators::DEFAULT_BURN_IN,
                m,
                1,
                0.0,
            )?;
            let mut times = crate::metrics::UpdateTimes::new();
            for i in 0..updates.max(1) {
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
            progress(rows.len(), total);
        }
    }
    let mut w = csv::Writer::from_path(dir.join("table.csv"))?;
    for r in &rows {
        w.serialize(r)?;
    }
    w.flush()?;
    std::fs::write(dir.join("table.json"), serde_json::to_string_pretty(&rows)?)?;
    line_chart(&dir.join("update_time"), &update_time_chart(&rows, m))?;
    Ok((rows, dir))
}

/// Table III's figure: the median update time of RLS, KF and TAG-K against `n` (window `m`).
fn update_time_chart(rows: &[TimingRow], m: usize) -> LineChart {
    LineChart {
        title: format!("Per-update time, m = {m} (median)"),
        x_label: "parameter dimension n [–]".into(),
        y_label: "update time [µs]".into(),
        log_y: true,
        series: ["RLS", "KF", "TAG-K"]
            .iter()
            .map(|nm| ChartSeries {
                label: (*nm).into(),
                points: rows
                    .iter()
                    .filter(|r| r.estimator == *nm)
                    .map(|r| (r.n as f64, r.median_us))
                    .collect(),
            })
            .collect(),
        ..LineChart::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CellSummary;
    use crate::plot::check::{covers, edges_blank};
    use crate::plot::{PNG_SCALE, chart_axes, render_line_chart, render_paths_3d};

    /// A synthetic cell: the errors of issue #30's figures, by noise level `k` and row `j`.
    fn cell(k: usize, j: usize, label: &str) -> CellSummary {
        let noise = NoiseLevel::ALL[k];
        let (pos, perr) = match label {
            "oracle" => (0.2 + 0.05 * k as f64, f64::NAN),
            "nominal" => (1.05 + 0.03 * k as f64, f64::NAN),
            "TAG-K" if k == 3 => (22.7, 2.4e-3),
            l if l.starts_with("TAG-K (") => (0.81 + 0.02 * k as f64, 2.0e-3 + 1e-4 * k as f64),
            _ => (2.0 + 0.1 * j as f64, 4.0e-3 + 3e-4 * j as f64),
        };
        CellSummary {
            noise,
            adaptation: Adaptation::Nominal,
            label: label.into(),
            trials: 8,
            position_error_cm: pos,
            position_error_all_cm: pos,
            position_error_all_se: 0.01,
            parameter_error_se: 1e-5,
            t1_error_clean: 1.5 * perr,
            t1_error_mixed: 2.5 * perr,
            t1_error_se: 1e-5,
            t1_mixed_pct: 50.0,
            success_paper_pct: 100.0,
            parameter_error: perr,
            rel_mass: 0.1,
            rel_first_moment: 0.1,
            rel_inertia: 0.1,
            t1_error: 2.0 * perr,
            success_pct: if label == "oracle" {
                100.0
            } else {
                12.5 * j as f64
            },
            success_after_update_pct: 100.0,
            aborted_pct: 0.0,
            update_median_us: 3.0,
            update_p95_us: 5.0,
            settle_errors: vec![0.5; 8],
            position_errors: (0..8)
                .map(|i| {
                    if i == 3 {
                        f64::NAN
                    } else {
                        pos * (0.8 + 0.05 * i as f64)
                    }
                })
                .collect(),
        }
    }

    const LABELS: [&str; 8] = [
        "RLS-low",
        "RLS-high",
        "KF-low",
        "KF-high",
        "TAG-K",
        "TAG-K (scaled, tol 3σ, fz+τ rows, events 5σ)",
        "nominal",
        "oracle",
    ];

    fn sweep_result() -> SweepResult {
        SweepResult {
            cells: (0..4)
                .flat_map(|k| LABELS.iter().enumerate().map(move |(j, l)| cell(k, j, l)))
                .collect(),
            trials: 8,
            seed: 1,
            elapsed_s: 1.0,
            threads: 1,
        }
    }

    /// `[min, max]` of the values a chart can draw, straight from its series.
    fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
        values
            .filter(|v| v.is_finite() && (!log || *v > 0.0))
            .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)))
    }

    /// The chart's labelled ticks hold its data on both axes, both axis names carry a unit,
    /// and it renders at the PNG's scale with nothing running off the figure.
    fn check_chart(name: &str, chart: &LineChart) {
        let axes = chart_axes(chart);
        let pts = || chart.series.iter().flat_map(|s| s.points.iter());
        let (ylo, yhi) = range(pts().map(|p| p.1), chart.log_y);
        covers(&axes.y, ylo, yhi).unwrap_or_else(|e| panic!("{name}, y axis: {e}"));
        let (xlo, xhi) = range(pts().map(|p| p.0), chart.log_x);
        if chart.x_categories.is_empty() {
            covers(&axes.x, xlo, xhi).unwrap_or_else(|e| panic!("{name}, x axis: {e}"));
        } else {
            let names: Vec<&str> = axes.x.labelled.iter().map(|(_, l)| l.as_str()).collect();
            assert_eq!(names, chart.x_categories, "{name}");
            assert!(xlo >= 0.0 && xhi <= (names.len() - 1) as f64, "{name}");
        }
        for label in [&chart.x_label, &chart.y_label] {
            let unit = label
                .split_once('[')
                .is_some_and(|(_, u)| u.contains(']') && !u.starts_with(']'));
            assert!(unit, "{name}: no unit in {label:?}");
        }
        let r = render_line_chart(chart, PNG_SCALE).unwrap();
        assert_eq!((r.width, r.height), (1800, 1120));
        assert!(
            edges_blank(&r, 2 * PNG_SCALE),
            "{name}: drawn off the figure"
        );
    }

    #[test]
    fn every_figure_labels_its_data_and_renders() {
        let result = sweep_result();
        let charts = noise_sweep_charts(&result);
        assert_eq!(charts.len(), 9);
        for (name, chart) in &charts {
            check_chart(name, chart);
        }
        // The CDFs are staircases from 0 to 1.
        for (name, chart) in charts.iter().filter(|(n, _)| n.starts_with("cdf")) {
            for s in &chart.series {
                let p = &s.points;
                assert_eq!((p[0].1, p[p.len() - 1].1), (0.0, 1.0), "{name}");
                assert!(p.windows(2).all(|w| w[0].0 == w[1].0 || w[0].1 == w[1].1));
            }
        }
        check_chart(
            "position_error_cdf",
            &cdf_chart("cdf".into(), &result, NoiseLevel::High),
        );
        let curves: Vec<(String, Vec<f64>)> = LABELS[..4]
            .iter()
            .enumerate()
            .map(|(j, l)| {
                let curve = (0..2000)
                    .map(|i| match i {
                        0..500 => 6.5e-9,
                        500..510 => 1.3e-2,
                        510..1300 => 1e-4 * (1.0 + j as f64),
                        _ => 3.4e-6 * (1.0 + 3.0 * j as f64),
                    })
                    .collect();
                (l.to_string(), curve)
            })
            .collect();
        check_chart(
            "parameter_error_time",
            &parameter_error_chart("error".into(), curves, 0.01),
        );
        let tagk: Vec<(f64, CellSummary)> = [0.0, 0.25, 0.5, 0.75, 0.9]
            .iter()
            .map(|b| {
                let mut c = cell(1, 5, LABELS[5]);
                c.parameter_error = 2.9e-5 - 1e-6 * b;
                c.t1_error = 4.0e-5 - 4e-6 * b;
                (*b, c)
            })
            .collect();
        let burn: Vec<(f64, &CellSummary)> = tagk.iter().map(|(b, c)| (*b, c)).collect();
        check_chart("burn_in_sweep", &burn_in_chart(&burn));
        let rows: Vec<TimingRow> = [40, 60, 80, 100, 120]
            .iter()
            .flat_map(|n| {
                [("RLS", 0.0037), ("KF", 0.0036), ("TAG-K", 0.0011)].map(|(e, k)| TimingRow {
                    estimator: e.into(),
                    n: *n,
                    m: 30,
                    median_us: k * (*n as f64).powf(1.8) / 0.5,
                    p95_us: 0.0,
                })
            })
            .collect();
        check_chart("update_time", &update_time_chart(&rows, 30));
    }

    #[test]
    fn the_path_figure_labels_its_data_and_renders() {
        let paths: Vec<Path3> = LABELS
            .iter()
            .enumerate()
            .map(|(j, l)| Path3 {
                label: l.to_string(),
                points: (0..400)
                    .map(|i| {
                        let t = i as f64 * 0.0157;
                        (
                            0.3 + 0.7 * t.sin(),
                            0.45 + 0.25 * (2.0 * t).sin(),
                            1.3 + 0.01 * j as f64,
                        )
                    })
                    .collect(),
                marks: vec![(0.3, 0.45, 1.3)],
            })
            .collect();
        let axes = crate::plot::paths_3d_axes(&paths);
        for (i, t) in axes.iter().enumerate() {
            let coord = |p: &(f64, f64, f64)| [p.0, p.1, p.2][i];
            let (lo, hi) = range(paths.iter().flat_map(|p| p.points.iter().map(coord)), false);
            covers(t, lo, hi).unwrap_or_else(|e| panic!("axis {i}: {e}"));
        }
        let r = render_paths_3d("paths", &paths, PNG_SCALE).unwrap();
        assert_eq!((r.width, r.height), (1800, 1400));
        assert!(edges_blank(&r, 2 * PNG_SCALE));
    }
}
