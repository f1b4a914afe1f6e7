#![doc = include_str!("../README.md")]

pub mod arm;
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
pub mod tuning;

pub use error::SimError;
pub use estimators::{EstimatorKind, EstimatorSpec, FilterTuning};
pub use monte_carlo::{
    CellSummary, ErrorCurves, Sweep, SweepObserver, SweepResult, Traces, trial_seed,
};
pub use plant::{Plant, PlantState};
pub use plant_effects::{BatteryVoltage, PlantEffect, PlantEffects};
pub use sim::{
    Adaptation, Controller, ExperimentProfile, FlightStack, FlightTruth, LogRate,
    MEMORY_BUDGET_BYTES, NoiseLevel, Payload, PayloadSchedule, PayloadShape, Sensing,
    SensingProfile, SimConfig, SimOutput, TrialMetrics, TruthSample, simulate,
    simulate_with_progress,
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

    /// The progress callback sees every control step once, in order, and the flight is the
    /// same bits as without it.
    #[test]
    fn simulate_with_progress_counts_every_step_and_changes_nothing() {
        let config = crate::SimConfig {
            duration: 2.0,
            record_log: true,
            ..crate::SimConfig::default()
        };
        let plain = crate::simulate(&config).unwrap();
        let mut seen = Vec::new();
        let observed = crate::simulate_with_progress(&config, |done, total| {
            seen.push((done, total));
        })
        .unwrap();
        let total = (config.duration / config.control_dt).round() as usize;
        let expected: Vec<(usize, usize)> = (1..=total).map(|k| (k, total)).collect();
        assert_eq!(seen, expected);
        assert!(!plain.log.is_empty());
        assert_eq!(plain.log, observed.log);
    }
}
