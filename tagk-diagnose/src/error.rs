//! Typed errors of the diagnosis layer.

use tagk_dynamics::EffectKind;
use thiserror::Error;

/// A problem with a flight log: every variant names where it is (CSV line, 1-based, the header
/// being line 1; and the column) so that the user can fix the file.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum LogError {
    /// A required column of the log format is absent from the header.
    #[error("line 1: missing required column `{column}`")]
    MissingColumn {
        /// The column's name.
        column: String,
    },
    /// The same column name appears twice in the header.
    #[error("line 1: duplicate column `{column}` (columns {first} and {second}, 1-based)")]
    DuplicateColumn {
        /// The column's name.
        column: String,
        /// 1-based position of its first occurrence.
        first: usize,
        /// 1-based position of its second occurrence.
        second: usize,
    },
    /// A cell that is not a number.
    #[error("line {line}, column `{column}`: `{value}` is not a number")]
    NotANumber {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// Column name.
        column: String,
        /// The offending text.
        value: String,
    },
    /// A cell that is NaN or infinite.
    #[error("line {line}, column `{column}`: non-finite value {value}")]
    NonFinite {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// Column name.
        column: String,
        /// The value read.
        value: f64,
    },
    /// Time does not strictly increase.
    #[error("line {line}, column `t`: time {t} s does not increase (previous sample {previous} s)")]
    NonIncreasingTime {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// The time on this line \[s\].
        t: f64,
        /// The previous sample's time \[s\].
        previous: f64,
    },
    /// The attitude quaternion's norm is far from one.
    #[error(
        "line {line}, columns `qw,qx,qy,qz`: quaternion norm {norm:.4} is not 1 (tolerance {tolerance})"
    )]
    QuaternionNorm {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// The norm found.
        norm: f64,
        /// Allowed deviation `|‖q‖ − 1|`.
        tolerance: f64,
    },
    /// A row with the wrong number of fields, or a CSV syntax error.
    #[error("line {line}: malformed CSV row: {message}")]
    Malformed {
        /// CSV line (1-based; the header is line 1).
        line: usize,
        /// What the CSV reader reported.
        message: String,
    },
    /// Too few samples to fit the model.
    #[error("log too short to fit: {rows} rows, at least {needed} needed")]
    TooShort {
        /// Rows in the log.
        rows: usize,
        /// Rows needed.
        needed: usize,
    },
    /// In-memory log whose signals have different lengths.
    #[error("signal `{column}` has {got} samples, expected {expected}")]
    LengthMismatch {
        /// Signal name.
        column: String,
        /// Its length.
        got: usize,
        /// The length of `t`.
        expected: usize,
    },
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The path.
        path: String,
        /// The OS error.
        message: String,
    },
}

impl LogError {
    /// The 1-based CSV line the error points at (the header is line 1), if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            LogError::MissingColumn { .. } | LogError::DuplicateColumn { .. } => Some(1),
            LogError::NotANumber { line, .. }
            | LogError::NonFinite { line, .. }
            | LogError::NonIncreasingTime { line, .. }
            | LogError::QuaternionNorm { line, .. }
            | LogError::Malformed { line, .. } => Some(*line),
            _ => None,
        }
    }

    /// The column the error points at, if any.
    pub fn column(&self) -> Option<&str> {
        match self {
            LogError::MissingColumn { column }
            | LogError::DuplicateColumn { column, .. }
            | LogError::NotANumber { column, .. }
            | LogError::NonFinite { column, .. }
            | LogError::LengthMismatch { column, .. } => Some(column),
            LogError::NonIncreasingTime { .. } => Some("t"),
            LogError::QuaternionNorm { .. } => Some("qw"),
            _ => None,
        }
    }
}

/// Every failure of the diagnosis workflow.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
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
    /// An unknown effect name (CLI `--with`): neither a name or alias of
    /// [`tagk_dynamics::EffectKind`] nor a custom effect's name.
    #[error("unknown effect `{0}` (known: {known})", known = known_effects())]
    UnknownEffect(String),
    /// An effect of the vocabulary without a diagnosis candidate in this version.
    #[error("effect `{0}` has no diagnosis candidate")]
    NoCandidate(EffectKind),
    /// A custom effect multiplies a column the log does not have.
    #[error("custom effect `{effect}`: the log has no column `{column}`")]
    UnknownColumn {
        /// Effect name.
        effect: String,
        /// The missing column.
        column: String,
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

/// The built-in effect names, comma separated (for error messages).
fn known_effects() -> String {
    EffectKind::ALL.map(EffectKind::name).join(", ")
}
