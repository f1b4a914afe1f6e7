//! Drag: linear, quadratic and rotor drag on the body-frame velocity (forces only).

use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::signals::{Channel, Signals};

/// Horizontal speed in the body frame \[m/s\]: the driving signal of the drag effects.
fn horiz_speed(s: &Signals) -> Vec<f64> {
    s.velocity_body
        .iter()
        .map(|v| (v.x * v.x + v.y * v.y).sqrt())
        .collect()
}

/// Linear aerodynamic drag in the body frame: `f_ext = −diag(d_x, d_y, d_z) v_b`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct LinearDrag;

impl Effect for LinearDrag {
    fn name(&self) -> &str {
        EffectKind::LinearDrag.name()
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
pub(crate) struct QuadraticDrag;

impl Effect for QuadraticDrag {
    fn name(&self) -> &str {
        EffectKind::QuadraticDrag.name()
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

/// Rotor (blade-flapping / induced) drag, per rotor at its hub: `H_i = −K |ω_i| v_hub,i` with
/// `K = diag(k_x, k_y, k_z)` and `v_hub,i = v_b + Ω × r_i` the hub's body-frame velocity, and
/// the yaw moment of the horizontal hub forces about the origin, `(r_i × H_i)_z` (from
/// differential rotor speeds times the horizontal velocity, and the yaw rate). The hub
/// positions `r_i` (in the body x-y plane) come from the mixer identified from the log
/// ([`Signals::rotor_mixer`]); without one, the force `−K (Σ|ω_i|) v_b` alone. Needs rotor
/// speeds.
///
/// The roll and pitch moments of the vertical hub forces are left out: their hub velocity is
/// dominated by `Ω × r_i`, so they act as a roll/pitch rate damping `∝ k_z Σ y_i² ω_i Ω` that
/// the vertical force barely constrains, and on simulator logs they fitted unrelated
/// rate-correlated torque residuals (a spurious `rotor-drag` after a lag or a delay).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RotorDrag;

impl Effect for RotorDrag {
    fn name(&self) -> &str {
        EffectKind::RotorDrag.name()
    }
    fn description(&self) -> &str {
        "rotor drag at each hub, -K |w_i| v_hub, with its moments about the origin"
    }
    fn channels(&self) -> Vec<Channel> {
        (0..6).collect()
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
        let hubs = s.rotor_mixer().map(|m| m.hubs);
        let n = s.len();
        // data[axis][channel]: the external wrench per unit k_axis.
        let mut data: Vec<[Option<Vec<f64>>; 6]> = (0..3)
            .map(|axis| {
                let mut d: [Option<Vec<f64>>; 6] = Default::default();
                d[axis] = Some(vec![0.0; n]);
                if hubs.is_some() {
                    let torques: &[usize] = match axis {
                        0 | 1 => &[5],
                        _ => &[],
                    };
                    for &c in torques {
                        d[c] = Some(vec![0.0; n]);
                    }
                }
                d
            })
            .collect();
        let mut put = |axis: usize, c: usize, i: usize, x: f64| {
            if let Some(v) = data[axis][c].as_mut() {
                v[i] += x;
            }
        };
        for i in 0..n {
            let v = s.velocity_body[i];
            match hubs {
                None => {
                    let sum: f64 = w[i].iter().map(|x| x.abs()).sum();
                    for axis in 0..3 {
                        put(axis, axis, i, -v[axis] * sum);
                    }
                }
                Some(h) => {
                    let om = s.omega[i];
                    for (r, hub) in h.iter().enumerate() {
                        let (x, y) = (hub[0], hub[1]);
                        let p = nalgebra::Vector3::new(x, y, 0.0);
                        let vh = v + om.cross(&p);
                        let wr = w[i][r].abs();
                        // H = −K |ω| v_hub; moment r × H with r = (x, y, 0).
                        let (hx, hy, hz) = (-wr * vh.x, -wr * vh.y, -wr * vh.z);
                        put(0, 0, i, hx);
                        put(0, 5, i, -y * hx);
                        put(1, 1, i, hy);
                        put(1, 5, i, x * hy);
                        put(2, 2, i, hz);
                    }
                }
            }
        }
        ["k_x", "k_y", "k_z"]
            .iter()
            .zip(data)
            .map(|(name, data)| EffectColumn {
                name: name.to_string(),
                unit: "N s²/(m rad)".into(),
                data,
                fixed: None,
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
