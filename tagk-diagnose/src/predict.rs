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
    let bad_horizon = |reason: String| DiagnoseError::InvalidOption {
        field: "horizons",
        reason,
    };
    if horizons.is_empty() || horizons.contains(&0) {
        return Err(bad_horizon(format!(
            "{horizons:?}: give at least one horizon, each at least 1 step"
        )));
    }
    let Some(first) = logs.first() else {
        return Err(DiagnoseError::InvalidOption {
            field: "logs",
            reason: "no flight log given".into(),
        });
    };
    let mut acc: Vec<Accumulator> = horizons.iter().map(|_| Accumulator::default()).collect();
    for signals in logs {
        accumulate(signals, model, horizons, &mut acc)?;
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
    Ok(Prediction { horizons: out })
}

/// Adds the predictions of `model` on one log to the accumulators of `horizons`.
fn accumulate(
    signals: &Signals,
    model: &ModelFile,
    horizons: &[usize],
    acc: &mut [Accumulator],
) -> Result<(), DiagnoseError> {
    let hmax = *horizons.iter().max().expect("non-empty");
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
                for (k, _) in horizons.iter().enumerate().filter(|(_, x)| **x == h) {
                    acc[k].add(&state, &BodyState::logged(log, j + 1));
                }
            }
        }
    }
    Ok(())
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
/// and writes (`--json`: `{"models": [{"model": …, "horizons": […]}]}`).
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
}

impl Comparison {
    /// The comparison as pretty JSON.
    ///
    /// # Errors
    /// [`DiagnoseError::Output`] if serialisation fails.
    pub fn to_json(&self) -> Result<String, DiagnoseError> {
        serde_json::to_string_pretty(self).map_err(|e| DiagnoseError::Output {
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
            let _ = writeln!(out, "model {}: {}", k + 1, m.model);
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
        out
    }
}
