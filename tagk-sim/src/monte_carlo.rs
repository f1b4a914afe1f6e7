//! The one Monte Carlo driver behind every experiment, and the observers that plug into it.
//!
//! A sweep flies `trials` closed-loop trials for every (noise level, estimator) cell. Trial
//! `i` of noise level `j` gets the seed `trial_seed(seed, j, i)` and the trajectory
//! `TrajectoryKind::ALL[i % 5]`, the same for every estimator (paired comparison). Trials run
//! in parallel with rayon, in chunks. Each chunk's trials are folded into the cell aggregates,
//! and handed to the [`SweepObserver`], **in trial order**. So every number except wall-clock
//! update times is identical at any thread count. Memory stays bounded by the chunk size, plus
//! one position error per trial for the CDFs and whatever the observers keep.
//!
//! Observers add what an experiment needs beyond the aggregates: [`ErrorCurves`] (the mean
//! parameter error on the control-step grid), [`Traces`] (full per-step traces of the first
//! trials), a progress display (the examples' indicatif bar), or anything else. Combine
//! several with a tuple: `sweep.run_with(&mut (&mut curves, &mut traces))`.

use std::sync::atomic::{AtomicUsize, Ordering};

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::metrics::UpdateTimes;
use crate::sim::{Adaptation, NoiseLevel, SimConfig, SimOutput, TraceSample, simulate};
use crate::trajectory::TrajectoryKind;
use crate::{EstimatorSpec, SimError};

/// Watches a [`Sweep`]: which trials record their traces, progress as trials finish, and every
/// trial's output in trial order.
///
/// `Send + Sync` because the driver asks [`wants_trace`](Self::wants_trace) and reports
/// [`trial_finished`](Self::trial_finished) from its rayon worker threads (in any order);
/// [`fold_trial`](Self::fold_trial) runs on the calling thread in trial order, so whatever
/// an observer computes from it is identical at any thread count.
pub trait SweepObserver: Send + Sync {
    /// Whether trial `trial` of cell `cell` records its per-control-step trace
    /// ([`SimOutput::trace`]) for [`fold_trial`](Self::fold_trial). Default: no.
    fn wants_trace(&self, cell: usize, trial: usize) -> bool {
        let _ = (cell, trial);
        false
    }

    /// A trial finished on a worker thread: `done` trials of `total` so far (any order).
    fn trial_finished(&self, done: usize, total: usize) {
        let _ = (done, total);
    }

    /// Trial `trial` of cell `cell` (cells noise-major: `level * estimators + estimator`)
    /// with its output; called on the calling thread, in trial order.
    fn fold_trial(&mut self, cell: usize, trial: usize, output: &SimOutput) {
        let _ = (cell, trial, output);
    }

    /// The sweep ended (after the last [`fold_trial`](Self::fold_trial)), successfully or not.
    fn sweep_finished(&mut self) {}
}

/// The observer that observes nothing.
impl SweepObserver for () {}

impl<T: SweepObserver + ?Sized> SweepObserver for &mut T {
    fn wants_trace(&self, cell: usize, trial: usize) -> bool {
        (**self).wants_trace(cell, trial)
    }
    fn trial_finished(&self, done: usize, total: usize) {
        (**self).trial_finished(done, total);
    }
    fn fold_trial(&mut self, cell: usize, trial: usize, output: &SimOutput) {
        (**self).fold_trial(cell, trial, output);
    }
    fn sweep_finished(&mut self) {
        (**self).sweep_finished();
    }
}

/// Two observers as one (nest tuples for more).
impl<A: SweepObserver, B: SweepObserver> SweepObserver for (A, B) {
    fn wants_trace(&self, cell: usize, trial: usize) -> bool {
        self.0.wants_trace(cell, trial) || self.1.wants_trace(cell, trial)
    }
    fn trial_finished(&self, done: usize, total: usize) {
        self.0.trial_finished(done, total);
        self.1.trial_finished(done, total);
    }
    fn fold_trial(&mut self, cell: usize, trial: usize, output: &SimOutput) {
        self.0.fold_trial(cell, trial, output);
        self.1.fold_trial(cell, trial, output);
    }
    fn sweep_finished(&mut self) {
        self.0.sweep_finished();
        self.1.sweep_finished();
    }
}

/// The mean parameter error `‖θ̂ − θ‖₂` per control step over every trial of each cell
/// (Fig. 3b / 4b curves): step `i` averages the finite errors of the trials that flew it.
#[derive(Debug, Clone, Default)]
pub struct ErrorCurves {
    sums: Vec<Vec<f64>>,
    counts: Vec<Vec<usize>>,
}

impl ErrorCurves {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// The mean error curve of cell `cell` (empty if it had no trial).
    pub fn curve(&self, cell: usize) -> Vec<f64> {
        match (self.sums.get(cell), self.counts.get(cell)) {
            (Some(s), Some(n)) => s.iter().zip(n).map(|(s, n)| mean(*s, *n)).collect(),
            _ => Vec::new(),
        }
    }
}

impl SweepObserver for ErrorCurves {
    fn wants_trace(&self, _cell: usize, _trial: usize) -> bool {
        true
    }

    fn fold_trial(&mut self, cell: usize, _trial: usize, output: &SimOutput) {
        if output.trace.is_empty() {
            return;
        }
        if self.sums.len() <= cell {
            self.sums.resize(cell + 1, Vec::new());
            self.counts.resize(cell + 1, Vec::new());
        }
        let (sum, n) = (&mut self.sums[cell], &mut self.counts[cell]);
        if sum.len() < output.trace.len() {
            sum.resize(output.trace.len(), 0.0);
            n.resize(output.trace.len(), 0);
        }
        for (i, t) in output.trace.iter().enumerate() {
            if t.parameter_error.is_finite() {
                sum[i] += t.parameter_error;
                n[i] += 1;
            }
        }
    }
}

/// The full per-control-step traces of the first `per_cell` trials of every cell.
#[derive(Debug, Clone, Default)]
pub struct Traces {
    per_cell: usize,
    traces: Vec<Vec<Vec<TraceSample>>>,
}

impl Traces {
    /// Keeps the traces of trials `0..per_cell` of every cell.
    pub fn first(per_cell: usize) -> Self {
        Self {
            per_cell,
            traces: Vec::new(),
        }
    }

    /// The traces kept of cell `cell`, in trial order.
    pub fn of_cell(&self, cell: usize) -> &[Vec<TraceSample>] {
        self.traces.get(cell).map_or(&[], Vec::as_slice)
    }
}

impl SweepObserver for Traces {
    fn wants_trace(&self, _cell: usize, trial: usize) -> bool {
        trial < self.per_cell
    }

    fn fold_trial(&mut self, cell: usize, trial: usize, output: &SimOutput) {
        if trial < self.per_cell {
            if self.traces.len() <= cell {
                self.traces.resize(cell + 1, Vec::new());
            }
            self.traces[cell].push(output.trace.clone());
        }
    }
}

/// A sweep's configuration.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// Noise levels (rows of the cell grid).
    pub noise_levels: Vec<NoiseLevel>,
    /// Estimators (columns of the cell grid).
    pub estimators: Vec<EstimatorSpec>,
    /// Trials per cell.
    pub trials: usize,
    /// Base seed.
    pub seed: u64,
    /// Template flight: everything except seed, trajectory, noise and adaptation, which the
    /// driver sets per trial.
    pub base: SimConfig,
    /// If set, every trial flies this trajectory kind instead of cycling through all five.
    pub trajectory: Option<TrajectoryKind>,
    /// Reference columns after the estimators: [`Adaptation::Nominal`] (never adapts) and
    /// [`Adaptation::Oracle`] (the true parameters from each event on); empty by default.
    pub references: Vec<Adaptation>,
}

impl Sweep {
    /// The paper's Table II sweep: 4 noise levels × `estimators`, `trials` per cell.
    pub fn new(estimators: Vec<EstimatorSpec>, trials: usize, seed: u64) -> Self {
        Self {
            noise_levels: NoiseLevel::ALL.to_vec(),
            estimators,
            trials,
            seed,
            base: SimConfig::default(),
            trajectory: None,
            references: Vec::new(),
        }
    }
}

/// Seed of trial `trial` at noise level index `level` (independent of the estimator).
pub fn trial_seed(seed: u64, level: usize, trial: usize) -> u64 {
    use rand::RngExt;
    crate::sim::sub_rng(seed ^ ((level as u64) << 40), trial as u64 + 17).random::<u64>()
}

/// Aggregated results of one (noise level, estimator) cell.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CellSummary {
    /// Noise level.
    pub noise: NoiseLevel,
    /// What adapts the controller: an estimator, or a reference (nominal, oracle).
    pub adaptation: Adaptation,
    /// Label: the estimator's, `nominal` or `oracle`.
    pub label: String,
    /// Trials flown.
    pub trials: usize,
    /// Mean position error over the trials that did not abort \[cm\].
    pub position_error_cm: f64,
    /// Mean position error over all trials, an aborted trial's missing steps at the abort
    /// threshold (`metrics::position_error_all_cm`) \[cm\].
    pub position_error_all_cm: f64,
    /// Standard error of [`position_error_all_cm`](Self::position_error_all_cm) \[cm\].
    pub position_error_all_se: f64,
    /// Standard error of [`parameter_error`](Self::parameter_error).
    pub parameter_error_se: f64,
    /// Mean (t+1) error over the events whose first window held only post-event frames.
    pub t1_error_clean: f64,
    /// Mean (t+1) error over the events whose first window mixed pre- and post-event frames.
    pub t1_error_mixed: f64,
    /// Standard error of [`t1_error`](Self::t1_error).
    pub t1_error_se: f64,
    /// Share of trials with a mixed first window [%].
    pub t1_mixed_pct: f64,
    /// The paper's success rule (5 cm, 10 control steps after each event) [%].
    pub success_paper_pct: f64,
    /// Mean parameter error `‖θ̂ − θ‖₂` over trials (each the mean over its updates).
    pub parameter_error: f64,
    /// Mean relative mass error.
    pub rel_mass: f64,
    /// Mean relative first-moment error.
    pub rel_first_moment: f64,
    /// Mean relative inertia error.
    pub rel_inertia: f64,
    /// Mean (t+1) error over trials that have one.
    pub t1_error: f64,
    /// Success rate, Table II's rule (`metrics::is_settled`: 1 cm, 2 s after each event) [%].
    pub success_pct: f64,
    /// Success rate judged after the first post-event update [%].
    pub success_after_update_pct: f64,
    /// Abort rate [%].
    pub aborted_pct: f64,
    /// Median estimator update time \[µs\].
    pub update_median_us: f64,
    /// 95th-percentile estimator update time \[µs\].
    pub update_p95_us: f64,
    /// Per-trial position errors \[cm\] (in trial order; NaN for aborted trials), for CDFs.
    pub position_errors: Vec<f64>,
    /// Per-trial settle errors \[cm\] (`TrialMetrics::settle_error_cm`, in trial order), for
    /// the success curve ([`CellSummary::success_at`]).
    #[serde(default)]
    pub settle_errors: Vec<f64>,
}

impl CellSummary {
    /// Success % with the settle threshold `threshold_cm` \[cm\] instead of 1 cm (judged
    /// 2 s after each event, as [`crate::metrics::is_settled`]); NaN without trials.
    pub fn success_at(&self, threshold_cm: f64) -> f64 {
        if self.settle_errors.is_empty() {
            return f64::NAN;
        }
        let ok = self
            .settle_errors
            .iter()
            .filter(|e| **e < threshold_cm)
            .count();
        100.0 * ok as f64 / self.settle_errors.len() as f64
    }

    /// Standard error of [`CellSummary::aborted_pct`] (binomial, percentage points).
    pub fn aborted_se(&self) -> f64 {
        let n = self.trials.max(1) as f64;
        let p = self.aborted_pct / 100.0;
        100.0 * (p * (1.0 - p) / n).sqrt()
    }
}

/// Running count, sum and sum of squares (mean and standard error of the mean).
#[derive(Default)]
struct Moments {
    n: usize,
    sum: f64,
    sum2: f64,
}

impl Moments {
    fn add(&mut self, x: f64) {
        if x.is_finite() {
            self.n += 1;
            self.sum += x;
            self.sum2 += x * x;
        }
    }
    fn mean(&self) -> f64 {
        mean(self.sum, self.n)
    }
    /// Standard error of the mean, `s / √n` with the sample standard deviation `s`.
    fn se(&self) -> f64 {
        if self.n < 2 {
            return f64::NAN;
        }
        let n = self.n as f64;
        let var = ((self.sum2 - self.sum * self.sum / n) / (n - 1.0)).max(0.0);
        (var / n).sqrt()
    }
}

#[derive(Default)]
struct Accumulator {
    trials: usize,
    pos_sum: f64,
    pos_n: usize,
    pos_all: Moments,
    pe: Moments,
    t1: Moments,
    t1_clean: Moments,
    t1_mixed: Moments,
    settled: usize,
    pe_sum: f64,
    pe_n: usize,
    mass: f64,
    fm: f64,
    inertia: f64,
    t1_sum: f64,
    t1_n: usize,
    success: usize,
    success_upd: usize,
    aborted: usize,
    times: UpdateTimes,
    positions: Vec<f64>,
    settles: Vec<f64>,
}

/// One finished trial on its way from a worker thread to the fold.
struct FinishedTrial {
    cell: usize,
    trial: usize,
    output: SimOutput,
}

/// Results of a sweep: one [`CellSummary`] per (noise level, estimator), noise-major.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepResult {
    /// Cells, `cells[level * estimators + estimator]`.
    pub cells: Vec<CellSummary>,
    /// Trials per cell.
    pub trials: usize,
    /// Base seed.
    pub seed: u64,
    /// Wall-clock time of the sweep \[s\].
    pub elapsed_s: f64,
    /// Rayon threads used.
    pub threads: usize,
}

impl Sweep {
    /// Runs the sweep on the current rayon thread pool (use `ThreadPool::install` to pick
    /// one) without observers.
    ///
    /// # Errors
    /// As [`Sweep::run_with`].
    pub fn run(&self) -> Result<SweepResult, SimError> {
        self.run_with(&mut ())
    }

    /// Runs the sweep on the current rayon thread pool, reporting to `observer`.
    ///
    /// # Errors
    /// An invalid sweep ([`Sweep::validate`]) or the first configuration error of any trial.
    pub fn run_with<O: SweepObserver + ?Sized>(
        &self,
        observer: &mut O,
    ) -> Result<SweepResult, SimError> {
        let result = self.run_observed(observer);
        observer.sweep_finished();
        result
    }

    /// Checks the sweep without flying: a non-empty grid and a valid template flight.
    ///
    /// # Errors
    /// `trials == 0` or no estimator/noise level is an [`SimError::InvalidParameter`]; the
    /// template's problems as [`SimConfig::validate`].
    pub fn validate(&self) -> Result<(), SimError> {
        if self.trials == 0 || self.estimators.is_empty() || self.noise_levels.is_empty() {
            return Err(SimError::InvalidParameter {
                name: "sweep size (trials, estimators, noise levels)",
                value: 0.0,
                reason: "must all be non-empty",
            });
        }
        self.base.validate()
    }

    /// Columns of the cell grid: the estimators, then the references.
    fn columns(&self) -> usize {
        self.estimators.len() + self.references.len()
    }

    /// What adapts the controller in column `c`.
    fn column(&self, c: usize) -> Adaptation {
        match self.estimators.get(c) {
            Some(spec) => Adaptation::Estimator(*spec),
            None => self.references[c - self.estimators.len()],
        }
    }

    fn run_observed<O: SweepObserver + ?Sized>(
        &self,
        observer: &mut O,
    ) -> Result<SweepResult, SimError> {
        self.validate()?;
        let start = std::time::Instant::now();
        let n_est = self.columns();
        let n_cells = self.noise_levels.len() * n_est;
        let total = n_cells * self.trials;
        let done = AtomicUsize::new(0);
        let mut acc: Vec<Accumulator> = (0..n_cells).map(|_| Accumulator::default()).collect();
        // Job order: trial-major, so every chunk mixes cells and all cells progress together.
        let chunk = 512;
        let mut job = 0;
        while job < total {
            let end = (job + chunk).min(total);
            let shared: &O = observer;
            // In parallel with the `parallel` feature, else on this thread: the same bits.
            #[cfg(feature = "parallel")]
            let jobs = (job..end).into_par_iter();
            #[cfg(not(feature = "parallel"))]
            let jobs = job..end;
            let results: Vec<Result<FinishedTrial, SimError>> = jobs
                .map(|j| {
                    let r = self.run_job(j, n_cells, shared);
                    shared.trial_finished(done.fetch_add(1, Ordering::Relaxed) + 1, total);
                    r
                })
                .collect();
            for r in results {
                let f = r?;
                fold(&mut acc[f.cell], &f.output);
                observer.fold_trial(f.cell, f.trial, &f.output);
            }
            job = end;
        }
        let cells = acc
            .into_iter()
            .enumerate()
            .map(|(c, a)| finish(self.noise_levels[c / n_est], self.column(c % n_est), a))
            .collect();
        Ok(SweepResult {
            cells,
            trials: self.trials,
            seed: self.seed,
            elapsed_s: start.elapsed().as_secs_f64(),
            threads: worker_threads(),
        })
    }

    fn run_job<O: SweepObserver + ?Sized>(
        &self,
        job: usize,
        n_cells: usize,
        observer: &O,
    ) -> Result<FinishedTrial, SimError> {
        let trial = job / n_cells;
        let cell = job % n_cells;
        let n_est = self.columns();
        let level = cell / n_est;
        let mut cfg = self.base.clone();
        cfg.seed = trial_seed(self.seed, level, trial);
        cfg.trajectory = self
            .trajectory
            .unwrap_or(TrajectoryKind::ALL[trial % TrajectoryKind::ALL.len()]);
        cfg.noise = self.noise_levels[level];
        cfg.adaptation = self.column(cell % n_est);
        cfg.record_trace = observer.wants_trace(cell, trial);
        cfg.record_log = false;
        let output = simulate(&cfg)?;
        Ok(FinishedTrial {
            cell,
            trial,
            output,
        })
    }
}

fn fold(a: &mut Accumulator, output: &SimOutput) {
    let m = &output.metrics;
    a.trials += 1;
    if m.aborted {
        a.aborted += 1;
        a.positions.push(f64::NAN);
    } else {
        a.pos_sum += m.position_error_cm;
        a.pos_n += 1;
        a.positions.push(m.position_error_cm);
    }
    if m.parameter_error.is_finite() {
        a.pe_sum += m.parameter_error;
        a.mass += m.group_errors.mass;
        a.fm += m.group_errors.first_moment;
        a.inertia += m.group_errors.inertia;
        a.pe_n += 1;
    }
    if m.t1_error.is_finite() {
        a.t1_sum += m.t1_error;
        a.t1_n += 1;
    }
    a.settles.push(m.settle_error_cm);
    a.success += usize::from(m.success);
    a.settled += usize::from(m.settled);
    a.pos_all.add(m.position_error_all_cm);
    a.pe.add(m.parameter_error);
    a.t1.add(m.t1_error);
    a.t1_clean.add(m.t1_error_clean);
    a.t1_mixed.add(m.t1_error_mixed);
    a.success_upd += usize::from(m.success_after_update);
    for u in &output.updates {
        a.times.record(u.micros);
    }
}

fn mean(sum: f64, n: usize) -> f64 {
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// The table label of a column.
fn adaptation_label(adaptation: &Adaptation) -> String {
    match adaptation {
        Adaptation::Nominal => "nominal".into(),
        Adaptation::Oracle => "oracle".into(),
        Adaptation::Estimator(spec) => spec.label(),
    }
}

fn finish(noise: NoiseLevel, adaptation: Adaptation, a: Accumulator) -> CellSummary {
    let pct = |k: usize| 100.0 * k as f64 / a.trials.max(1) as f64;
    CellSummary {
        noise,
        adaptation,
        label: adaptation_label(&adaptation),
        trials: a.trials,
        position_error_cm: mean(a.pos_sum, a.pos_n),
        position_error_all_cm: a.pos_all.mean(),
        position_error_all_se: a.pos_all.se(),
        parameter_error_se: a.pe.se(),
        t1_error_clean: a.t1_clean.mean(),
        t1_error_mixed: a.t1_mixed.mean(),
        t1_error_se: a.t1.se(),
        t1_mixed_pct: pct(a.t1_mixed.n),
        success_paper_pct: pct(a.success),
        parameter_error: mean(a.pe_sum, a.pe_n),
        rel_mass: mean(a.mass, a.pe_n),
        rel_first_moment: mean(a.fm, a.pe_n),
        rel_inertia: mean(a.inertia, a.pe_n),
        t1_error: mean(a.t1_sum, a.t1_n),
        success_pct: pct(a.settled),
        success_after_update_pct: pct(a.success_upd),
        aborted_pct: pct(a.aborted),
        update_median_us: a.times.median(),
        update_p95_us: a.times.p95(),
        position_errors: a.positions,
        settle_errors: a.settles,
    }
}

impl SweepResult {
    /// The Table II layout as fixed-width text (with the wall-clock update times).
    pub fn table(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!(
            "{:<7} {:<38} {:>16} {:>10} {:>10} {:>10} {:>10} {:>7} {:>7} {:>8} {:>8} {:>9} {:>9}\n",
            "noise",
            "estimator",
            "pos all [cm]",
            "param",
            "(t+1)",
            "clean",
            "mixed",
            "succ %",
            "paper %",
            "abort %",
            "pos [cm]",
            "med [us]",
            "P95 [us]"
        ));
        for c in &self.cells {
            s.push_str(&format!(
                "{:<7} {:<38} {:>8.3} ± {:<5.3} {:>10.3e} {:>10.3e} {:>10.3e} {:>10.3e} {:>7.1} {:>7.1} {:>8.1} {:>8.3} {:>9.2} {:>9.2}\n",
                c.noise.name(),
                c.label,
                c.position_error_all_cm,
                c.position_error_all_se,
                c.parameter_error,
                c.t1_error,
                c.t1_error_clean,
                c.t1_error_mixed,
                c.success_pct,
                c.success_paper_pct,
                c.aborted_pct,
                c.position_error_cm,
                c.update_median_us,
                c.update_p95_us
            ));
        }
        s
    }

    /// The accuracy table as Markdown, every column a deterministic function of the seeds
    /// (no wall-clock times): what the READMEs show and CI compares.
    pub fn markdown_accuracy(&self) -> String {
        self.markdown_table(false)
    }

    /// The table as Markdown: [`SweepResult::markdown_accuracy`] plus the update times of
    /// this run.
    pub fn markdown(&self) -> String {
        self.markdown_table(true)
    }

    /// The success thresholds of [`SweepResult::markdown_headline`]'s curve \[cm\].
    pub const SUCCESS_CURVE_CM: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

    /// Issue #27's headline table as Markdown, every column a function of the seeds: lost
    /// flights (± s.e.), position error over all trials (± s.e.), then the (t+1) and parameter
    /// errors against what the data identify (θ/(1+ε)), and success as a curve over its
    /// threshold ([`SweepResult::SUCCESS_CURVE_CM`], judged 2 s after each event).
    pub fn markdown_headline(&self) -> String {
        let mut s = String::from(
            "| noise | estimator | lost flights % | position error, all trials \\[cm\\] | (t+1) error vs θ/(1+ε) | parameter error vs θ/(1+ε) | success % at 0.5 / 1 / 2 / 4 cm |\n|---|---|---:|---:|---:|---:|---:|\n",
        );
        for c in &self.cells {
            let curve: Vec<String> = Self::SUCCESS_CURVE_CM
                .iter()
                .map(|t| format!("{:.1}", c.success_at(*t)))
                .collect();
            s.push_str(&format!(
                "| {} | {} | {:.1} ± {:.1} | {:.3} ± {:.3} | {:.2e} ± {:.1e} | {:.2e} ± {:.1e} | {} |\n",
                c.noise.name(),
                c.label,
                c.aborted_pct,
                c.aborted_se(),
                c.position_error_all_cm,
                c.position_error_all_se,
                c.t1_error,
                c.t1_error_se,
                c.parameter_error,
                c.parameter_error_se,
                curve.join(" / "),
            ));
        }
        s
    }

    /// The Markdown table, with the update-time column or without.
    fn markdown_table(&self, times: bool) -> String {
        let mut s = String::from(
            "| noise | estimator | position error, all trials \\[cm\\] | parameter error | (t+1) error | (t+1) clean / mixed | success % | paper success % | aborted % |",
        );
        s.push_str(if times {
            " update median / P95 \\[µs\\] |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n"
        } else {
            "\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n"
        });
        for c in &self.cells {
            s.push_str(&format!(
                "| {} | {} | {:.3} ± {:.3} | {:.2e} ± {:.1e} | {:.2e} | {:.2e} / {:.2e} | {:.1} | {:.1} | {:.1} |",
                c.noise.name(),
                c.label,
                c.position_error_all_cm,
                c.position_error_all_se,
                c.parameter_error,
                c.parameter_error_se,
                c.t1_error,
                c.t1_error_clean,
                c.t1_error_mixed,
                c.success_pct,
                c.success_paper_pct,
                c.aborted_pct,
            ));
            if times {
                s.push_str(&format!(
                    " {:.2} / {:.2} |",
                    c.update_median_us, c.update_p95_us
                ));
            }
            s.push('\n');
        }
        s
    }

    /// Writes one CSV row per cell (aggregates only).
    ///
    /// # Errors
    /// I/O and CSV errors.
    pub fn write_csv(&self, path: &std::path::Path) -> Result<(), SimError> {
        let mut w = csv::Writer::from_path(path)?;
        w.write_record([
            "noise",
            "estimator",
            "trials",
            "position_error_cm",
            "parameter_error",
            "rel_mass",
            "rel_first_moment",
            "rel_inertia",
            "t1_error",
            "success_pct",
            "success_paper_pct",
            "success_after_update_pct",
            "position_error_all_cm",
            "position_error_all_se",
            "parameter_error_se",
            "t1_error_clean",
            "t1_error_mixed",
            "t1_mixed_pct",
            "aborted_pct",
            "update_median_us",
            "update_p95_us",
        ])?;
        for c in &self.cells {
            w.write_record([
                c.noise.name().to_string(),
                c.label.clone(),
                c.trials.to_string(),
                c.position_error_cm.to_string(),
                c.parameter_error.to_string(),
                c.rel_mass.to_string(),
                c.rel_first_moment.to_string(),
                c.rel_inertia.to_string(),
                c.t1_error.to_string(),
                c.success_pct.to_string(),
                c.success_paper_pct.to_string(),
                c.success_after_update_pct.to_string(),
                c.position_error_all_cm.to_string(),
                c.position_error_all_se.to_string(),
                c.parameter_error_se.to_string(),
                c.t1_error_clean.to_string(),
                c.t1_error_mixed.to_string(),
                c.t1_mixed_pct.to_string(),
                c.aborted_pct.to_string(),
                c.update_median_us.to_string(),
                c.update_p95_us.to_string(),
            ])?;
        }
        w.flush()?;
        Ok(())
    }

    /// Writes the whole result (including the per-trial position errors) as JSON.
    ///
    /// # Errors
    /// I/O and JSON errors.
    pub fn write_json(&self, path: &std::path::Path) -> Result<(), SimError> {
        let f = std::io::BufWriter::new(std::fs::File::create(path)?);
        serde_json::to_writer_pretty(f, self)?;
        Ok(())
    }

    /// The cell of `noise` and estimator label `label`, if any.
    pub fn cell(&self, noise: NoiseLevel, label: &str) -> Option<&CellSummary> {
        self.cells
            .iter()
            .find(|c| c.noise == noise && c.label == label)
    }
}

/// Threads the sweep runs on: rayon's current pool with the `parallel` feature, else 1.
fn worker_threads() -> usize {
    #[cfg(feature = "parallel")]
    {
        rayon::current_num_threads()
    }
    #[cfg(not(feature = "parallel"))]
    {
        1
    }
}
