//! Typed errors shared by every estimator in the workspace.

/// Why an [`OnlineEstimator::update`](crate::OnlineEstimator::update) or
/// [`reset`](crate::OnlineEstimator::reset) was refused.
///
/// Whenever one of these is returned, the estimator's state (estimate, covariance, random
/// generator) is exactly what it was before the call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum EstimatorError {
    /// The window has no rows (`b` is empty).
    #[error("the window is empty: it has no rows")]
    EmptyWindow,
    /// The window has more rows than the estimator's buffers were sized for.
    #[error("the window has {rows} rows but the estimator was built for at most {capacity}")]
    WindowTooLarge {
        /// Rows in the offered window.
        rows: usize,
        /// Maximum rows the estimator accepts.
        capacity: usize,
    },
    /// The regressor's length is not `rows × cols` (row-major `A`, `rows = b.len()`).
    #[error(
        "the regressor has {found} entries, expected {expected} ({rows} rows × {cols} columns)"
    )]
    ShapeMismatch {
        /// `rows × cols`.
        expected: usize,
        /// `a.len()`.
        found: usize,
        /// Rows of the window (`b.len()`).
        rows: usize,
        /// Columns, the estimator's dimension `n`.
        cols: usize,
    },
    /// A vector handed to `reset` has the wrong length.
    #[error("the estimate has {found} entries, expected {expected}")]
    DimensionMismatch {
        /// The estimator's dimension `n`.
        expected: usize,
        /// The length offered.
        found: usize,
    },
    /// A regressor entry is NaN or infinite (or a row's squared norm overflows).
    #[error("non-finite regressor entry at row {row}, column {col}")]
    NonFiniteRegressor {
        /// Row index in the window (0-based).
        row: usize,
        /// Column index (0-based); for an overflowing row norm, the row's first column.
        col: usize,
    },
    /// A measurement is NaN or infinite.
    #[error("non-finite measurement at row {row}")]
    NonFiniteMeasurement {
        /// Row index in the window (0-based).
        row: usize,
    },
    /// A value handed to `reset` is NaN or infinite.
    #[error("non-finite value at index {index} of the estimate")]
    NonFiniteEstimate {
        /// Index of the offending entry.
        index: usize,
    },
    /// Every row of the window is zero: there is nothing to project on.
    #[error("every row of the window is zero: nothing to learn from")]
    NoUsableRow,
    /// The update would have produced a non-finite estimate (overflow); it was discarded.
    #[error("the update produced a non-finite estimate; the previous estimate is kept")]
    Diverged,
    /// A row weight handed to [`FrontEnd::update_weighted`](crate::FrontEnd::update_weighted)
    /// is negative or not finite, or the weights are not one per row.
    #[error("invalid row weight at row {row}: weights must be finite, non-negative, one per row")]
    InvalidWeight {
        /// Row index in the window (0-based); the window's row count for a length mismatch.
        row: usize,
    },
    /// A factorisation failed (for example an innovation covariance that is not positive
    /// definite in RLS or the Kalman filter).
    #[error("numerical failure: {0}")]
    NumericalFailure(&'static str),
}

/// Why an estimator could not be constructed from its configuration.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The parameter dimension `n` is zero.
    #[error("the parameter dimension must be at least 1")]
    ZeroDimension,
    /// The maximum window size is zero.
    #[error("the window capacity (maximum rows) must be at least 1")]
    ZeroCapacity,
    /// A fixed iteration count of zero.
    #[error("the number of iterations per window must be at least 1")]
    ZeroIterations,
    /// A fixed burn-in that leaves no iterate to average.
    #[error("burn-in {burn_in} must be smaller than the {iterations} iterations per window")]
    BurnInTooLarge {
        /// Requested burn-in.
        burn_in: usize,
        /// Iterations per window.
        iterations: usize,
    },
    /// A caller-provided buffer is too short.
    #[error("the buffer holds {found} values but {needed} are needed")]
    BufferTooSmall {
        /// Required length.
        needed: usize,
        /// Offered length.
        found: usize,
    },
    /// The buffers of dimension `n` and window capacity `m` hold more scalars than a `usize`
    /// counts, more bytes than an allocation may have, or more than the heap could give.
    #[error(
        "dimension {n} with windows of {m} rows needs more memory than can be addressed or allocated"
    )]
    TooLarge {
        /// The parameter dimension.
        n: usize,
        /// The window capacity (maximum rows).
        m: usize,
    },
    /// A scalar setting is out of its valid range.
    #[error("invalid `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Name of the setting.
        name: &'static str,
        /// The offered value.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
}

/// A Cholesky factorisation met a pivot that is not positive and finite
/// ([`linalg::cholesky_in_place`](crate::linalg::cholesky_in_place)): the matrix is not
/// numerically positive definite, or holds a NaN or an infinity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "the matrix is not numerically positive definite (pivot {pivot} is not positive and finite)"
)]
#[non_exhaustive]
pub struct NotPositiveDefinite {
    /// Index of the failed pivot (0-based).
    pub pivot: usize,
}
