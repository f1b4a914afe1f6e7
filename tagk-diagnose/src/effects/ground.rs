//! Ground effect: extra rotor thrust close to the ground.

use tagk_dynamics::EffectKind;

/// Largest physical ground-effect gain (the Cheeseman-Bennett law's is 1; measured rotors near
/// the ground gain up to a few times its prediction).
pub const MAX_GROUND_GAIN: f64 = 4.0;

use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::signals::{Channel, Signals};

/// Ground effect: extra rotor thrust near the ground after Cheeseman and Bennett:
/// `T_IGE/T_OGE = 1/(1 − (R/4z)²)`. So the external wrench is
/// `c · [0, 0, f_z, 0, 0, 0] · ((1/(1 − (R/4z)²)) − 1)` with `c ≈ 1`, `z` the height of the
/// body origin above the ground plane `z = 0` (clamped to `z ≥ R`).
///
/// The rotor torques scale alike, but the column leaves them out, for the reason of
/// `thrust-gain`. The measured torques of a small quadrotor are mostly rotor-speed noise. A
/// column of the measured torque regresses that noise onto itself and pulls `c` down
/// (measured: `c = 0.94` where the plant's is 1, and the thrust gain then fits better). The
/// torques' share is small: its mean part is the inertia's scale, and what varies with the
/// height is about 1 % of the torque.
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
        vec![2]
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        data[2] = Some(
            s.positions()
                .zip(s.wrench())
                .map(|(p, w)| w[2] * self.shape(p.z))
                .collect(),
        );
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
        w[2] = b[2] * shape;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{Model, fit_model};
    use crate::testdata::{crazyflie, gauss, synthetic_log};
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// Cheeseman and Bennett's excess thrust ratio, written out again: `1/(1 − (R/4z)²) − 1`.
    fn excess(z: f64) -> f64 {
        let z = z.max(0.0225);
        let x = 0.0225 / (4.0 * z);
        x * x / (1.0 - x * x)
    }

    /// A log near the ground: the synthetic motion lowered to heights of 3–43 cm. The plant
    /// delivers the logged thrust and torques times `1/(1 − (R/4z)²)` (as the simulator's
    /// rotors do). The logged thrust and torques carry rotor-speed noise `sigma_f` \[N\] and
    /// `sigma_t` \[N m\].
    fn near_ground(n: usize, sigma_f: f64, sigma_t: f64, seed: u64) -> Signals {
        let mut log = synthetic_log(&crazyflie(), n, 5e-4, seed, &|_, _| [0.0; 6]);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 1);
        for (p, w) in log.position.iter_mut().zip(&mut log.wrench) {
            p[2] -= 0.97;
            let ratio = 1.0 + excess(p[2]);
            for (c, b) in w.iter_mut().enumerate().skip(2) {
                let sigma = if c == 2 { sigma_f } else { sigma_t };
                *b = *b / ratio + sigma * gauss(&mut rng);
            }
        }
        Signals::from_log(&log).unwrap()
    }

    #[test]
    fn the_column_is_the_thrust_times_the_excess_ratio() {
        let s = near_ground(500, 0.0, 0.0, 3);
        let cols = GroundEffect::default().columns(&s, None);
        assert_eq!(cols.len(), 1);
        let fz = s.channel(2);
        for (c, data) in cols[0].data.iter().enumerate() {
            if c != 2 {
                assert!(data.is_none(), "channel {c}");
                continue;
            }
            let data = data.as_ref().unwrap();
            for ((d, f), p) in data.iter().zip(&fz).zip(s.positions()) {
                assert!((d - f * excess(p.z)).abs() <= 1e-15, "{d} {f} {}", p.z);
            }
        }
    }

    /// The gain of `model` fitted to `s`, and its standard error.
    fn gain(s: &Signals) -> (f64, f64) {
        let model = Model::rigid_body()
            .with_known_mass(crazyflie().mass())
            .with_ref(crate::effects::builtin(EffectKind::GroundEffect).unwrap());
        let fit = fit_model(&model, s, None).unwrap();
        let c = &fit.effects[0].coefficients[0];
        (c.value, c.std_error.unwrap())
    }

    #[test]
    fn the_gain_of_the_plant_is_found_within_its_interval() {
        let (c, se) = gain(&near_ground(12_000, 2e-3, 1e-4, 7));
        assert!(se > 0.0 && se < 0.02, "{c} ± {se}");
        assert!((c - 1.0).abs() < 3.0 * se, "{c} ± {se}");
    }

    /// Measured torques that are mostly rotor-speed noise leave the gain as it is. A column
    /// of the measured torques would regress that noise onto itself (measured on these logs:
    /// `c = −10` instead of 1).
    #[test]
    fn noise_on_the_measured_torques_does_not_move_the_gain() {
        // The same draws: the thrust's noise is the same in both logs.
        let (quiet, se) = gain(&near_ground(12_000, 2e-2, 0.0, 7));
        let (noisy, _) = gain(&near_ground(12_000, 2e-2, 1e-4, 7));
        assert!(
            (noisy - quiet).abs() < 0.2 * se,
            "{quiet} ± {se} against {noisy}"
        );
    }
}
