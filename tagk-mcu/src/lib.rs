#![doc = include_str!("../README.md")]
#![no_std]

#[cfg(feature = "std")]
extern crate std;

pub mod counter;
pub mod covariance;
mod error;
pub mod estimators;
pub mod harness;

#[cfg(all(feature = "cortex-m", target_arch = "arm"))]
pub use counter::DwtCycleCounter;
#[cfg(feature = "std")]
pub use counter::StdClock;
pub use counter::{CycleCounter, NullCounter};
pub use covariance::{KalmanFilter, KfConfig, Rls, RlsConfig, covariance_buffer_len};
pub use error::HarnessError;
pub use estimators::{EstimatorKind, McuEstimator, tagk_paper_config};
pub use harness::{
    ARENA_LEN, CASES, Case, CaseReport, Checksum, Precision, SyntheticWindows, run_case,
    run_case_in,
};

// The kernels this crate runs, re-exported so firmware needs only one dependency.
pub use tagk_core::{
    ConfigError, EstimatorError, KaczmarzConfig, OnlineEstimator, Real, TagK, UpdateInfo,
    kaczmarz_buffer_len,
};
