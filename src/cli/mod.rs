//! Command-line pieces shared by the `tagk` binary and the examples: the `simulate`, `diagnose`
//! and `vehicle` subcommands and clap parsers for the simulator's names (trajectories, noise levels,
//! estimators, effects) that list the accepted values in `--help`; the progress bar
//! ([`progress`]); errors printed once and quiet broken pipes ([`terminal`]).

pub mod compare;
pub mod diagnose;
pub mod progress;
pub mod simulate;
pub mod terminal;
pub mod vehicle;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use tagk_dynamics::EffectKind;
use tagk_sim::{EstimatorKind, LogRate, NoiseLevel, SensingProfile, TrajectoryKind};

/// Parses a [`TrajectoryKind`] by its command-line name (`figure8`, `circle`, …).
pub fn trajectory_parser() -> impl TypedValueParser<Value = TrajectoryKind> {
    PossibleValuesParser::new(TrajectoryKind::ALL.map(TrajectoryKind::cli_name))
        .try_map(|s| s.parse::<TrajectoryKind>())
}

/// Parses a [`NoiseLevel`] by its name (`none`, `low`, `medium`, `high`).
pub fn noise_parser() -> impl TypedValueParser<Value = NoiseLevel> {
    PossibleValuesParser::new(NoiseLevel::ALL.map(NoiseLevel::name))
        .try_map(|s| s.parse::<NoiseLevel>())
}

/// Parses a [`SensingProfile`] by its name (`ideal`, `realistic`, `realistic-calibrated`,
/// `cf21-brushless`).
pub fn sensing_parser() -> impl TypedValueParser<Value = SensingProfile> {
    PossibleValuesParser::new(SensingProfile::ALL.map(SensingProfile::name))
        .try_map(|s| s.parse::<SensingProfile>())
}

/// Parses a [`LogRate`] by its name (`control`, `physics`).
pub fn log_rate_parser() -> impl TypedValueParser<Value = LogRate> {
    PossibleValuesParser::new(LogRate::ALL.map(LogRate::name)).try_map(|s| s.parse::<LogRate>())
}

/// Parses an [`EstimatorKind`] by its command-line name (`rls-low`, …, `tagk`, …).
pub fn estimator_parser() -> impl TypedValueParser<Value = EstimatorKind> {
    PossibleValuesParser::new(EstimatorKind::ALL.map(EstimatorKind::cli_name))
        .try_map(|s| s.parse::<EstimatorKind>())
}

/// Parses an [`EffectKind`] of the shared vocabulary by its name or one of its aliases.
pub fn effect_parser() -> impl TypedValueParser<Value = EffectKind> {
    PossibleValuesParser::new(EffectKind::ALL.map(|k| {
        PossibleValue::new(k.name())
            .aliases(k.aliases().iter().copied())
            .help(k.summary())
    }))
    .try_map(|s| s.parse::<EffectKind>())
}
