#![doc = include_str!("../README.md")]

mod error;
pub mod estimators;
#[cfg(feature = "plot")]
pub mod experiments;
pub mod metrics;
pub mod monte_carlo;
pub mod plant;
pub mod plant_effects;
pub mod plant_model;
#[cfg(feature = "plot")]
pub mod plot;
pub mod sim;
pub mod trajectory;

pub use error::SimError;
pub use estimators::{EstimatorKind, EstimatorSpec};
pub use monte_carlo::{
    CellSummary, ErrorCurves, Sweep, SweepObserver, SweepResult, Traces, trial_seed,
};
pub use plant::{Plant, PlantState};
pub use plant_effects::{BatteryVoltage, PlantEffect, PlantEffects};
pub use sim::{
    Adaptation, Controller, ExperimentProfile, FlightStack, FlightTruth, LogRate,
    MEMORY_BUDGET_BYTES, NoiseLevel, Payload, PayloadSchedule, PayloadShape, Sensing,
    SensingProfile, SimConfig, SimOutput, TrialMetrics, TruthSample, simulate,
};
/// The flight-log type the simulator records (re-exported from `tagk-dynamics`).
pub use tagk_dynamics::log::{FlightLog, LogError, LogSample};
/// The effect vocabulary shared with the diagnosis (re-exported from `tagk-dynamics`).
pub use tagk_dynamics::{EffectKind, UnknownEffect};
pub use trajectory::{Trajectory, TrajectoryKind};

#[cfg(test)]
mod tests {
    /// The driver shares the sweep and its observers across rayon threads.
    #[test]
    fn public_types_are_send_and_sync() {
        fn send_sync<T: Send + Sync>() {}
        send_sync::<crate::SimConfig>();
        send_sync::<crate::Sweep>();
        send_sync::<crate::SweepResult>();
        send_sync::<crate::SimOutput>();
        send_sync::<crate::ErrorCurves>();
        send_sync::<crate::Traces>();
        send_sync::<crate::SimError>();
        send_sync::<crate::FlightTruth>();
    }
}
