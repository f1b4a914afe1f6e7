//! Drag: linear, quadratic and rotor drag on the body-frame velocity (forces only).

use nalgebra::{Matrix3, Vector3};
use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::predict::BodyState;
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
    fn columns_at(
        &self,
        _s: &Signals,
        _i: usize,
        state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        let v = state.velocity_body();
        Some((0..3).map(|k| on_channel(k, -v[k])).collect())
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
    fn columns_at(
        &self,
        _s: &Signals,
        _i: usize,
        state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        let v = state.velocity_body();
        Some((0..3).map(|k| on_channel(k, -v[k] * v[k].abs())).collect())
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["c_x", "c_y", "c_z"], coef, se, "drag coefficient")
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("horizontal body speed [m/s]".into(), horiz_speed(s))
    }
}

/// The force of a steady wind through the rotors' drag, per unit `k_h v_w,j`, for the world
/// directions `j = x, y` (horizontal), in one pass over the attitudes: each hub feels
/// `+|ω_i| Rᵀ e_j` (the air moving past it) and its moment `r_i × (…)` about the origin, on
/// all six channels. `None` without rotor speeds or a rotor mixer (hub positions).
pub(crate) fn hub_wind_columns(s: &Signals) -> Option<[[Option<Vec<f64>>; 6]; 2]> {
    let w = s.rotor_speeds()?;
    let hubs = s.rotor_mixer()?.hubs;
    let n = s.len();
    let mut data: [[Vec<f64>; 6]; 2] =
        std::array::from_fn(|_| std::array::from_fn(|_| vec![0.0; n]));
    for (i, rot) in s.rotations().enumerate() {
        let at = hub_wind_at(&rot, &w[i], &hubs);
        for (col, values) in data.iter_mut().zip(at) {
            for c in 0..6 {
                col[c][i] = values[c];
            }
        }
    }
    Some(data.map(|col| col.map(Some)))
}

/// [`hub_wind_columns`] at one sample: attitude `rot` (body → world), rotor speeds `w`
/// \[rad/s\], hub positions `hubs` \[m\]; per world direction `x`, `y`, the wrench
/// `[fx..tz]` per unit `k_h v_w`.
pub(crate) fn hub_wind_at(rot: &Matrix3<f64>, w: &[f64; 4], hubs: &[[f64; 2]; 4]) -> [[f64; 6]; 2] {
    let rt = rot.transpose();
    let mut out = [[0.0; 6]; 2];
    for (col, j) in out.iter_mut().zip([0, 1]) {
        let d = rt * Vector3::ith(j, 1.0);
        for (r, hub) in hubs.iter().enumerate() {
            let (x, y) = (hub[0], hub[1]);
            let wr = w[r].abs();
            let (hx, hy, hz) = (wr * d.x, wr * d.y, wr * d.z);
            col[0] += hx;
            col[1] += hy;
            col[2] += hz;
            col[3] += y * hz;
            col[4] += -x * hz;
            col[5] += x * hy - y * hx;
        }
    }
    out
}

/// A wrench `[fx..tz]` with `value` on `channel` and zero elsewhere.
pub(crate) fn on_channel(channel: usize, value: f64) -> [f64; 6] {
    let mut w = [0.0; 6];
    w[channel] = value;
    w
}

/// The rotor drag's two columns at one sample ([`RotorDrag`]): per unit `k_h` (horizontal
/// forces and every hub moment) and per unit `k_z` (the vertical force), from the body-frame
/// velocity `v` \[m/s\], the body rate `om` \[rad/s\], the rotor speeds `w` \[rad/s\] and the
/// hub positions (without them, the force `−K (Σ|ω_i|) v` alone).
pub(crate) fn rotor_drag_at(
    v: &Vector3<f64>,
    om: &Vector3<f64>,
    w: &[f64; 4],
    hubs: Option<&[[f64; 2]; 4]>,
) -> [[f64; 6]; 2] {
    let mut horizontal = [0.0; 6];
    let mut vertical = [0.0; 6];
    match hubs {
        None => {
            let sum: f64 = w.iter().map(|x| x.abs()).sum();
            horizontal[0] += -v.x * sum;
            horizontal[1] += -v.y * sum;
            vertical[2] += -v.z * sum;
        }
        Some(h) => {
            for (r, hub) in h.iter().enumerate() {
                let (x, y) = (hub[0], hub[1]);
                let p = Vector3::new(x, y, 0.0);
                let vh = v + om.cross(&p);
                let wr = w[r].abs();
                // H = −K |ω| v_hub; moment r × H with r = (x, y, 0).
                let (hx, hy, hz) = (-wr * vh.x, -wr * vh.y, -wr * vh.z);
                horizontal[0] += hx;
                horizontal[1] += hy;
                horizontal[5] += x * hy - y * hx;
                // The vertical hub forces' moments: their hub velocity is mostly Ω × r_i (a
                // roll/pitch rate damping), carried by k_h.
                horizontal[3] += y * hz;
                horizontal[4] += -x * hz;
                vertical[2] += hz;
            }
        }
    }
    [horizontal, vertical]
}

/// Rotor (blade-flapping / induced) drag, per rotor at its hub: `H_i = −K |ω_i| v_hub,i` with
/// `K = diag(k_h, k_h, k_z)` (axisymmetric rotors: one horizontal coefficient) and
/// `v_hub,i = v_b + Ω × r_i` the hub's body-frame velocity, and the moments `r_i × H_i` about
/// the origin: a yaw torque from differential rotor speeds times the horizontal velocity (and
/// the yaw rate), and roll/pitch torques from the vertical hub forces, whose hub velocity is
/// mostly `Ω × r_i` (a roll/pitch rate damping `∝ Σ y_i² ω_i Ω`). Every moment is carried by
/// `k_h`, which the horizontal forces pin down; `k_z` fits the vertical force alone (with the
/// moments on a free `k_z`, the weakly observed vertical coefficient became a free rate
/// damping that fitted unrelated torque residuals). For the Crazyflie `k_z ≈ 1.1 k_h`
/// (Förster 2015), so the moments are a tenth low at most. The hub positions `r_i` (in the body x-y plane) come from the mixer
/// identified from the log ([`Signals::rotor_mixer`]); without one, the force
/// `−K (Σ|ω_i|) v_b` alone. Needs rotor speeds.
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
        super::needs_rotor_speeds(s)
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let Some(w) = s.rotor_speeds() else {
            return Vec::new();
        };
        let hubs = s.rotor_mixer().map(|m| m.hubs);
        let n = s.len();
        // data[0]: per unit k_h (horizontal forces and every hub moment), data[1]: per unit
        // k_z (the vertical force).
        let mut horizontal: [Option<Vec<f64>>; 6] = Default::default();
        let mut vertical: [Option<Vec<f64>>; 6] = Default::default();
        for c in [0, 1] {
            horizontal[c] = Some(vec![0.0; n]);
        }
        if hubs.is_some() {
            for c in [3, 4, 5] {
                horizontal[c] = Some(vec![0.0; n]);
            }
        }
        vertical[2] = Some(vec![0.0; n]);
        let hubs = hubs.as_ref();
        for i in 0..n {
            let at = rotor_drag_at(&s.velocity_body[i], &s.omega(i), &w[i], hubs);
            for (d, values) in [&mut horizontal, &mut vertical].into_iter().zip(at) {
                for (c, column) in d.iter_mut().enumerate() {
                    if let Some(column) = column {
                        column[i] = values[c];
                    }
                }
            }
        }
        vec![
            EffectColumn::new("k_h", "N s²/(m rad)", horizontal),
            EffectColumn::new("k_z", "N s²/(m rad)", vertical),
        ]
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        nonneg(&["k_h", "k_z"], coef, se, "rotor-drag coefficient")
    }
    fn columns_at(
        &self,
        s: &Signals,
        i: usize,
        state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        let w = s.rotor_speeds()?;
        let hubs = s.rotor_mixer().map(|m| m.hubs);
        let at = rotor_drag_at(&state.velocity_body(), &state.omega, &w[i], hubs.as_ref());
        Some(at.to_vec())
    }

    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("horizontal body speed [m/s]".into(), horiz_speed(s))
    }
}
