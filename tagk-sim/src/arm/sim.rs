//! The closed loop: plant, joint sensing, computed-torque control and online estimation.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use tagk_core::OnlineEstimator;
use tagk_dynamics::deriv::{savitzky_golay_derivative, savitzky_golay_smooth};
use tagk_dynamics::{InertialParams, JointEffects};

use super::{ArmModel, ArmPlant, ArmState, ArmTrajectory, BaseParameters};
use crate::sim::gaussian;
use crate::{EstimatorKind, SimError};

/// Joint sensing: encoders, velocity and motor-current (or joint-torque) sensing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSensing {
    /// Encoder resolution \[rad per count\]; positions are rounded to it (0: exact).
    pub encoder_resolution: f64,
    /// Standard deviation of the velocity noise \[rad/s\] (the drive's velocity estimate).
    pub velocity_noise: f64,
    /// Standard deviation of the torque noise \[N m\].
    pub torque_noise: f64,
    /// Largest torque offset \[N m\]: each joint's constant offset is uniform in `±` this,
    /// drawn once per run. Unknown to the model.
    pub torque_offset: f64,
}

impl JointSensing {
    /// Exact sensing.
    pub const IDEAL: Self = Self {
        encoder_resolution: 0.0,
        velocity_noise: 0.0,
        torque_noise: 0.0,
        torque_offset: 0.0,
    };

    /// A geared arm's sensing: an 18-bit encoder (2π/2¹⁸ ≈ 2.4e-5 rad), velocity noise
    /// 2e-3 rad/s, torque noise 0.1 N m and offsets up to 0.05 N m.
    pub const REALISTIC: Self = Self {
        encoder_resolution: std::f64::consts::TAU / 262_144.0,
        velocity_noise: 2e-3,
        torque_noise: 0.1,
        torque_offset: 0.05,
    };
}

/// A payload event: at `time` \[s\] the flange holds `payload` from then on (`None`: empty).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PayloadEvent {
    /// When \[s\].
    pub time: f64,
    /// The payload's parameters in the flange body's frame about its origin, or `None`.
    pub payload: Option<InertialParams>,
}

/// What feeds the controller's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ArmAdaptation {
    /// The URDF's parameters, never adapted.
    Nominal,
    /// The true parameters, from each event on.
    Oracle,
    /// An online estimator's base-parameter estimate after each window.
    Estimator(EstimatorKind),
    /// The same on equilibrated columns: the estimator sees `A D` and estimates `D⁻¹β`, with
    /// `D` the inverse RMS of each column ([`BaseParameters::scales`]).
    Scaled(EstimatorKind),
}

impl ArmAdaptation {
    /// The label of a table row: the estimator's name, `nominal` or `oracle`.
    pub fn label(&self) -> String {
        match self {
            ArmAdaptation::Nominal => "nominal".into(),
            ArmAdaptation::Oracle => "oracle".into(),
            ArmAdaptation::Estimator(k) => k.name().into(),
            ArmAdaptation::Scaled(k) => format!("{} (scaled)", k.name()),
        }
    }

    /// The estimator kind and whether its columns are scaled (`None` for nominal and oracle).
    fn estimator(&self) -> Option<(EstimatorKind, bool)> {
        match *self {
            ArmAdaptation::Estimator(k) => Some((k, false)),
            ArmAdaptation::Scaled(k) => Some((k, true)),
            _ => None,
        }
    }
}

/// One closed-loop run of the arm.
#[derive(Debug, Clone)]
pub struct ArmSimConfig {
    /// Run length \[s\].
    pub duration: f64,
    /// Control and integration step \[s\] (RK4, torque held over the step).
    pub control_dt: f64,
    /// The estimator samples every this many control steps.
    pub sample_every: usize,
    /// Samples per estimator window (`window · dof` rows per update).
    pub window: usize,
    /// Half-width `h` of the Savitzky–Golay filter of the estimator's samples (see
    /// [`centre_fit`]); at least 1. `h = 1` is the plain central difference of `q̇`.
    pub filter_half_width: usize,
    /// Gate an estimate on the torques it predicts before it reaches the controller (see
    /// [`torque_gate_threshold`]).
    pub torque_gate: bool,
    /// Seed of the sensing noise and the Kaczmarz estimators.
    pub seed: u64,
    /// The reference.
    pub trajectory: ArmTrajectory,
    /// Payload events, in time order.
    pub events: Vec<PayloadEvent>,
    /// The plant's joint effects (the model knows them: identified beforehand).
    pub effects: JointEffects,
    /// Joint sensing.
    pub sensing: JointSensing,
    /// Closed-loop natural frequency `ω_n` \[rad/s\] of the computed-torque law (critically
    /// damped: `K_p = ω_n²`, `K_d = 2 ω_n`).
    pub natural_frequency: f64,
    /// The true links' parameters (without payload); `None`: the URDF's.
    pub true_links: Option<Vec<InertialParams>>,
    /// What feeds the controller.
    pub adaptation: ArmAdaptation,
    /// Joint tracking error \[rad\] at which the run is aborted.
    pub abort_error: f64,
    /// Keep a joint-space log of every control step.
    pub record_log: bool,
}

impl ArmSimConfig {
    /// A run of `trajectory` on `model`: 1 kHz control, 100 Hz samples, windows of 10, the
    /// typical joint effects, ideal sensing, `ω_n = 10 rad/s`, no payload, nominal control.
    pub fn new(model: &ArmModel, trajectory: ArmTrajectory, duration: f64) -> Self {
        Self {
            duration,
            control_dt: 1e-3,
            sample_every: 10,
            window: 10,
            filter_half_width: DEFAULT_FILTER_HALF_WIDTH,
            torque_gate: true,
            seed: 0,
            trajectory,
            events: Vec::new(),
            effects: model.typical_effects(),
            sensing: JointSensing::IDEAL,
            natural_frequency: 10.0,
            true_links: None,
            adaptation: ArmAdaptation::Nominal,
            abort_error: 0.5,
            record_log: false,
        }
    }
}

/// A joint-space log: one row per control step (sensed `q`, `q̇`, `τ`; the plant's `q̈`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ArmLog {
    /// Number of joints.
    pub dof: usize,
    /// Rows `[t, q1..qN, dq1..dqN, ddq1..ddqN, tau1..tauN]` (SI, radians).
    pub rows: Vec<Vec<f64>>,
}

impl ArmLog {
    /// The CSV header `t,q1..qN,dq1..dqN,ddq1..ddqN,tau1..tauN`.
    pub fn header(&self) -> String {
        let mut h = vec!["t".to_string()];
        for p in ["q", "dq", "ddq", "tau"] {
            h.extend((1..=self.dof).map(|j| format!("{p}{j}")));
        }
        h.join(",")
    }

    /// Writes the log as CSV (header, then one row per step, shortest exact decimals).
    ///
    /// # Errors
    /// [`SimError::Io`] if writing fails.
    pub fn write_csv_to<W: Write>(&self, mut out: W) -> Result<(), SimError> {
        writeln!(out, "{}", self.header())?;
        for r in &self.rows {
            let line: Vec<String> = r.iter().map(|v| format!("{v}")).collect();
            writeln!(out, "{}", line.join(","))?;
        }
        Ok(())
    }

    /// Writes the log as a CSV file (see [`write_csv_to`](Self::write_csv_to)).
    ///
    /// # Errors
    /// [`SimError::Io`] if the file cannot be written.
    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<(), SimError> {
        let f = std::io::BufWriter::new(std::fs::File::create(path)?);
        self.write_csv_to(f)
    }
}

/// One estimator update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// When \[s\].
    pub time: f64,
    /// `‖β̂ − β‖₂ / ‖β‖₂` against the true base parameters at that time.
    pub parameter_error: f64,
    /// Wall time of the `update` call \[s\] (0 for nominal and oracle).
    pub update_s: f64,
}

/// What one run produced.
#[derive(Debug, Clone)]
pub struct ArmOutput {
    /// Sample times \[s\] (every `sample_every` control steps).
    pub times: Vec<f64>,
    /// Flange-origin position error `‖p(q) − p(q_d)‖` per sample \[m\].
    pub flange_error: Vec<f64>,
    /// Largest joint error `max_j |q_j − q_dj|` per sample \[rad\].
    pub joint_error: Vec<f64>,
    /// Every estimate (one per window; nominal and oracle are evaluated on the same grid).
    pub updates: Vec<UpdateRecord>,
    /// The last base-parameter estimate.
    pub final_estimate: Vec<f64>,
    /// The true base parameters at the end.
    pub final_truth: Vec<f64>,
    /// `true` if the run stopped early (tracking error or a failed step).
    pub aborted: bool,
    /// Estimates that passed the safety gate and reached the controller.
    pub accepted: usize,
    /// Estimates the safety gate rejected (the controller kept its parameters).
    pub rejected: usize,
    /// Of those, the estimates the predicted-torque gate rejected.
    pub torque_rejected: usize,
    /// The log, if asked for.
    pub log: Option<ArmLog>,
}

/// Largest factor between the controller's joint-space inertia and the nominal one (both with
/// the armature) that the safety gate admits. The true inertia with a 2 kg payload 20 cm
/// from a UR5's or a Panda's flange joint stays within it (a test checks).
pub const GATE_INERTIA_RATIO: f64 = 4.0;

/// Smallest pseudo-inertia eigenvalue \[kg m²\] of the flange body after the gate's projection
/// (payload scope; docs/CONVENTIONS.md §1).
pub const GATE_MIN_PSEUDO_INERTIA: f64 = 1e-6;

/// The safety gate of an estimate `beta`: its parameters for the controller, or `None`.
///
/// In the payload scope the flange body is first projected onto the physically consistent set
/// (eigenvalue clipping of its pseudo-inertia at [`GATE_MIN_PSEUDO_INERTIA`]). The estimator
/// keeps its own estimate. The gate passes when every value is finite and the controller's
/// mass matrix with it (plus the
/// armature) lies within a factor [`GATE_INERTIA_RATIO`] of the nominal one in every direction
/// at the sensed posture `q` (generalised eigenvalues): the computed-torque gains then stay
/// within that factor of their design. Physical consistency of a body is not asked: the small flange link's
/// inertia is barely excited, and the check would reject most useful estimates.
fn gate(
    model: &ArmModel,
    base: &BaseParameters,
    beta: &[f64],
    nominal: &[f64],
    effects: &JointEffects,
    q: &[f64],
) -> Option<Vec<InertialParams>> {
    if !beta.iter().all(|x| x.is_finite()) {
        return None;
    }
    let full = base.to_full(beta, nominal);
    let mut params = params_of(&full).ok()?;
    let n_b = params.len();
    if base.columns.len() == 10 && base.columns[0] == 10 * (n_b - 1) {
        params[n_b - 1] = params[n_b - 1].project_to_consistent(GATE_MIN_PSEUDO_INERTIA);
    }
    let mut tree = model.tree.clone();
    tree.set_params(&params).ok()?;
    let mut m = tree.mass_matrix(q).ok()?;
    let mut m0 = model.tree.mass_matrix(q).ok()?;
    for j in 0..q.len() {
        m[(j, j)] += effects.armature[j];
        m0[(j, j)] += effects.armature[j];
    }
    // Generalised eigenvalues of (M̂, M₀): those of L⁻¹ M̂ L⁻ᵀ with M₀ = L Lᵀ.
    let l = m0.cholesky()?.l();
    let x = l.solve_lower_triangular(&m)?;
    let y = l.solve_lower_triangular(&x.transpose())?;
    let sym = (&y + y.transpose()) * 0.5;
    let eig = sym.symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    (lo >= 1.0 / GATE_INERTIA_RATIO && hi <= GATE_INERTIA_RATIO).then_some(params)
}

/// Default half-width of the estimator's Savitzky–Golay filter: 5 samples, 50 ms at 100 Hz.
/// Its `q̈` noise gain is 0.32, against 0.71 for the central difference. Wider fits bias
/// the estimate on exact data (UR5 payload, TAG-K: 1.2 % at `h = 1`, 2.0 % at 2, 5.5 % at 5).
pub const DEFAULT_FILTER_HALF_WIDTH: usize = 2;

/// Factor on the measured torque noise in the predicted-torque gate.
///
/// The true parameters' residual also holds the regressor's own errors (filtered `q̈`
/// noise). Measured: 0.062 N m against a threshold of 0.10 N m (Panda, realistic sensing).
pub const TORQUE_GATE_FACTOR: f64 = 3.0;

/// The Savitzky–Golay fit at the centre of `x`: `(value, slope)`.
///
/// `x` holds `2h + 1` samples `dt` \[s\] apart. A quadratic is fitted by least squares
/// (`tagk_dynamics::deriv`). The value is the smoothed sample, the slope its time
/// derivative \[1/s\]. Both are exact for quadratics. The estimator applies it to `q`, `q̇`
/// and `τ` alike. Fewer than 3 samples give `(x[centre], 0)`.
pub fn centre_fit(dt: f64, x: &[f64]) -> (f64, f64) {
    let len = x.len();
    if len < 3 {
        return (x.get(len / 2).copied().unwrap_or(0.0), 0.0);
    }
    let h = (len - 1) / 2;
    let t: Vec<f64> = (0..len).map(|k| k as f64 * dt).collect();
    (
        savitzky_golay_smooth(&t, x, h)[h],
        savitzky_golay_derivative(&t, x, h)[h],
    )
}

/// Noise gain of [`centre_fit`]'s value at half-width `h`: `√(3(3h²+3h−1) / ((2h−1)(2h+1)(2h+3)))`
/// (1 at `h = 1`, 0.45 at `h = 5`).
pub fn smoothing_noise_gain(h: usize) -> f64 {
    if h == 0 {
        return 1.0;
    }
    let h = h as f64;
    (3.0 * (3.0 * h * h + 3.0 * h - 1.0) / ((2.0 * h - 1.0) * (2.0 * h + 1.0) * (2.0 * h + 3.0)))
        .sqrt()
}

/// RMS torque residual \[N m\] of `x` on a window: `√(Σ (b − A x)² / rows)`.
///
/// `a` holds `b.len()` rows of `x.len()` columns, row-major. NaN for an empty window or a
/// size mismatch.
pub fn torque_residual(a: &[f64], b: &[f64], x: &[f64]) -> f64 {
    let cols = x.len();
    if b.is_empty() || cols == 0 || a.len() != b.len() * cols {
        return f64::NAN;
    }
    let ss: f64 = a
        .chunks(cols)
        .zip(b)
        .map(|(row, bi)| {
            let p: f64 = row.iter().zip(x).map(|(ai, xi)| ai * xi).sum();
            (bi - p) * (bi - p)
        })
        .sum();
    (ss / b.len() as f64).sqrt()
}

/// Threshold \[N m\] of the predicted-torque gate.
///
/// `sigma_1k` is the measured torque noise of one control step \[N m\]. Block means of
/// `sample_every` steps and the filter of half-width `h` reduce it. The gate allows
/// [`TORQUE_GATE_FACTOR`] times that, combined in quadrature with `offset` \[N m\], the
/// largest unmodelled torque offset of the sensing.
pub fn torque_gate_threshold(sigma_1k: f64, sample_every: usize, h: usize, offset: f64) -> f64 {
    let s = sigma_1k / (sample_every.max(1) as f64).sqrt() * smoothing_noise_gain(h);
    ((TORQUE_GATE_FACTOR * s).powi(2) + offset * offset).sqrt()
}

fn params_of(theta: &[f64]) -> Result<Vec<InertialParams>, SimError> {
    theta
        .chunks(10)
        .map(|c| InertialParams::from_slice(c).map_err(SimError::from))
        .collect()
}

/// Runs the arm in closed loop (see the [module docs](super)).
///
/// `base` says which parameters the estimator learns (and in which combinations). Nominal
/// and oracle runs use it only to score their parameters.
///
/// # Errors
/// [`SimError::InvalidDuration`] / [`SimError::InvalidParameter`] for a bad configuration,
/// [`SimError::Dynamics`] for inputs the dynamics reject, [`SimError::Estimator`] if an
/// estimator rejects a window. A run that diverges is not an error: it is `aborted`.
pub fn simulate_arm(
    model: &ArmModel,
    base: &BaseParameters,
    config: &ArmSimConfig,
) -> Result<ArmOutput, SimError> {
    for (what, v) in [
        ("duration", config.duration),
        ("control_dt", config.control_dt),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(SimError::InvalidDuration { what, value: v });
        }
    }
    if config.sample_every == 0 || config.window == 0 {
        return Err(SimError::InvalidParameter {
            name: "sample_every / window",
            value: 0.0,
            reason: "at least 1",
        });
    }
    if config.filter_half_width == 0 {
        return Err(SimError::InvalidParameter {
            name: "filter_half_width",
            value: 0.0,
            reason: "at least 1",
        });
    }
    let wn = config.natural_frequency;
    if !(wn.is_finite() && wn > 0.0) {
        return Err(SimError::InvalidParameter {
            name: "natural_frequency",
            value: wn,
            reason: "positive and finite",
        });
    }
    let n = model.dof();
    let nb = model.tree.n_bodies();
    let flange = model.flange();
    let (kp, kd) = (wn * wn, 2.0 * wn);
    let dt = config.control_dt;
    let sample_dt = dt * config.sample_every as f64;

    // The truth and the nominal model.
    let mut true_tree = model.tree.clone();
    if let Some(links) = &config.true_links {
        true_tree.set_params(links)?;
    }
    let mut plant = ArmPlant::new(true_tree, config.effects.clone())?;
    let nominal_theta: Vec<f64> = model.tree.params_vector().iter().copied().collect();
    let truth_theta = |p: &ArmPlant| -> Vec<f64> { p.params_vector().iter().copied().collect() };

    // The controller's parameters.
    let mut ctrl_params = model.tree.params();
    let beta0 = base.to_base(&nominal_theta);
    let r = base.rank();
    // Column scales: the estimator's unknowns are x = β ⊙ s (all ones unless scaled).
    let col_scale: Vec<f64> = match config.adaptation.estimator() {
        Some((_, true)) => base.scales.clone(),
        _ => vec![1.0; r],
    };
    let mut estimator: Option<Box<dyn OnlineEstimator<f64> + Send>> =
        match config.adaptation.estimator() {
            Some((kind, _)) => {
                let mut e = crate::estimators::build_kind(
                    kind,
                    r,
                    crate::estimators::DEFAULT_BURN_IN,
                    config.window * n,
                    config.seed ^ 0x5EED,
                    0.0,
                )?;
                let x0: Vec<f64> = beta0.iter().zip(&col_scale).map(|(b, s)| b * s).collect();
                e.reset(&x0)?;
                Some(e)
            }
            None => None,
        };
    let mut current_estimate = beta0.clone();
    if config.adaptation == ArmAdaptation::Oracle {
        ctrl_params = plant.tree().params();
        current_estimate = base.to_base(&truth_theta(&plant));
    }

    // Sensing.
    let mut noise: ChaCha8Rng = crate::sim::sub_rng(config.seed, 0xA4);
    let mut offset_rng: ChaCha8Rng = crate::sim::sub_rng(config.seed, 0xA5);
    let offsets: Vec<f64> = (0..n)
        .map(|_| {
            let u: f64 = offset_rng.random_range(-1.0..1.0);
            u * config.sensing.torque_offset
        })
        .collect();
    let sense = &config.sensing;

    let r0 = config.trajectory.sample(0.0);
    let mut state = ArmState {
        q: r0.q.clone(),
        qd: r0.qd.clone(),
    };
    let steps = (config.duration / dt).round() as usize;
    let mut out = ArmOutput {
        times: Vec::new(),
        flange_error: Vec::new(),
        joint_error: Vec::new(),
        updates: Vec::new(),
        final_estimate: Vec::new(),
        final_truth: Vec::new(),
        aborted: false,
        accepted: 0,
        rejected: 0,
        torque_rejected: 0,
        log: config.record_log.then(|| ArmLog {
            dof: n,
            rows: Vec::with_capacity(steps),
        }),
    };
    let mut ws = model.tree.workspace();
    let mut tau = vec![0.0; n];
    let mut v = vec![0.0; n];
    let mut next_event = 0;
    // The controller's base parameters (the incumbent of the predicted-torque gate).
    let mut ctrl_beta = current_estimate.clone();
    // The last estimate, waiting to be judged on the next window's torques.
    let mut pending: Option<Vec<f64>> = None;
    // Measured torque noise: squared successive differences of the sensed 1 kHz torques.
    let mut prev_tau: Option<Vec<f64>> = None;
    let (mut diff_ss, mut diff_count) = (0.0, 0usize);
    let h = config.filter_half_width;
    let span = 2 * h + 1;
    // Samples (q, q̇, τ) for the filter, and the window being filled.
    let mut history: std::collections::VecDeque<(Vec<f64>, Vec<f64>, Vec<f64>)> =
        std::collections::VecDeque::with_capacity(span + 1);
    let mut block = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut a_rows: Vec<f64> = Vec::with_capacity(config.window * n * r);
    let mut b_rows: Vec<f64> = Vec::with_capacity(config.window * n);
    let mut reg = vec![0.0; n * 10 * nb];
    let not_estimated: Vec<usize> = (0..10 * nb).filter(|c| !base.columns.contains(c)).collect();
    let model_effects = &config.effects;
    let zeros = vec![0.0; n];

    for k in 0..steps {
        let t = k as f64 * dt;
        while next_event < config.events.len() && config.events[next_event].time <= t {
            plant.set_payload(config.events[next_event].payload)?;
            next_event += 1;
            if config.adaptation == ArmAdaptation::Oracle {
                ctrl_params = plant.tree().params();
                current_estimate = base.to_base(&truth_theta(&plant));
            }
        }
        // Sensing.
        let q_m: Vec<f64> = state
            .q
            .iter()
            .map(|&q| {
                if sense.encoder_resolution > 0.0 {
                    (q / sense.encoder_resolution).round() * sense.encoder_resolution
                } else {
                    q
                }
            })
            .collect();
        let qd_m: Vec<f64> = state
            .qd
            .iter()
            .map(|&x| {
                if sense.velocity_noise > 0.0 {
                    x + sense.velocity_noise * gaussian(&mut noise)
                } else {
                    x
                }
            })
            .collect();
        // Computed-torque control with the controller's parameters.
        let reference = config.trajectory.sample(t);
        for j in 0..n {
            v[j] = reference.qdd[j]
                + kd * (reference.qd[j] - qd_m[j])
                + kp * (reference.q[j] - q_m[j]);
        }
        model
            .tree
            .rnea_into(&q_m, &qd_m, &v, &ctrl_params, &mut ws, &mut tau)?;
        let te = model_effects.torque(&qd_m, &v)?;
        for j in 0..n {
            let lim = model.limits.effort[j];
            tau[j] = (tau[j] + te[j]).clamp(-lim, lim);
        }
        let tau_m: Vec<f64> = (0..n)
            .map(|j| {
                let e = if sense.torque_noise > 0.0 {
                    sense.torque_noise * gaussian(&mut noise)
                } else {
                    0.0
                };
                tau[j] + offsets[j] + e
            })
            .collect();
        if let Some(p) = &prev_tau {
            diff_ss += p
                .iter()
                .zip(&tau_m)
                .map(|(a, b)| (b - a).powi(2))
                .sum::<f64>();
            diff_count += n;
        }
        prev_tau = Some(tau_m.clone());

        if k % config.sample_every == 0 {
            let jerr = (0..n)
                .map(|j| (state.q[j] - reference.q[j]).abs())
                .fold(0.0, f64::max);
            let p = model.tree.forward_kinematics(&state.q)?[flange].translation;
            let pd = model.tree.forward_kinematics(&reference.q)?[flange].translation;
            out.times.push(t);
            out.joint_error.push(jerr);
            out.flange_error.push((p - pd).norm());
            if jerr.is_nan() || jerr > config.abort_error {
                out.aborted = true;
                break;
            }
        }
        // The estimator's samples: block means of the sensed signals over `sample_every`
        // control steps (decimation; the noise falls by √sample_every). The known friction
        // and offset are removed from each 1 kHz torque first: Coulomb friction is too
        // nonlinear in q̇ to be removed after the filter.
        let friction = model_effects.torque(&qd_m, &zeros)?;
        for j in 0..n {
            block.0[j] += q_m[j];
            block.1[j] += qd_m[j];
            block.2[j] += tau_m[j] - friction[j];
        }
        if (k + 1) % config.sample_every == 0 {
            let inv = 1.0 / config.sample_every as f64;
            let mean = |v: &mut Vec<f64>| -> Vec<f64> {
                let m = v.iter().map(|x| x * inv).collect();
                v.fill(0.0);
                m
            };
            history.push_back((mean(&mut block.0), mean(&mut block.1), mean(&mut block.2)));
            if history.len() > span {
                history.pop_front();
            }
            if history.len() == span {
                // The row of the centre sample: q, q̇, q̈ and τ from the same Savitzky–Golay
                // fit (h samples late).
                let mut q1 = vec![0.0; n];
                let mut qd1 = vec![0.0; n];
                let mut qdd1 = vec![0.0; n];
                let mut tau1 = vec![0.0; n];
                let mut xs = vec![0.0; span];
                for j in 0..n {
                    for (x, s) in xs.iter_mut().zip(&history) {
                        *x = s.0[j];
                    }
                    q1[j] = centre_fit(sample_dt, &xs).0;
                    for (x, s) in xs.iter_mut().zip(&history) {
                        *x = s.1[j];
                    }
                    (qd1[j], qdd1[j]) = centre_fit(sample_dt, &xs);
                    for (x, s) in xs.iter_mut().zip(&history) {
                        *x = s.2[j];
                    }
                    tau1[j] = centre_fit(sample_dt, &xs).0;
                }
                model
                    .tree
                    .joint_torque_regressor_into(&q1, &qd1, &qdd1, &mut ws, &mut reg)?;
                // The armature's share (the effects at zero velocity, minus the offset).
                let te_a = model_effects.torque(&zeros, &qdd1)?;
                let te_0 = model_effects.torque(&zeros, &zeros)?;
                let te1: Vec<f64> = te_a.iter().zip(&te_0).map(|(a, b)| a - b).collect();
                let cols = 10 * nb;
                for row in 0..n {
                    let y = &reg[row * cols..(row + 1) * cols];
                    let known: f64 = not_estimated.iter().map(|&c| y[c] * nominal_theta[c]).sum();
                    b_rows.push(tau1[row] - te1[row] - known);
                    a_rows.extend(
                        base.independent
                            .iter()
                            .zip(&col_scale)
                            .map(|(&i, s)| y[base.columns[i]] / s),
                    );
                }
                if b_rows.len() == config.window * n {
                    let mut update_s = 0.0;
                    let scaled = |beta: &[f64]| -> Vec<f64> {
                        beta.iter().zip(&col_scale).map(|(b, s)| b * s).collect()
                    };
                    let flat = |p: &[InertialParams]| -> Vec<f64> {
                        p.iter().flat_map(|x| x.to_array()).collect()
                    };
                    if let Some(e) = estimator.as_mut() {
                        // The previous window's estimate, judged on this window's torques
                        // (which it has not seen) against the controller's parameters.
                        if let Some(cand) = pending.take() {
                            let sigma_1k = if diff_count > 0 {
                                (diff_ss / (2.0 * diff_count as f64)).sqrt()
                            } else {
                                0.0
                            };
                            let threshold = torque_gate_threshold(
                                sigma_1k,
                                config.sample_every,
                                h,
                                sense.torque_offset,
                            );
                            let r_cand = torque_residual(&a_rows, &b_rows, &scaled(&cand));
                            let r_ctrl = torque_residual(&a_rows, &b_rows, &scaled(&ctrl_beta));
                            let passes = r_cand <= threshold.max(r_ctrl);
                            if !passes {
                                out.rejected += 1;
                                out.torque_rejected += 1;
                            } else if let Some(params) =
                                gate(model, base, &cand, &nominal_theta, &config.effects, &q_m)
                            {
                                ctrl_beta = base.to_base(&flat(&params));
                                ctrl_params = params;
                                out.accepted += 1;
                            } else {
                                out.rejected += 1;
                            }
                        }
                        let start = Instant::now();
                        e.update(&a_rows, &b_rows)?;
                        update_s = start.elapsed().as_secs_f64();
                        current_estimate = e
                            .estimate()
                            .iter()
                            .zip(&col_scale)
                            .map(|(x, s)| x / s)
                            .collect();
                        if config.torque_gate {
                            pending = Some(current_estimate.clone());
                        } else if let Some(params) = gate(
                            model,
                            base,
                            &current_estimate,
                            &nominal_theta,
                            &config.effects,
                            &q_m,
                        ) {
                            ctrl_beta = base.to_base(&flat(&params));
                            ctrl_params = params;
                            out.accepted += 1;
                        } else {
                            out.rejected += 1;
                        }
                    }
                    diff_ss = 0.0;
                    diff_count = 0;
                    let truth = base.to_base(&truth_theta(&plant));
                    let num: f64 = current_estimate
                        .iter()
                        .zip(&truth)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum::<f64>()
                        .sqrt();
                    let den = truth.iter().map(|b| b * b).sum::<f64>().sqrt().max(1e-12);
                    out.updates.push(UpdateRecord {
                        time: t,
                        parameter_error: num / den,
                        update_s,
                    });
                    a_rows.clear();
                    b_rows.clear();
                }
            }
        }

        let qdd = match plant.step_rk4(&mut state, &tau, dt) {
            Ok(a) => a,
            Err(_) => {
                out.aborted = true;
                break;
            }
        };
        if let Some(log) = out.log.as_mut() {
            let mut row = Vec::with_capacity(1 + 4 * n);
            row.push(t);
            row.extend_from_slice(&q_m);
            row.extend_from_slice(&qd_m);
            row.extend(qdd.iter().copied());
            row.extend_from_slice(&tau_m);
            log.rows.push(row);
        }
    }
    out.final_estimate = current_estimate;
    out.final_truth = base.to_base(&truth_theta(&plant));
    Ok(out)
}

/// A payload: a solid box of `mass` \[kg\] and edge `size` \[m\] centred at `centre` (flange
/// body frame) \[m\], as the parameters to add to the flange body.
pub fn box_payload(mass: f64, centre: Vector3<f64>, size: f64) -> Result<InertialParams, SimError> {
    if !(mass.is_finite() && mass > 0.0) {
        return Err(SimError::NonPositiveMass {
            what: "payload",
            mass,
        });
    }
    if !(size.is_finite() && size >= 0.0 && centre.iter().all(|c| c.is_finite())) {
        return Err(SimError::InvalidParameter {
            name: "payload size or centre",
            value: size,
            reason: "finite, size ≥ 0",
        });
    }
    Ok(InertialParams::solid_box(
        mass,
        centre,
        Vector3::repeat(size),
    ))
}
