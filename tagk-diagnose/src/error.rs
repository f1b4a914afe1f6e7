//! Typed errors of the diagnosis layer.

use thiserror::Error;

/// A problem with a flight log (defined with the log type in `tagk-dynamics`).
pub use tagk_dynamics::log::LogError;

/// Every failure of the diagnosis workflow.
#[derive(Debug, Error)]
pub enum DiagnoseError {
    /// The flight log is invalid.
    #[error(transparent)]
    Log(#[from] LogError),
    /// An effect cannot be used on this log (e.g. it needs rotor speeds the log lacks).
    #[error("effect `{effect}` cannot be used on this log: {reason}")]
    EffectUnavailable {
        /// Effect name.
        effect: String,
        /// Why.
        reason: String,
    },
    /// An unknown effect name (CLI `--with`).
    #[error("unknown effect `{0}` (known: {known})", known = crate::effects::BUILTIN_NAMES.join(", "))]
    UnknownEffect(String),
    /// A malformed `--custom` specification.
    #[error("bad custom effect `{spec}`: {reason}")]
    BadCustomSpec {
        /// The specification given.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// The regression is rank deficient beyond repair or produced non-finite numbers.
    #[error("least-squares fit failed: {0}")]
    Fit(String),
    /// Writing an output file failed.
    #[error("{path}: {message}")]
    Output {
        /// The path.
        path: String,
        /// The OS or serialisation error.
        message: String,
    },
    /// The online TAG-K pass failed.
    #[error("online TAG-K pass failed: {0}")]
    Online(String),
}
