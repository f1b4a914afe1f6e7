//! Errors of the Table III harness.

use tagk_core::{ConfigError, EstimatorError};

/// Why a harness case could not run or did not reproduce the reference result.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HarnessError {
    /// The caller's arena cannot hold the case's windows and estimator.
    #[error("the arena holds {found} scalars but this case needs {needed}")]
    ArenaTooSmall {
        /// Scalars needed ([`crate::Case::arena_len`]).
        needed: usize,
        /// Scalars offered.
        found: usize,
    },
    /// A case asks for zero timed repetitions or an empty window pool.
    #[error("a case needs at least one window in its pool and one timed repetition")]
    NothingToRun,
    /// The estimator could not be built.
    #[error("building the estimator failed: {0}")]
    Config(#[from] ConfigError),
    /// An update was refused.
    #[error("an update failed: {0}")]
    Update(#[from] EstimatorError),
    /// The estimates differ from the reference run's.
    #[error(
        "checksum mismatch for case {index}: got {found_hash:#018x} (sum {found_sum:e}), \
         expected {expected_hash:#018x} (sum {expected_sum:e})"
    )]
    ChecksumMismatch {
        /// The case's [`crate::Case::index`] (`usize::MAX` for a case in neither list).
        index: usize,
        /// Hash computed here.
        found_hash: u64,
        /// Hash of the reference run.
        expected_hash: u64,
        /// Sum of the final estimate computed here.
        found_sum: f64,
        /// Sum of the reference run's final estimate.
        expected_sum: f64,
    },
}
