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

/// Rotor (blade-flapping / induced) drag: `f_ext,k = −k_k (Σ |ωᵢ|) v_b,k` per body axis;
/// needs rotor speeds.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RotorDrag;

impl Effect for RotorDrag {
    fn name(&self) -> &str {
        EffectKind::RotorDrag.name()
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
