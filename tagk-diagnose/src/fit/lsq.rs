//! The weighted least-squares solve (Householder QR, SVD of `R`), predictions, per-channel
//! statistics and the 1-D scan of a nonlinear parameter.

use nalgebra::{DMatrix, DVector};

use crate::error::DiagnoseError;
use crate::fit::ChannelFit;
use crate::fit::columns::{Blocks, Column, for_each_block};
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS, Signals};
use crate::stats;

/// Result of the QR least-squares solve.
pub(crate) struct LsSolution {
    pub beta: Vec<f64>,
    pub se: Vec<Option<f64>>,
    /// The coefficients' covariance, row-major `p × p` (`NaN` in the rows and columns of
    /// unidentifiable coefficients, whose `se` is `None`).
    pub cov: Vec<f64>,
}

/// Weighted least squares `min Σ_c w_c² ‖b_c − X_c β‖²` with a Householder QR of
/// `[A | b]` (nalgebra; columns equilibrated; factored by blocks of rows, [`stacked_qr_r`]), then an SVD of the small `R` (truncated at a
/// relative 1e-11 so collinear columns get a minimum-norm solution and no standard error).
/// `kappa` inflates the covariance for autocorrelated residuals. The rigid-body columns
/// ([`Column::Rigid`]) are computed block by block from `s`.
pub(crate) fn weighted_qr_solve(
    s: &Signals,
    cols: &[Column<'_>],
    b: &[[f64; 6]],
    w: &[f64; 6],
    kappa: f64,
) -> Result<LsSolution, DiagnoseError> {
    let n = b.len();
    let p = cols.len();
    let rows = 6 * n;
    // Σ x² per column and channel, in sample order across the blocks.
    let mut squares: Vec<[Option<f64>; 6]> = vec![[None; 6]; p];
    let mut blocks = Blocks::new(s, None);
    blocks.need(cols);
    for_each_block(&mut blocks, 0..n, |blk, _, _| {
        for (j, col) in cols.iter().enumerate() {
            for c in 0..6 {
                if let Some((v, _)) = blk.get(col, c) {
                    let terms = v.iter().map(|x| x * x);
                    squares[j][c] = Some(match squares[j][c] {
                        None => terms.sum::<f64>(),
                        Some(acc) => terms.fold(acc, |a, t| a + t),
                    });
                }
            }
        }
    });
    let mut scale = vec![0.0; p];
    for (j, col) in cols.iter().enumerate() {
        let mut s2 = 0.0;
        for c in 0..6 {
            if col.has(c) {
                let sq = squares[j][c].unwrap_or_else(|| std::iter::empty::<f64>().sum());
                s2 += w[c] * w[c] * sq;
            }
        }
        scale[j] = if s2 > 0.0 { 1.0 / s2.sqrt() } else { 0.0 };
    }
    let r = stacked_qr_r(s, cols, b, w, &scale);
    let mut r11 = DMatrix::<f64>::zeros(p, p);
    let mut z = DVector::<f64>::zeros(p);
    for i in 0..p {
        for j in i..p {
            r11[(i, j)] = r[(i, j)];
        }
        z[i] = r[(i, p)];
    }
    let rss = r[(p, p)] * r[(p, p)];
    if !rss.is_finite() || r11.iter().any(|x| !x.is_finite()) {
        return Err(DiagnoseError::Fit(
            "non-finite values in the QR factor".into(),
        ));
    }
    let svd = r11.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
        return Err(DiagnoseError::Fit("SVD of R failed".into()));
    };
    let smax = svd.singular_values.iter().fold(0.0f64, |m, x| m.max(*x));
    let cut = smax * 1e-11;
    let rank = svd.singular_values.iter().filter(|s| **s > cut).count();
    let utz = u.transpose() * &z;
    let mut beta_s = DVector::<f64>::zeros(p);
    let mut cov = DMatrix::<f64>::zeros(p, p);
    for k in 0..p {
        let s = svd.singular_values[k];
        if s > cut {
            let vk = vt.row(k).transpose();
            beta_s += &vk * (utz[k] / s);
            cov += &vk * vk.transpose() / (s * s);
        }
    }
    let dof = (rows as f64 - rank as f64).max(1.0);
    let sigma2 = rss / dof * kappa;
    // A coefficient is identifiable if its direction is not (numerically) in the null space.
    let mut beta = vec![0.0; p];
    let mut se = vec![None; p];
    for j in 0..p {
        beta[j] = beta_s[j] * scale[j];
        let mut null_part = 0.0;
        for k in 0..p {
            if svd.singular_values[k] <= cut {
                null_part += vt[(k, j)] * vt[(k, j)];
            }
        }
        if scale[j] > 0.0 && null_part < 1e-6 {
            se[j] = Some((cov[(j, j)] * sigma2).sqrt() * scale[j]);
        }
    }
    if beta.iter().any(|x| !x.is_finite()) {
        return Err(DiagnoseError::Fit("non-finite coefficients".into()));
    }
    let mut covariance = vec![f64::NAN; p * p];
    for j in 0..p {
        for k in 0..p {
            if se[j].is_some() && se[k].is_some() {
                covariance[j * p + k] = cov[(j, k)] * sigma2 * scale[j] * scale[k];
            }
        }
    }
    Ok(LsSolution {
        beta,
        se,
        cov: covariance,
    })
}

/// Samples per block of the blocked QR ([`stacked_qr_r`]): `6 ×` this many rows at a time.
const QR_BLOCK_SAMPLES: usize = 512;

/// The `(p+1) × (p+1)` triangular factor `R` of the weighted, equilibrated `[A | b]`
/// (rows `6 i + c`: sample `i`, channel `c`), factored block by block: each block of
/// [`QR_BLOCK_SAMPLES`] samples is stacked under the previous block's `R` and factored again
/// (`[A₁; A₂] = Q R` has the same `R`, up to the signs of its rows, as the QR of
/// `[R₁; A₂]`), so that only one block of rows is ever in memory instead of all `6 n`.
/// Rows of `R` beyond the number of rows seen are zero. The Householder QR is nalgebra's: on
/// these tall, narrow blocks (`p` ≈ 10 to 40 columns) it took 236 ns per sample with 12
/// columns in blocks of 512 samples (which stay in the L2 cache; 321 ns in blocks of 4096),
/// where faer's, whose scaled column norms dominate at this width, took 834 ns (Intel Xeon
/// with AVX-512, Linux 6.18).
fn stacked_qr_r(
    s: &Signals,
    cols: &[Column<'_>],
    b: &[[f64; 6]],
    w: &[f64; 6],
    scale: &[f64],
) -> DMatrix<f64> {
    let n = b.len();
    let p = cols.len();
    let mut r = DMatrix::<f64>::zeros(p + 1, p + 1);
    let mut r_rows = 0;
    let mut lo = 0;
    let mut blocks = Blocks::new(s, None);
    blocks.need(cols);
    while lo < n {
        let hi = (lo + QR_BLOCK_SAMPLES).min(n);
        let mut a = DMatrix::<f64>::zeros(r_rows + 6 * (hi - lo), p + 1);
        for i in 0..r_rows {
            for j in i..=p {
                a[(i, j)] = r[(i, j)];
            }
        }
        for_each_block(&mut blocks, lo..hi, |blk, blo, bhi| {
            for (j, col) in cols.iter().enumerate() {
                let mut column = a.column_mut(j);
                for c in 0..6 {
                    if let Some((v, _)) = blk.get(col, c) {
                        let f = w[c] * scale[j];
                        for (i, x) in (blo..bhi).zip(v) {
                            column[r_rows + 6 * (i - lo) + c] = x * f;
                        }
                    }
                }
            }
        });
        let mut column = a.column_mut(p);
        for i in lo..hi {
            for c in 0..6 {
                column[r_rows + 6 * (i - lo) + c] = b[i][c] * w[c];
            }
        }
        let thin = a.qr().r();
        r_rows = thin.nrows();
        for i in 0..r_rows {
            for j in 0..=p {
                r[(i, j)] = if j >= i { thin[(i, j)] } else { 0.0 };
            }
        }
        lo = hi;
    }
    r
}

/// Prediction `X β` per sample (the rigid-body columns computed block by block from `s`).
pub(crate) fn predict(s: &Signals, cols: &[Column<'_>], beta: &[f64]) -> Vec<[f64; 6]> {
    let n = s.len();
    let mut out = vec![[0.0; 6]; n];
    let mut blocks = Blocks::new(s, None);
    blocks.need(cols);
    for_each_block(&mut blocks, 0..n, |blk, lo, hi| {
        for (col, &bj) in cols.iter().zip(beta) {
            if bj == 0.0 {
                continue;
            }
            for c in 0..6 {
                if let Some((v, _)) = blk.get(col, c) {
                    for (o, x) in out[lo..hi].iter_mut().zip(v) {
                        o[c] += x * bj;
                    }
                }
            }
        }
    });
    out
}

/// Per-channel fit %, RMS and RMS relative to the channel group's scale
/// ([`ChannelFit::error_percent`]).
pub(crate) fn channel_stats(b: &[[f64; 6]], res: &[[f64; 6]]) -> Vec<ChannelFit> {
    let n = b.len() as f64;
    // RMS magnitude of the measured force (the thrust) and of the measured torque.
    let group_scale = |range: std::ops::Range<usize>| {
        (b.iter()
            .map(|x| x[range.clone()].iter().map(|v| v * v).sum::<f64>())
            .sum::<f64>()
            / n)
            .sqrt()
    };
    let scales = [group_scale(0..3), group_scale(3..6)];
    (0..6)
        .map(|c| {
            let mean = b.iter().map(|x| x[c]).sum::<f64>() / n;
            let dev = b.iter().map(|x| (x[c] - mean).powi(2)).sum::<f64>().sqrt();
            let rn = res.iter().map(|x| x[c] * x[c]).sum::<f64>().sqrt();
            let scale = b.iter().map(|x| x[c].abs()).fold(0.0f64, f64::max);
            let fit_percent = if dev > 1e-12 * scale.max(f64::MIN_POSITIVE) && dev > 0.0 {
                Some(100.0 * (1.0 - rn / dev))
            } else {
                None
            };
            let rms = rn / n.sqrt();
            let group = scales[c / 3];
            ChannelFit {
                name: CHANNEL_NAMES[c].into(),
                unit: CHANNEL_UNITS[c].into(),
                fit_percent,
                error_percent: (group > 0.0 && group.is_finite()).then(|| 100.0 * rms / group),
                rms,
            }
        })
        .collect()
}

/// Mean long-run variance factor κ (batch means) of the weighted residual over the channels.
pub(crate) fn residual_kappa(res: &[[f64; 6]], w: &[f64; 6]) -> f64 {
    let mut k = 0.0;
    for c in 0..6 {
        let r: Vec<f64> = res.iter().map(|x| x[c] * w[c]).collect();
        k += stats::batch_means_factor(&r);
    }
    k / 6.0
}

/// 1-D minimisation of `f` over a scan grid: every grid value first, then a golden-section
/// search (12 steps) between the best value's neighbours in the sorted grid.
pub(crate) fn scan_min(grid: &[f64], mut f: impl FnMut(f64) -> f64) -> (f64, f64) {
    let mut g: Vec<f64> = grid.iter().copied().filter(|x| x.is_finite()).collect();
    g.sort_by(|a, b| a.total_cmp(b));
    g.dedup();
    if g.is_empty() {
        return (0.0, f(0.0));
    }
    let vals: Vec<f64> = g.iter().map(|&x| f(x)).collect();
    let (mut bi, mut bv) = (0, f64::INFINITY);
    for (i, &v) in vals.iter().enumerate() {
        if v < bv {
            bi = i;
            bv = v;
        }
    }
    let mut best = (g[bi], bv);
    if g.len() < 3 {
        return best;
    }
    let (mut a, mut b) = (g[bi.saturating_sub(1)], g[(bi + 1).min(g.len() - 1)]);
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = b - r * (b - a);
    let mut x2 = a + r * (b - a);
    let mut f1 = f(x1);
    let mut f2 = f(x2);
    for _ in 0..8 {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - r * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + r * (b - a);
            f2 = f(x2);
        }
    }
    for (x, v) in [(x1, f1), (x2, f2)] {
        if v < best.1 {
            best = (x, v);
        }
    }
    best
}
