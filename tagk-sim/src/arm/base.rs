//! Numerical base parameters: the identifiable combinations of a set of regressor columns.

use nalgebra::{DMatrix, DVector};
use rand::RngExt;

use super::ArmModel;
use crate::SimError;

/// Which inertial parameters the estimator learns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimationScope {
    /// The flange body's 10 parameters (link + payload); the other links are known.
    Payload,
    /// Every body's 10 parameters (`10·n`), reduced to the base parameters.
    AllLinks,
}

impl EstimationScope {
    /// The regressor columns this scope estimates, for a tree of `n_bodies` bodies.
    pub fn columns(self, n_bodies: usize) -> Vec<usize> {
        match self {
            EstimationScope::Payload => (10 * (n_bodies - 1)..10 * n_bodies).collect(),
            EstimationScope::AllLinks => (0..10 * n_bodies).collect(),
        }
    }

    /// A short name for tables.
    pub fn name(self) -> &'static str {
        match self {
            EstimationScope::Payload => "payload",
            EstimationScope::AllLinks => "all links",
        }
    }
}

/// Relative tolerance of the column selection: a column is dependent when the part of it
/// that the kept columns do not explain has a norm below this fraction of its own.
pub const BASE_TOLERANCE: f64 = 1e-6;

/// A column whose norm is below this fraction of the largest column's is zero (round-off).
pub const ZERO_COLUMN: f64 = 1e-10;

/// Random samples (per estimated column) stacked to find the base parameters.
pub const BASE_SAMPLES_PER_COLUMN: usize = 20;

/// The numerical base parameters of a set of regressor columns.
///
/// `Y_S` (columns `S` of the joint-torque regressor) is stacked over random states, joint
/// positions uniform within the limits, velocities within the limits and accelerations in
/// `±5 rad/s²`. Columns are scaled to unit norm and visited from the last parameter to the
/// first (so the flange body keeps its own). A column below [`ZERO_COLUMN`] of the largest
/// is dropped. A column is kept when its
/// Gram–Schmidt remainder exceeds [`BASE_TOLERANCE`]. The kept columns `I` give
/// `β = θ_I + K θ_D` with `Y_D = Y_I K` (least squares on the stack), so `Y_S θ_S = Y_I β`.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseParameters {
    /// The estimated columns `S` (indices into the full `10·n` parameter vector).
    pub columns: Vec<usize>,
    /// Positions in `S` of the kept (independent) columns, ascending.
    pub independent: Vec<usize>,
    /// Positions in `S` of the dependent columns, ascending.
    pub dependent: Vec<usize>,
    /// `K` (`|I| × |D|`): `Y_D = Y_I K`.
    pub k: DMatrix<f64>,
    /// RMS of each kept column over the stack (the torque \[N m\] per unit parameter): the
    /// column scales of [`ArmAdaptation::Scaled`](super::ArmAdaptation::Scaled).
    pub scales: Vec<f64>,
}

impl BaseParameters {
    /// The base parameters of `scope` for `model`, from the random states of `seed`.
    ///
    /// # Errors
    /// [`SimError::Dynamics`] if the regressor fails; [`SimError::InvalidParameter`] if no
    /// column is identifiable.
    pub fn compute(model: &ArmModel, scope: EstimationScope, seed: u64) -> Result<Self, SimError> {
        let tree = &model.tree;
        let n = tree.dof();
        let columns = scope.columns(tree.n_bodies());
        let s = columns.len();
        let samples = BASE_SAMPLES_PER_COLUMN * s.div_ceil(n).max(1) + 10;
        let mut rng = crate::sim::sub_rng(seed, 0xBA5E);
        let mut w = DMatrix::<f64>::zeros(samples * n, s);
        for k in 0..samples {
            let q: Vec<f64> = (0..n)
                .map(|j| rng.random_range(model.limits.lower[j]..model.limits.upper[j]))
                .collect();
            let qd: Vec<f64> = (0..n)
                .map(|j| {
                    let v = model.limits.velocity[j];
                    rng.random_range(-v..v)
                })
                .collect();
            let qdd: Vec<f64> = (0..n).map(|_| rng.random_range(-5.0..5.0)).collect();
            let y = tree.joint_torque_regressor(&q, &qd, &qdd)?;
            for r in 0..n {
                for (c, &col) in columns.iter().enumerate() {
                    w[(k * n + r, c)] = y[(r, col)];
                }
            }
        }
        Self::from_stack(columns, &w)
    }

    /// The base parameters of the stacked regressor `w` (one column per entry of `columns`).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] if no column is identifiable.
    pub fn from_stack(columns: Vec<usize>, w: &DMatrix<f64>) -> Result<Self, SimError> {
        let s = w.ncols();
        let mut basis: Vec<DVector<f64>> = Vec::new();
        let mut keep = vec![false; s];
        let largest = w.column_iter().map(|c| c.norm()).fold(0.0, f64::max);
        for c in (0..s).rev() {
            let col = w.column(c).into_owned();
            let norm = col.norm();
            // A column of round-off (a parameter that no joint feels) is zero.
            if norm.is_nan() || norm <= ZERO_COLUMN * largest {
                continue;
            }
            let mut r = col / norm;
            // Two passes of modified Gram–Schmidt for stability.
            for _ in 0..2 {
                for b in &basis {
                    let d = b.dot(&r);
                    r -= b * d;
                }
            }
            let rn = r.norm();
            if rn > BASE_TOLERANCE {
                basis.push(r / rn);
                keep[c] = true;
            }
        }
        let independent: Vec<usize> = (0..s).filter(|&c| keep[c]).collect();
        let dependent: Vec<usize> = (0..s).filter(|&c| !keep[c]).collect();
        if independent.is_empty() {
            return Err(SimError::InvalidParameter {
                name: "identifiable columns",
                value: 0.0,
                reason: "the regressor columns are all zero",
            });
        }
        let wi = w.select_columns(&independent);
        let wd = w.select_columns(&dependent);
        let k = if dependent.is_empty() {
            DMatrix::zeros(independent.len(), 0)
        } else {
            let svd = wi.clone().svd(true, true);
            svd.solve(&wd, 1e-12)
                .map_err(|_| SimError::InvalidParameter {
                    name: "base parameter solve",
                    value: 0.0,
                    reason: "least squares failed",
                })?
        };
        let rows = w.nrows().max(1) as f64;
        let scales = independent
            .iter()
            .map(|&c| w.column(c).norm() / rows.sqrt())
            .collect();
        Ok(Self {
            columns,
            independent,
            dependent,
            k,
            scales,
        })
    }

    /// Number of base parameters `r = |I|` (the estimator's dimension).
    pub fn rank(&self) -> usize {
        self.independent.len()
    }

    /// The base parameters `β = θ_I + K θ_D` of the full parameter vector `theta` (`10·n`).
    pub fn to_base(&self, theta: &[f64]) -> Vec<f64> {
        let ts: Vec<f64> = self.columns.iter().map(|&c| theta[c]).collect();
        let td =
            DVector::from_iterator(self.dependent.len(), self.dependent.iter().map(|&d| ts[d]));
        let kd = &self.k * td;
        self.independent
            .iter()
            .enumerate()
            .map(|(i, &c)| ts[c] + kd[i])
            .collect()
    }

    /// A full parameter vector with base parameters `beta`: the dependent and unestimated
    /// entries are `reference`'s, the independent ones `β − K θ_D`. Its torques are `Y_I β`
    /// plus the unestimated columns' `reference` share.
    pub fn to_full(&self, beta: &[f64], reference: &[f64]) -> Vec<f64> {
        let mut theta = reference.to_vec();
        let td = DVector::from_iterator(
            self.dependent.len(),
            self.dependent.iter().map(|&d| reference[self.columns[d]]),
        );
        let kd = &self.k * td;
        for (i, &c) in self.independent.iter().enumerate() {
            theta[self.columns[c]] = beta[i] - kd[i];
        }
        theta
    }
}
