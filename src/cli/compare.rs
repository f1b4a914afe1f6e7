//! `tagk compare`: the k-step-ahead prediction of identified models on flight logs, as
//! MATLAB's `compare(data, sys, k)` ([`crate::diagnose::k_step_prediction_logs`]).

use std::path::PathBuf;

use crate::diagnose::{
    AlignOptions, Comparison, DiagnoseError, DiagnosisPlan, ModelFile, ModelPrediction, Signals,
    default_horizons, k_step_prediction_logs,
};
use crate::dynamics::log_input::ColumnMapping;
use crate::dynamics::vehicle::Vehicle;

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
    /// Write an HTML page with the error against the horizon to this file.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Do not print the tables.
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

/// The comparison of every `--model` on the logs.
///
/// # Errors
/// A model file that cannot be read; the logs' errors ([`read_logs`]); the prediction's
/// ([`k_step_prediction_logs`]).
pub fn compare(args: &CompareArgs) -> Result<Comparison, DiagnoseError> {
    let horizons = default_horizons(args.horizon);
    let mut models = Vec::new();
    for path in &args.models {
        let model = ModelFile::from_path(path)?;
        let logs = read_logs(args, &model)?;
        let prediction = k_step_prediction_logs(&logs, &model, &horizons)?;
        models.push(ModelPrediction {
            model: path.display().to_string(),
            horizons: prediction.horizons,
        });
    }
    Ok(Comparison { models })
}

/// `tagk compare LOG… --model M [--model M2 …] [--horizon K] [--json F] [--report F.html]`:
/// prints the tables and writes the requested files.
///
/// # Errors
/// As [`compare`]; [`DiagnoseError::Output`] for a file that cannot be written.
pub fn run_compare(args: &CompareArgs) -> Result<(), DiagnoseError> {
    let comparison = compare(args)?;
    let write = |path: &PathBuf, text: String| {
        std::fs::write(path, text).map_err(|e| DiagnoseError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    };
    if let Some(path) = &args.json {
        write(path, comparison.to_json()?)?;
    }
    if let Some(path) = &args.report {
        write(path, crate::diagnose::html::render_comparison(&comparison))?;
    }
    if !args.quiet {
        print!("{}", comparison.table());
    }
    Ok(())
}
