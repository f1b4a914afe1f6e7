//! The diagnosis workflow: compare, where it fails, what is missing, step by step.
//!
//! [`diagnose`] fits the model ([`crate::fit_model`]), measures the noise of every channel
//! ([`noise`]), searches the candidate effects and sets of them on held-out data in units of
//! that noise ([`select`]) against the physical rules ([`sanity`]), finds where the model fails
//! ([`residual`]), judges the parameters ([`parameters`]) and says whether the model is
//! adequate: what remains is the noise. [`discover`] repeats it: rigid body → + the chosen
//! effects → … until no set is admissible.

mod inputs;
mod noise;
mod parameters;
mod ranking;
mod residual;
mod sanity;
mod select;
mod stepwise;

use std::sync::Arc;

use serde::Serialize;
use tagk_dynamics::SafetyGate;

use crate::effects::{EffectRef, builtin_effects, scan_problem};
use crate::error::DiagnoseError;
use crate::fit::{ChannelFit, Fit, FittedEffect, Model, fit_model, is_start_nuisance};
use crate::signals::{CHANNEL_NAMES, Signals};
use crate::stats;

pub use inputs::{
    INPUT_CORRELATION_LAGS, InputCorrelation, ResidualInput, Z_99, input_correlation,
    input_correlation_lags, residual_inputs,
};
pub use noise::{FLOOR_RESOLUTION, FloorSource, NoiseFloor};
pub use parameters::Parameter;
pub use ranking::{Candidate, CandidateStatus, Unavailable};
pub use residual::{FailureWindow, RegimeStat, Whiteness, residual_autocorrelation};
pub use sanity::{
    CONSISTENCY_TOLERANCE, INCONSISTENCY_STANDARD_ERRORS, MAX_CONSTANT_FORCE_OF_THRUST,
    MAX_MASS_CHANGE, MAX_MASS_FROM_VEHICLE, consistency_margin, consistent_within_tolerance,
    second_moment_eigen,
};
pub use select::{MAX_INFLATION, MIN_GAIN};
pub use stepwise::{Discovery, Equivalent, Step, StepChannel, discover, discover_from};

pub(crate) use noise::noise_floor;
pub(crate) use select::Context;
pub(crate) use select::chance_margin;

/// A channel is adequate when its held-out residual RMS is within this factor of its noise
/// (1.2) and its residual is white ([`ADEQUATE_AUTOCORRELATION`]).
pub const ADEQUACY_FACTOR: f64 = 1.2;

/// Whiteness of an adequate channel's residual: the sum of its squared autocorrelations at lags
/// 1 to 20, `Σ ρ_k²`, at most the larger of a Ljung–Box bound (see [`WHITENESS_FALSE_ALARM`])
/// and this effect size. The effect size is 0.02: one lag correlated by 0.14, a model error of
/// about a seventh of the noise variance. A long log's tiny correlations are not a missing
/// effect.
pub const ADEQUATE_AUTOCORRELATION: f64 = 0.02;

/// How often white noise fails the whiteness test on one log, over all six channels together
/// (0.001). The verdict "adequate" is one claim about six channels. So each channel's
/// Ljung–Box bound is `χ²_K(1 − 0.001/6) / n` (Bonferroni), as the candidate tests share
/// their `alpha`.
pub const WHITENESS_FALSE_ALARM: f64 = 1e-3;

/// The largest `Σ ρ_k²` of an adequate channel's residual of `n` samples (lags
/// `1..=min(20, n/4)`, [`residual_autocorrelation`]): the Ljung–Box bound
/// `χ²_K(1 − WHITENESS_FALSE_ALARM/6) / n` for `K` lags, at least
/// [`ADEQUATE_AUTOCORRELATION`] (dimensionless).
pub fn whiteness_limit(n: usize) -> f64 {
    let max_lag = residual::whiteness_lags(n);
    let per_channel = WHITENESS_FALSE_ALARM / CHANNEL_NAMES.len() as f64;
    (stats::chi2_quantile(per_channel, max_lag as f64) / n.max(1) as f64)
        .max(ADEQUATE_AUTOCORRELATION)
}

/// Settings of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Blocks of the blocked cross-validation over time (default 5).
    pub folds: usize,
    /// Family-wise significance level of the candidate tests (Bonferroni over the
    /// candidates; default 0.01).
    pub alpha: f64,
    /// Radius of the airframe \[m\]: a fitted centre of mass significantly farther from the
    /// body's z axis is flagged as evidence of an unmodelled force (default: the Crazyflie's
    /// `L_arm` = 0.0325 m).
    pub airframe_radius: f64,
    /// Largest distance of the centre of mass from the rotor plane \[m\] (default: half the
    /// airframe radius, 0.016 m for the Crazyflie: its battery hangs just below the rotors).
    pub com_vertical_limit: f64,
    /// Height of the rotor plane above the body origin, body z \[m\] (default 0: the origin
    /// in the rotor plane, as in the Crazyflie's vehicle file).
    pub rotor_plane_height: f64,
    /// The vehicle file's mass \[kg\], if given: the report says when the fitted mass is
    /// more than [`MAX_MASS_FROM_VEHICLE`] off it.
    pub vehicle_mass: Option<f64>,
    /// Candidate effects to rank (default: every built-in).
    pub candidates: Vec<EffectRef>,
    /// Measurement noise per channel (N, N m), e.g. from the sensors' specification: the
    /// yardstick of every decision. `None` (default): measured from the data ([`NoiseFloor`]).
    pub noise_floor: Option<[f64; 6]>,
    /// Most effects [`discover`] adds (default 5).
    pub max_steps: usize,
    /// Told before each candidate or set of candidates the search judges (default: nobody).
    /// For a progress display; the diagnosis is the same without it.
    pub progress: ProgressHook,
}

/// Where the search for missing effects is: what [`ProgressHook`] is told.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SearchProgress<'a> {
    /// Effects in the model the search starts from (0: the rigid body).
    pub effects: usize,
    /// What is judged now: a candidate's name, or `pairs` and `triples` for the sets.
    pub judging: &'a str,
    /// Judged so far at this stage (candidates alone, then the pairs, then the triples).
    pub done: usize,
    /// To judge at this stage.
    pub total: usize,
}

/// A function told where the search is ([`SearchProgress`]), e.g. to move a progress bar.
///
/// It is called on the thread that runs the diagnosis. The default tells nobody.
#[derive(Clone, Default)]
pub struct ProgressHook(Option<Arc<ProgressFn>>);

/// The function of a [`ProgressHook`].
type ProgressFn = dyn Fn(&SearchProgress<'_>) + Send + Sync;

impl ProgressHook {
    /// A hook that calls `f` at each step of the search.
    pub fn new(f: impl Fn(&SearchProgress<'_>) + Send + Sync + 'static) -> Self {
        Self(Some(Arc::new(f)))
    }

    /// Tells the function, if there is one.
    pub(crate) fn report(&self, progress: &SearchProgress<'_>) {
        if let Some(f) = &self.0 {
            f(progress);
        }
    }
}

impl std::fmt::Debug for ProgressHook {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let state = if self.0.is_some() { "set" } else { "none" };
        write!(f, "ProgressHook({state})")
    }
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            alpha: 0.01,
            airframe_radius: SafetyGate::crazyflie().max_com_offset,
            com_vertical_limit: 0.5 * SafetyGate::crazyflie().max_com_offset,
            rotor_plane_height: 0.0,
            vehicle_mass: None,
            candidates: builtin_effects(),
            noise_floor: None,
            max_steps: 5,
            progress: ProgressHook::default(),
        }
    }
}

impl DiagnoseOptions {
    /// Checks every field: `folds ≥ 2`, `alpha` in `(0, 1)`, `airframe_radius` and
    /// `com_vertical_limit` positive and finite, `rotor_plane_height` finite, a vehicle mass
    /// positive and finite, and a non-empty list of candidates with
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
        if !(self.airframe_radius.is_finite() && self.airframe_radius > 0.0) {
            return bad(
                "airframe_radius",
                format!("{} m is not positive and finite", self.airframe_radius),
            );
        }
        if !(self.com_vertical_limit.is_finite() && self.com_vertical_limit > 0.0) {
            return bad(
                "com_vertical_limit",
                format!("{} m is not positive and finite", self.com_vertical_limit),
            );
        }
        if !self.rotor_plane_height.is_finite() {
            return bad(
                "rotor_plane_height",
                format!("{} m is not finite", self.rotor_plane_height),
            );
        }
        if let Some(m) = self.vehicle_mass
            && !(m.is_finite() && m > 0.0)
        {
            return bad("vehicle_mass", format!("{m} kg is not positive and finite"));
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

    /// These options with a vehicle's airframe: its airframe radius, the height of its rotor
    /// plane (the mean height of its hubs), a vertical limit of the centre of mass of half the
    /// airframe radius, and its mass prior (reported against the fit).
    pub fn with_vehicle(self, vehicle: &tagk_dynamics::vehicle::Vehicle) -> Self {
        let plane = vehicle.rotors.iter().map(|r| r.position.z).sum::<f64>()
            / vehicle.rotors.len().max(1) as f64;
        Self {
            airframe_radius: vehicle.airframe_radius,
            com_vertical_limit: 0.5 * vehicle.airframe_radius,
            rotor_plane_height: plane,
            vehicle_mass: vehicle.mass,
            ..self
        }
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
    /// The noise the candidates were judged against.
    pub noise_floor: NoiseFloor,
    /// `true` when the model is adequate: every channel's held-out residual within
    /// [`ADEQUACY_FACTOR`] of its noise and white ([`ChannelAdequacy`]).
    pub adequate: bool,
    /// Per channel: how far the held-out residual is from the noise, and whether it is white.
    pub adequacy: Vec<ChannelAdequacy>,
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
    /// Plain-language findings ("the fx/fy residual grows with body-frame speed"): none on
    /// the channels whose held-out residual is within [`ADEQUACY_FACTOR`] of their noise.
    pub findings: Vec<String>,
    /// Cross-correlation of each channel's residual (whitened, as [`Diagnosis::whiteness`])
    /// with each actual input, against its 99 % band ([`input_correlation`]), channel-major.
    pub input_correlation: Vec<InputCorrelation>,
    /// Candidate effects, best first.
    pub ranking: Vec<Candidate>,
    /// Candidates that could not be evaluated.
    pub unavailable: Vec<Unavailable>,
    /// The first effect of the recommended set (`None`: no admissible set).
    pub recommended: Option<String>,
    /// The set of effects the search adds next, in staircase order (empty: none admissible).
    pub recommended_set: Vec<String>,
    /// Effects the data cannot tell apart, with what to fly to separate them.
    pub confounded: Vec<Confounding>,
    /// Other sets of effects that explain the data as well as the recommended one.
    pub alternatives: Vec<Vec<String>>,
    /// One-line verdict.
    pub verdict: String,
    /// The underlying fit (residual and prediction series, for plots). Shared: a clone of
    /// a diagnosis (the report keeps several) does not copy a long log's series. Its effects
    /// are the plain fit's: [`Diagnosis::effects`] adds the intervals and what limits them.
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
                .find(|col| col.data[c].is_some() && !is_start_nuisance(&col.name))?;
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

/// One channel's distance from its noise: the adequacy test of [`Diagnosis::adequacy`].
#[derive(Debug, Clone, Serialize)]
pub struct ChannelAdequacy {
    /// Channel (`fx` … `tz`).
    pub channel: String,
    /// Held-out residual RMS (N, N m).
    pub held_out_rms: f64,
    /// The channel's noise (N, N m).
    pub noise: f64,
    /// `held_out_rms / noise`.
    pub ratio: f64,
    /// `Σ ρ_k²` of the residual's autocorrelation at lags 1–20.
    pub autocorrelation_sum: f64,
    /// The largest `Σ ρ_k²` of a white residual ([`ADEQUATE_AUTOCORRELATION`]).
    pub autocorrelation_limit: f64,
    /// The channel passes: below its resolution, or within [`ADEQUACY_FACTOR`] of its noise
    /// and white.
    pub adequate: bool,
    /// The sensor quantity that limits the channel ([`NoiseFloor::limited_by`]).
    pub limited_by: String,
}

/// Two effects the data cannot tell apart.
#[derive(Debug, Clone, Serialize)]
pub struct Confounding {
    /// The two effects (or an effect and `rigid body`).
    pub effects: [String; 2],
    /// Variance inflation of the first's coefficients once the second is in the model.
    pub inflation: f64,
    /// What would separate them (`fly a yaw rotation`, …).
    pub advice: String,
}

/// What would separate two confounded effects, in a sentence.
pub(crate) fn separation_advice(a: &str, b: &str) -> String {
    use tagk_dynamics::EffectKind;
    let kinds: Vec<Option<EffectKind>> = [a, b].iter().map(|n| EffectKind::from_name(n)).collect();
    let has = |k: EffectKind| kinds.contains(&Some(k));
    let constant_force = [a, b].contains(&crate::effects::ACCEL_BIAS) || has(EffectKind::BodyBias);
    if has(EffectKind::Wind) && constant_force {
        "a constant body force and a steady wind look alike at constant heading: fly a yaw rotation"
            .into()
    } else if has(EffectKind::MotorLag) && has(EffectKind::TimeDelay) {
        "a lag and a delay look alike for slow commands: fly faster thrust changes".into()
    } else if has(EffectKind::GroundEffect) {
        "fly at several heights, some within a few rotor radii of the ground".into()
    } else if [a, b].contains(&"rigid body") {
        "it trades with the rigid body's parameters on this flight: fly more varied motion, or give the mass (`--mass`)".into()
    } else {
        "fly a more varied trajectory (speeds, accelerations, heading)".into()
    }
}

/// The adequacy test per channel (module docs): the held-out RMS `held_out` against the
/// noise, and the whiteness of the model's whitened in-sample residual of `n` samples (its
/// autocorrelation in `whiteness`, from [`residual::where_it_fails`]).
fn adequacy(
    whiteness: &[Whiteness],
    n: usize,
    held_out: &[f64; 6],
    floor: &NoiseFloor,
) -> Vec<ChannelAdequacy> {
    let limit = whiteness_limit(n);
    (0..6)
        .map(|c| {
            let noise = floor.rms[c];
            let ratio = if noise > 0.0 {
                held_out[c] / noise
            } else {
                f64::INFINITY
            };
            let sum: f64 = whiteness[c].autocorrelation.iter().map(|x| x * x).sum();
            let below_resolution = held_out[c] <= ADEQUACY_FACTOR * floor.resolution[c];
            ChannelAdequacy {
                channel: CHANNEL_NAMES[c].into(),
                held_out_rms: held_out[c],
                noise,
                ratio,
                autocorrelation_sum: sum,
                autocorrelation_limit: limit,
                adequate: below_resolution || (ratio <= ADEQUACY_FACTOR && sum <= limit),
                limited_by: floor.limited_by(c).into(),
            }
        })
        .collect()
}

/// The physical limits of `opts` for `model`.
pub(crate) fn limits_of(model: &Model, opts: &DiagnoseOptions) -> sanity::Limits {
    sanity::Limits {
        airframe_radius: opts.airframe_radius,
        com_vertical: opts.com_vertical_limit,
        rotor_plane: opts.rotor_plane_height,
        known_mass: model.known_mass().is_some(),
    }
}

/// Diagnoses `model` on a log: fit and compare, the noise of every channel, where it fails,
/// and the candidate effects (and sets of them) not already in the model, judged against
/// that noise.
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
    let floor = noise_floor(s, &fit, model, opts.noise_floor, opts.airframe_radius);
    diagnose_with_fit(model, s, opts, &floor, Arc::new(fit), true, None)
}

/// [`diagnose`] against a given noise (options already validated).
pub(crate) fn diagnose_against(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
) -> Result<Diagnosis, DiagnoseError> {
    let fit = fit_model(model, s, None)?;
    diagnose_with_fit(model, s, opts, floor, Arc::new(fit), true, None)
}

/// [`diagnose_against`] with the model's fit at hand; `search`: run the search for the next
/// step (the intermediate models of a step's set do without); `reference`: the rigid body the
/// physical rules judge a refit against (the staircase's starting model's: a model missing an
/// effect can have a mass far off, and a refit that puts it right is not to blame; `None`:
/// the model's own).
pub(crate) fn diagnose_with_fit(
    model: &Model,
    s: &Signals,
    opts: &DiagnoseOptions,
    floor: &NoiseFloor,
    fit: Arc<Fit>,
    search: bool,
    reference: Option<tagk_dynamics::InertialParams>,
) -> Result<Diagnosis, DiagnoseError> {
    let ctx = Context::new(s, model, &fit.params, floor, opts.folds);
    let engine = ctx.engine();
    let limits = limits_of(model, opts);
    // The model itself first (the search reuses its score): its held-out error, where it
    // fails and whether it is adequate.
    let (base, whitened) = ctx.base_with_residual(&engine);
    let held_out_rms = ctx.held_out_rms(&base);
    let at_noise: [bool; 6] =
        std::array::from_fn(|c| held_out_rms[c] <= ADEQUACY_FACTOR * floor.rms[c]);
    let failures = residual::where_it_fails(s, &whitened, &floor.rms, &at_noise);
    let input_correlation = inputs::input_correlation(s, &whitened)?;
    let adequacy = adequacy(&failures.whiteness, whitened.len(), &held_out_rms, floor);
    // Not kept through the search (6 n values).
    drop(whitened);
    let adequate = adequacy.iter().all(|a| a.adequate);
    let missing = if search {
        let found = select::search(&ctx, &engine, opts, &limits, reference.unwrap_or(fit.theta));
        ranking::rank(&ctx, &found, opts)
    } else {
        ranking::Ranking::default()
    };
    // The fit's effects with their intervals and what limits them (the fit itself is shared
    // with the discovery's cache of fits: not copied).
    let intervals = ranking::scanned_intervals(model, s, &fit, floor, opts.folds);
    let mut effects = fit.effects.clone();
    for ((fe, iv), e) in effects.iter_mut().zip(&intervals).zip(model.effects()) {
        fe.scanned_interval = *iv;
        fe.limited_by = floor.limits(&e.channels()).to_string();
    }
    assemble(
        s,
        opts,
        &limits,
        floor,
        fit,
        missing,
        Assessment {
            held_out_rms,
            adequacy,
            adequate,
            failures,
            effects,
            input_correlation,
        },
    )
}

/// What [`diagnose_with_fit`] measured of the model itself: its held-out error, adequacy,
/// where it fails, and its effects with their intervals.
struct Assessment {
    held_out_rms: [f64; 6],
    adequacy: Vec<ChannelAdequacy>,
    adequate: bool,
    failures: residual::FailureAnalysis,
    effects: Vec<FittedEffect>,
    /// The residual–input cross-correlations.
    input_correlation: Vec<InputCorrelation>,
}

/// The diagnosis from a model's fit, its held-out error and its ranking: the parameters
/// (judged against `limits`), the verdict.
fn assemble(
    s: &Signals,
    opts: &DiagnoseOptions,
    limits: &sanity::Limits,
    floor: &NoiseFloor,
    fit: Arc<Fit>,
    missing: ranking::Ranking,
    assessed: Assessment,
) -> Result<Diagnosis, DiagnoseError> {
    let Assessment {
        held_out_rms,
        adequacy,
        adequate,
        failures,
        effects,
        input_correlation,
    } = assessed;
    let params = parameters::parameter_report(
        &fit,
        s,
        opts,
        limits,
        missing.recommended.first().map(String::as_str),
    );
    let verdict = verdict(&missing, &adequacy, adequate);
    let n = s.len();
    let partial_residuals = partial_residuals(s, opts, &missing.ranking, &fit);
    Ok(Diagnosis {
        model: fit.label.clone(),
        samples: n,
        duration: s.t[n - 1] - s.t[0],
        derived_accelerations: s.derived_accel,
        channels: fit.channels.clone(),
        held_out_rms,
        noise_floor: floor.clone(),
        adequate,
        adequacy,
        parameters: params.parameters,
        com: params.com,
        physically_consistent: params.physically_consistent,
        safety_gate: params.safety_gate,
        effects,
        warnings: params.warnings,
        whiteness: failures.whiteness,
        failure_windows: failures.failure_windows,
        regimes: failures.regimes,
        findings: failures.findings,
        input_correlation,
        ranking: missing.ranking,
        unavailable: missing.unavailable,
        recommended: missing.recommended.first().cloned(),
        recommended_set: missing.recommended,
        confounded: missing.confounded,
        alternatives: missing.alternatives,
        verdict,
        fit,
        t: Arc::new(s.t.clone()),
        measured: Arc::new(s.wrench().to_vec()),
        top_driver: missing.top_driver,
        partial_residuals,
    })
}

/// What remains of a model that is not adequate, per channel, in a phrase: `fx 5.3× its
/// noise`.
fn remains(adequacy: &[ChannelAdequacy]) -> String {
    adequacy
        .iter()
        .filter(|a| !a.adequate)
        .map(|a| {
            if a.ratio > ADEQUACY_FACTOR {
                format!("{} {:.1}× its noise", a.channel, a.ratio)
            } else {
                format!(
                    "{} not white (Σρ² over lags 1–20 {:.3}, white below {:.3})",
                    a.channel, a.autocorrelation_sum, a.autocorrelation_limit
                )
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The one-line verdict: the missing effects and their held-out gain, or whether the model
/// is adequate, and what remains if not.
fn verdict(missing: &ranking::Ranking, adequacy: &[ChannelAdequacy], adequate: bool) -> String {
    if !missing.recommended.is_empty() {
        let names: Vec<String> = missing
            .recommended
            .iter()
            .map(|r| format!("`{r}`"))
            .collect();
        let sensor = missing
            .recommended
            .iter()
            .all(|r| crate::effects::is_sensor_effect(r));
        return format!(
            "{}: {} (held-out error {:+.0} % in units of the noise)",
            if sensor {
                "a sensor error"
            } else {
                "missing physics"
            },
            names.join(" + "),
            -100.0 * missing.set_reduction
        );
    }
    if adequate {
        return format!(
            "model adequate: every channel's held-out error is within {ADEQUACY_FACTOR}× its noise and white"
        );
    }
    let best = missing
        .ranking
        .first()
        .map(|b| {
            format!(
                " (best candidate `{}`: {})",
                b.effect,
                b.explanation.rsplit("; ").next().unwrap_or("")
            )
        })
        .unwrap_or_default();
    format!(
        "not adequate: {}; not explained by any built-in effect{best}",
        remains(adequacy)
    )
}
