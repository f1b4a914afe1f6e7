//! `tagk diagnose`: compare the rigid-body model with a flight log, find the missing effect,
//! add effects with `--with` and print the before/after comparison.

use std::path::PathBuf;

pub use crate::diagnose::KnownMass;
use crate::diagnose::format::shell_join;
use crate::diagnose::{
    AlignOptions, DEFAULT_ONLINE_STRIDE, DiagnoseError, DiagnosisPlan, EffectKind, FlightLog,
    NextStep, Report, ResolvedPlan, TimeWindow, parse_shift, report_table,
};
use crate::dynamics::log_input::{ColumnMapping, InputError, MergeReport};
use crate::dynamics::vehicle::Vehicle;

/// Arguments of tagk diagnose.
#[derive(Debug, Clone, clap::Args)]
#[command(after_help = effects_help())]
pub struct DiagnoseArgs {
    /// Flight log(s) (CSV: columns, units and frames as in docs/CONVENTIONS.md §6 of the tagk
    /// repository). With --columns each is read through the column mapping. Several logs of
    /// one vehicle are diagnosed jointly (one set of parameters and effect coefficients). Each
    /// log's own staircase and parameters are compared with the joint ones. A log whose mass or
    /// effect coefficients differ beyond their intervals (another vehicle state) is named and left
    /// out of the joint fit. The same data twice is refused.
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
    /// Write every number as JSON to this file. Its directory must exist: checked before the
    /// log is read.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a self-contained HTML report with SVG plots into this directory (created, with
    /// its parents, before the log is read).
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Also run TAG-K online over the log, as the simulator's tuned TAG-K flies, and compare
    /// it with the batch fit of the model. It sees the fz and torque rows only. The model's
    /// fitted effects are removed from the measured wrench first. TAG-K starts from the
    /// --vehicle's mass and inertia priors when it has both, else from the batch estimate.
    /// Rows are scaled by the fit's residual noise, columns by that start. Each window stops
    /// at the noise. It reports the online mass against the batch mass.
    #[arg(long)]
    pub online: bool,
    /// Custom candidate effect: NAME=EXPR@CH[,CH...], an expression of log columns on
    /// wrench channels; repeatable. Quote it for the shell, e.g. --custom
    /// drag_x='vbx*abs(vbx)'@fx or vbat=vbat*fz@fz. EXPR: columns (vx, wz, w1, an extra
    /// column), vbx..vbz (body-frame velocity), d(COL) (time derivative), numbers, PI, the
    /// operators + - * / ^, pow min max (two arguments), abs sign sqrt sin cos tan atan tanh
    /// exp ln.
    /// Units are checked: a sum of different units is refused. The coefficient's unit is
    /// the channel's over the expression's (docs/CONVENTIONS.md §7.4).
    #[arg(long = "custom", value_name = "SPEC")]
    pub custom: Vec<String>,
    /// Keep only this time window of each log, START..END in seconds of log time (the t
    /// column; e.g. 5..40); repeatable: rows within any window are kept, the time between
    /// windows is a gap. A window outside the log or without a row is refused.
    #[arg(long = "window", value_name = "START..END")]
    pub window: Vec<TimeWindow>,
    /// Score every model of the staircase on this second log of the same vehicle (read
    /// with the same --columns mapping and --vehicle; no window applies): its residual RMS
    /// per channel, the models not refitted. In the summary, the JSON (validation) and the
    /// HTML report.
    #[arg(long, value_name = "FILE")]
    pub validate: Option<PathBuf>,
    /// Vehicle description: a preset (crazyflie-2.1; tagk vehicle list) or a vehicle file
    /// (TOML, docs/VEHICLE.md). A log without the wrench fx..tz then gets it from its rotor
    /// speeds w1..w4 (rad/s) (a logged wrench is used as it is); the vehicle's airframe
    /// radius becomes the default --airframe-radius.
    #[arg(long, value_name = "NAME|FILE")]
    pub vehicle: Option<String>,
    /// Known vehicle mass in kg, or vehicle for the mass prior of --vehicle (fixes the
    /// mass; makes thrust-gain identifiable). Without it the mass is fitted. A mass outside
    /// 1e-4..1e4 kg is refused (a typo or grams).
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
    /// the velocity onto it before the fit (docs/CONVENTIONS.md §7.2). The accelerometer's
    /// vertical offset against the velocity is then also reported only, not removed (§7.1).
    #[arg(long)]
    pub no_align: bool,
    /// Shift a stream by a known time offset in seconds, positive when the stream is late
    /// (e.g. pose=-0.012); repeatable. Streams: gyro, accelerometer, velocity, actuators,
    /// pose. With a shift given, nothing is moved automatically.
    #[arg(long = "shift", value_name = "STREAM=SECONDS")]
    pub shift: Vec<String>,
    /// Write the final model (vehicle, inertial parameters with their covariance, effects
    /// with their coefficients, sensing, the logs' hashes) to this model file
    /// (docs/MODEL_FILE.md); tagk compare --model reads it.
    #[arg(long, value_name = "FILE")]
    pub save_model: Option<PathBuf>,
    /// Write one model file per step into this directory (created): the rigid body, the
    /// --with model, then each staircase step (step-0-….toml, step-1-….toml, …), so that
    /// tagk compare LOG --model DIR/*.toml shows the error fall.
    #[arg(long, value_name = "DIR")]
    pub save_steps: Option<PathBuf>,
    /// Most effects the stepwise search adds.
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub max_steps: usize,
    /// Do not print the terminal summary, nor the progress (shown on a terminal only).
    #[arg(long)]
    pub quiet: bool,
    /// Diagnose a robot arm's joint torques instead of a flight: a shipped robot (ur5,
    /// panda, planar_2link) or a URDF file. The log then has the columns t, q1..qN, dq1..dqN,
    /// optional ddq1..ddqN, tau1..tauN (SI units, radians; docs/ARM_LOG.md). --noise-floor then
    /// gives one torque noise per joint (N m); --json and --max-steps apply.
    #[arg(
        long,
        value_name = "NAME|URDF",
        conflicts_with_all = ["columns", "stream", "with", "online", "custom", "window", "validate",
            "vehicle", "mass", "resample", "shift", "save_model", "save_steps", "report"]
    )]
    pub robot: Option<String>,
    /// Go on when a scale or consistency check fails (a gain of 57.3 between the gyro and
    /// the attitude's rate, a fitted mass 10× the vehicle's, …): the finding is reported
    /// instead of stopping (docs/CONVENTIONS.md §7.3).
    #[arg(long)]
    pub accept_scales: bool,
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
    text.push_str(concat!(
        "\nCustom terms (--custom NAME=EXPR@CH[,CH...]; docs/CONVENTIONS.md §7.4):\n",
        "  --custom drag_x='vbx*abs(vbx)'@fx    signed square of the body-frame speed on fx\n",
        "  --custom lag='d(wz)'@tz             time derivative of a column (as accelerations)\n",
        "  --custom vbat=vbat*fz@fz            product of columns (the older syntax)\n",
        "  Units: each column's SI unit; a sum, min or max of different units, or sin/exp/...\n",
        "  of a quantity that is not a pure number, is refused. -x^2 is (-x)^2.\n",
        "Windows and validation: --window 5..40 (repeatable), --validate SECOND_LOG.csv\n",
    ));
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
            window: Vec::new(),
            validate: None,
            vehicle: None,
            mass: None,
            airframe_radius: None,
            noise_floor: None,
            resample: None,
            max_steps: 5,
            save_model: None,
            save_steps: None,
            quiet: false,
            no_align: false,
            shift: Vec::new(),
            accept_scales: false,
            robot: None,
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

    /// The arguments that reproduce the final model of a report, unquoted: these arguments
    /// with `--with` set to every effect of the final model (the files and flags as given).
    pub fn command_args(&self, effects: &[String]) -> Vec<String> {
        let path = |p: &std::path::Path| p.to_string_lossy().into_owned();
        let mut args = vec!["tagk".to_string(), "diagnose".to_string()];
        args.extend(self.logs.iter().map(|l| path(l)));
        for stream in &self.stream {
            args.extend(["--stream".into(), path(stream)]);
        }
        if let Some(c) = &self.columns {
            args.extend(["--columns".into(), path(c)]);
        }
        if let Some(v) = &self.vehicle {
            args.extend(["--vehicle".into(), v.clone()]);
        }
        match self.mass {
            Some(KnownMass::Kg(m)) => args.extend(["--mass".into(), m.to_string()]),
            Some(KnownMass::Vehicle) => args.extend(["--mass".into(), "vehicle".into()]),
            None => {}
        }
        if let Some(r) = self.airframe_radius {
            args.extend(["--airframe-radius".into(), r.to_string()]);
        }
        for c in &self.custom {
            args.extend(["--custom".into(), c.clone()]);
        }
        for w in &self.window {
            args.extend(["--window".into(), w.to_string()]);
        }
        if let Some(v) = &self.validate {
            args.extend(["--validate".into(), path(v)]);
        }
        if let Some(f) = &self.noise_floor {
            let v: Vec<String> = f.iter().map(|x| format!("{x:e}")).collect();
            args.extend(["--noise-floor".into(), v.join(",")]);
        }
        if let Some(dt) = self.resample {
            args.extend(["--resample".into(), dt.to_string()]);
        }
        if self.no_align {
            args.push("--no-align".into());
        }
        for shift in &self.shift {
            args.extend(["--shift".into(), shift.replace(' ', "")]);
        }
        if !effects.is_empty() {
            args.extend(["--with".into(), effects.join(",")]);
        }
        args
    }

    /// The command line that reproduces the final model of a report ([`Self::command_args`]),
    /// safe to paste into a POSIX shell. Every argument with a character outside
    /// `[A-Za-z0-9_./=,:@%+-]` is single-quoted ([`shell_join`]): a file name with a space, `;`
    /// or `$(…)`, a `--custom` specification with `*`.
    pub fn command_for(&self, effects: &[String]) -> String {
        shell_join(self.command_args(effects))
    }
}

impl DiagnoseArgs {
    /// The command to run after this report, and why:
    ///
    /// - with the effects the stepwise search added, the same command with `--with` all of them
    ///   (before/after on the same log);
    /// - otherwise, without `--report`, the same command with `--report` (the residual plots);
    /// - otherwise with `--online` (does TAG-K converge to the fit?);
    /// - then the model on a second flight (a joint diagnosis of several logs).
    pub fn next_step(&self, report: &Report) -> NextStep {
        let effects = &report.final_model.effects;
        let report_dir = self.report.as_ref().map_or_else(
            || "tagk-report".to_string(),
            |d| d.to_string_lossy().into_owned(),
        );
        let report_dir = shell_join(["--report", &report_dir]);
        let with_report = format!("{} {report_dir}", self.command_for(effects));
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
                command: format!("{} {report_dir}", joint.command_for(effects)),
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

    /// The plan these arguments ask for, without its inputs: the effects (`--with`,
    /// `--custom`), the vehicle, the mass and the options.
    ///
    /// # Errors
    /// [`DiagnoseError::InvalidOption`] (field `shift`) for a malformed `--shift`.
    pub fn settings(&self, vehicle: Option<Vehicle>) -> Result<DiagnosisPlan, DiagnoseError> {
        let mut plan = DiagnosisPlan::new()
            .with_effects(&self.with)
            .align(self.align_options()?)
            .max_steps(self.max_steps)
            .accept_scales(self.accept_scales);
        for spec in &self.custom {
            plan = plan.custom(spec);
        }
        for w in &self.window {
            plan = plan.window(*w);
        }
        if let Some(v) = &self.validate {
            plan = plan.validation_file(v);
        }
        if let Some(v) = vehicle {
            plan = plan.vehicle(v);
        }
        if let Some(m) = self.mass {
            plan = plan.known_mass(m);
        }
        if let Some(r) = self.airframe_radius {
            plan = plan.airframe_radius(r);
        }
        if let Some(noise) = &self.noise_floor {
            plan = plan.noise_floor(noise);
        }
        if let Some(dt) = self.resample {
            plan = plan.resample(dt);
        }
        if self.online {
            plan = plan.online(DEFAULT_ONLINE_STRIDE);
        }
        Ok(plan)
    }

    /// `plan` with the flights: each of `logs` (or the `--stream` files as one flight),
    /// through the `--columns` mapping if given.
    fn with_inputs(
        &self,
        mut plan: DiagnosisPlan,
        logs: &[PathBuf],
    ) -> Result<DiagnosisPlan, DiagnoseError> {
        if let Some(path) = &self.columns {
            plan = plan.columns(ColumnMapping::from_path(path)?);
        }
        if self.stream.is_empty() {
            for log in logs {
                plan = plan.file(log);
            }
        } else {
            plan = plan.streams(&self.stream);
        }
        Ok(plan)
    }

    /// The report with what only the command line knows: the command that reproduces the
    /// final model and the next step.
    fn finish(&self, mut report: Report) -> Report {
        report.final_model.command = Some(self.command_for(&report.final_model.effects));
        report.next = Some(self.next_step(&report));
        report
    }
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

/// What the arguments ask for on a given log ([`DiagnosisPlan::resolve`]; loads `--vehicle`).
///
/// # Errors
/// A malformed custom specification or one naming a column the log lacks, an unknown effect
/// name, a mass that is not positive and finite, `--mass vehicle` without a vehicle mass, an
/// invalid vehicle, invalid options.
pub fn plan(args: &DiagnoseArgs, log: &FlightLog) -> Result<ResolvedPlan, DiagnoseError> {
    args.settings(load_vehicle(args)?)?.resolve(log)
}

/// Runs the whole loop on a log in memory ([`DiagnosisPlan::run`] with the arguments'
/// settings), with the command and the next step filled in.
///
/// # Errors
/// As [`DiagnosisPlan::run`].
pub fn diagnose_log(log: &FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    diagnose_owned_log(log.clone(), args)
}

/// [`diagnose_log`] of a log it consumes (no copy of a long log).
///
/// # Errors
/// As [`diagnose_log`].
pub fn diagnose_owned_log(log: FlightLog, args: &DiagnoseArgs) -> Result<Report, DiagnoseError> {
    let report = args.settings(load_vehicle(args)?)?.log(log).run()?;
    Ok(args.finish(report))
}

/// Runs the joint loop on several named logs of one vehicle ([`DiagnosisPlan::run`]): the
/// report compares each log's own staircase with the joint one.
///
/// # Errors
/// As [`DiagnosisPlan::run`], for any of the logs (naming it).
pub fn diagnose_logs(
    logs: Vec<(String, FlightLog)>,
    args: &DiagnoseArgs,
) -> Result<Report, DiagnoseError> {
    let report = args.settings(load_vehicle(args)?)?.named_logs(logs).run()?;
    Ok(args.finish(report))
}

/// Reads the flight ([`DiagnosisPlan::read`]): the first `LOG` as it is (the project's
/// format), or with `--columns` and/or `--stream` through the column mapping and the merge of
/// the streams, whose report is returned.
///
/// # Errors
/// The log's or the mapping's errors (file, line, column; a missing quantity with the columns
/// that could provide it); no file at all.
pub fn read_log(args: &DiagnoseArgs) -> Result<(FlightLog, Option<MergeReport>), DiagnoseError> {
    let mut plan = DiagnosisPlan::new();
    if let Some(v) = load_vehicle(args)? {
        plan = plan.vehicle(v);
    }
    let plan = args.with_inputs(plan, &args.logs[..args.logs.len().min(1)])?;
    match plan.read()?.into_flights().into_iter().next() {
        Some(flight) => Ok((flight.log, flight.merge)),
        None => Err(InputError::NoStream.into()),
    }
}

/// The merge report in a few lines (primary stream, sources, derived quantities, each
/// stream, gaps, dropped samples, warnings): [`MergeReport::text`].
pub fn merge_summary(m: &MergeReport) -> String {
    m.text()
}

/// `tagk diagnose LOG [--vehicle NAME|FILE] [--with ...] [--json FILE] [--report DIR]
/// [--online] [--custom SPEC]`: fills the [`DiagnosisPlan`] from the arguments, reads the
/// flights (for one flight, prints how its streams were merged and whether its wrench comes
/// from the rotor speeds), runs it, prints the summary and writes the requested files.
///
/// # Errors
/// [`DiagnoseError::Output`] for a `--json` or `--report` destination that cannot be written,
/// before any file is read ([`check_outputs`]); log validation errors (naming line and
/// column), fit failures, output failures.
pub fn run_diagnose(args: &DiagnoseArgs) -> Result<(), DiagnoseError> {
    check_outputs(args)?;
    if let Some(robot) = &args.robot {
        return run_arm(args, robot);
    }
    let bar = super::progress::Progress::spinner(!args.quiet, "reading the log");
    let result = diagnose_with_progress(args, &bar);
    bar.finish();
    write_outputs(&result?, args)
}

/// [`run_diagnose`] up to the report, its model files saved, with `bar` telling where it is
/// (reading, the search's step and candidate, saving).
fn diagnose_with_progress(
    args: &DiagnoseArgs,
    bar: &super::progress::Progress,
) -> Result<Report, DiagnoseError> {
    let vehicle = load_vehicle(args)?;
    let shown = bar.clone();
    let hook = crate::diagnose::ProgressHook::new(move |p| {
        shown.message(format!(
            "step {}: judging {} ({}/{})",
            p.effects + 1,
            p.judging,
            p.done + 1,
            p.total
        ));
    });
    let plan = args
        .with_inputs(args.settings(vehicle.clone())?, &args.logs)?
        .progress(hook);
    plan.validate()?;
    let plan = plan.read()?;
    let flights: Vec<_> = plan.flights().collect();
    if let [flight] = flights[..] {
        // Argument errors first, then what was read; the wrench's errors name the file.
        plan.resolve_flight(flight)?;
        if !args.quiet {
            bar.suspend(|| {
                if let Some(merge) = &flight.merge {
                    println!("{}", merge_summary(merge));
                }
                if let Some(v) = vehicle.as_ref().filter(|_| !flight.log.has_wrench()) {
                    println!(
                        "wrench: computed from the rotor speeds w1..w4 with vehicle `{}`",
                        v.name
                    );
                }
            });
        }
    } else if !args.quiet {
        // Several flights: each merge's warnings (the whole reports are in the JSON and HTML).
        bar.suspend(|| {
            for flight in &flights {
                for w in flight.merge.iter().flat_map(|m| &m.warnings) {
                    println!("{}: warning: {w}", flight.name);
                }
            }
        });
    }
    bar.message("conditioning the log and fitting the rigid body");
    let report = args.finish(plan.run_read()?);
    bar.message("saving");
    save_models(&report, args, vehicle)?;
    Ok(report)
}

/// What a model file records besides the fit, from the arguments: the vehicle, the logs'
/// hashes, the custom specifications, the known mass and the sensing options.
///
/// # Errors
/// [`DiagnoseError::ModelFile`] for a log that cannot be read for its hash.
pub fn model_context(
    args: &DiagnoseArgs,
    vehicle: Option<Vehicle>,
) -> Result<crate::diagnose::ModelContext, DiagnoseError> {
    let mut files: Vec<&PathBuf> = args.logs.iter().chain(&args.stream).collect();
    if files.is_empty()
        && let Some(c) = &args.columns
    {
        files.push(c);
    }
    let logs = files
        .into_iter()
        .map(|p| crate::diagnose::LogSource::of_file(p))
        .collect::<Result<_, _>>()?;
    let known_mass = match args.mass {
        Some(KnownMass::Kg(m)) => Some(m),
        Some(KnownMass::Vehicle) => vehicle.as_ref().and_then(|v| v.mass),
        None => None,
    };
    Ok(crate::diagnose::ModelContext {
        vehicle,
        logs,
        custom: args.custom.clone(),
        known_mass,
        align: !args.no_align,
        resample: args.resample,
    })
}

/// Writes `--save-model` and `--save-steps`.
///
/// # Errors
/// [`DiagnoseError::ModelFile`] naming the file that could not be written.
fn save_models(
    report: &Report,
    args: &DiagnoseArgs,
    vehicle: Option<Vehicle>,
) -> Result<(), DiagnoseError> {
    if args.save_model.is_none() && args.save_steps.is_none() {
        return Ok(());
    }
    let context = model_context(args, vehicle)?;
    if let Some(path) = &args.save_model {
        crate::diagnose::ModelFile::from_diagnosis(report, &context).write(path)?;
    }
    if let Some(dir) = &args.save_steps {
        for (k, file) in crate::diagnose::ModelFile::steps(report, &context)
            .iter()
            .enumerate()
        {
            let last = file
                .effects
                .last()
                .map_or("rigid-body", |e| e.name.as_str());
            let name: String = last
                .chars()
                .map(|c| {
                    if c.is_ascii_alphanumeric() || c == '-' {
                        c
                    } else {
                        '_'
                    }
                })
                .collect();
            file.write(&dir.join(format!("step-{k}-{name}.toml")))?;
        }
    }
    Ok(())
}

/// Checks the `--json` and `--report` destinations before any work, so that a typo in them
/// costs no fit. The JSON file's directory must exist and the file must not be a directory.
/// The report directory is created (with its parents) and its `index.html` must not be a
/// directory.
///
/// # Errors
/// [`DiagnoseError::Output`] naming the destination and what is wrong with it.
pub fn check_outputs(args: &DiagnoseArgs) -> Result<(), DiagnoseError> {
    let output = |path: &std::path::Path, message: String| DiagnoseError::Output {
        path: path.display().to_string(),
        message,
    };
    if let Some(path) = &args.json {
        if path.is_dir() {
            return Err(output(
                path,
                "is a directory, not a file (--json FILE)".into(),
            ));
        }
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => std::path::Path::new("."),
        };
        if !parent.is_dir() {
            return Err(output(
                path,
                format!(
                    "cannot write the JSON (--json): directory {} does not exist",
                    parent.display()
                ),
            ));
        }
        if std::fs::metadata(path).is_ok_and(|m| m.permissions().readonly()) {
            return Err(output(path, "is read-only (--json)".into()));
        }
    }
    if let Some(path) = &args.save_model {
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => std::path::Path::new("."),
        };
        if !parent.is_dir() || path.is_dir() {
            return Err(output(
                path,
                format!(
                    "cannot write the model file (--save-model): {} is not a directory, or the file is one",
                    parent.display()
                ),
            ));
        }
    }
    if let Some(dir) = &args.save_steps {
        std::fs::create_dir_all(dir).map_err(|e| {
            output(
                dir,
                format!("cannot create the directory (--save-steps): {e}"),
            )
        })?;
    }
    if let Some(dir) = &args.report {
        std::fs::create_dir_all(dir).map_err(|e| {
            output(
                dir,
                format!("cannot create the report directory (--report): {e}"),
            )
        })?;
        let file = dir.join(crate::diagnose::html::REPORT_FILE);
        if file.is_dir() {
            return Err(output(
                &file,
                "is a directory, not a file (--report DIR)".into(),
            ));
        }
    }
    Ok(())
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

/// The robot of `--robot`: a shipped robot by name, else a URDF file.
///
/// # Errors
/// [`DiagnoseError::InvalidModel`] naming the robot when it is neither a shipped name nor a
/// readable, valid URDF file.
pub fn load_robot(robot: &str) -> Result<crate::dynamics::KinematicTree, DiagnoseError> {
    use crate::dynamics::KinematicTree;
    use crate::dynamics::robots::{SHIPPED_ROBOTS, shipped_urdf};
    let tree = match shipped_urdf(robot) {
        Some(urdf) => KinematicTree::from_urdf_str(urdf),
        None => {
            let path = std::path::Path::new(robot);
            if !path.is_file() {
                return Err(DiagnoseError::InvalidModel(format!(
                    "--robot {robot}: no such URDF file, and not a shipped robot ({})",
                    SHIPPED_ROBOTS.join(", ")
                )));
            }
            KinematicTree::from_urdf_file(path)
        }
    };
    tree.map_err(|e| DiagnoseError::InvalidModel(format!("--robot {robot}: {e}")))
}

/// `tagk diagnose LOG --robot NAME|URDF`: the joint-torque diagnosis
/// ([`crate::diagnose::arm`]) of one joint-space log; prints the summary and writes `--json`.
///
/// # Errors
/// The robot's ([`load_robot`]), the log's (naming file, line and column), the diagnosis's,
/// and [`DiagnoseError::Output`] when the JSON cannot be written.
pub fn run_arm(args: &DiagnoseArgs, robot: &str) -> Result<(), DiagnoseError> {
    use crate::diagnose::arm::{ArmOptions, diagnose_arm};
    use crate::dynamics::JointLog;
    let tree = load_robot(robot)?;
    let [log_path] = args.logs.as_slice() else {
        return Err(DiagnoseError::InvalidOption {
            field: "LOG",
            reason: format!("--robot diagnoses one joint log, {} given", args.logs.len()),
        });
    };
    let log = JointLog::from_csv_path(log_path)?;
    let options = ArmOptions {
        max_steps: args.max_steps,
        noise: args.noise_floor.clone(),
        ..ArmOptions::default()
    };
    let report = diagnose_arm(&tree, &log, &options)?;
    if let Some(path) = &args.json {
        std::fs::write(path, report.to_json()?).map_err(|e| DiagnoseError::Output {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
    }
    if !args.quiet {
        print!("{}", report.table());
    }
    Ok(())
}
