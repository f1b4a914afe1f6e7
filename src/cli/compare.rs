//! `tagk compare`: the k-step-ahead prediction of identified models on flight logs, as
//! MATLAB's `compare(data, sys, k)` ([`crate::diagnose::predict_logs`]).
//!
//! The constant-rate reference ([`crate::diagnose::Predictor::ConstantRate`]) is listed last,
//! named `constant-rate`, unless `--no-baseline`. It is on by default: a model's error means
//! little until it is set beside what holding the current rates predicts.

use std::path::PathBuf;

use crate::diagnose::{
    AlignOptions, CONSTANT_RATE, Comparison, DiagnoseError, DiagnosisPlan, ModelFile,
    ModelPrediction, Predictor, Signals, default_horizons, predict_logs,
};
use crate::dynamics::log_input::ColumnMapping;
use crate::dynamics::vehicle::Vehicle;

use super::progress::Progress;

/// Arguments of tagk compare.
#[derive(Debug, Clone, clap::Args)]
pub struct CompareArgs {
    /// Flight log(s), read as tagk diagnose reads them (CSV of docs/CONVENTIONS.md §6, or
    /// through --columns). Several logs are pooled: every start sample counts once.
    #[arg(value_name = "LOG", required_unless_present_any = ["stream", "columns"])]
    pub logs: Vec<PathBuf>,
    /// Model files written by tagk diagnose --save-model or --save-steps
    /// (docs/MODEL_FILE.md), shown side by side. Repeatable, and one --model takes several
    /// files (--model DIR/*.toml): give the logs before it.
    #[arg(long = "model", value_name = "FILE", required = true, num_args = 1..)]
    pub models: Vec<PathBuf>,
    /// Longest horizon in steps of the log. The horizons reported are 1, 2, 5, 10, 20, 50,
    /// … up to it, and it.
    #[arg(long, value_name = "K", default_value_t = 50)]
    pub horizon: usize,
    /// Horizons, in steps, at which to overlay the logged state and the predictions over time
    /// (comma-separated) [default: the longest horizon, K, on the page only; given, the
    /// series enter the JSON file too].
    #[arg(
        long,
        value_name = "H,...",
        value_delimiter = ',',
        conflicts_with = "no_overlay"
    )]
    pub overlay: Vec<usize>,
    /// No overlay (a smaller JSON file and page).
    #[arg(long)]
    pub no_overlay: bool,
    /// Leave out the constant-rate reference (body rate and velocity held), listed last
    /// as constant-rate by default.
    #[arg(long)]
    pub no_baseline: bool,
    /// Column mapping (TOML, docs/COLUMN_MAPPING.md), as for tagk diagnose.
    #[arg(long, value_name = "FILE")]
    pub columns: Option<PathBuf>,
    /// One stream of the flight (repeatable), as for tagk diagnose.
    #[arg(long = "stream", value_name = "FILE", conflicts_with = "logs")]
    pub stream: Vec<PathBuf>,
    /// Vehicle (a preset or a file) instead of the model file's own: its rotor map turns
    /// the logged rotor speeds into the wrench.
    #[arg(long, value_name = "NAME|FILE")]
    pub vehicle: Option<String>,
    /// Write the errors as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write an HTML page with the error against the horizon and the overlays to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Do not print the tables, nor the progress (shown on a terminal only).
    #[arg(long)]
    pub quiet: bool,
}

/// The logs of `args` as `model` expects them: read as tagk diagnose reads them, with the
/// model's vehicle (or `--vehicle`), its stream shifts applied and nothing measured again.
///
/// # Errors
/// The files', the mapping's and the vehicle's errors.
pub fn read_logs(args: &CompareArgs, model: &ModelFile) -> Result<Vec<Signals>, DiagnoseError> {
    let mut plan = DiagnosisPlan::new().align(AlignOptions {
        auto: false,
        shifts: model.sensing.shifts_to_apply(),
        ..AlignOptions::default()
    });
    let vehicle = match &args.vehicle {
        Some(v) => Some(Vehicle::from_name_or_path(v)?),
        None => model.vehicle.clone(),
    };
    if let Some(v) = vehicle {
        plan = plan.vehicle(v);
    }
    if let Some(dt) = model.sensing.resample {
        plan = plan.resample(dt);
    }
    if let Some(path) = &args.columns {
        plan = plan.columns(ColumnMapping::from_path(path)?);
    }
    if args.stream.is_empty() {
        for log in &args.logs {
            plan = plan.file(log);
        }
    } else {
        plan = plan.streams(&args.stream);
    }
    plan.accept_scales(true)
        .conditioned_flights()?
        .into_iter()
        .map(|(_, log)| Ok(Signals::from_owned_log_split(log)?.0))
        .collect()
}

/// The overlay horizons of `args` \[steps\]: `--overlay`, by default the longest horizon, none
/// with `--no-overlay`.
pub fn overlay_horizons(args: &CompareArgs) -> Vec<usize> {
    if args.no_overlay {
        Vec::new()
    } else if args.overlay.is_empty() {
        vec![args.horizon]
    } else {
        args.overlay.clone()
    }
}

/// The comparison of every `--model` on the logs, then the constant-rate reference (on the
/// logs as the first model reads them) unless `--no-baseline`.
///
/// # Errors
/// A model file that cannot be read; the logs' errors ([`read_logs`]); the prediction's
/// ([`predict_logs`]).
pub fn compare(args: &CompareArgs) -> Result<Comparison, DiagnoseError> {
    compare_with_progress(args, &Progress::new(false))
}

/// [`compare`], with `bar` counting the models predicted.
fn compare_with_progress(args: &CompareArgs, bar: &Progress) -> Result<Comparison, DiagnoseError> {
    let horizons = default_horizons(args.horizon);
    let overlays = overlay_horizons(args);
    let total = (args.models.len() + usize::from(!args.no_baseline)) as u64;
    bar.set(0, total);
    let mut models = Vec::new();
    let mut first_logs = None;
    for path in &args.models {
        bar.message(format!("{}", path.display()));
        let model = ModelFile::from_path(path)?;
        let logs = read_logs(args, &model)?;
        let prediction = predict_logs(&logs, Predictor::Model(&model), &horizons, &overlays)?;
        models.push(ModelPrediction::new(path.display().to_string(), prediction));
        first_logs.get_or_insert(logs);
        bar.inc();
    }
    if !args.no_baseline
        && let Some(logs) = &first_logs
    {
        bar.message(CONSTANT_RATE);
        let prediction = predict_logs(logs, Predictor::ConstantRate, &horizons, &overlays)?;
        models.push(ModelPrediction::new(CONSTANT_RATE, prediction));
        bar.inc();
    }
    Ok(Comparison { models })
}

/// `tagk compare LOG… --model M [--model M2 …] [--horizon K] [--json F] [--report F.html]`:
/// prints the tables and writes the requested files.
///
/// # Errors
/// As [`compare`]; [`DiagnoseError::Output`] for a file that cannot be written.
pub fn run_compare(args: &CompareArgs) -> Result<(), DiagnoseError> {
    let bar = Progress::counting(!args.quiet, 0, "models");
    let comparison = compare_with_progress(args, &bar);
    bar.finish();
    let comparison = comparison?;
    let write = |path: &PathBuf, text: String| {
        std::fs::write(path, text).map_err(|e| DiagnoseError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    };
    if let Some(path) = &args.json {
        // The overlays' series (every sample of every log) enter the JSON file only when
        // asked for: by default they are for the page, and would make the file 40 MB per
        // model on a 10-minute log.
        if args.overlay.is_empty() {
            let mut slim = comparison.clone();
            slim.models.iter_mut().for_each(|m| m.overlays.clear());
            write(path, slim.to_json()?)?;
        } else {
            write(path, comparison.to_json()?)?;
        }
    }
    if let Some(path) = &args.report {
        write(path, crate::diagnose::html::render_comparison(&comparison))?;
    }
    if !args.quiet {
        print!("{}", comparison.table());
    }
    Ok(())
}
