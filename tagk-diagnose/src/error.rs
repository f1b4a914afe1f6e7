//! Typed errors of the diagnosis layer.

use tagk_dynamics::EffectKind;
use thiserror::Error;

/// A problem with a flight log (defined with the log type in `tagk-dynamics`).
pub use tagk_dynamics::log::LogError;

/// Every failure of the diagnosis workflow.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// The flight log is invalid.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The vehicle description (`--vehicle`) is invalid or unknown.
    #[error(transparent)]
    Vehicle(#[from] tagk_dynamics::vehicle::VehicleError),
    /// A column mapping (`--columns`) or the streams it maps (`--stream`) cannot be read.
    #[error(transparent)]
    Input(#[from] tagk_dynamics::log_input::InputError),
    /// An effect cannot be used on this log (e.g. it needs rotor speeds the log lacks).
    #[error("effect `{effect}` cannot be used on this log: {reason}")]
    EffectUnavailable {
        /// Effect name.
        effect: String,
        /// Why.
        reason: String,
    },
    /// An unknown effect name (CLI `--with`): neither a name or alias of
    /// [`tagk_dynamics::EffectKind`] nor a custom effect's name.
    #[error("unknown effect `{0}` (known: {known})", known = known_effects())]
    UnknownEffect(String),
    /// An effect of the vocabulary without a diagnosis candidate in this version.
    #[error("effect `{0}` has no diagnosis candidate")]
    NoCandidate(EffectKind),
    /// A custom effect reads a column the log does not have.
    #[error("custom effect `{effect}`: the log has no column `{column}` (available: {available})")]
    UnknownColumn {
        /// Effect name.
        effect: String,
        /// The missing column.
        column: String,
        /// The signals the log offers, comma separated.
        available: String,
    },
    /// A custom effect's expression mixes units: a sum, difference, `min` or `max` of
    /// different units, or a function that needs a pure number given a quantity.
    #[error("custom effect `{effect}`: `{expression}`: {reason}")]
    CustomUnits {
        /// Effect name.
        effect: String,
        /// The expression.
        expression: String,
        /// The unit mistake.
        reason: String,
    },
    /// A custom effect multiplies a column of the log that was not read as a signal: an
    /// unmapped column with a cell that is not a number
    /// ([`tagk_dynamics::log_input::UnreadColumn`]).
    #[error(
        "custom effect `{effect}`: the column `{column}` of {stream} was not read as a signal: \
         its cell on line {line} is `{value}`, not a number (unmapped columns are offered to \
         custom effects only when every cell is a finite number)"
    )]
    UnreadColumn {
        /// Effect name.
        effect: String,
        /// The column.
        column: String,
        /// The stream file it is in.
        stream: String,
        /// The CSV line of its first cell that is not a number.
        line: usize,
        /// That cell's text.
        value: String,
    },
    /// A setting out of its domain (e.g. `DiagnoseOptions { folds: 0 }`).
    #[error("invalid option `{field}`: {reason}")]
    InvalidOption {
        /// The setting, as named in its struct.
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// A model that cannot be fitted as specified (a duplicate effect, a known mass that is
    /// not a positive finite number).
    #[error("invalid model: {0}")]
    InvalidModel(String),
    /// A time window (`--window START..END`) that is malformed, empty, reversed or outside
    /// the log.
    #[error("bad window `{window}`: {reason}")]
    BadWindow {
        /// The window as given.
        window: String,
        /// What is wrong with it.
        reason: String,
    },
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
    /// A scale or consistency check failed (a unit mistake, a flipped sign, swapped rotor
    /// spins: [`crate::scales`]); accept it with `--accept-scales`
    /// ([`crate::DiagnosisPlan::accept_scales`]).
    #[error("{message} (if the data are right, go on with --accept-scales)")]
    ScaleMismatch {
        /// The first check that failed (`gyro`, `velocity`, `accelerometer`, `thrust`,
        /// `yaw-torque`, `mass`, `inertia`).
        check: String,
        /// Every failed check, with its likely cause.
        message: String,
    },
    /// A model file (`--model`, `--save-model`) cannot be read or written.
    #[error(transparent)]
    ModelFile(#[from] crate::model_file::ModelFileError),
    /// The online TAG-K pass failed: the estimator could not be built or rejected a window.
    #[error("online TAG-K pass failed: {0}")]
    Online(String),
    /// The log is shorter than one window of the online TAG-K pass.
    #[error("online TAG-K pass: the log has {samples} samples, fewer than one window of {needed}")]
    OnlineTooShort {
        /// Samples in the log.
        samples: usize,
        /// Samples of one window.
        needed: usize,
    },
}

/// The built-in effect names, comma separated (for error messages).
fn known_effects() -> String {
    EffectKind::ALL.map(EffectKind::name).join(", ")
}
