#![doc = include_str!("../README.md")]
// Channel-indexed numerical loops (c in 0..6 over several parallel arrays) read better with
// indices than with zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod cli;
pub mod deriv;
pub mod diagnose;
pub mod effects;
mod error;
pub mod fit;
pub mod html;
pub mod log;
pub mod online;
pub mod report;
pub mod signals;
pub mod stats;

pub use diagnose::{Candidate, DiagnoseOptions, Diagnosis, diagnose};
pub use effects::{
    BodyBias, CustomEffect, Effect, EffectColumn, EffectRef, GroundEffect, LinearDrag, MotorLag,
    Plausibility, QuadraticDrag, RotorDrag, ScanSpec, ThrustGain, TimeDelay, Wind, builtin_by_name,
    builtin_effects,
};
pub use error::{DiagnoseError, LogError};
pub use fit::{ChannelFit, Coefficient, Fit, FittedEffect, Model, fit_model};
pub use log::{FlightLog, LogSample};
pub use report::{Report, add_recommended, run_loop};
pub use signals::Signals;

#[cfg(test)]
pub(crate) mod testdata;
#[cfg(test)]
mod unit_tests;
