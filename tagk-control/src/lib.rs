#![doc = include_str!("../README.md")]

/// The nalgebra version used in this crate's API (re-exported for convenience).
pub use nalgebra;
/// The inertial parameters and actuator model this crate designs for.
pub use tagk_dynamics::{InertialParams, QuadrotorModel};

pub mod dare;
mod linalg;
pub mod lqr;
pub mod quadrotor;
pub mod zoh;

pub use dare::{
    DareError, DareOptions, DareSolution, dare_residual, solve_dare, solve_dare_cold,
    solve_dare_sda,
};
pub use lqr::{DEFAULT_DT, Lqr, LqrWeights, RiccatiSolver, SolveReport};
pub use quadrotor::{
    ContinuousModel, DiscreteModel, ErrorState, OperatingPoint, QuadrotorState, discretize,
    error_state, hover_trim, linearize, trim_thrusts,
};
pub use zoh::discretize_zoh;

/// Errors of `tagk-control`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ControlError {
    /// The Riccati solve failed.
    #[error("Riccati solve failed: {0}")]
    Dare(#[from] DareError),
    /// The dynamics crate rejected the parameters or state.
    #[error("dynamics: {0}")]
    Dynamics(#[from] tagk_dynamics::DynamicsError),
    /// Inertial parameters that admit no forward dynamics.
    #[error("invalid inertial parameters: {reason}")]
    InvalidParams {
        /// What is wrong.
        reason: &'static str,
    },
    /// A NaN or infinite input.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The control period must be positive and finite.
    #[error("invalid time step {dt} s")]
    InvalidTimeStep {
        /// The offending value \[s\].
        dt: f64,
    },
    /// `A` must be square and `B` must have as many rows as `A`.
    #[error("shape mismatch: A is {a:?}, B is {b:?}")]
    ShapeMismatch {
        /// Shape of `A`.
        a: (usize, usize),
        /// Shape of `B`.
        b: (usize, usize),
    },
    /// The requested reference acceleration needs a force across body `z`.
    #[error("trim infeasible: requires {lateral_force:e} N across body z")]
    TrimInfeasible {
        /// Magnitude of the required lateral force \[N\].
        lateral_force: f64,
    },
}
