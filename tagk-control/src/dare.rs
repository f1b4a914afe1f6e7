//! Discrete algebraic Riccati equation (DARE)
//!
//! ```text
//! P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q,        K = (R + BᵀPB)⁻¹ BᵀPA
//! ```
//!
//! for the discrete-time system `x⁺ = A x + B u` with cost `Σ xᵀQx + uᵀRu`; the
//! optimal feedback is `u = −K x`.
//!
//! Two solvers share one validation and one result type:
//!
//! - [`solve_dare`] — the reference: iterates the Riccati difference equation
//!   `P_{k+1} = 𝓡(P_k)` from a given `P₀` (a warm start: the solution for a nearby model)
//!   until the relative change `‖P_{k+1} − P_k‖_F ≤ tol · ‖P_{k+1}‖_F`. Converges linearly
//!   with rate about `ρ(A − BK)²`.
//! - [`solve_dare_sda`] — the structure-preserving doubling algorithm (Chu, Fan & Lin 2005,
//!   *A structure-preserving doubling algorithm for discrete-time algebraic Riccati
//!   equations*). Its `k`-th iterate equals the `2ᵏ`-th iterate of the difference equation
//!   started from `P = 0`, so it converges quadratically. It cannot use a warm start.
//!
//! Both are generic over nalgebra dimensions, and both sizes go through the same code.
//! `SMatrix<f64, 12, 12>` / `SMatrix<f64, 12, 4>` are statically sized: no heap allocation on
//! success. `DMatrix<f64>` allocates its workspace once per call, nothing inside the loop.
//! The hot kernels have a constant-size fast path for `n = 12`.
//! Linear systems are solved by Cholesky (for `R + BᵀPB`) and partially pivoted LU
//! (for `I + GH` in the doubling); no inverse is formed.

use nalgebra::{DMatrix, DefaultAllocator, Dim, Matrix, OMatrix, RawStorage, allocator::Allocator};

use crate::linalg::{
    backward_lower_t_in_place, cholesky_in_place, cholesky_solve_in_place, forward_lower_in_place,
    frobenius_diff, lu_in_place, lu_solve_transposed_in_place, max_asymmetry, symmetrize,
};

/// Relative tolerance under which `Q`, `R` and `P₀` count as symmetric:
/// `max |M_ij − M_ji| ≤ SYMMETRY_TOL · max(1e-300, max |M_ij|)`.
pub const SYMMETRY_TOL: f64 = 1e-10;

/// Errors of the Riccati solvers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DareError {
    /// An input matrix has the wrong shape (A must be n×n, B n×m, Q n×n, R m×m, P₀ n×n).
    #[error("shape mismatch: {what} is {found:?}, expected {expected:?} (rows, columns)")]
    ShapeMismatch {
        /// Which input.
        what: &'static str,
        /// Expected (rows, columns).
        expected: (usize, usize),
        /// Actual (rows, columns).
        found: (usize, usize),
    },
    /// An input contains NaN or ±∞.
    #[error("{what} contains a non-finite entry")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// `Q`, `R` or `P₀` is not symmetric (see [`SYMMETRY_TOL`]).
    #[error("{what} is not symmetric (largest |M_ij - M_ji| = {asymmetry:e})")]
    NotSymmetric {
        /// Which input.
        what: &'static str,
        /// Largest absolute asymmetry.
        asymmetry: f64,
    },
    /// `Q` has a negative eigenvalue (beyond `1e-12 · n · max|Q_ij|`).
    #[error("Q is not positive semidefinite (smallest eigenvalue {min_eigenvalue:e})")]
    QNotPositiveSemidefinite {
        /// Smallest eigenvalue of `Q`.
        min_eigenvalue: f64,
    },
    /// `R` is not positive definite (its Cholesky factorisation fails).
    #[error("R is not positive definite (smallest eigenvalue {min_eigenvalue:e})")]
    RNotPositiveDefinite {
        /// Smallest eigenvalue of `R`.
        min_eigenvalue: f64,
    },
    /// `R + BᵀPB` (iteration) or `I + GH` (doubling) lost definiteness / became singular,
    /// e.g. because the warm start `P₀` was indefinite.
    #[error(
        "breakdown at iteration {iteration}: R + B^T P B not positive definite or I + G H singular"
    )]
    Breakdown {
        /// Iteration at which it happened (1-based).
        iteration: usize,
    },
    /// The iterates became non-finite: typically `(A, B)` is not stabilisable.
    #[error("iterates diverged (non-finite) at iteration {iteration}; is (A, B) stabilisable?")]
    Diverged {
        /// Iteration at which it happened (1-based).
        iteration: usize,
    },
    /// The iteration cap was reached before the relative-change test passed.
    #[error(
        "no convergence after {iterations} iterations (last relative change {relative_change:e})"
    )]
    NotConverged {
        /// Iterations performed.
        iterations: usize,
        /// Last relative change `‖P_{k+1} − P_k‖_F / ‖P_{k+1}‖_F`.
        relative_change: f64,
    },
}

/// Stopping rule of the Riccati solvers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DareOptions {
    /// Relative change `‖P_{k+1} − P_k‖_F / ‖P_{k+1}‖_F` at which to stop (dimensionless).
    /// Because `P_{k+1} − P_k` is exactly the DARE residual of `P_k`, the relative residual
    /// of the returned `P` is below this (times `ρ(A−BK)² < 1`).
    pub tolerance: f64,
    /// Iteration cap: Riccati steps for [`solve_dare`], doubling steps for
    /// [`solve_dare_sda`] (each doubling step doubles the horizon, so 64 is "infinite").
    pub max_iterations: usize,
}

impl Default for DareOptions {
    /// `tolerance = 1e-11`, `max_iterations = 100 000`.
    fn default() -> Self {
        Self {
            tolerance: 1e-11,
            max_iterations: 100_000,
        }
    }
}

/// Result of a Riccati solve.
#[derive(Debug, Clone, PartialEq)]
pub struct DareSolution<N: Dim, M: Dim>
where
    DefaultAllocator: Allocator<N, N> + Allocator<M, N>,
{
    /// Stabilising solution `P` (n×n, symmetric positive semidefinite).
    pub p: OMatrix<f64, N, N>,
    /// Optimal gain `K = (R + BᵀPB)⁻¹BᵀPA` (m×n) for the feedback `u = −K x`.
    pub k: OMatrix<f64, M, N>,
    /// Iterations used (Riccati steps, or doubling steps for SDA).
    pub iterations: usize,
    /// Relative DARE residual of the returned `P`:
    /// `‖AᵀPA − P − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q‖_F / ‖P‖_F` (absolute if `P = 0`).
    pub residual: f64,
}

/// Workspace of one Riccati step (allocated once per solve).
struct RiccatiWork<N: Dim, M: Dim>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    at: OMatrix<f64, N, N>,
    bt: OMatrix<f64, M, N>,
    pa: OMatrix<f64, N, N>,
    btp: OMatrix<f64, M, N>,
    bpa: OMatrix<f64, M, N>,
    s: OMatrix<f64, M, M>,
    y: OMatrix<f64, M, N>,
    yt: OMatrix<f64, N, M>,
    k: OMatrix<f64, M, N>,
    next: OMatrix<f64, N, N>,
}

impl<N: Dim, M: Dim> RiccatiWork<N, M>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    fn new(a: &OMatrix<f64, N, N>, b: &OMatrix<f64, N, M>) -> Self {
        let (n, m) = b.shape_generic();
        Self {
            at: a.transpose(),
            bt: b.transpose(),
            pa: OMatrix::zeros_generic(n, n),
            btp: OMatrix::zeros_generic(m, n),
            bpa: OMatrix::zeros_generic(m, n),
            s: OMatrix::zeros_generic(m, m),
            y: OMatrix::zeros_generic(m, n),
            yt: OMatrix::zeros_generic(n, m),
            k: OMatrix::zeros_generic(m, n),
            next: OMatrix::zeros_generic(n, n),
        }
    }

    /// `next = 𝓡(p)`, `k = (R + BᵀpB)⁻¹Bᵀp A`. Returns `false` if `R + BᵀpB` is not PD.
    ///
    /// With `S = R + BᵀPB = LLᵀ` and `Y = L⁻¹BᵀPA`: `K = L⁻ᵀY` and
    /// `𝓡(P) = Q + Aᵀ(PA) − YᵀY`. Every product is a plain (non-transposed) `gemm` on
    /// pre-transposed operands: column `axpy`s, which vectorise.
    fn step(
        &mut self,
        a: &OMatrix<f64, N, N>,
        b: &OMatrix<f64, N, M>,
        q: &OMatrix<f64, N, N>,
        r: &OMatrix<f64, M, M>,
        p: &OMatrix<f64, N, N>,
    ) -> bool {
        let m = self.s.nrows();
        p.mul_to(a, &mut self.pa);
        self.bt.mul_to(p, &mut self.btp);
        self.btp.mul_to(a, &mut self.bpa);
        self.s.copy_from(r);
        self.s.gemm(1.0, &self.btp, b, 1.0);
        if !cholesky_in_place(self.s.as_mut_slice(), m) {
            return false;
        }
        self.y.copy_from(&self.bpa);
        forward_lower_in_place(self.s.as_slice(), m, self.y.as_mut_slice());
        self.k.copy_from(&self.y);
        backward_lower_t_in_place(self.s.as_slice(), m, self.k.as_mut_slice());
        self.y.transpose_to(&mut self.yt);
        self.next.copy_from(q);
        self.next.gemm(1.0, &self.at, &self.pa, 1.0);
        self.next.gemm(-1.0, &self.yt, &self.y, 1.0);
        symmetrize(&mut self.next);
        true
    }
}

fn check_shape<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
    what: &'static str,
    m: &Matrix<f64, R, C, S>,
    expected: (usize, usize),
) -> Result<(), DareError> {
    if m.shape() != expected {
        return Err(DareError::ShapeMismatch {
            what,
            expected,
            found: m.shape(),
        });
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(DareError::NonFinite { what });
    }
    Ok(())
}

fn check_symmetric<D: Dim, S: RawStorage<f64, D, D>>(
    what: &'static str,
    m: &Matrix<f64, D, D, S>,
) -> Result<(), DareError> {
    let scale = m
        .iter()
        .fold(0.0_f64, |acc, v| acc.max(v.abs()))
        .max(1e-300);
    let asym = max_asymmetry(m);
    if asym > SYMMETRY_TOL * scale {
        return Err(DareError::NotSymmetric {
            what,
            asymmetry: asym,
        });
    }
    Ok(())
}

/// Smallest eigenvalue of a symmetric matrix (error path only: allocates).
fn min_eigenvalue<D: Dim, S: RawStorage<f64, D, D>>(m: &Matrix<f64, D, D, S>) -> f64 {
    let n = m.nrows();
    let d = DMatrix::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
    d.symmetric_eigenvalues().min()
}

/// Validates shapes, finiteness, symmetry and definiteness of a DARE problem.
fn validate<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    p0: Option<&OMatrix<f64, N, N>>,
) -> Result<(), DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, M>,
{
    let n = a.nrows();
    let m = b.ncols();
    check_shape("A", a, (n, n))?;
    check_shape("B", b, (n, m))?;
    check_shape("Q", q, (n, n))?;
    check_shape("R", r, (m, m))?;
    check_symmetric("Q", q)?;
    check_symmetric("R", r)?;
    if let Some(p0) = p0 {
        check_shape("P0", p0, (n, n))?;
        check_symmetric("P0", p0)?;
    }
    let mut rc = r.clone();
    if !cholesky_in_place(rc.as_mut_slice(), m) {
        return Err(DareError::RNotPositiveDefinite {
            min_eigenvalue: min_eigenvalue(r),
        });
    }
    // Q ⪰ 0  ⇔  Q + δI ≻ 0 for every δ > 0; δ is a rounding-level shift.
    let scale = q.iter().fold(0.0_f64, |acc, v| acc.max(v.abs()));
    let mut qs = q.clone();
    let shift = 1e-12 * (n as f64) * scale.max(1e-300);
    for i in 0..n {
        qs[(i, i)] += shift;
    }
    if !cholesky_in_place(qs.as_mut_slice(), n) {
        return Err(DareError::QNotPositiveSemidefinite {
            min_eigenvalue: min_eigenvalue(q),
        });
    }
    Ok(())
}

/// Relative residual and gain of the final `P`: one more Riccati step.
/// Relative residual of `p` (one Riccati step into `work`, which also leaves the gain of
/// `p` in `work.k`).
fn residual_of<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    p: &OMatrix<f64, N, N>,
    iteration: usize,
    work: &mut RiccatiWork<N, M>,
) -> Result<f64, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    if !work.step(a, b, q, r, p) {
        return Err(DareError::Breakdown { iteration });
    }
    let norm = p.norm();
    let res = frobenius_diff(&work.next, p);
    let residual = if norm > 0.0 { res / norm } else { res };
    if !residual.is_finite() {
        return Err(DareError::Diverged { iteration });
    }
    Ok(residual)
}

/// The solution for `p`: its gain and residual from one more Riccati step.
fn finish<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    p: OMatrix<f64, N, N>,
    iterations: usize,
    work: &mut RiccatiWork<N, M>,
) -> Result<DareSolution<N, M>, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    let residual = residual_of(a, b, q, r, &p, iterations + 1, work)?;
    Ok(DareSolution {
        p,
        k: work.k.clone(),
        iterations,
        residual,
    })
}

/// Relative DARE residual `‖AᵀPA − P − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q‖_F / ‖P‖_F` of a given `P`
/// (absolute if `P = 0`). Validates its inputs like the solvers.
pub fn dare_residual<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    p: &OMatrix<f64, N, N>,
) -> Result<f64, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    validate(a, b, q, r, Some(p))?;
    let mut work = RiccatiWork::new(a, b);
    Ok(finish(a, b, q, r, p.clone(), 0, &mut work)?.residual)
}

/// Solves the DARE by iterating the Riccati difference equation from `p0`.
///
/// `p0` is the warm start (symmetric; positive semidefinite in practice, e.g. the
/// solution for a nearby model, or `Q` / zero for a cold start, see [`solve_dare_cold`]).
/// Stops when `‖P_{k+1} − P_k‖_F ≤ options.tolerance · ‖P_{k+1}‖_F`; then returns
/// `P = P_{k+1}`, the gain for that `P` and its residual (one extra Riccati step).
///
/// # Errors
/// [`DareError`] for bad shapes, non-finite or non-symmetric input, `Q` not PSD, `R` not PD,
/// breakdown, divergence or when `options.max_iterations` is reached.
pub fn solve_dare<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    p0: &OMatrix<f64, N, N>,
    options: &DareOptions,
) -> Result<DareSolution<N, M>, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    validate(a, b, q, r, Some(p0))?;
    let mut work = RiccatiWork::new(a, b);
    let mut p = p0.clone();
    let mut relative_change = f64::INFINITY;
    for it in 1..=options.max_iterations {
        if !work.step(a, b, q, r, &p) {
            return Err(DareError::Breakdown { iteration: it });
        }
        let change = frobenius_diff(&work.next, &p);
        let norm = work.next.norm();
        core::mem::swap(&mut p, &mut work.next);
        if !(change.is_finite() && norm.is_finite()) {
            return Err(DareError::Diverged { iteration: it });
        }
        relative_change = if norm > 0.0 { change / norm } else { change };
        if change <= options.tolerance * norm {
            return finish(a, b, q, r, p, it, &mut work);
        }
    }
    Err(DareError::NotConverged {
        iterations: options.max_iterations,
        relative_change,
    })
}

/// [`solve_dare`] from the cold start `P₀ = Q`.
///
/// # Errors
/// As [`solve_dare`].
pub fn solve_dare_cold<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    options: &DareOptions,
) -> Result<DareSolution<N, M>, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    solve_dare(a, b, q, r, q, options)
}

/// Solves the DARE by the structure-preserving doubling algorithm (SDA).
///
/// With `G₀ = BR⁻¹Bᵀ`, `H₀ = Q`, `E₀ = A` and `W = I + GₖHₖ`:
///
/// ```text
/// Eₖ₊₁ = Eₖ W⁻¹ Eₖ,   Gₖ₊₁ = Gₖ + Eₖ W⁻¹ Gₖ Eₖᵀ,   Hₖ₊₁ = Hₖ + Eₖᵀ Hₖ W⁻¹ Eₖ,
/// ```
///
/// and `Hₖ → P` quadratically (`Hₖ` is the `2ᵏ`-step Riccati iterate from zero).
/// Stops when `‖Hₖ₊₁ − Hₖ‖_F ≤ options.tolerance · ‖Hₖ₊₁‖_F`, or — tested once that
/// relative increment is below `√tolerance`, which saves the last, confirming doubling —
/// when the relative DARE residual of `Hₖ₊₁` is `≤ options.tolerance`. Fails after
/// `options.max_iterations` doubling steps (capped at 64). The gain and residual come
/// from one final Riccati step, as in [`solve_dare`].
///
/// The linear systems with `W` are solved by partially pivoted LU, in transposed form so
/// that the substitutions run along contiguous rows.
///
/// # Errors
/// As [`solve_dare`].
pub fn solve_dare_sda<N: Dim, M: Dim>(
    a: &OMatrix<f64, N, N>,
    b: &OMatrix<f64, N, M>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
    options: &DareOptions,
) -> Result<DareSolution<N, M>, DareError>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    validate(a, b, q, r, None)?;
    let n = a.shape_generic().0;
    let (nn, mm) = b.shape();
    let mut work = RiccatiWork::new(a, b);

    // G = B R⁻¹ Bᵀ via the Cholesky factor of R (work.s) and R⁻¹Bᵀ (work.k).
    work.s.copy_from(r);
    if !cholesky_in_place(work.s.as_mut_slice(), mm) {
        return Err(DareError::RNotPositiveDefinite {
            min_eigenvalue: min_eigenvalue(r),
        });
    }
    work.k.copy_from(&work.bt);
    cholesky_solve_in_place(work.s.as_slice(), mm, work.k.as_mut_slice());
    let mut g = OMatrix::<f64, N, N>::zeros_generic(n, n);
    b.mul_to(&work.k, &mut g);
    symmetrize(&mut g);

    let mut e = a.clone();
    let mut h = q.clone();
    let mut w = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut y1 = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut y2 = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut t = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut et = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut tmp = OMatrix::<f64, N, N>::zeros_generic(n, n);
    let mut piv_small = [0usize; 32];
    let mut piv_large = Vec::new();
    let piv: &mut [usize] = if nn <= piv_small.len() {
        &mut piv_small[..nn]
    } else {
        piv_large.resize(nn, 0);
        &mut piv_large[..]
    };

    let cap = options.max_iterations.min(64);
    let mut relative_change = f64::INFINITY;
    for it in 1..=cap {
        // W = I + G H, factorised.
        w.fill_with_identity();
        w.gemm(1.0, &g, &h, 1.0);
        if !lu_in_place(w.as_mut_slice(), nn, piv) {
            return Err(DareError::Breakdown { iteration: it });
        }
        // Y1 = W⁻¹E and Y2 = W⁻¹G, solved in transposed form (rows contiguous).
        e.transpose_to(&mut et);
        t.copy_from(&et);
        lu_solve_transposed_in_place(w.as_slice(), nn, piv, t.as_mut_slice());
        t.transpose_to(&mut y1);
        tmp.copy_from(&g); // Gᵀ = G
        lu_solve_transposed_in_place(w.as_slice(), nn, piv, tmp.as_mut_slice());
        tmp.transpose_to(&mut y2);

        // H ← H + Eᵀ (H W⁻¹E)
        h.mul_to(&y1, &mut t);
        et.mul_to(&t, &mut tmp);
        let change = tmp.norm();
        h += &tmp;
        symmetrize(&mut h);
        // G ← G + E (W⁻¹G) Eᵀ
        e.mul_to(&y2, &mut t);
        g.gemm(1.0, &t, &et, 1.0);
        symmetrize(&mut g);
        // E ← E W⁻¹E
        e.mul_to(&y1, &mut t);
        core::mem::swap(&mut e, &mut t);

        let norm = h.norm();
        if !(change.is_finite() && norm.is_finite()) {
            return Err(DareError::Diverged { iteration: it });
        }
        relative_change = if norm > 0.0 { change / norm } else { change };
        if change <= options.tolerance * norm {
            return finish(a, b, q, r, h, it, &mut work);
        }
        // Quadratic convergence: once the increment is below √tol the next one is about
        // tol, so test the residual (one Riccati step) before paying for another doubling.
        if relative_change <= options.tolerance.sqrt() {
            let residual = residual_of(a, b, q, r, &h, it + 1, &mut work)?;
            if residual <= options.tolerance {
                return Ok(DareSolution {
                    p: h,
                    k: work.k.clone(),
                    iterations: it,
                    residual,
                });
            }
        }
    }
    Err(DareError::NotConverged {
        iterations: cap,
        relative_change,
    })
}
