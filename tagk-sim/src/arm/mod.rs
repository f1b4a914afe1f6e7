//! A fixed-base robot arm from its URDF, and online payload estimation on it.
//!
//! - **Model** ([`ArmModel`]): the URDF's kinematic tree (tagk-dynamics) and joint limits.
//! - **Plant** ([`ArmPlant`]): `(M(q) + diag(a)) q̈ = τ − h(q, q̇) − τ_v(q̇)` with the true
//!   parameters and the [`JointEffects`](tagk_dynamics::JointEffects) (viscous and smoothed
//!   Coulomb friction, armature `a`, offset). Classical RK4, 1 ms step, torque held per step.
//!   A payload at the flange (the last body) adds its parameters to that body.
//! - **Reference** ([`ArmTrajectory`]): Fourier-series excitation within the joint limits, or
//!   pick-and-place with quintic moves.
//! - **Sensing** ([`JointSensing`]): encoder quantisation, velocity noise, torque noise and a
//!   constant torque offset per joint, all from the run's seed.
//! - **Control**: computed torque `τ = Y(q, q̇, v) θ̂ + τ_e(q̇, v)` with
//!   `v = q̈_d + K_d (q̇_d − q̇) + K_p (q_d − q)`, the *estimated* parameters `θ̂` and the
//!   known joint effects; saturated at the effort limits.
//! - **Estimation**: every 10 ms a sample, the mean of the sensed `q`, `q̇`, `τ` over those
//!   10 control steps. One Savitzky–Golay fit ([`centre_fit`], 5 samples) filters `q`, `q̇`
//!   and `τ` (less the known friction) alike; `q̈` is the slope of `q̇` (2 samples late). A window of 10
//!   samples (`10·dof` rows) updates any `OnlineEstimator`:
//!   `τ − τ_e − Y_known θ_known = Y_I β` ([`BaseParameters`]).
//! - **Gates**: an estimate reaches the controller only if it predicts the next window's
//!   torques within the measured noise, or better than the controller's parameters
//!   ([`torque_gate_threshold`]), and its inertia stays near the nominal.
//! - **Experiment** ([`ArmExperiment`], [`run_arm_trial`], [`ArmRow`]): the arm's Table II.
//! - **Prescribed motion** ([`prescribed_log`]): a joint-torque log by inverse dynamics along a
//!   [`FourierTrajectory`], no integrator, for the joint-torque diagnosis and its tests.

mod base;
mod experiment;
mod model;
mod plant;
mod prescribed;
mod sim;
mod trajectory;

pub use base::{
    BASE_SAMPLES_PER_COLUMN, BASE_TOLERANCE, BaseParameters, EstimationScope, ZERO_COLUMN,
};
pub use experiment::{
    ARM_JUDGE_TIME, ARM_SETTLE_TIME, ARM_SUCCESS_THRESHOLD, ArmExperiment, ArmRow,
    ArmTrajectoryKind, ArmTrialMetrics, arm_table, arm_table_rows, run_arm_trial,
};
pub use model::{ArmModel, JointLimits};
pub use plant::{ArmPlant, ArmState};
pub use prescribed::prescribed_log;
pub use sim::{
    ArmAdaptation, ArmLog, ArmOutput, ArmSimConfig, DEFAULT_FILTER_HALF_WIDTH, GATE_INERTIA_RATIO,
    GATE_MIN_PSEUDO_INERTIA, JointSensing, PayloadEvent, TORQUE_GATE_FACTOR, UpdateRecord,
    box_payload, centre_fit, simulate_arm, smoothing_noise_gain, torque_gate_threshold,
    torque_residual,
};
pub use trajectory::{ArmTrajectory, FourierTrajectory, JointReference, PickAndPlace};
