#![doc = include_str!("../README.md")]
//!
//! # Algorithm and cost per update
//!
//! Both filters share one block update. For a window `A` (`m × n`) with residual
//! `r = b − A θ`, prior covariance `P` and diagonal term `d` (`λ` for RLS, `σ_R²` for the
//! Kalman filter):
//!
//! | step | operation | multiply-adds |
//! |---|---|---|
//! | 0 | `r = b − A θ` | `m n` |
//! | 1 | `U = A P` | `m n²` |
//! | 2 | `S = U Aᵀ + d·I` (lower triangle) | `m² n / 2` |
//! | 3 | `S = L Lᵀ` (Cholesky; a non-positive pivot is refused) | `m³ / 6` |
//! | 4 | `[G | w] = L⁻¹ [U | r]` (forward substitution) | `m² n / 2` |
//! | 5 | `θ ← θ + Gᵀ w` (`= θ + K r`, `K = P Aᵀ S⁻¹`) | `m n` |
//! | 6 | `P ← s·(P − Gᵀ G)` (upper triangle, mirrored; `Gᵀ G = K A P`) | `m n² / 2` |
//!
//! In total about `1.5 m n² + m² n + m³/6` multiply-adds: `O(m n²)` for `m ≤ n`, never
//! `O(n³)`, and no inverse or gain matrix is formed. The Kalman filter adds `P ← P + σ_Q²·I`
//! (`n`) before step 1; RLS scales by `s = 1/λ` in step 6. All buffers (`2n² + m(n+1) + m² + 3n`
//! values) are allocated by the constructor; `update` does not allocate.
//!
//! # Failure handling
//!
//! Every update validates the window first (shape, capacity, finiteness: the same typed
//! [`EstimatorError`](tagk_core::EstimatorError)s as the Kaczmarz estimators), then works on
//! scratch copies of `θ` and `P` and commits them only if the Cholesky factorisation succeeded
//! and the new `θ` and `P` are finite with a positive diagonal. On any error the estimate and
//! covariance are exactly what they were.

mod config;
mod kalman;
mod kernel;
mod rls;
mod state;

pub use config::{Backend, KalmanConfig, RlsConfig, WindupGuard};
pub use kalman::KalmanFilter;
pub use rls::Rls;
pub use tagk_core::{ConfigError, EstimatorError, OnlineEstimator, UpdateInfo};
