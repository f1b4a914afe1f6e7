//! Zero-order-hold discretisation `ẋ = A x + B u  →  x⁺ = A_d x + B_d u` over `dt`:
//!
//! ```text
//! A_d = Φ(dt) = exp(A dt),     B_d = Γ(dt) B,     Γ(t) = ∫₀ᵗ exp(A s) ds
//! ```
//!
//! (the blocks of `exp([[A, B], [0, 0]] dt)`). Computed by scaling and squaring of a
//! truncated Taylor series: with `t = dt / 2ˢ` chosen so that `θ = ‖A t‖₁ ≤ 1/2`,
//!
//! ```text
//! Ψ = Σ_{k=0}^{K} (A t)ᵏ / (k+1)!   (Horner),   Γ(t) = t Ψ,   Φ(t) = 1 + (A t) Ψ,
//! ```
//!
//! where `K` is the smallest order with `θ^{K+1}/(K+1)! ≤ 1e-17` (the truncation error of both
//! series is below that times `e^θ`), then `s` doublings `Γ(2t) = Γ(t) + Φ(t) Γ(t)`,
//! `Φ(2t) = Φ(t)²`. For the 50 Hz hover quadrotor `θ ≈ 0.2`: no doubling and `K = 12`, i.e.
//! 13 products of 12×12 matrices.
//! That is about 1.5× faster than nalgebra's Padé exponential of the 16×16 augmented matrix
//! (bench `linearize/*`), against which it is tested.

use nalgebra::{DefaultAllocator, Dim, OMatrix, allocator::Allocator};

use crate::ControlError;

/// Largest `‖A t‖₁` accepted by the series before squaring.
const THETA_MAX: f64 = 0.5;
/// Truncation threshold of the series.
const SERIES_TOL: f64 = 1e-17;

/// `(A_d, B_d)`: a discrete-time state matrix (n×n) and input matrix (n×m).
pub type DiscretePair<N, M> = (OMatrix<f64, N, N>, OMatrix<f64, N, M>);

/// Zero-order-hold discretisation of `ẋ = A x + B u` (`A` n×n, `B` n×m) over `dt` \[s\]:
/// returns `(A_d, B_d)` (module docs). Generic over nalgebra dimensions: statically sized
/// inputs allocate nothing.
///
/// # Errors
/// [`ControlError::InvalidTimeStep`] unless `dt > 0` and finite;
/// [`ControlError::ShapeMismatch`] if `A` is not square or `B` has another row count;
/// [`ControlError::NonFinite`] for non-finite input or overflow (`‖A dt‖` astronomically
/// large).
pub fn discretize_zoh<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    dt: f64,
) -> Result<DiscretePair<N, M>, ControlError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M>,
{
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(ControlError::InvalidTimeStep { dt });
    }
    let n = a.nrows();
    if a.ncols() != n || b.nrows() != n {
        return Err(ControlError::ShapeMismatch {
            a: a.shape(),
            b: b.shape(),
        });
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(ControlError::NonFinite {
            what: "continuous model",
        });
    }
    let (nd, md) = b.shape_generic();

    // Scaling: t = dt / 2^s with ‖A t‖₁ ≤ THETA_MAX.
    let norm = a.column_iter().map(|c| c.lp_norm(1)).fold(0.0, f64::max) * dt;
    let mut s = 0u32;
    let mut theta = norm;
    while theta > THETA_MAX {
        theta *= 0.5;
        s += 1;
    }
    let t = dt / 2f64.powi(s as i32);
    // Order: smallest K with θ^{K+1}/(K+1)! ≤ SERIES_TOL (K ≤ 20 since θ ≤ 1/2).
    let mut order = 1usize;
    let mut term = theta * theta / 2.0;
    while term > SERIES_TOL && order < 30 {
        order += 1;
        term *= theta / (order + 1) as f64;
    }

    let x = a * t;
    let mut psi = OMatrix::<f64, N, N>::identity_generic(nd, nd);
    let mut tmp = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
    for j in (1..=order).rev() {
        // psi ← 1 + X psi / (j + 1)
        x.mul_to(&psi, &mut tmp);
        tmp /= (j + 1) as f64;
        for i in 0..n {
            tmp[(i, i)] += 1.0;
        }
        core::mem::swap(&mut psi, &mut tmp);
    }
    // Φ = 1 + X Ψ, Γ = t Ψ.
    let mut phi = OMatrix::<f64, N, N>::identity_generic(nd, nd);
    phi.gemm(1.0, &x, &psi, 1.0);
    let mut gamma = psi * t;
    for _ in 0..s {
        // Γ ← Γ + Φ Γ; Φ ← Φ².
        tmp.copy_from(&gamma);
        gamma.gemm(1.0, &phi, &tmp, 1.0);
        phi.mul_to(&phi, &mut tmp);
        core::mem::swap(&mut phi, &mut tmp);
    }
    let mut bd = OMatrix::<f64, N, M>::zeros_generic(nd, md);
    gamma.mul_to(b, &mut bd);
    if phi.iter().chain(bd.iter()).any(|v| !v.is_finite()) {
        return Err(ControlError::NonFinite {
            what: "discretised model",
        });
    }
    Ok((phi, bd))
}
