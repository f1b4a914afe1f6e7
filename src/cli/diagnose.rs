//! `tagk diagnose`: compare the rigid-body model with a flight log, find the missing effect,
//! add effects with `--with` and print the before/after comparison.

use std::borrow::Cow;
use std::path::PathBuf;

use crate::diagnose::{
    AlignOptions, CustomEffect, DiagnoseError, DiagnoseOptions, Effect, EffectKind, EffectRef,
    FlightLog, Model, NextStep, OnlineOptions, Report, SamplingFindings, Signals,
    align_streams_owned, builtin_by_name, builtin_effects, online_pass_with, parse_shift,
    report_table, run_logs, run_loop,
};
use crate::dynamics::log_input::{ColumnMapping, MergeReport, ReadOptions, read_streams};
use crate::dynamics::vehicle::Vehicle;

/// Arguments of tagk diagnose.
#[derive(Debug, Clone, clap::Args)]
#[command(after_help = effects_help())]
pub struct DiagnoseArgs {
    /// Flight log(s) (CSV: columns, units and frames as in docs/CONVENTIONS.md §6 of the tagk
    /// repository). With --columns each is read through the column mapping. Several logs of
    /// one vehicle are diagnosed jointly (one set of parameters and effect coefficients), and
    /// each log's own staircase is compared with the joint one.
    #[arg(value_name = "LOG", required_unless_present_any = ["stream", "columns"])]
    pub logs: Vec<PathBuf>,
    /// Column mapping (TOML, docs/COLUMN_MAPPING.md): column names, units, quaternion order,
    /// NED/FRD frames, and the streams of the flight.
    #[arg(long, value_name = "FILE")]
    pub columns: Option<PathBuf>,
    /// One stream of the flight (a CSV file per topic, each with its own time column);
    /// repeatable. The streams are merged onto the first one's time base (or the mapping's
    /// primary); gaps are reported, never interpolated over. Not several flights: one
    /// flight in several files.
    #[arg(long = "stream", value_name = "FILE", conflicts_with = "logs")]
    pub stream: Vec<PathBuf>,
    /// Effects to add to the rigid-body model, comma separated (e.g. linear-drag,wind):
    /// built-in names or aliases (listed below) or the names of --custom effects.
    #[arg(long = "with", value_delimiter = ',', value_name = "EFFECT")]
    pub with: Vec<String>,
    /// Write every number as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML report with SVG plots into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Also run TAG-K online over the log, as the simulator's tuned TAG-K flies, and compare
    /// it with the batch fit of the model. It sees the fz and torque rows only. The model's
    /// fitted effects are removed from the measured wrench first. Rows are scaled by the
    /// fit's residual noise, columns by the batch estimate. TAG-K starts from the batch
    /// estimate; each window stops at the noise. It reports the online mass against the
    /// batch mass.
    #[arg(long)]
    pub online: bool,
    /// Custom candidate effect from log signals: NAME=COL[*COL...]@CH[,CH...]
    /// (e.g. vbat=vbat*fz@fz); repeatable.
    #[arg(long = "custom", value_name = "SPEC")]
    pub custom: Vec<String>,
    /// Vehicle description: a preset (crazyflie-2.1; tagk vehicle list) or a vehicle file
    /// (TOML, docs/VEHICLE.md). A log without the wrench fx..tz then gets it from its rotor
    /// speeds w1..w4 (rad/s) (a logged wrench is used as it is); the vehicle's airframe
    /// radius becomes the default --airframe-radius.
    #[arg(long, value_name = "NAME|FILE")]
    pub vehicle: Option<String>,
    /// Known vehicle mass in kg, or vehicle for the mass prior of --vehicle (fixes the
    /// mass; makes thrust-gain identifiable). Without it the mass is fitted.
    #[arg(long, value_name = "KG|vehicle")]
    pub mass: Option<KnownMass>,
    /// Airframe radius in m beyond which a fitted centre of mass is flagged [default: the
    /// vehicle's airframe_radius with --vehicle, else 0.0325].
    #[arg(long, value_name = "M")]
    pub airframe_radius: Option<f64>,
    /// Measurement noise per channel fx,fy,fz,tx,ty,tz (N, N m) (e.g. from the sensors'
    /// specification): the noise floor of the stepwise search. Default: from the data (the
    /// held-out residual of every candidate at once; docs/CONVENTIONS.md §7).
    #[arg(long, value_name = "FX,FY,FZ,TX,TY,TZ", value_delimiter = ',')]
    pub noise_floor: Option<Vec<f64>>,
    /// Resample the log onto a uniform time grid of this step (s) before the diagnosis, by
    /// linear interpolation (the attitude by normalised linear interpolation), each segment
    /// between gaps on its own grid: for irregular sampling. Gaps are never bridged.
    #[arg(long, value_name = "S")]
    pub resample: Option<f64>,
    /// Only report the time offset of each sensor stream (gyro, accelerometer, velocity)
    /// against the pose. By default the IMU is the clock: a significant gyro offset (its 95 %
    /// interval excludes zero and it is at least half a sampling period) moves the pose and
    /// the velocity onto it before the fit (docs/CONVENTIONS.md §7.2).
    #[arg(long)]
    pub no_align: bool,
    /// Shift a stream by a known time offset in seconds, positive when the stream is late
    /// (e.g. pose=-0.012); repeatable. Streams: gyro, accelerometer, velocity, actuators,
    /// pose. With a shift given, nothing is moved automatically.
    #[arg(long = "shift", value_name = "STREAM=SECONDS")]
    pub shift: Vec<String>,
    /// Most effects the stepwise search adds.
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub max_steps: usize,
    /// Do not print the terminal summary.
    #[arg(long)]
    pub quiet: bool,
}

/// The value of `--mass`: a mass in kg, or the vehicle's mass prior.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KnownMass {
    /// A mass \[kg\].
    Kg(f64),
    /// The `mass` of the `--vehicle` description.
    Vehicle,
}

impl std::str::FromStr for KnownMass {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "vehicle" => Ok(KnownMass::Vehicle),
            t => t.parse::<f64>().map(KnownMass::Kg).map_err(|_| {
                format!("`{s}` is neither a mass in kg nor `vehicle` (the --vehicle mass prior)")
            }),
        }
    }
}

impl From<f64> for KnownMass {
    fn from(kg: f64) -> Self {
        KnownMass::Kg(kg)
    }
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
    text.push_str("\nFit measures of the tables:\n");
    for line in crate::diagnose::FIT_MEASURES.lines() {
        text.push_str(&format!("  {line}\n"));
    }
    text
}

impl DiagnoseArgs {
    /// Arguments for a log with every option at its default.
    pub fn new(log: impl Into<PathBuf>) -> Self {
        Self {
            logs: vec![log.into()],
            columns: None,
            stream: Vec::new(),
            with: Vec::new(),
            json: None,
            report: None,
            online: false,
            custom: Vec::new(),
            vehicle: None,
            mass: None,
            airframe_radius: None,
            noise_floor: None,
            resample: None,
            max_steps: 5,
            quiet: false,
            no_align: false,
            shift: Vec::new(),
        }
    }

    /// The stream alignment these arguments ask for (`--no-align`, `--shift`).
    ///
    /// # Errors
    /// [`DiagnoseError::InvalidOption`] (field `shift`) for a malformed `--shift`.
    pub fn align_options(&self) -> Result<AlignOptions, DiagnoseError> {
        Ok(AlignOptions {
            auto: !self.no_align,
            shifts: self
                .shift
                .iter()
                .map(|s| parse_shift(s))
                .collect::<Result<_, _>>()?,
            ..AlignOptions::default()
        })
    }

    /// The command line that reproduces the final model of a report: these arguments with
    /// `--with` set to every effect of the final model (the files and flags as given).
    pub fn command_for(&self, effects: &[String]) -> String {
        let quote = |p: &std::path::Path| {
            let s = p.display().to_string();
            if s.contains(|c: char| c.is_whitespace() || c == '\'' || c == '"') {
                format!("'{}'", s.replace('\'', "'\\''"))
            } else {
                s
            }
        };
        let mut cmd = String::from("tagk diagnose");
        for log in &self.logs {
            cmd.push(' ');
            cmd.push_str(&quote(log));
        }
        for stream in &self.stream {
            cmd.push_str(&format!(" --stream {}", quote(stream)));
        }
        if let Some(c) = &self.columns {
            cmd.push_str(&format!(" --columns {}", quote(c)));
        }
        if let Some(v) = &self.vehicle {
            cmd.push_str(&format!(" --vehicle {v}"));
        }
        match self.mass {
            Some(KnownMass::Kg(m)) => cmd.push_str(&format!(" --mass {m}")),
            Some(KnownMass::Vehicle) => cmd.push_str(" --mass vehicle"),
            None => {}
        }
        if let Some(r) = self.airframe_radius {
            cmd.push_str(&format!(" --airframe-radius {r}"));
        }
        for c in &self.custom {
            cmd.push_str(&format!(" --custom {c}"));
        }
        if let Some(f) = &self.noise_floor {
            let v: Vec<String> = f.iter().map(|x| format!("{x:e}")).collect();
            cmd.push_str(&format!(" --noise-floor {}", v.join(",")));
        }
        if let Some(dt) = self.resample {
            cmd.push_str(&format!(" --resample {dt}"));
        }
        if self.no_align {
            cmd.push_str(" --no-align");
        }
        for shift in &self.shift {
            cmd.push_str(&format!(" --shift {}", shift.replace(' ', "")));
        }
        if !effects.is_empty() {
            cmd.push_str(&format!(" --with {}", effects.join(",")));
        }
        cmd
    }
}

impl DiagnoseArgs {
    /// The command to run after this report, and why: with the effects the stepwise search
    /// added, the same command with `--with` all of them (before/after on the same log);
    /// otherwise, without `--report`, the same command with `--report` (the residual plots);
    /// otherwise with `--online` (does TAG-K converge to the fit?); then the model on a second
    /// flight (a joint diagnosis of several logs).
    pub fn next_step(&self, report: &Report) -> NextStep {
        let effects = &report.final_model.effects;
        let report_dir = self
            .report
            .as_ref()
            .map_or_else(|| "tagk-report".to_string(), |d| d.display().to_string());
        let with_report = format!("{} --report {report_dir}", self.command_for(effects));
        if !report.final_model.added.is_empty() {
            NextStep {
                command: with_report,
                why: format!(
                    "refit with {} and compare before/after",
                    report.final_model.added.join(", ")
                ),
            }
        } else if self.report.is_none() {
            NextStep {
                command: with_report,
                why: "nothing more to add: look at the residual plots".into(),
            }
        } else if !self.online {
            NextStep {
                command: format!("{with_report} --online"),
                why: "the model is adequate: check that TAG-K online converges to this fit".into(),
            }
        } else if self.stream.is_empty() && !self.logs.is_empty() {
            let mut joint = self.clone();
            joint.logs.push(PathBuf::from("SECOND_FLIGHT.csv"));
            NextStep {
                command: format!("{} --report {report_dir}", joint.command_for(effects)),
                why: "the model is adequate: check it on a second flight of the vehicle".into(),
            }
        } else {
            NextStep {
                command: with_report,
                why: "the model is adequate on this flight: diagnose the next flight the same way"
                    .into(),
            }
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

/// The vehicle of `--vehicle` (a preset or a file), if given.
///
/// # Errors
/// [`DiagnoseError::Vehicle`]: neither a preset nor a file, or an invalid file (naming the
/// file, and the line and column or the key).
pub fn load_vehicle(args: &DiagnoseArgs) -> Result<Option<Vehicle>, DiagnoseError> {
    Ok(args
        .vehicle
        .as_deref()
        .map(Vehicle::from_name_or_path)
        .transpose()?)
}

/// The log ready to fit: a log without the wrench gets it from its rotor speeds with the
/// vehicle (a logged wrench is kept as it is).
///
/// # Errors
/// [`DiagnoseError::Log`] with [`LogError::MissingWrench`](crate::diagnose::LogError) if the
/// log has no wrench and no vehicle or no rotor speeds to compute it; a rotor speed out of
/// range (line and column).
pub fn log_with_wrench(
    log: FlightLog,
    vehicle: Option<&Vehicle>,
) -> Result<FlightLog, DiagnoseError> {
    let mut log = log;
    if !log.has_wrench() && !log.is_empty() {
        match vehicle {
            Some(v) => log.compute_wrench_from_rotor_speeds(v)?,
            None => {
                return Err(crate::diagnose::LogError::MissingWrench {
                    has_rotor_speeds: log.rotor_speeds.is_some(),
                }
                .into());
            }
        }
    }
    Ok(log)
}

/// Builds the [`Plan`] from the arguments, checked against the log (loads `--vehicle`).
///
/// # Errors
/// A malformed custom specification or one naming a column the log lacks, an unknown effect
/// name, a mass that is not positive and finite, `--mass vehicle` without a vehicle mass, an
/// invalid vehicle, invalid options.
pub fn plan(args: &DiagnoseArgs, log: &FlightLog) -> Result<Plan, DiagnoseError> {
    plan_with_vehicle(args, log, load_vehicle(args)?.as_ref())
}

/// [`plan`] with the vehicle already loaded.
///
/// # Errors
/// As [`plan`].
pub fn plan_with_vehicle(
    args: &DiagnoseArgs,
    log: &FlightLog,
    vehicle: Option<&Vehicle>,
) -> Result<Plan, DiagnoseError> {
    let mut customs: Vec<EffectRef> = Vec::new();
    for spec in &args.custom {
        let custom = CustomEffect::parse(spec)?;
        if let Some(kind) = crate::dynamics::EffectKind::from_name(custom.name()) {
            return Err(DiagnoseError::BadCustomSpec {
                spec: spec.clone(),
                reason: format!(
                    "`{}` already names the built-in effect `{}`; give the custom effect another name",
                    custom.name(),
                    kind.name()
                ),
            });
        }
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
    let mass = match args.mass {
        None => None,
        Some(KnownMass::Kg(m)) => Some(m),
        Some(KnownMass::Vehicle) => match vehicle {
            Some(v) => Some(v.mass.ok_or_else(|| DiagnoseError::InvalidOption {
                field: "mass",
                reason: format!(
                    "`--mass vehicle`: vehicle `{}` has no `mass` prior; give the mass in kg",
                    v.name
                ),
            })?),
            None => {
                return Err(DiagnoseError::InvalidOption {
                    field: "mass",
                    reason: "`--mass vehicle` needs `--vehicle NAME|FILE`".into(),
                });
            }
        },
    };
    if let Some(m) = mass
        && !(m > 0.0 && m.is_finite())
    {
        return Err(DiagnoseError::InvalidModel(match args.mass {
            Some(KnownMass::Vehicle) => format!(
                "`--mass vehicle`: the vehicle's mass prior {m} kg is not positive and finite"
            ),
            _ => format!("`--mass {m}`: the known mass must be a positive, finite number of kg"),
        }));
    }
    if let Some(m) = mass {
        base = base.with_known_mass(m);
    }
    base.validate()?;
    let mut candidates = builtin_effects();
    candidates.extend(customs);
    let defaults = DiagnoseOptions::default();
    let airframe_radius = args
        .airframe_radius
        .or(vehicle.map(|v| v.airframe_radius))
        .unwrap_or(defaults.airframe_radius);
    let noise_floor =
        match &args.noise_floor {
            None => None,
            Some(v) => Some(<[f64; 6]>::try_from(v.as_slice()).map_err(|_| {
                DiagnoseError::InvalidOption {
                    field: "noise_floor",
                    reason: format!("{} values given, six needed (fx,fy,fz,tx,ty,tz)", v.len()),
                }
            })?),
        };
    let options = DiagnoseOptions {
        airframe_radius,
        candidates,
        noise_floor,
        max_steps: args.max_steps,
        ..defaults
    };
    options.validate()?;
    Ok(Plan {
        base,
        with,
        options,
    })
}

/// Runs the whole loop on a log in memory (what [`run_diagnose`] does after reading the file):
/// a log without the wrench gets it from `--vehicle` ([`log_with_wrench`]); `--resample`
/// resamples it ([`FlightLog::resample_linear`]); a log with gaps in its time stamps is split
/// at them and its segments are fitted jointly ([`Signals::from_log_split`]: nothing is
/// differentiated, lagged or shifted across a gap).
///
/// # Errors
/// As [`log_with_wrench`], [`plan`], [`run_loop`] and [`online_pass_with`].
pub fn diagnose_log(log: &FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    diagnose_cow_log(Cow::Borrowed(log), args)
}

/// [`diagnose_log`] of a log it may consume: each intermediate log (with the wrench,
/// resampled, aligned) replaces the one before it and the last becomes the signals' own
/// ([`Signals::from_owned_log_split`]), so that a long log is held about once instead of
/// three times.
///
/// # Errors
/// As [`diagnose_log`].
pub fn diagnose_owned_log(log: FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    diagnose_cow_log(Cow::Owned(log), args)
}

/// [`diagnose_log`] of a borrowed or owned log.
fn diagnose_cow_log(log: Cow<'_, FlightLog>, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    let vehicle = load_vehicle(args)?;
    let plan = plan_with_vehicle(args, &log, vehicle.as_ref())?;
    let log = if log.has_wrench() {
        log
    } else {
        Cow::Owned(log_with_wrench(log.into_owned(), vehicle.as_ref())?)
    };
    let sampling = SamplingFindings::of("", &log, args.resample);
    let log = match args.resample {
        Some(dt) => Cow::Owned(log.resample_linear(dt)?),
        None => log,
    };
    let (aligned, streams) = align_streams_owned(log.into_owned(), &args.align_options()?)?;
    let (s, _) = Signals::from_owned_log_split(aligned)?;
    let mut report = run_loop(&s, &plan.base, &plan.with, &plan.options)?;
    report.streams = streams;
    report.sampling = vec![sampling];
    if args.online {
        let online = OnlineOptions {
            arm_length: plan.options.airframe_radius,
            ..OnlineOptions::default()
        };
        report.online = Some(online_pass_with(&s, &report.last().fit, &online)?);
    }
    report.final_model.command = Some(args.command_for(&report.final_model.effects));
    report.next = Some(args.next_step(&report));
    Ok(report)
}

/// Runs the joint loop on several logs of one vehicle ([`run_logs`]): each gets its wrench
/// from `--vehicle` when it has none; the report compares each log's own staircase with the
/// joint one. A log with gaps is split at them and each segment of at least
/// [`MIN_ROWS`](crate::dynamics::log::MIN_ROWS) samples joins as a log of its own.
///
/// # Errors
/// As [`diagnose_log`], for any of the logs (naming its file).
pub fn diagnose_logs(
    logs: Vec<(String, FlightLog)>,
    args: &DiagnoseArgs,
) -> Result<Report, DiagnoseError> {
    let vehicle = load_vehicle(args)?;
    let Some((_, first)) = logs.first() else {
        return Err(DiagnoseError::InvalidOption {
            field: "logs",
            reason: "no flight log given".into(),
        });
    };
    let plan = plan_with_vehicle(args, first, vehicle.as_ref())?;
    let align = args.align_options()?;
    let mut parts = Vec::new();
    let mut streams = Vec::new();
    let mut sampling = Vec::new();
    for (name, log) in logs {
        let in_file = |e: DiagnoseError| match e {
            DiagnoseError::Log(source) => DiagnoseError::Log(crate::diagnose::LogError::InFile {
                path: name.clone(),
                source: Box::new(source),
            }),
            other => other,
        };
        let log = log_with_wrench(log, vehicle.as_ref()).map_err(in_file)?;
        sampling.push(SamplingFindings::of(name.clone(), &log, args.resample));
        let log = match args.resample {
            Some(dt) => log.resample_linear(dt).map_err(|e| in_file(e.into()))?,
            None => log,
        };
        let (log, timing) = align_streams_owned(log, &align).map_err(in_file)?;
        streams.extend(timing.into_iter().map(|mut t| {
            t.log = name.clone();
            t
        }));
        let segments = log.sampling().segments();
        if segments.len() == 1 {
            let s = Signals::from_log(&log).map_err(|e| in_file(e.into()))?;
            parts.push((name, s));
            continue;
        }
        // A log with gaps: each segment long enough to be fitted is a log of its own.
        log.validate().map_err(|e| in_file(e.into()))?;
        let count = segments.len();
        let min_rows = crate::dynamics::log::MIN_ROWS;
        if segments.iter().all(|r| r.len() < min_rows) {
            return Err(DiagnoseError::InvalidOption {
                field: "logs",
                reason: format!(
                    "{name}: its gaps leave no segment of at least {min_rows} samples to fit \
                     with the other logs (diagnose it alone: its segments are then fitted jointly)"
                ),
            });
        }
        for (k, r) in segments.into_iter().enumerate() {
            if r.len() < min_rows {
                continue;
            }
            let segment = log.slice(r.clone());
            let label = format!(
                "{name} (segment {} of {count}, t = {:.3}..{:.3} s)",
                k + 1,
                log.t[r.start],
                log.t[r.end - 1]
            );
            let s = Signals::from_log(&segment).map_err(|e| in_file(e.into()))?;
            parts.push((label, s));
        }
    }
    let mut report = run_logs(parts, &plan.base, &plan.with, &plan.options)?;
    report.streams = streams;
    report.sampling = sampling;
    report.final_model.command = Some(args.command_for(&report.final_model.effects));
    report.next = Some(args.next_step(&report));
    Ok(report)
}

/// Reads the flight: `LOG` as it is (the project's format), or with `--columns` and/or
/// `--stream` through the column mapping and the merge of the streams
/// ([`read_streams`]), whose report is returned.
///
/// # Errors
/// The log's or the mapping's errors (file, line, column; a missing quantity with the columns
/// that could provide it); no file at all.
pub fn read_log(args: &DiagnoseArgs) -> Result<(FlightLog, Option<MergeReport>), DiagnoseError> {
    if args.columns.is_none()
        && args.stream.is_empty()
        && let Some(path) = args.logs.first()
    {
        return Ok((FlightLog::from_csv_path(path)?, None));
    }
    let mapping = match &args.columns {
        Some(path) => ColumnMapping::from_path(path)?,
        None => ColumnMapping::default(),
    };
    let files: Vec<PathBuf> = if !args.stream.is_empty() {
        args.stream.clone()
    } else if let Some(log) = args.logs.first() {
        vec![log.clone()]
    } else {
        mapping.files.clone()
    };
    let vehicle = load_vehicle(args)?;
    let options = ReadOptions {
        vehicle: vehicle.as_ref(),
    };
    let (log, merge) = read_streams(&files, &mapping, &options)?;
    Ok((log, Some(merge)))
}

/// The merge report in a few lines (primary stream, sources, derived quantities, gaps,
/// dropped samples).
pub fn merge_summary(m: &MergeReport) -> String {
    let mut text = format!("time base: {}", m.primary);
    let sources: Vec<String> = m
        .sources
        .iter()
        .map(|(q, s)| format!("{q} <- {s}"))
        .collect();
    text.push_str(&format!("\nquantities: {}", sources.join(", ")));
    if !m.derived.is_empty() {
        text.push_str(&format!("\nderived: {}", m.derived.join(", ")));
    }
    for g in &m.gaps {
        text.push_str(&format!(
            "\ngap in {}: {:.3} s long at t = {:.3} s",
            g.stream, g.duration, g.start
        ));
    }
    if m.dropped_in_gaps + m.dropped_outside > 0 {
        text.push_str(&format!(
            "\ndropped: {} samples inside gaps, {} outside another stream's time range",
            m.dropped_in_gaps, m.dropped_outside
        ));
    }
    text
}

/// `tagk diagnose LOG [--vehicle NAME|FILE] [--with ...] [--json FILE] [--report DIR]
/// [--online] [--custom SPEC]`: reads the log (computing its wrench from the rotor speeds
/// with the vehicle if it has none), runs the loop, prints the summary and writes the requested files.
///
/// # Errors
/// Log validation errors (naming line and column), fit failures, output failures.
pub fn run_diagnose(args: &DiagnoseArgs) -> Result<(), DiagnoseError> {
    if args.logs.len() > 1 {
        let mut logs = Vec::new();
        for path in &args.logs {
            let one = DiagnoseArgs {
                logs: vec![path.clone()],
                ..args.clone()
            };
            let (log, _) = read_log(&one)?;
            logs.push((path.display().to_string(), log));
        }
        let report = diagnose_logs(logs, args)?;
        return write_outputs(&report, args);
    }
    let vehicle = load_vehicle(args)?;
    let (log, merge) = read_log(args)?;
    // Argument errors first, then the wrench (its errors name the file).
    plan_with_vehicle(args, &log, vehicle.as_ref())?;
    if !args.quiet
        && let Some(merge) = &merge
    {
        println!("{}", merge_summary(merge));
    }
    if let Some(v) = vehicle
        .as_ref()
        .filter(|_| !log.has_wrench() && !args.quiet)
    {
        println!(
            "wrench: computed from the rotor speeds w1..w4 with vehicle `{}`",
            v.name
        );
    }
    let log = log_with_wrench(log, vehicle.as_ref()).map_err(|e| match e {
        DiagnoseError::Log(source) => DiagnoseError::Log(crate::diagnose::LogError::InFile {
            path: args
                .logs
                .first()
                .map_or_else(|| "<streams>".to_string(), |p| p.display().to_string()),
            source: Box::new(source),
        }),
        other => other,
    })?;
    let report = diagnose_owned_log(log, args)?;
    write_outputs(&report, args)
}

/// Prints the report (unless `--quiet`) and writes the `--json` and `--report` files.
///
/// # Errors
/// [`DiagnoseError::Output`] naming the file that could not be written.
fn write_outputs(report: &Report, args: &DiagnoseArgs) -> Result<(), DiagnoseError> {
    if let Some(path) = &args.json {
        std::fs::write(path, report.to_json()?).map_err(|e| DiagnoseError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
    }
    let html = match &args.report {
        Some(dir) => Some(crate::diagnose::html::write_report(report, dir)?),
        None => None,
    };
    if !args.quiet {
        let mut table = report_table(report);
        if let Some(file) = html {
            // The report's path goes before the closing "next" lines.
            let at = table.rfind("\nnext (").unwrap_or(table.len());
            table.insert_str(at, &format!("report: {}\n", file.display()));
        }
        print!("{table}");
    }
    Ok(())
}
