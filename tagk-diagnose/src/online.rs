//! Optional online pass: TAG-K (tagk-core) run over the log as it would run in flight.

use serde::Serialize;
use tagk_core::{KaczmarzConfig, OnlineEstimator, TagK};

use crate::error::DiagnoseError;
use crate::fit::{Fit, rigid_columns};
use crate::signals::Signals;

/// Frames per TAG-K window (the 5 most recent frames, 30 rows).
pub(crate) const WINDOW_FRAMES: usize = 5;

/// Summary of the online pass.
#[derive(Debug, Clone, Serialize)]
pub struct OnlineSummary {
    /// Windows processed.
    pub updates: usize,
    /// Estimate after the last window (order of `tagk_dynamics::InertialParams`).
    pub final_estimate: [f64; 10],
    /// Tail average of the estimates over the second half of the log.
    pub tail_average: [f64; 10],
    /// The batch least-squares estimate it is compared with.
    pub batch_estimate: [f64; 10],
    /// `‖tail_average − batch‖ / ‖batch‖` (relative).
    pub distance_to_batch: f64,
    /// Mass estimate after each update \[kg\] (for plots).
    pub mass_history: Vec<f64>,
}

/// Runs TAG-K over the log with windows of 5 frames (30 rows) every `stride` samples,
/// rows weighted like the batch fit `fit` and columns equilibrated (so that the mass and the
/// inertia, five orders of magnitude apart, converge alike), warm-started from zero.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] for `stride == 0`; [`DiagnoseError::Online`] if the
/// estimator rejects a window.
pub fn online_pass(s: &Signals, fit: &Fit, stride: usize) -> Result<OnlineSummary, DiagnoseError> {
    if stride == 0 {
        return Err(DiagnoseError::InvalidOption {
            field: "stride",
            reason: "0 samples between windows: the stride must be at least 1".into(),
        });
    }
    let n = s.len();
    let cols = rigid_columns(s);
    let w = fit.weights;
    let mut scale = [1.0; 10];
    for (j, col) in cols.iter().enumerate() {
        let mut s2 = 0.0;
        for (c, d) in col.iter().enumerate() {
            if let Some(v) = d {
                s2 += w[c] * w[c] * v.iter().map(|x| x * x).sum::<f64>();
            }
        }
        scale[j] = if s2 > 0.0 {
            (n as f64 / s2).sqrt()
        } else {
            1.0
        };
    }
    let rows = 6 * WINDOW_FRAMES;
    let mut est = TagK::<f64, Vec<f64>>::new(10, rows, KaczmarzConfig::default())
        .map_err(|e| DiagnoseError::Online(e.to_string()))?;
    let mut a = vec![0.0; rows * 10];
    let mut b = vec![0.0; rows];
    let mut updates = 0;
    let mut tail = [0.0; 10];
    let mut tail_n = 0usize;
    let mut mass_history = Vec::new();
    let mut end = WINDOW_FRAMES;
    while end <= n {
        for (f, i) in (end - WINDOW_FRAMES..end).enumerate() {
            for c in 0..6 {
                let r = 6 * f + c;
                for (j, col) in cols.iter().enumerate() {
                    a[r * 10 + j] = col[c].as_ref().map_or(0.0, |v| v[i]) * w[c] * scale[j];
                }
                b[r] = s.wrench()[i][c] * w[c];
            }
        }
        est.update(&a, &b)
            .map_err(|e| DiagnoseError::Online(e.to_string()))?;
        updates += 1;
        let th = est.estimate();
        mass_history.push(th[0] * scale[0]);
        if end > n / 2 {
            for j in 0..10 {
                tail[j] += th[j] * scale[j];
            }
            tail_n += 1;
        }
        end += stride;
    }
    let last = est.estimate();
    let final_estimate: [f64; 10] = std::array::from_fn(|j| last[j] * scale[j]);
    let tail_average: [f64; 10] = std::array::from_fn(|j| tail[j] / tail_n.max(1) as f64);
    let batch = fit.theta.to_array();
    let nb = batch.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d = tail_average
        .iter()
        .zip(&batch)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    Ok(OnlineSummary {
        updates,
        final_estimate,
        tail_average,
        batch_estimate: batch,
        distance_to_batch: if nb > 0.0 { d / nb } else { d },
        mass_history,
    })
}
