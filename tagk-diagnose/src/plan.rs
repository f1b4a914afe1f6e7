//! From flight logs or files to a [`Report`] in one call: [`DiagnosisPlan`].
//!
//! The plan holds everything between "I have logs" and "I have a report": the inputs, the
//! vehicle, the effects to add, the known mass and the options. It checks them before any
//! work and then does what `tagk diagnose` does. The command line only fills it from its
//! arguments, prints the report and writes the files.

use std::path::PathBuf;
use std::sync::Arc;

use tagk_dynamics::EffectKind;
use tagk_dynamics::log_input::{ColumnMapping, MergeReport, ReadOptions, read_streams};
use tagk_dynamics::vehicle::Vehicle;

use crate::diagnose::{DiagnoseOptions, ProgressHook};
use crate::effects::{CustomEffect, Effect, EffectRef, builtin, builtin_by_name};
use crate::error::{DiagnoseError, LogError};
use crate::fit::Model;
use crate::glitches::SampleSource;
use crate::log::{FlightLog, MIN_ROWS};
use crate::online::{OnlineOptions, online_pass_with};
use crate::report::{Report, run_logs, run_loop};
use crate::sampling::SamplingFindings;
use crate::signals::Signals;
use crate::streams::{AlignOptions, StreamAlignment, align_streams_owned};
use crate::window::{TimeWindow, keep_windows, window_mask};

/// Samples between two windows of the online TAG-K pass of `tagk diagnose --online`: the
/// window length, so that windows touch without overlapping.
pub const DEFAULT_ONLINE_STRIDE: usize = tagk_dynamics::front_end::WINDOW_FRAMES;

/// The masses a known mass may take \[kg\]: from 0.1 g (below any vehicle that carries an
/// IMU) to 10 t (beyond any multirotor). A `--mass` outside is a typo or a wrong unit
/// (grams for kilograms), never a vehicle: it is refused, not fitted.
pub const KNOWN_MASS_RANGE: [f64; 2] = [1e-4, 1e4];

/// A known vehicle mass: a value, or the vehicle's mass prior.
///
/// It parses from `0.035` or `vehicle` (the command line's `--mass`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KnownMass {
    /// A mass \[kg\].
    Kg(f64),
    /// The `mass` prior of the plan's vehicle.
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

/// An effect to add to the rigid body: a name, a kind of the vocabulary, or an effect.
///
/// A name is a built-in name or alias (`linear-drag`, `delay`), the name of a custom effect
/// of the plan, or the name of one of its extra candidates.
#[derive(Debug, Clone)]
pub enum EffectChoice {
    /// By name.
    Name(String),
    /// A built-in effect.
    Kind(EffectKind),
    /// An effect as it is.
    Effect(EffectRef),
}

/// `From` a name or a specification (`&str`, `String`, `&String`) for an enum variant that
/// holds a `String`.
macro_rules! from_text {
    ($ty:ident :: $variant:ident) => {
        impl From<&str> for $ty {
            fn from(text: &str) -> Self {
                $ty::$variant(text.to_string())
            }
        }

        impl From<String> for $ty {
            fn from(text: String) -> Self {
                $ty::$variant(text)
            }
        }

        impl From<&String> for $ty {
            fn from(text: &String) -> Self {
                $ty::$variant(text.clone())
            }
        }
    };
}

from_text!(EffectChoice::Name);

impl From<EffectKind> for EffectChoice {
    fn from(kind: EffectKind) -> Self {
        EffectChoice::Kind(kind)
    }
}

impl From<EffectRef> for EffectChoice {
    fn from(effect: EffectRef) -> Self {
        EffectChoice::Effect(effect)
    }
}

/// A custom candidate effect: a specification `NAME=EXPR@CH[,CH...]` or a
/// [`CustomEffect`].
#[derive(Debug, Clone, PartialEq)]
pub enum CustomChoice {
    /// A specification, parsed by [`CustomEffect::parse`].
    Spec(String),
    /// An effect already built.
    Effect(CustomEffect),
}

from_text!(CustomChoice::Spec);

impl From<CustomEffect> for CustomChoice {
    fn from(effect: CustomEffect) -> Self {
        CustomChoice::Effect(effect)
    }
}

impl CustomChoice {
    /// The effect and its specification (for error messages).
    fn build(&self) -> Result<(CustomEffect, String), DiagnoseError> {
        match self {
            CustomChoice::Spec(spec) => Ok((CustomEffect::parse(spec)?, spec.clone())),
            CustomChoice::Effect(e) => Ok((e.clone(), e.spec())),
        }
    }
}

/// One flight in memory: its name, its log and, when read through a column mapping, how its
/// streams were merged.
#[derive(Debug, Clone)]
pub struct Flight {
    /// The flight's name: its file, or the name given with the log. Errors about the log
    /// name it; several flights are reported under it.
    pub name: String,
    /// The log.
    pub log: FlightLog,
    /// How the streams were merged, when read through a mapping
    /// ([`tagk_dynamics::log_input::read_streams`]).
    pub merge: Option<MergeReport>,
    /// The file and line each sample was read from, when read from files: the glitches
    /// name them ([`crate::glitches`]).
    pub source: Option<SampleSource>,
}

/// One input of a plan: a flight in memory, or the files of one.
#[derive(Debug, Clone)]
enum Input {
    /// In memory.
    Flight(Box<Flight>),
    /// One file: the project's format, or through the mapping if the plan has one.
    File(PathBuf),
    /// The stream files of one flight, merged through the mapping (the identity without one).
    Streams(Vec<PathBuf>),
}

/// What a plan asks for on a given log: the starting model, the effects to add and the
/// diagnosis options ([`DiagnosisPlan::resolve`]).
#[derive(Debug, Clone)]
pub struct ResolvedPlan {
    /// The starting model: the rigid body, with the known mass if given.
    pub base: Model,
    /// The effects to add, in order.
    pub with: Vec<EffectRef>,
    /// The diagnosis options: every built-in candidate, the custom ones, the extra ones.
    pub options: DiagnoseOptions,
}

/// Everything between "I have flight logs (or files)" and "I have a [`Report`]": what
/// `tagk diagnose` does, as a library call.
///
/// Build it step by step, then [`run`](DiagnosisPlan::run) it:
///
/// - inputs: logs in memory ([`log`](Self::log), [`named_log`](Self::named_log)), files
///   ([`file`](Self::file)), or the stream files of one flight ([`streams`](Self::streams)),
///   optionally through a column mapping ([`columns`](Self::columns));
/// - the vehicle ([`vehicle`](Self::vehicle)): a log without the wrench gets it from its rotor
///   speeds, and its airframe radius is the default;
/// - the effects to add ([`with_effects`](Self::with_effects)), custom candidates
///   ([`custom`](Self::custom)) and your own [`Effect`]s ([`candidate`](Self::candidate));
/// - the known mass ([`known_mass`](Self::known_mass)), the airframe radius, the noise per
///   channel, resampling, stream alignment, the online pass and the number of steps.
/// - time windows of the flights ([`window`](Self::window)) and a second flight that scores
///   every model of the staircase ([`validation_file`](Self::validation_file),
///   [`validation_log`](Self::validation_log)).
///
/// One flight is diagnosed alone: a log with gaps is split at them and its segments are
/// fitted jointly. Several flights are fitted jointly ([`run_logs`]): a flight with gaps joins
/// as one log per segment of at least [`MIN_ROWS`] samples.
///
/// The report's `final_model.command` and `next` stay empty: they name command-line flags.
///
/// ```
/// use tagk_diagnose::{DiagnosisPlan, EffectKind, FlightLog, LogSample};
/// use tagk_dynamics::nalgebra::{UnitQuaternion, Vector3};
/// use tagk_dynamics::{GRAVITY_WORLD, InertialParams, newton_euler};
///
/// // A 20 s log at 100 Hz of a 35 g body whose actuators also fight a linear drag.
/// let theta = InertialParams::from_array([0.035, 0.0, 0.0, 0.0, 1.7e-5, 0.0, 1.7e-5, 0.0, 0.0, 2.9e-5]);
/// let mut log = FlightLog::new();
/// for k in 0..2000 {
///     let t = k as f64 * 0.01;
///     let v = Vector3::new(0.5 * (0.8 * t).cos(), 0.4 * (1.1 * t).cos(), 0.1 * (0.5 * t).cos());
///     let acc = Vector3::new(-0.4 * (0.8 * t).sin(), -0.44 * (1.1 * t).sin(), -0.05 * (0.5 * t).sin());
///     let q = UnitQuaternion::from_euler_angles(0.2 * (1.3 * t).sin(), 0.15 * (0.9 * t).sin(), 0.3 * t);
///     let w = Vector3::new(0.26 * (1.3 * t).cos(), 0.135 * (0.9 * t).cos(), 0.3);
///     let wd = Vector3::new(-0.338 * (1.3 * t).sin(), -0.1215 * (0.9 * t).sin(), 0.0);
///     let a_body = q.inverse_transform_vector(&(acc - GRAVITY_WORLD));
///     let mut wrench = newton_euler(&theta, &a_body, &w, &wd).to_array();
///     let v_body = q.inverse_transform_vector(&v);
///     for c in 0..3 {
///         wrench[c] += 0.01 * v_body[c];
///     }
///     log.push(&LogSample {
///         t,
///         position: [0.0, 0.0, 1.0],
///         velocity: v.into(),
///         attitude: [q.w, q.i, q.j, q.k],
///         omega: w.into(),
///         wrench,
///         accel: Some(acc.into()),
///         omega_dot: Some(wd.into()),
///         rotor_speeds: None,
///     });
/// }
///
/// // The staircase finds the drag.
/// let report = DiagnosisPlan::new().log(log.clone()).max_steps(1).run()?;
/// assert_eq!(report.final_model.added, [EffectKind::LinearDrag.name()]);
///
/// // Add it: the residual falls.
/// let with_drag = DiagnosisPlan::new()
///     .log(log)
///     .with_effects(["linear-drag"])
///     .known_mass(0.035)
///     .max_steps(0)
///     .run()?;
/// let after = with_drag.after.as_ref().expect("an effect was added");
/// assert!(after.channels[0].rms < 0.01 * with_drag.before.channels[0].rms);
///
/// // Mistakes are caught before any work.
/// let err = DiagnosisPlan::new().with_effects(["anti-gravity"]).validate();
/// assert!(matches!(err, Err(tagk_diagnose::DiagnoseError::UnknownEffect(_))));
/// # Ok::<(), tagk_diagnose::DiagnoseError>(())
/// ```
#[derive(Debug, Clone)]
pub struct DiagnosisPlan {
    inputs: Vec<Input>,
    columns: Option<ColumnMapping>,
    vehicle: Option<Vehicle>,
    with: Vec<EffectChoice>,
    custom: Vec<CustomChoice>,
    candidates: Vec<EffectRef>,
    known_mass: Option<KnownMass>,
    airframe_radius: Option<f64>,
    noise_floor: Option<Vec<f64>>,
    resample: Option<f64>,
    align: AlignOptions,
    online: Option<usize>,
    max_steps: usize,
    accept_scales: bool,
    windows: Vec<TimeWindow>,
    validation: Option<Box<Input>>,
    progress: ProgressHook,
}

impl Default for DiagnosisPlan {
    fn default() -> Self {
        Self::new()
    }
}

impl DiagnosisPlan {
    /// A plan with no input, the rigid body and every option at its default (the defaults of
    /// `tagk diagnose`).
    pub fn new() -> Self {
        Self {
            inputs: Vec::new(),
            columns: None,
            vehicle: None,
            with: Vec::new(),
            custom: Vec::new(),
            candidates: Vec::new(),
            known_mass: None,
            airframe_radius: None,
            noise_floor: None,
            resample: None,
            align: AlignOptions::default(),
            online: None,
            max_steps: DiagnoseOptions::default().max_steps,
            accept_scales: false,
            windows: Vec::new(),
            validation: None,
            progress: ProgressHook::default(),
        }
    }

    /// Tells `hook` where the search for missing effects is ([`DiagnoseOptions::progress`]),
    /// e.g. for a progress bar. The report is the same without it.
    pub fn progress(mut self, hook: ProgressHook) -> Self {
        self.progress = hook;
        self
    }

    /// Goes on when a scale or consistency check fails ([`crate::scales`]): the finding is
    /// reported (severity `accepted`) instead of stopping the run with
    /// [`DiagnoseError::ScaleMismatch`] (the command line's `--accept-scales`). Default: off.
    pub fn accept_scales(mut self, accept: bool) -> Self {
        self.accept_scales = accept;
        self
    }

    /// Adds a flight in memory, without a name.
    pub fn log(self, log: FlightLog) -> Self {
        self.named_log("", log)
    }

    /// Adds a flight in memory. Errors about it name it; with several flights the report
    /// lists it under this name.
    pub fn named_log(mut self, name: impl Into<String>, log: FlightLog) -> Self {
        self.inputs.push(Input::Flight(Box::new(Flight {
            name: name.into(),
            log,
            merge: None,
            source: None,
        })));
        self
    }

    /// Adds several named flights in memory.
    pub fn named_logs(mut self, logs: impl IntoIterator<Item = (String, FlightLog)>) -> Self {
        for (name, log) in logs {
            self = self.named_log(name, log);
        }
        self
    }

    /// Adds a flight in one file: the project's CSV format (`docs/CONVENTIONS.md` §6), or
    /// read through the column mapping if the plan has one.
    pub fn file(mut self, path: impl Into<PathBuf>) -> Self {
        self.inputs.push(Input::File(path.into()));
        self
    }

    /// Adds one flight logged as several files, one per stream, merged onto the first one's
    /// time stamps (or the mapping's primary) through the column mapping (the identity
    /// without one).
    pub fn streams<P: Into<PathBuf>>(mut self, paths: impl IntoIterator<Item = P>) -> Self {
        self.inputs
            .push(Input::Streams(paths.into_iter().map(Into::into).collect()));
        self
    }

    /// Reads the files through this column mapping (`docs/COLUMN_MAPPING.md`). Without any
    /// other input, the plan reads the mapping's own stream files as one flight.
    pub fn columns(mut self, mapping: ColumnMapping) -> Self {
        self.columns = Some(mapping);
        self
    }

    /// The vehicle: a log without the wrench gets it from its rotor speeds; its airframe
    /// radius is the default; [`KnownMass::Vehicle`] takes its mass prior.
    pub fn vehicle(mut self, vehicle: Vehicle) -> Self {
        self.vehicle = Some(vehicle);
        self
    }

    /// Adds one effect to the rigid body.
    pub fn with_effect(mut self, effect: impl Into<EffectChoice>) -> Self {
        self.with.push(effect.into());
        self
    }

    /// Adds effects to the rigid body, in order. Names are trimmed; empty names are skipped.
    pub fn with_effects<E: Into<EffectChoice>>(
        mut self,
        effects: impl IntoIterator<Item = E>,
    ) -> Self {
        self.with.extend(effects.into_iter().map(Into::into));
        self
    }

    /// Adds a custom candidate: an expression of log columns on some channels
    /// ([`crate::effects::expression`]). Its name may not be a built-in effect's, and the log
    /// must have its columns.
    pub fn custom(mut self, effect: impl Into<CustomChoice>) -> Self {
        self.custom.push(effect.into());
        self
    }

    /// Adds an extra candidate: your own [`Effect`], ranked with the built-in ones.
    pub fn candidate(mut self, effect: EffectRef) -> Self {
        self.candidates.push(effect);
        self
    }

    /// Fixes the mass: a value in kg, or [`KnownMass::Vehicle`]. Without it the mass is fitted.
    /// [`DiagnosisPlan::validate`] refuses a mass outside [`KNOWN_MASS_RANGE`].
    pub fn known_mass(mut self, mass: impl Into<KnownMass>) -> Self {
        self.known_mass = Some(mass.into());
        self
    }

    /// The airframe radius \[m\] beyond which a fitted centre of mass is flagged. Default: the
    /// vehicle's, else [`DiagnoseOptions`]'s.
    pub fn airframe_radius(mut self, radius: f64) -> Self {
        self.airframe_radius = Some(radius);
        self
    }

    /// The measurement noise per channel `fx, fy, fz, tx, ty, tz` (N, N m): the noise floor
    /// of the stepwise search. Six values are needed. Default: from the data.
    pub fn noise_floor(mut self, noise: impl AsRef<[f64]>) -> Self {
        self.noise_floor = Some(noise.as_ref().to_vec());
        self
    }

    /// Resamples each flight onto a uniform grid of this step \[s\] before the fit, within
    /// each segment between gaps ([`FlightLog::resample_linear`]).
    pub fn resample(mut self, step: f64) -> Self {
        self.resample = Some(step);
        self
    }

    /// How the sensor streams are timed and aligned before the fit. Default: measured, and
    /// the IMU is the clock ([`AlignOptions::default`]).
    pub fn align(mut self, options: AlignOptions) -> Self {
        self.align = options;
        self
    }

    /// Runs TAG-K online over a single flight after the fit, one window every `stride`
    /// samples ([`online_pass_with`]; from the vehicle's mass and inertia priors when the
    /// vehicle has them, else from the batch estimate; `tagk diagnose --online` uses
    /// [`DEFAULT_ONLINE_STRIDE`]).
    /// Several flights get no online pass.
    pub fn online(mut self, stride: usize) -> Self {
        self.online = Some(stride);
        self
    }

    /// Keeps only the rows of each flight within this time window (log time, both ends
    /// included; [`crate::window`]). Several windows keep the rows within any of them; the
    /// time between them is a gap. A window outside a flight, or without a row, is refused
    /// ([`DiagnoseError::BadWindow`]) when the plan runs.
    pub fn window(mut self, window: TimeWindow) -> Self {
        self.windows.push(window);
        self
    }

    /// Scores every model of the staircase on a second flight in this file, read like the
    /// plan's flights (the same mapping and vehicle): the report's
    /// [`validation`](Report::validation). The models are not refitted on it
    /// ([`crate::validation`]). Windows do not apply to it.
    pub fn validation_file(mut self, path: impl Into<PathBuf>) -> Self {
        self.validation = Some(Box::new(Input::File(path.into())));
        self
    }

    /// [`DiagnosisPlan::validation_file`] with a flight in memory, named `name`.
    pub fn validation_log(mut self, name: impl Into<String>, log: FlightLog) -> Self {
        self.validation = Some(Box::new(Input::Flight(Box::new(Flight {
            name: name.into(),
            log,
            merge: None,
            source: None,
        }))));
        self
    }

    /// The most effects the stepwise search adds (default 5).
    pub fn max_steps(mut self, steps: usize) -> Self {
        self.max_steps = steps;
        self
    }

    /// Checks every setting that needs no log: custom specifications, effect names, the
    /// known mass, the options.
    ///
    /// # Errors
    /// As [`DiagnosisPlan::resolve`], except the check of the log's columns.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        self.resolve_on(None).map(|_| ())
    }

    /// What the plan asks for on `log`: the starting model, the effects to add, the options.
    /// Every setting is checked, and the custom effects against the log's columns.
    ///
    /// # Errors
    /// [`DiagnoseError::BadCustomSpec`]: a malformed custom specification, or one that takes
    /// a built-in effect's name; [`DiagnoseError::UnknownColumn`]: a custom effect naming a
    /// column the log lacks; [`DiagnoseError::UnknownEffect`]: an unknown effect name;
    /// [`DiagnoseError::InvalidOption`] (field `mass`): [`KnownMass::Vehicle`] without a
    /// vehicle or a mass prior, or a mass outside [`KNOWN_MASS_RANGE`];
    /// [`DiagnoseError::InvalidModel`]: a mass that is not positive and finite, an effect twice; [`DiagnoseError::InvalidOption`]: invalid options (e.g.
    /// `airframe_radius`, `noise_floor`).
    pub fn resolve(&self, log: &FlightLog) -> Result<ResolvedPlan, DiagnoseError> {
        self.resolve_on(Some(log))
    }

    /// [`DiagnosisPlan::resolve`], checking the custom effects' columns when given a log.
    fn resolve_on(&self, log: Option<&FlightLog>) -> Result<ResolvedPlan, DiagnoseError> {
        let mut customs: Vec<EffectRef> = Vec::new();
        for choice in &self.custom {
            let (custom, spec) = choice.build()?;
            if let Some(kind) = EffectKind::from_name(custom.name()) {
                return Err(DiagnoseError::BadCustomSpec {
                    spec,
                    reason: format!(
                        "`{}` already names the built-in effect `{}`; give the custom effect another name",
                        custom.name(),
                        kind.name()
                    ),
                });
            }
            if let Some(log) = log {
                custom.require_columns(log)?;
            }
            customs.push(Arc::new(custom));
        }
        let mut with = Vec::new();
        for choice in &self.with {
            with.push(match choice {
                EffectChoice::Name(name) => {
                    let name = name.trim();
                    if name.is_empty() {
                        continue;
                    }
                    match customs
                        .iter()
                        .chain(&self.candidates)
                        .find(|c| c.name() == name)
                    {
                        Some(c) => c.clone(),
                        None => builtin_by_name(name)?,
                    }
                }
                EffectChoice::Kind(kind) => builtin(*kind)?,
                EffectChoice::Effect(effect) => effect.clone(),
            });
        }
        let mut base = Model::rigid_body();
        if let Some(m) = self.mass()? {
            base = base.with_known_mass(m);
        }
        base.validate()?;
        let noise_floor = match &self.noise_floor {
            None => None,
            Some(v) => Some(<[f64; 6]>::try_from(v.as_slice()).map_err(|_| {
                DiagnoseError::InvalidOption {
                    field: "noise_floor",
                    reason: format!("{} values given, six needed (fx,fy,fz,tx,ty,tz)", v.len()),
                }
            })?),
        };
        // Every built-in candidate, the vehicle's airframe (radius, rotor plane, vertical limit
        // of the centre of mass) and mass prior, then the explicit airframe radius.
        let mut options = DiagnoseOptions::default();
        if let Some(v) = &self.vehicle {
            options = options.with_vehicle(v);
        }
        if let Some(r) = self.airframe_radius {
            options.airframe_radius = r;
            options.com_vertical_limit = 0.5 * r;
        }
        options.candidates.extend(customs);
        options.candidates.extend(self.candidates.iter().cloned());
        options.noise_floor = noise_floor;
        options.max_steps = self.max_steps;
        options.progress = self.progress.clone();
        options.validate()?;
        Ok(ResolvedPlan {
            base,
            with,
            options,
        })
    }

    /// The known mass \[kg\], checked: positive and finite, within [`KNOWN_MASS_RANGE`], the
    /// vehicle's prior if asked.
    fn mass(&self) -> Result<Option<f64>, DiagnoseError> {
        let mass = match self.known_mass {
            None => return Ok(None),
            Some(KnownMass::Kg(m)) => m,
            Some(KnownMass::Vehicle) => match &self.vehicle {
                Some(v) => v.mass.ok_or_else(|| DiagnoseError::InvalidOption {
                    field: "mass",
                    reason: format!(
                        "`--mass vehicle`: vehicle `{}` has no `mass` prior; give the mass in kg",
                        v.name
                    ),
                })?,
                None => {
                    return Err(DiagnoseError::InvalidOption {
                        field: "mass",
                        reason: "`--mass vehicle` needs `--vehicle NAME|FILE`".into(),
                    });
                }
            },
        };
        if !(mass > 0.0 && mass.is_finite()) {
            return Err(DiagnoseError::InvalidModel(match self.known_mass {
                Some(KnownMass::Vehicle) => format!(
                    "`--mass vehicle`: the vehicle's mass prior {mass} kg is not positive and finite"
                ),
                _ => format!(
                    "`--mass {mass}`: the known mass must be a positive, finite number of kg"
                ),
            }));
        }
        let [lo, hi] = KNOWN_MASS_RANGE;
        if !(lo..=hi).contains(&mass) {
            // 1e-300 as `1e-300`, not as three hundred digits.
            let shown = if (1e-3..1e6).contains(&mass.abs()) {
                format!("{mass}")
            } else {
                format!("{mass:e}")
            };
            let given = match self.known_mass {
                Some(KnownMass::Vehicle) => {
                    format!("`--mass vehicle` (the vehicle's prior {shown} kg)")
                }
                _ => format!("`--mass {shown}`"),
            };
            return Err(DiagnoseError::InvalidOption {
                field: "mass",
                reason: format!(
                    "{given} is outside any vehicle's mass ({lo:e} to {hi:e} kg): a typo or another unit (grams?)"
                ),
            });
        }
        Ok(Some(mass))
    }

    /// Reads every file of the plan into memory. A plan with a column mapping and no input
    /// reads the mapping's stream files as one flight. [`DiagnosisPlan::flights`] then lists
    /// every flight, with the merge report of those read through the mapping.
    ///
    /// # Errors
    /// The file's or the mapping's errors (naming the file, line and column; a quantity no
    /// stream provides, with the columns that could).
    pub fn read(mut self) -> Result<Self, DiagnoseError> {
        if self.inputs.is_empty()
            && let Some(mapping) = &self.columns
        {
            self.inputs.push(Input::Streams(mapping.files.clone()));
        }
        let inputs = std::mem::take(&mut self.inputs);
        for input in inputs {
            let flight = self.read_input(input)?;
            self.inputs.push(Input::Flight(Box::new(flight)));
        }
        Ok(self)
    }

    /// One input read into memory.
    fn read_input(&self, input: Input) -> Result<Flight, DiagnoseError> {
        Ok(match input {
            Input::Flight(flight) => *flight,
            Input::File(path) => match &self.columns {
                None => {
                    let name = path.display().to_string();
                    let read = FlightLog::read_csv_path(&path)?;
                    // Columns not read are reported as a merge of one stream reports
                    // them (a custom effect naming one is told why it is missing).
                    let merge = (!read.unread_columns.is_empty()).then(|| MergeReport {
                        primary: name.clone(),
                        unread_columns: read.unread_columns,
                        ..MergeReport::default()
                    });
                    Flight {
                        source: Some(SampleSource::of_file(name.clone(), read.lines)),
                        name,
                        log: read.log,
                        merge,
                    }
                }
                Some(_) => self.read_streams(std::slice::from_ref(&path))?,
            },
            Input::Streams(paths) => self.read_streams(&paths)?,
        })
    }

    /// The flight cut to the plan's windows ([`crate::window`]), its sample sources with it.
    fn windowed(&self, mut flight: Flight) -> Result<Flight, DiagnoseError> {
        if self.windows.is_empty() {
            return Ok(flight);
        }
        let keep = window_mask(&flight.log, &self.windows)?;
        flight.log = keep_windows(flight.log, &self.windows)?;
        if let Some(source) = &mut flight.source
            && source.lines.len() == keep.len()
        {
            source.lines = source
                .lines
                .iter()
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(l, _)| *l)
                .collect();
        }
        Ok(flight)
    }

    /// Every model of `report`'s staircase scored on the validation flight, conditioned as
    /// the plan's flights (wrench, glitches, resampling, alignment), without the windows.
    fn validation(
        &self,
        report: &Report,
        plan: &ResolvedPlan,
    ) -> Result<Option<crate::validation::Validation>, DiagnoseError> {
        let Some(input) = &self.validation else {
            return Ok(None);
        };
        let flight = self.read_input((**input).clone())?;
        let name = if flight.name.is_empty() {
            "validation log".to_string()
        } else {
            flight.name.clone()
        };
        let named = |e: DiagnoseError| in_file(&name, e);
        let c = self.condition(&name, flight.log, flight.source.as_ref(), named, named)?;
        let (s, _) = Signals::from_owned_log_split(c.log).map_err(named)?;
        let effects: Vec<EffectRef> = plan
            .with
            .iter()
            .chain(&plan.options.candidates)
            .cloned()
            .collect();
        let steps = report
            .step_fits
            .iter()
            .map(|fit| {
                Ok(crate::validation::ValidationStep {
                    model: fit.label.clone(),
                    rms: crate::validation::validation_rms(fit, &effects, &s)?,
                })
            })
            .collect::<Result<Vec<_>, DiagnoseError>>()?;
        Ok(Some(crate::validation::Validation {
            log: name,
            samples: s.len(),
            steps,
        }))
    }

    /// One flight from its stream files, through the mapping (the identity without one).
    fn read_streams(&self, paths: &[PathBuf]) -> Result<Flight, DiagnoseError> {
        let identity = ColumnMapping::default();
        let mapping = self.columns.as_ref().unwrap_or(&identity);
        let options = ReadOptions {
            vehicle: self.vehicle.as_ref(),
        };
        let (log, mut merge) = read_streams(paths, mapping, &options)?;
        let name = paths
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ");
        // The primary stream by the path given (the merge names streams by file name).
        let file = paths
            .iter()
            .find(|p| {
                p.file_name()
                    .is_some_and(|f| f.to_string_lossy() == merge.primary)
            })
            .map_or_else(|| merge.primary.clone(), |p| p.display().to_string());
        let source = SampleSource {
            file,
            lines: std::mem::take(&mut merge.lines),
            primary: merge.primary.clone(),
            sources: merge.sources.clone(),
        };
        Ok(Flight {
            name,
            log,
            merge: Some(merge),
            source: Some(source),
        })
    }

    /// The flights in memory, in the order given (every flight after
    /// [`DiagnosisPlan::read`]).
    pub fn flights(&self) -> impl Iterator<Item = &Flight> {
        self.inputs.iter().filter_map(|input| match input {
            Input::Flight(flight) => Some(&**flight),
            _ => None,
        })
    }

    /// The flights in memory, in the order given, out of the plan (every flight after
    /// [`DiagnosisPlan::read`]).
    pub fn into_flights(mut self) -> Vec<Flight> {
        self.take_flights()
    }

    /// Takes the flights in memory out of the plan, in the order given; the plan keeps no
    /// input.
    fn take_flights(&mut self) -> Vec<Flight> {
        std::mem::take(&mut self.inputs)
            .into_iter()
            .filter_map(|input| match input {
                Input::Flight(flight) => Some(*flight),
                _ => None,
            })
            .collect()
    }

    /// Runs the plan: checks it, reads the files, diagnoses one flight alone or several
    /// jointly, and returns the report.
    ///
    /// For each flight: the wrench from the rotor speeds if the log has none (with the
    /// vehicle), the sampling findings, the resampling, the stream alignment. Then one flight
    /// is split at its gaps and fitted ([`run_loop`]), with the online pass if asked; several
    /// flights are fitted jointly ([`run_logs`]).
    ///
    /// It is [`DiagnosisPlan::validate`], [`DiagnosisPlan::read`], then
    /// [`DiagnosisPlan::run_read`].
    ///
    /// # Errors
    /// As [`DiagnosisPlan::resolve`] (against the first flight) and [`DiagnosisPlan::read`];
    /// [`DiagnoseError::InvalidOption`] (field `logs`) for no flight, for two flights with the
    /// same samples (the same file twice, or identical copies), or for a flight among
    /// several whose gaps leave no segment of [`MIN_ROWS`] samples; a log without the wrench
    /// and no vehicle or no rotor speeds ([`LogError::MissingWrench`], in
    /// [`LogError::InFile`] naming the flight); the log's, the alignment's, the fit's and the
    /// online pass's errors.
    pub fn run(self) -> Result<Report, DiagnoseError> {
        self.validate()?;
        self.read()?.run_read()
    }

    /// [`DiagnosisPlan::run`] of a plan already read ([`DiagnosisPlan::read`]), without
    /// checking it first. A caller can then look at the flights before the work. A file not
    /// read yet is read first.
    ///
    /// # Errors
    /// As [`DiagnosisPlan::run`].
    pub fn run_read(self) -> Result<Report, DiagnoseError> {
        let mut settings = self.read()?;
        let mut flights = settings.take_flights();
        match flights.len() {
            0 => Err(DiagnoseError::InvalidOption {
                field: "logs",
                reason: "no flight log given".into(),
            }),
            1 => settings.run_one(flights.pop().expect("one flight")),
            _ => settings.run_joint(flights),
        }
    }

    /// The flights read and made ready as for a diagnosis, without fitting: the wrench from
    /// the rotor speeds if a log has none (with the vehicle), the glitches excluded, the
    /// resampling, the stream alignment (the shifts given, or the measured ones) and the scale
    /// checks. What `tagk compare` predicts on. Returns each flight's name and log.
    ///
    /// # Errors
    /// As [`DiagnosisPlan::read`]; a log without the wrench and no vehicle or no rotor speeds
    /// (naming the flight); the alignment's and the scale checks' errors.
    pub fn conditioned_flights(self) -> Result<Vec<(String, FlightLog)>, DiagnoseError> {
        let mut settings = self.read()?;
        let flights = settings.take_flights();
        flights
            .into_iter()
            .map(|f| {
                let name = f.name;
                let named = |e: DiagnoseError| in_file(&name, e);
                let c = settings.condition(&name, f.log, f.source.as_ref(), named, named)?;
                Ok((name, c.log))
            })
            .collect()
    }

    /// A flight's log ready to fit, and what was found on the way: the wrench from the rotor
    /// speeds if the log has none ([`log_with_wrench`]), the sampling findings (named
    /// `label`), the glitches excluded ([`crate::glitches`], located by `source`), the
    /// resampling, the stream alignment and the scale checks ([`DiagnosisPlan::check_scales`]).
    /// The wrench's errors pass through `wrench_error`, the resampling's and the alignment's
    /// through `error`.
    fn condition(
        &self,
        label: &str,
        log: FlightLog,
        source: Option<&SampleSource>,
        wrench_error: impl FnOnce(DiagnoseError) -> DiagnoseError,
        error: impl Fn(DiagnoseError) -> DiagnoseError,
    ) -> Result<Conditioned, DiagnoseError> {
        let log = log_with_wrench(log, self.vehicle.as_ref()).map_err(wrench_error)?;
        let sampling = SamplingFindings::of(label, &log, self.resample);
        let glitches = crate::glitches::screen_located(label, &log, source);
        let (log, excluded) = crate::glitches::exclude(log, &glitches);
        let log = match self.resample {
            Some(dt) => log.resample_linear(dt).map_err(|e| error(e.into()))?,
            None => log,
        };
        let (log, streams) = align_streams_owned(log, &self.align).map_err(error)?;
        let scale_checks = self.check_scales(label, &log)?;
        let (log, accelerometer_offset) =
            crate::accel_offset::remove_vertical_offset(label, log, self.align.auto);
        Ok(Conditioned {
            log,
            streams,
            accelerometer_offset,
            sampling,
            glitches,
            excluded,
            scale_checks,
        })
    }

    /// [`DiagnosisPlan::resolve`] on a flight: a custom effect that names a column its merge
    /// did not read (a cell is not a number) says so.
    ///
    /// # Errors
    /// As [`DiagnosisPlan::resolve`]; [`DiagnoseError::UnreadColumn`] for such a column.
    pub fn resolve_flight(&self, flight: &Flight) -> Result<ResolvedPlan, DiagnoseError> {
        self.resolve(&flight.log)
            .map_err(|e| match (e, &flight.merge) {
                (
                    DiagnoseError::UnknownColumn {
                        effect,
                        column,
                        available,
                    },
                    Some(merge),
                ) => match merge.unread_columns.iter().find(|u| u.column == column) {
                    Some(u) => DiagnoseError::UnreadColumn {
                        effect,
                        column,
                        stream: u.stream.clone(),
                        line: u.line,
                        value: u.value.clone(),
                    },
                    None => DiagnoseError::UnknownColumn {
                        effect,
                        column,
                        available,
                    },
                },
                (e, _) => e,
            })
    }

    /// One flight alone: split at its gaps, its segments fitted jointly.
    fn run_one(&self, flight: Flight) -> Result<Report, DiagnoseError> {
        let plan = self.resolve_flight(&flight)?;
        let mut flight = self.windowed(flight)?;
        let inputs: Vec<MergeReport> = flight.merge.take().into_iter().collect();
        let name = flight.name;
        // A flight without a name is a log in memory: its errors stay as they are.
        let wrench_error = |e| match name.as_str() {
            "" => e,
            name => in_file(name, e),
        };
        let from_rotor_speeds = !flight.log.has_wrench() || flight.log.rotor_speeds.is_some();
        let c = self.condition("", flight.log, flight.source.as_ref(), wrench_error, |e| e)?;
        let (s, _) = Signals::from_owned_log_split(c.log)?;
        let mut report = run_loop(&s, &plan.base, &plan.with, &plan.options)?;
        let mut findings = c.scale_checks;
        findings.extend(self.check_fit("", &report, from_rotor_speeds)?);
        report.streams = c.streams;
        report.accelerometer_offsets = c.accelerometer_offset.into_iter().collect();
        report.sampling = vec![c.sampling];
        report.inputs = inputs;
        report.scale_checks = findings;
        report.glitches = c.glitches;
        report.glitch_samples_excluded = c.excluded;
        if let Some(stride) = self.online {
            // From the vehicle's nominal parameters when it has them (a pass that converges,
            // as in flight), otherwise from the batch estimate (a pass that stays).
            let online = OnlineOptions {
                stride,
                prior: self.vehicle.as_ref().and_then(|v| v.inertial_prior()),
                arm_length: plan.options.airframe_radius,
                ..OnlineOptions::default()
            };
            report.online = Some(online_pass_with(&s, &report.last().fit, &online)?);
        }
        report.windows = self.windows.iter().map(|w| [w.start, w.end]).collect();
        report.validation = self.validation(&report, &plan)?;
        Ok(report)
    }

    /// Several flights jointly; a flight with gaps joins as one log per long enough segment.
    fn run_joint(&self, flights: Vec<Flight>) -> Result<Report, DiagnoseError> {
        refuse_duplicates(&flights)?;
        let plan = self.resolve_flight(&flights[0])?;
        let mut parts = Vec::new();
        let mut streams = Vec::new();
        let mut offsets = Vec::new();
        let mut sampling = Vec::new();
        let mut inputs = Vec::new();
        let mut findings = Vec::new();
        let mut glitches = Vec::new();
        let mut excluded = 0;
        let mut from_rotor_speeds = false;
        for flight in flights {
            let Flight {
                name,
                log,
                merge,
                source,
            } = self.windowed(flight)?;
            inputs.extend(merge);
            let in_file = |e: DiagnoseError| in_file(&name, e);
            from_rotor_speeds |= !log.has_wrench() || log.rotor_speeds.is_some();
            let c = self.condition(&name, log, source.as_ref(), in_file, in_file)?;
            let (log, timing) = (c.log, c.streams);
            offsets.extend(c.accelerometer_offset);
            sampling.push(c.sampling);
            findings.extend(c.scale_checks);
            glitches.extend(c.glitches);
            excluded += c.excluded;
            streams.extend(timing.into_iter().map(|mut t| {
                t.log = name.clone();
                t
            }));
            let segments = log.sampling().segments();
            if segments.len() == 1 {
                let s = Signals::from_owned_log(log).map_err(|e| in_file(e.into()))?;
                parts.push((name, s));
                continue;
            }
            // A log with gaps: each segment long enough to be fitted is a log of its own.
            log.validate().map_err(|e| in_file(e.into()))?;
            let count = segments.len();
            if segments.iter().all(|r| r.len() < MIN_ROWS) {
                return Err(DiagnoseError::InvalidOption {
                    field: "logs",
                    reason: format!(
                        "{name}: its gaps leave no segment of at least {MIN_ROWS} samples to fit \
                         with the other logs (diagnose it alone: its segments are then fitted jointly)"
                    ),
                });
            }
            for (k, r) in segments.into_iter().enumerate() {
                if r.len() < MIN_ROWS {
                    continue;
                }
                let label = format!(
                    "{name} (segment {} of {count}, t = {:.3}..{:.3} s)",
                    k + 1,
                    log.t[r.start],
                    log.t[r.end - 1]
                );
                // A segment of the validated log, of at least `MIN_ROWS` samples, is valid.
                let s = Signals::from_segment(log.slice(r)).map_err(|e| in_file(e.into()))?;
                parts.push((label, s));
            }
        }
        let mut report = run_logs(parts, &plan.base, &plan.with, &plan.options)?;
        findings.extend(self.check_fit("", &report, from_rotor_speeds)?);
        report.streams = streams;
        report.accelerometer_offsets = offsets;
        report.sampling = sampling;
        report.inputs = inputs;
        report.scale_checks = findings;
        report.glitches = glitches;
        report.glitch_samples_excluded = excluded;
        report.windows = self.windows.iter().map(|w| [w.start, w.end]).collect();
        report.validation = self.validation(&report, &plan)?;
        Ok(report)
    }

    /// The scale checks of one flight's log before the fit ([`crate::scales::check_log`])
    /// against the known mass, else the vehicle's.
    ///
    /// # Errors
    /// [`DiagnoseError::ScaleMismatch`] unless the scales are accepted.
    fn check_scales(
        &self,
        name: &str,
        log: &FlightLog,
    ) -> Result<Vec<crate::scales::ScaleFinding>, DiagnoseError> {
        let mass = self.mass()?.or(self.vehicle.as_ref().and_then(|v| v.mass));
        let mut found = crate::scales::check_log(name, log, mass);
        crate::scales::settle(&mut found, self.accept_scales)?;
        Ok(found)
    }

    /// The checks of the fit against the vehicle file ([`crate::scales::check_fit`]), none
    /// without a vehicle; `from_rotor_speeds`: the log has rotor speeds or no wrench of its
    /// own (its wrench may come from the vehicle's rotors).
    ///
    /// # Errors
    /// [`DiagnoseError::ScaleMismatch`] unless the scales are accepted.
    fn check_fit(
        &self,
        name: &str,
        report: &Report,
        from_rotor_speeds: bool,
    ) -> Result<Vec<crate::scales::ScaleFinding>, DiagnoseError> {
        let Some(vehicle) = &self.vehicle else {
            return Ok(Vec::new());
        };
        let mut found = crate::scales::check_fit(
            name,
            report,
            vehicle,
            self.known_mass.is_none(),
            from_rotor_speeds,
        );
        crate::scales::settle(&mut found, self.accept_scales)?;
        Ok(found)
    }
}

/// A flight's log ready to fit and what was found on the way ([`DiagnosisPlan::condition`]).
struct Conditioned {
    /// The log: wrench computed, glitches excluded, resampled and aligned as asked.
    log: FlightLog,
    /// The timing of each sensor stream against the pose, and the offsets removed.
    streams: Vec<StreamAlignment>,
    /// The accelerometer's offset against the velocity, and its vertical part removed.
    accelerometer_offset: Option<crate::accel_offset::AccelerometerOffset>,
    /// How the log is sampled.
    sampling: SamplingFindings,
    /// The glitches found and excluded.
    glitches: Vec<crate::glitches::Glitch>,
    /// Samples excluded around the glitches.
    excluded: usize,
    /// The scale checks before the fit that found something.
    scale_checks: Vec<crate::scales::ScaleFinding>,
}

/// A hash of every sample of a log (time, motion, wrench, the optional signals and the extra
/// columns with their names), to find the same data given twice under two names.
fn data_hash(log: &FlightLog) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    let mut floats = |v: &mut dyn Iterator<Item = f64>| {
        for x in v {
            x.to_bits().hash(&mut h);
        }
        u64::MAX.hash(&mut h);
    };
    floats(&mut log.t.iter().copied());
    floats(&mut log.position.iter().flatten().copied());
    floats(&mut log.velocity.iter().flatten().copied());
    floats(&mut log.attitude.iter().flatten().copied());
    floats(&mut log.omega.iter().flatten().copied());
    floats(&mut log.wrench.iter().flatten().copied());
    floats(&mut log.accel.iter().flatten().flatten().copied());
    floats(&mut log.omega_dot.iter().flatten().flatten().copied());
    floats(&mut log.rotor_speeds.iter().flatten().flatten().copied());
    for (name, column) in &log.extra {
        name.hash(&mut h);
        for x in column {
            x.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

/// Refuses a joint diagnosis in which two flights hold the same data (the same file given
/// twice, or two files with identical samples): counted twice, one flight would narrow every
/// interval by √2 and look like a confirmation. Compared by a hash of the samples, then
/// sample by sample.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (field `logs`) naming both flights.
fn refuse_duplicates(flights: &[Flight]) -> Result<(), DiagnoseError> {
    let hashes: Vec<u64> = flights.iter().map(|f| data_hash(&f.log)).collect();
    for (j, b) in flights.iter().enumerate() {
        for (k, a) in flights[..j].iter().enumerate() {
            if hashes[k] == hashes[j] && a.log == b.log {
                let same = if a.name == b.name {
                    format!("{} is given twice", a.name)
                } else {
                    format!(
                        "{} and {} hold the same data (identical samples)",
                        a.name, b.name
                    )
                };
                return Err(DiagnoseError::InvalidOption {
                    field: "logs",
                    reason: format!(
                        "{same}: one flight counted twice would narrow every interval by √2; give each flight once"
                    ),
                });
            }
        }
    }
    Ok(())
}

/// A log error of the flight `name`, wrapped to name it ([`LogError::InFile`]).
fn in_file(name: &str, e: DiagnoseError) -> DiagnoseError {
    match e {
        DiagnoseError::Log(source) => DiagnoseError::Log(LogError::in_file(name, source)),
        other => other,
    }
}

/// The log ready to fit: a log without the wrench gets it from its rotor speeds with the
/// vehicle (a logged wrench is kept as it is).
fn log_with_wrench(
    mut log: FlightLog,
    vehicle: Option<&Vehicle>,
) -> Result<FlightLog, DiagnoseError> {
    if !log.has_wrench() && !log.is_empty() {
        match vehicle {
            Some(v) => log.compute_wrench_from_rotor_speeds(v)?,
            None => {
                return Err(LogError::MissingWrench {
                    has_rotor_speeds: log.rotor_speeds.is_some(),
                }
                .into());
            }
        }
    }
    Ok(log)
}
