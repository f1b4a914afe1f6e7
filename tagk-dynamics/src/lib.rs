#![doc = include_str!("../README.md")]

pub mod alignment;
pub mod conventions;
pub mod deriv;
pub mod effect;
mod error;
pub mod front_end;
mod inertial;
pub mod joint_effect;
pub mod joint_log;
pub mod log;
pub mod log_input;
pub mod math;
pub mod quadrotor;
mod rigid_body;
pub mod robots;
pub mod tree;
#[cfg(feature = "urdf")]
pub mod urdf;
pub mod vehicle;
mod window;

/// The nalgebra version this crate's API uses (re-exported so callers match it).
pub use nalgebra;

pub use effect::{BATTERY_COLUMN, BATTERY_REFERENCE_VOLTAGE, EffectKind, UnknownEffect};
pub use error::DynamicsError;
pub use inertial::{GateViolation, InertialParams, SafetyGate};
pub use joint_effect::{COULOMB_VELOCITY_SCALE, JointEffectKind, JointEffects, UnknownJointEffect};
pub use joint_log::JointLog;
pub use log::{FlightLog, LogError, LogSample};
pub use quadrotor::QuadrotorModel;
pub use rigid_body::{
    ForwardDynamics, GRAVITY_WORLD, RigidBodyRegressor, Wrench, forward_dynamics, newton_euler,
    proper_acceleration, rigid_body_regressor, try_forward_dynamics, write_rigid_body_regressor,
};
pub use tree::{Body, JointKind, JointLimit, KinematicTree, Pose, TreeWorkspace};
#[cfg(feature = "urdf")]
pub use urdf::UrdfOptions;
pub use vehicle::{Vehicle, VehicleError};
pub use window::{A_FRAME_LEN, B_FRAME_LEN, WindowBuilder};
