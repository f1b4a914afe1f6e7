//! Ground effect: extra rotor thrust close to the ground.

use tagk_dynamics::EffectKind;

/// Largest physical ground-effect gain (the Cheeseman-Bennett law's is 1; measured rotors near
/// the ground gain up to a few times its prediction).
pub const MAX_GROUND_GAIN: f64 = 4.0;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::signals::{Channel, Signals};

/// Ground effect: extra rotor thrust (and rotor torques) near the ground after Cheeseman and
/// Bennett: `T_IGE/T_OGE = 1/(1 − (R/4z)²)`, so the external wrench is
/// `c · [0, 0, f_z, τ_x, τ_y, τ_z] · ((1/(1 − (R/4z)²)) − 1)` with `c ≈ 1`, `z` the height of
/// the body origin above the ground plane `z = 0` (clamped to `z ≥ R`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct GroundEffect {
    /// Rotor radius `R` \[m\] (Crazyflie: 0.0225 m).
    pub rotor_radius: f64,
    /// Heights below this are clamped \[m\] (avoids the singularity at `z = R/4`).
    pub min_height: f64,
}

impl Default for GroundEffect {
    fn default() -> Self {
        Self {
            rotor_radius: tagk_dynamics::quadrotor::CRAZYFLIE_ROTOR_RADIUS,
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
        EffectKind::GroundEffect.name()
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
                s.positions()
                    .zip(s.wrench())
                    .map(|(p, w)| w[c] * self.shape(p.z))
                    .collect(),
            );
        }
        vec![EffectColumn::new("c_ge", "1", data)]
    }
    fn columns_at(
        &self,
        s: &Signals,
        i: usize,
        state: &crate::predict::BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        let shape = self.shape(state.position.z);
        let b = s.wrench()[i];
        let mut w = [0.0; 6];
        for c in 2..6 {
            w[c] = b[c] * shape;
        }
        Some(vec![w])
    }
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        let sign = nonneg(&["c_ge"], coef, se, "ground-effect gain");
        if !sign.plausible {
            return sign;
        }
        // The column is the measured wrench times the Cheeseman-Bennett shape: a gain far
        // from 1 scales the whole measured wrench near the ground instead of adding a ground
        // effect (whatever its standard error, a gain below -1 or significantly above
        // MAX_GROUND_GAIN is not one).
        let (c, e) = (coef[0], se[0]);
        if c < -1.0 || c - 3.0 * e.max(0.0) > MAX_GROUND_GAIN {
            return Plausibility::broken(
                "ground-gain-range",
                format!(
                    "ground-effect gain c_ge = {c:.3e} is outside the physical range 0–{MAX_GROUND_GAIN} (Cheeseman-Bennett: 1)"
                ),
            );
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("height [m]".into(), s.positions().map(|p| p.z).collect())
    }
}
