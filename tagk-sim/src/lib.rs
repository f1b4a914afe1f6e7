#![doc = include_str!("../README.md")]

pub mod cli;
pub mod effects;
mod error;
pub mod estimators;
pub mod experiments;
pub mod log;
pub mod metrics;
pub mod monte_carlo;
pub mod plant;
pub mod plot;
pub mod sim;
pub mod trajectory;

pub use effects::{
    EffectKind, GroundEffect, LinearDrag, MotorLag, PlantEffects, QuadraticDrag,
    ThrustCoefficientError, Wind, WrenchBias,
};
pub use error::SimError;
pub use estimators::{EstimatorKind, EstimatorSpec};
pub use log::{LogSample, write_log_csv, write_log_csv_file};
pub use monte_carlo::{Capture, CellSummary, Sweep, SweepResult};
pub use plant::{Plant, PlantState};
pub use sim::{
    Adaptation, Controller, NoiseLevel, Payload, PayloadSchedule, PayloadShape, SimConfig,
    SimOutput, TrialMetrics, simulate,
};
pub use trajectory::{Trajectory, TrajectoryKind};

/// The clap version this crate's argument structs derive with (the examples parse through it).
pub use clap;
