//! The trait every online estimator in tagk implements, and the window checks they share.

use crate::{ConfigError, EstimatorError, Real};

/// What one successful update did, for logging and progress observers.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UpdateInfo {
    /// Rows in the window (`m`).
    pub rows: usize,
    /// Inner iterations performed: Kaczmarz projections, or 1 for a recursive filter.
    pub iterations: usize,
    /// `‖b − A θ_prev‖₂` before the update, over the window's usable (non-zero) rows,
    /// in the measurement's units.
    pub prior_residual_norm: f64,
    /// Whether an iterative method stopped early because `‖r‖₂ ≤ tolerance`.
    pub converged: bool,
}

/// An estimator of a parameter vector `θ ∈ ℝⁿ` from a stream of linear windows `A θ ≈ b`.
///
/// Each call to [`update`](Self::update) brings the newest window: `A` is `m × n`, row-major,
/// and `b` has `m` entries. `m` may change between calls up to [`capacity`](Self::capacity).
/// A failed update returns a typed [`EstimatorError`] and leaves every part of the state as it
/// was. The trait is object-safe: simulators hold `Box<dyn OnlineEstimator<f64> + Send>`.
///
/// # Examples
///
/// One driver for any estimator behind the trait: it feeds a fixed stream, then checks the
/// estimate against the least-squares solution computed by hand.
///
/// ```
/// use tagk_core::{GreedyKaczmarz, KaczmarzConfig, OnlineEstimator, TagK};
///
/// // b = a θ for θ = (0.5, 3): rows (1, 0), (0, 1), (1, 1), windows of 2 rows.
/// let a = [1.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 0.0];
/// let b = [0.5, 3.0, 3.5, 0.5];
/// fn drive(est: &mut dyn OnlineEstimator<f64>, a: &[f64], b: &[f64]) -> Vec<f64> {
///     for _ in 0..50 {
///         for (aw, bw) in a.chunks(4).zip(b.chunks(2)) {
///             est.update(aw, bw).expect("a valid window");
///         }
///     }
///     est.estimate().to_vec()
/// }
/// let cfg = KaczmarzConfig::default();
/// let mut estimators: Vec<Box<dyn OnlineEstimator<f64>>> = vec![
///     Box::new(TagK::<f64, Vec<f64>>::new(2, 2, cfg)?),
///     Box::new(GreedyKaczmarz::<f64, Vec<f64>>::new(2, 2, cfg)?),
/// ];
/// for est in &mut estimators {
///     let theta = drive(est.as_mut(), &a, &b);
///     // The system is consistent: the least-squares solution is θ = (0.5, 3).
///     assert!((theta[0] - 0.5).abs() < 1e-9 && (theta[1] - 3.0).abs() < 1e-9, "{theta:?}");
///     assert_eq!(est.dim(), 2);
///     assert_eq!(est.capacity(), 2);
///     // A window longer than the capacity is refused, and reset restarts from a given θ.
///     assert!(est.update(&[1.0; 6], &[1.0; 3]).is_err());
///     est.reset(&[0.0, 0.0])?;
///     assert_eq!(est.estimate(), &[0.0, 0.0]);
/// }
/// assert_eq!(estimators[0].name(), "TAG-K");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub trait OnlineEstimator<T: Real = f64> {
    /// A short, stable name for tables and plots (for example `"TAG-K"` or `"RLS-low"`).
    fn name(&self) -> &str;

    /// The parameter dimension `n`.
    fn dim(&self) -> usize;

    /// The largest number of rows a window may have.
    fn capacity(&self) -> usize;

    /// The current estimate `θ̂` (length `n`).
    fn estimate(&self) -> &[T];

    /// Incorporates one window `A θ ≈ b` (`a`: `m·n` values row-major, `b`: `m` values).
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError>;

    /// Returns the estimator to its just-constructed state with `θ̂ = estimate`: covariances
    /// back to their initial value, random generators re-seeded.
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError>;

    /// Sets the residual tolerance `‖b − A θ‖₂` (measurement units) at which an iterative
    /// estimator stops a window's iterations, and returns `true`; estimators without such a
    /// stop (the recursive filters, whose noise model is their covariance) ignore it and return
    /// `false` (the default). A negative or non-finite value is ignored too. Used by the
    /// noise-aware stop of [`FrontEnd`](crate::FrontEnd).
    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        let _ = tolerance;
        false
    }
}

impl<T: Real, E: OnlineEstimator<T> + ?Sized> OnlineEstimator<T> for &mut E {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn capacity(&self) -> usize {
        (**self).capacity()
    }
    fn estimate(&self) -> &[T] {
        (**self).estimate()
    }
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        (**self).update(a, b)
    }
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        (**self).reset(estimate)
    }
    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        (**self).set_tolerance(tolerance)
    }
}

#[cfg(feature = "alloc")]
impl<T: Real, E: OnlineEstimator<T> + ?Sized> OnlineEstimator<T> for alloc::boxed::Box<E> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn dim(&self) -> usize {
        (**self).dim()
    }
    fn capacity(&self) -> usize {
        (**self).capacity()
    }
    fn estimate(&self) -> &[T] {
        (**self).estimate()
    }
    fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        (**self).update(a, b)
    }
    fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        (**self).reset(estimate)
    }
    fn set_tolerance(&mut self, tolerance: f64) -> bool {
        (**self).set_tolerance(tolerance)
    }
}

/// Checks the sizes every estimator is built with: a parameter dimension `n ≥ 1` and a window
/// capacity `m_max ≥ 1`.
pub fn check_dimensions(n: usize, m_max: usize) -> Result<(), ConfigError> {
    if n == 0 {
        return Err(ConfigError::ZeroDimension);
    }
    if m_max == 0 {
        return Err(ConfigError::ZeroCapacity);
    }
    Ok(())
}

/// Checks a window's shape against an estimator of dimension `n` and capacity `capacity`,
/// and returns the number of rows `m = b.len()`. Does not look at the values.
pub fn check_window_shape<T>(
    n: usize,
    capacity: usize,
    a: &[T],
    b: &[T],
) -> Result<usize, EstimatorError> {
    let m = b.len();
    if m == 0 {
        return Err(EstimatorError::EmptyWindow);
    }
    if m > capacity {
        return Err(EstimatorError::WindowTooLarge { rows: m, capacity });
    }
    if a.len() != m * n {
        return Err(EstimatorError::ShapeMismatch {
            expected: m * n,
            found: a.len(),
            rows: m,
            cols: n,
        });
    }
    Ok(m)
}

/// Finds the first non-finite value of a window (regressor first, row by row, then
/// measurements) and returns the matching error, or `Ok(())` when every value is finite.
pub fn check_window_finite<T: Real>(n: usize, a: &[T], b: &[T]) -> Result<(), EstimatorError> {
    if let Some(k) = a.iter().position(|v| !v.is_finite()) {
        return Err(EstimatorError::NonFiniteRegressor {
            row: k / n,
            col: k % n,
        });
    }
    if let Some(row) = b.iter().position(|v| !v.is_finite()) {
        return Err(EstimatorError::NonFiniteMeasurement { row });
    }
    Ok(())
}

/// [`check_window_shape`] followed by [`check_window_finite`]: the full validation an
/// estimator performs before touching its state. Returns `m`.
pub fn validate_window<T: Real>(
    n: usize,
    capacity: usize,
    a: &[T],
    b: &[T],
) -> Result<usize, EstimatorError> {
    let m = check_window_shape(n, capacity, a, b)?;
    check_window_finite(n, a, b)?;
    Ok(m)
}

/// Checks a vector handed to [`OnlineEstimator::reset`]: length `n`, every value finite.
pub fn validate_estimate<T: Real>(n: usize, estimate: &[T]) -> Result<(), EstimatorError> {
    if estimate.len() != n {
        return Err(EstimatorError::DimensionMismatch {
            expected: n,
            found: estimate.len(),
        });
    }
    if let Some(index) = estimate.iter().position(|v| !v.is_finite()) {
        return Err(EstimatorError::NonFiniteEstimate { index });
    }
    Ok(())
}
