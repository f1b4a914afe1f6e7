//! The `tagk simulate` command: fly one trial from flags and write its flight log (the CSV
//! format of [`tagk_dynamics::log`]). The binary flattens [`SimulateArgs`], calls
//! [`run_simulate`] and prints the returned [`SimulateSummary`].

use std::fmt;
use std::path::PathBuf;

use tagk_diagnose::{ModelFile, ModelFileError};
use tagk_dynamics::EffectKind;
use tagk_dynamics::vehicle::Vehicle;
use tagk_dynamics::{QuadrotorModel, SafetyGate};
use tagk_sim::{
    Adaptation, EstimatorKind, EstimatorSpec, LogRate, NoiseLevel, Payload, PayloadSchedule,
    PayloadShape, PlantEffects, SensingProfile, SimConfig, SimError, TrajectoryKind,
};

use crate::model_plant::{ModelPlantError, SkippedEffect, model_plant};

use super::{
    effect_parser, estimator_parser, log_rate_parser, noise_parser, sensing_parser,
    trajectory_parser,
};

/// Payload choice on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PayloadArg {
    /// No payload.
    None,
    /// The protocol's random payload (30–50 % of the mass, attached at 4–6 s, removed at
    /// 12–14 s).
    Protocol,
    /// The payload given by --payload-mass, --payload-offset, --attach, --remove.
    Fixed,
}

/// Flags of tagk simulate.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// Reference trajectory.
    #[arg(long, value_parser = trajectory_parser(), default_value = "figure8")]
    pub trajectory: TrajectoryKind,
    /// Flight duration (s).
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Velocity/acceleration noise level of the paper's protocol (added to the sensing
    /// profile's noise, in quadrature).
    #[arg(long, value_parser = noise_parser(), default_value = "none")]
    pub noise: NoiseLevel,
    /// Sensing profile: the vehicle's gyro, accelerometer, velocity and rotor-speed noise and
    /// biases (ideal: none; realistic: a Crazyflie 2.1 in flight; realistic-calibrated:
    /// the same with the accelerometer bias calibrated away; cf21-brushless: the Crazyflie 2.1
    /// Brushless, its rotor speeds read as eRPM telemetry).
    #[arg(long, value_parser = sensing_parser(), default_value = "ideal")]
    pub sensing: SensingProfile,
    /// Rate-gyro noise, standard deviation per axis (rad/s) (replaces the sensing profile's).
    #[arg(long)]
    pub gyro_noise: Option<f64>,
    /// Reference yaw rate (rad/s): the heading turns at this rate from 0 (default 0: the
    /// heading stays along world x).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub yaw_rate: f64,
    /// Payload events.
    #[arg(long, value_enum, default_value_t = PayloadArg::None)]
    pub payload: PayloadArg,
    /// Fixed payload mass (kg).
    #[arg(long, default_value_t = FIXED_PAYLOAD_DEFAULTS.0, allow_negative_numbers = true)]
    pub payload_mass: f64,
    /// Fixed payload offset in the body frame (m), as x,y,z.
    #[arg(long, value_delimiter = ',', default_values_t = FIXED_PAYLOAD_DEFAULTS.1, allow_negative_numbers = true)]
    pub payload_offset: Vec<f64>,
    /// Fixed payload attach time (s).
    #[arg(long, default_value_t = FIXED_PAYLOAD_DEFAULTS.2)]
    pub attach: f64,
    /// Fixed payload removal time (s) (omit to keep it).
    #[arg(long)]
    pub remove: Option<f64>,
    /// Plant effects to switch on at their Crazyflie defaults (repeatable; the names of the
    /// effect vocabulary shared with tagk diagnose --with).
    #[arg(long = "effect", value_parser = effect_parser())]
    pub effects: Vec<EffectKind>,
    /// Fly an identified model: a model file written by tagk diagnose --save-model
    /// (docs/MODEL_FILE.md), its vehicle, inertial parameters and effects with their fitted
    /// coefficients. Not with --vehicle or --effect: the model gives both.
    #[arg(long, conflicts_with_all = ["vehicle", "effects"])]
    pub model: Option<PathBuf>,
    /// The vehicle to fly: a preset name (tagk vehicle list) or a vehicle file
    /// (docs/VEHICLE.md) with k_f and the mass and inertia keys (default: the
    /// Crazyflie 2.1). Its airframe radius is the safety gate's largest centre-of-mass offset.
    #[arg(long)]
    pub vehicle: Option<String>,
    /// Online estimator feeding the controller (omit: the controller keeps the nominal
    /// parameters).
    #[arg(long, value_parser = estimator_parser())]
    pub estimator: Option<EstimatorKind>,
    /// Height of the trajectory centre (m) (default: random 0.8–1.5 m).
    #[arg(long)]
    pub altitude: Option<f64>,
    /// Log samples: control (one per 50 Hz control interval, at its midpoint) or physics
    /// (one per 2 ms physics step: instantaneous IMU-style samples, no angular-acceleration
    /// columns).
    #[arg(long, value_parser = log_rate_parser(), default_value = "control")]
    pub log_rate: LogRate,
    /// Output CSV path (the flight-log format of docs/CONVENTIONS.md §6).
    #[arg(long, short, default_value = "flight.csv")]
    pub output: PathBuf,
    /// Print nothing but errors: no progress bar (shown on a terminal only), no summary.
    #[arg(long)]
    pub quiet: bool,
}

/// Why `tagk simulate` failed.
#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    /// The flags or the flight.
    #[error("{0}")]
    Sim(#[from] SimError),
    /// The model file of `--model` cannot be read.
    #[error("{0}")]
    ModelFile(#[from] ModelFileError),
    /// The model of `--model` cannot be flown.
    #[error("{0}")]
    Model(#[from] ModelPlantError),
}

impl SimulateArgs {
    /// The flight configuration these flags describe, and the effects of `--model` not flown.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a payload offset without three values;
    /// [`SimError::UnsupportedEffect`] for an effect the simulator cannot produce;
    /// [`SimError::Vehicle`], [`SimError::NotFlyable`] for a vehicle it cannot read or fly;
    /// [`SimulateError::ModelFile`], [`SimulateError::Model`] for a model file that cannot be
    /// read or flown ([`model_plant`]).
    pub fn config_and_skipped(&self) -> Result<(SimConfig, Vec<SkippedEffect>), SimulateError> {
        let config = self.config()?;
        match &self.model {
            None => Ok((config, Vec::new())),
            Some(path) => {
                let model = ModelFile::from_path(path)?;
                let plant = model_plant(&model)?;
                let mut config = plant.configure(config);
                if let Some(vehicle) = &model.vehicle {
                    config.gate =
                        SafetyGate::for_vehicle(vehicle.airframe_radius, &config.vehicle.params);
                }
                Ok((config, plant.skipped))
            }
        }
    }

    /// The flight configuration these flags describe, without `--model` (see
    /// [`SimulateArgs::config_and_skipped`]).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a payload offset without three values;
    /// [`SimError::UnsupportedEffect`] for an effect the simulator cannot produce;
    /// [`SimError::Vehicle`], [`SimError::NotFlyable`] for a vehicle it cannot read or fly.
    pub fn config(&self) -> Result<SimConfig, SimError> {
        self.check_payload_flags()?;
        let payload = match self.payload {
            PayloadArg::None => PayloadSchedule::None,
            PayloadArg::Protocol => PayloadSchedule::Protocol,
            PayloadArg::Fixed => {
                let [x, y, z] = self.payload_offset[..] else {
                    return Err(SimError::InvalidParameter {
                        name: "payload_offset",
                        value: self.payload_offset.len() as f64,
                        reason: "needs exactly three values x,y,z",
                    });
                };
                PayloadSchedule::Fixed(vec![Payload {
                    mass: self.payload_mass,
                    offset: [x, y, z],
                    shape: PayloadShape::PointMass,
                    attach_time: self.attach,
                    remove_time: self.remove,
                }])
            }
        };
        let effects = self
            .effects
            .iter()
            .try_fold(PlantEffects::none(), |e, k| e.with(*k))?;
        let adaptation = match self.estimator {
            Some(k) => Adaptation::Estimator(EstimatorSpec::new(k)),
            None => Adaptation::Nominal,
        };
        let mut base = SimConfig::default();
        if let Some(name) = &self.vehicle {
            let vehicle = Vehicle::from_name_or_path(name)?;
            base.vehicle = QuadrotorModel::from_vehicle(&vehicle)?;
            base.gate = SafetyGate::for_vehicle(vehicle.airframe_radius, &base.vehicle.params);
        }
        Ok(SimConfig {
            trajectory: self.trajectory,
            duration: self.duration,
            seed: self.seed,
            noise: self.noise,
            sensing: match self.gyro_noise {
                Some(g) => self.sensing.sensing().with_gyro_noise(g),
                None => self.sensing.sensing(),
            },
            yaw_rate: self.yaw_rate,
            payload,
            effects,
            adaptation,
            altitude: self.altitude,
            record_log: true,
            log_rate: self.log_rate,
            flight_stack: self.sensing.flight_stack(base.flight_stack),
            ..base
        })
    }
}

/// The defaults of the fixed-payload flags (`--payload-mass`, `--payload-offset`,
/// `--attach`), to tell a flag given without `--payload fixed`.
const FIXED_PAYLOAD_DEFAULTS: (f64, [f64; 3], f64) = (0.014, [0.008, 0.0, 0.0], 5.0);

impl SimulateArgs {
    /// The fixed-payload flags: a mass that is positive and finite, and no flag of the fixed
    /// payload changed from its default without `--payload fixed` (it would be ignored).
    fn check_payload_flags(&self) -> Result<(), SimError> {
        if !(self.payload_mass > 0.0 && self.payload_mass.is_finite()) {
            return Err(SimError::NonPositiveMass {
                what: "`--payload-mass`: the payload",
                mass: self.payload_mass,
            });
        }
        let (mass, offset, attach) = FIXED_PAYLOAD_DEFAULTS;
        if self.payload != PayloadArg::Fixed {
            let changed = [
                ("payload_mass", self.payload_mass != mass, self.payload_mass),
                (
                    "payload_offset",
                    self.payload_offset[..] != offset[..],
                    self.payload_offset.first().copied().unwrap_or(f64::NAN),
                ),
                ("attach", self.attach != attach, self.attach),
                (
                    "remove",
                    self.remove.is_some(),
                    self.remove.unwrap_or(f64::NAN),
                ),
            ];
            if let Some((name, _, value)) = changed.into_iter().find(|c| c.1) {
                return Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "a fixed-payload flag, used only with `--payload fixed`",
                });
            }
        }
        Ok(())
    }
}

/// What `tagk simulate` did; its `Display` is the one-line summary the command prints.
#[derive(Debug, Clone, PartialEq)]
pub struct SimulateSummary {
    /// Samples written.
    pub samples: usize,
    /// The log file.
    pub output: PathBuf,
    /// Position error of the flight \[cm\].
    pub position_error_cm: f64,
    /// Whether the flight aborted.
    pub aborted: bool,
    /// Payload events.
    pub events: usize,
    /// Effects of `--model` not flown, and why.
    pub skipped: Vec<SkippedEffect>,
}

impl fmt::Display for SimulateSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {} samples to {} (position error {:.2} cm{}, {} payload events)",
            self.samples,
            self.output.display(),
            self.position_error_cm,
            if self.aborted { ", aborted" } else { "" },
            self.events
        )?;
        for s in &self.skipped {
            write!(f, "\nnot flown: `{}` ({})", s.effect, s.reason)?;
        }
        Ok(())
    }
}

/// Flies the flight of `args` and writes its log to `args.output`.
///
/// # Errors
/// Invalid flags (typed [`SimError`]s), a model file that cannot be read or flown, and I/O
/// errors.
pub fn run_simulate(args: &SimulateArgs) -> Result<SimulateSummary, SimulateError> {
    let (cfg, skipped) = args.config_and_skipped()?;
    let bar = super::progress::Progress::counting(!args.quiet, 0, "control steps");
    let out = tagk_sim::simulate_with_progress(&cfg, |done, total| {
        bar.set(done as u64, total as u64);
    });
    bar.message(format!("writing {}", args.output.display()));
    let written = out.map_err(SimulateError::from).and_then(|out| {
        out.log
            .write_csv_path(&args.output)
            .map_err(SimError::from)?;
        Ok(out)
    });
    bar.finish();
    let out = written?;
    Ok(SimulateSummary {
        samples: out.log.len(),
        output: args.output.clone(),
        position_error_cm: out.metrics.position_error_cm,
        aborted: out.metrics.aborted,
        events: out.events.len(),
        skipped,
    })
}
