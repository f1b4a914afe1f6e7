//! `tagk diagnose`: the command-line front end (the root binary wires [`DiagnoseArgs`] in).

use std::path::PathBuf;

use crate::diagnose::DiagnoseOptions;
use crate::effects::{CustomEffect, EffectRef, builtin_by_name, builtin_effects};
use crate::error::DiagnoseError;
use crate::fit::Model;
use crate::log::FlightLog;
use crate::online::online_pass;
use crate::report::{Report, report_table, run_loop};
use crate::signals::Signals;

/// Arguments of `tagk diagnose`.
#[derive(Debug, Clone, clap::Args)]
pub struct DiagnoseArgs {
    /// Flight log (CSV, CONVENTIONS §6).
    #[arg(value_name = "LOG")]
    pub log: PathBuf,
    /// Effects to add to the rigid-body model, comma separated (e.g. `linear-drag,wind`);
    /// built-in names or the names of `--custom` effects.
    #[arg(long = "with", value_delimiter = ',', value_name = "EFFECT")]
    pub with: Vec<String>,
    /// Write every number as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML report with SVG plots into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Also run TAG-K online over the log and compare with the batch fit.
    #[arg(long)]
    pub online: bool,
    /// Custom candidate effect from log signals: `NAME=COL[*COL...]@CH[,CH...]`
    /// (e.g. `vbat=vbat*fz@fz`); repeatable.
    #[arg(long = "custom", value_name = "SPEC")]
    pub custom: Vec<String>,
    /// Known vehicle mass \[kg\] (fixes the mass; makes `thrust-gain` identifiable).
    #[arg(long, value_name = "KG")]
    pub mass: Option<f64>,
    /// Airframe radius \[m\] beyond which a fitted centre of mass is flagged.
    #[arg(long, value_name = "M", default_value_t = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET)]
    pub airframe_radius: f64,
    /// Do not print the terminal summary.
    #[arg(long)]
    pub quiet: bool,
}

impl DiagnoseArgs {
    /// Arguments for a log with every option at its default.
    pub fn new(log: impl Into<PathBuf>) -> Self {
        Self {
            log: log.into(),
            with: Vec::new(),
            json: None,
            report: None,
            online: false,
            custom: Vec::new(),
            mass: None,
            airframe_radius: tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET,
            quiet: false,
        }
    }
}

/// Builds the base model, the `--with` effects and the options from the arguments.
///
/// # Errors
/// Unknown effect names, malformed custom specifications, a non-positive mass.
pub fn plan(
    args: &DiagnoseArgs,
) -> Result<(Model, Vec<EffectRef>, DiagnoseOptions), DiagnoseError> {
    let mut customs: Vec<EffectRef> = Vec::new();
    for spec in &args.custom {
        customs.push(std::sync::Arc::new(CustomEffect::parse(spec)?));
    }
    let mut with = Vec::new();
    for name in args.with.iter().map(|s| s.trim()).filter(|s| !s.is_empty()) {
        match customs.iter().find(|c| c.name() == name) {
            Some(c) => with.push(c.clone()),
            None => with.push(builtin_by_name(name)?),
        }
    }
    let mut base = Model::rigid_body();
    if let Some(m) = args.mass {
        if !(m > 0.0 && m.is_finite()) {
            return Err(DiagnoseError::Fit(format!(
                "--mass must be positive, got {m}"
            )));
        }
        base = base.with_known_mass(m);
    }
    let mut candidates = builtin_effects();
    candidates.extend(customs);
    let opts = DiagnoseOptions {
        airframe_radius: args.airframe_radius,
        candidates,
        ..DiagnoseOptions::default()
    };
    Ok((base, with, opts))
}

/// Runs the whole loop on a log in memory (what [`run_diagnose`] does after reading the file).
///
/// # Errors
/// As [`run_loop`] and [`online_pass`].
pub fn diagnose_log(log: &FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    let (base, with, opts) = plan(args)?;
    let s = Signals::from_log(log)?;
    let mut report = run_loop(&s, &base, &with, &opts)?;
    if args.online {
        report.online = Some(online_pass(&s, &report.last().fit, 5)?);
    }
    Ok(report)
}

/// `tagk diagnose LOG [--with ...] [--json FILE] [--report DIR] [--online] [--custom SPEC]`:
/// reads the log, runs the loop, prints the summary and writes the requested files.
///
/// # Errors
/// Log validation errors (naming line and column), fit failures, output failures.
pub fn run_diagnose(args: &DiagnoseArgs) -> Result<(), DiagnoseError> {
    let log = FlightLog::from_csv_path(&args.log)?;
    let report = diagnose_log(&log, args)?;
    if !args.quiet {
        println!("{}", report_table(&report));
    }
    if let Some(path) = &args.json {
        std::fs::write(path, report.to_json()?).map_err(|e| DiagnoseError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
    }
    if let Some(dir) = &args.report {
        let file = crate::html::write_report(&report, dir)?;
        if !args.quiet {
            println!("report: {}", file.display());
        }
    }
    Ok(())
}
