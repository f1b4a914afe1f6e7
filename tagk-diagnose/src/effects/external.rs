//! External forces not produced by the rotors: a constant body-frame bias and a constant
//! world-frame force (steady wind).

use nalgebra::Vector3;

use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility};
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// Constant body-frame force and torque bias (e.g. a miscalibrated motor or a tether).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BodyBias;

impl Effect for BodyBias {
    fn name(&self) -> &str {
        EffectKind::BodyBias.name()
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
pub(crate) struct Wind;

impl Effect for Wind {
    fn name(&self) -> &str {
        EffectKind::Wind.name()
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
