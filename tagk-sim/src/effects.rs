//! Optional plant effects: the physics a real Crazyflie has and the paper's ideal model
//! leaves out. Each effect is a switch (`Option`) in [`PlantEffects`]; all are off by default
//! (the TAG-K paper's experiments), and every effect's `crazyflie()` constructor (also its
//! `Default`) gives a realistic magnitude for a Crazyflie 2.x with its source.
//!
//! The effects act on the **plant only**. The measured wrench `b` the estimator sees is
//! always computed from the commanded rotor speeds with the nominal `k_f`, `k_m` through the
//! mixer, so every effect shows up as a model mismatch `b − Y θ ≠ 0` that a diagnosis tool can
//! look for.

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::SimError;

/// Body-frame linear rotor drag (blade flapping and induced drag), proportional to the sum of
/// rotor speeds: `f_b = −K (Σ ωᵢ) v_b`, with `v_b = Rᵀ (v − v_wind)` the air-relative velocity
/// of the body origin in the body frame [m/s] and `ωᵢ` the actual rotor speeds [rad/s].
///
/// Model and Crazyflie coefficients: J. Förster, "System identification of the Crazyflie 2.0
/// nano quadrocopter", ETH Zürich, 2015 (`K = diag(9.1785, 9.1785, 10.311)·10⁻⁷ kg/rad`);
/// the body-frame linear form is also the one of M. Faessler, A. Franchi, D. Scaramuzza,
/// "Differential flatness of quadrotor dynamics subject to rotor drag", IEEE RA-L 2018.
/// At hover (`Σω ≈ 3.9·10³ rad/s`) this is about `3.5·10⁻³ N s/m` horizontally.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearDrag {
    /// Diagonal of `K` [kg/rad] (body x, y, z).
    pub coefficients: [f64; 3],
}

impl LinearDrag {
    /// Förster (2015)'s identified Crazyflie 2.0 coefficients.
    pub fn crazyflie() -> Self {
        Self {
            coefficients: [9.1785e-7, 9.1785e-7, 10.311e-7],
        }
    }
}

impl Default for LinearDrag {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Quadratic parasitic (bluff-body) drag per body axis: `f_b,i = −½ ρ (C_d A)_i |v_i| v_i`
/// with `v_b` the air-relative body-frame velocity [m/s].
///
/// Standard form of pressure drag (S. F. Hoerner, "Fluid-Dynamic Drag", 1965); the Crazyflie
/// numbers take `C_d ≈ 1` for its frame and a frontal area of about `3·10⁻³ m²` sideways and
/// `6·10⁻³ m²` from above (92 mm × 92 mm frame, mostly open), so it is small next to rotor
/// drag below 1 m/s — as Faessler et al. (2018) observe for quadrotors at low speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QuadraticDrag {
    /// `C_d A` per body axis [m²].
    pub cd_area: [f64; 3],
    /// Air density `ρ` [kg/m³].
    pub air_density: f64,
}

impl QuadraticDrag {
    /// Crazyflie-sized bluff body in sea-level air (`ρ = 1.225 kg/m³`).
    pub fn crazyflie() -> Self {
        Self {
            cd_area: [3e-3, 3e-3, 6e-3],
            air_density: 1.225,
        }
    }
}

impl Default for QuadraticDrag {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// First-order motor lag: each rotor speed follows its command with
/// `ω̇ᵢ = (ω_cmd,i − ωᵢ) / τ_m` (brushless or brushed DC motor with propeller load, the usual
/// first-order model; e.g. Förster 2015 models the Crazyflie motor/propeller response as
/// first order). The default `τ_m = 0.02 s` is at the fast end of the tens-of-milliseconds
/// range of Crazyflie-class coreless motors. The simulator's tracking LQR is designed without
/// lag: with `τ_m = 0.05 s` it loses stability within a second (a diagnosis tool should find
/// the lag before that happens).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotorLag {
    /// Time constant `τ_m` [s].
    pub time_constant: f64,
}

impl MotorLag {
    /// `τ_m = 0.02 s`.
    pub fn crazyflie() -> Self {
        Self {
            time_constant: 0.02,
        }
    }
}

impl Default for MotorLag {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Ground effect on rotor thrust, after I. C. Cheeseman and W. E. Bennett, "The effect of the
/// ground on a helicopter rotor in forward flight", ARC R&M 3021, 1955:
/// `T_IGE / T_OGE = 1 / (1 − (R / 4z)²)` with rotor radius `R` and height `z` of the rotor
/// plane (the body origin's world `z`, ground at `z = 0`). The height is clamped to
/// `z ≥ R` (the formula is only used out to `T_IGE/T_OGE = 16/15`).
///
/// Noticeable only within a few rotor radii of the ground: fly at `altitude ≲ 0.1 m`
/// ([`crate::SimConfig::altitude`]) to see it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundEffect {
    /// Rotor radius `R` [m].
    pub rotor_radius: f64,
}

impl GroundEffect {
    /// Crazyflie 2.x propellers: 45 mm diameter, `R = 0.0225 m`.
    pub fn crazyflie() -> Self {
        Self {
            rotor_radius: 0.0225,
        }
    }

    /// Thrust multiplier at height `z` [m].
    pub fn thrust_ratio(&self, z: f64) -> f64 {
        let z = z.max(self.rotor_radius);
        let r = self.rotor_radius / (4.0 * z);
        1.0 / (1.0 - r * r)
    }
}

impl Default for GroundEffect {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Constant wind, world frame [m/s]. It acts through the air-relative velocity of the drag
/// effects; if neither [`LinearDrag`] nor [`QuadraticDrag`] is on, the wind uses
/// [`LinearDrag::crazyflie`] (without drag, air motion would exert no force).
///
/// Default: a light indoor draft of 0.3 m/s along world x (e.g. ventilation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wind {
    /// Wind velocity, world frame [m/s].
    pub velocity: [f64; 3],
}

impl Wind {
    /// 0.3 m/s along world x.
    pub fn crazyflie() -> Self {
        Self {
            velocity: [0.3, 0.0, 0.0],
        }
    }
}

impl Default for Wind {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Thrust-coefficient error: the true rotors make `(1 + ε) k_f ω²` (and `(1 + ε) k_m ω²` of
/// reaction torque) while the vehicle computes its wrench with the nominal `k_f`, `k_m`.
/// Default `ε = −0.1`: battery sag and propeller wear, which Förster (2015) shows change the
/// Crazyflie's thrust map by this order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThrustCoefficientError {
    /// Relative error `ε` (dimensionless, `> −1`).
    pub relative_error: f64,
}

impl ThrustCoefficientError {
    /// `ε = −0.1`.
    pub fn crazyflie() -> Self {
        Self {
            relative_error: -0.1,
        }
    }
}

impl Default for ThrustCoefficientError {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Constant body-frame force [N] and torque about the origin [N m] not produced by the
/// commanded rotors (an unmodelled cable, a bent arm or unbalanced propeller).
/// Default: 2 mN along body x and 3·10⁻⁵ N m about body x (a 1 % thrust imbalance of one
/// rotor at hover times its 0.0325 m lever).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WrenchBias {
    /// Force, body frame [N].
    pub force: [f64; 3],
    /// Torque about the body origin, body frame [N m].
    pub torque: [f64; 3],
}

impl WrenchBias {
    /// 2 mN along body x, 3·10⁻⁵ N m about body x.
    pub fn crazyflie() -> Self {
        Self {
            force: [2e-3, 0.0, 0.0],
            torque: [3e-5, 0.0, 0.0],
        }
    }
}

impl Default for WrenchBias {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Names of the plant effects (for the CLI and for generating one-effect logs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
pub enum EffectKind {
    /// [`LinearDrag`].
    LinearDrag,
    /// [`QuadraticDrag`].
    QuadraticDrag,
    /// [`MotorLag`].
    MotorLag,
    /// [`GroundEffect`].
    GroundEffect,
    /// [`Wind`].
    Wind,
    /// [`ThrustCoefficientError`].
    ThrustError,
    /// [`WrenchBias`].
    Bias,
}

impl EffectKind {
    /// Every effect, in declaration order.
    pub const ALL: [EffectKind; 7] = [
        EffectKind::LinearDrag,
        EffectKind::QuadraticDrag,
        EffectKind::MotorLag,
        EffectKind::GroundEffect,
        EffectKind::Wind,
        EffectKind::ThrustError,
        EffectKind::Bias,
    ];
}

/// Which plant effects are on (all off by default: the paper's ideal plant).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlantEffects {
    /// Body-frame linear rotor drag.
    pub linear_drag: Option<LinearDrag>,
    /// Quadratic parasitic drag.
    pub quadratic_drag: Option<QuadraticDrag>,
    /// First-order motor lag.
    pub motor_lag: Option<MotorLag>,
    /// Ground effect.
    pub ground_effect: Option<GroundEffect>,
    /// Constant wind.
    pub wind: Option<Wind>,
    /// Thrust-coefficient error.
    pub thrust_error: Option<ThrustCoefficientError>,
    /// Constant body force/torque bias.
    pub bias: Option<WrenchBias>,
}

impl PlantEffects {
    /// No effect: the ideal plant.
    pub fn none() -> Self {
        Self::default()
    }

    /// Exactly one effect on, at its Crazyflie default magnitude.
    pub fn only(kind: EffectKind) -> Self {
        Self::none().with(kind)
    }

    /// This set with `kind` switched on at its Crazyflie default magnitude.
    pub fn with(mut self, kind: EffectKind) -> Self {
        match kind {
            EffectKind::LinearDrag => self.linear_drag = Some(LinearDrag::crazyflie()),
            EffectKind::QuadraticDrag => self.quadratic_drag = Some(QuadraticDrag::crazyflie()),
            EffectKind::MotorLag => self.motor_lag = Some(MotorLag::crazyflie()),
            EffectKind::GroundEffect => self.ground_effect = Some(GroundEffect::crazyflie()),
            EffectKind::Wind => self.wind = Some(Wind::crazyflie()),
            EffectKind::ThrustError => {
                self.thrust_error = Some(ThrustCoefficientError::crazyflie())
            }
            EffectKind::Bias => self.bias = Some(WrenchBias::crazyflie()),
        }
        self
    }

    /// `true` when no effect is on.
    pub fn is_ideal(&self) -> bool {
        *self == Self::none()
    }

    /// Checks every magnitude (finite; positive time constant, radius, density; `ε > −1`).
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad value.
    pub fn validate(&self) -> Result<(), SimError> {
        fn finite(name: &'static str, v: &[f64]) -> Result<(), SimError> {
            match v.iter().find(|x| !x.is_finite()) {
                Some(&value) => Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "must be finite",
                }),
                None => Ok(()),
            }
        }
        fn positive(name: &'static str, value: f64) -> Result<(), SimError> {
            if value > 0.0 && value.is_finite() {
                Ok(())
            } else {
                Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "must be positive and finite",
                })
            }
        }
        if let Some(d) = &self.linear_drag {
            finite("linear_drag.coefficients", &d.coefficients)?;
        }
        if let Some(d) = &self.quadratic_drag {
            finite("quadratic_drag.cd_area", &d.cd_area)?;
            positive("quadratic_drag.air_density", d.air_density)?;
        }
        if let Some(l) = &self.motor_lag {
            positive("motor_lag.time_constant", l.time_constant)?;
        }
        if let Some(g) = &self.ground_effect {
            positive("ground_effect.rotor_radius", g.rotor_radius)?;
        }
        if let Some(w) = &self.wind {
            finite("wind.velocity", &w.velocity)?;
        }
        if let Some(e) = &self.thrust_error {
            finite("thrust_error.relative_error", &[e.relative_error])?;
            if e.relative_error <= -1.0 {
                return Err(SimError::InvalidParameter {
                    name: "thrust_error.relative_error",
                    value: e.relative_error,
                    reason: "must be > -1",
                });
            }
        }
        if let Some(b) = &self.bias {
            finite("bias.force", &b.force)?;
            finite("bias.torque", &b.torque)?;
        }
        Ok(())
    }

    /// Multiplier on every rotor's thrust and reaction torque at height `z` [m]
    /// (thrust-coefficient error times ground effect; 1 for the ideal plant).
    pub fn thrust_multiplier(&self, z: f64) -> f64 {
        let mut k = 1.0;
        if let Some(e) = &self.thrust_error {
            k *= 1.0 + e.relative_error;
        }
        if let Some(g) = &self.ground_effect {
            k *= g.thrust_ratio(z);
        }
        k
    }

    /// Aerodynamic force on the body origin, body frame [N], at world velocity `velocity`
    /// [m/s], attitude `attitude` and actual rotor-speed sum `rotor_speed_sum` [rad/s], plus
    /// the constant bias force.
    pub fn extra_force(
        &self,
        velocity: &Vector3<f64>,
        attitude: &UnitQuaternion<f64>,
        rotor_speed_sum: f64,
    ) -> Vector3<f64> {
        let mut f = Vector3::zeros();
        let wind = self
            .wind
            .map_or_else(Vector3::zeros, |w| Vector3::from(w.velocity));
        let v_air_b = attitude.inverse_transform_vector(&(velocity - wind));
        let linear = match (&self.linear_drag, &self.quadratic_drag, &self.wind) {
            (Some(d), _, _) => Some(*d),
            (None, None, Some(_)) => Some(LinearDrag::crazyflie()),
            _ => None,
        };
        if let Some(d) = linear {
            f -= Vector3::from(d.coefficients).component_mul(&v_air_b) * rotor_speed_sum;
        }
        if let Some(d) = &self.quadratic_drag {
            for i in 0..3 {
                f[i] -= 0.5 * d.air_density * d.cd_area[i] * v_air_b[i].abs() * v_air_b[i];
            }
        }
        if let Some(b) = &self.bias {
            f += Vector3::from(b.force);
        }
        f
    }

    /// Constant bias torque about the origin, body frame [N m] (zero unless
    /// [`bias`](Self::bias) is on).
    pub fn extra_torque(&self) -> Vector3<f64> {
        self.bias
            .map_or_else(Vector3::zeros, |b| Vector3::from(b.torque))
    }
}
