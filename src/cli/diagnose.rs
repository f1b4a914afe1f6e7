//! `tagk diagnose`: compare the rigid-body model with a flight log, find the missing effect,
//! add effects with `--with` and print the before/after comparison.

use std::path::PathBuf;

use crate::diagnose::{
    CustomEffect, DiagnoseError, DiagnoseOptions, EffectKind, EffectRef, FlightLog, Model, Report,
    Signals, builtin_by_name, builtin_effects, online_pass, report_table, run_loop,
};

/// Arguments of `tagk diagnose`.
#[derive(Debug, Clone, clap::Args)]
#[command(after_help = effects_help())]
pub struct DiagnoseArgs {
    /// Flight log (CSV: columns, units and frames as in docs/CONVENTIONS.md §6 of the tagk
    /// repository).
    #[arg(value_name = "LOG")]
    pub log: PathBuf,
    /// Effects to add to the rigid-body model, comma separated (e.g. `linear-drag,wind`):
    /// built-in names or aliases (listed below) or the names of `--custom` effects.
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
    /// Known vehicle mass in kg (fixes the mass; makes `thrust-gain` identifiable).
    #[arg(long, value_name = "KG")]
    pub mass: Option<f64>,
    /// Airframe radius in m beyond which a fitted centre of mass is flagged.
    #[arg(long, value_name = "M", default_value_t = default_airframe_radius())]
    pub airframe_radius: f64,
    /// Do not print the terminal summary.
    #[arg(long)]
    pub quiet: bool,
}

/// The default of `--airframe-radius`: the one of [`DiagnoseOptions::default`].
fn default_airframe_radius() -> f64 {
    DiagnoseOptions::default().airframe_radius
}

/// The built-in effects with their aliases and one-line summaries, for `--help`.
fn effects_help() -> String {
    let mut text = String::from("Built-in effects (--with NAME; docs/CONVENTIONS.md §7):\n");
    for kind in EffectKind::ALL {
        let aliases = kind.aliases();
        let also = if aliases.is_empty() {
            String::new()
        } else {
            format!(" (also: {})", aliases.join(", "))
        };
        text.push_str(&format!("  {:<15} {}{also}\n", kind.name(), kind.summary()));
    }
    text
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
            airframe_radius: default_airframe_radius(),
            quiet: false,
        }
    }
}

/// What the arguments ask for on a given log: the starting model, the effects to add and the
/// diagnosis options (built-in candidates plus the custom ones).
#[derive(Debug, Clone)]
pub struct Plan {
    /// The starting model (rigid body, with the known mass if given).
    pub base: Model,
    /// The effects to add (`--with`).
    pub with: Vec<EffectRef>,
    /// The diagnosis options.
    pub options: DiagnoseOptions,
}

/// Builds the [`Plan`] from the arguments, checked against the log.
///
/// # Errors
/// A malformed custom specification or one naming a column the log lacks, an unknown effect
/// name, a mass that is not positive and finite, invalid options.
pub fn plan(args: &DiagnoseArgs, log: &FlightLog) -> Result<Plan, DiagnoseError> {
    let mut customs: Vec<EffectRef> = Vec::new();
    for spec in &args.custom {
        let custom = CustomEffect::parse(spec)?;
        custom.require_columns(log)?;
        customs.push(std::sync::Arc::new(custom));
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
        base = base.with_known_mass(m);
    }
    base.validate()?;
    let mut candidates = builtin_effects();
    candidates.extend(customs);
    let options = DiagnoseOptions {
        airframe_radius: args.airframe_radius,
        candidates,
        ..DiagnoseOptions::default()
    };
    options.validate()?;
    Ok(Plan {
        base,
        with,
        options,
    })
}

/// Runs the whole loop on a log in memory (what [`run_diagnose`] does after reading the file).
///
/// # Errors
/// As [`plan`], [`run_loop`] and [`online_pass`].
pub fn diagnose_log(log: &FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    let plan = plan(args, log)?;
    let s = Signals::from_log(log)?;
    let mut report = run_loop(&s, &plan.base, &plan.with, &plan.options)?;
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
        let file = crate::diagnose::html::write_report(&report, dir)?;
        if !args.quiet {
            println!("report: {}", file.display());
        }
    }
    Ok(())
}
