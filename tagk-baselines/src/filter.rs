//! The state and the block update shared by RLS and the Kalman filter, over one buffer of
//! caller-provided (or owned) storage.
//!
//! The inputs are the prior covariance `P̃ = P + q·I`, a window `A` (`m × n`, row-major), the
//! residual `r = b − A θ` and a diagonal term `d`.
//! For the Kalman filter `q = σ_Q²` and `d = σ_R²`; for RLS `q = 0` and `d = λ`.
//! From them the portable kernel computes
//!
//! 1. `W = A P̃` (`m × n`, one dot product per entry: rows of the symmetric `P`);
//! 2. `S = W Aᵀ + d·I` (lower triangle) and `S = L Lᵀ` ([`cholesky_in_place`]);
//! 3. `y = L⁻¹ r` and `Z = Wᵀ L⁻ᵀ` (`n × m`: row `i` is `L⁻¹` times column `i` of `W`);
//! 4. `θ ← θ + Z y` (`= θ + K r`, `K = P̃ Aᵀ S⁻¹`) and `P ← s·(P̃ − Z Zᵀ)` on the upper
//!    triangle, mirrored (`s = 1/λ` for RLS, `1` for the Kalman filter).
//!
//! No gain and no inverse is formed: `1.5 m n² + m² n + m³/6` multiply-adds. The new `θ` and
//! `P` are checked before anything is written (a bound on every new entry of `P`), so a
//! refused window leaves the state exactly as it was. The `faer` backend (host, `f64`) runs
//! the same algorithm with faer's products; see `faer_kernel.rs`.
//!
//! **Extreme dynamic range.** A window can pin a direction far below the rounding level of the
//! prior (`p₀ ‖a‖² / d ≳ 10¹²`). The first window of "KF-low" does: `P₀ = 10³`,
//! `σ_R² = 10⁻¹⁰`. Then either the Cholesky factorisation of the numerically singular `S`
//! fails, or step 4's subtraction leaves a diagonal entry with no correct digit
//! (`P⁺_kk ≤ 10⁴ ε₆₄ · P̃_kk`, `ε₆₄ = 2.2·10⁻¹⁶`).
//! The check costs `n` comparisons of values the update computes anyway. That window is then redone in information form,
//! `P⁺ = (P̃⁻¹ + Aᵀ A / d)⁻¹`, `Δθ = P⁺ Aᵀ r / d`, with Cholesky factorisations of `n × n`
//! matrices (about `n³ + m n²`, on such windows only). The threshold is the same number in
//! `f32`, where it catches only a complete cancellation (a diagonal entry that is zero or
//! negative): `f32` filters then try the fallback before they fail, and otherwise run the
//! block update.
//!
//! **Layouts.** The full buffer ([`covariance_buffer_len`]) holds a second `n × n` copy of
//! `P`: the faer backend's posterior, and the fallback's `P⁺`, factorised and inverted in
//! place (LAPACK's `potrf`/`trtri`/`lauum` order), committed by switching copies. The compact
//! buffer ([`compact_covariance_buffer_len`], portable kernel only) has none: the kernel
//! decides on the fallback before it writes `P`, so it refuses those windows with a typed
//! `NumericalFailure` and the state is kept.

use core::fmt;

use tagk_core::linalg::{axpy, cholesky_in_place, dot, reciprocal_diagonal, solve_lower_in_place};
use tagk_core::{ConfigError, EstimatorError, Real, Storage, UpdateInfo, validate_window};

use crate::Backend;

/// Length of the buffer an [`Rls`](crate::Rls) or [`KalmanFilter`](crate::KalmanFilter) of
/// dimension `n` and window capacity `m_max` needs with every feature.
///
/// It is `2n² + 4n + 2·m_max·n + m_max² + 3·m_max` scalars.
/// The estimate is kept twice, so that an update commits by switching copies.
/// The covariance has an `n × n` second copy: the faer backend computes its posterior there,
/// and the information-form fallback its `P⁺`.
/// The rest is the block update's workspace.
/// The `Vec` constructors allocate this much.
///
/// A `const fn`, so firmware can size a static array: `[0.0; covariance_buffer_len(120, 30)]`.
/// [`compact_covariance_buffer_len`] is about `n²` scalars less, without the fallback.
/// Saturates at `usize::MAX` where the length overflows (no buffer is that long, so such sizes
/// are refused); [`checked_covariance_buffer_len`] says so with `None`.
pub const fn covariance_buffer_len(n: usize, m_max: usize) -> usize {
    match checked_covariance_buffer_len(n, m_max) {
        Some(len) => len,
        None => usize::MAX,
    }
}

/// [`covariance_buffer_len`] in checked arithmetic: `None` when the length overflows a
/// `usize` (the constructors then return [`ConfigError::TooLarge`]).
pub const fn checked_covariance_buffer_len(n: usize, m_max: usize) -> Option<usize> {
    checked_buffer_len(n, m_max, true)
}

/// Length of the smallest buffer an [`Rls`](crate::Rls) or
/// [`KalmanFilter`](crate::KalmanFilter) on the portable kernel ([`Backend::Loops`]) accepts:
/// `n² + 3n + 2·m_max·n + m_max² + 3·m_max` scalars (one covariance, updated in place).
///
/// A filter built in a buffer shorter than [`covariance_buffer_len`] has **no
/// information-form fallback**. The fallback would redo a window whose Cholesky factorisation
/// of `S` fails, or whose covariance update cancels to fewer than ~4 digits on the diagonal
/// (see the crate docs). Here such a window is refused with
/// [`EstimatorError::NumericalFailure`] and leaves the filter as it was. Every other window
/// gives the same bits as with the full buffer. This suits memory-bound targets, such as the
/// Cortex-M7 firmware of `tagk-mcu`. [`Backend::Faer`] needs the full buffer.
/// It saturates at `usize::MAX` where the length overflows;
/// [`checked_compact_covariance_buffer_len`] says so with `None`.
pub const fn compact_covariance_buffer_len(n: usize, m_max: usize) -> usize {
    match checked_compact_covariance_buffer_len(n, m_max) {
        Some(len) => len,
        None => usize::MAX,
    }
}

/// [`compact_covariance_buffer_len`] in checked arithmetic: `None` when the length overflows
/// a `usize` (the constructors then return [`ConfigError::TooLarge`]).
pub const fn checked_compact_covariance_buffer_len(n: usize, m_max: usize) -> Option<usize> {
    checked_buffer_len(n, m_max, false)
}

/// [`covariance_buffer_len`] (with the fallback) or [`compact_covariance_buffer_len`]
/// (without) in checked arithmetic: `(1 + f)n² + (3 + f)n + 2mn + m² + 3m`, `f = fallback`.
pub(crate) const fn checked_buffer_len(n: usize, m: usize, fallback: bool) -> Option<usize> {
    /// `?` for `Option` in a `const fn`.
    macro_rules! ok {
        ($e:expr) => {
            match $e {
                Some(v) => v,
                None => return None,
            }
        };
    }
    let extra = fallback as usize;
    let nn = ok!(ok!(n.checked_mul(n)).checked_mul(1 + extra));
    let mn = ok!(ok!(m.checked_mul(n)).checked_mul(2));
    let mm = ok!(m.checked_mul(m));
    let sum = ok!(ok!(nn.checked_add(mn)).checked_add(mm));
    let sum = ok!(sum.checked_add(ok!(n.checked_mul(3 + extra))));
    sum.checked_add(ok!(m.checked_mul(3)))
}

/// The fallback threshold (see the module docs): `P⁺_kk ≤ CANCELLATION · P̃_kk` means fewer
/// than ~4 significant digits of `P⁺_kk` survived in `f64`.
pub(crate) const CANCELLATION: f64 = 1e4 * f64::EPSILON;

pub(crate) const CHOLESKY_FAILED: &str =
    "the innovation covariance A P Aᵀ + D is not numerically positive definite";
const COVARIANCE_INDEFINITE: &str =
    "the updated covariance has a non-positive diagonal entry (lost positive definiteness)";
const CANCELLED_WITHOUT_FALLBACK: &str = "the covariance update cancels (a diagonal entry keeps \
     fewer than ~4 digits) and this filter's compact buffer has no information-form fallback";

/// The constants that turn the shared block update into RLS or the Kalman filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Model<T> {
    /// Added to `P`'s diagonal before the update (`σ_Q²`; 0 for RLS).
    pub(crate) q: T,
    /// Added to `S`'s diagonal (`λ` for RLS, `σ_R²` for the Kalman filter).
    pub(crate) d: T,
    /// Multiplies the updated covariance (`1/λ` for RLS, 1 for the Kalman filter).
    pub(crate) scale: T,
    /// `P₀ = p₀·I`.
    pub(crate) p0: T,
    /// The RLS wind-up guard's bound on `trace(P)`, if any.
    pub(crate) max_trace: Option<T>,
}

/// Estimate, covariance and workspace of one filter in one buffer `buf`.
#[derive(Clone)]
pub(crate) struct BlockFilter<T: Real, S: Storage<T>> {
    pub(crate) n: usize,
    pub(crate) m_max: usize,
    pub(crate) backend: Backend,
    pub(crate) model: Model<T>,
    /// Whether the buffer holds the second `P` and the fallback's `Aᵀ r` (the full layout,
    /// [`covariance_buffer_len`]) or not ([`compact_covariance_buffer_len`]).
    pub(crate) fallback: bool,
    /// Which of the two copies of `θ` (0 or 1) is current.
    theta_slot: usize,
    /// Which of the two copies of `P` (0 or 1) is current.
    p_slot: usize,
    buf: S,
}

/// Disjoint views of a [`BlockFilter`]'s buffer.
pub(crate) struct Parts<'a, T> {
    /// Current `θ` (`n`).
    pub(crate) theta: &'a mut [T],
    /// The other copy of `θ`: the candidate.
    pub(crate) theta_next: &'a mut [T],
    /// Current `P` (`n × n`, row-major, symmetric).
    pub(crate) p: &'a mut [T],
    /// The other copy of `P`: the faer backend's posterior, the fallback's `P⁺` and its
    /// scratch (empty in the compact layout).
    pub(crate) p_next: &'a mut [T],
    /// `Aᵀ r` of the fallback (`n`; empty in the compact layout).
    pub(crate) atr: &'a mut [T],
    /// `Δθ` (`n`); the portable kernel keeps `‖z_i‖²` here.
    pub(crate) dtheta: &'a mut [T],
    /// `m_max (2n + 1)` scalars: `W` then `Z` (portable), `[U | r]` (faer).
    pub(crate) work: &'a mut [T],
    /// `S`, then `L` (`m × m`, stride `m`).
    pub(crate) s: &'a mut [T],
    /// `r`, then `L⁻¹ r` (`m`).
    pub(crate) y: &'a mut [T],
    /// `1 / l_jj` (`m`).
    pub(crate) inv_diag: &'a mut [T],
}

impl<T: Real, S: Storage<T>> BlockFilter<T, S> {
    /// `θ = 0`, `P = p₀·I` in `buf`: the full layout if it holds [`covariance_buffer_len`]
    /// scalars, else the compact one (portable kernel only, no fallback) if it holds
    /// [`compact_covariance_buffer_len`].
    pub(crate) fn new(
        n: usize,
        m_max: usize,
        backend: Backend,
        model: Model<T>,
        buf: S,
    ) -> Result<Self, ConfigError> {
        tagk_core::check_dimensions(n, m_max)?;
        let found = buf.as_ref().len();
        // Sizes whose least layout overflows can never be satisfied.
        let compact =
            checked_buffer_len(n, m_max, false).ok_or(ConfigError::TooLarge { n, m: m_max })?;
        let full = checked_buffer_len(n, m_max, true).unwrap_or(usize::MAX);
        let fallback = found >= full;
        if !fallback {
            // The compact layout serves the portable kernel only; report the least that works.
            let needed = if backend == Backend::Loops {
                compact
            } else {
                full
            };
            if found < needed {
                return Err(ConfigError::BufferTooSmall { needed, found });
            }
        }
        let mut filter = Self {
            n,
            m_max,
            backend,
            model,
            fallback,
            theta_slot: 0,
            p_slot: 0,
            buf,
        };
        filter.buf.as_mut().fill(T::zero());
        #[cfg(feature = "faer")]
        if backend == Backend::Faer {
            let (n, m) = (filter.n, filter.m_max);
            crate::faer_kernel::warm_up(n, m, filter.parts().cast_f64());
            filter.buf.as_mut().fill(T::zero());
        }
        filter.reset_covariance();
        Ok(filter)
    }

    pub(crate) fn parts(&mut self) -> Parts<'_, T> {
        let (n, m) = (self.n, self.m_max);
        // The compact layout's slices first, in both layouts (same offsets and lengths, so
        // the kernel compiles the same), then the full layout's second `P` and `Aᵀ r`.
        let rest = self.buf.as_mut();
        let (thetas, rest) = rest.split_at_mut(2 * n);
        let (p0, rest) = rest.split_at_mut(n * n);
        let (dtheta, rest) = rest.split_at_mut(n);
        let (work, rest) = rest.split_at_mut(m * (2 * n + 1));
        let (s, rest) = rest.split_at_mut(m * m);
        let (y, rest) = rest.split_at_mut(m);
        let (inv_diag, rest) = rest.split_at_mut(m);
        let (p1, rest) = rest.split_at_mut(if self.fallback { n * n } else { 0 });
        let atr = &mut rest[..if self.fallback { n } else { 0 }];
        let (t0, t1) = thetas.split_at_mut(n);
        let (theta, theta_next) = if self.theta_slot == 0 {
            (t0, t1)
        } else {
            (t1, t0)
        };
        let (p, p_next) = if self.p_slot == 0 { (p0, p1) } else { (p1, p0) };
        Parts {
            theta,
            theta_next,
            p,
            p_next,
            atr,
            dtheta,
            work,
            s,
            y,
            inv_diag,
        }
    }

    pub(crate) fn estimate(&self) -> &[T] {
        let n = self.n;
        &self.buf.as_ref()[self.theta_slot * n..(self.theta_slot + 1) * n]
    }

    /// The covariance `P`, row-major `n × n`.
    pub(crate) fn covariance(&self) -> &[T] {
        let (n, m) = (self.n, self.m_max);
        // See `parts`: the second copy follows the compact layout.
        let start = if self.p_slot == 0 {
            2 * n
        } else {
            compact_covariance_buffer_len(n, m)
        };
        &self.buf.as_ref()[start..start + n * n]
    }

    pub(crate) fn into_storage(self) -> S {
        self.buf
    }

    fn reset_covariance(&mut self) {
        let n = self.n;
        let p0 = self.model.p0;
        let p = self.parts().p;
        p.fill(T::zero());
        for k in 0..n {
            p[k * n + k] = p0;
        }
    }

    /// `θ = estimate`, `P = p₀·I`.
    pub(crate) fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
        tagk_core::validate_estimate(self.n, estimate)?;
        self.parts().theta.copy_from_slice(estimate);
        self.reset_covariance();
        Ok(())
    }

    /// Makes the candidate `θ` current, and the other copy of `P` too if `new_p`.
    fn switch(&mut self, new_p: bool) {
        self.theta_slot ^= 1;
        if new_p {
            self.p_slot ^= 1;
        }
    }

    /// One window: validation, then the backend's block update (or the fallback).
    pub(crate) fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
        let n = self.n;
        let m = validate_window(n, self.m_max, a, b)?;
        #[cfg(feature = "faer")]
        if self.backend == Backend::Faer {
            let model = Model {
                q: self.model.q.as_f64(),
                d: self.model.d.as_f64(),
                scale: self.model.scale.as_f64(),
                p0: self.model.p0.as_f64(),
                max_trace: self.model.max_trace.map(Real::as_f64),
            };
            let (a, b) = (cast_slice(a), cast_slice(b));
            let norm = crate::faer_kernel::update(n, m, &model, a, b, self.parts().cast_f64())?;
            self.switch(true);
            return Ok(info(m, norm));
        }
        let model = self.model;
        let (norm, outcome) = update_portable(n, m, &model, a, b, self.parts())?;
        if let Some(redo) = outcome {
            redo_in_information_form(n, m, &model, a, redo, self.parts())?;
        }
        self.switch(outcome.is_some());
        Ok(info(m, norm))
    }
}

impl<T: Real, S: Storage<T>> fmt::Debug for BlockFilter<T, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BlockFilter")
            .field("n", &self.n)
            .field("m_max", &self.m_max)
            .field("backend", &self.backend)
            .field("fallback", &self.fallback)
            .field("estimate", &self.estimate())
            .finish_non_exhaustive()
    }
}

fn info(rows: usize, prior_residual_norm: f64) -> UpdateInfo {
    UpdateInfo {
        rows,
        iterations: 1,
        prior_residual_norm,
        converged: false,
    }
}

/// `f64` views of the buffers, for the faer backend (only ever built with `T = f64`).
#[cfg(feature = "faer")]
impl<'a, T: Real> Parts<'a, T> {
    fn cast_f64(self) -> Parts<'a, f64> {
        Parts {
            theta: cast_slice_mut(self.theta),
            theta_next: cast_slice_mut(self.theta_next),
            p: cast_slice_mut(self.p),
            p_next: cast_slice_mut(self.p_next),
            atr: cast_slice_mut(self.atr),
            dtheta: cast_slice_mut(self.dtheta),
            work: cast_slice_mut(self.work),
            s: cast_slice_mut(self.s),
            y: cast_slice_mut(self.y),
            inv_diag: cast_slice_mut(self.inv_diag),
        }
    }
}

/// `x` as `&[f64]`. Panics unless `T` is `f64` (the faer backend is only selected for `f64`).
#[cfg(feature = "faer")]
fn cast_slice<T: Real>(x: &[T]) -> &[f64] {
    assert_eq!(core::any::TypeId::of::<T>(), core::any::TypeId::of::<f64>());
    // SAFETY: `T` is `f64` (checked above): same layout, same length, same lifetime.
    unsafe { core::slice::from_raw_parts(x.as_ptr().cast::<f64>(), x.len()) }
}

/// `x` as `&mut [f64]`; see [`cast_slice`].
#[cfg(feature = "faer")]
fn cast_slice_mut<T: Real>(x: &mut [T]) -> &mut [f64] {
    assert_eq!(core::any::TypeId::of::<T>(), core::any::TypeId::of::<f64>());
    // SAFETY: `T` is `f64` (checked above): same layout, same length, same lifetime.
    unsafe { core::slice::from_raw_parts_mut(x.as_mut_ptr().cast::<f64>(), x.len()) }
}

/// Stores `r = b − A θ` in `r[i·stride]` and returns `‖r‖₂` over the non-zero rows of `A`.
///
/// Errors: every row zero ([`EstimatorError::NoUsableRow`]); a residual that overflows
/// ([`EstimatorError::Diverged`]).
pub(crate) fn residual<T: Real>(
    n: usize,
    a: &[T],
    b: &[T],
    theta: &[T],
    r: &mut [T],
    stride: usize,
) -> Result<f64, EstimatorError> {
    let mut usable = false;
    let mut norm2 = T::zero();
    for (i, (row, &bi)) in a.chunks_exact(n).zip(b).enumerate() {
        let ri = bi - dot(row, theta);
        r[i * stride] = ri;
        if row.iter().any(|&v| v != T::zero()) {
            usable = true;
            norm2 += ri * ri;
        }
    }
    if !usable {
        return Err(EstimatorError::NoUsableRow);
    }
    if !norm2.is_finite() {
        return Err(EstimatorError::Diverged);
    }
    Ok(norm2.sqrt().as_f64())
}

/// Why the portable kernel hands a window to the information-form fallback.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Redo {
    /// The Cholesky factorisation of `S` failed; `y` still holds `r`.
    CholeskyFailed,
    /// The covariance update would cancel; the candidate `θ` is in `theta_next`.
    Cancelled,
}

/// The portable block update (module docs). Returns the prior residual norm and `None` when
/// `P` was updated in place, or the reason the window must be redone in information form
/// (`P` untouched). The candidate `θ` is in `theta_next` unless the Cholesky factorisation
/// failed.
fn update_portable<T: Real>(
    n: usize,
    m: usize,
    model: &Model<T>,
    a: &[T],
    b: &[T],
    parts: Parts<'_, T>,
) -> Result<(f64, Option<Redo>), EstimatorError> {
    let Parts {
        theta,
        theta_next: candidate,
        p,
        dtheta: zz,
        work,
        s,
        y,
        inv_diag,
        ..
    } = parts;
    let Model { q, d, scale, .. } = *model;
    let norm = residual(n, a, b, theta, y, 1)?;
    let (w, z) = work.split_at_mut(m * n);
    let z = &mut z[..n * m];
    let s = &mut s[..m * m];

    // W = A P̃ with P̃ = P + qI: row j of W is P̃ a_j (P is symmetric).
    for (aj, wj) in a.chunks_exact(n).zip(w.chunks_exact_mut(n)) {
        for (wji, pi) in wj.iter_mut().zip(p.chunks_exact(n)) {
            *wji = dot(pi, aj);
        }
        if q != T::zero() {
            axpy(q, aj, wj);
        }
    }
    // S = W Aᵀ + d I (lower triangle, stride m), then S = L Lᵀ in place.
    for j in 0..m {
        let wj = &w[j * n..(j + 1) * n];
        for k in 0..=j {
            s[j * m + k] = dot(wj, &a[k * n..(k + 1) * n]);
        }
        s[j * m + j] += d;
    }
    if cholesky_in_place(s, m).is_err() {
        return Ok((norm, Some(Redo::CholeskyFailed)));
    }
    reciprocal_diagonal(s, m, inv_diag);
    solve_lower_in_place(s, m, inv_diag, &mut y[..m]);
    // Z = Wᵀ L⁻ᵀ, row-major n × m: row i is L⁻¹ (column i of W).
    for (i, zi) in z.chunks_exact_mut(m).enumerate() {
        for (j, zij) in zi.iter_mut().enumerate() {
            *zij = w[j * n + i];
        }
        solve_lower_in_place(s, m, inv_diag, zi);
    }
    // Candidate θ + Z y, ‖z_i‖², and the cancellation check on the new diagonal.
    let threshold = T::cast(CANCELLATION);
    let mut zmax = T::zero();
    let mut cancelled = false;
    for i in 0..n {
        let zi = &z[i * m..(i + 1) * m];
        candidate[i] = theta[i] + dot(zi, &y[..m]);
        let zzi = dot(zi, zi);
        zz[i] = zzi;
        zmax = zmax.max(zzi);
        let prior = p[i * n + i] + q;
        let posterior = prior - zzi;
        cancelled |= posterior.is_nan() || posterior <= threshold * prior;
    }
    if cancelled {
        return Ok((norm, Some(Redo::Cancelled)));
    }
    finite_candidate(candidate)?;
    // |(Z Zᵀ)_il| ≤ max_i ‖z_i‖², so (|P| + q + max ‖z_i‖²)·scale bounds every new entry.
    let mut pmax = T::zero();
    for i in 0..n {
        for v in &p[i * n + i..(i + 1) * n] {
            pmax = pmax.max(v.abs());
        }
    }
    let two = T::one() + T::one();
    if !((pmax + q + zmax) * scale * two).is_finite() {
        return Err(EstimatorError::Diverged);
    }
    // Commit: P ← (P̃ − Z Zᵀ)·scale on the upper triangle, mirrored (the diagonal is positive:
    // it passed the cancellation check).
    commit_covariance(n, m, q, scale, z, zz, p);
    if let Some(max_trace) = model.max_trace {
        windup_guard(p, n, max_trace);
    }
    Ok((norm, None))
}

/// `P ← (P + q·I − Z Zᵀ)·scale` on the upper triangle, mirrored, with `‖z_i‖²` from `zz`.
/// Out of line: a loop nest with few live values, compiled the same whatever the caller
/// keeps in registers (the Cortex-M7's instruction counts depend on it).
#[inline(never)]
fn commit_covariance<T: Real>(n: usize, m: usize, q: T, scale: T, z: &[T], zz: &[T], p: &mut [T]) {
    for i in 0..n {
        let zi = &z[i * m..(i + 1) * m];
        p[i * n + i] = (p[i * n + i] + q - zz[i]) * scale;
        for l in i + 1..n {
            let v = (p[i * n + l] - dot(zi, &z[l * m..(l + 1) * m])) * scale;
            p[i * n + l] = v;
            p[l * n + i] = v;
        }
    }
}

/// The window `update_portable` handed back, redone in information form into the other copy
/// of `P` (the caller switches copies on success), or refused with a typed
/// [`EstimatorError::NumericalFailure`] in the compact layout, which has no fallback. Kept
/// out of line so that the hot kernel does not carry the fallback's buffers.
#[cold]
#[inline(never)]
fn redo_in_information_form<T: Real>(
    n: usize,
    m: usize,
    model: &Model<T>,
    a: &[T],
    redo: Redo,
    parts: Parts<'_, T>,
) -> Result<(), EstimatorError> {
    let Parts {
        theta,
        theta_next: candidate,
        p,
        p_next,
        atr,
        dtheta: zz,
        y,
        ..
    } = parts;
    if p_next.is_empty() {
        // The compact layout: no fallback (P is still untouched).
        return Err(EstimatorError::NumericalFailure(match redo {
            Redo::CholeskyFailed => CHOLESKY_FAILED,
            Redo::Cancelled => CANCELLED_WITHOUT_FALLBACK,
        }));
    }
    let fallback = Fallback {
        p_out: &mut *p_next,
        atr,
    };
    match redo {
        // `y` still holds r: Δθ comes from the fallback too.
        Redo::CholeskyFailed => {
            fallback.run(n, m, model, a, p, y, 1, Some(&mut *zz))?;
            for ((c, &t), &dt) in candidate.iter_mut().zip(&*theta).zip(&*zz) {
                *c = t + dt;
            }
        }
        // Δθ of the block update is kept (its error is bounded by the conditioning of S, not
        // by the cancellation); only P is recomputed.
        Redo::Cancelled => fallback.run(n, m, model, a, p, y, 1, None)?,
    }
    finish_fallback(p_next, n, model)?;
    finite_candidate(candidate)
}

/// Scales, mirrors and checks the fallback's `P⁺`, then applies the wind-up guard.
fn finish_fallback<T: Real>(p: &mut [T], n: usize, model: &Model<T>) -> Result<(), EstimatorError> {
    finish_covariance(p, n, model.scale)?;
    if let Some(max_trace) = model.max_trace {
        windup_guard(p, n, max_trace);
    }
    Ok(())
}

fn finite_candidate<T: Real>(candidate: &[T]) -> Result<(), EstimatorError> {
    if candidate.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EstimatorError::Diverged)
    }
}

/// `trace` of an `n × n` row-major matrix.
pub(crate) fn trace<T: Real>(p: &[T], n: usize) -> T {
    (0..n).fold(T::zero(), |acc, k| acc + p[k * n + k])
}

/// The RLS wind-up guard: if `trace(P) > max_trace`, `P ← P · max_trace / trace(P)`.
pub(crate) fn windup_guard<T: Real>(p: &mut [T], n: usize, max_trace: T) {
    let tr = trace(p, n);
    if tr > max_trace {
        let shrink = max_trace / tr;
        for v in p[..n * n].iter_mut() {
            *v *= shrink;
        }
    }
}

/// Buffers of the information-form fallback.
pub(crate) struct Fallback<'a, T> {
    /// Receives `P⁺` (`n × n`, full); also the fallback's only `n × n` scratch.
    pub(crate) p_out: &'a mut [T],
    /// `Aᵀ r` (`n`).
    pub(crate) atr: &'a mut [T],
}

impl<T: Real> Fallback<'_, T> {
    /// The fallback of the module docs, with `P̃ = p_prev + q·I`.
    ///
    /// It writes `P⁺ = (P̃⁻¹ + Aᵀ A / d)⁻¹` into `p_out`, full, not yet scaled by `s` nor
    /// checked. If `dtheta` is given, it writes `Δθ = P⁺ Aᵀ r / d` into it
    /// (`r_i = r[i·stride]`). Plain loops: this path is rare.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn run(
        self,
        n: usize,
        m: usize,
        model: &Model<T>,
        a: &[T],
        p_prev: &[T],
        r: &[T],
        stride: usize,
        dtheta: Option<&mut [T]>,
    ) -> Result<(), EstimatorError> {
        let Self { p_out: fa, atr } = self;
        let fa = &mut fa[..n * n];
        let chol = |x: &mut [T]| {
            cholesky_in_place(x, n).map_err(|_| EstimatorError::NumericalFailure(CHOLESKY_FAILED))
        };
        // P̃ = C Cᵀ, then P̃⁻¹ = C⁻ᵀ C⁻¹ into `fa`.
        fa.copy_from_slice(&p_prev[..n * n]);
        for k in 0..n {
            fa[k * n + k] += model.q;
        }
        chol(fa)?;
        invert_lower_in_place(fa, n);
        gram_lower_inverse_in_place(fa, n);
        // Information matrix P̃⁻¹ + Aᵀ A / d (lower triangle) and Aᵀ r.
        let inv_d = T::one() / model.d;
        let atr = &mut atr[..n];
        atr.fill(T::zero());
        for (i, ai) in a.chunks_exact(n).take(m).enumerate() {
            axpy(r[i * stride], ai, atr);
            for k in 0..n {
                let c = ai[k] * inv_d;
                if c != T::zero() {
                    axpy(c, &ai[..=k], &mut fa[k * n..k * n + k + 1]);
                }
            }
        }
        // P⁺ = (C' C'ᵀ)⁻¹ (full: the Gram product writes both triangles).
        chol(fa)?;
        invert_lower_in_place(fa, n);
        gram_lower_inverse_in_place(fa, n);
        if let Some(dtheta) = dtheta {
            for k in 0..n {
                dtheta[k] = dot(&fa[k * n..(k + 1) * n], atr) * inv_d;
            }
        }
        Ok(())
    }
}

/// `x ← L⁻¹` in place for the lower-triangular `L` in the lower triangle of `x` (`n × n`,
/// row-major; the strict upper triangle is neither read nor written). Column `j` of `L⁻¹`
/// by forward substitution on `e_j`, written over column `j` of `L`, which no later column
/// reads (LAPACK's `trtri` order; the same operations as an out-of-place inverse).
fn invert_lower_in_place<T: Real>(x: &mut [T], n: usize) {
    for j in 0..n {
        x[j * n + j] = T::one() / x[j * n + j];
        for i in j + 1..n {
            // Row i of L from column j on (not yet overwritten), column j of L⁻¹ above row i.
            let mut s = T::zero();
            for k in j..i {
                s += x[i * n + k] * x[k * n + j];
            }
            x[i * n + j] = -s / x[i * n + i];
        }
    }
}

/// `x ← Xᵀ X` (full, symmetric) in place for the lower-triangular `X` in the lower triangle
/// of `x` (`n × n`, row-major): with `X = L⁻¹`, `Xᵀ X = (L Lᵀ)⁻¹`. The strict upper
/// triangle (free) takes the off-diagonal entries first, then the diagonal (entry `j` reads
/// only column `j`), then the mirror: LAPACK's `lauum`.
fn gram_lower_inverse_in_place<T: Real>(x: &mut [T], n: usize) {
    let entry = |x: &[T], j: usize, l: usize| {
        let mut s = T::zero();
        for k in l..n {
            s += x[k * n + j] * x[k * n + l];
        }
        s
    };
    for j in 0..n {
        for l in j + 1..n {
            x[j * n + l] = entry(x, j, l);
        }
    }
    for j in 0..n {
        x[j * n + j] = entry(x, j, j);
    }
    for j in 0..n {
        for l in j + 1..n {
            x[l * n + j] = x[j * n + l];
        }
    }
}

/// Scales the upper triangle of `p` by `scale`, mirrors it into the lower triangle and checks
/// the result: every entry finite ([`EstimatorError::Diverged`] otherwise) and a positive
/// diagonal ([`EstimatorError::NumericalFailure`] otherwise).
pub(crate) fn finish_covariance<T: Real>(
    p: &mut [T],
    n: usize,
    scale: T,
) -> Result<(), EstimatorError> {
    let mut finite = true;
    let mut positive = true;
    for k in 0..n {
        let dkk = p[k * n + k] * scale;
        p[k * n + k] = dkk;
        finite &= dkk.is_finite();
        positive &= dkk > T::zero();
        for l in k + 1..n {
            let v = p[k * n + l] * scale;
            p[k * n + l] = v;
            p[l * n + k] = v;
            finite &= v.is_finite();
        }
    }
    if !finite {
        return Err(EstimatorError::Diverged);
    }
    if !positive {
        return Err(EstimatorError::NumericalFailure(COVARIANCE_INDEFINITE));
    }
    Ok(())
}

/// The part of the API that [`Rls`](crate::Rls) and [`KalmanFilter`](crate::KalmanFilter)
/// share, written once: accessors of the block filter they wrap, `Debug`, and
/// [`OnlineEstimator`].
macro_rules! covariance_filter_api {
    ($filter:ident, $config:ty) => {
        impl<T: Real, S: Storage<T>> $filter<T, S> {
            /// Renames the estimator (its [`name`](OnlineEstimator::name), e.g. a preset's
            /// name).
            pub fn with_name(mut self, name: &'static str) -> Self {
                self.name = name;
                self
            }

            /// The configuration this estimator was built with.
            pub fn config(&self) -> &$config {
                &self.config
            }

            /// The covariance `P` after the last accepted update (`n × n`, row-major,
            /// symmetric; squared units of `θ`).
            pub fn covariance(&self) -> &[T] {
                self.filter.covariance()
            }

            /// `trace(P)` (for RLS, the quantity the
            /// [`WindupGuard::MaxTrace`](crate::WindupGuard::MaxTrace) bound acts on).
            pub fn covariance_trace(&self) -> T {
                crate::filter::trace(self.filter.covariance(), self.filter.n)
            }

            /// The backend in use ([`Backend::Auto`](crate::Backend::Auto) resolved).
            pub fn backend(&self) -> crate::Backend {
                self.filter.backend
            }

            /// Whether this estimator redoes extreme windows in information form: `true` when
            /// its buffer holds [`covariance_buffer_len`](crate::covariance_buffer_len)
            /// scalars (always with the `Vec` constructors), `false` in a
            /// [`compact_covariance_buffer_len`](crate::compact_covariance_buffer_len)
            /// buffer, where such windows are refused with
            /// [`EstimatorError::NumericalFailure`](tagk_core::EstimatorError::NumericalFailure).
            pub fn has_information_fallback(&self) -> bool {
                self.filter.fallback
            }

            /// The storage, handed back.
            pub fn into_storage(self) -> S {
                self.filter.into_storage()
            }
        }

        impl<T: Real, S: Storage<T>> core::fmt::Debug for $filter<T, S> {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                f.debug_struct(stringify!($filter))
                    .field("name", &self.name)
                    .field("config", &self.config)
                    .field("filter", &self.filter)
                    .finish()
            }
        }

        impl<T: Real, S: Storage<T>> OnlineEstimator<T> for $filter<T, S> {
            fn name(&self) -> &str {
                self.name
            }

            fn dim(&self) -> usize {
                self.filter.n
            }

            fn capacity(&self) -> usize {
                self.filter.m_max
            }

            fn estimate(&self) -> &[T] {
                self.filter.estimate()
            }

            fn update(&mut self, a: &[T], b: &[T]) -> Result<UpdateInfo, EstimatorError> {
                self.filter.update(a, b)
            }

            fn reset(&mut self, estimate: &[T]) -> Result<(), EstimatorError> {
                self.filter.reset(estimate)
            }
        }
    };
}
pub(crate) use covariance_filter_api;
