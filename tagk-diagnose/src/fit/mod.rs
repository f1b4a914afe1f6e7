//! The model (rigid body plus effects) and its batch least-squares fit: the design
//! ([`design`]), the weighted QR solve ([`lsq`]) and the Gram-matrix engine behind the blocked
//! cross-validation and the 1-D scans ([`gram`]).

mod columns;
mod design;
mod gram;
mod likelihood;
mod lsq;
mod model;

use serde::Serialize;
use tagk_dynamics::InertialParams;

use crate::effects::{Plausibility, usable};
use crate::error::DiagnoseError;
use crate::signals::Signals;

pub(crate) use columns::{Column, rigid_channels};
#[cfg(test)]
pub(crate) use design::rigid_columns;
pub(crate) use design::{
    Actuator, ColData, EffectDesign, actuator_interaction, actuator_role, add_offset,
    checked_effect_design, design_of_columns, effect_design, is_start_nuisance, rigid_design,
    sampled_effect_design, window_effect_design,
};
pub(crate) use gram::{Evaluation, GramEngine};
pub use likelihood::TargetFilter;
pub(crate) use likelihood::{
    NoiseModel, channel_filters, channel_score, estimate_noise, high_frequency_noise, part_ranges,
    whitened,
};
pub(crate) use lsq::{channel_stats, scan_min, weighted_qr_solve};
pub use model::Model;

pub(crate) use design::weights_from_residual;
use design::{add_known_mass, initial_weights};
use lsq::{LsSolution, predict, residual_kappa};

/// `true` when `effect` at `param` filters some channel of the measured wrench
/// ([`crate::Effect::unfilter`]).
pub(crate) fn filters(s: &Signals, effect: &dyn crate::Effect, param: Option<f64>) -> bool {
    (0..6).any(|c| effect.unfilter(s, param, c, &mut []))
}

/// Maps a residual of filtered targets back to the measured wrench's domain, log by log
/// (filters never run across a join of several logs): every filtering effect of `filt` in
/// turn. A channel weight is a constant factor, so weighted and unweighted residuals alike.
pub(crate) fn unfilter_residual(
    s: &Signals,
    filt: &[(crate::EffectRef, Option<f64>)],
    r: &mut [[f64; 6]],
) {
    if filt.is_empty() {
        return;
    }
    let parts = s.parts();
    let mut col = Vec::new();
    for (k, range) in part_ranges(s).into_iter().enumerate() {
        let sig = if parts.is_empty() { s } else { &parts[k] };
        for c in 0..6 {
            col.clear();
            col.extend(r[range.clone()].iter().map(|x| x[c]));
            let mut any = false;
            for (e, p) in filt {
                any |= e.unfilter(sig, *p, c, &mut col);
            }
            if any {
                for (x, v) in r[range.clone()].iter_mut().zip(&col) {
                    x[c] = *v;
                }
            }
        }
    }
}

/// The likelihood score of a residual `r` of the (filtered) target, unweighted, under the
/// noise model `noise`, per channel: the innovations' sum of squares and the
/// log-determinant term, both in units of the channel's noise variance
/// ([`likelihood::channel_score`]); `filt` are the filtering effects at their parameters.
pub(crate) fn residual_score(
    s: &Signals,
    r: &[[f64; 6]],
    filt: &[(crate::EffectRef, Option<f64>)],
    noise: &NoiseModel,
) -> ([f64; 6], [f64; 6]) {
    let parts = s.parts();
    let mut norm = [0.0; 6];
    let mut logdet = [0.0; 6];
    let mut series = Vec::new();
    for (k, range) in part_ranges(s).into_iter().enumerate() {
        let sig = if parts.is_empty() { s } else { &parts[k] };
        let filters = channel_filters(filt, sig);
        for c in 0..6 {
            series.clear();
            series.extend(r[range.clone()].iter().map(|x| x[c]));
            let (n, l) = channel_score(
                &series,
                filters[c].as_ref(),
                noise.wrench[c],
                noise.motion[c],
            );
            norm[c] += n;
            logdet[c] += l;
        }
    }
    (norm, logdet)
}

/// Effects with their parameters (the filtering effects of a model, in order).
pub(crate) type EffectParams = Vec<(crate::EffectRef, Option<f64>)>;

/// Samples a scan of a filtered effect reads on a long log (a contiguous window: a filter
/// needs every sample of it).
pub(crate) const SCAN_WINDOW: usize = 12_000;

/// The contiguous window a scan of a filtered effect reads: the middle [`SCAN_WINDOW`]
/// samples of a single log more than twice that long; `None` (the whole log) otherwise, and
/// for joined logs.
pub(crate) fn scan_window(s: &Signals) -> Option<std::ops::Range<usize>> {
    let n = s.len();
    if !s.parts().is_empty() || n <= 2 * SCAN_WINDOW {
        return None;
    }
    let lo = (n - SCAN_WINDOW) / 2;
    Some(lo..lo + SCAN_WINDOW)
}

/// [`residual_score`] of a residual `r` over the samples `span` of a single log (a scan
/// window), or of the whole log.
pub(crate) fn residual_score_span(
    s: &Signals,
    r: &[[f64; 6]],
    span: std::ops::Range<usize>,
    filt: &[(crate::EffectRef, Option<f64>)],
    noise: &NoiseModel,
) -> ([f64; 6], [f64; 6]) {
    if span == (0..s.len()) {
        return residual_score(s, r, filt, noise);
    }
    let filters = channel_filters(filt, s);
    let mut norm = [0.0; 6];
    let mut logdet = [0.0; 6];
    for c in 0..6 {
        let series: Vec<f64> = r.iter().map(|x| x[c]).collect();
        let (n, l) = channel_score(
            &series,
            filters[c].as_ref(),
            noise.wrench[c],
            noise.motion[c],
        );
        norm[c] = n;
        logdet[c] = l;
    }
    (norm, logdet)
}

/// The criterion a scanned parameter is estimated on when a filter of the target is in the
/// model (a motor lag's time constant): the innovations' sum of squares of the residual `r`
/// over `span` ([`residual_score_span`]), in units of each channel's noise variance, summed
/// over the channels, **without** the log-determinant term. Its expectation is the number of
/// innovations plus the model's own mismatch, whatever the parameter, so it is least at the
/// true value ([`likelihood`] module docs: estimating a filter's parameter).
pub(crate) fn scan_criterion(
    s: &Signals,
    r: &[[f64; 6]],
    span: std::ops::Range<usize>,
    filt: &[(crate::EffectRef, Option<f64>)],
    noise: &NoiseModel,
) -> f64 {
    let (norm, _) = residual_score_span(s, r, span, filt, noise);
    norm.iter().sum()
}

/// The whitened residual of a residual `r` of the (filtered) target, unweighted
/// ([`likelihood::whitened`]: white with each channel's noise variance at the true model;
/// `r` itself on channels without a filter).
pub(crate) fn whitened_residual(
    s: &Signals,
    r: &[[f64; 6]],
    filt: &[(crate::EffectRef, Option<f64>)],
    noise: &NoiseModel,
) -> Vec<[f64; 6]> {
    if filt.is_empty() {
        return r.to_vec();
    }
    let parts = s.parts();
    let mut out = r.to_vec();
    let mut series = Vec::new();
    for (k, range) in part_ranges(s).into_iter().enumerate() {
        let sig = if parts.is_empty() { s } else { &parts[k] };
        let filters = channel_filters(filt, sig);
        for c in 0..6 {
            if filters[c].is_none() {
                continue;
            }
            series.clear();
            series.extend(r[range.clone()].iter().map(|x| x[c]));
            let w = whitened(
                &series,
                filters[c].as_ref(),
                noise.wrench[c],
                noise.motion[c],
            );
            for (x, v) in out[range.clone()].iter_mut().zip(w) {
                x[c] = v;
            }
        }
    }
    out
}

/// The noise model of a model's forward residual `r` (unweighted): its filters undone, then
/// [`likelihood::estimate_noise`], each channel at least `floor` in total.
pub(crate) fn noise_of_residual(
    s: &Signals,
    r: &[[f64; 6]],
    filt: &[(crate::EffectRef, Option<f64>)],
    floor: &[f64; 6],
) -> (NoiseModel, [f64; 6]) {
    let mut e = r.to_vec();
    unfilter_residual(s, filt, &mut e);
    let filters = channel_filters(filt, s);
    let (model, raw) = estimate_noise(s, &e, &filters);
    let total: [f64; 6] = std::array::from_fn(|c| model.variance(c).sqrt().max(floor[c]));
    (model.scaled_to(&total), raw)
}

/// The filtering effects of a model at its parameters.
pub(crate) fn model_filters(
    model: &Model,
    s: &Signals,
    params: &[Option<f64>],
) -> Vec<(crate::EffectRef, Option<f64>)> {
    model
        .effects()
        .iter()
        .zip(params)
        .filter(|(e, p)| filters(s, e.as_ref(), **p))
        .map(|(e, p)| (e.clone(), *p))
        .collect()
}

/// Names of the ten rigid-body parameters, in the order of `tagk_dynamics::InertialParams`.
pub(crate) const THETA_NAMES: [&str; 10] = [
    "m", "h_x", "h_y", "h_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz",
];
/// Units of the ten rigid-body parameters.
pub(crate) const THETA_UNITS: [&str; 10] = [
    "kg", "kg m", "kg m", "kg m", "kg m²", "kg m²", "kg m²", "kg m²", "kg m²", "kg m²",
];

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
    /// 95 % confidence interval `value ± 1.96 std_error` (normal approximation); `null` if
    /// unidentifiable.
    pub confidence_interval: Option<[f64; 2]>,
}

impl Coefficient {
    /// A coefficient with its standard error and the 95 % interval that follows from it.
    pub fn new(name: &str, unit: &str, value: f64, std_error: Option<f64>) -> Self {
        let std_error = std_error.filter(|e| e.is_finite());
        Self {
            name: name.to_string(),
            unit: unit.to_string(),
            value,
            std_error,
            confidence_interval: std_error.map(|e| [value - Z_95 * e, value + Z_95 * e]),
        }
    }
}

/// Two-sided 95 % quantile of the standard normal distribution.
pub const Z_95: f64 = 1.959_963_984_540_054;

/// An effect's fitted coefficients.
#[derive(Debug, Clone, Serialize)]
pub struct FittedEffect {
    /// Effect name.
    pub effect: String,
    /// One-line description.
    pub description: String,
    /// Scanned nonlinear parameter `(name, value, unit)`, if any.
    pub scanned: Option<(String, f64, String)>,
    /// 95 % confidence interval of the scanned parameter (its unit), when the data bound it.
    pub scanned_interval: Option<[f64; 2]>,
    /// Coefficients.
    pub coefficients: Vec<Coefficient>,
    /// Quantities derived from the coefficients (e.g. the wind velocity), with standard
    /// errors and 95 % intervals.
    pub derived: Vec<Coefficient>,
    /// Physical plausibility verdict.
    pub plausible: bool,
    /// Plausibility note.
    pub plausibility_note: String,
    /// The sensor quantity whose noise limits these coefficients (the larger noise source of
    /// the channels the effect acts on; filled in by the diagnosis, empty from a plain fit).
    pub limited_by: String,
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
    /// Residual RMS as a percentage of the channel group's scale, defined for every channel
    /// of a flight: `100 · RMS(r_c) / RMS(|f|)` for `fx`, `fy`, `fz` (the RMS magnitude of the
    /// measured force, i.e. the thrust) and `100 · RMS(r_c) / RMS(|τ|)` for `tx`, `ty`, `tz`
    /// (the RMS magnitude of the measured torque) \[%\]; lower is better. `null` only when the
    /// whole group is zero.
    pub error_percent: Option<f64>,
    /// Residual RMS \[channel unit\].
    pub rms: f64,
}

/// The smallest pseudo-inertia eigenvalue of a repaired fit ([`Fit::consistent_theta`]), as a
/// fraction of its largest second moment: a Crazyflie's smallest is a tenth of its largest.
pub const CONSISTENT_MARGIN: f64 = 1e-3;

/// Result of fitting a [`Model`].
#[derive(Debug, Clone)]
pub struct Fit {
    /// Model label.
    pub label: String,
    /// Fitted rigid-body parameters.
    pub theta: InertialParams,
    /// Their standard errors.
    pub theta_se: [Option<f64>; 10],
    /// Their covariance (row-major 10 × 10, the order of `theta`), inflated like
    /// [`Fit::theta_se`]: its diagonal is their square. `NaN` in the rows and columns of a
    /// parameter without a standard error (unidentifiable, or the known mass).
    pub theta_cov: [[f64; 10]; 10],
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
    /// The scanned parameters of every model effect but the `k`-th (the parameters of the
    /// model without that effect).
    pub(crate) fn params_without(&self, k: usize) -> Vec<Option<f64>> {
        self.params
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != k)
            .map(|(_, p)| *p)
            .collect()
    }

    /// The physically consistent parameters nearest to [`Fit::theta`] in the metric of its
    /// covariance ([`InertialParams::nearest_consistent`]): `theta` itself when its
    /// pseudo-inertia is positive semidefinite. The least-squares θ is the data's answer;
    /// one whose pseudo-inertia has a negative eigenvalue is no body's. The repair moves it
    /// most along the directions the log determines least (an inertia the flight hardly
    /// excites). A parameter without a standard error carries no information and moves
    /// freely, except a mass without one (a known mass), which stays. The repaired body keeps
    /// every pseudo-inertia eigenvalue at least [`CONSISTENT_MARGIN`] of its largest second
    /// moment: on the boundary it would be flat, and its spatial inertia singular (a model
    /// that cannot be integrated).
    pub fn consistent_theta(&self) -> InertialParams {
        if self
            .theta
            .min_pseudo_inertia_eigenvalue()
            .is_none_or(|l| l >= 0.0)
        {
            return self.theta;
        }
        let second_moment = self
            .theta
            .pseudo_inertia()
            .fixed_view::<3, 3>(0, 0)
            .into_owned();
        let largest = second_moment.symmetric_eigenvalues().max().max(0.0);
        let margin = CONSISTENT_MARGIN * largest;
        let known: Vec<usize> = (0..10)
            .filter(|&k| self.theta_cov[k][k].is_finite() && self.theta_cov[k][k] > 0.0)
            .collect();
        let cov = nalgebra::DMatrix::from_fn(known.len(), known.len(), |i, j| {
            self.theta_cov[known[i]][known[j]]
        });
        if !cov.iter().all(|x| x.is_finite()) {
            return self.theta.project_to_consistent(0.0);
        }
        // The information: the covariance's (pseudo-)inverse on the parameters it covers,
        // through the correlation matrix (the parameters' scales differ by 10²⁰).
        let sd = cov.diagonal().map(f64::sqrt);
        let corr = nalgebra::DMatrix::from_fn(cov.nrows(), cov.ncols(), |i, j| {
            cov[(i, j)] / (sd[i] * sd[j])
        });
        let eig = corr.symmetric_eigen();
        let top = eig.eigenvalues.amax();
        let inverse = nalgebra::DMatrix::from_diagonal(
            &eig.eigenvalues
                .map(|l| if l > 1e-12 * top { 1.0 / l } else { 0.0 }),
        );
        let corr_info = &eig.eigenvectors * inverse * eig.eigenvectors.transpose();
        let info = nalgebra::DMatrix::from_fn(cov.nrows(), cov.ncols(), |i, j| {
            corr_info[(i, j)] / (sd[i] * sd[j])
        });
        let mut p = [[0.0; 10]; 10];
        for (a, &i) in known.iter().enumerate() {
            for (b, &j) in known.iter().enumerate() {
                p[i][j] = info[(a, b)];
            }
        }
        if !known.contains(&0) {
            let most = (0..10).map(|k| p[k][k]).fold(1.0f64, f64::max);
            p[0][0] = 1e6 * most;
        }
        self.theta.nearest_consistent(&p, margin)
    }

    /// Residual of one channel as a series.
    pub fn residual_channel(&self, c: usize) -> Vec<f64> {
        self.residual.iter().map(|r| r[c]).collect()
    }
}

/// Fits `model` to the log: scanned effect parameters first (grid search on the weighted
/// residual, one coordinate pass), then the weighted batch least squares by QR. Channel
/// weights are `weights` if given, otherwise two passes: measurement scale, then
/// `1 / residual RMS` of the first pass.
///
/// # Errors
/// [`DiagnoseError::InvalidModel`] if the model does not validate ([`Model::validate`]),
/// [`DiagnoseError::EffectUnavailable`] if an effect cannot be used on this log,
/// [`DiagnoseError::InvalidOption`] for non-positive or non-finite `weights`,
/// [`DiagnoseError::Fit`] if the solve fails.
pub fn fit_model(
    model: &Model,
    s: &Signals,
    weights: Option<[f64; 6]>,
) -> Result<Fit, DiagnoseError> {
    fit(model, s, weights, true)
}

/// [`fit_model`], keeping the prediction or not.
fn fit(
    model: &Model,
    s: &Signals,
    weights: Option<[f64; 6]>,
    keep_prediction: bool,
) -> Result<Fit, DiagnoseError> {
    model.validate()?;
    check_effects_usable(model, s)?;
    if let Some(w) = weights
        && w.iter().any(|x| !(x.is_finite() && *x > 0.0))
    {
        return Err(DiagnoseError::InvalidOption {
            field: "weights",
            reason: format!("channel weights {w:?} must be positive and finite"),
        });
    }
    let (rigid, target) = rigid_design(model, s);
    let target: &[[f64; 6]] = &target;
    let mut w = weights.unwrap_or_else(|| initial_weights(s));
    // Weighting passes: the measurement scale first, then 1 / residual RMS of the previous
    // pass; with scanned effects the weights and the scanned parameters are iterated until the
    // parameters settle (at most three passes), since a parameter chosen under poor weights
    // gives poor weights in turn.
    let scanned = model
        .effects()
        .iter()
        .filter(|e| e.scan().is_some())
        .count();
    let passes = match (weights.is_some(), scanned) {
        (true, _) => 1,
        (false, 0) => 2,
        (false, _) => 3,
    };
    // The smallest noise the scans' likelihood and the standard errors assume.
    let resolution = default_resolution(s);
    let mut params = initial_scan_parameters(model);
    let mut last: Option<Pass> = None;
    let mut settled = 0;
    for pass in 0..passes {
        if let Some(previous) = last.take() {
            // Only the weights are kept of an intermediate pass (its prediction and
            // residual, `12 n` values, go before the next pass makes its own).
            w = weights_from_residual(&previous.residual);
        }
        let before = params.clone();
        // A lag and a delay trade along a ridge (the net offset): in the full-grid passes
        // they are scanned jointly first, then refined one at a time.
        if pass <= 1 {
            joint_actuator_scan(model, s, &rigid, target, &w, &mut params, &resolution);
        }
        // Coordinate descent over the scanned effects: rounds until no parameter moves (at
        // most three; one when fewer than two effects are scanned).
        for _ in 0..if scanned > 1 { 3 } else { 1 } {
            let round = params.clone();
            scan_parameters(
                model,
                s,
                &rigid,
                target,
                &w,
                &mut params,
                // The first two passes scan the whole grid: the first pass's weights are the
                // measurement scale, under which a noise-dominated channel (a small
                // quadrotor's torques) can outweigh the channel that carries the parameter
                // (the thrust, for a delay); the second pass's are the residual's, the noise.
                pass > 1,
                &resolution,
            );
            if params == round {
                break;
            }
        }
        // Two weighting passes always; then stop once the parameters no longer move (by more
        // than 1 % of their value: the golden-section refinement never lands twice on the
        // same bits).
        let moved = params.iter().zip(&before).any(|(a, b)| match (a, b) {
            (Some(a), Some(b)) => (a - b).abs() > 0.01 * a.abs().max(b.abs()),
            _ => false,
        });
        settled = if pass > 0 && !moved { settled + 1 } else { 0 };
        let final_pass = pass + 1 == passes || (pass >= 1 && settled >= 1);
        last = Some(solve_pass(
            model,
            s,
            &rigid,
            target,
            &w,
            &params,
            match (final_pass, keep_prediction) {
                (false, _) => PassKind::Intermediate,
                (true, false) => PassKind::FinalResidual,
                (true, true) => PassKind::Final,
            },
        )?);
        if final_pass {
            break;
        }
    }
    let Some(Pass {
        predicted,
        residual,
        solution: Some(mut sol),
        names,
    }) = last
    else {
        return Err(DiagnoseError::Fit("no pass ran".into()));
    };
    // Standard errors inflated for the residual's autocorrelation (σ² → κ σ²): the residual
    // of the regression actually solved (of the filtered target, with a lag).
    let kappa = residual_kappa(&residual, &w);
    // No coefficient is known better than the resolution of the data allows: a residual below
    // the resolution (a noise-free log, fitted to its discretisation) counts as the resolution
    // (`crate::FLOOR_RESOLUTION`).
    let rows = (6 * residual.len()) as f64;
    let p = sol.beta.len() as f64;
    let variance = residual
        .iter()
        .map(|r| (0..6).map(|c| (r[c] * w[c]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / (rows - p).max(1.0);
    let floor = (0..6).map(|c| (resolution[c] * w[c]).powi(2)).sum::<f64>() / 6.0;
    let lift = if variance > 0.0 && variance < floor {
        (floor / variance).sqrt()
    } else {
        1.0
    };
    for se in sol.se.iter_mut().flatten() {
        *se *= kappa.sqrt() * lift;
    }
    for c in &mut sol.cov {
        *c *= kappa * lift * lift;
    }
    // The residual and the prediction of the measured wrench itself: a filter of the target
    // (a lag) is undone on the residual ([`crate::Effect::unfilter`]).
    let filt = model_filters(model, s, &params);
    let (predicted, residual) = if filt.is_empty() {
        (predicted, residual)
    } else {
        let mut residual = residual;
        unfilter_residual(s, &filt, &mut residual);
        let predicted = if predicted.is_empty() {
            predicted
        } else {
            s.target()
                .iter()
                .zip(&residual)
                .map(|(b, e)| std::array::from_fn(|c| b[c] - e[c]))
                .collect()
        };
        (predicted, residual)
    };
    let (theta, theta_se, theta_cov) = rigid_parameters(model, &sol, rigid.len());
    let effects = fitted_effects(model, s, &params, &names, &sol, rigid.len());
    Ok(Fit {
        label: model.label(),
        theta,
        theta_se,
        theta_cov,
        effects,
        channels: channel_stats(s.target(), &residual),
        predicted,
        residual,
        weights: w,
        kappa,
        params,
    })
}

/// Step 1 of [`fit_model`]: every effect of the model must be usable on this log (e.g. rotor
/// drag needs rotor speeds; a user's effect must give finite columns of the log's length).
fn check_effects_usable(model: &Model, s: &Signals) -> Result<(), DiagnoseError> {
    for e in model.effects() {
        usable(e.as_ref(), s).map_err(|reason| DiagnoseError::EffectUnavailable {
            effect: e.name().to_string(),
            reason,
        })?;
    }
    Ok(())
}

/// The starting value of each effect's scanned parameter: its `start`, else the middle of its grid (`None`
/// for an effect without a scan). Grids are non-empty ([`Model::validate`]).
fn initial_scan_parameters(model: &Model) -> Vec<Option<f64>> {
    model
        .effects()
        .iter()
        .map(|e| {
            e.scan()
                .map(|sc| sc.start.unwrap_or(sc.grid[sc.grid.len() / 2]))
        })
        .collect()
}

/// Step 2 (each pass): the scanned parameters, one coordinate at a time, each minimising the
/// weighted in-sample residual with the other effects at their current parameters.
/// `resolution` is the log's [`default_resolution`]: the least noise of a filtered scan.
#[allow(clippy::too_many_arguments)]
fn scan_parameters(
    model: &Model,
    s: &Signals,
    rigid: &[Column<'static>],
    target: &[[f64; 6]],
    w: &[f64; 6],
    params: &mut [Option<f64>],
    near_previous: bool,
    resolution: &[f64; 6],
) {
    for (k, e) in model.effects().iter().enumerate() {
        let Some(spec) = e.scan() else { continue };
        // After the first two weighting passes a parameter only moves near where it was: the
        // scan covers the two grid values on each side of it (and it).
        let grid = match params[k] {
            Some(p) if near_previous => local_grid(&spec.grid, p),
            _ => spec.grid.clone(),
        };
        let mut others: Vec<ColData> = Vec::new();
        let mut shifted_target = std::borrow::Cow::Borrowed(target);
        // The other effects' lag (its known part) or delay, composed with this effect's
        // delay or lag at each value scanned ([`actuator_interaction`]).
        let role = actuator_role(e.as_ref());
        let mut other_lag: Option<ColData> = None;
        let mut other_delay: Option<f64> = None;
        for (j, f) in model.effects().iter().enumerate() {
            if j != k {
                let d = effect_design(f.as_ref(), s, params[j]);
                match (role, actuator_role(f.as_ref())) {
                    (Some(Actuator::Delay), Some(Actuator::Lag)) => other_lag = d.offset.clone(),
                    (Some(Actuator::Lag), Some(Actuator::Delay)) => other_delay = params[j],
                    _ => {}
                }
                others.extend(d.cols);
                if let Some(o) = &d.offset {
                    sub_offset(shifted_target.to_mut(), o);
                }
            }
        }
        let fixed: Vec<Column<'_>> = rigid
            .iter()
            .copied()
            .chain(Column::stored(&others))
            .collect();
        // The criterion is the error of predicting the measured wrench: with a filtering
        // effect (a lag) in the model the residual is mapped back through its inverse, on
        // every sample (a filter runs over all of them); otherwise a sum of squares on every
        // `n / 10 000`-th sample.
        let other_filters: Vec<(crate::EffectRef, Option<f64>)> = model
            .effects()
            .iter()
            .enumerate()
            .filter(|(j, f)| *j != k && filters(s, f.as_ref(), params[*j]))
            .map(|(j, f)| (f.clone(), params[j]))
            .collect();
        let filtered = !other_filters.is_empty() || filters(s, e.as_ref(), grid.first().copied());
        let best = if filtered {
            let full = GramEngine::new(s, w, &fixed, Some(&shifted_target), 1);
            let window = scan_window(s)
                .map(|r| GramEngine::new_window(s, w, &fixed, Some(&shifted_target), r));
            // The residual's forward form, unweighted, at parameter `g`, over the engine's
            // samples.
            // On a window of a long log, the effect's columns there only
            // ([`window_effect_design`]).
            let composed = other_lag.is_some() || other_delay.is_some();
            let residual_at = |engine: &GramEngine<'_>, g: f64| -> (Vec<[f64; 6]>, EffectParams) {
                let span = engine.span();
                // A composed lag and delay reads the whole log (the shift crosses the window).
                let windowed = (span != (0..s.len()) && !composed)
                    .then(|| window_effect_design(e.as_ref(), s, Some(g), span))
                    .flatten();
                let r = match windowed {
                    Some(d) => {
                        let ev = engine.evaluate_window(&d.cols, d.offset.as_ref());
                        engine.residual_window_unweighted(&d.cols, d.offset.as_ref(), &ev.beta)
                    }
                    None => {
                        let mut d = effect_design(e.as_ref(), s, Some(g));
                        let cross = match (&other_lag, other_delay, &d.offset) {
                            (Some(lag), _, _) => actuator_interaction(s, lag, g),
                            (None, Some(delay), Some(lag)) => actuator_interaction(s, lag, delay),
                            _ => None,
                        };
                        if let Some(cross) = cross {
                            match &mut d.offset {
                                None => d.offset = Some(cross),
                                Some(acc) => add_col_data(acc, cross),
                            }
                        }
                        let ev = engine.evaluate_with(&d.cols, d.offset.as_ref());
                        engine.residual_unweighted(&d.cols, d.offset.as_ref(), &ev.beta)
                    }
                };
                let mut filt = other_filters.clone();
                if filters(s, e.as_ref(), Some(g)) {
                    filt.push((e.clone(), Some(g)));
                }
                (r, filt)
            };
            // The noise of the two sources, measured at the current value, then the
            // likelihood over the grid ([`likelihood`]).
            let now = params[k].unwrap_or(grid[grid.len() / 2]);
            let (r0, f0) = residual_at(&full, now);
            let (noise, _) = noise_of_residual(s, &r0, &f0, resolution);
            let engine = window.as_ref().unwrap_or(&full);
            scan_min(&grid, |g| {
                let (r, filt) = residual_at(engine, g);
                scan_criterion(s, &r, engine.span(), &filt, &noise)
            })
            .0
        } else {
            let engine = GramEngine::new_for_scan(s, w, &fixed, Some(&shifted_target));
            scan_min(&grid, |g| {
                sampled_effect_design(e.as_ref(), s, Some(g), engine.stride())
                    .map_or(f64::INFINITY, |d| {
                        engine.evaluate_sampled(&d.cols, d.offset.as_ref()).sse_full
                    })
            })
            .0
        };
        params[k] = Some(best);
    }
}

/// The motor lag's and the time delay's parameters of `model` chosen jointly over both grids
/// (when the model holds one of each; otherwise nothing). Each pair is scored by the scan
/// criterion of the composed pair ([`actuator_interaction`]), with the other effects at
/// `params` and the noise measured once, at the current values. Coordinate scans alone
/// follow the ridge along which the two trade and stop on it, far from the true pair.
#[allow(clippy::too_many_arguments)]
fn joint_actuator_scan(
    model: &Model,
    s: &Signals,
    rigid: &[Column<'static>],
    target: &[[f64; 6]],
    w: &[f64; 6],
    params: &mut [Option<f64>],
    resolution: &[f64; 6],
) {
    let effects = model.effects();
    let find = |role: Actuator| {
        let mut hits = effects
            .iter()
            .enumerate()
            .filter(|(_, e)| actuator_role(e.as_ref()) == Some(role) && e.scan().is_some());
        match (hits.next(), hits.next()) {
            (Some((k, _)), None) => Some(k),
            _ => None,
        }
    };
    let (Some(a), Some(b)) = (find(Actuator::Lag), find(Actuator::Delay)) else {
        return;
    };
    let (Some(lag_spec), Some(delay_spec)) = (effects[a].scan(), effects[b].scan()) else {
        return;
    };
    let mut others: Vec<ColData> = Vec::new();
    let mut shifted_target = std::borrow::Cow::Borrowed(target);
    let mut other_filters: EffectParams = Vec::new();
    for (j, f) in effects.iter().enumerate() {
        if j == a || j == b {
            continue;
        }
        let d = effect_design(f.as_ref(), s, params[j]);
        others.extend(d.cols);
        if let Some(o) = &d.offset {
            sub_offset(shifted_target.to_mut(), o);
        }
        if filters(s, f.as_ref(), params[j]) {
            other_filters.push((f.clone(), params[j]));
        }
    }
    let fixed: Vec<Column<'_>> = rigid
        .iter()
        .copied()
        .chain(Column::stored(&others))
        .collect();
    let full = GramEngine::new(s, w, &fixed, Some(&shifted_target), 1);
    let window =
        scan_window(s).map(|r| GramEngine::new_window(s, w, &fixed, Some(&shifted_target), r));
    let delay_design = |p: f64| effect_design(effects[b].as_ref(), s, Some(p));
    // The residual of the composed pair (lag design `lag` at `tau`, delay `p`) on `engine`.
    let residual = |engine: &GramEngine<'_>, lag: &EffectDesign, tau: f64, p: f64| {
        let mut offset: ColData = Default::default();
        if let Some(o) = &lag.offset {
            add_col_data(&mut offset, o.clone());
            if let Some(cross) = actuator_interaction(s, o, p) {
                add_col_data(&mut offset, cross);
            }
        }
        if let Some(o) = delay_design(p).offset {
            add_col_data(&mut offset, o);
        }
        let ev = engine.evaluate_with(&lag.cols, Some(&offset));
        let r = engine.residual_unweighted(&lag.cols, Some(&offset), &ev.beta);
        let mut filt = other_filters.clone();
        if filters(s, effects[a].as_ref(), Some(tau)) {
            filt.push((effects[a].clone(), Some(tau)));
        }
        (r, filt)
    };
    let tau0 = params[a].unwrap_or(lag_spec.grid[lag_spec.grid.len() / 2]);
    let p0 = params[b].unwrap_or(delay_spec.grid[delay_spec.grid.len() / 2]);
    let (r0, f0) = residual(
        &full,
        &effect_design(effects[a].as_ref(), s, Some(tau0)),
        tau0,
        p0,
    );
    let (noise, _) = noise_of_residual(s, &r0, &f0, resolution);
    let engine = window.as_ref().unwrap_or(&full);
    let mut best: Option<(f64, f64, f64)> = None;
    for &tau in lag_spec.grid.iter().filter(|x| x.is_finite()) {
        let lag = effect_design(effects[a].as_ref(), s, Some(tau));
        for &p in delay_spec.grid.iter().filter(|x| x.is_finite()) {
            let (r, filt) = residual(engine, &lag, tau, p);
            let v = scan_criterion(s, &r, engine.span(), &filt, &noise);
            if v.is_finite() && best.is_none_or(|(_, _, bv)| v < bv) {
                best = Some((tau, p, v));
            }
        }
    }
    if let Some((tau, p, _)) = best {
        params[a] = Some(tau);
        params[b] = Some(p);
    }
}

/// The resolution of the noise with the Crazyflie's airframe radius ([`resolution`]): the
/// smallest noise a fit's own likelihood assumes.
pub(crate) fn default_resolution(s: &Signals) -> [f64; 6] {
    resolution(s, tagk_dynamics::SafetyGate::crazyflie().max_com_offset)
}

/// The resolution per channel: `crate::FLOOR_RESOLUTION` × the RMS measured force magnitude,
/// times `airframe_radius` \[m\] for the torques.
pub(crate) fn resolution(s: &Signals, airframe_radius: f64) -> [f64; 6] {
    resolution_of(s.wrench(), airframe_radius)
}

/// The resolution per channel of a wrench series (one `[fx..tz]` per sample \[N, N m\]):
/// `crate::FLOOR_RESOLUTION` × the RMS force magnitude for forces, times `airframe_radius`
/// \[m\] for torques.
pub fn resolution_of(wrench: &[[f64; 6]], airframe_radius: f64) -> [f64; 6] {
    let n = wrench.len().max(1) as f64;
    let force_rms = (wrench
        .iter()
        .map(|b| b[0] * b[0] + b[1] * b[1] + b[2] * b[2])
        .sum::<f64>()
        / n)
        .sqrt();
    std::array::from_fn(|c| {
        if c < 3 {
            crate::FLOOR_RESOLUTION * force_rms
        } else {
            crate::FLOOR_RESOLUTION * force_rms * airframe_radius
        }
    })
}

/// The grid values within two places of `p` in the sorted grid, and `p` itself.
fn local_grid(grid: &[f64], p: f64) -> Vec<f64> {
    let mut g: Vec<f64> = grid.iter().copied().filter(|x| x.is_finite()).collect();
    g.sort_by(|a, b| a.total_cmp(b));
    let at = g.partition_point(|x| *x < p);
    let lo = at.saturating_sub(2);
    let hi = (at + 2).min(g.len());
    let mut local = g[lo..hi].to_vec();
    local.push(p);
    local
}

/// Subtracts `offset` (a sum of fixed columns) from per-sample values.
fn sub_offset(values: &mut [[f64; 6]], offset: &ColData) {
    for (c, d) in offset.iter().enumerate() {
        if let Some(v) = d {
            for (x, o) in values.iter_mut().zip(v) {
                x[c] -= o;
            }
        }
    }
}

/// `acc += o`, channel by channel (a channel only `o` has is taken as it is).
fn add_col_data(acc: &mut ColData, o: ColData) {
    for (a, b) in acc.iter_mut().zip(o) {
        match (a.as_mut(), b) {
            (Some(x), Some(y)) => x.iter_mut().zip(&y).for_each(|(p, q)| *p += q),
            (None, Some(y)) => *a = Some(y),
            _ => {}
        }
    }
}

/// What a pass of [`fit_model`] solves and returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum PassKind {
    /// Normal equations; the residual only sets the next pass's weights.
    Intermediate,
    /// The QR solve, with the prediction and the residual.
    Final,
    /// The QR solve, with the residual only ([`fit`] without `keep_prediction`).
    FinalResidual,
}

/// One pass's solution: prediction and residual (and the QR solution on the final pass).
struct Pass {
    predicted: Vec<[f64; 6]>,
    residual: Vec<[f64; 6]>,
    solution: Option<LsSolution>,
    /// Per effect of the model, the name and unit of each fitted column's coefficient.
    names: Vec<Vec<(String, String)>>,
}

/// Step 3 (each pass): the linear solve at the current parameters. Intermediate passes only
/// set the weights, so normal equations suffice; the final pass is the QR solve. The
/// prediction is returned only by [`PassKind::Final`] (empty otherwise: only the residual).
fn solve_pass(
    model: &Model,
    s: &Signals,
    rigid: &[Column<'static>],
    target: &[[f64; 6]],
    w: &[f64; 6],
    params: &[Option<f64>],
    kind: PassKind,
) -> Result<Pass, DiagnoseError> {
    let mut effect_cols: Vec<ColData> = Vec::new();
    let mut known: Option<ColData> = None;
    let mut names = Vec::new();
    // A lag's known part and a delay, composed after the loop ([`actuator_interaction`]).
    let mut lag: Option<ColData> = None;
    let mut delay: Option<f64> = None;
    for (k, e) in model.effects().iter().enumerate() {
        let d = effect_design(e.as_ref(), s, params[k]);
        effect_cols.extend(d.cols);
        names.push(d.names);
        match actuator_role(e.as_ref()) {
            Some(Actuator::Lag) => lag = d.offset.clone(),
            Some(Actuator::Delay) => delay = params[k],
            None => {}
        }
        if let Some(o) = d.offset {
            match &mut known {
                None => known = Some(o),
                Some(acc) => {
                    for (a, b) in acc.iter_mut().zip(o) {
                        match (a.as_mut(), b) {
                            (Some(x), Some(y)) => x.iter_mut().zip(&y).for_each(|(p, q)| *p += q),
                            (None, Some(y)) => *a = Some(y),
                            _ => {}
                        }
                    }
                }
            }
        }
    }
    if let (Some(lag), Some(delay)) = (&lag, delay)
        && let Some(cross) = actuator_interaction(s, lag, delay)
    {
        match &mut known {
            None => known = Some(cross),
            Some(acc) => add_col_data(acc, cross),
        }
    }
    let cols: Vec<Column<'_>> = rigid
        .iter()
        .copied()
        .chain(Column::stored(&effect_cols))
        .collect();
    let mut shifted_target = std::borrow::Cow::Borrowed(target);
    if let Some(o) = &known {
        sub_offset(shifted_target.to_mut(), o);
    }
    let (beta, solution) = if kind != PassKind::Intermediate {
        let sol = weighted_qr_solve(s, &cols, &shifted_target, w, 1.0)?;
        (sol.beta.clone(), Some(sol))
    } else {
        let engine = GramEngine::new(s, w, &cols, Some(&shifted_target), 1);
        (engine.evaluate(&[]).beta, None)
    };
    drop(shifted_target);
    let mut predicted = predict(s, &cols, &beta);
    if let Some(o) = &known {
        add_offset(&mut predicted, o);
    }
    add_known_mass(model, s, &mut predicted);
    let (predicted, residual) = if kind == PassKind::Final {
        let residual: Vec<[f64; 6]> = s
            .target()
            .iter()
            .zip(&predicted)
            .map(|(b, p)| std::array::from_fn(|c| b[c] - p[c]))
            .collect();
        (predicted, residual)
    } else {
        // The residual in the prediction's place (the same differences).
        let mut residual = predicted;
        for (r, b) in residual.iter_mut().zip(s.target()) {
            *r = std::array::from_fn(|c| b[c] - r[c]);
        }
        (Vec::new(), residual)
    };
    Ok(Pass {
        predicted,
        residual,
        solution,
        names,
    })
}

/// Step 4: the ten rigid-body parameters, their standard errors and their covariance from the
/// solution's first `nr` coefficients (nine with a known mass, which is put back in place).
fn rigid_parameters(
    model: &Model,
    sol: &LsSolution,
    nr: usize,
) -> (InertialParams, [Option<f64>; 10], [[f64; 10]; 10]) {
    let mut theta = [0.0; 10];
    let mut theta_se = [None; 10];
    theta[10 - nr..].copy_from_slice(&sol.beta[..nr]);
    theta_se[10 - nr..].copy_from_slice(&sol.se[..nr]);
    if let Some(m) = model.known_mass() {
        theta[0] = m;
    }
    let p = sol.beta.len();
    let mut cov = [[f64::NAN; 10]; 10];
    for j in 0..nr {
        for k in 0..nr {
            cov[10 - nr + j][10 - nr + k] = sol.cov[j * p + k];
        }
    }
    (InertialParams::from_array(theta), theta_se, cov)
}

/// Step 5: each effect's coefficients (after the first `nr` rigid-body ones), named by its
/// fitted columns (`names`, per effect, from the final pass's design), with the effect's
/// plausibility verdict.
fn fitted_effects(
    model: &Model,
    s: &Signals,
    params: &[Option<f64>],
    names: &[Vec<(String, String)>],
    sol: &LsSolution,
    nr: usize,
) -> Vec<FittedEffect> {
    let mut effects = Vec::new();
    let mut j = nr;
    for (k, e) in model.effects().iter().enumerate() {
        let q = names[k].len();
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
                .and_then(|sp| params[k].map(|v| (sp.name, e.applied(s, v), sp.unit))),
            scanned_interval: None,
            coefficients: names[k]
                .iter()
                .enumerate()
                .map(|(i, (name, unit))| Coefficient::new(name, unit, coef[i], sol.se[j + i]))
                .collect(),
            derived: e.derived(&coef, &se, params[k]),
            plausible: pl.plausible,
            plausibility_note: pl.note,
            limited_by: String::new(),
        });
        j += q;
    }
    effects
}
