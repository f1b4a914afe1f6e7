//! The diagnosis workflow: compare, where it fails, what is missing, step by step.
//!
//! [`diagnose`] runs four named steps: fit the model ([`crate::fit_model`]), rank the missing
//! candidates against the noise floor ([`ranking`], [`floor`]) and the physical rules
//! ([`sanity`]), find where the model fails ([`residual`]), judge the parameters
//! ([`parameters`]); then it states a verdict. [`discover`] repeats it: rigid body → + the
//! recommended effect → … until the model is at the noise floor or nothing qualifies.

mod floor;
mod parameters;
mod ranking;
mod residual;
mod sanity;
mod stepwise;

use std::sync::Arc;

use serde::Serialize;
use tagk_dynamics::SafetyGate;

use crate::effects::{EffectRef, builtin_effects, scan_problem};
use crate::error::DiagnoseError;
use crate::fit::{ChannelFit, Fit, FittedEffect, Model, fit_model};
use crate::signals::Signals;

pub use floor::{FLOOR_RESOLUTION, FloorSource, NoiseFloor};
pub use parameters::Parameter;
pub use ranking::{
    Candidate, CandidateStatus, FLOOR_MARGIN, MAX_CHANNEL_WORSENING, MIN_GAIN_OF_FLOOR, Unavailable,
};
pub use residual::{FailureWindow, RegimeStat, Whiteness};
pub use sanity::{MAX_CONSTANT_FORCE_OF_THRUST, MAX_MASS_CHANGE};
pub use stepwise::{Discovery, Step, StepChannel, discover, discover_from};

/// Settings of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Blocks of the blocked cross-validation over time (default 5).
    pub folds: usize,
    /// Family-wise significance level of the candidate tests (Bonferroni over the
    /// candidates; default 0.01).
    pub alpha: f64,
    /// Smallest held-out residual reduction (fraction of the channel-normalised held-out SSE)
    /// worth recommending (default 0.02).
    pub min_reduction: f64,
    /// Radius of the airframe \[m\]: a fitted centre of mass significantly farther from the
    /// origin is flagged as evidence of an unmodelled force (default: the Crazyflie's
    /// `L_arm` = 0.0325 m).
    pub airframe_radius: f64,
    /// Candidate effects to rank (default: every built-in).
    pub candidates: Vec<EffectRef>,
    /// Measurement noise per channel (N, N m), e.g. from the sensors' specification: the
    /// noise floor of the stepwise search. `None` (default): the floor comes from the data
    /// ([`NoiseFloor`]).
    pub noise_floor: Option<[f64; 6]>,
    /// Most effects [`discover`] adds (default 5).
    pub max_steps: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            alpha: 0.01,
            min_reduction: 0.02,
            airframe_radius: SafetyGate::crazyflie().max_com_offset,
            candidates: builtin_effects(),
            noise_floor: None,
            max_steps: 5,
        }
    }
}

impl DiagnoseOptions {
    /// Checks every field: `folds ≥ 2`, `alpha` in `(0, 1)`, `min_reduction` finite and below
    /// 1, `airframe_radius` positive and finite, and a non-empty list of candidates with
    /// unique names and usable scan grids. [`diagnose`] runs this first (and also needs
    /// `folds ≤ samples / 4`).
    ///
    /// # Errors
    /// [`DiagnoseError::InvalidOption`] naming the first bad field.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let bad = |field: &'static str, reason: String| {
            Err(DiagnoseError::InvalidOption { field, reason })
        };
        if self.folds < 2 {
            return bad(
                "folds",
                format!(
                    "{} block(s): the blocked cross-validation needs at least 2",
                    self.folds
                ),
            );
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return bad("alpha", format!("{} is not in (0, 1)", self.alpha));
        }
        if !(self.min_reduction.is_finite() && self.min_reduction < 1.0) {
            return bad(
                "min_reduction",
                format!("{} is not a finite fraction below 1", self.min_reduction),
            );
        }
        if !(self.airframe_radius.is_finite() && self.airframe_radius > 0.0) {
            return bad(
                "airframe_radius",
                format!("{} m is not positive and finite", self.airframe_radius),
            );
        }
        if self.candidates.is_empty() {
            return bad("candidates", "no candidate effect to rank".into());
        }
        if let Some(f) = self.noise_floor
            && f.iter().any(|x| !(x.is_finite() && *x > 0.0))
        {
            return bad(
                "noise_floor",
                format!("{f:?}: every channel's noise level must be positive and finite"),
            );
        }
        for (k, e) in self.candidates.iter().enumerate() {
            if self.candidates[..k].iter().any(|f| f.name() == e.name()) {
                return bad("candidates", format!("effect `{}` listed twice", e.name()));
            }
            if let Some(problem) = scan_problem(e.as_ref()) {
                return bad("candidates", problem);
            }
        }
        Ok(())
    }

    /// [`Self::validate`] plus the checks that need the log's length: every one of the
    /// `folds` blocks must hold at least 4 samples.
    fn validate_for(&self, samples: usize) -> Result<(), DiagnoseError> {
        self.validate()?;
        if self.folds > samples / 4 {
            return Err(DiagnoseError::InvalidOption {
                field: "folds",
                reason: format!(
                    "{} blocks for {samples} samples: at most {} (4 samples per block)",
                    self.folds,
                    samples / 4
                ),
            });
        }
        Ok(())
    }
}

/// Everything the diagnosis of one model on one log found.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Model label.
    pub model: String,
    /// Samples.
    pub samples: usize,
    /// Duration \[s\].
    pub duration: f64,
    /// `true` if accelerations were derived by the Savitzky–Golay differentiator.
    pub derived_accelerations: bool,
    /// Per-channel fit.
    pub channels: Vec<ChannelFit>,
    /// Held-out (blocked CV) residual RMS per channel (N, N m).
    pub held_out_rms: [f64; 6],
    /// The noise floor the candidates were judged against.
    pub noise_floor: NoiseFloor,
    /// `true` when every channel's held-out RMS is within [`FLOOR_MARGIN`] of the floor.
    pub at_floor: bool,
    /// Rigid-body parameter estimates (order of `tagk_dynamics::InertialParams`) with
    /// standard errors.
    pub parameters: Vec<Parameter>,
    /// Centre of mass `h / m` \[m\].
    pub com: [f64; 3],
    /// Pseudo-inertia positive definite (Wensing et al.).
    pub physically_consistent: bool,
    /// Safety gate verdict (`pass` or the violation).
    pub safety_gate: String,
    /// Fitted effects of the model.
    pub effects: Vec<FittedEffect>,
    /// Implausible estimates and what they suggest.
    pub warnings: Vec<String>,
    /// Residual whiteness per channel.
    pub whiteness: Vec<Whiteness>,
    /// Windows of significantly large residual.
    pub failure_windows: Vec<FailureWindow>,
    /// Residual statistics by regime.
    pub regimes: Vec<RegimeStat>,
    /// Plain-language findings ("the fx/fy residual grows with body-frame speed").
    pub findings: Vec<String>,
    /// Candidate effects, best first.
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The recommended effect, or `None` when the model is adequate.
    pub recommended: Option<String>,
    /// One-line verdict.
    pub verdict: String,
    /// The underlying fit (residual and prediction series, for plots). Shared: a clone of
    /// a diagnosis (the report keeps several) does not copy a long log's series.
    #[serde(skip)]
    pub fit: Arc<Fit>,
    /// Time stamps \[s\] (for plots; shared like [`Diagnosis::fit`]).
    #[serde(skip)]
    pub t: Arc<Vec<f64>>,
    /// Measured wrench (for plots; shared like [`Diagnosis::fit`]).
    #[serde(skip)]
    pub measured: Arc<Vec<[f64; 6]>>,
    /// Top candidate's driver signal (for plots).
    #[serde(skip)]
    pub top_driver: Option<(String, Vec<f64>)>,
    /// The top candidate's partial residuals (for plots), one per channel it acts on.
    #[serde(skip)]
    pub partial_residuals: Vec<PartialResidual>,
}

/// The residual of a model against one regressor column of a candidate on one channel (the
/// partial-residual plot): where the candidate is missing, the points line up along the
/// column with its coefficient as slope. Every `k`-th sample, at most
/// [`crate::html`]'s plot size.
#[derive(Debug, Clone)]
pub struct PartialResidual {
    /// The candidate effect.
    pub effect: String,
    /// The channel (index into [`crate::CHANNEL_NAMES`]).
    pub channel: usize,
    /// The column's coefficient name.
    pub column: String,
    /// The column's values (external wrench per unit coefficient).
    pub x: Vec<f64>,
    /// The model's residual on the channel at the same samples.
    pub y: Vec<f64>,
}

/// The top candidate's [`PartialResidual`]s: on each channel, its first column there (start-of-log
/// nuisance columns left out), at the scanned parameter of its ranking.
fn partial_residuals(
    s: &Signals,
    opts: &DiagnoseOptions,
    ranking: &[Candidate],
    fit: &Fit,
) -> Vec<PartialResidual> {
    let Some(top) = ranking.first() else {
        return Vec::new();
    };
    let Some(effect) = opts.candidates.iter().find(|e| e.name() == top.effect) else {
        return Vec::new();
    };
    let columns =
        crate::effects::effect_columns(effect.as_ref(), s, top.scanned.as_ref().map(|p| p.1));
    let step = s.len().div_ceil(crate::html::MAX_POINTS).max(1);
    (0..6)
        .filter_map(|c| {
            let column = columns
                .iter()
                .find(|col| col.data[c].is_some() && !col.name.starts_with("start_"))?;
            let x = column.data[c].as_ref()?;
            Some(PartialResidual {
                effect: top.effect.clone(),
                channel: c,
                column: column.name.clone(),
                x: x.iter().step_by(step).copied().collect(),
                y: fit.residual.iter().step_by(step).map(|r| r[c]).collect(),
            })
        })
        .collect()
}

/// Diagnoses `model` on a log: fit and compare, where it fails, and the ranking of the
/// candidate effects not already in the model against the log's noise floor.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] if `opts` does not validate
/// ([`DiagnoseOptions::validate`]); as [`fit_model`]: an invalid model, an effect of `model`
/// that cannot be used on this log, a failed solve.
pub fn diagnose(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    opts.validate_for(s.len())?;
    let fit = fit_model(model, s, None)?;
    let scored = ranking::score_candidates(model, s, &fit, opts);
    let floor = floor::noise_floor(model, s, opts, &fit, &scored.ranking, None)?;
    let missing = ranking::judge_scored(scored, s, &floor, opts);
    assemble(model, s, opts, &floor, Arc::new(fit), missing)
}

/// [`diagnose`] against a given noise floor (options already validated).
pub(crate) fn diagnose_against(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
) -> Result<Diagnosis, DiagnoseError> {
    let fit = fit_model(model, s, None)?;
    let missing = ranking::rank_candidates(model, s, &fit, opts, floor);
    assemble(model, s, opts, floor, Arc::new(fit), missing)
}

/// [`diagnose_against`] with the model's fit already at hand (a new floor, the same fit).
pub(crate) fn diagnose_with_fit(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    fit: Arc<Fit>,
) -> Result<Diagnosis, DiagnoseError> {
    let missing = ranking::rank_candidates(model, s, &fit, opts, floor);
    assemble(model, s, opts, floor, fit, missing)
}

/// The diagnosis from a model's fit and its judged ranking: where it fails, the parameters,
/// the verdict.
fn assemble(
    _model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    fit: Arc<Fit>,
    missing: ranking::Ranking,
) -> Result<Diagnosis, DiagnoseError> {
    let failures = residual::where_it_fails(s, &fit);
    let params =
        parameters::parameter_report(&fit, opts.airframe_radius, missing.recommended.as_deref());
    let verdict = verdict(
        &missing.ranking,
        missing.recommended.as_deref(),
        missing.at_floor,
    );
    let n = s.len();
    let partial_residuals = partial_residuals(s, opts, &missing.ranking, &fit);
    Ok(Diagnosis {
        model: fit.label.clone(),
        samples: n,
        duration: s.t[n - 1] - s.t[0],
        derived_accelerations: s.derived_accel,
        channels: fit.channels.clone(),
        held_out_rms: missing.held_out_rms,
        noise_floor: floor.clone(),
        at_floor: missing.at_floor,
        parameters: params.parameters,
        com: params.com,
        physically_consistent: params.physically_consistent,
        safety_gate: params.safety_gate,
        effects: fit.effects.clone(),
        warnings: params.warnings,
        whiteness: failures.whiteness,
        failure_windows: failures.failure_windows,
        regimes: failures.regimes,
        findings: failures.findings,
        ranking: missing.ranking,
        unavailable: missing.unavailable,
        recommended: missing.recommended,
        verdict,
        fit,
        t: Arc::new(s.t.clone()),
        measured: Arc::new(s.wrench().to_vec()),
        top_driver: missing.top_driver,
        partial_residuals,
    })
}

/// The one-line verdict: the missing effect and its held-out gain, or why nothing is
/// missing (at the noise floor, or no candidate qualifies).
fn verdict(ranking: &[Candidate], recommended: Option<&str>, at_floor: bool) -> String {
    match recommended {
        Some(r) => {
            let c = ranking.iter().find(|c| c.effect == r);
            format!(
                "missing physics: `{r}` (held-out residual {:+.0} %)",
                c.map_or(0.0, |c| -c.reduction * 100.0)
            )
        }
        None if at_floor => {
            "model adequate: the held-out residual is at the noise floor on every channel".into()
        }
        None => match ranking.first() {
            Some(best) => format!(
                "no candidate qualifies (best: `{}`, {}); what remains is not explained by a built-in effect",
                best.effect,
                best.explanation.rsplit("; ").next().unwrap_or("")
            ),
            None => "model adequate: no candidate left to try".into(),
        },
    }
}
