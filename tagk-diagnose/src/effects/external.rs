//! External forces not produced by the rotors: a constant body-frame bias and a steady wind
//! (drag on the air-relative velocity).

use nalgebra::Vector3;

use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::fit::Coefficient;
use crate::predict::BodyState;
use crate::signals::{CHANNEL_NAMES, Channel, Signals};

/// Constant body-frame torque bias (an unbalanced propeller, a bent arm, a cable pulling off
/// the centre): `bias_tx`, `bias_ty`, `bias_tz` \[N m\]. A constant body-frame *force* is not
/// here: it is indistinguishable from an accelerometer offset, and that is by far its most
/// common cause ([`AccelBias`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct BodyBias;

/// The channels of [`BodyBias`].
const BIAS_CHANNELS: [usize; 3] = [3, 4, 5];

impl Effect for BodyBias {
    fn name(&self) -> &str {
        EffectKind::BodyBias.name()
    }
    fn description(&self) -> &str {
        "constant torque in the body frame (unbalanced propeller, bent arm, cable)"
    }
    fn channels(&self) -> Vec<Channel> {
        BIAS_CHANNELS.to_vec()
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let n = s.len();
        BIAS_CHANNELS
            .iter()
            .map(|&c| {
                EffectColumn::on(
                    &format!("bias_{}", CHANNEL_NAMES[c]),
                    "N m",
                    c,
                    vec![1.0; n],
                )
            })
            .collect()
    }
    fn columns_at(
        &self,
        _s: &Signals,
        _i: usize,
        _state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        Some(
            BIAS_CHANNELS
                .iter()
                .map(|&c| crate::effects::drag::on_channel(c, 1.0))
                .collect(),
        )
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("time [s]".into(), s.t.clone())
    }
}

/// The name of the accelerometer-offset candidate (`AccelBias`, a built-in): a sensor error, not
/// physics, and not an effect the simulator's plant has (its sensing profiles have it).
pub const ACCEL_BIAS: &str = "accel-bias";

/// Accelerometer offset: a constant body-frame bias `b_a` of the measured specific force. The
/// regression multiplies the measured acceleration by the mass, so the logged wrench differs
/// from the model by `m b_a`, a constant body-frame force: columns `f_x`, `f_y` \[N\] (the
/// force `m b_a`; `b_a = f / m`). The vertical part is not here: in near-level flight `m b_z`
/// is the weight again, and the wrench rows return the mass scaled by about `1 − b_z / g`.
/// [`crate::DiagnosisPlan`] measures it against the velocity and removes it before the fit
/// ([`crate::accel_offset`]). A
/// physical constant force (a cable) looks the same; it is reported as what it most often is,
/// a sensor offset.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct AccelBias;

impl Effect for AccelBias {
    fn name(&self) -> &str {
        ACCEL_BIAS
    }
    fn description(&self) -> &str {
        "accelerometer offset: a constant body-frame force m b_a (or a physical constant force, which looks the same)"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![0, 1]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let n = s.len();
        (0..2)
            .map(|c| EffectColumn::on(&format!("f_{}", ["x", "y"][c]), "N", c, vec![1.0; n]))
            .collect()
    }
    /// Zero: a sensor error, no force on the body. The fit's column `m b_a` is the offset of
    /// the measured acceleration; the body itself moves by the actuators' wrench.
    fn columns_at(
        &self,
        _s: &Signals,
        _i: usize,
        _state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        Some(vec![[0.0; 6]; 2])
    }
    fn plausibility(&self, _coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("time [s]".into(), s.t.clone())
    }
}

/// Largest plausible wind speed \[m/s\] (a strong breeze; flying a small multirotor in more
/// is not a diagnosis question).
pub const MAX_WIND_SPEED: f64 = 15.0;

/// Steady horizontal wind: drag on the air-relative velocity, `f_b = −D Rᵀ (v − v_w)` with
/// `D = diag(d_x, d_y, d_z)` \[N s/m\] and `v_w` the wind, world frame \[m/s\], horizontal (a
/// constant vertical world force is the weight again and would trade against the mass).
/// Fitted together as the drag columns `−v_b` and the world-frame force `F_w = D v_w`
/// (body-frame columns `Rᵀ e_x, Rᵀ e_y`; exact for `d_x = d_y` and level flight, the usual case); the
/// wind velocity `v_w ≈ F_w / d` with `d` the mean horizontal drag is reported as a derived
/// quantity. With rotor speeds in the log the drag is the rotor drag, `D = K Σ|ω_i|`: every
/// column carries the factor `Σ|ω_i|` and the coefficients are `K` and `K v_w`.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Wind;

/// Names of the wind's columns with rotor speeds in the log: the rotor drag `K`, then `K v_w`.
const ROTOR_WIND_COLUMNS: [(&str, &str); 5] = [
    ("k_x", "N s²/(m rad)"),
    ("k_y", "N s²/(m rad)"),
    ("k_z", "N s²/(m rad)"),
    ("kv_wx", "N s/rad"),
    ("kv_wy", "N s/rad"),
];

/// Names of the wind's columns: the drag, then the world-frame force.
const WIND_COLUMNS: [(&str, &str); 5] = [
    ("d_x", "N s/m"),
    ("d_y", "N s/m"),
    ("d_z", "N s/m"),
    ("F_wx", "N"),
    ("F_wy", "N"),
];

/// Where the wind's coefficients are: the hub form (`k_h`, `k_z`, then the wind `kv_wx`,
/// `kv_wy`) or the body-origin form (`d_x`, `d_y`, `d_z`, then `F_wx`, `F_wy`, or their
/// rotor-speed-scaled `k`, `kv`).
struct WindLayout {
    /// The names of the drag coefficients (the first ones).
    drags: &'static [&'static str],
    /// The index of the first wind coefficient.
    first_wind: usize,
    /// The drag that divides the wind force, and its standard error: `k_h`, or the mean of
    /// `d_x` and `d_y`.
    drag: (f64, f64),
}

impl WindLayout {
    /// The layout of the coefficients `coef` with standard errors `se`.
    fn of(coef: &[f64], se: &[f64]) -> Self {
        if coef.len() == 4 {
            Self {
                drags: &["k_h", "k_z"],
                first_wind: 2,
                drag: (coef[0], se[0]),
            }
        } else {
            Self {
                drags: &["d_x", "d_y", "d_z"],
                first_wind: 3,
                drag: (
                    0.5 * (coef[0] + coef[1]),
                    0.5 * (se[0].powi(2) + se[1].powi(2)).sqrt(),
                ),
            }
        }
    }
}

impl Effect for Wind {
    fn name(&self) -> &str {
        EffectKind::Wind.name()
    }
    fn description(&self) -> &str {
        "steady wind: linear drag on the air-relative velocity (drag and wind force fitted together)"
    }
    fn channels(&self) -> Vec<Channel> {
        // With rotor speeds the hub moments act on the torques too.
        (0..6).collect()
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        // With rotor speeds and hub positions the wind acts through the rotors' drag at each
        // hub, moments included: the rotor drag's columns (`k_h`, `k_z`) and the wind's
        // (`kv_wx`, `kv_wy`, per unit `k_h v_w`).
        if let Some([x, y]) = crate::effects::drag::hub_wind_columns(s) {
            let mut cols = crate::effects::drag::RotorDrag.columns(s, None);
            for (name, data) in [("kv_wx", x), ("kv_wy", y)] {
                cols.push(EffectColumn::new(name, "N s/rad", data));
            }
            return cols;
        }
        // With rotor speeds the drag is the rotor drag, scaled by Σ|ω_i|: both the drag and
        // the wind force columns carry the factor (the coefficients become K and K v_w).
        let scale: Vec<f64> = match s.rotor_speeds() {
            Some(w) => w.iter().map(|x| x.iter().map(|v| v.abs()).sum()).collect(),
            None => vec![1.0; s.len()],
        };
        let names = if s.rotor_speeds().is_some() {
            ROTOR_WIND_COLUMNS
        } else {
            WIND_COLUMNS
        };
        let mut cols: Vec<EffectColumn> = (0..3)
            .map(|k| {
                EffectColumn::on(
                    names[k].0,
                    names[k].1,
                    k,
                    s.velocity_body
                        .iter()
                        .zip(&scale)
                        .map(|(v, f)| -v[k] * f)
                        .collect(),
                )
            })
            .collect();
        // Horizontal wind only: a constant vertical world force is the weight `m g` again and
        // would trade against the fitted mass. The body-frame `Rᵀ e_x`, `Rᵀ e_y` in one pass
        // over the attitudes.
        let axes = [0, 1].map(|j| Vector3::ith(j, 1.0));
        let mut wind: [[Vec<f64>; 3]; 2] =
            std::array::from_fn(|_| std::array::from_fn(|_| Vec::with_capacity(s.len())));
        for (r, f) in s.rotations().zip(&scale) {
            let rt = r.transpose();
            for (force, e) in wind.iter_mut().zip(axes) {
                let v = rt * e;
                for (c, column) in force.iter_mut().enumerate() {
                    column.push(v[c] * f);
                }
            }
        }
        for (j, [x, y, z]) in wind.into_iter().enumerate() {
            cols.push(EffectColumn::new(
                names[3 + j].0,
                names[3 + j].1,
                [Some(x), Some(y), Some(z), None, None, None],
            ));
        }
        cols
    }
    fn columns_at(
        &self,
        s: &Signals,
        i: usize,
        state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        let rot = state.rotation();
        let v = state.velocity_body();
        let w = s.rotor_speeds().map(|w| w[i]);
        if let (Some(w), Some(mixer)) = (w, s.rotor_mixer()) {
            let mut cols =
                crate::effects::drag::rotor_drag_at(&v, &state.omega, &w, Some(&mixer.hubs))
                    .to_vec();
            cols.extend(crate::effects::drag::hub_wind_at(&rot, &w, &mixer.hubs));
            return Some(cols);
        }
        let f = w.map_or(1.0, |w| w.iter().map(|x| x.abs()).sum());
        let mut cols: Vec<[f64; 6]> = (0..3)
            .map(|k| crate::effects::drag::on_channel(k, -v[k] * f))
            .collect();
        let rt = rot.transpose();
        for j in 0..2 {
            let d = rt * Vector3::ith(j, 1.0);
            cols.push([d.x * f, d.y * f, d.z * f, 0.0, 0.0, 0.0]);
        }
        Some(cols)
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        let WindLayout {
            drags,
            first_wind,
            drag: (d, d_se),
        } = WindLayout::of(coef, se);
        let drag = nonneg(drags, coef, se, "drag coefficient");
        if !drag.plausible {
            return drag;
        }
        // A wind whose force is within its noise is a plain drag: leave it to the drag effects.
        let horizontal = [first_wind, first_wind + 1];
        if horizontal
            .iter()
            .all(|&j| coef[j].abs() <= 3.0 * se[j].max(f64::MIN_POSITIVE))
        {
            return Plausibility::broken(
                "no-wind",
                "the fitted wind force is within 3 standard errors of zero: a drag without wind explains this",
            );
        }
        // The implied wind speed needs the drag: when a drag effect of the model carries it,
        // the wind's own drag columns are duplicates and their share is not the drag.
        let force = coef[first_wind].hypot(coef[first_wind + 1]);
        if d > 3.0 * d_se && force / d > MAX_WIND_SPEED {
            return Plausibility::broken(
                "wind-speed",
                format!(
                    "implied wind {:.1} m/s (|F_w| / d) beyond {MAX_WIND_SPEED} m/s",
                    force / d
                ),
            );
        }
        Plausibility::ok()
    }
    fn derived(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Vec<Coefficient> {
        let WindLayout {
            first_wind,
            drag: (d, d_se),
            ..
        } = WindLayout::of(coef, se);
        if d.is_nan() || d <= 3.0 * d_se {
            // No drag of its own (another effect carries it): no wind speed to report.
            return Vec::new();
        }
        ["v_wx", "v_wy"]
            .iter()
            .enumerate()
            .map(|(j, name)| {
                // Delta method on F / d (independent errors).
                let v = coef[first_wind + j] / d;
                let e = ((se[first_wind + j] / d).powi(2) + (v * d_se / d).powi(2)).sqrt();
                Coefficient::new(name, "m/s", v, e.is_finite().then_some(e))
            })
            .collect()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (
            "yaw angle [rad]".into(),
            s.rotations().map(|r| r[(1, 0)].atan2(r[(0, 0)])).collect(),
        )
    }
}
