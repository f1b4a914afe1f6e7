//! Rotor imbalance: per-rotor thrust and reaction-torque coefficients.

use tagk_dynamics::EffectKind;

use crate::effects::{Effect, EffectColumn, Plausibility};
use crate::fit::Coefficient;
use crate::signals::{Channel, Signals};

/// The names of the fitted contrasts: rotor `i`'s relative coefficient error minus the four
/// rotors' mean, for rotors 1..3; rotor 4's is their negative sum ([`Effect::derived`]).
const NAMES: [&str; 3] = ["d_eps1", "d_eps2", "d_eps3"];

/// Per-rotor coefficients (`rotor-imbalance`): rotor `i` makes `(1 + ε_i)` times its nominal
/// thrust `k_f ω_i²` and reaction torque `k_m ω_i²` (a weak or damaged rotor). The extra
/// wrench is `Σ ε_i W_i`, with `W_i = M_i ω_i²` rotor `i`'s nominal wrench on `[f_z, τ_x, τ_y,
/// τ_z]` (`M_i` the `i`-th column of the mixer identified from the log).
///
/// Split `ε_i = ε̄ + δ_i` with `Σ δ_i = 0`. The common part `ε̄` is `thrust-gain`: a common
/// scale of the wrench, identifiable only with a known mass. This effect fits the three
/// contrasts alone, with or without a known mass, and leaves `ε̄` to `thrust-gain`: the two
/// effects then never share a direction of the coefficients, and `thrust-gain` keeps its
/// per-log coefficient (a battery's charge). The columns are `W_j − W_4` for `δ_1..δ_3`
/// (`δ_4 = −δ_1 − δ_2 − δ_3`, derived). Their wrench shows in the torques: the roll and pitch
/// contrasts trade against a centre-of-mass offset in level flight, the yaw contrast
/// (`s_i k_m`) against nothing. Needs rotor speeds and the mixer.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RotorImbalance;

impl Effect for RotorImbalance {
    fn name(&self) -> &str {
        EffectKind::RotorImbalance.name()
    }
    fn description(&self) -> &str {
        "per-rotor thrust and torque coefficients (1 + eps_i) k_f w_i^2: the three contrasts"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![2, 3, 4, 5]
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        super::needs_rotor_speeds(s)?;
        if s.rotor_mixer().is_none() {
            return Err("needs the rotor mixer (a wrench computed from the rotor speeds)".into());
        }
        Ok(())
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let (Some(w), Some(mixer)) = (s.rotor_speeds(), s.rotor_mixer()) else {
            return Vec::new();
        };
        let sq: Vec<[f64; 4]> = w.iter().map(|x| x.map(|v| v * v)).collect();
        NAMES
            .iter()
            .enumerate()
            .map(|(j, name)| {
                let mut data: [Option<Vec<f64>>; 6] = Default::default();
                for (r, slot) in data[2..6].iter_mut().enumerate() {
                    let m = &mixer.matrix[r];
                    *slot = Some(sq.iter().map(|x| m[j] * x[j] - m[3] * x[3]).collect());
                }
                EffectColumn::new(name, "1", data)
            })
            .collect()
    }
    fn plausibility(&self, coef: &[f64], _se: &[f64], _p: Option<f64>) -> Plausibility {
        let fourth = -coef.iter().sum::<f64>();
        match coef.iter().chain([&fourth]).find(|d| d.abs() > 0.5) {
            Some(d) => Plausibility::broken(
                "rotor-imbalance-range",
                format!("a rotor's coefficient {d:.2} off the mean: beyond ±50 %"),
            ),
            None => Plausibility::ok(),
        }
    }
    fn derived(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Vec<Coefficient> {
        if coef.len() != 3 || se.len() != 3 {
            return Vec::new();
        }
        // The standard error ignores the contrasts' correlation: a rough scale only.
        let value = -coef.iter().sum::<f64>();
        let spread = se.iter().map(|s| s * s).sum::<f64>().sqrt();
        vec![Coefficient::new("d_eps4", "1", value, Some(spread))]
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        ("thrust fz [N]".into(), s.channel(2))
    }
}
