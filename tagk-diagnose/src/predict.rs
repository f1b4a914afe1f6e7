//! k-step-ahead prediction of a model on a flight log, as MATLAB's `compare(data, sys, k)`.
//!
//! From every sample `i`, the model is integrated open loop for `h` steps from the logged
//! state at `i`, driven by the log's measured inputs. The prediction is compared with the
//! logged state at `i + h`. The model is the rigid body with its identified parameters `θ`
//! plus its effects:
//!
//! - the applied wrench is the rotors' (the rotor speeds through the vehicle's rotor map, or
//!   the logged wrench when there is no vehicle or no rotor speeds) plus each effect's
//!   external wrench `Φ β`;
//! - a state-driven effect (drag, ground effect, wind, biases) is evaluated at the
//!   *predicted* state ([`crate::Effect::columns_at`]); an input-driven one (a lag, a delay, a
//!   thrust gain, a custom effect) takes its columns from the log;
//! - the rigid body's Newton–Euler wrench equals the applied one: the 6 × 6 spatial-inertia
//!   system gives the accelerations ([`tagk_dynamics::ForwardDynamics`], the exact inverse of
//!   the regressor the fit uses).
//!
//! Integrator: classical Runge–Kutta (RK4) at the log's own steps. The inputs are held over
//! each step (zero-order hold). The attitude is a unit quaternion (body → world), integrated
//! as four numbers and normalised after each step. A prediction never runs across a gap in
//! the time stamps.
//!
//! **The constant-rate reference** ([`Predictor::ConstantRate`], named [`CONSTANT_RATE`]) needs
//! no model. From the logged state at `i` it holds the body rate `ω_i` and the velocity `v_i`.
//! The attitude turns at that rate: `q(t_i + τ) = q_i ⊗ exp(ω_i τ / 2)`. The position moves
//! at that velocity: `p(t_i + τ) = p_i + v_i τ`. It is the naive baseline ("persistence") of
//! multi-horizon prediction benchmarks: a model is worth its cost where it beats it.
//!
//! **Overlays** ([`Overlay`]): at a chosen horizon `h`, the logged state at each sample beside
//! the `h`-step prediction that ends there, per component, with the error norms.

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use serde::Serialize;
use tagk_dynamics::log::{Sampling, attitude_quaternion};
use tagk_dynamics::{ForwardDynamics, GRAVITY_WORLD, Wrench};

use crate::effects::{EffectRef, effect_columns};
use crate::error::DiagnoseError;
use crate::model_file::{ModelEffect, ModelFile, ModelFileError};
use crate::signals::Signals;

/// The state of the rigid body the prediction integrates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    /// Position of the body origin, world frame \[m\].
    pub position: Vector3<f64>,
    /// Velocity of the body origin, world frame \[m/s\].
    pub velocity: Vector3<f64>,
    /// Attitude, body → world (Hamilton).
    pub attitude: UnitQuaternion<f64>,
    /// Body angular velocity, body frame \[rad/s\].
    pub omega: Vector3<f64>,
}

impl BodyState {
    /// The logged state at sample `i` of a log.
    pub fn logged(log: &tagk_dynamics::FlightLog, i: usize) -> Self {
        Self {
            position: Vector3::from(log.position[i]),
            velocity: Vector3::from(log.velocity[i]),
            attitude: attitude_quaternion(&log.attitude[i]),
            omega: Vector3::from(log.omega[i]),
        }
    }

    /// The rotation matrix, body → world.
    pub fn rotation(&self) -> Matrix3<f64> {
        self.attitude.to_rotation_matrix().into_inner()
    }

    /// The velocity in the body frame `Rᵀ v` \[m/s\].
    pub fn velocity_body(&self) -> Vector3<f64> {
        self.rotation().transpose() * self.velocity
    }
}

/// The errors of one horizon: mean error norms and MATLAB's fit %.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HorizonError {
    /// The horizon \[steps\].
    pub h: usize,
    /// The log's sampling step \[s\] (the horizon is `h · dt` seconds).
    pub dt: f64,
    /// Mean position error norm \[m\].
    pub position: f64,
    /// Mean velocity error norm \[m/s\].
    pub velocity: f64,
    /// Mean attitude error \[rad\]: the angle of the relative rotation.
    pub attitude: f64,
    /// Mean body-rate error norm \[rad/s\].
    pub body_rate: f64,
    /// Fit % per quantity.
    pub fit: QuantityFit,
    /// How many predictions were compared (starting samples with `i + h` in the same
    /// segment).
    #[serde(skip)]
    pub samples: usize,
}

/// MATLAB `compare`'s fit `100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖)` \[%\] per quantity, the components
/// stacked (`ȳ`: each component's mean). The attitude's components are the unit quaternion's,
/// the predicted one signed to the logged one's hemisphere. `None` where the logged quantity
/// is constant (the fit is undefined).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct QuantityFit {
    /// Position fit \[%\].
    pub position: Option<f64>,
    /// Velocity fit \[%\].
    pub velocity: Option<f64>,
    /// Attitude fit \[%\].
    pub attitude: Option<f64>,
    /// Body-rate fit \[%\].
    pub body_rate: Option<f64>,
}

/// The k-step prediction errors of one model on one log, per horizon.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Prediction {
    /// One entry per horizon, in the order asked.
    pub horizons: Vec<HorizonError>,
    /// One entry per overlay horizon asked and per log, in that order (empty: none asked).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub overlays: Vec<Overlay>,
}

/// Name of the constant-rate reference predictor in a [`Comparison`].
pub const CONSTANT_RATE: &str = "constant-rate";

/// What predicts ahead.
#[derive(Debug, Clone, Copy)]
pub enum Predictor<'a> {
    /// An identified model (rigid body plus effects), integrated open loop from the log's
    /// inputs: see the module documentation.
    Model(&'a ModelFile),
    /// The model-free reference: body rate and velocity held at their logged values at the
    /// start, attitude and position integrated with them (module documentation).
    ConstantRate,
}

/// Logged or predicted states over time, per component.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct OverlaySeries {
    /// Position `x, y, z`, world frame \[m\].
    pub position: Vec<[f64; 3]>,
    /// Velocity `x, y, z`, world frame \[m/s\].
    pub velocity: Vec<[f64; 3]>,
    /// Attitude as roll, pitch, yaw (Z-Y-X Euler angles of body → world) \[rad\].
    /// The logged angles are unwrapped over time. A predicted angle lies within π of the
    /// logged one.
    pub attitude: Vec<[f64; 3]>,
    /// Body rate `p, q, r`, body frame \[rad/s\].
    pub body_rate: Vec<[f64; 3]>,
}

/// The error norms of each prediction of an overlay.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct OverlayErrors {
    /// Position error norm \[m\].
    pub position: Vec<f64>,
    /// Velocity error norm \[m/s\].
    pub velocity: Vec<f64>,
    /// Attitude error: the angle of the relative rotation \[rad\].
    pub attitude: Vec<f64>,
    /// Body-rate error norm \[rad/s\].
    pub body_rate: Vec<f64>,
}

impl OverlayErrors {
    /// The error series of quantity `k` of [`QUANTITIES`] (0 position … 3 body rate).
    pub fn of(&self, k: usize) -> &[f64] {
        match k {
            0 => &self.position,
            1 => &self.velocity,
            2 => &self.attitude,
            _ => &self.body_rate,
        }
    }
}

impl OverlaySeries {
    /// The component series of quantity `k` of [`QUANTITIES`] (0 position … 3 body rate).
    pub fn of(&self, k: usize) -> &[[f64; 3]] {
        match k {
            0 => &self.position,
            1 => &self.velocity,
            2 => &self.attitude,
            _ => &self.body_rate,
        }
    }
}

/// The component names of each quantity of [`QUANTITIES`], in its order.
pub const COMPONENTS: [[&str; 3]; 4] = [
    ["x", "y", "z"],
    ["x", "y", "z"],
    ["roll", "pitch", "yaw"],
    ["p", "q", "r"],
];

/// The `h`-step predictions of one log beside the logged states they predict.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Overlay {
    /// The horizon \[steps\].
    pub h: usize,
    /// The log's sampling step \[s\].
    pub dt: f64,
    /// Index of the log among those pooled (0 for one log).
    pub log: usize,
    /// Time of each compared sample, where its prediction ends \[s\] (the log's clock).
    pub t: Vec<f64>,
    /// The logged state at each time.
    pub logged: OverlaySeries,
    /// The prediction made `h` steps before each time.
    pub predicted: OverlaySeries,
    /// The error norms at each time.
    pub error: OverlayErrors,
}

/// The largest error of one quantity in an overlay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverlayPeak {
    /// The error \[SI unit of the quantity\].
    pub error: f64,
    /// When it occurs \[s\], the end of the prediction (the log's clock).
    pub t: f64,
    /// In which log (index among those pooled).
    pub log: usize,
}

impl Overlay {
    /// An empty overlay of horizon `h` on log `log`.
    fn new(h: usize, log: usize) -> Self {
        Self {
            h,
            dt: 0.0,
            log,
            t: Vec::new(),
            logged: OverlaySeries::default(),
            predicted: OverlaySeries::default(),
            error: OverlayErrors::default(),
        }
    }

    /// Adds the prediction `p` of the logged state `y` at time `t` \[s\].
    fn push(&mut self, t: f64, p: &BodyState, y: &BodyState) {
        let v3 = |v: &Vector3<f64>| [v.x, v.y, v.z];
        self.t.push(t);
        self.logged.position.push(v3(&y.position));
        self.predicted.position.push(v3(&p.position));
        self.logged.velocity.push(v3(&y.velocity));
        self.predicted.velocity.push(v3(&p.velocity));
        self.logged.body_rate.push(v3(&y.omega));
        self.predicted.body_rate.push(v3(&p.omega));
        let euler = |q: &UnitQuaternion<f64>| {
            let (r, p, y) = q.euler_angles();
            [r, p, y]
        };
        let raw_y = euler(&y.attitude);
        let raw_p = euler(&p.attitude);
        // The logged angles unwrapped against the previous sample; the predicted ones within
        // π of the logged.
        let logged = match self.logged.attitude.last() {
            Some(prev) => std::array::from_fn(|c| prev[c] + wrap_angle(raw_y[c] - prev[c])),
            None => raw_y,
        };
        let predicted: [f64; 3] =
            std::array::from_fn(|c| logged[c] + wrap_angle(raw_p[c] - raw_y[c]));
        self.logged.attitude.push(logged);
        self.predicted.attitude.push(predicted);
        self.error.position.push((p.position - y.position).norm());
        self.error.velocity.push((p.velocity - y.velocity).norm());
        self.error.attitude.push(p.attitude.angle_to(&y.attitude));
        self.error.body_rate.push((p.omega - y.omega).norm());
    }

    /// The largest error of quantity `k` of [`QUANTITIES`] and when it occurs (`None` for an
    /// empty overlay).
    pub fn peak(&self, k: usize) -> Option<OverlayPeak> {
        self.error
            .of(k)
            .iter()
            .zip(&self.t)
            .filter(|(e, _)| e.is_finite())
            .max_by(|a, b| a.0.total_cmp(b.0))
            .map(|(e, t)| OverlayPeak {
                error: *e,
                t: *t,
                log: self.log,
            })
    }
}

/// `a` wrapped into `[−π, π)` \[rad\].
fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    (a + PI).rem_euclid(TAU) - PI
}

/// The horizons `1, 2, 5, 10, 20, 50, 100, …` up to `max`, and `max` itself.
pub fn default_horizons(max: usize) -> Vec<usize> {
    let mut out = Vec::new();
    let mut decade = 1;
    'outer: loop {
        for m in [1, 2, 5] {
            let h = m * decade;
            if h > max {
                break 'outer;
            }
            out.push(h);
        }
        decade *= 10;
    }
    if max > 0 && out.last() != Some(&max) {
        out.push(max);
    }
    out
}

/// MATLAB's fit % of predictions `yhat` against measurements `y` (rows of `D` components,
/// stacked): `100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖)` with `ȳ` each component's mean. `None` for no rows
/// or a constant measurement.
pub fn fit_percent<const D: usize>(y: &[[f64; D]], yhat: &[[f64; D]]) -> Option<f64> {
    if y.is_empty() || y.len() != yhat.len() {
        return None;
    }
    let n = y.len() as f64;
    let mean: [f64; D] = std::array::from_fn(|k| y.iter().map(|r| r[k]).sum::<f64>() / n);
    let mut err = 0.0;
    let mut spread = 0.0;
    for (a, b) in y.iter().zip(yhat) {
        for k in 0..D {
            err += (a[k] - b[k]).powi(2);
            spread += (a[k] - mean[k]).powi(2);
        }
    }
    (spread > 0.0).then(|| 100.0 * (1.0 - err.sqrt() / spread.sqrt()))
}

/// An effect of the model ready to evaluate: its coefficients in the order of its columns.
struct Ready {
    effect: EffectRef,
    param: Option<f64>,
    /// One coefficient per column (fixed columns at their fixed value).
    coef: Vec<f64>,
    /// For an input-driven effect, its wrench at every sample of the log.
    logged: Option<Vec<[f64; 6]>>,
}

/// The coefficient of each column of `effect` on `s`, from the file's record `record`.
fn coefficients(
    record: &ModelEffect,
    columns: &[crate::effects::EffectColumn],
) -> Result<Vec<f64>, DiagnoseError> {
    columns
        .iter()
        .map(|c| match c.fixed {
            Some(v) => Ok(v),
            None => record
                .coefficient(&c.name)
                .or_else(|| {
                    c.name
                        .split_once('@')
                        .and_then(|(base, _)| record.coefficient(base))
                })
                .ok_or_else(|| {
                    ModelFileError::BadValue {
                        key: format!("effects.{}.coefficients", record.name),
                        reason: format!("has no coefficient `{}`", c.name),
                    }
                    .into()
                }),
        })
        .collect()
}

/// The k-step prediction of `model` on the log of `signals` at each of `horizons` (steps):
/// see the module documentation.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (field `horizons`) for no horizon, a zero horizon, or one
/// longer than every gap-free segment of the log; [`DiagnoseError::ModelFile`] for an effect
/// that cannot be instantiated or lacks a coefficient; [`DiagnoseError::EffectUnavailable`]
/// for an effect the log cannot drive; [`DiagnoseError::InvalidModel`] for parameters without
/// a positive-definite spatial inertia, or a prediction that is not finite.
pub fn k_step_prediction(
    signals: &Signals,
    model: &ModelFile,
    horizons: &[usize],
) -> Result<Prediction, DiagnoseError> {
    k_step_prediction_logs(std::slice::from_ref(signals), model, horizons)
}

/// [`k_step_prediction`] over several logs: every start sample of every log counts once in
/// the mean errors and the fit % (the log's sampling step of the first log is reported).
///
/// # Errors
/// As [`k_step_prediction`]; [`DiagnoseError::InvalidOption`] (field `logs`) for no log.
pub fn k_step_prediction_logs(
    logs: &[Signals],
    model: &ModelFile,
    horizons: &[usize],
) -> Result<Prediction, DiagnoseError> {
    predict_logs(logs, Predictor::Model(model), horizons, &[])
}

/// The constant-rate reference's k-step prediction on one log ([`Predictor::ConstantRate`]).
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (field `horizons`) as [`k_step_prediction`].
pub fn constant_rate_prediction(
    signals: &Signals,
    horizons: &[usize],
) -> Result<Prediction, DiagnoseError> {
    predict_logs(
        std::slice::from_ref(signals),
        Predictor::ConstantRate,
        horizons,
        &[],
    )
}

/// The k-step prediction of `predictor` over several logs at `horizons` (steps), with an
/// [`Overlay`] per log at each of `overlays` (steps; empty: none). Every start sample of every
/// log counts once in the mean errors and the fit %. The sampling step of the first log is
/// reported.
///
/// # Errors
/// As [`k_step_prediction`]; [`DiagnoseError::InvalidOption`] (field `logs`) for no log,
/// (field `overlays`) for a zero overlay horizon or one longer than every gap-free segment.
pub fn predict_logs(
    logs: &[Signals],
    predictor: Predictor<'_>,
    horizons: &[usize],
    overlays: &[usize],
) -> Result<Prediction, DiagnoseError> {
    let bad_horizon = |reason: String| DiagnoseError::InvalidOption {
        field: "horizons",
        reason,
    };
    if horizons.is_empty() || horizons.contains(&0) {
        return Err(bad_horizon(format!(
            "{horizons:?}: give at least one horizon, each at least 1 step"
        )));
    }
    if overlays.contains(&0) {
        return Err(DiagnoseError::InvalidOption {
            field: "overlays",
            reason: format!("{overlays:?}: each overlay horizon must be at least 1 step"),
        });
    }
    let Some(first) = logs.first() else {
        return Err(DiagnoseError::InvalidOption {
            field: "logs",
            reason: "no flight log given".into(),
        });
    };
    let mut acc: Vec<Accumulator> = horizons.iter().map(|_| Accumulator::default()).collect();
    let mut out_overlays = Vec::new();
    for (k, signals) in logs.iter().enumerate() {
        let mut ov: Vec<Overlay> = overlays.iter().map(|h| Overlay::new(*h, k)).collect();
        accumulate(signals, predictor, horizons, &mut acc, &mut ov)?;
        let dt = tagk_dynamics::log::median_step(&signals.t);
        for o in &mut ov {
            o.dt = dt;
        }
        out_overlays.push(ov);
    }
    let dt = tagk_dynamics::log::median_step(&first.t);
    let mut out = Vec::with_capacity(horizons.len());
    for (h, a) in horizons.iter().zip(acc) {
        if a.count == 0 {
            return Err(bad_horizon(format!(
                "{h} steps is longer than every gap-free segment of the log"
            )));
        }
        out.push(a.finish(*h, dt));
    }
    // Overlays ordered by horizon as asked, then by log.
    let mut overlays_out = Vec::new();
    for (k, h) in overlays.iter().enumerate() {
        if out_overlays.iter().all(|ov| ov[k].t.is_empty()) {
            return Err(DiagnoseError::InvalidOption {
                field: "overlays",
                reason: format!("{h} steps is longer than every gap-free segment of the log"),
            });
        }
        for ov in &out_overlays {
            overlays_out.push(ov[k].clone());
        }
    }
    Ok(Prediction {
        horizons: out,
        overlays: overlays_out,
    })
}

/// Adds the predictions of `predictor` on one log to the accumulators of `horizons` and to
/// the overlays `ov`.
fn accumulate(
    signals: &Signals,
    predictor: Predictor<'_>,
    horizons: &[usize],
    acc: &mut [Accumulator],
    ov: &mut [Overlay],
) -> Result<(), DiagnoseError> {
    match predictor {
        Predictor::Model(model) => accumulate_model(signals, model, horizons, acc, ov),
        Predictor::ConstantRate => drive(signals, horizons, acc, ov, |state, _, dt| {
            Ok(hold_step(state, dt))
        }),
    }
}

/// One step of the constant-rate reference: `ω` and `v` held, `q ← q ⊗ exp(ω dt / 2)`,
/// `p ← p + v dt` (exact for a constant rate).
fn hold_step(state: &BodyState, dt: f64) -> BodyState {
    BodyState {
        position: state.position + state.velocity * dt,
        velocity: state.velocity,
        attitude: state.attitude * UnitQuaternion::from_scaled_axis(state.omega * dt),
        omega: state.omega,
    }
}

/// From every start sample of every gap-free segment, steps the state with `step(state, j,
/// dt)` (over the log's step `j → j + 1`) up to the longest horizon, and adds each prediction
/// at a horizon of `horizons` to its accumulator and at an overlay's horizon to the overlay.
fn drive(
    signals: &Signals,
    horizons: &[usize],
    acc: &mut [Accumulator],
    ov: &mut [Overlay],
    mut step: impl FnMut(&BodyState, usize, f64) -> Result<BodyState, DiagnoseError>,
) -> Result<(), DiagnoseError> {
    let hmax = horizons
        .iter()
        .chain(ov.iter().map(|o| &o.h))
        .copied()
        .max()
        .unwrap_or(0);
    let log = signals.log();
    let segments = Sampling::of(&signals.t).segments();
    for seg in &segments {
        for i in seg.clone() {
            if i + 1 >= seg.end {
                break;
            }
            let mut state = BodyState::logged(log, i);
            let last = (i + hmax).min(seg.end - 1);
            for j in i..last {
                let dt = signals.t[j + 1] - signals.t[j];
                state = step(&state, j, dt)?;
                let h = j + 1 - i;
                let logged = BodyState::logged(log, j + 1);
                for (k, _) in horizons.iter().enumerate().filter(|(_, x)| **x == h) {
                    acc[k].add(&state, &logged);
                }
                for o in ov.iter_mut().filter(|o| o.h == h) {
                    o.push(signals.t[j + 1], &state, &logged);
                }
            }
        }
    }
    Ok(())
}

/// [`accumulate`] of a model.
fn accumulate_model(
    signals: &Signals,
    model: &ModelFile,
    horizons: &[usize],
    acc: &mut [Accumulator],
    ov: &mut [Overlay],
) -> Result<(), DiagnoseError> {
    let log = signals.log();
    let n = signals.len();
    let fd = ForwardDynamics::new(&model.inertial.theta()).map_err(|e| {
        DiagnoseError::InvalidModel(format!("the model's inertial parameters: {e}"))
    })?;
    // The effects with their coefficients.
    let mut ready = Vec::new();
    for record in &model.effects {
        let effect = record.instantiate()?;
        effect
            .check(signals)
            .map_err(|reason| DiagnoseError::EffectUnavailable {
                effect: effect.name().to_string(),
                reason,
            })?;
        let param = record.scanned.as_ref().map(|p| p.value);
        let columns = effect_columns(effect.as_ref(), signals, param);
        crate::effects::check_columns(&columns, signals).map_err(|reason| {
            DiagnoseError::EffectUnavailable {
                effect: effect.name().to_string(),
                reason,
            }
        })?;
        let coef = coefficients(record, &columns)?;
        let probe = BodyState::logged(log, 0);
        let state_driven = effect.columns_at(signals, 0, &probe, param).is_some();
        let logged = (!state_driven).then(|| {
            (0..n)
                .map(|i| {
                    let mut w = [0.0; 6];
                    for (col, b) in columns.iter().zip(&coef) {
                        for (c, d) in col.data.iter().enumerate() {
                            if let Some(v) = d {
                                w[c] += b * v[i];
                            }
                        }
                    }
                    w
                })
                .collect()
        });
        ready.push(Ready {
            effect,
            param,
            coef,
            logged,
        });
    }
    // The actuators' wrench at each sample.
    let inputs: Vec<[f64; 6]> = match (&model.vehicle, log.rotor_speeds.as_ref()) {
        (Some(v), Some(w)) => w
            .iter()
            .map(|w| v.wrench_from_rotor_speeds(w).to_array())
            .collect(),
        _ => log.wrench.clone(),
    };
    let applied = |state: &BodyState, j: usize| -> [f64; 6] {
        let mut w = inputs[j];
        for r in &ready {
            let ext = match &r.logged {
                Some(l) => l[j],
                None => {
                    let cols = r
                        .effect
                        .columns_at(signals, j, state, r.param)
                        .unwrap_or_default();
                    let mut e = [0.0; 6];
                    for (col, b) in cols.iter().zip(&r.coef) {
                        for c in 0..6 {
                            e[c] += b * col[c];
                        }
                    }
                    e
                }
            };
            for c in 0..6 {
                w[c] += ext[c];
            }
        }
        w
    };
    let derivative = |state: &BodyState, j: usize| -> Result<Derivative, DiagnoseError> {
        let w = applied(state, j);
        let (a, omega_dot) = fd
            .accelerations(&Wrench::from_array(w), &state.omega)
            .map_err(|e| DiagnoseError::InvalidModel(format!("prediction at sample {j}: {e}")))?;
        let q = state.attitude.quaternion();
        let q_dot = q * Quaternion::from_imag(state.omega) * 0.5;
        Ok(Derivative {
            position: state.velocity,
            velocity: state.attitude * a + GRAVITY_WORLD,
            attitude: q_dot,
            omega: omega_dot,
        })
    };
    let step = |state: &BodyState, j: usize, dt: f64| -> Result<BodyState, DiagnoseError> {
        let k1 = derivative(state, j)?;
        let k2 = derivative(&advance(state, &k1, 0.5 * dt), j)?;
        let k3 = derivative(&advance(state, &k2, 0.5 * dt), j)?;
        let k4 = derivative(&advance(state, &k3, dt), j)?;
        let sum = Derivative {
            position: k1.position + 2.0 * k2.position + 2.0 * k3.position + k4.position,
            velocity: k1.velocity + 2.0 * k2.velocity + 2.0 * k3.velocity + k4.velocity,
            attitude: k1.attitude + k2.attitude * 2.0 + k3.attitude * 2.0 + k4.attitude,
            omega: k1.omega + 2.0 * k2.omega + 2.0 * k3.omega + k4.omega,
        };
        Ok(advance(state, &sum, dt / 6.0))
    };
    drive(signals, horizons, acc, ov, step)
}

/// The time derivative of a [`BodyState`] (the quaternion's as four numbers).
struct Derivative {
    position: Vector3<f64>,
    velocity: Vector3<f64>,
    attitude: Quaternion<f64>,
    omega: Vector3<f64>,
}

/// `state + dt · d`, the quaternion normalised.
fn advance(state: &BodyState, d: &Derivative, dt: f64) -> BodyState {
    BodyState {
        position: state.position + d.position * dt,
        velocity: state.velocity + d.velocity * dt,
        attitude: UnitQuaternion::from_quaternion(state.attitude.quaternion() + d.attitude * dt),
        omega: state.omega + d.omega * dt,
    }
}

/// Running sums of the fit % of one quantity of `D` components: the squared error and each
/// component's mean and squared spread (Welford's update, stable for positions far from 0).
#[derive(Clone, Copy)]
struct FitSums<const D: usize> {
    n: f64,
    err: f64,
    mean: [f64; D],
    m2: [f64; D],
}

impl<const D: usize> Default for FitSums<D> {
    fn default() -> Self {
        Self {
            n: 0.0,
            err: 0.0,
            mean: [0.0; D],
            m2: [0.0; D],
        }
    }
}

impl<const D: usize> FitSums<D> {
    /// Adds the measurement `y` and its prediction `yhat`.
    fn add(&mut self, y: [f64; D], yhat: [f64; D]) {
        self.n += 1.0;
        for k in 0..D {
            self.err += (y[k] - yhat[k]).powi(2);
            let delta = y[k] - self.mean[k];
            self.mean[k] += delta / self.n;
            self.m2[k] += delta * (y[k] - self.mean[k]);
        }
    }

    /// The fit % ([`fit_percent`]).
    fn percent(&self) -> Option<f64> {
        let spread: f64 = self.m2.iter().sum();
        (self.n > 0.0 && spread > 0.0).then(|| 100.0 * (1.0 - self.err.sqrt() / spread.sqrt()))
    }
}

/// Error sums of one horizon.
#[derive(Default)]
struct Accumulator {
    count: usize,
    sums: [f64; 4],
    position: FitSums<3>,
    velocity: FitSums<3>,
    attitude: FitSums<4>,
    body_rate: FitSums<3>,
}

impl Accumulator {
    /// Adds one prediction `p` of the logged state `y`.
    fn add(&mut self, p: &BodyState, y: &BodyState) {
        self.count += 1;
        self.sums[0] += (p.position - y.position).norm();
        self.sums[1] += (p.velocity - y.velocity).norm();
        self.sums[2] += p.attitude.angle_to(&y.attitude);
        self.sums[3] += (p.omega - y.omega).norm();
        let v3 = |v: &Vector3<f64>| [v.x, v.y, v.z];
        self.position.add(v3(&y.position), v3(&p.position));
        self.velocity.add(v3(&y.velocity), v3(&p.velocity));
        self.body_rate.add(v3(&y.omega), v3(&p.omega));
        let qy = y.attitude.quaternion().coords;
        let mut qp = p.attitude.quaternion().coords;
        if qp.dot(&qy) < 0.0 {
            qp = -qp;
        }
        self.attitude
            .add([qy.w, qy.x, qy.y, qy.z], [qp.w, qp.x, qp.y, qp.z]);
    }

    /// The horizon's errors.
    fn finish(self, h: usize, dt: f64) -> HorizonError {
        let n = self.count as f64;
        HorizonError {
            h,
            dt,
            position: self.sums[0] / n,
            velocity: self.sums[1] / n,
            attitude: self.sums[2] / n,
            body_rate: self.sums[3] / n,
            fit: QuantityFit {
                position: self.position.percent(),
                velocity: self.velocity.percent(),
                attitude: self.attitude.percent(),
                body_rate: self.body_rate.percent(),
            },
            samples: self.count,
        }
    }
}

/// serde_json's pretty formatter, except that an array opened at nesting depth `depth` or
/// deeper (the root value is depth 1) is written compactly, on one line.
struct SeriesOnOneLine {
    pretty: serde_json::ser::PrettyFormatter<'static>,
    /// Nesting depth of the containers open.
    level: usize,
    /// Depth of the compact array open, if any.
    compact_at: Option<usize>,
    /// First depth written compactly.
    depth: usize,
}

impl SeriesOnOneLine {
    fn new(depth: usize) -> Self {
        Self {
            pretty: serde_json::ser::PrettyFormatter::new(),
            level: 0,
            compact_at: None,
            depth,
        }
    }
}

/// Forwards a formatter call to the compact or the pretty formatter.
macro_rules! forward {
    ($self:ident, $name:ident ( $($arg:expr),* )) => {
        if $self.compact_at.is_some() {
            serde_json::ser::CompactFormatter.$name($($arg),*)
        } else {
            $self.pretty.$name($($arg),*)
        }
    };
}

impl serde_json::ser::Formatter for SeriesOnOneLine {
    fn begin_array<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        self.level += 1;
        if self.compact_at.is_none() && self.level >= self.depth {
            self.compact_at = Some(self.level);
        }
        forward!(self, begin_array(w))
    }
    fn end_array<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        let r = forward!(self, end_array(w));
        if self.compact_at == Some(self.level) {
            self.compact_at = None;
        }
        self.level -= 1;
        r
    }
    fn begin_array_value<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        forward!(self, begin_array_value(w, first))
    }
    fn end_array_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        forward!(self, end_array_value(w))
    }
    fn begin_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        self.level += 1;
        forward!(self, begin_object(w))
    }
    fn end_object<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        let r = forward!(self, end_object(w));
        self.level -= 1;
        r
    }
    fn begin_object_key<W: ?Sized + std::io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> std::io::Result<()> {
        forward!(self, begin_object_key(w, first))
    }
    fn begin_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        forward!(self, begin_object_value(w))
    }
    fn end_object_value<W: ?Sized + std::io::Write>(&mut self, w: &mut W) -> std::io::Result<()> {
        forward!(self, end_object_value(w))
    }
}

/// One predicted quantity: its name, unit, mean error and fit % of a horizon.
#[derive(Debug, Clone, Copy)]
pub struct Quantity {
    /// Its name (`position`, `velocity`, `attitude`, `body rate`).
    pub name: &'static str,
    /// The error's unit.
    pub unit: &'static str,
    /// The mean error norm of a horizon.
    pub error: fn(&HorizonError) -> f64,
    /// The fit % of a horizon.
    pub fit: fn(&QuantityFit) -> Option<f64>,
}

/// The four predicted quantities, in the order of the tables and plots.
pub const QUANTITIES: [Quantity; 4] = [
    Quantity {
        name: "position",
        unit: "m",
        error: |e| e.position,
        fit: |f| f.position,
    },
    Quantity {
        name: "velocity",
        unit: "m/s",
        error: |e| e.velocity,
        fit: |f| f.velocity,
    },
    Quantity {
        name: "attitude",
        unit: "rad",
        error: |e| e.attitude,
        fit: |f| f.attitude,
    },
    Quantity {
        name: "body rate",
        unit: "rad/s",
        error: |e| e.body_rate,
        fit: |f| f.body_rate,
    },
];

/// The k-step predictions of several models on one set of logs: what `tagk compare` prints
/// and writes (`--json`: `{"models": [{"model": …, "horizons": […], "overlays": […]}]}`).
/// The constant-rate reference is an entry named [`CONSTANT_RATE`]. The key `overlays` is
/// absent where none was asked.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// One entry per model, in the order given.
    pub models: Vec<ModelPrediction>,
}

/// One model's k-step prediction errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelPrediction {
    /// The model (its file).
    pub model: String,
    /// The errors per horizon ([`Prediction::horizons`]).
    pub horizons: Vec<HorizonError>,
    /// The overlays ([`Prediction::overlays`]); not written when empty.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub overlays: Vec<Overlay>,
}

impl ModelPrediction {
    /// The entry of `model` (a name) from its prediction.
    pub fn new(model: impl Into<String>, prediction: Prediction) -> Self {
        Self {
            model: model.into(),
            horizons: prediction.horizons,
            overlays: prediction.overlays,
        }
    }
}

impl Comparison {
    /// The comparison as pretty JSON.
    ///
    /// # Errors
    /// [`DiagnoseError::Output`] if serialisation fails.
    /// An overlay's series (arrays nested six levels deep or more) are written each on one
    /// line: pretty-printed, a long log's overlay would take one line per number.
    pub fn to_json(&self) -> Result<String, DiagnoseError> {
        let mut out = Vec::new();
        let mut ser = serde_json::Serializer::with_formatter(&mut out, SeriesOnOneLine::new(6));
        self.serialize(&mut ser)
            .map_err(|e| DiagnoseError::Output {
                path: "<json>".into(),
                message: e.to_string(),
            })?;
        String::from_utf8(out).map_err(|e| DiagnoseError::Output {
            path: "<json>".into(),
            message: e.to_string(),
        })
    }

    /// The terminal tables: per quantity, one row per horizon and one column per model
    /// (models side by side), mean error norms in SI units; then the fit % the same way.
    pub fn table(&self) -> String {
        use std::fmt::Write as _;
        let mut out = String::new();
        for (k, m) in self.models.iter().enumerate() {
            let note = if m.model == CONSTANT_RATE {
                " (reference: body rate and velocity held)"
            } else {
                ""
            };
            let _ = writeln!(out, "model {}: {}{note}", k + 1, m.model);
        }
        let Some(first) = self.models.first() else {
            return out;
        };
        for q in QUANTITIES {
            let (name, unit, get) = (q.name, q.unit, q.error);
            let _ = write!(out, "\n{name} error [{unit}]\n{:>5} {:>9}", "h", "t [s]");
            for k in 0..self.models.len() {
                let _ = write!(out, " {:>10}", format!("model {}", k + 1));
            }
            out.push('\n');
            for (row, e) in first.horizons.iter().enumerate() {
                let _ = write!(out, "{:>5} {:>9.3}", e.h, e.h as f64 * e.dt);
                for m in &self.models {
                    let v = m.horizons.get(row).map_or(f64::NAN, get);
                    let _ = write!(out, " {v:>10.3e}");
                }
                out.push('\n');
            }
        }
        let _ = write!(
            out,
            "\nfit % (MATLAB compare) at the longest horizon, h = {}\n",
            { first.horizons.last().map_or(0, |e| e.h) }
        );
        let _ = write!(out, "{:>10}", "");
        for k in 0..self.models.len() {
            let _ = write!(out, " {:>10}", format!("model {}", k + 1));
        }
        out.push('\n');
        for q in QUANTITIES {
            let (name, get) = (q.name, q.fit);
            let _ = write!(out, "{name:>10}");
            for m in &self.models {
                match m.horizons.last().and_then(|e| get(&e.fit)) {
                    Some(v) => {
                        let _ = write!(out, " {v:>10.2}");
                    }
                    None => {
                        let _ = write!(out, " {:>10}", "n/a");
                    }
                }
            }
            out.push('\n');
        }
        out.push_str(&self.overlay_summary());
        out
    }

    /// One line per model and overlay horizon: the largest error of each quantity and when it
    /// occurs (the end of the prediction; with several logs, which log). Empty without
    /// overlays.
    pub fn overlay_summary(&self) -> String {
        use std::fmt::Write as _;
        let mut out = String::new();
        let mut hs: Vec<(usize, f64)> = Vec::new();
        for o in self.models.iter().flat_map(|m| &m.overlays) {
            if !hs.iter().any(|(h, _)| *h == o.h) {
                hs.push((o.h, o.dt));
            }
        }
        if hs.is_empty() {
            return out;
        }
        let several = self
            .models
            .iter()
            .flat_map(|m| &m.overlays)
            .any(|o| o.log > 0);
        out.push_str("\nlargest error at the overlay horizons (at t, the end of the prediction)\n");
        for (h, dt) in hs {
            for (k, m) in self.models.iter().enumerate() {
                let _ = write!(out, "h {h:>4} ({:.3} s) model {:>2}:", h as f64 * dt, k + 1);
                for (q, quantity) in QUANTITIES.iter().enumerate() {
                    let peak = m
                        .overlays
                        .iter()
                        .filter(|o| o.h == h)
                        .filter_map(|o| o.peak(q))
                        .max_by(|a, b| a.error.total_cmp(&b.error));
                    let sep = if q == 0 { " " } else { ", " };
                    match peak {
                        Some(p) if several => {
                            let _ = write!(
                                out,
                                "{sep}{} {:.2e} {} at {:.2} s (log {})",
                                quantity.name,
                                p.error,
                                quantity.unit,
                                p.t,
                                p.log + 1
                            );
                        }
                        Some(p) => {
                            let _ = write!(
                                out,
                                "{sep}{} {:.2e} {} at {:.2} s",
                                quantity.name, p.error, quantity.unit, p.t
                            );
                        }
                        None => {
                            let _ = write!(out, "{sep}{} n/a", quantity.name);
                        }
                    }
                }
                out.push('\n');
            }
        }
        out
    }
}
