//! The model (rigid body plus effects), its batch least-squares fit (faer QR), and the
//! Gram-matrix engine behind the blocked cross-validation and the 1-D scans.

use std::sync::Arc;

use faer::Mat;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use tagk_dynamics::{InertialParams, write_rigid_body_regressor};

use crate::effects::{Effect, EffectRef, Plausibility};
use crate::error::DiagnoseError;
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS, Signals};
use crate::stats;

/// Names of the ten rigid-body parameters (CONVENTIONS §1 order).
pub const THETA_NAMES: [&str; 10] = [
    "m", "h_x", "h_y", "h_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz",
];
/// Units of the ten rigid-body parameters.
pub const THETA_UNITS: [&str; 10] = [
    "kg", "kg m", "kg m", "kg m", "kg m²", "kg m²", "kg m²", "kg m²", "kg m²", "kg m²",
];

/// A regressor column: one value per sample on each channel it touches.
pub(crate) type ColData = [Option<Vec<f64>>; 6];

/// The model: the rigid-body regressor plus zero or more effects.
///
/// ```
/// use tagk_diagnose::{Model, effects::LinearDrag};
/// let m = Model::rigid_body().with(LinearDrag);
/// assert_eq!(m.effects().len(), 1);
/// ```
#[derive(Debug, Clone, Default)]
pub struct Model {
    effects: Vec<EffectRef>,
    known_mass: Option<f64>,
}

impl Model {
    /// The bare rigid-body model `b = Y θ`.
    pub fn rigid_body() -> Self {
        Self::default()
    }

    /// Adds an effect.
    pub fn with<E: Effect + 'static>(self, effect: E) -> Self {
        self.with_ref(Arc::new(effect))
    }

    /// Fixes the mass to a known value \[kg\] (weighed on a scale) instead of fitting it.
    /// Needed to tell a thrust-gain error from a mass error: both scale the whole
    /// regression, so without a known mass a thrust-gain error is unidentifiable.
    pub fn with_known_mass(mut self, mass: f64) -> Self {
        self.known_mass = Some(mass);
        self
    }

    /// The known mass, if fixed \[kg\].
    pub fn known_mass(&self) -> Option<f64> {
        self.known_mass
    }

    /// Adds a shared effect.
    pub fn with_ref(mut self, effect: EffectRef) -> Self {
        self.effects.push(effect);
        self
    }

    /// The effects, in the order added.
    pub fn effects(&self) -> &[EffectRef] {
        &self.effects
    }

    /// `true` if an effect with this name is in the model.
    pub fn has(&self, name: &str) -> bool {
        self.effects.iter().any(|e| e.name() == name)
    }

    /// A short label, e.g. `rigid body + linear-drag`.
    pub fn label(&self) -> String {
        let mut s = "rigid body".to_string();
        for e in &self.effects {
            s.push_str(" + ");
            s.push_str(e.name());
        }
        s
    }

    /// Fits the model to a log by weighted batch least squares (see [`fit_model`]).
    ///
    /// # Errors
    /// See [`fit_model`].
    pub fn fit(&self, signals: &Signals) -> Result<Fit, DiagnoseError> {
        fit_model(self, signals, None)
    }
}

/// A fitted coefficient with its standard error.
#[derive(Debug, Clone, Serialize)]
pub struct Coefficient {
    /// Name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Estimate.
    pub value: f64,
    /// Standard error (inflated for residual autocorrelation); `null` if unidentifiable.
    pub std_error: Option<f64>,
}

/// An effect's fitted coefficients.
#[derive(Debug, Clone, Serialize)]
pub struct FittedEffect {
    /// Effect name.
    pub effect: String,
    /// One-line description.
    pub description: String,
    /// Scanned nonlinear parameter `(name, value, unit)`, if any.
    pub scanned: Option<(String, f64, String)>,
    /// Coefficients.
    pub coefficients: Vec<Coefficient>,
    /// Physical plausibility verdict.
    pub plausible: bool,
    /// Plausibility note.
    pub plausibility_note: String,
}

/// Per-channel agreement between measurement and model.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelFit {
    /// Channel name (`fx` … `tz`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// MATLAB `compare` fit `100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖)` \[%\]; `null` for a constant
    /// measurement (e.g. a quadrotor's `fx`, always 0), where it is undefined.
    pub fit_percent: Option<f64>,
    /// Residual RMS \[channel unit\].
    pub rms: f64,
}

/// Result of fitting a [`Model`].
#[derive(Debug, Clone)]
pub struct Fit {
    /// Model label.
    pub label: String,
    /// Fitted rigid-body parameters.
    pub theta: InertialParams,
    /// Their standard errors.
    pub theta_se: [Option<f64>; 10],
    /// Fitted effects.
    pub effects: Vec<FittedEffect>,
    /// Predicted wrench per sample.
    pub predicted: Vec<[f64; 6]>,
    /// Residual `b − b̂` per sample.
    pub residual: Vec<[f64; 6]>,
    /// Per-channel statistics.
    pub channels: Vec<ChannelFit>,
    /// Channel weights used (1 / residual scale).
    pub weights: [f64; 6],
    /// Residual autocorrelation factor κ (effective sample size = n / κ).
    pub kappa: f64,
    /// Chosen scanned parameters, one per model effect (`None` if not scanned).
    pub params: Vec<Option<f64>>,
}

impl Fit {
    /// Residual of one channel as a series.
    pub fn residual_channel(&self, c: usize) -> Vec<f64> {
        self.residual.iter().map(|r| r[c]).collect()
    }
}

/// The ten rigid-body columns on a log.
pub(crate) fn rigid_columns(s: &Signals) -> Vec<ColData> {
    let n = s.len();
    let mut cols: Vec<ColData> = (0..10)
        .map(|j| {
            let mut d: ColData = Default::default();
            let chans: &[usize] = match j {
                0 => &[0, 1, 2],
                1..=3 => &[0, 1, 2, 3, 4, 5],
                _ => &[3, 4, 5],
            };
            for &c in chans {
                d[c] = Some(vec![0.0; n]);
            }
            d
        })
        .collect();
    let mut buf = [0.0; 60];
    for i in 0..n {
        // Infallible: the buffer has 60 entries.
        let _ =
            write_rigid_body_regressor(&s.accel_proper[i], &s.omega[i], &s.omega_dot[i], &mut buf);
        for (j, col) in cols.iter_mut().enumerate() {
            for (c, d) in col.iter_mut().enumerate() {
                if let Some(v) = d {
                    v[i] = buf[10 * c + j];
                }
            }
        }
    }
    cols
}

/// The rigid-body design of a model and its regression target: with a known mass the mass
/// column moves to the target (`b − m·Y₀`) and only nine columns remain.
pub(crate) fn rigid_design(model: &Model, s: &Signals) -> (Vec<ColData>, Vec<[f64; 6]>) {
    let mut cols = rigid_columns(s);
    match model.known_mass() {
        None => (cols, s.wrench.clone()),
        Some(m) => {
            let c0 = cols.remove(0);
            let mut target = s.wrench.clone();
            for (c, d) in c0.iter().enumerate() {
                if let Some(v) = d {
                    for (t, x) in target.iter_mut().zip(v) {
                        t[c] -= m * x;
                    }
                }
            }
            (cols, target)
        }
    }
}

fn add_known_mass(model: &Model, s: &Signals, pred: &mut [[f64; 6]]) {
    if let Some(m) = model.known_mass() {
        for (p, a) in pred.iter_mut().zip(&s.accel_proper) {
            for c in 0..3 {
                p[c] += m * a[c];
            }
        }
    }
}

/// Turns effect columns into regression columns (`b = Yθ − Φβ`: sign flipped).
pub(crate) fn effect_design(effect: &dyn Effect, s: &Signals, p: Option<f64>) -> Vec<ColData> {
    effect
        .columns(s, p)
        .into_iter()
        .map(|c| {
            c.data
                .map(|d| d.map(|v| v.into_iter().map(|x| -x).collect()))
        })
        .collect()
}

/// Initial channel weights from the measurement scale per unit group (forces, torques).
pub(crate) fn initial_weights(s: &Signals) -> [f64; 6] {
    let mut w = [1.0; 6];
    for group in [[0usize, 1, 2], [3, 4, 5]] {
        let scale = group
            .iter()
            .map(|&c| stats::rms(&s.channel(c)))
            .fold(0.0f64, f64::max);
        let scale = if scale > 0.0 { scale } else { 1.0 };
        for c in group {
            w[c] = 1.0 / scale;
        }
    }
    w
}

/// Weights `1 / rms` from a residual, floored at `1e-6` of each unit group's largest RMS.
pub(crate) fn weights_from_residual(res: &[[f64; 6]]) -> [f64; 6] {
    let mut r = [0.0; 6];
    for (c, rc) in r.iter_mut().enumerate() {
        *rc = stats::rms(&res.iter().map(|x| x[c]).collect::<Vec<_>>());
    }
    let mut w = [1.0; 6];
    for group in [[0usize, 1, 2], [3, 4, 5]] {
        let top = group.iter().map(|&c| r[c]).fold(0.0f64, f64::max);
        let floor = if top > 0.0 { top * 1e-6 } else { 1.0 };
        for c in group {
            w[c] = 1.0 / r[c].max(floor);
        }
    }
    w
}

/// Result of the QR least-squares solve.
pub(crate) struct LsSolution {
    pub beta: Vec<f64>,
    pub se: Vec<Option<f64>>,
}

/// Weighted least squares `min Σ_c w_c² ‖b_c − X_c β‖²` with a Householder QR of
/// `[A | b]` (faer; columns equilibrated), then an SVD of the small `R` (truncated at a
/// relative 1e-11 so collinear columns get a minimum-norm solution and no standard error).
/// `kappa` inflates the covariance for autocorrelated residuals.
pub(crate) fn weighted_qr_solve(
    cols: &[ColData],
    b: &[[f64; 6]],
    w: &[f64; 6],
    kappa: f64,
) -> Result<LsSolution, DiagnoseError> {
    let n = b.len();
    let p = cols.len();
    let rows = 6 * n;
    let mut scale = vec![0.0; p];
    for (j, col) in cols.iter().enumerate() {
        let mut s2 = 0.0;
        for (c, d) in col.iter().enumerate() {
            if let Some(v) = d {
                s2 += w[c] * w[c] * v.iter().map(|x| x * x).sum::<f64>();
            }
        }
        scale[j] = if s2 > 0.0 { 1.0 / s2.sqrt() } else { 0.0 };
    }
    let mut a = Mat::<f64>::zeros(rows, p + 1);
    for (j, col) in cols.iter().enumerate() {
        for (c, d) in col.iter().enumerate() {
            if let Some(v) = d {
                let f = w[c] * scale[j];
                for i in 0..n {
                    a[(6 * i + c, j)] = v[i] * f;
                }
            }
        }
    }
    for i in 0..n {
        for c in 0..6 {
            a[(6 * i + c, p)] = b[i][c] * w[c];
        }
    }
    let qr = a.qr();
    let r = qr.thin_R();
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
    Ok(LsSolution { beta, se })
}

/// Prediction `X β` per sample.
pub(crate) fn predict(cols: &[ColData], beta: &[f64], n: usize) -> Vec<[f64; 6]> {
    let mut out = vec![[0.0; 6]; n];
    for (col, &bj) in cols.iter().zip(beta) {
        if bj == 0.0 {
            continue;
        }
        for (c, d) in col.iter().enumerate() {
            if let Some(v) = d {
                for i in 0..n {
                    out[i][c] += v[i] * bj;
                }
            }
        }
    }
    out
}

/// Per-channel fit % and RMS.
pub(crate) fn channel_stats(b: &[[f64; 6]], res: &[[f64; 6]]) -> Vec<ChannelFit> {
    let n = b.len() as f64;
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
            ChannelFit {
                name: CHANNEL_NAMES[c].into(),
                unit: CHANNEL_UNITS[c].into(),
                fit_percent,
                rms: rn / n.sqrt(),
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

/// Fits `model` to the log: scanned effect parameters first (grid search on the weighted
/// residual, one coordinate pass), then the weighted batch least squares by QR. Channel
/// weights are `weights` if given, otherwise two passes: measurement scale, then
/// `1 / residual RMS` of the first pass.
///
/// # Errors
/// [`DiagnoseError::EffectUnavailable`] if an effect cannot be used on this log,
/// [`DiagnoseError::Fit`] if the solve fails.
pub fn fit_model(
    model: &Model,
    s: &Signals,
    weights: Option<[f64; 6]>,
) -> Result<Fit, DiagnoseError> {
    for e in model.effects() {
        e.check(s)
            .map_err(|reason| DiagnoseError::EffectUnavailable {
                effect: e.name().to_string(),
                reason,
            })?;
    }
    let (rigid, target) = rigid_design(model, s);
    let n = s.len();
    let mut w = weights.unwrap_or_else(|| initial_weights(s));
    let passes = if weights.is_some() { 1 } else { 2 };
    let mut params: Vec<Option<f64>> = model
        .effects()
        .iter()
        .map(|e| e.scan().map(|sc| sc.grid[sc.grid.len() / 2]))
        .collect();
    #[allow(clippy::type_complexity)]
    let mut last: Option<(
        Vec<ColData>,
        Vec<[f64; 6]>,
        Vec<[f64; 6]>,
        Option<LsSolution>,
    )> = None;
    for pass in 0..passes {
        if pass > 0
            && let Some((_, _, res, _)) = &last
        {
            w = weights_from_residual(res);
        }
        // Scan the nonlinear parameters, one coordinate at a time.
        for (k, e) in model.effects().iter().enumerate() {
            let Some(spec) = e.scan() else { continue };
            let mut fixed: Vec<ColData> = rigid.clone();
            for (j, f) in model.effects().iter().enumerate() {
                if j != k {
                    fixed.extend(effect_design(f.as_ref(), s, params[j]));
                }
            }
            let engine = GramEngine::new(s, &w, &fixed, Some(&target), 1);
            let (best, _) = scan_min(&spec.grid, |g| {
                engine
                    .evaluate(&effect_design(e.as_ref(), s, Some(g)))
                    .sse_full
            });
            params[k] = Some(best);
        }
        let mut cols = rigid.clone();
        for (k, e) in model.effects().iter().enumerate() {
            cols.extend(effect_design(e.as_ref(), s, params[k]));
        }
        // Intermediate passes only set the weights: normal equations suffice; the final pass
        // is the QR solve.
        let (beta, sol) = if pass + 1 < passes {
            let engine = GramEngine::new(s, &w, &cols, Some(&target), 1);
            (engine.evaluate(&[]).beta, None)
        } else {
            let sol = weighted_qr_solve(&cols, &target, &w, 1.0)?;
            (sol.beta.clone(), Some(sol))
        };
        let mut pred = predict(&cols, &beta, n);
        add_known_mass(model, s, &mut pred);
        let res: Vec<[f64; 6]> = s
            .wrench
            .iter()
            .zip(&pred)
            .map(|(b, p)| std::array::from_fn(|c| b[c] - p[c]))
            .collect();
        last = Some((cols, pred, res, sol));
    }
    let Some((_cols, pred, res, Some(mut sol))) = last else {
        return Err(DiagnoseError::Fit("no pass ran".into()));
    };
    // Standard errors inflated for the residual's autocorrelation (σ² → κ σ²).
    let kappa = residual_kappa(&res, &w);
    for se in sol.se.iter_mut().flatten() {
        *se *= kappa.sqrt();
    }
    let mut theta = [0.0; 10];
    let mut theta_se = [None; 10];
    let nr = rigid.len();
    theta[10 - nr..].copy_from_slice(&sol.beta[..nr]);
    theta_se[10 - nr..].copy_from_slice(&sol.se[..nr]);
    if let Some(m) = model.known_mass() {
        theta[0] = m;
    }
    let mut effects = Vec::new();
    let mut j = nr;
    for (k, e) in model.effects().iter().enumerate() {
        let ecols = e.columns(s, params[k]);
        let q = ecols.len();
        let coef: Vec<f64> = sol.beta[j..j + q].to_vec();
        let se: Vec<f64> = sol.se[j..j + q]
            .iter()
            .map(|x| x.unwrap_or(f64::INFINITY))
            .collect();
        let pl: Plausibility = e.plausibility(&coef, &se, params[k]);
        effects.push(FittedEffect {
            effect: e.name().to_string(),
            description: e.description().to_string(),
            scanned: e
                .scan()
                .and_then(|sp| params[k].map(|v| (sp.name, v, sp.unit))),
            coefficients: ecols
                .iter()
                .enumerate()
                .map(|(i, c)| Coefficient {
                    name: c.name.clone(),
                    unit: c.unit.clone(),
                    value: coef[i],
                    std_error: sol.se[j + i],
                })
                .collect(),
            plausible: pl.plausible,
            plausibility_note: pl.note,
        });
        j += q;
    }
    Ok(Fit {
        label: model.label(),
        theta: InertialParams::from_array(theta),
        theta_se,
        effects,
        channels: channel_stats(&s.wrench, &res),
        predicted: pred,
        residual: res,
        weights: w,
        kappa,
        params,
    })
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
    for _ in 0..12 {
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

/// Evaluation of a candidate set of extra columns by the [`GramEngine`].
#[derive(Debug, Clone)]
pub(crate) struct Evaluation {
    /// Weighted in-sample SSE with the candidate.
    pub sse_full: f64,
    /// Held-out (blocked CV) weighted SSE.
    pub sse_cv: f64,
    /// Held-out SSE per channel.
    pub sse_cv_ch: [f64; 6],
    /// Full-data coefficients (base deltas then candidate).
    pub beta: Vec<f64>,
    /// Diagonal of the (pseudo-)inverse weighted Gram matrix: `σ² κ ·` this is the variance.
    pub cov_diag: Vec<f64>,
}

/// Gram-matrix engine: the weighted target `y` and the base columns are reduced once to
/// per-piece, per-channel cross-product matrices; each candidate only adds its own cross
/// products. Pieces implement blocked K-fold cross-validation over time with a buffer of
/// `buffer` samples on each side of the held-out block removed from training (so that
/// autocorrelated neighbours do not leak).
pub(crate) struct GramEngine<'a> {
    s: &'a Signals,
    w: [f64; 6],
    /// Weighted target.
    y: ColData,
    /// Weighted base columns.
    base: Vec<ColData>,
    pieces: Vec<(usize, usize)>,
    folds: usize,
    /// Per piece, per channel: (1+p0)² cross products of [y, base…].
    base_gram: Vec<f64>,
}

impl<'a> GramEngine<'a> {
    /// `target`: the unweighted target (the measured wrench when `None`).
    pub fn new(
        s: &'a Signals,
        w: &[f64; 6],
        base: &[ColData],
        target: Option<&[[f64; 6]]>,
        folds: usize,
    ) -> Self {
        let n = s.len();
        let tgt = target.unwrap_or(&s.wrench);
        let y: ColData =
            std::array::from_fn(|c| Some(tgt.iter().map(|b| b[c] * w[c]).collect::<Vec<f64>>()));
        let weigh = |col: &ColData| -> ColData {
            std::array::from_fn(|c| {
                col[c]
                    .as_ref()
                    .map(|v| v.iter().map(|x| x * w[c]).collect())
            })
        };
        let base: Vec<ColData> = base.iter().map(weigh).collect();
        let folds = folds.max(1);
        let mut pieces = Vec::new();
        if folds == 1 {
            pieces.push((0, n));
        } else {
            let dt = s.mean_dt().max(1e-9);
            let buffer = ((1.0 / dt).round() as usize).min(n / (4 * folds)).max(1);
            for k in 0..folds {
                let a = k * n / folds;
                let b = (k + 1) * n / folds;
                pieces.push((a, a + buffer));
                pieces.push((a + buffer, b - buffer));
                pieces.push((b - buffer, b));
            }
        }
        let mut all: Vec<&ColData> = vec![&y];
        all.extend(base.iter());
        let base_gram = cross_tensor(&all, &all, &pieces);
        Self {
            s,
            w: *w,
            y,
            base,
            pieces,
            folds,
            base_gram,
        }
    }

    /// Weighted version of unweighted candidate columns.
    fn weigh(&self, cols: &[ColData]) -> Vec<ColData> {
        cols.iter()
            .map(|col| {
                std::array::from_fn(|c| {
                    col[c]
                        .as_ref()
                        .map(|v| v.iter().map(|x| x * self.w[c]).collect())
                })
            })
            .collect()
    }

    /// Evaluates base + `cand` (unweighted extra columns; may be empty).
    pub fn evaluate(&self, cand: &[ColData]) -> Evaluation {
        let cand = self.weigh(cand);
        let p0 = 1 + self.base.len();
        let q = cand.len();
        let pp = p0 + q;
        let np = self.pieces.len();
        let mut left: Vec<&ColData> = vec![&self.y];
        left.extend(self.base.iter());
        left.extend(cand.iter());
        let candr: Vec<&ColData> = cand.iter().collect();
        let cross = cross_tensor(&left, &candr, &self.pieces);
        // Assemble the full (pp × pp) matrices per piece and channel.
        let mut g = vec![0.0; np * 6 * pp * pp];
        for pc in 0..np * 6 {
            let dst = &mut g[pc * pp * pp..(pc + 1) * pp * pp];
            let src = &self.base_gram[pc * p0 * p0..(pc + 1) * p0 * p0];
            for i in 0..p0 {
                for j in 0..p0 {
                    dst[i * pp + j] = src[i * p0 + j];
                }
            }
            let cs = &cross[pc * pp * q..(pc + 1) * pp * q];
            for i in 0..pp {
                for j in 0..q {
                    dst[i * pp + p0 + j] = cs[i * q + j];
                    dst[(p0 + j) * pp + i] = cs[i * q + j];
                }
            }
        }
        let sum_pieces = |sel: &dyn Fn(usize) -> bool, ch: Option<usize>| -> Vec<f64> {
            let mut out = vec![0.0; pp * pp];
            for pi in 0..np {
                if !sel(pi) {
                    continue;
                }
                for c in 0..6 {
                    if ch.is_some_and(|x| x != c) {
                        continue;
                    }
                    let m = &g[(pi * 6 + c) * pp * pp..(pi * 6 + c + 1) * pp * pp];
                    for (o, x) in out.iter_mut().zip(m) {
                        *o += x;
                    }
                }
            }
            out
        };
        let total = sum_pieces(&|_| true, None);
        let (beta, cov_diag) = solve_gram(&total, pp, None);
        let sse_full = sse_of(&total, pp, &beta);
        let (mut sse_cv, mut sse_cv_ch) = (0.0, [0.0; 6]);
        if self.folds > 1 {
            let k_of = |pi: usize| pi / 3;
            for k in 0..self.folds {
                let excluded = |pi: usize| {
                    k_of(pi) == k
                        || (k > 0 && pi == 3 * (k - 1) + 2)
                        || (k + 1 < self.folds && pi == 3 * (k + 1))
                };
                let train = sum_pieces(&|pi| !excluded(pi), None);
                let (bk, _) = solve_gram(&train, pp, Some(&total));
                for c in 0..6 {
                    let test = sum_pieces(&|pi| k_of(pi) == k, Some(c));
                    let e = sse_of(&test, pp, &bk);
                    sse_cv_ch[c] += e;
                    sse_cv += e;
                }
            }
        } else {
            sse_cv = sse_full;
            for (c, o) in sse_cv_ch.iter_mut().enumerate() {
                *o = sse_of(&sum_pieces(&|_| true, Some(c)), pp, &beta);
            }
        }
        Evaluation {
            sse_full,
            sse_cv,
            sse_cv_ch,
            beta,
            cov_diag,
        }
    }

    /// Weighted residual of base + `cand` at coefficients `beta` (from [`Self::evaluate`]).
    pub fn residual(&self, cand: &[ColData], beta: &[f64]) -> Vec<[f64; 6]> {
        let cand = self.weigh(cand);
        let n = self.s.len();
        let mut r: Vec<[f64; 6]> = (0..n)
            .map(|i| std::array::from_fn(|c| self.y[c].as_ref().map_or(0.0, |v| v[i])))
            .collect();
        for (col, &b) in self.base.iter().chain(cand.iter()).zip(beta) {
            for (c, d) in col.iter().enumerate() {
                if let Some(v) = d {
                    for i in 0..n {
                        r[i][c] -= b * v[i];
                    }
                }
            }
        }
        r
    }
}

/// Cross products `Σ_{i ∈ piece} a_j[c][i] b_k[c][i]` for every piece, channel, `j`, `k`;
/// layout `[piece][channel][j][k]`.
fn cross_tensor(a: &[&ColData], b: &[&ColData], pieces: &[(usize, usize)]) -> Vec<f64> {
    let (pa, pb) = (a.len(), b.len());
    let mut out = vec![0.0; pieces.len() * 6 * pa * pb];
    for (j, aj) in a.iter().enumerate() {
        for (k, bk) in b.iter().enumerate() {
            for c in 0..6 {
                let (Some(x), Some(y)) = (&aj[c], &bk[c]) else {
                    continue;
                };
                for (pi, &(lo, hi)) in pieces.iter().enumerate() {
                    let mut s = 0.0;
                    for i in lo..hi {
                        s += x[i] * y[i];
                    }
                    out[((pi * 6 + c) * pa + j) * pb + k] = s;
                }
            }
        }
    }
    out
}

/// Solves the normal equations of a Gram matrix laid out as `[y, x…]²`: returns β for the
/// `x` part (pseudo-inverse via a symmetric eigendecomposition of the equilibrated matrix,
/// eigenvalues below 1e-12 of the largest dropped).
///
/// With `reference` (the Gram matrix of all the data), a column whose diagonal here is below
/// 1e-10 of its reference diagonal — a column that (almost) vanishes on these samples, like a
/// start-of-log transient in a training set without the start — is left out (coefficient 0).
fn solve_gram(gm: &[f64], pp: usize, reference: Option<&[f64]>) -> (Vec<f64>, Vec<f64>) {
    let p = pp - 1;
    let mut d = vec![0.0; p];
    for j in 0..p {
        let g = gm[(j + 1) * pp + j + 1];
        let vanishes = reference.is_some_and(|r| g <= 1e-10 * r[(j + 1) * pp + j + 1]);
        d[j] = if g > 0.0 && !vanishes {
            1.0 / g.sqrt()
        } else {
            0.0
        };
    }
    let a = DMatrix::<f64>::from_fn(p, p, |i, j| gm[(i + 1) * pp + j + 1] * d[i] * d[j]);
    let rhs = DVector::<f64>::from_fn(p, |i, _| gm[(i + 1) * pp] * d[i]);
    let eig = a.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |m, x| m.max(*x));
    let mut x = DVector::<f64>::zeros(p);
    let mut diag = vec![0.0; p];
    for k in 0..p {
        let l = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k);
        if l > lmax * 1e-12 && l > 0.0 {
            x += v * (v.dot(&rhs) / l);
            for j in 0..p {
                diag[j] += v[j] * v[j] / l;
            }
        } else {
            for j in 0..p {
                if v[j] * v[j] > 1e-6 {
                    diag[j] = f64::INFINITY;
                }
            }
        }
    }
    (
        (0..p).map(|j| x[j] * d[j]).collect(),
        (0..p).map(|j| diag[j] * d[j] * d[j]).collect(),
    )
}

/// `yᵀy − 2 βᵀ g + βᵀ G β` from a `[y, x…]²` Gram matrix.
fn sse_of(gm: &[f64], pp: usize, beta: &[f64]) -> f64 {
    let p = pp - 1;
    let mut s = gm[0];
    for i in 0..p {
        s -= 2.0 * beta[i] * gm[(i + 1) * pp];
        for j in 0..p {
            s += beta[i] * beta[j] * gm[(i + 1) * pp + j + 1];
        }
    }
    s.max(0.0)
}
