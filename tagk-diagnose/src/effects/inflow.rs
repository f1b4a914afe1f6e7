//! Rotor inflow: each rotor's thrust loss with its own axial air speed, with its moments.

use nalgebra::Vector3;
use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::predict::BodyState;
use crate::signals::{Channel, Signals};

/// The inflow column at one sample, `[fx..tz]` per unit `k_in`: from the body-frame velocity
/// `v` \[m/s\], the body rate `om` \[rad/s\], the rotor speeds `w` \[rad/s\] and the hub
/// positions `(x_i, y_i)` \[m\]. Hub `i` has the axial velocity `v_a,i = v_z + p y_i − q x_i`
/// and adds the force `f_z,i = −|ω_i| v_a,i` and the moment `(y_i f_z,i, −x_i f_z,i, 0)`.
/// Without hubs, the force `−(Σ|ω_i|) v_z` alone.
pub(crate) fn inflow_at(
    v: &Vector3<f64>,
    om: &Vector3<f64>,
    w: &[f64; 4],
    hubs: Option<&[[f64; 2]; 4]>,
) -> [f64; 6] {
    let mut out = [0.0; 6];
    match hubs {
        None => out[2] = -v.z * w.iter().map(|x| x.abs()).sum::<f64>(),
        Some(h) => {
            for (hub, wr) in h.iter().zip(w) {
                let (x, y) = (hub[0], hub[1]);
                let fz = -wr.abs() * (v.z + om.x * y - om.y * x);
                out[2] += fz;
                out[3] += y * fz;
                out[4] += -x * fz;
            }
        }
    }
    out
}

/// Half-width of the neighbourhood whose mean stands for a rotor's speed \[samples\].
const NEIGHBOURS: usize = 2;

/// Rotor `r`'s speed at sample `i` as the mean of `|ω_r|` at the samples `i ± 1 … i ± 2`
/// within the log, sample `i` itself left out \[rad/s\]. The logged wrench at `i` is the
/// mixer of the read-back speeds at `i`. A column carrying the same read-back noise would
/// correlate with the target's noise (errors in variables). Measured on simulated helices with
/// 20 rad/s read-back noise and no inflow: `k_in = 5.7e-6` (5.5× the Crazyflie's value), as
/// `−2 k_f ω σ² Σ v_a,i` predicts. The neighbours' noise is independent of sample `i`'s; the
/// symmetric mean follows the slow speed to second order. A log of one sample uses its own.
fn neighbour_speeds(w: &[[f64; 4]], i: usize) -> [f64; 4] {
    let lo = i.saturating_sub(NEIGHBOURS);
    let hi = (i + NEIGHBOURS).min(w.len().saturating_sub(1));
    let mut sum = [0.0; 4];
    let mut count = 0.0;
    for (k, speeds) in w.iter().enumerate().take(hi + 1).skip(lo) {
        if k == i {
            continue;
        }
        for r in 0..4 {
            sum[r] += speeds[r].abs();
        }
        count += 1.0;
    }
    if count == 0.0 {
        return w[i].map(f64::abs);
    }
    sum.map(|x| x / count)
}

/// Rotor inflow (`rotor-inflow`): rotor `i` makes `k_f ω_i² − k_in |ω_i| v_a,i`, with
/// `v_a,i = v_z + (Ω × r_i)_z` the body-`z` velocity of its hub \[m/s\]. One coefficient
/// `k_in ≥ 0` \[N s²/(m rad)\] carries the vertical force `−k_in Σ|ω_i| v_a,i` and its moments
/// `r_i × f_i`: a roll/pitch rate damping `∝ Σ |ω_i| y_i² p`.
///
/// The force near hover is `rotor-drag`'s `k_z` column. What tells the two apart is the
/// moments: `rotor-drag` carries its hub moments on `k_h`, which the horizontal forces pin
/// down; here they ride on `k_in` with the vertical force. The pair is fitted jointly without
/// a null space (a test). The hub positions come from the mixer identified from the log
/// ([`Signals::rotor_mixer`]); without one, the force alone. Each `|ω_i|` is the mean of the
/// neighbouring samples' read-back speeds ([`neighbour_speeds`]): the logged wrench's own
/// read-back noise stays out of the column. Needs rotor speeds.
///
/// Plausible: `0 ≤ k_in ≤ limit`, each within 3 standard errors. The limit is momentum
/// theory's. Blade-element and momentum theory at hover give
/// `−dT/dv = 1 / (8/(σ a) + 1/(2 λ_h)) · ρ A Ω R < 2 ρ A v_h`. With `T = k_f Ω² = 2 ρ A v_h²`,
/// `k_in < sqrt(2 ρ A k_f)` for any blade. A larger fit is another effect's residual. Measured:
/// a 20 ms motor lag hidden with a 60 ms log delay, fitted as `time-delay` + `rotor-inflow`,
/// gives `k_in = 1.5e-5` (seeds 7, 21, 22), 1.6× the Crazyflie's limit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RotorInflow {
    /// The momentum-theory limit of `k_in` \[kg/rad\].
    pub(crate) limit: f64,
}

impl Default for RotorInflow {
    /// The Crazyflie's limit, `sqrt(2 ρ π R² k_f)` with `ρ = 1.225 kg/m³`,
    /// `R = 0.0225 m`, `k_f = 2.3e-8 N s²` (9.5e-6 kg/rad).
    fn default() -> Self {
        let area = std::f64::consts::PI * tagk_dynamics::quadrotor::CRAZYFLIE_ROTOR_RADIUS.powi(2);
        Self {
            limit: (2.0 * 1.225 * area * tagk_dynamics::quadrotor::CRAZYFLIE_K_F).sqrt(),
        }
    }
}

impl Effect for RotorInflow {
    fn name(&self) -> &str {
        EffectKind::RotorInflow.name()
    }
    fn description(&self) -> &str {
        "rotor thrust loss with its axial air speed, -k_in |w_i| v_z,hub, with its moments"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4]
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
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        let channels: &[usize] = if hubs.is_some() { &[2, 3, 4] } else { &[2] };
        for &c in channels {
            data[c] = Some(vec![0.0; n]);
        }
        for i in 0..n {
            let speeds = neighbour_speeds(w, i);
            let at = inflow_at(&s.velocity_body[i], &s.omega(i), &speeds, hubs.as_ref());
            for &c in channels {
                if let Some(col) = &mut data[c] {
                    col[i] = at[c];
                }
            }
        }
        vec![EffectColumn::new("k_in", "N s²/(m rad)", data)]
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
        Some(vec![inflow_at(
            &state.velocity_body(),
            &state.omega,
            &neighbour_speeds(w, i),
            hubs.as_ref(),
        )])
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        let sign = nonneg(&["k_in"], coef, se, "inflow coefficient");
        if !sign.plausible {
            return sign;
        }
        match coef.first() {
            Some(&k) if k - self.limit > 3.0 * se.first().copied().unwrap_or(0.0).max(1e-300) => {
                Plausibility::broken(
                    "inflow-limit",
                    format!(
                        "inflow coefficient k_in = {k:.3e} is significantly above momentum theory's limit {:.3e} (BuiltinOptions::inflow_limit)",
                        self.limit
                    ),
                )
            }
            _ => Plausibility::ok(),
        }
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        (
            "roll/pitch rate [rad/s]".into(),
            (0..s.len())
                .map(|i| {
                    let om = s.omega(i);
                    (om.x * om.x + om.y * om.y).sqrt()
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tagk_sim::plant_effects::RotorInflow as PlantInflow;

    /// The Crazyflie's hubs (M1..M4, docs/CONVENTIONS.md §4).
    fn hubs() -> [[f64; 2]; 4] {
        let l = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
        [[l, -l], [-l, -l], [-l, l], [l, l]]
    }

    /// The column times `k_in` is the simulator's inflow wrench (written separately, with 3-D
    /// cross products), on states that exercise every term.
    #[test]
    fn the_column_is_the_plant_law_per_unit_coefficient() {
        let k = 1.7e-6;
        let plant = PlantInflow { coefficient: k };
        let hubs3 = hubs().map(|h| Vector3::new(h[0], h[1], 0.0));
        let states = [
            (Vector3::new(0.3, -0.2, 0.4), Vector3::new(0.0, 0.0, 0.0)),
            (Vector3::new(0.0, 0.0, 0.0), Vector3::new(1.2, -0.7, 0.4)),
            (Vector3::new(-0.5, 0.1, -0.3), Vector3::new(-2.0, 0.9, -1.5)),
        ];
        let w = [1900.0, 2100.0, 1800.0, 2300.0];
        for (v, om) in states {
            let col = inflow_at(&v, &om, &w, Some(&hubs()));
            let truth = plant.wrench(&v, &om, &w, &hubs3).to_array();
            for c in 0..6 {
                assert!(
                    (k * col[c] - truth[c]).abs() <= 1e-12 * truth[c].abs().max(1e-9),
                    "channel {c}: {} vs {}",
                    k * col[c],
                    truth[c]
                );
            }
        }
    }

    /// Closed forms: at `Ω = 0` with equal speeds the torques cancel (a symmetric layout) and
    /// the force is `−(Σ|ω|) v_z`, `rotor-drag`'s `k_z` column; a pure roll rate `p` gives the
    /// roll torque `−Σ |ω_i| y_i² p` and no force (`Σ y_i = 0`); without hubs the force alone.
    #[test]
    fn the_column_follows_its_closed_forms() {
        let v = Vector3::new(0.2, 0.1, -0.4);
        let w = [2000.0; 4];
        let col = inflow_at(&v, &Vector3::zeros(), &w, Some(&hubs()));
        assert!((col[2] - 0.4 * 8000.0).abs() < 1e-9);
        assert!(col[3].abs() < 1e-12 && col[4].abs() < 1e-12);
        let drag = crate::effects::drag::rotor_drag_at(&v, &Vector3::zeros(), &w, Some(&hubs()));
        assert!((col[2] - drag[1][2]).abs() < 1e-9);
        let p = 1.3;
        let col = inflow_at(
            &Vector3::zeros(),
            &Vector3::new(p, 0.0, 0.0),
            &w,
            Some(&hubs()),
        );
        let l = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
        assert!(col[2].abs() < 1e-12);
        assert!((col[3] + 4.0 * 2000.0 * l * l * p).abs() < 1e-12);
        assert!(col[4].abs() < 1e-12);
        let bare = inflow_at(&v, &Vector3::new(p, 0.0, 0.0), &w, None);
        assert_eq!(bare, [0.0, 0.0, 0.4 * 8000.0, 0.0, 0.0, 0.0]);
    }

    /// The neighbours' mean leaves the sample out, follows a quadratic exactly in the interior
    /// (symmetric weights), and at the ends takes what exists.
    /// The default limit is `sqrt(2 ρ π R² k_f)` for the Crazyflie, computed by hand
    /// (`2 · 1.225 · π · 0.0225² · 2.3e-8 = 8.962e-11`); a fit above it by more than 3
    /// standard errors is implausible, within them or below it plausible.
    #[test]
    fn the_limit_is_momentum_theorys() {
        let e = RotorInflow::default();
        assert!(
            (e.limit - 8.962e-11_f64.sqrt()).abs() < 1e-4 * e.limit,
            "{}",
            e.limit
        );
        assert!(!e.plausibility(&[1.5e-5], &[5e-7], None).plausible);
        assert!(e.plausibility(&[1.0e-5], &[5e-7], None).plausible);
        assert!(e.plausibility(&[1.0e-6], &[5e-7], None).plausible);
        assert!(!e.plausibility(&[-1.0e-5], &[5e-7], None).plausible);
    }

    #[test]
    fn neighbour_speeds_leave_the_sample_out() {
        let w: Vec<[f64; 4]> = (0..7)
            .map(|k| {
                let x = k as f64;
                [1000.0 + 3.0 * x, -(1500.0 + 2.0 * x), 1200.0, 900.0]
            })
            .collect();
        let mut spiked = w.clone();
        spiked[3][0] += 500.0;
        let mid = neighbour_speeds(&spiked, 3);
        assert_eq!(mid, [1009.0, 1506.0, 1200.0, 900.0]);
        // Ends: sample 0 averages samples 1 and 2.
        assert_eq!(neighbour_speeds(&w, 0)[0], 1000.0 + 4.5);
        assert_eq!(
            neighbour_speeds(&w[..1], 0),
            [1000.0, 1500.0, 1200.0, 900.0]
        );
        // A quadratic in the interior: the symmetric mean is off by (1 + 4)/2 · a for
        // ω = a k², i.e. second order in the step.
        let q: Vec<[f64; 4]> = (0..7).map(|k| [(k * k) as f64; 4]).collect();
        assert_eq!(neighbour_speeds(&q, 3)[0], 9.0 + 2.5);
    }
}
