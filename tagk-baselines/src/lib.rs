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
//! (`n`) before step 1; RLS scales by `s = 1/λ` in step 6. Measured per-update times are in
//! the README.
//!
//! The faer backend runs these steps as written. The portable kernel ([`Backend::Loops`], the
//! firmware's) computes the same quantities with dot products only: `W = A P`, `Z = Wᵀ L⁻ᵀ`,
//! so that `Gᵀ w = Z L⁻¹ r` and `Gᵀ G = Z Zᵀ`. It updates `P` in place after checking a bound
//! on every new entry, and keeps `‖z_i‖²` for the checks below. The Cholesky factorisation is
//! tagk-core's [`cholesky_in_place`](tagk_core::linalg::cholesky_in_place).
//!
//! **Extreme dynamic range.** A window may pin a direction far below the rounding level of
//! the prior: `p₀ ‖a‖² / d ≳ 10¹²`, with `d = λ` or `σ_R²`. In practice this is the first
//! window of "KF-low" (`P₀ = 10³`, `σ_R² = 10⁻¹⁰`). Then `S` is numerically singular, or step
//! 6 cancels to no correct digits. This is detected: a failed Cholesky pivot, or a diagonal
//! entry `P⁺_kk ≤ 10⁴ ε P_kk`. `ε` is that of `f64` also for `f32`, where it thus catches only
//! a complete cancellation. That window is redone in information form,
//! `P⁺ = (P⁻¹ + Aᵀ A / d)⁻¹`, `Δθ = P⁺ Aᵀ r / d`, by Cholesky factorisations of `n × n`
//! matrices: about `n³ + m n²`, on such windows only.
//!
//! **Memory.** One buffer of [`covariance_buffer_len`]`(n, m)` = `2n² + 4n + 2mn + m² + 3m`
//! scalars holds everything. That is two copies of `θ`, committed by switching; `P` and a
//! second `n × n` copy, where the faer backend computes its posterior and the fallback its
//! `P⁺`, with its factorisations in place; and the workspace. [`Rls::new`] /
//! [`KalmanFilter::new`] allocate it, or the caller provides it (`with_storage`); `update` does
//! not allocate.
//!
//! The portable kernel updates `P` in place (after every check). So with `with_storage` it also
//! runs in a buffer of only [`compact_covariance_buffer_len`]`(n, m)` =
//! `n² + 3n + 2mn + m² + 3m` scalars, **without the fallback**. The windows it would redo are
//! then refused with [`EstimatorError::NumericalFailure`] and the state is kept. All others
//! give the same bits ([`Rls::has_information_fallback`]).
//!
//! Both lengths are `const fn`s that saturate at `usize::MAX` where they overflow. No buffer
//! is that long: the constructors refuse it with [`ConfigError::TooLarge`].
//! [`checked_covariance_buffer_len`] and [`checked_compact_covariance_buffer_len`] return
//! `None` there.
//!
//! With [`Backend::Faer`], faer additionally keeps per-thread packing buffers, sized by the L3
//! cache. It allocates them on first use in a thread. The constructor runs one dummy update so
//! they exist for the constructing thread. An estimator moved to another thread triggers that
//! one-time allocation there on its first update.
//!
//! # Failure handling
//!
//! Every update validates the window first: shape, capacity, finiteness, with the same typed
//! [`EstimatorError`](tagk_core::EstimatorError)s as the Kaczmarz estimators. Then it computes
//! the new `θ` and `P` in scratch space, or checks a bound on every new entry before updating
//! `P` in place. It commits them only if they are finite with a positive diagonal. On any
//! error the estimate and covariance are exactly what they were.

#![no_std]

#[cfg(feature = "alloc")]
extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

mod config;
#[cfg(feature = "faer")]
mod faer_kernel;
mod filter;
mod kalman;
mod kind;
mod rls;

pub use config::{Backend, KalmanConfig, PAPER_P0, RlsConfig, WindupGuard};
pub use filter::{
    checked_compact_covariance_buffer_len, checked_covariance_buffer_len,
    compact_covariance_buffer_len, covariance_buffer_len,
};
pub use kalman::KalmanFilter;
pub use kind::{EstimatorKind, UnknownEstimator};
pub use rls::Rls;
pub use tagk_core::{ConfigError, EstimatorError, OnlineEstimator, Real, Storage, UpdateInfo};

/// The zeroed buffer the `Vec` constructors allocate ([`tagk_core::zeroed_buffer`]), or
/// [`ConfigError::TooLarge`] for sizes that overflow `usize` or an allocation the heap
/// refuses (no abort).
#[cfg(feature = "alloc")]
fn owned_buffer(n: usize, m_max: usize) -> Result<alloc::vec::Vec<f64>, ConfigError> {
    let len =
        filter::checked_buffer_len(n, m_max, true).ok_or(ConfigError::TooLarge { n, m: m_max })?;
    tagk_core::zeroed_buffer(len, n, m_max)
}

/// The storage of [`Rls`] and [`KalmanFilter`] when none is named: a `Vec<T>` with the
/// `alloc` feature (on by default, through `std`), else a `&'static mut [T]` (a static
/// buffer on a microcontroller).
#[cfg(feature = "alloc")]
pub type DefaultStorage<T> = alloc::vec::Vec<T>;
/// The storage of [`Rls`] and [`KalmanFilter`] when none is named: a `Vec<T>` with the
/// `alloc` feature (on by default, through `std`), else a `&'static mut [T]` (a static
/// buffer on a microcontroller).
#[cfg(not(feature = "alloc"))]
pub type DefaultStorage<T> = &'static mut [T];
