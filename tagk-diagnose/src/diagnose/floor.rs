//! The noise floor: the held-out residual below which no model term is worth adding.
//!
//! **Rule.** Per channel, the floor is the larger of
//! - the **reachable residual**: the held-out (blocked CV) residual RMS of the *saturated*
//!   model, the current model plus every usable candidate that is plausible when added alone,
//!   all at once (each scan at its best value), pruned one effect at a time until its fit is
//!   physical (an effect whose own rules fail in the joint fit, or one that collapses the
//!   rigid body's mass by more than [`crate::MAX_MASS_CHANGE`], goes: the one with the
//!   smallest held-out gain alone first). No
//!   sequence of candidates can do better on held-out data, so the distance from a model to it
//!   is what the candidates can still explain; on a log whose only imperfection is
//!   measurement noise it is the noise;
//! - the **noise**: the high-frequency estimate below — held-out data cannot be predicted
//!   better than their white noise; a saturated model that seems to (a lag whose fixed gain
//!   smooths the measured wrench's own noise) does not lower the floor;
//! - the **resolution**: 10⁻⁴ of the RMS of the measured force magnitude (forces), times the
//!   airframe radius (torques) — below that no effect matters to a flight-dynamics model, and a
//!   noise-free simulator log would otherwise chase rounding.
//!
//! When no candidate is plausible, the reachable residual is the model's own and the
//! high-frequency noise estimate below takes its place. Or, when the user gives the sensor
//! noise per channel ([`crate::DiagnoseOptions::noise_floor`]),
//! that value. The **high-frequency noise estimate** is taken on the residual of the
//! saturated model without a lag (a lag filters the measured wrench, noise included), by first
//! differences: `σ² ≈ mean((r_{i+1} − r_i)²) / 2`, exact for white noise; a floor well above
//! it says something that no candidate explains remains in the data.

use serde::Serialize;

use crate::diagnose::{Candidate, DiagnoseOptions};
use crate::effects::EffectRef;
use crate::error::DiagnoseError;
use crate::fit::{
    ColData, Column, Evaluation, Fit, GramEngine, Model, effect_design, fit_residual_only,
    rigid_design,
};
use crate::signals::Signals;
use tagk_dynamics::EffectKind;

/// Resolution of the floor, relative to the RMS measured force magnitude (10⁻⁴).
pub const FLOOR_RESOLUTION: f64 = 1e-4;

/// Where the floor came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FloorSource {
    /// The data: the saturated model's held-out residual (or the resolution).
    Data,
    /// The user's per-channel noise level.
    Given,
}

/// The noise floor of a log.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseFloor {
    /// Floor per channel (N, N m): held-out residual RMS below which nothing is added.
    pub rms: [f64; 6],
    /// Where it came from.
    pub source: FloorSource,
    /// Held-out residual RMS of the saturated model per channel (the reachable residual).
    pub reachable: [f64; 6],
    /// High-frequency (first-difference) noise estimate of the saturated residual per channel.
    pub noise_estimate: [f64; 6],
    /// Effects of the saturated model.
    pub saturated_model: Vec<String>,
}

/// Held-out residual RMS per channel (unweighted) of an evaluation with channel weights `w`
/// on `n` samples: every sample is held out once by the blocked cross-validation.
pub(crate) fn held_out_rms(ev: &Evaluation, w: &[f64; 6], n: usize) -> [f64; 6] {
    std::array::from_fn(|c| {
        if w[c] > 0.0 && n > 0 {
            (ev.sse_cv_ch[c] / n as f64).sqrt() / w[c]
        } else {
            0.0
        }
    })
}

/// The design of a fitted model (rigid columns, then each effect's fitted columns at its
/// fitted parameter; the fixed columns are already in the fit's residual).
pub(crate) fn model_design(model: &Model, s: &Signals, fit: &Fit) -> ModelDesign {
    let (rigid, _) = rigid_design(model, s);
    let mut effects = Vec::new();
    for (k, e) in model.effects().iter().enumerate() {
        effects.extend(effect_design(e.as_ref(), s, fit.params[k]).cols);
    }
    ModelDesign { rigid, effects }
}

/// The design of a fitted model ([`model_design`]): the rigid-body columns (computed where
/// they are read) and the effects' stored columns.
pub(crate) struct ModelDesign {
    rigid: Vec<Column<'static>>,
    effects: Vec<ColData>,
}

impl ModelDesign {
    /// Every column, rigid body first.
    pub fn columns(&self) -> Vec<Column<'_>> {
        self.rigid
            .iter()
            .copied()
            .chain(Column::stored(&self.effects))
            .collect()
    }
}

/// The held-out evaluation of a fitted model: its columns against its own residual, so the
/// training folds refit every coefficient.
pub(crate) fn held_out_evaluation(
    model: &Model,
    s: &Signals,
    fit: &Fit,
    folds: usize,
) -> Evaluation {
    let design = model_design(model, s, fit);
    GramEngine::new(
        s,
        &fit.weights,
        &design.columns(),
        Some(&fit.residual),
        folds,
    )
    .evaluate(&[])
}

/// The candidates that can join `model` on this log: those not in it, scored alone on this
/// log (`alone`, from [`crate::diagnose::ranking::score_candidates`], which scores only the
/// candidates usable here: [`crate::effects::usable`]) and plausible there, each with its
/// score.
fn joinable<'a>(
    model: &Model,
    candidates: &'a [EffectRef],
    alone: &'a [Candidate],
) -> Vec<(&'a EffectRef, &'a Candidate)> {
    candidates
        .iter()
        .filter(|c| !model.has(c.name()))
        .filter(|c| !(c.needs_known_mass() && model.known_mass().is_none()))
        .filter_map(|e| {
            alone
                .iter()
                .find(|c| c.effect == e.name() && c.plausible)
                .map(|c| (e, c))
        })
        .collect()
}

/// The saturated model and its fit: the model plus, per effect family not yet in it
/// ([`EffectKind::family`]), the joinable candidate with the largest held-out gain among those
/// plausible when added alone, pruned until the joint fit is physical — one effect per round, the one
/// whose own rules fail in the joint fit (or, if none fails but the rigid body does, mass off
/// by more than [`crate::MAX_MASS_CHANGE`] or not positive, any) with the smallest held-out gain
/// alone. With nothing left, the model itself (and `None` for its fit: `start_fit`). The
/// saturated fit's prediction is not kept (the floor reads its residual).
fn saturated_fit(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    start_fit: &Fit,
    alone: &[Candidate],
) -> Result<(Model, Option<Fit>), DiagnoseError> {
    let gain_alone = |name: &str| {
        alone
            .iter()
            .find(|c| c.effect == name)
            .map_or(f64::NEG_INFINITY, |c| c.reduction)
    };
    // One member per family (the best alone): members of one family are near collinear
    // (the drag laws) or alike to first order (a lag and a delay), and fitted together they
    // split one physical effect between them. A wind includes its drag.
    let mut best: std::collections::BTreeMap<String, (f64, EffectRef)> = Default::default();
    for (e, c) in joinable(model, &opts.candidates, alone) {
        let family = EffectKind::from_name(e.name())
            .map_or_else(|| e.name().to_string(), |k| k.family().to_string());
        if best.get(&family).is_none_or(|(r, _)| c.reduction > *r) {
            best.insert(family, (c.reduction, e.clone()));
        }
    }
    if best.contains_key(EffectKind::Wind.family()) {
        best.remove(EffectKind::LinearDrag.family());
    }
    for e in model.effects() {
        if let Some(k) = EffectKind::from_name(e.name()) {
            best.remove(k.family());
            if k.includes_drag() {
                best.remove(EffectKind::LinearDrag.family());
            }
        }
    }
    let mut set: Vec<EffectRef> = best.into_values().map(|(_, e)| e).collect();
    let m0 = start_fit.theta.mass();
    while !set.is_empty() {
        let mut saturated = model.clone();
        for e in &set {
            saturated = saturated.with_ref(e.clone());
        }
        let fit = fit_residual_only(&saturated, s, None)?;
        let bad: Vec<&str> = fit
            .effects
            .iter()
            .filter(|f| !f.plausible && !model.has(&f.effect))
            .map(|f| f.effect.as_str())
            .collect();
        let m1 = fit.theta.mass();
        let mass_ok = crate::diagnose::sanity::mass_kept(m0, m1);
        if bad.is_empty() && mass_ok {
            return Ok((saturated, Some(fit)));
        }
        let pool: Vec<&str> = if bad.is_empty() {
            set.iter().map(|e| e.name()).collect()
        } else {
            bad
        };
        let Some(drop) = pool
            .iter()
            .copied()
            .min_by(|a, b| gain_alone(a).total_cmp(&gain_alone(b)))
            .map(str::to_string)
        else {
            break;
        };
        set.retain(|e| e.name() != drop);
    }
    Ok((model.clone(), None))
}

/// The noise floor of a log for `model` and the candidates of `opts` (rule in the module
/// docs).
///
/// # Errors
/// As [`crate::fit_model`] on the saturated model (an invalid model or a failed solve).
pub(crate) fn noise_floor(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    start_fit: &Fit,
    alone: &[Candidate],
    known_noise: Option<[f64; 6]>,
) -> Result<NoiseFloor, DiagnoseError> {
    let (saturated, saturated_fit) = saturated_fit(model, s, opts, start_fit, alone)?;
    let fit = saturated_fit.as_ref().unwrap_or(start_fit);
    let ev = held_out_evaluation(&saturated, s, fit, opts.folds);
    let reachable = held_out_rms(&ev, &fit.weights, s.len());
    // The noise is measured on a residual whose target is the measured wrench itself: a lag
    // (a fixed column: the target becomes the lagged wrench) filters the target, which also
    // averages the wrench's measurement noise away.
    let noise_estimate = match known_noise {
        // Measured already (the noise does not change with the model).
        Some(n) => n,
        None => unfiltered_noise(model, s, &saturated, fit)?,
    };
    let force_rms = (s
        .wrench()
        .iter()
        .map(|b| b[0] * b[0] + b[1] * b[1] + b[2] * b[2])
        .sum::<f64>()
        / s.len().max(1) as f64)
        .sqrt();
    let resolution = |c: usize| {
        if c < 3 {
            FLOOR_RESOLUTION * force_rms
        } else {
            FLOOR_RESOLUTION * force_rms * opts.airframe_radius
        }
    };
    let (rms, source) = match opts.noise_floor {
        Some(given) => (given, FloorSource::Given),
        // Without a plausible candidate there is nothing to reach: the floor is the
        // measurement noise itself (the high-frequency estimate).
        None if saturated.effects().len() == model.effects().len() => (
            std::array::from_fn(|c| noise_estimate[c].max(resolution(c))),
            FloorSource::Data,
        ),
        None => {
            // Where the saturated model does no better than the model itself, nothing is
            // reachable on that channel: its floor is the noise alone.
            let start_ev = held_out_evaluation(model, s, start_fit, opts.folds);
            let start = held_out_rms(&start_ev, &start_fit.weights, s.len());
            (
                std::array::from_fn(|c| {
                    let reach = if reachable[c] < start[c] {
                        reachable[c]
                    } else {
                        0.0
                    };
                    reach.max(noise_estimate[c]).max(resolution(c))
                }),
                FloorSource::Data,
            )
        }
    };
    Ok(NoiseFloor {
        rms,
        source,
        reachable,
        noise_estimate,
        saturated_model: saturated
            .effects()
            .iter()
            .map(|e| e.name().to_string())
            .collect(),
    })
}

/// The high-frequency noise estimate per channel (module docs): first differences of the
/// residual of the saturated model without a lag.
fn unfiltered_noise(
    model: &Model,
    s: &Signals,
    saturated: &Model,
    fit: &Fit,
) -> Result<[f64; 6], DiagnoseError> {
    let filters = |e: &EffectRef| EffectKind::from_name(e.name()) == Some(EffectKind::MotorLag);
    let unfiltered_fit;
    let noise_fit = if saturated.effects().iter().any(filters) {
        let mut plain = Model::rigid_body();
        if let Some(m) = model.known_mass() {
            plain = plain.with_known_mass(m);
        }
        for e in saturated.effects().iter().filter(|e| !filters(e)) {
            plain = plain.with_ref(e.clone());
        }
        // The saturated fit's weights: one pass.
        unfiltered_fit = fit_residual_only(&plain, s, Some(fit.weights))?;
        &unfiltered_fit
    } else {
        fit
    };
    Ok(std::array::from_fn(|c| {
        let r = &noise_fit.residual;
        if r.len() < 2 {
            return 0.0;
        }
        let d2: f64 = r.windows(2).map(|w| (w[1][c] - w[0][c]).powi(2)).sum();
        (d2 / (2.0 * (r.len() - 1) as f64)).sqrt()
    }))
}
