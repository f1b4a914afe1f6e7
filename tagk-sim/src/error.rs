//! The one error type of the simulator and the experiments.

use tagk_control::ControlError;
use tagk_core::{ConfigError, EstimatorError};
use tagk_dynamics::quadrotor::NotFlyable;
use tagk_dynamics::{DynamicsError, EffectKind, LogError, VehicleError};

/// Everything that can go wrong when configuring or running a simulation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A mass that is not strictly positive (vehicle or payload) \[kg\].
    #[error("{what} mass must be positive and finite, got {mass} kg")]
    NonPositiveMass {
        /// Which body.
        what: &'static str,
        /// The offending mass \[kg\].
        mass: f64,
    },
    /// A duration or time step that is not strictly positive and finite \[s\].
    #[error("{what} must be positive and finite, got {value} s")]
    InvalidDuration {
        /// Which duration.
        what: &'static str,
        /// The offending value \[s\].
        value: f64,
    },
    /// The flight would keep more in memory than the budget allows (its log, trace and
    /// tracking error grow with the duration): shorten it, or split it into several flights.
    #[error(
        "duration {duration} s would keep {gib:.1} GiB in memory, above the {budget_gib:.1} GiB budget (at most {max_s:.0} s with these settings); shorten the flight or split it",
        gib = *bytes as f64 / f64::from(1u32 << 30),
        budget_gib = *budget as f64 / f64::from(1u32 << 30),
        max_s = *duration * (*budget as f64 / *bytes as f64)
    )]
    OverMemoryBudget {
        /// The requested duration \[s\].
        duration: f64,
        /// The memory it would keep \[bytes\].
        bytes: u64,
        /// The budget \[bytes\] ([`MEMORY_BUDGET_BYTES`](crate::sim::MEMORY_BUDGET_BYTES)).
        budget: u64,
    },
    /// The vehicle with its payload cannot hover: a rotor would need more than its limit.
    #[error(
        "payload needs {required:.4} N on one rotor to hover, above the {available:.4} N limit"
    )]
    PayloadBeyondThrust {
        /// Largest hover trim thrust of one rotor with the payload \[N\].
        required: f64,
        /// Largest thrust of one rotor \[N\].
        available: f64,
    },
    /// Any other out-of-range or non-finite configuration value.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The offending value.
        value: f64,
        /// What is allowed.
        reason: &'static str,
    },
    /// An effect of the vocabulary that the simulator's plant cannot produce.
    #[error(
        "the simulator cannot produce the effect `{effect}` (it can: {supported})",
        supported = crate::PlantEffects::supported().map(EffectKind::name).collect::<Vec<_>>().join(", ")
    )]
    UnsupportedEffect {
        /// The effect asked for.
        effect: EffectKind,
    },
    /// A vehicle description could not be read (file, TOML or value).
    #[error("vehicle: {0}")]
    Vehicle(#[from] VehicleError),
    /// A vehicle description the simulator cannot fly.
    #[error("{0}")]
    NotFlyable(#[from] NotFlyable),
    /// A built-in effect given the wrong number of coefficients
    /// ([`PlantEffects::with_coefficients`](crate::PlantEffects::with_coefficients)).
    #[error("effect `{effect}` takes {expected} coefficients ({names}) or none, got {got}")]
    EffectCoefficients {
        /// The effect.
        effect: EffectKind,
        /// How many it takes.
        expected: usize,
        /// Their names, in order.
        names: &'static str,
        /// How many were given.
        got: usize,
    },
    /// A configuration string that names nothing known (CLI).
    #[error("unknown {what} `{value}` (expected one of: {expected})")]
    Unknown {
        /// Kind of name.
        what: &'static str,
        /// The string given.
        value: String,
        /// The accepted names.
        expected: &'static str,
    },
    /// The dynamics crate rejected an input.
    #[error("dynamics: {0}")]
    Dynamics(#[from] DynamicsError),
    /// The controller could not be designed.
    #[error("control: {0}")]
    Control(#[from] ControlError),
    /// An estimator could not be built.
    #[error("estimator configuration: {0}")]
    EstimatorConfig(#[from] ConfigError),
    /// An estimator rejected a window.
    #[error("estimator: {0}")]
    Estimator(#[from] EstimatorError),
    /// File output failed.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// A flight log could not be written.
    #[error("flight log: {0}")]
    Log(#[from] LogError),
    /// CSV output failed.
    #[error("CSV: {0}")]
    Csv(#[from] csv::Error),
    /// JSON output failed.
    #[error("JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// Drawing a figure failed.
    #[error("plot: {0}")]
    Plot(String),
    /// A rayon thread pool could not be built (feature `parallel`).
    #[cfg(feature = "parallel")]
    #[error("thread pool: {0}")]
    ThreadPool(#[from] rayon::ThreadPoolBuildError),
}
