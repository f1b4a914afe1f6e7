#![doc = include_str!("../README.md")]
// Channel-indexed numerical loops (c in 0..6 over several parallel arrays) read better with
// indices than with zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod accel_offset;
pub mod arm;
mod deriv;
mod diagnose;
pub mod effects;
mod error;
mod fit;
pub mod format;
pub mod glitches;
pub mod html;
pub mod log;
pub mod log_params;
pub mod model_file;
pub mod online;
mod plan;
pub mod predict;
pub mod report;
pub mod sampling;
pub mod scales;
mod signals;
mod stats;
pub mod streams;
pub mod validation;
pub mod window;

pub use accel_offset::AccelerometerOffset;
pub use arm::{ArmEffect, ArmOptions, ArmReport, BaseReduction, diagnose_arm};
pub use diagnose::{
    ADEQUACY_FACTOR, ADEQUATE_AUTOCORRELATION, CONSISTENCY_TOLERANCE, Candidate, CandidateStatus,
    ChannelAdequacy, Confounding, DiagnoseOptions, Diagnosis, Discovery, Equivalent,
    FLOOR_RESOLUTION, FailureWindow, FloorSource, INCONSISTENCY_STANDARD_ERRORS,
    INPUT_CORRELATION_LAGS, InputCorrelation, MAX_CONSTANT_FORCE_OF_THRUST, MAX_INFLATION,
    MAX_MASS_CHANGE, MAX_MASS_FROM_VEHICLE, MIN_GAIN, NoiseFloor, Parameter, PartialResidual,
    ProgressHook, RegimeStat, ResidualInput, SearchProgress, Step, StepChannel, Unavailable,
    WHITENESS_FALSE_ALARM, Whiteness, Z_99, consistency_margin, consistent_within_tolerance,
    diagnose, discover, discover_from, input_correlation, input_correlation_lags,
    residual_autocorrelation, residual_inputs, second_moment_eigen, whiteness_limit,
};
pub use effects::{
    ACCEL_BIAS, BuiltinOptions, CustomEffect, Effect, EffectColumn, EffectRef, NOT_PROPOSED,
    Plausibility, ScanSpec, builtin, builtin_by_name, builtin_effects, builtin_with, cut_to_window,
    effect_columns, expression::Expression, is_sensor_effect, subsample,
};
pub use error::{DiagnoseError, LogError};
pub use fit::resolution_of;
pub use fit::{
    CONSISTENT_MARGIN, ChannelFit, Coefficient, Fit, FittedEffect, Model, TargetFilter, Z_95,
    fit_model,
};
pub use glitches::{Glitch, SampleSource};
pub use log::{FlightLog, LogSample};
pub use log_params::{
    LOG_CONSISTENCY_EFFECT_FACTOR, LOG_CONSISTENCY_RELATIVE, LOG_CONSISTENCY_Z, LogParameter,
};
pub use model_file::{
    LogSource, MODEL_FILE_VERSION, MODEL_FORMAT, ModelContext, ModelEffect, ModelFile,
    ModelFileError,
};
pub use online::{OnlineOptions, OnlineStart, OnlineSummary, online_pass, online_pass_with};
pub use plan::{
    CustomChoice, DEFAULT_ONLINE_STRIDE, DiagnosisPlan, EffectChoice, Flight, KNOWN_MASS_RANGE,
    KnownMass, ResolvedPlan,
};
pub use predict::{
    BodyState, COMPONENTS, CONSTANT_RATE, Comparison, HorizonError, ModelPrediction, Overlay,
    OverlayErrors, OverlayPeak, OverlaySeries, Prediction, Predictor, QUANTITIES, Quantity,
    QuantityFit, constant_rate_prediction, default_horizons, fit_percent, k_step_prediction,
    k_step_prediction_logs, predict_logs,
};
pub use report::{
    ChannelChange, FIT_MEASURES, FinalModel, LogVerdict, NextStep, RankingEntry, Report,
    add_recommended, diagnosis_table, report_table, run_logs, run_loop, staircase_table,
};
pub use sampling::{SamplingFindings, sampling_text};
pub use scales::{ScaleFinding, Severity};
pub use signals::{CHANNEL_NAMES, CHANNEL_UNITS, Channel, MIN_SEGMENT_ROWS, RotorMixer, Signals};
pub use streams::{
    AlignOptions, StreamAlignment, align_streams, align_streams_owned, parse_shift,
    shift_contradiction, streams_table,
};
/// The effect vocabulary shared with the simulator (re-exported from `tagk-dynamics`): the
/// built-in candidates are keyed by it ([`builtin`]).
pub use tagk_dynamics::EffectKind;
pub use tagk_dynamics::alignment::{DelayEstimate, Sensor};
pub use validation::{Validation, ValidationStep, validation_rms};
pub use window::{TimeWindow, keep_windows};

#[cfg(test)]
mod sampled_tests;
#[cfg(test)]
pub(crate) mod testdata;
#[cfg(test)]
mod unit_tests;
