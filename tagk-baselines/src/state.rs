//! State shared by the two filters: estimate, covariance, their scratch copies and the
//! block-update workspace. Updates work on the copies and commit by swapping, so a failed
//! update leaves the estimate and covariance bit-for-bit as they were.

use tagk_core::{EstimatorError, validate_estimate};

use crate::Backend;
use crate::kernel::Workspace;

pub(crate) struct FilterState {
    pub(crate) n: usize,
    pub(crate) m_max: usize,
    p0: f64,
    pub(crate) theta: Vec<f64>,
    theta_next: Vec<f64>,
    /// `n × n`, row-major, symmetric.
    pub(crate) p: Vec<f64>,
    pub(crate) p_next: Vec<f64>,
    pub(crate) ws: Workspace,
}

impl FilterState {
    /// `θ = 0`, `P = p₀·I`, every buffer allocated. `n, m_max ≥ 1` checked by the caller.
    pub(crate) fn new(n: usize, m_max: usize, p0: f64, backend: Backend) -> Self {
        let mut s = Self {
            n,
            m_max,
            p0,
            theta: vec![0.0; n],
            theta_next: vec![0.0; n],
            p: vec![0.0; n * n],
            p_next: vec![0.0; n * n],
            ws: Workspace::new(n, m_max, backend),
        };
        s.ws.warm_up(&mut s.p_next);
        s.reset_covariance();
        s
    }

    fn reset_covariance(&mut self) {
        let n = self.n;
        self.p.fill(0.0);
        for k in 0..n {
            self.p[k * n + k] = self.p0;
        }
    }

    /// `θ = estimate`, `P = p₀·I`.
    pub(crate) fn reset(&mut self, estimate: &[f64]) -> Result<(), EstimatorError> {
        validate_estimate(self.n, estimate)?;
        self.theta.copy_from_slice(estimate);
        self.reset_covariance();
        Ok(())
    }

    /// `θ_next = θ + Δθ`; if finite, makes `θ_next` and `P_next` current.
    pub(crate) fn commit(&mut self) -> Result<(), EstimatorError> {
        let dtheta = self.ws.dtheta();
        let mut finite = true;
        for ((next, &t), &d) in self.theta_next.iter_mut().zip(&self.theta).zip(dtheta) {
            *next = t + d;
            finite &= next.is_finite();
        }
        if !finite {
            return Err(EstimatorError::Diverged);
        }
        core::mem::swap(&mut self.theta, &mut self.theta_next);
        core::mem::swap(&mut self.p, &mut self.p_next);
        Ok(())
    }

    /// `trace(P)` of the current covariance.
    pub(crate) fn trace(&self) -> f64 {
        trace(&self.p, self.n)
    }
}

/// `trace` of an `n × n` row-major matrix.
pub(crate) fn trace(p: &[f64], n: usize) -> f64 {
    (0..n).map(|k| p[k * n + k]).sum()
}
