//! Diagnosis on joint torques: a fixed-base arm's model against a joint-space log.
//!
//! The same loop as the quadrotor's: compare the model with the data, say where it fails
//! (per joint), find the missing effect, add it, watch the error fall. The model is the
//! robot's URDF (a [`KinematicTree`]); the log a [`JointLog`] (docs/ARM_LOG.md).
//!
//! **Starting model.** The rigid body at the URDF's parameters: `τ = Y(q, q̇, q̈) θ_URDF`.
//! The residual `τ − Y θ_URDF` is what the candidates must explain. Holding the URDF fixed is
//! what makes a payload visible: with every inertial parameter free, a change of the last
//! link would be absorbed by the fit.
//!
//! **Candidates** ([`ArmEffect`]): the joint effects of [`tagk_dynamics::joint_effect`]
//! (one coefficient per joint) and `payload`, the change of the payload body's ten inertial
//! parameters relative to the URDF's (`KinematicTree::payload_body`: the last body of a serial
//! arm, the hand of an arm with a two-finger gripper), reduced to the combinations the log identifies
//! ([`BaseReduction`]). `joint-elasticity` is refused with the reason
//! ([`ELASTICITY_REASON`]).
//!
//! **Noise.** Each joint's torque noise `σ_j` is measured from the residual's second
//! differences (the quadrotor's estimate: the median of the squared second differences over `6 × 0.4549`). Every
//! decision is made in units of it.
//!
//! **Selection.** Blocked cross-validation: the log is cut into `folds` contiguous blocks;
//! each block is predicted by the model fitted on the others. An effect's held-out gain is
//! `G = Σ_j Σ_i (e_before² − e_after²) / σ_j²` over every held-out sample. It is admitted
//! when (a) `G` exceeds the quadrotor's chance margin `2 √max(G, 1)`, (b) `G` per sample is
//! at least [`MIN_GAIN`], and (c) its coefficients differ from zero by a
//! Wald χ² test at level [`ArmOptions::significance`]. Forward steps add the admissible
//! effect of largest gain. At the end, an effect that no longer passes within the final
//! model is dropped, and the staircase shows the final effects in the order of their gain.
//! If the final model's residual shows a clearly lower noise on a joint
//! (a missing effect had inflated it), the search runs again against it (at most twice).
//!
//! **Intervals.** Weighted least squares (rows scaled by `1/σ_j`). The covariance is
//! `s² (XᵀX)⁻¹`, `s²` the residual variance per row. Each coefficient's variance is inflated
//! by the batch-means long-run variance factor of its joint's residual
//! (the quadrotor's batch means); a payload coefficient by the largest of them.
//! The interval is `value ± 1.96 std_error`.
//!
//! **Base parameters.** The report also fits every identifiable inertial combination: the
//! stacked rigid regressor is reduced by QR with column pivoting ([`BaseReduction`],
//! tolerance [`BASE_TOLERANCE`] on `|R_kk| / |R_00|`), and the base parameters are fitted
//! with the final model's joint effects, with 95 % intervals, beside the URDF's values.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use tagk_dynamics::{InertialParams, JointEffectKind, JointLog, KinematicTree};

use crate::diagnose::chance_margin;
use crate::error::DiagnoseError;
use crate::fit::{Coefficient, Z_95};
use crate::stats;
use crate::{ADEQUACY_FACTOR, MIN_GAIN};

/// Relative tolerance of the base-parameter reduction: a pivot `|R_kk|` at or below
/// `1e-8 |R_00|` ends the numerical rank.
pub const BASE_TOLERANCE: f64 = 1e-8;

/// Length \[s\] of the Savitzky–Golay window that derives `q̈` from `q̇` by default (0.1 s:
/// the quadrotor's 11 samples at 100 Hz).
pub const DERIVATIVE_WINDOW: f64 = 0.1;

/// Default level of the Wald test an added effect's coefficients must pass (10⁻³).
pub const ARM_SIGNIFICANCE: f64 = 1e-3;

/// Relative tolerance below which an effect's column, projected off the rigid body's base
/// columns, is not identifiable beside them (its residual norm over its norm).
pub const EFFECT_IDENTIFIABILITY: f64 = 1e-5;

/// A noise estimate lower than this fraction of the one searched against runs the search
/// again (0.8).
pub const NOISE_RERUN_RATIO: f64 = 0.8;

/// Why `joint-elasticity` is no candidate on a log of one position per joint.
pub const ELASTICITY_REASON: &str = "a joint's elasticity `k (θ_m − q)` needs the motor-side \
position θ_m beside the link-side q; from q and τ alone the deflection is τ/k and its effect \
on the torque enters through the fourth derivative of q, which a log cannot give (log both \
encoders to diagnose it)";

/// The names of the parameters of one body, in the order of [`InertialParams`].
pub const PARAMETER_NAMES: [&str; 10] = [
    "m", "h_x", "h_y", "h_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz",
];

/// The unit of each parameter of [`PARAMETER_NAMES`].
pub const PARAMETER_UNITS: [&str; 10] = [
    "kg", "kg m", "kg m", "kg m", "kg m^2", "kg m^2", "kg m^2", "kg m^2", "kg m^2", "kg m^2",
];

/// A candidate effect of the joint-torque diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ArmEffect {
    /// A joint effect, one coefficient per joint.
    Joint(JointEffectKind),
    /// A change of the payload body's inertial parameters relative to the URDF's
    /// ([`KinematicTree::payload_body`]: the last body of a serial arm, a gripper's hand).
    Payload,
}

impl ArmEffect {
    /// Every candidate, in the order of the report.
    pub const ALL: [ArmEffect; 5] = [
        ArmEffect::Joint(JointEffectKind::ViscousFriction),
        ArmEffect::Joint(JointEffectKind::CoulombFriction),
        ArmEffect::Joint(JointEffectKind::Armature),
        ArmEffect::Joint(JointEffectKind::TorqueOffset),
        ArmEffect::Payload,
    ];

    /// The kebab-case name (`viscous-friction`, …, `payload`).
    pub fn name(self) -> &'static str {
        match self {
            ArmEffect::Joint(k) => k.name(),
            ArmEffect::Payload => "payload",
        }
    }

    /// The effect of a name.
    ///
    /// # Errors
    /// [`DiagnoseError::EffectUnavailable`] for `joint-elasticity` (with
    /// [`ELASTICITY_REASON`]) and for a name outside the vocabulary.
    pub fn from_name(name: &str) -> Result<Self, DiagnoseError> {
        if let Some(e) = Self::ALL.into_iter().find(|e| e.name() == name) {
            return Ok(e);
        }
        let reason = if name == "joint-elasticity" {
            ELASTICITY_REASON.to_string()
        } else {
            format!(
                "not an arm effect (known: {}, joint-elasticity)",
                Self::ALL.map(ArmEffect::name).join(", ")
            )
        };
        Err(DiagnoseError::EffectUnavailable {
            effect: name.to_string(),
            reason,
        })
    }
}

/// Settings of [`diagnose_arm`].
#[derive(Debug, Clone, PartialEq)]
pub struct ArmOptions {
    /// Blocks of the cross-validation (at least 2; default 5).
    pub folds: usize,
    /// Half-width (samples) of the Savitzky–Golay derivative that gives `q̈` when the log
    /// has none; `None`: the samples within ±[`DERIVATIVE_WINDOW`]/2 of the median step (5 at
    /// 100 Hz, the quadrotor's default), at least 2.
    pub half_width: Option<usize>,
    /// Most effects the search adds (default 5).
    pub max_steps: usize,
    /// Torque noise per joint \[N m\] (a sensor specification); `None`: measured.
    pub noise: Option<Vec<f64>>,
    /// Tolerance of the base-parameter reduction ([`BASE_TOLERANCE`]).
    pub base_tolerance: f64,
    /// Level of the Wald test ([`ARM_SIGNIFICANCE`]).
    pub significance: f64,
    /// The candidates searched (default: all of [`ArmEffect::ALL`]).
    pub candidates: Vec<ArmEffect>,
    /// Whether to fit the rigid body's base parameters for the report (costs one QR of the
    /// stacked regressor).
    pub base_parameters: bool,
}

impl Default for ArmOptions {
    fn default() -> Self {
        Self {
            folds: 5,
            half_width: None,
            max_steps: 5,
            noise: None,
            base_tolerance: BASE_TOLERANCE,
            significance: ARM_SIGNIFICANCE,
            candidates: ArmEffect::ALL.to_vec(),
            base_parameters: true,
        }
    }
}

/// A numerical base of a regressor's columns: the independent columns and how the others
/// combine into them.
///
/// With `W P = Q R` (QR with column pivoting), the rank `r` is the number of pivots with
/// `|R_kk| > tolerance · |R_00|`. The first `r` pivoted columns are independent; the others
/// are `W_dep = W_ind K` with `K = R₁₁⁻¹ R₁₂`. The base parameters are `β = θ_ind + K θ_dep`:
/// `W θ = W_ind β`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BaseReduction {
    /// Columns of the regressor.
    pub n_params: usize,
    /// Numerical rank.
    pub rank: usize,
    /// Independent columns, in pivot order.
    pub independent: Vec<usize>,
    /// Dependent columns, in pivot order.
    pub dependent: Vec<usize>,
    /// `K` (`rank × dependent`), row-major per independent column.
    pub combination: Vec<Vec<f64>>,
    /// The tolerance used.
    pub tolerance: f64,
    /// `|R_kk| / |R_00|` for every pivot.
    pub pivots: Vec<f64>,
}

impl BaseReduction {
    /// The reduction of the regressor `w` (rows: samples × joints; columns: parameters).
    ///
    /// # Errors
    /// [`DiagnoseError::Fit`] for a non-finite regressor or one without a non-zero column.
    pub fn of(w: &DMatrix<f64>, tolerance: f64) -> Result<Self, DiagnoseError> {
        if w.iter().any(|x| !x.is_finite()) {
            return Err(DiagnoseError::Fit("non-finite regressor".into()));
        }
        let n = w.ncols();
        let qr = w.clone().col_piv_qr();
        let r = qr.r();
        let mut order = DMatrix::<f64>::from_fn(1, n, |_, c| c as f64);
        qr.p().permute_columns(&mut order);
        let order: Vec<usize> = order.iter().map(|x| *x as usize).collect();
        let d0 = r[(0, 0)].abs();
        if d0 == 0.0 {
            return Err(DiagnoseError::Fit("the regressor is zero".into()));
        }
        let k_max = r.nrows().min(n);
        let pivots: Vec<f64> = (0..k_max).map(|k| r[(k, k)].abs() / d0).collect();
        let rank = pivots.iter().take_while(|p| **p > tolerance).count();
        let r11 = r.view((0, 0), (rank, rank)).into_owned();
        let r12 = r.view((0, rank), (rank, n - rank)).into_owned();
        let k = r11
            .solve_upper_triangular(&r12)
            .ok_or_else(|| DiagnoseError::Fit("singular base block".into()))?;
        Ok(Self {
            n_params: n,
            rank,
            independent: order[..rank].to_vec(),
            dependent: order[rank..].to_vec(),
            combination: (0..rank)
                .map(|i| k.row(i).iter().copied().collect())
                .collect(),
            tolerance,
            pivots,
        })
    }

    /// The base parameters `β = θ_ind + K θ_dep` of a full parameter vector `θ`.
    pub fn base_values(&self, theta: &[f64]) -> Vec<f64> {
        self.independent
            .iter()
            .zip(&self.combination)
            .map(|(&i, k)| {
                theta[i]
                    + self
                        .dependent
                        .iter()
                        .zip(k)
                        .map(|(&d, c)| c * theta[d])
                        .sum::<f64>()
            })
            .collect()
    }

    /// A readable name of base parameter `i`: its independent column's name plus the
    /// dependent ones it absorbs (coefficients below 10⁻⁹ left out).
    pub fn base_name(&self, i: usize, names: &[String]) -> String {
        let mut s = names[self.independent[i]].clone();
        for (&d, c) in self.dependent.iter().zip(&self.combination[i]) {
            if c.abs() > 1e-9 {
                let sign = if *c < 0.0 { '-' } else { '+' };
                s += &format!(" {sign} {:.4}·{}", c.abs(), names[d]);
            }
        }
        s
    }
}

/// One joint of one step: its held-out residual against its noise.
#[derive(Debug, Clone, Serialize)]
pub struct StepJoint {
    /// The joint's name (URDF).
    pub name: String,
    /// Held-out residual RMS \[N m\].
    pub held_out_rms: f64,
    /// The joint's torque noise \[N m\].
    pub noise: f64,
    /// `held_out_rms / noise`.
    pub ratio_to_noise: f64,
    /// `true` when the ratio is within [`ADEQUACY_FACTOR`].
    pub adequate: bool,
    /// Relative change of the held-out RMS from the previous step (0 for the first).
    pub change: f64,
}

/// One step of the staircase: the model after adding `effect`.
#[derive(Debug, Clone, Serialize)]
pub struct ArmStep {
    /// The effect this step adds (`null` for the starting model).
    pub effect: Option<String>,
    /// The step's model label (`rigid body (URDF) + …`).
    pub model: String,
    /// Held-out residual RMS per joint \[N m\].
    pub held_out_rms: Vec<f64>,
    /// Per joint: held-out RMS, noise, change.
    pub joints: Vec<StepJoint>,
    /// Held-out gain of the step in units of the noise variance, summed over samples and
    /// joints (0 for the first step).
    pub gain: f64,
    /// Wald statistic of the added effect's coefficients and its degrees of freedom.
    pub wald: Option<(f64, usize)>,
    /// The added effect's coefficients in this step's model, with 95 % intervals.
    pub coefficients: Vec<Coefficient>,
}

/// The final model of the staircase.
#[derive(Debug, Clone, Serialize)]
pub struct ArmFinalModel {
    /// The effects added to the rigid body.
    pub effects: Vec<String>,
    /// Their coefficients, fitted jointly, with 95 % intervals.
    pub coefficients: Vec<Coefficient>,
}

/// The identifiable combinations of the payload body's parameters a payload changes.
#[derive(Debug, Clone, Serialize)]
pub struct PayloadBasis {
    /// The body (URDF link) that carries the payload: [`KinematicTree::payload_body`].
    pub body: String,
    /// The reduction of its ten regressor columns.
    pub reduction: BaseReduction,
}

impl PayloadBasis {
    /// The payload coefficients (the base combinations) of a change `delta` of the body's
    /// parameters.
    pub fn coefficients_of(&self, delta: &InertialParams) -> Vec<f64> {
        self.reduction.base_values(&delta.to_array())
    }
}

/// One base parameter of the rigid body, fitted.
#[derive(Debug, Clone, Serialize)]
pub struct BaseParameter {
    /// The fitted value with its interval (its name shows the combination).
    pub coefficient: Coefficient,
    /// The URDF's value of the same combination.
    pub urdf: f64,
    /// `(value − urdf) / std_error`.
    pub z: Option<f64>,
}

/// The rigid body's base parameters fitted with the final model's joint effects.
#[derive(Debug, Clone, Serialize)]
pub struct BaseParameters {
    /// Parameters of the full model (`10 × bodies`).
    pub n_params: usize,
    /// Numerical rank of the stacked regressor: the number of base parameters.
    pub rank: usize,
    /// The tolerance of the reduction.
    pub tolerance: f64,
    /// The base parameters.
    pub parameters: Vec<BaseParameter>,
    /// The joint-effect coefficients fitted beside them.
    pub effects: Vec<Coefficient>,
    /// Joint-effect columns not identifiable beside the base parameters (absorbed by them).
    pub absorbed: Vec<String>,
    /// Held-out residual RMS per joint of this fit \[N m\].
    pub held_out_rms: Vec<f64>,
}

/// The outcome of [`diagnose_arm`]; its JSON has the quadrotor report's shape
/// (`recommended`, `steps[].effect`, `final_model.effects`).
#[derive(Debug, Clone, Serialize)]
pub struct ArmReport {
    /// The robot's name (URDF).
    pub robot: String,
    /// The joints' names, in log order.
    pub joints: Vec<String>,
    /// Samples in the log.
    pub samples: usize,
    /// `true` when the accelerations were derived from the velocities.
    pub derived_accelerations: bool,
    /// The first effect added (`null` when the URDF's rigid body is adequate).
    pub recommended: Option<String>,
    /// The staircase.
    pub steps: Vec<ArmStep>,
    /// The final model.
    pub final_model: ArmFinalModel,
    /// The torque noise per joint the search ran against \[N m\].
    pub noise: Vec<f64>,
    /// The noise measured on the final model's residual \[N m\].
    pub final_noise: Vec<f64>,
    /// `true` when every joint's held-out residual of the final model is within
    /// [`ADEQUACY_FACTOR`] of its noise.
    pub adequate: bool,
    /// Why the staircase stopped.
    pub stopped: String,
    /// The payload's identifiable combinations.
    pub payload: Option<PayloadBasis>,
    /// The rigid body's base parameters (absent when not asked for).
    pub base_parameters: Option<BaseParameters>,
    /// Candidates that cannot be diagnosed on this log, with the reason.
    pub unavailable: Vec<(String, String)>,
}

impl ArmReport {
    /// The report as pretty-printed JSON.
    ///
    /// # Errors
    /// [`DiagnoseError::Output`] if serialisation fails (it does not for finite numbers).
    pub fn to_json(&self) -> Result<String, DiagnoseError> {
        serde_json::to_string_pretty(self).map_err(|e| DiagnoseError::Output {
            path: "<json>".into(),
            message: e.to_string(),
        })
    }

    /// The names of the effects of the final model.
    pub fn found(&self) -> Vec<ArmEffect> {
        self.final_model
            .effects
            .iter()
            .filter_map(|n| ArmEffect::from_name(n).ok())
            .collect()
    }

    /// The terminal summary: the staircase per joint, the final coefficients, the base
    /// parameters.
    pub fn table(&self) -> String {
        let mut s = format!(
            "robot {} ({} joints), {} samples{}\n",
            self.robot,
            self.joints.len(),
            self.samples,
            if self.derived_accelerations {
                ", accelerations derived from the velocities"
            } else {
                ""
            }
        );
        s += "torque noise per joint [N m]: ";
        s += &self
            .noise
            .iter()
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join("  ");
        s += "\n\nheld-out residual RMS / noise per joint (* = within the noise):\n";
        s += &format!("{:<44}", "model");
        for j in 1..=self.joints.len() {
            s += &format!("{:>9}", format!("j{j}"));
        }
        s += &format!("{:>12}\n", "gain");
        for st in &self.steps {
            let label = st
                .effect
                .as_ref()
                .map_or_else(|| st.model.clone(), |e| format!("+ {e}"));
            s += &format!("{:<44}", truncate(&label, 43));
            for j in &st.joints {
                s += &format!(
                    "{:>9}",
                    format!(
                        "{:.2}{}",
                        j.ratio_to_noise,
                        if j.adequate { "*" } else { " " }
                    )
                );
            }
            s += &format!("{:>12.0}\n", st.gain);
        }
        s += &format!(
            "\nrecommended: {}\n",
            self.recommended
                .as_deref()
                .unwrap_or("nothing: the URDF's rigid body explains the torques")
        );
        if !self.final_model.coefficients.is_empty() {
            s += "\nfinal model coefficients (95 % intervals):\n";
            for c in &self.final_model.coefficients {
                s += &coefficient_line(c);
            }
        }
        if let Some(b) = &self.base_parameters {
            s += &format!(
                "\nbase parameters: {} of {} identifiable (QR with pivoting, tolerance {:e}); \
                 fitted with the final model's joint effects:\n",
                b.rank, b.n_params, b.tolerance
            );
            for p in &b.parameters {
                s += &format!(
                    "  {:<60} {:>11.5} ± {:<9.2e} URDF {:>10.5}\n",
                    truncate(&p.coefficient.name, 59),
                    p.coefficient.value,
                    p.coefficient.std_error.map_or(f64::NAN, |e| Z_95 * e),
                    p.urdf
                );
            }
            if !b.absorbed.is_empty() {
                s += &format!(
                    "  absorbed by the base parameters: {}\n",
                    b.absorbed.join(", ")
                );
            }
        }
        for (e, why) in &self.unavailable {
            s += &format!("\nnot a candidate: {e}: {why}\n");
        }
        s += &format!("\n{}\n", self.stopped);
        s
    }
}

fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        s.chars().take(n - 1).collect::<String>() + "…"
    }
}

fn coefficient_line(c: &Coefficient) -> String {
    match c.confidence_interval {
        Some([lo, hi]) => format!(
            "  {:<48} {:>11.5} [{:.5}, {:.5}] {}\n",
            c.name, c.value, lo, hi, c.unit
        ),
        None => format!(
            "  {:<48} {:>11.5} (not identifiable) {}\n",
            c.name, c.value, c.unit
        ),
    }
}

/// The measured torques, the regressors and the candidates' columns of one log.
struct Problem {
    dof: usize,
    samples: usize,
    /// Columns of the candidates (unweighted), row `i·dof + j`, row-major.
    x: Vec<f64>,
    /// Number of candidate columns.
    cols: usize,
    /// Residual of the URDF's rigid body `τ − Y θ_URDF` per row.
    y: Vec<f64>,
    /// Each candidate's columns.
    groups: Vec<(ArmEffect, Vec<usize>)>,
    /// Each column's name, unit and joint (`None`: several joints).
    info: Vec<(String, String, Option<usize>)>,
}

/// Gram matrices of weighted rows, per fold and joint.
struct FoldGrams {
    folds: usize,
    dof: usize,
    g: Vec<DMatrix<f64>>,
    b: Vec<DVector<f64>>,
    yy: Vec<f64>,
}

impl FoldGrams {
    fn new(x: &[f64], y: &[f64], cols: usize, dof: usize, sigma: &[f64], folds: usize) -> Self {
        let samples = y.len() / dof;
        let mut g = vec![DMatrix::zeros(cols, cols); folds * dof];
        let mut b = vec![DVector::zeros(cols); folds * dof];
        let mut yy = vec![0.0; folds * dof];
        for i in 0..samples {
            let f = fold_of(i, samples, folds);
            for j in 0..dof {
                let r = i * dof + j;
                let w = 1.0 / sigma[j];
                let row = &x[r * cols..(r + 1) * cols];
                let k = f * dof + j;
                let yw = y[r] * w;
                yy[k] += yw * yw;
                let gk = &mut g[k];
                for (c1, &x1) in row.iter().enumerate() {
                    if x1 == 0.0 {
                        continue;
                    }
                    let x1 = x1 * w;
                    b[k][c1] += x1 * yw;
                    for (c2, &x2) in row.iter().enumerate().skip(c1) {
                        gk[(c1, c2)] += x1 * x2 * w;
                    }
                }
            }
        }
        for gk in &mut g {
            for c1 in 0..cols {
                for c2 in 0..c1 {
                    gk[(c1, c2)] = gk[(c2, c1)];
                }
            }
        }
        Self {
            folds,
            dof,
            g,
            b,
            yy,
        }
    }

    /// The normal equations of the columns `sel` over the folds `keep`.
    fn normal(&self, sel: &[usize], keep: impl Fn(usize) -> bool) -> (DMatrix<f64>, DVector<f64>) {
        let n = sel.len();
        let mut a = DMatrix::zeros(n, n);
        let mut r = DVector::zeros(n);
        for f in (0..self.folds).filter(|f| keep(*f)) {
            for j in 0..self.dof {
                let k = f * self.dof + j;
                for (p, &c1) in sel.iter().enumerate() {
                    r[p] += self.b[k][c1];
                    for (q, &c2) in sel.iter().enumerate() {
                        a[(p, q)] += self.g[k][(c1, c2)];
                    }
                }
            }
        }
        (a, r)
    }

    /// Held-out weighted squared residual per joint of the columns `sel`.
    fn cv(&self, sel: &[usize]) -> Vec<f64> {
        let mut sse = vec![0.0; self.dof];
        for f in 0..self.folds {
            let beta = if sel.is_empty() {
                DVector::zeros(0)
            } else {
                let (a, r) = self.normal(sel, |k| k != f);
                solve_spd(a, &r)
            };
            for j in 0..self.dof {
                let k = f * self.dof + j;
                let mut e = self.yy[k];
                for (p, &c1) in sel.iter().enumerate() {
                    e -= 2.0 * beta[p] * self.b[k][c1];
                    for (q, &c2) in sel.iter().enumerate() {
                        e += beta[p] * beta[q] * self.g[k][(c1, c2)];
                    }
                }
                sse[j] += e.max(0.0);
            }
        }
        sse
    }
}

/// Solves `a x = r` for a symmetric positive semi-definite `a` (Cholesky; a symmetric
/// eigen-decomposition pseudo-inverse when it fails).
fn solve_spd(a: DMatrix<f64>, r: &DVector<f64>) -> DVector<f64> {
    match a.clone().cholesky() {
        Some(c) => c.solve(r),
        None => pseudo_inverse(&a) * r,
    }
}

fn pseudo_inverse(a: &DMatrix<f64>) -> DMatrix<f64> {
    let e = a.clone().symmetric_eigen();
    let top = e.eigenvalues.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut inv = DMatrix::zeros(a.nrows(), a.ncols());
    for (k, l) in e.eigenvalues.iter().enumerate() {
        if *l > 1e-12 * top {
            let v = e.eigenvectors.column(k);
            inv += v * v.transpose() / *l;
        }
    }
    inv
}

/// The fold of sample `i` of `n` (contiguous blocks).
fn fold_of(i: usize, n: usize, folds: usize) -> usize {
    (i * folds / n).min(folds - 1)
}

/// A fit of some columns on the whole log.
struct FullFit {
    beta: DVector<f64>,
    /// Covariance with each column's inflation.
    cov: DMatrix<f64>,
    /// Weighted residual per joint, in sample order.
    residual: Vec<Vec<f64>>,
}

#[allow(clippy::too_many_arguments)]
fn full_fit(
    x: &[f64],
    y: &[f64],
    cols: usize,
    dof: usize,
    grams: &FoldGrams,
    sigma: &[f64],
    sel: &[usize],
    joint_of: impl Fn(usize) -> Option<usize>,
) -> FullFit {
    let samples = y.len() / dof;
    let (a, r) = grams.normal(sel, |_| true);
    let ainv = match a.clone().cholesky() {
        Some(c) => c.inverse(),
        None => pseudo_inverse(&a),
    };
    let beta = &ainv * &r;
    let mut residual = vec![Vec::with_capacity(samples); dof];
    let mut sse = 0.0;
    for i in 0..samples {
        for j in 0..dof {
            let row = i * dof + j;
            let w = 1.0 / sigma[j];
            let p: f64 = sel
                .iter()
                .zip(beta.iter())
                .map(|(&c, b)| x[row * cols + c] * b)
                .sum();
            let e = (y[row] - p) * w;
            sse += e * e;
            residual[j].push(e);
        }
    }
    let dofs = (samples * dof).saturating_sub(sel.len()).max(1) as f64;
    let s2 = sse / dofs;
    let kappa: Vec<f64> = residual
        .iter()
        .map(|e| stats::batch_means_factor(e))
        .collect();
    let kappa_max = kappa.iter().fold(1.0f64, |m, k| m.max(*k));
    let infl: Vec<f64> = sel
        .iter()
        .map(|&c| joint_of(c).map_or(kappa_max, |j| kappa[j]).sqrt())
        .collect();
    let mut cov = ainv * s2;
    for p in 0..sel.len() {
        for q in 0..sel.len() {
            cov[(p, q)] *= infl[p] * infl[q];
        }
    }
    FullFit {
        beta,
        cov,
        residual,
    }
}

/// The Wald statistic of the coefficients at positions `idx` of a fit.
fn wald(fit: &FullFit, idx: &[usize]) -> f64 {
    let n = idx.len();
    let b = DVector::from_iterator(n, idx.iter().map(|&i| fit.beta[i]));
    let c = DMatrix::from_fn(n, n, |p, q| fit.cov[(idx[p], idx[q])]);
    let cinv = match c.clone().cholesky() {
        Some(ch) => ch.inverse(),
        None => pseudo_inverse(&c),
    };
    (b.transpose() * cinv * &b)[(0, 0)]
}

/// The accelerations of a log: as logged, or the Savitzky–Golay derivative of the velocities.
fn accelerations(log: &JointLog, half_width: Option<usize>) -> (Vec<Vec<f64>>, bool) {
    if let Some(qdd) = &log.qdd {
        return (qdd.clone(), false);
    }
    let half_width = half_width.unwrap_or_else(|| {
        let dt = tagk_dynamics::log::median_step(&log.t);
        if dt > 0.0 {
            ((0.5 * DERIVATIVE_WINDOW / dt).round() as usize).max(2)
        } else {
            crate::deriv::DEFAULT_HALF_WIDTH
        }
    });
    let dof = log.dof();
    let mut out = vec![vec![0.0; dof]; log.len()];
    for j in 0..dof {
        let v: Vec<f64> = log.qd.iter().map(|r| r[j]).collect();
        let d = crate::deriv::savitzky_golay_derivative(&log.t, &v, half_width);
        for (o, x) in out.iter_mut().zip(d) {
            o[j] = x;
        }
    }
    (out, true)
}

fn fit_error(e: tagk_dynamics::DynamicsError) -> DiagnoseError {
    DiagnoseError::Fit(e.to_string())
}

/// Diagnoses a joint-torque log against a robot's model (module docs).
///
/// # Errors
/// [`DiagnoseError::Log`] for an inconsistent log, [`DiagnoseError::InvalidModel`] when the
/// log's joints are not the robot's, [`DiagnoseError::InvalidOption`] for bad options,
/// [`DiagnoseError::Fit`] when the regressor cannot be built.
pub fn diagnose_arm(
    tree: &KinematicTree,
    log: &JointLog,
    options: &ArmOptions,
) -> Result<ArmReport, DiagnoseError> {
    log.validate()?;
    let dof = tree.dof();
    if log.dof() != dof {
        return Err(DiagnoseError::InvalidModel(format!(
            "the log has {} joints (q1..q{}), the robot `{}` has {dof} ({})",
            log.dof(),
            log.dof(),
            tree.name(),
            tree.joint_names().join(", ")
        )));
    }
    if options.folds < 2 {
        return Err(DiagnoseError::InvalidOption {
            field: "folds",
            reason: "at least 2 blocks".into(),
        });
    }
    if !(options.significance > 0.0 && options.significance < 1.0) {
        return Err(DiagnoseError::InvalidOption {
            field: "significance",
            reason: "a level in (0, 1)".into(),
        });
    }
    if !(options.base_tolerance > 0.0 && options.base_tolerance < 1.0) {
        return Err(DiagnoseError::InvalidOption {
            field: "base_tolerance",
            reason: "a relative tolerance in (0, 1)".into(),
        });
    }
    if let Some(n) = &options.noise
        && (n.len() != dof || n.iter().any(|x| !(x.is_finite() && *x > 0.0)))
    {
        return Err(DiagnoseError::InvalidOption {
            field: "noise",
            reason: format!("one positive finite value per joint ({dof})"),
        });
    }
    let samples = log.len();
    if samples < options.folds * 10 {
        return Err(DiagnoseError::Log(tagk_dynamics::LogError::TooShort {
            rows: samples,
            needed: options.folds * 10,
        }));
    }
    let (qdd, derived) = accelerations(log, options.half_width);
    let theta = tree.params_vector();
    let np = tree.n_params();
    let last = tree.payload_body().ok_or_else(|| {
        DiagnoseError::InvalidModel(format!("the robot `{}` has no moving joint", tree.name()))
    })?;
    let joints: Vec<String> = tree.joint_names().into_iter().map(String::from).collect();

    // The stacked rigid regressor (rows i·dof + j) and the URDF's residual.
    let mut w = DMatrix::zeros(samples * dof, np);
    let mut y = vec![0.0; samples * dof];
    for i in 0..samples {
        let yi = tree
            .joint_torque_regressor(&log.q[i], &log.qd[i], &qdd[i])
            .map_err(fit_error)?;
        let nominal = &yi * &theta;
        for j in 0..dof {
            w.row_mut(i * dof + j).copy_from(&yi.row(j));
            y[i * dof + j] = log.tau[i][j] - nominal[j];
        }
    }

    // Candidate columns.
    let mut groups = Vec::new();
    let mut info: Vec<(String, String, Option<usize>)> = Vec::new();
    let mut payload = None;
    for &e in &options.candidates {
        let start = info.len();
        match e {
            ArmEffect::Joint(k) => {
                for (j, name) in joints.iter().enumerate() {
                    info.push((format!("{}[{name}]", k.name()), k.unit().into(), Some(j)));
                }
            }
            ArmEffect::Payload => {
                let wl = w.columns(10 * last, 10).into_owned();
                let reduction = BaseReduction::of(&wl, options.base_tolerance)?;
                let names: Vec<String> = PARAMETER_NAMES.iter().map(|n| format!("Δ{n}")).collect();
                for (i, &c) in reduction.independent.iter().enumerate() {
                    info.push((
                        format!("payload {}", reduction.base_name(i, &names)),
                        PARAMETER_UNITS[c].into(),
                        None,
                    ));
                }
                payload = Some(PayloadBasis {
                    body: tree.bodies()[last].link().to_string(),
                    reduction,
                });
            }
        }
        groups.push((e, (start..info.len()).collect::<Vec<usize>>()));
    }
    let cols = info.len();
    let mut x = vec![0.0; samples * dof * cols];
    for i in 0..samples {
        for j in 0..dof {
            let r = i * dof + j;
            for (e, idx) in &groups {
                match e {
                    ArmEffect::Joint(k) => {
                        x[r * cols + idx[j]] = k.column(log.qd[i][j], qdd[i][j]);
                    }
                    ArmEffect::Payload => {
                        let red = &payload.as_ref().expect("payload basis").reduction;
                        for (p, &c) in idx.iter().zip(&red.independent) {
                            x[r * cols + p] = w[(r, 10 * last + c)];
                        }
                    }
                }
            }
        }
    }
    let problem = Problem {
        dof,
        samples,
        x,
        cols,
        y,
        groups,
        info,
    };

    // The noise: given, or measured on the URDF's residual, then on the final model's.
    let mut sigma = match &options.noise {
        Some(n) => n.clone(),
        None => measured_noise(&problem, &problem.y, log),
    };
    let mut outcome = search(&problem, &sigma, options, &joints);
    if options.noise.is_none() {
        for _ in 0..2 {
            let again = measured_noise(&problem, &outcome.final_residual, log);
            if again
                .iter()
                .zip(&sigma)
                .any(|(a, s)| *a < NOISE_RERUN_RATIO * s)
            {
                sigma = again;
                outcome = search(&problem, &sigma, options, &joints);
            } else {
                break;
            }
        }
    }
    let final_noise = measured_noise(&problem, &outcome.final_residual, log);
    let base_parameters = if options.base_parameters {
        Some(base_parameters(
            tree,
            &w,
            log,
            &qdd,
            &problem,
            &outcome.chosen,
            &sigma,
            options,
        )?)
    } else {
        None
    };
    let adequate = outcome
        .steps
        .last()
        .is_some_and(|s| s.joints.iter().all(|j| j.adequate));
    Ok(ArmReport {
        robot: tree.name().to_string(),
        joints,
        samples,
        derived_accelerations: derived,
        recommended: outcome.steps.get(1).and_then(|s| s.effect.clone()),
        steps: outcome.steps,
        final_model: outcome.final_model,
        noise: sigma,
        final_noise,
        adequate,
        stopped: outcome.stopped,
        payload,
        base_parameters,
        unavailable: vec![("joint-elasticity".into(), ELASTICITY_REASON.into())],
    })
}

/// Each joint's torque noise from the second differences of a residual (N m per row), never
/// below 10⁻⁶ of the joint's RMS torque (a noise-free log would chase rounding otherwise).
fn measured_noise(p: &Problem, residual: &[f64], log: &JointLog) -> Vec<f64> {
    (0..p.dof)
        .map(|j| {
            let e: Vec<f64> = (0..p.samples).map(|i| residual[i * p.dof + j]).collect();
            let tau: Vec<f64> = log.tau.iter().map(|r| r[j]).collect();
            let floor = 1e-6 * stats::rms(&tau).max(1e-9);
            stats::second_difference_noise(&e).max(floor)
        })
        .collect()
}

struct SearchOutcome {
    steps: Vec<ArmStep>,
    final_model: ArmFinalModel,
    chosen: Vec<ArmEffect>,
    stopped: String,
    /// The final model's residual per row \[N m\] (unweighted).
    final_residual: Vec<f64>,
}

/// How one effect fares added to a set of effects.
struct Trial {
    gain: f64,
    cv: Vec<f64>,
    wald: f64,
    df: usize,
    admissible: bool,
}

fn search(p: &Problem, sigma: &[f64], options: &ArmOptions, joints: &[String]) -> SearchOutcome {
    let grams = FoldGrams::new(&p.x, &p.y, p.cols, p.dof, sigma, options.folds);
    let cols_of = |set: &[ArmEffect]| -> Vec<usize> {
        p.groups
            .iter()
            .filter(|(e, _)| set.contains(e))
            .flat_map(|(_, c)| c.iter().copied())
            .collect()
    };
    let joint_of = |c: usize| p.info[c].2;
    let fit_of = |set: &[ArmEffect]| {
        full_fit(
            &p.x,
            &p.y,
            p.cols,
            p.dof,
            &grams,
            sigma,
            &cols_of(set),
            joint_of,
        )
    };
    let trial = |set: &[ArmEffect], e: ArmEffect, before: &[f64]| -> Trial {
        let mut with = set.to_vec();
        with.push(e);
        let sel = cols_of(&with);
        let cv = grams.cv(&sel);
        let gain: f64 = before.iter().zip(&cv).map(|(b, a)| b - a).sum();
        let fit = fit_of(&with);
        let own: Vec<usize> = sel
            .iter()
            .enumerate()
            .filter(|(_, c)| p.groups.iter().any(|(g, cs)| *g == e && cs.contains(*c)))
            .map(|(k, _)| k)
            .collect();
        let w = wald(&fit, &own);
        let df = own.len();
        let admissible = gain > chance_margin(gain)
            && gain / p.samples as f64 >= MIN_GAIN
            && w > stats::chi2_quantile(options.significance, df as f64);
        Trial {
            gain,
            cv,
            wald: w,
            df,
            admissible,
        }
    };
    let mut chosen: Vec<ArmEffect> = Vec::new();
    let mut current = grams.cv(&[]);
    let mut stopped = String::new();
    for _ in 0..options.max_steps {
        let best = p
            .groups
            .iter()
            .map(|(e, _)| *e)
            .filter(|e| !chosen.contains(e))
            .map(|e| (e, trial(&chosen, e, &current)))
            .filter(|(_, t)| t.admissible)
            .max_by(|a, b| a.1.gain.total_cmp(&b.1.gain));
        match best {
            Some((e, t)) => {
                chosen.push(e);
                current = t.cv;
            }
            None => {
                stopped = "stopped: no remaining candidate passes the held-out gain, \
                           relevance and significance rules"
                    .into();
                break;
            }
        }
    }
    if stopped.is_empty() {
        stopped = format!("stopped: the most steps ({})", options.max_steps);
    }
    // Each added effect, within the final model.
    let mut k = 0;
    while k < chosen.len() {
        let rest: Vec<ArmEffect> = chosen.iter().copied().filter(|e| *e != chosen[k]).collect();
        let before = grams.cv(&cols_of(&rest));
        if trial(&rest, chosen[k], &before).admissible {
            k += 1;
        } else {
            stopped += &format!(
                "; `{}` dropped: it no longer passes within the final model",
                chosen[k].name()
            );
            chosen.remove(k);
        }
    }
    // The staircase: each step adds the remaining effect of the final model that gains most.
    let mut ordered: Vec<ArmEffect> = Vec::new();
    let mut cv = grams.cv(&[]);
    while ordered.len() < chosen.len() {
        let next = chosen
            .iter()
            .copied()
            .filter(|e| !ordered.contains(e))
            .map(|e| (e, trial(&ordered, e, &cv)))
            .max_by(|a, b| a.1.gain.total_cmp(&b.1.gain));
        let Some((e, t)) = next else { break };
        ordered.push(e);
        cv = t.cv;
    }
    let chosen = ordered;
    let step = |set: &[ArmEffect],
                cv: &[f64],
                prev: Option<&[f64]>,
                gain: f64,
                w: Option<(f64, usize)>| {
        let label = if set.is_empty() {
            "rigid body (URDF)".to_string()
        } else {
            format!(
                "rigid body (URDF) + {}",
                set.iter().map(|e| e.name()).collect::<Vec<_>>().join(" + ")
            )
        };
        let rms: Vec<f64> = cv
            .iter()
            .zip(sigma)
            .map(|(s, sg)| (s / p.samples as f64).sqrt() * sg)
            .collect();
        let joints_out = (0..p.dof)
            .map(|j| {
                let ratio = rms[j] / sigma[j];
                let change = prev.map_or(0.0, |pr| {
                    let before = (pr[j] / p.samples as f64).sqrt() * sigma[j];
                    if before > 0.0 {
                        rms[j] / before - 1.0
                    } else {
                        0.0
                    }
                });
                StepJoint {
                    name: joints[j].clone(),
                    held_out_rms: rms[j],
                    noise: sigma[j],
                    ratio_to_noise: ratio,
                    adequate: ratio <= ADEQUACY_FACTOR,
                    change,
                }
            })
            .collect();
        let coefficients = match set.last() {
            None => Vec::new(),
            Some(e) => coefficients(p, &fit_of(set), &cols_of(set), Some(*e)),
        };
        ArmStep {
            effect: set.last().map(|e| e.name().to_string()),
            model: label,
            held_out_rms: rms,
            joints: joints_out,
            gain,
            wald: w,
            coefficients,
        }
    };
    let mut cv = grams.cv(&[]);
    let mut steps = vec![step(&[], &cv, None, 0.0, None)];
    for n in 1..=chosen.len() {
        let t = trial(&chosen[..n - 1], chosen[n - 1], &cv);
        steps.push(step(
            &chosen[..n],
            &t.cv,
            Some(&cv),
            t.gain,
            Some((t.wald, t.df)),
        ));
        cv = t.cv;
    }
    let sel = cols_of(&chosen);
    let fit = fit_of(&chosen);
    let final_residual: Vec<f64> = (0..p.samples * p.dof)
        .map(|r| fit.residual[r % p.dof][r / p.dof] * sigma[r % p.dof])
        .collect();
    SearchOutcome {
        final_model: ArmFinalModel {
            effects: chosen.iter().map(|e| e.name().to_string()).collect(),
            coefficients: coefficients(p, &fit, &sel, None),
        },
        steps,
        chosen,
        stopped,
        final_residual,
    }
}

/// The coefficients of a fit over the columns `sel` (only `effect`'s, when given).
fn coefficients(
    p: &Problem,
    fit: &FullFit,
    sel: &[usize],
    effect: Option<ArmEffect>,
) -> Vec<Coefficient> {
    sel.iter()
        .enumerate()
        .filter(|(_, c)| {
            effect.is_none_or(|e| p.groups.iter().any(|(g, cs)| *g == e && cs.contains(*c)))
        })
        .map(|(k, &c)| {
            let var = fit.cov[(k, k)];
            Coefficient::new(
                &p.info[c].0,
                &p.info[c].1,
                fit.beta[k],
                (var >= 0.0).then(|| var.sqrt()),
            )
        })
        .collect()
}

/// Names of the full parameter vector: `link.m`, `link.h_x`, ….
fn parameter_names(tree: &KinematicTree) -> Vec<String> {
    tree.bodies()
        .iter()
        .flat_map(|b| {
            PARAMETER_NAMES
                .iter()
                .map(move |n| format!("{}.{n}", b.link()))
        })
        .collect()
}

/// The rigid body's base parameters, fitted with the final model's joint effects.
#[allow(clippy::too_many_arguments)]
fn base_parameters(
    tree: &KinematicTree,
    w: &DMatrix<f64>,
    log: &JointLog,
    qdd: &[Vec<f64>],
    p: &Problem,
    chosen: &[ArmEffect],
    sigma: &[f64],
    options: &ArmOptions,
) -> Result<BaseParameters, DiagnoseError> {
    let reduction = BaseReduction::of(w, options.base_tolerance)?;
    let names = parameter_names(tree);
    let kinds: Vec<JointEffectKind> = chosen
        .iter()
        .filter_map(|e| match e {
            ArmEffect::Joint(k) => Some(*k),
            ArmEffect::Payload => None,
        })
        .collect();
    let dof = p.dof;
    let r = reduction.rank;
    let mut info: Vec<(String, String, Option<usize>)> = reduction
        .independent
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            (
                reduction.base_name(i, &names),
                PARAMETER_UNITS[c % 10].into(),
                None,
            )
        })
        .collect();
    for k in &kinds {
        for (j, name) in tree.joint_names().iter().enumerate() {
            info.push((format!("{}[{name}]", k.name()), k.unit().into(), Some(j)));
        }
    }
    let cols = info.len();
    let mut x = vec![0.0; p.samples * dof * cols];
    let mut y = vec![0.0; p.samples * dof];
    for i in 0..p.samples {
        for j in 0..dof {
            let row = i * dof + j;
            for (q, &c) in reduction.independent.iter().enumerate() {
                x[row * cols + q] = w[(row, c)];
            }
            for (m, k) in kinds.iter().enumerate() {
                x[row * cols + r + m * dof + j] = k.column(log.qd[i][j], qdd[i][j]);
            }
            y[row] = log.tau[i][j];
        }
    }
    let grams = FoldGrams::new(&x, &y, cols, dof, sigma, options.folds);
    // Effect columns that the base columns (and the effects kept before them) explain.
    let (a, _) = grams.normal(&(0..cols).collect::<Vec<_>>(), |_| true);
    let mut keep: Vec<usize> = (0..r).collect();
    let mut absorbed = Vec::new();
    for c in r..cols {
        let gss = DMatrix::from_fn(keep.len(), keep.len(), |u, v| a[(keep[u], keep[v])]);
        let gsc = DVector::from_iterator(keep.len(), keep.iter().map(|&u| a[(u, c)]));
        let proj = (gsc.transpose() * solve_spd(gss, &gsc))[(0, 0)];
        let rest = (a[(c, c)] - proj).max(0.0);
        if a[(c, c)] > 0.0 && rest > (EFFECT_IDENTIFIABILITY * EFFECT_IDENTIFIABILITY) * a[(c, c)] {
            keep.push(c);
        } else {
            absorbed.push(info[c].0.clone());
        }
    }
    let fit = full_fit(&x, &y, cols, dof, &grams, sigma, &keep, |c| info[c].2);
    let cv = grams.cv(&keep);
    let urdf = reduction.base_values(tree.params_vector().as_slice());
    let mut parameters = Vec::new();
    let mut effects = Vec::new();
    for (k, &c) in keep.iter().enumerate() {
        let var = fit.cov[(k, k)];
        let coef = Coefficient::new(
            &info[c].0,
            &info[c].1,
            fit.beta[k],
            (var >= 0.0).then(|| var.sqrt()),
        );
        if c < r {
            let z = coef
                .std_error
                .filter(|e| *e > 0.0)
                .map(|e| (coef.value - urdf[c]) / e);
            parameters.push(BaseParameter {
                coefficient: coef,
                urdf: urdf[c],
                z,
            });
        } else {
            effects.push(coef);
        }
    }
    Ok(BaseParameters {
        n_params: reduction.n_params,
        rank: r,
        tolerance: reduction.tolerance,
        parameters,
        effects,
        absorbed,
        held_out_rms: cv
            .iter()
            .zip(sigma)
            .map(|(s, sg)| (s / p.samples as f64).sqrt() * sg)
            .collect(),
    })
}

/// The stacked rigid regressor of a log (rows `i·dof + j`), with the accelerations the
/// diagnosis uses (logged, or derived with `half_width`, as [`ArmOptions::half_width`]): for independent checks of the
/// base reduction.
///
/// # Errors
/// As [`diagnose_arm`] for a log that does not fit the robot.
pub fn stacked_regressor(
    tree: &KinematicTree,
    log: &JointLog,
    half_width: Option<usize>,
) -> Result<DMatrix<f64>, DiagnoseError> {
    log.validate()?;
    if log.dof() != tree.dof() {
        return Err(DiagnoseError::InvalidModel(format!(
            "the log has {} joints, the robot {}",
            log.dof(),
            tree.dof()
        )));
    }
    let dof = tree.dof();
    let (qdd, _) = accelerations(log, half_width);
    let mut w = DMatrix::zeros(log.len() * dof, tree.n_params());
    for i in 0..log.len() {
        let yi = tree
            .joint_torque_regressor(&log.q[i], &log.qd[i], &qdd[i])
            .map_err(fit_error)?;
        for j in 0..dof {
            w.row_mut(i * dof + j).copy_from(&yi.row(j));
        }
    }
    Ok(w)
}
