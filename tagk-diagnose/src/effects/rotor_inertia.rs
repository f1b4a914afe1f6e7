//! Rotor inertia: the torques of the spinning rotors on the body.

use tagk_dynamics::EffectKind;
use tagk_dynamics::quadrotor::CRAZYFLIE_INERTIA;

use crate::deriv::savitzky_golay_derivative;
use crate::effects::{Effect, EffectColumn, Plausibility, nonneg};
use crate::predict::BodyState;
use crate::signals::{Channel, Signals};

/// The largest plausible axial inertia of one rotor \[kg m²\]: a quarter of the Crazyflie's
/// `I_zz`. The four rotors spin about `z` and are part of the body, so `4 J_r ≤ I_zz`.
pub(crate) const MAX_ROTOR_INERTIA: f64 = CRAZYFLIE_INERTIA[5] / 4.0;

/// Half-width of the differentiator of `H` (1: three samples, a central difference on uniform
/// sampling).
const RATE_HALF_WIDTH: usize = 1;

/// Rotor inertia `J_r` \[kg m²\] of each rotor with its motor bell (docs/CONVENTIONS.md §7).
///
/// With the signed spin sum `H = Σ sᵢ ωᵢ` \[rad/s\] of the logged rotor speeds, the rotors add
/// the torque `J_r Ḣ e_z + J_r H (Ω × e_z)` (body frame). One column, on three channels:
/// `tx = H q`, `ty = −H p` (gyroscopic, `Ω = (p, q, r)` the logged body rate) and `tz = Ḣ`
/// (the yaw reaction of the rotors' acceleration, less what a timing error of the actuator log
/// makes: [`spin_sum_and_rate`]). The spin signs `sᵢ` are those of the yaw
/// row of the mixer identified from the log.
///
/// `Ḣ` is the local rate of `H`: the crate's Savitzky–Golay differentiator at its narrowest
/// window ([`RATE_HALF_WIDTH`], a central difference). Where the body-rate derivative was
/// derived, the fit smooths the torques and this column alike ([`Signals::smooth_channels`]).
/// So `Ḣ` then passes through the very filter `ω̇` passed through, and rotor-speed noise is
/// treated as gyro noise is. A wider differentiator here would smooth `Ḣ` twice, and a
/// smoothed regressor inflates the fitted `J_r` (a 20 ms motor lag moves `H` within 0.1 s).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RotorInertia;

/// The reaction-torque signs `sᵢ` of the log's mixer (the signs of its yaw row), or why not.
fn spins(s: &Signals) -> Result<[f64; 4], String> {
    if s.rotor_speeds().is_none() {
        return Err("the log has no rotor speeds (w1..w4)".into());
    }
    let mixer = s
        .rotor_mixer()
        .ok_or("the logged wrench is not a mixer of the rotor speeds (no spin directions)")?;
    let row = mixer.matrix[3];
    if row.iter().any(|k| !k.is_finite() || *k == 0.0) {
        return Err("the mixer's yaw row does not give every rotor a spin direction".into());
    }
    Ok(row.map(f64::signum))
}

/// The signed spin sum `H = Σ sᵢ ωᵢ` at every sample \[rad/s\].
fn spin_sum(w: &[[f64; 4]], spins: &[f64; 4]) -> Vec<f64> {
    w.iter()
        .map(|x| x.iter().zip(spins).map(|(w, s)| s * w).sum())
        .collect()
}

/// The key of [`spin_sum_and_rate`] in [`Signals::derived`].
const SPIN_RATE_KEY: &str = "rotor-inertia: H and its rate";

/// `(H, Ḣ⊥)` of the log at every sample, or empty vectors without rotor speeds or mixer.
///
/// `Ḣ⊥` is `Ḣ` less its least-squares multiple of `τ̇_z`, the rate of the logged yaw torque
/// (both by the same differentiator). Near hover `τ_z ≈ 2 k_m ω̄ H`, so that multiple is what
/// a timing error of the actuator log (a delay, a lag's time constant off its grid) leaves on
/// `tz`: `δ τ̇_z`. The rest is the yaw reaction a timing error cannot make.
fn spin_sum_and_rate(s: &Signals) -> (Vec<f64>, Vec<f64>) {
    let (Ok(spins), Some(w)) = (spins(s), s.rotor_speeds()) else {
        return (Vec::new(), Vec::new());
    };
    let h = spin_sum(w, &spins);
    let mut h_dot = savitzky_golay_derivative(&s.t, &h, RATE_HALF_WIDTH);
    let tz: Vec<f64> = s.wrench().iter().map(|b| b[5]).collect();
    let tz_dot = savitzky_golay_derivative(&s.t, &tz, RATE_HALF_WIDTH);
    let num: f64 = h_dot.iter().zip(&tz_dot).map(|(a, b)| a * b).sum();
    let den: f64 = tz_dot.iter().map(|b| b * b).sum();
    let c = if den > 0.0 { num / den } else { 0.0 };
    for (x, d) in h_dot.iter_mut().zip(&tz_dot) {
        *x -= c * d;
    }
    (h, h_dot)
}

/// The column's wrench per unit `J_r` at one sample: spin sum `h` \[rad/s\], its rate `h_dot`
/// \[rad/s²\] and body rate `(p, q)` \[rad/s\].
fn wrench_at(h: f64, h_dot: f64, p: f64, q: f64) -> [f64; 6] {
    [0.0, 0.0, 0.0, h * q, -h * p, h_dot]
}

impl Effect for RotorInertia {
    fn name(&self) -> &str {
        EffectKind::RotorInertia.name()
    }
    fn description(&self) -> &str {
        "rotor spin inertia J_r: yaw torque J_r dH/dt and gyroscopic torque J_r H (Omega x e_z), H = sum s_i w_i"
    }
    fn channels(&self) -> Vec<Channel> {
        vec![3, 4, 5]
    }
    fn check(&self, s: &Signals) -> Result<(), String> {
        spins(s).map(|_| ())
    }
    fn columns(&self, s: &Signals, _p: Option<f64>) -> Vec<EffectColumn> {
        let (h, h_dot) = spin_sum_and_rate(s);
        if h.len() != s.len() {
            return Vec::new();
        }
        let mut data: [Option<Vec<f64>>; 6] = Default::default();
        let (mut tx, mut ty) = (Vec::with_capacity(h.len()), Vec::with_capacity(h.len()));
        for (i, hi) in h.iter().enumerate() {
            let om = s.omega(i);
            tx.push(hi * om.y);
            ty.push(-hi * om.x);
        }
        data[3] = Some(tx);
        data[4] = Some(ty);
        data[5] = Some(h_dot);
        vec![EffectColumn::new("J_r", "kg m²", data)]
    }
    /// The gyroscopic part at the predicted body rate; `Ḣ` and `H` from the log at sample `i`
    /// (input-driven: the rotor speeds are the log's).
    fn columns_at(
        &self,
        s: &Signals,
        i: usize,
        state: &BodyState,
        _p: Option<f64>,
    ) -> Option<Vec<[f64; 6]>> {
        // The projection reads the whole log: computed once per log.
        let series = s.derived(SPIN_RATE_KEY, || spin_sum_and_rate(s))?;
        let (h, h_dot) = series.as_ref();
        let (&hi, &dot) = (h.get(i)?, h_dot.get(i)?);
        Some(vec![wrench_at(hi, dot, state.omega.x, state.omega.y)])
    }
    /// `J_r ≥ 0` (beyond 3 standard errors), and at most [`MAX_ROTOR_INERTIA`].
    fn plausibility(&self, coef: &[f64], se: &[f64], _p: Option<f64>) -> Plausibility {
        let sign = nonneg(&["J_r"], coef, se, "rotor inertia");
        if !sign.plausible {
            return sign;
        }
        if coef[0] - 3.0 * se[0] > MAX_ROTOR_INERTIA {
            return Plausibility::broken(
                "rotor-inertia-range",
                format!(
                    "rotor inertia J_r = {:.3e} kg m² exceeds a quarter of a Crazyflie's I_zz ({MAX_ROTOR_INERTIA:.2e} kg m²): four rotors cannot outweigh the body about z",
                    coef[0]
                ),
            );
        }
        Plausibility::ok()
    }
    fn driver(&self, s: &Signals) -> (String, Vec<f64>) {
        let (_, h_dot) = spin_sum_and_rate(s);
        let values = if h_dot.len() == s.len() {
            h_dot.iter().map(|x| x.abs()).collect()
        } else {
            vec![0.0; s.len()]
        };
        ("rotor spin acceleration |dH/dt| [rad/s²]".into(), values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plausibility_bounds_both_sides() {
        let e = RotorInertia;
        assert!(e.plausibility(&[2.5e-8], &[1e-9], None).plausible);
        assert!(e.plausibility(&[-1e-9], &[1e-9], None).plausible);
        let neg = e.plausibility(&[-1e-8], &[1e-9], None);
        assert_eq!(neg.rule, "negative-coefficient");
        let big = e.plausibility(&[1e-5], &[1e-7], None);
        assert_eq!(big.rule, "rotor-inertia-range");
    }
}
