//! Both filters behind one test trait that also exposes the covariance.

use tagk_baselines::{KalmanConfig, KalmanFilter, OnlineEstimator, Rls, RlsConfig, WindupGuard};

use super::BACKENDS;

pub trait Filter: OnlineEstimator<f64> {
    fn cov(&self) -> &[f64];
    /// `(θ, P)`, copied.
    fn snapshot(&self) -> (Vec<f64>, Vec<f64>) {
        (self.estimate().to_vec(), self.cov().to_vec())
    }
}

impl Filter for Rls {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}

impl Filter for KalmanFilter {
    fn cov(&self) -> &[f64] {
        self.covariance()
    }
}

/// The four paper presets plus a guarded RLS, on every backend.
pub fn all_filters(n: usize, m_max: usize) -> Vec<Box<dyn Filter>> {
    let mut out: Vec<Box<dyn Filter>> = Vec::new();
    for backend in BACKENDS {
        for cfg in [
            RlsConfig::LOW,
            RlsConfig::HIGH,
            RlsConfig::HIGH.with_windup_guard(WindupGuard::MaxTrace(10.0)),
        ] {
            out.push(Box::new(
                Rls::new(n, m_max, cfg.with_backend(backend)).unwrap(),
            ));
        }
        for cfg in [KalmanConfig::LOW, KalmanConfig::HIGH] {
            out.push(Box::new(
                KalmanFilter::new(n, m_max, cfg.with_backend(backend)).unwrap(),
            ));
        }
    }
    out
}
