#![doc = include_str!("../README.md")]
#![no_std]

#[cfg(feature = "std")]
extern crate std;

pub mod counter;
mod error;
pub mod estimators;
pub mod harness;

#[cfg(all(feature = "cortex-m", target_arch = "arm"))]
pub use counter::DwtCycleCounter;
#[cfg(feature = "std")]
pub use counter::StdClock;
pub use counter::{CycleCounter, NullCounter};
pub use error::HarnessError;
pub use estimators::{McuEstimator, buffer_len, state_bytes};
pub use harness::{
    ARENA_LEN, ARM_ARENA_LEN, ARM_CASES, CASE_COUNT, CASES, Case, CaseReport, Checksum, Precision,
    SyntheticWindows, case_at, run_case, run_case_in,
};

// The kernels this crate runs, re-exported so firmware needs only one dependency: TAG-K from
// tagk-core, RLS and the Kalman filter from tagk-baselines (its portable `no_std` kernel).
pub use tagk_baselines::{
    EstimatorKind, KalmanConfig, KalmanFilter, Rls, RlsConfig, WindupGuard,
    checked_compact_covariance_buffer_len, checked_covariance_buffer_len,
    compact_covariance_buffer_len, covariance_buffer_len,
};
pub use tagk_core::{
    ConfigError, EstimatorError, KaczmarzConfig, OnlineEstimator, Real, TagK, UpdateInfo,
    kaczmarz_buffer_len, tagk_paper_config,
};
