//! Physical effects that can be added to the rigid-body model.
//!
//! An effect is an **external wrench** `w_ext = Φ β` acting on the body that the rigid-body
//! model does not know about: the actuators' wrench then satisfies `b = Y θ − Φ β`. Each effect
//! contributes named columns of `Φ` (the external wrench per unit coefficient, body frame,
//! about the origin) and may have one nonlinear parameter (a time constant, a delay) found by
//! a 1-D scan. Coefficients have physical signs: a drag coefficient must come out positive.

use std::sync::Arc;

use nalgebra::Vector3;

use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// Names of the built-in effects, as accepted by `--with`.
pub const BUILTIN_NAMES: [&str; 9] = [
    "linear-drag",
    "quadratic-drag",
    "rotor-drag",
    "motor-lag",
    "time-delay",
    "ground-effect",
    "body-bias",
    "wind",
    "thrust-gain",
];

/// One column of an effect: the external wrench per unit coefficient on each channel it
/// touches (`None`: zero on that channel).
#[derive(Debug, Clone)]
pub struct EffectColumn {
    /// Coefficient name, e.g. `d_x`.
    pub name: String,
    /// Coefficient unit, e.g. `N s/m`.
    pub unit: String,
    /// External wrench per unit coefficient, per channel, one value per sample.
    pub data: [Option<Vec<f64>>; 6],
}

impl EffectColumn {
    /// A column acting on one channel.
    pub fn on(name: &str, unit: &str, channel: Channel, values: Vec<f64>) -> Self {
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        data[channel] = Some(values);
        Self {
            name: name.to_string(),
            unit: unit.to_string(),
            data,
        }
    }
}

/// A nonlinear parameter found by a 1-D grid scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanSpec {
    /// Parameter name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Values tried (the one with the smallest residual wins).
    pub grid: Vec<f64>,
}

/// Verdict on the physical plausibility of fitted coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct Plausibility {
    /// `true` if the coefficients are physically possible.
    pub plausible: bool,
    /// Why (empty when plausible and nothing to add).
    pub note: String,
}

impl Plausibility {
    /// Plausible, no note.
    pub fn ok() -> Self {
        Self {
            plausible: true,
            note: String::new(),
        }
    }
    /// Implausible, with a reason.
    pub fn bad(note: impl Into<String>) -> Self {
        Self {
            plausible: false,
            note: note.into(),
        }
    }
}

/// A physical effect: named regressor columns with units, the channels it acts on, a
/// plausibility check and an optional nonlinear parameter. Implement it to add your own.
pub trait Effect: Send + Sync + std::fmt::Debug {
    /// Short name, e.g. `linear-drag`.
    fn name(&self) -> &str;
    /// One-line physical description.
    fn description(&self) -> &str;
    /// Channels the effect acts on.
    fn channels(&self) -> Vec<Channel>;
    /// `Err(reason)` if the log lacks what the effect needs (e.g. rotor speeds).
    fn check(&self, _signals: &Signals) -> Result<(), String> {
        Ok(())
    }
    /// `true` if the effect is only identifiable with a known mass ([`crate::Model::with_known_mass`]).
    fn needs_known_mass(&self) -> bool {
        false
    }
    /// The nonlinear parameter to scan, if any.
    fn scan(&self) -> Option<ScanSpec> {
        None
    }
    /// The columns of `Φ` on this log (`param` is the scanned parameter, if any).
    fn columns(&self, signals: &Signals, param: Option<f64>) -> Vec<EffectColumn>;
    /// Physical plausibility of fitted coefficients `coef` with standard errors `se`.
    fn plausibility(&self, coef: &[f64], se: &[f64], param: Option<f64>) -> Plausibility;
    /// A scalar signal the effect is driven by (for regime plots), with its name and unit.
    fn driver(&self, signals: &Signals) -> (String, Vec<f64>);
}

/// Shared handle on an effect.
pub type EffectRef = Arc<dyn Effect>;

fn nonneg(names: &[&str], coef: &[f64], se: &[f64], what: &str) -> Plausibility {
    for (k, n) in names.iter().enumerate() {
        if coef[k] < -3.0 * se[k].max(1e-300) {
            return Plausibility::bad(format!(
                "{what} {n} = {:.3e} is significantly negative (would push the vehicle along its motion)",
                coef[k]
            ));
        }
    }
    Plausibility::ok()
}

fn horiz_speed(s: &Signals) -> Vec<f64> {
    s.velocity_body
        .iter()
        .map(|v| (v.x * v.x + v.y * v.y).sqrt())
        .collect()
}

/// Linear aerodynamic drag in the body frame: `f_ext = −diag(d_x, d_y, d_z) v_b`.
#[derive(Debug, Clone, Copy, Default)]
pub struct LinearDrag;

impl Effect for LinearDrag {
    fn name(&self) -> &str {
        "linear-drag"
    }
    fn description(&self) -> &str {
        "linear aerodynamic drag opposing the body-frame velocity, f = -D v_b"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1, 2]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        ["d_x", "d_y", "d_z"]
            .iter()
            .enumerate()
            .map(|(k, n)| {
                EffectColumn::on(
                    n,
                    "N s/m",
                    k,
                    s.velocity_body.iter().map(|v| -v[k]).collect(),
                )
            })
            .collect()
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["d_x", "d_y", "d_z"], coef, se, "drag coefficient")
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("horizontal body speed [m/s]".into(), horiz_speed(s))
    }
}

/// Quadratic aerodynamic drag in the body frame: `f_ext,k = −c_k v_k |v_k|`.
#[derive(Debug, Clone, Copy, Default)]
pub struct QuadraticDrag;

impl Effect for QuadraticDrag {
    fn name(&self) -> &str {
        "quadratic-drag"
    }
    fn description(&self) -> &str {
        "quadratic aerodynamic drag, f_k = -c_k v_k |v_k| in the body frame"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1, 2]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        ["c_x", "c_y", "c_z"]
            .iter()
            .enumerate()
            .map(|(k, n)| {
                EffectColumn::on(
                    n,
                    "N s²/m²",
                    k,
                    s.velocity_body.iter().map(|v| -v[k] * v[k].abs()).collect(),
                )
            })
            .collect()
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["c_x", "c_y", "c_z"], coef, se, "drag coefficient")
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("horizontal body speed [m/s]".into(), horiz_speed(s))
    }
}

/// Rotor (blade-flapping / induced) drag: `f_ext,k = −k_k (Σ |ωᵢ|) v_b,k` per body axis;
/// needs rotor speeds.
#[derive(Debug, Clone, Copy, Default)]
pub struct RotorDrag;

impl Effect for RotorDrag {
    fn name(&self) -> &str {
        "rotor-drag"
    }
    fn description(&self) -> &str {
        "rotor drag proportional to the summed rotor speed times the body-frame velocity"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1, 2]
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        if s.rotor_speeds.is_some() {
            Ok(())
        } else {
            Err("needs rotor speeds (columns w1..w4)".into())
        }
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let Some(w) = &s.rotor_speeds else {
            return Vec::new();
        };
        ["k_x", "k_y", "k_z"]
            .iter()
            .enumerate()
            .map(|(k, n)| {
                EffectColumn::on(
                    n,
                    "N s²/(m rad)",
                    k,
                    s.velocity_body
                        .iter()
                        .zip(w)
                        .map(|(v, w)| -v[k] * w.iter().map(|x| x.abs()).sum::<f64>())
                        .collect(),
                )
            })
            .collect()
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["k_x", "k_y", "k_z"], coef, se, "rotor-drag coefficient")
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("horizontal body speed [m/s]".into(), horiz_speed(s))
    }
}

/// First-order actuator dynamics: the delivered thrust and torques follow the logged command
/// through `τ ẏ = u − y`. Column: `y − b` on `fz, tx, ty, tz`, with `y` the exact response
/// to the piecewise-constant command sampled in the middle of each sample interval (see
/// [`first_order_lag`]); the coefficient is ≈ 1 for that sampling, between `e^{−Δt/2τ}` and
/// `e^{Δt/2τ}` for others, so gains in `[0.4, 2.5]` are accepted as plausible. Four nuisance
/// columns `e^{−(t − t₀)/τ}` (one per channel) absorb the unknown actuator state at the start
/// of the log.
#[derive(Debug, Clone)]
pub struct MotorLag {
    /// Time constants scanned \[s\].
    pub grid: Vec<f64>,
}

impl Default for MotorLag {
    fn default() -> Self {
        // 5 ms .. 200 ms, log-spaced.
        let grid = (0..16)
            .map(|k| 0.005 * (40.0f64).powf(k as f64 / 15.0))
            .collect();
        Self { grid }
    }
}

/// Response of the first-order lag `τ ẏ = u − y` (time constant `tau` \[s\]) to a command
/// `u` held constant over each sample interval `[t_k − Δt/2, t_k + Δt/2)` and sampled at
/// its middle `t_k` (the convention of logs whose rows describe one control interval):
/// with `Y_k` the state at the end of interval `k`,
/// `y_k = u_k + e^{−Δt/2τ} (Y_{k−1} − u_k)`, `Y_k = u_k + e^{−Δt/τ} (Y_{k−1} − u_k)`,
/// starting at rest on the first command (`Y_0 = u_0`).
pub fn first_order_lag(t: &[f64], u: &[f64], tau: f64) -> Vec<f64> {
    let mut y = Vec::with_capacity(u.len());
    if u.is_empty() {
        return y;
    }
    y.push(u[0]);
    let mut end = u[0];
    let (mut last_dt, mut a_half, mut a_full) = (f64::NAN, 0.0, 0.0);
    for k in 1..u.len() {
        let dt = t[k] - t[k - 1];
        // Uniformly sampled logs reuse the factors (exp is the cost of a 1-D scan).
        if dt != last_dt {
            last_dt = dt;
            (a_half, a_full) = if tau > 0.0 {
                ((-0.5 * dt / tau).exp(), (-dt / tau).exp())
            } else {
                (0.0, 0.0)
            };
        }
        y.push(u[k] + a_half * (end - u[k]));
        end = u[k] + a_full * (end - u[k]);
    }
    y
}

/// With rotor speeds in the log, the lag acts on each rotor speed and the wrench follows
/// through the squares: the mixer `[fz, tx, ty, tz]ᵀ = M [ω₁², …, ω₄²]ᵀ` is identified from the
/// log itself (least squares; it must reproduce the logged wrench to 1e-3 relative on at least
/// 90 % of the samples — saturated samples may disagree — otherwise
/// `None` and the lag is applied to the wrench directly), and the delivered wrench is
/// `M lag_τ(ω)²`. Returns `[fz, tx, ty, tz]` per sample.
fn lagged_wrench_from_rotors(s: &Signals, tau: f64) -> Option<Vec<[f64; 4]>> {
    let w = s.rotor_speeds.as_ref()?;
    let sq: Vec<[f64; 4]> = w.iter().map(|x| x.map(|v| v * v)).collect();
    let mut g = nalgebra::Matrix4::<f64>::zeros();
    let mut rhs = nalgebra::Matrix4::<f64>::zeros();
    for (x, b) in sq.iter().zip(&s.wrench) {
        let xv = nalgebra::Vector4::from(*x);
        let bv = nalgebra::Vector4::new(b[2], b[3], b[4], b[5]);
        g += xv * xv.transpose();
        rhs += xv * bv.transpose();
    }
    let mt = g.cholesky()?.solve(&rhs); // (4 rotors × 4 channels) = Mᵀ
    let mut good = 0usize;
    for (x, b) in sq.iter().zip(&s.wrench) {
        let pred = mt.transpose() * nalgebra::Vector4::from(*x);
        let bv = nalgebra::Vector4::new(b[2], b[3], b[4], b[5]);
        if (pred - bv).norm() <= 1e-3 * bv.norm() {
            good += 1;
        }
    }
    if good * 10 < s.len() * 9 {
        return None;
    }
    // Per rotor: ω² at the interval midpoint (what an accelerometer sample sees) and the
    // interval mean of ω² (what a differenced gyro — the logged angular acceleration — sees).
    let n = s.len();
    let mut mid = vec![[0.0; 4]; n];
    let mut mean = vec![[0.0; 4]; n];
    let mut factors = (f64::NAN, (0.0, 0.0, 0.0, 0.0));
    for r in 0..4 {
        let mut end = w[0][r];
        mid[0][r] = end * end;
        mean[0][r] = end * end;
        for i in 1..n {
            let dt = s.t[i] - s.t[i - 1];
            let u = w[i][r];
            let e = end - u;
            // Uniform sampling reuses the factors (the exponentials dominate a scan's cost).
            if dt != factors.0 {
                factors = (
                    dt,
                    if tau > 0.0 {
                        let x = dt / tau;
                        (
                            (-0.5 * x).exp(),
                            (-x).exp(),
                            (1.0 - (-x).exp()) / x,
                            (1.0 - (-2.0 * x).exp()) / (2.0 * x),
                        )
                    } else {
                        (0.0, 0.0, 0.0, 0.0)
                    },
                );
            }
            let (a_half, a_full, m1, m2) = factors.1;
            let ym = u + a_half * e;
            mid[i][r] = ym * ym;
            mean[i][r] = u * u + 2.0 * u * e * m1 + e * e * m2;
            end = u + a_full * e;
        }
    }
    Some(
        (0..n)
            .map(|i| {
                let ym = mt.transpose() * nalgebra::Vector4::from(mid[i]);
                let ya = mt.transpose() * nalgebra::Vector4::from(mean[i]);
                [ym[0], ya[1], ya[2], ya[3]]
            })
            .collect(),
    )
}

impl Effect for MotorLag {
    fn name(&self) -> &str {
        "motor-lag"
    }
    fn description(&self) -> &str {
        "first-order motor dynamics: delivered thrust/torque lags the logged command by a time constant"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn scan(&self) -> Option<ScanSpec> {
        Some(ScanSpec {
            name: "tau".into(),
            unit: "s".into(),
            grid: self.grid.clone(),
        })
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        let tau = p.unwrap_or(self.grid[self.grid.len() / 2]);
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        if let Some(lagged) = lagged_wrench_from_rotors(s, tau) {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                *d = Some(
                    lagged
                        .iter()
                        .zip(&s.wrench)
                        .map(|(y, b)| y[c - 2] - b[c])
                        .collect(),
                );
            }
        } else {
            for (c, d) in data.iter_mut().enumerate().skip(2) {
                let u = s.channel(c);
                let y = first_order_lag(&s.t, &u, tau);
                *d = Some(y.iter().zip(&u).map(|(y, u)| y - u).collect());
            }
        }
        let mut cols = vec![EffectColumn {
            name: "g_lag".into(),
            unit: "1".into(),
            data,
        }];
        // The actuators' state when the log starts is unknown: its effect decays like
        // e^{−(t − t₀)/τ}, a nuisance column per channel.
        let decay: Vec<f64> =
            s.t.iter()
                .map(|t| {
                    let x = if tau > 0.0 {
                        (-(t - s.t[0]) / tau).exp()
                    } else {
                        0.0
                    };
                    if x < 1e-12 { 0.0 } else { x }
                })
                .collect();
        for c in 2..6 {
            cols.push(EffectColumn::on(
                &format!("start_{}", CHANNEL_NAMES[c]),
                if c == 2 { "N" } else { "N m" },
                c,
                decay.clone(),
            ));
        }
        cols
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], p: Option<f64>) -> Plausibility {
        if !(0.4..=2.5).contains(&coef[0]) {
            return Plausibility::bad(format!(
                "lag gain {:.2} far from 1: the lag shape does not match",
                coef[0]
            ));
        }
        if let Some(tau) = p
            && tau >= *self.grid.last().unwrap_or(&f64::INFINITY)
        {
            return Plausibility::bad(format!("time constant {tau:.3} s at the end of the scan"));
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        let fz = s.channel(2);
        (
            "thrust rate |dfz/dt| [N/s]".into(),
            crate::deriv::savitzky_golay_derivative(&s.t, &fz, 2)
                .iter()
                .map(|x| x.abs())
                .collect(),
        )
    }
}

/// A constant time offset `d` between the actuator stream and the motion stream: the wrench
/// acting at `t` is the logged `b(t − d)`. Column `b(t − d) − b(t)` on all six channels
/// (coefficient ≈ 1, plausible in `[0.8, 1.25]`); `d` scanned.
#[derive(Debug, Clone)]
pub struct TimeDelay {
    /// Delays scanned \[s\] (positive: the actuator log is early).
    pub grid: Vec<f64>,
}

impl Default for TimeDelay {
    fn default() -> Self {
        let mut grid: Vec<f64> = (1..=12).map(|k| 0.01 * k as f64).collect();
        grid.extend((1..=12).map(|k| -0.01 * k as f64));
        Self { grid }
    }
}

/// `x(t − d)` at every sample by linear interpolation (clamped at the ends), in one
/// monotone sweep.
fn shifted(t: &[f64], x: &[f64], d: f64) -> Vec<f64> {
    let n = t.len();
    let mut out = Vec::with_capacity(n);
    let mut k = 0usize;
    for &ti in t {
        let tq = ti - d;
        if tq <= t[0] {
            out.push(x[0]);
            continue;
        }
        if tq >= t[n - 1] {
            out.push(x[n - 1]);
            continue;
        }
        while k + 1 < n && t[k + 1] <= tq {
            k += 1;
        }
        let f = (tq - t[k]) / (t[k + 1] - t[k]);
        out.push(x[k] * (1.0 - f) + x[k + 1] * f);
    }
    out
}

impl Effect for TimeDelay {
    fn name(&self) -> &str {
        "time-delay"
    }
    fn description(&self) -> &str {
        "constant time offset between the actuator stream and the motion stream"
    }
    fn channels(&self) -> Vec<Channel> {
        (0..6).collect()
    }
    fn scan(&self) -> Option<ScanSpec> {
        Some(ScanSpec {
            name: "delay".into(),
            unit: "s".into(),
            grid: self.grid.clone(),
        })
    }
    fn columns(&self, s: &Signals, p: Option<f64>) -> Vec<EffectColumn> {
        let d = p.unwrap_or(0.02);
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        for (c, dd) in data.iter_mut().enumerate() {
            let u = s.channel(c);
            if u.iter().all(|x| *x == 0.0) {
                continue;
            }
            *dd = Some(
                shifted(&s.t, &u, d)
                    .iter()
                    .zip(&u)
                    .map(|(a, b)| a - b)
                    .collect(),
            );
        }
        vec![EffectColumn {
            name: "g_delay".into(),
            unit: "1".into(),
            data,
        }]
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], p: Option<f64>) -> Plausibility {
        if !(0.8..=1.25).contains(&coef[0]) {
            return Plausibility::bad(format!(
                "delay gain {:.2} far from 1: not a pure time shift",
                coef[0]
            ));
        }
        if let Some(d) = p {
            let max = self.grid.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if d.abs() >= max {
                return Plausibility::bad(format!("delay {d:.3} s at the end of the scan"));
            }
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        MotorLag::default().driver(s)
    }
}

/// Ground effect: extra rotor thrust (and rotor torques) near the ground after Cheeseman and
/// Bennett: `T_IGE/T_OGE = 1/(1 − (R/4z)²)`, so the external wrench is
/// `c · [0, 0, f_z, τ_x, τ_y, τ_z] · ((1/(1 − (R/4z)²)) − 1)` with `c ≈ 1`, `z` the height of
/// the body origin above the ground plane `z = 0` (clamped to `z ≥ R`).
#[derive(Debug, Clone, Copy)]
pub struct GroundEffect {
    /// Rotor radius `R` \[m\] (Crazyflie: 0.0225 m).
    pub rotor_radius: f64,
    /// Heights below this are clamped \[m\] (avoids the singularity at `z = R/4`).
    pub min_height: f64,
}

impl Default for GroundEffect {
    fn default() -> Self {
        Self {
            rotor_radius: 0.0225,
            min_height: 0.0225,
        }
    }
}

impl GroundEffect {
    fn shape(&self, z: f64) -> f64 {
        let z = z.max(self.min_height);
        let r = self.rotor_radius / (4.0 * z);
        1.0 / (1.0 - r * r) - 1.0
    }
}

impl Effect for GroundEffect {
    fn name(&self) -> &str {
        "ground-effect"
    }
    fn description(&self) -> &str {
        "extra rotor thrust near the ground, growing like (R/4z)^2 as the height z falls"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        for (c, d) in data.iter_mut().enumerate().skip(2) {
            *d = Some(
                s.position
                    .iter()
                    .zip(&s.wrench)
                    .map(|(p, w)| w[c] * self.shape(p.z))
                    .collect(),
            );
        }
        vec![EffectColumn {
            name: "c_ge".into(),
            unit: "1".into(),
            data,
        }]
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["c_ge"], coef, se, "ground-effect gain")
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (
            "height [m]".into(),
            s.position.iter().map(|p| p.z).collect(),
        )
    }
}

/// Constant body-frame force and torque bias (e.g. a miscalibrated motor or a tether).
#[derive(Debug, Clone, Copy, Default)]
pub struct BodyBias;

impl Effect for BodyBias {
    fn name(&self) -> &str {
        "body-bias"
    }
    fn description(&self) -> &str {
        "constant force and torque in the body frame (miscalibrated motor, cable, sensor offset)"
    }
    fn channels(&self) -> Vec<Channel> {
        (0..6).collect()
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let n = s.len();
        (0..6)
            .map(|c| {
                EffectColumn::on(
                    &format!("bias_{}", CHANNEL_NAMES[c]),
                    if c < 3 { "N" } else { "N m" },
                    c,
                    vec![1.0; n],
                )
            })
            .collect()
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("time [s]".into(), s.t.clone())
    }
}

/// Constant world-frame force (steady wind): body-frame columns `Rᵀ e_x, Rᵀ e_y, Rᵀ e_z`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Wind;

impl Effect for Wind {
    fn name(&self) -> &str {
        "wind"
    }
    fn description(&self) -> &str {
        "constant force fixed in the world frame (steady wind), seen rotating in the body frame"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1, 2]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        ["F_wx", "F_wy", "F_wz"]
            .iter()
            .enumerate()
            .map(|(j, n)| {
                let mut e = Vector3::zeros();
                e[j] = 1.0;
                let body: Vec<Vector3<f64>> =
                    s.rotation.iter().map(|r| r.transpose() * e).collect();
                let mut data: [Option<Vec<f64>>; 6] = Default::default();
                for (c, d) in data.iter_mut().enumerate().take(3) {
                    *d = Some(body.iter().map(|v| v[c]).collect());
                }
                EffectColumn {
                    name: n.to_string(),
                    unit: "N".into(),
                    data,
                }
            })
            .collect()
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (
            "yaw angle [rad]".into(),
            s.rotation
                .iter()
                .map(|r| r[(1, 0)].atan2(r[(0, 0)]))
                .collect(),
        )
    }
}

/// Thrust-gain error: the delivered collective thrust is `(1 + κ)` times the logged one
/// (a wrong thrust coefficient, battery sag), and so are the rotor torques. Column
/// `[0, 0, f_z, τ_x, τ_y, τ_z]`. Identifiable only with a known mass.
#[derive(Debug, Clone, Copy, Default)]
pub struct ThrustGain;

impl Effect for ThrustGain {
    fn name(&self) -> &str {
        "thrust-gain"
    }
    fn description(&self) -> &str {
        "delivered thrust is a constant factor (1 + kappa) times the logged thrust"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn needs_known_mass(&self) -> bool {
        true
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        for (c, d) in data.iter_mut().enumerate().skip(2) {
            *d = Some(s.channel(c));
        }
        vec![EffectColumn {
            name: "kappa".into(),
            unit: "1".into(),
            data,
        }]
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        if coef[0].abs() > 0.5 {
            Plausibility::bad(format!("thrust gain error {:.2} beyond ±50 %", coef[0]))
        } else {
            Plausibility::ok()
        }
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("thrust fz [N]".into(), s.channel(2))
    }
}

/// A user-defined effect from log signals: the product of named columns as a regressor on
/// chosen wrench channels (one coefficient per channel). CLI syntax (`--custom`):
/// `NAME=COL[*COL…]@CH[,CH…]`, e.g. `vbat=vbat*fz@fz`.
#[derive(Debug, Clone)]
pub struct CustomEffect {
    /// Effect name.
    pub name: String,
    /// Log columns multiplied together.
    pub factors: Vec<String>,
    /// Channels it acts on.
    pub on: Vec<Channel>,
    description: String,
}

impl CustomEffect {
    /// Builds a custom effect.
    pub fn new(name: &str, factors: Vec<String>, on: Vec<Channel>) -> Self {
        let description = format!(
            "custom: {} on {}",
            factors.join("·"),
            on.iter()
                .map(|c| CHANNEL_NAMES[*c])
                .collect::<Vec<_>>()
                .join(",")
        );
        Self {
            name: name.to_string(),
            factors,
            on,
            description,
        }
    }

    /// Parses `NAME=COL[*COL…]@CH[,CH…]`.
    ///
    /// # Errors
    /// [`crate::DiagnoseError::BadCustomSpec`] on a syntax error or unknown channel.
    pub fn parse(spec: &str) -> Result<Self, crate::DiagnoseError> {
        let bad = |reason: &str| crate::DiagnoseError::BadCustomSpec {
            spec: spec.to_string(),
            reason: reason.to_string(),
        };
        let (name, rest) = spec
            .split_once('=')
            .ok_or_else(|| bad("expected NAME=COL[*COL...]@CH[,CH...]"))?;
        let (expr, chans) = rest
            .split_once('@')
            .ok_or_else(|| bad("missing @channels"))?;
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty name"));
        }
        let factors: Vec<String> = expr.split('*').map(|s| s.trim().to_string()).collect();
        if factors.iter().any(String::is_empty) {
            return Err(bad("empty factor"));
        }
        let mut on = Vec::new();
        for c in chans.split(',') {
            let c = c.trim();
            let k = CHANNEL_NAMES
                .iter()
                .position(|n| *n == c)
                .ok_or_else(|| bad(&format!("unknown channel `{c}` (fx,fy,fz,tx,ty,tz)")))?;
            if !on.contains(&k) {
                on.push(k);
            }
        }
        Ok(Self::new(name, factors, on))
    }

    fn product(&self, s: &Signals) -> Result<Vec<f64>, String> {
        let mut out = vec![1.0; s.len()];
        for f in &self.factors {
            let v = s
                .log
                .signal(f)
                .ok_or_else(|| format!("log has no column `{f}`"))?;
            for (o, x) in out.iter_mut().zip(v) {
                *o *= x;
            }
        }
        Ok(out)
    }
}

impl Effect for CustomEffect {
    fn name(&self) -> &str {
        &self.name
    }
    fn description(&self) -> &str {
        &self.description
    }
    fn channels(&self) -> Vec<Channel> {
        self.on.clone()
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        self.product(s).map(|_| ())
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let Ok(v) = self.product(s) else {
            return Vec::new();
        };
        self.on
            .iter()
            .map(|&c| {
                EffectColumn::on(
                    &format!("{}_{}", self.name, CHANNEL_NAMES[c]),
                    "?",
                    c,
                    v.clone(),
                )
            })
            .collect()
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (self.factors.join("*"), self.product(s).unwrap_or_default())
    }
}

/// Every built-in effect with default settings, in [`BUILTIN_NAMES`] order.
pub fn builtin_effects() -> Vec<EffectRef> {
    vec![
        Arc::new(LinearDrag),
        Arc::new(QuadraticDrag),
        Arc::new(RotorDrag),
        Arc::new(MotorLag::default()),
        Arc::new(TimeDelay::default()),
        Arc::new(GroundEffect::default()),
        Arc::new(BodyBias),
        Arc::new(Wind),
        Arc::new(ThrustGain),
    ]
}

/// A built-in effect by name.
///
/// # Errors
/// [`crate::DiagnoseError::UnknownEffect`].
pub fn builtin_by_name(name: &str) -> Result<EffectRef, crate::DiagnoseError> {
    builtin_effects()
        .into_iter()
        .find(|e| e.name() == name)
        .ok_or_else(|| crate::DiagnoseError::UnknownEffect(name.to_string()))
}

#[cfg(test)]
pub(crate) fn shifted_for_tests(t: &[f64], x: &[f64], d: f64) -> Vec<f64> {
    shifted(t, x, d)
}
