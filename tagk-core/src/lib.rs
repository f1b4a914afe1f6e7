#![doc = include_str!("../README.md")]
#![no_std]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

#[cfg(all(target_arch = "aarch64", target_feature = "neon"))]
mod aarch64;
pub mod accumulate;
pub mod change;
mod error;
mod estimator;
pub mod front_end;
mod greedy;
pub mod kaczmarz;
#[cfg(any(
    all(feature = "std", target_arch = "x86_64"),
    all(target_arch = "aarch64", target_feature = "neon")
))]
mod lanes;
pub mod linalg;
mod real;
pub mod synthetic;
#[cfg(all(feature = "std", target_arch = "x86_64"))]
mod x86;

pub use accumulate::{
    Accumulate, AccumulateConfig, accumulate_buffer_len, checked_accumulate_buffer_len,
};
pub use change::{
    ChangeDetector, Check, DetectorConfig, EventTriggered, checked_event_triggered_buffer_len,
    chi_square_quantile,
};
pub use error::{ConfigError, EstimatorError, NotPositiveDefinite};
pub use estimator::{
    OnlineEstimator, UpdateInfo, check_dimensions, check_window_finite, check_window_shape,
    validate_estimate, validate_window,
};
pub use front_end::{
    FrontEnd, FrontEndConfig, FrontEndInfo, checked_front_end_buffer_len, front_end_buffer_len,
    scales_from_prior,
};
#[cfg(feature = "alloc")]
pub use kaczmarz::zeroed_buffer;
pub use kaczmarz::{
    BurnIn, GreedyKaczmarz, Iterations, Kaczmarz, KaczmarzConfig, KernelChoice, RandomizedKaczmarz,
    Storage, TagK, TailAveragedKaczmarz, checked_kaczmarz_buffer_len, kaczmarz_buffer_len,
    tagk_paper_config,
};
pub use real::Real;
pub use synthetic::SyntheticWindows;
