//! Flying an identified model: a model file (docs/MODEL_FILE.md) as a simulator plant.
//!
//! [`model_plant`] reads a [`ModelFile`]'s vehicle, inertial parameters and effects and gives
//! the [`PlantModel`] that `tagk simulate --model` flies. Each diagnosis effect's fitted
//! coefficients (docs/CONVENTIONS.md §7) become the plant effect's coefficients
//! (`PlantEffects::coefficient_names`). The mapping, per effect:
//!
//! | diagnosis effect | its numbers | plant |
//! |---|---|---|
//! | `linear-drag` | `d_x, d_y, d_z` \[N s/m\] | `linear-drag`, the same `D` |
//! | `quadratic-drag` | `c_x, c_y, c_z` \[N s²/m²\] | `quadratic-drag`, `C_d A = 2 c / ρ`, `ρ = 1.225 kg/m³` |
//! | `rotor-drag` | `k_h, k_z` \[kg/rad\] | `rotor-drag`, `K = diag(k_h, k_h, k_z)` |
//! | `body-bias` | `bias_tx, bias_ty, bias_tz` \[N m\] | `body-bias`, that torque and no force |
//! | `thrust-gain` | `kappa` \[1\] | `thrust-gain`, `ε = κ`, the inertia times `1 + κ` |
//! | `ground-effect` | `c_ge` \[1\] | [`GroundEffectGain`]: `1 + c_ge (T_IGE/T_OGE − 1)` |
//! | `motor-lag` | scanned `tau` \[s\] | `motor-lag`, `τ_m = tau` |
//! | `time-delay` | scanned `delay` \[s\] | `time-delay` of `−delay` (the diagnosis's is positive for an early wrench) |
//! | `wind` | `k_h, k_z, kv_wx, kv_wy` | `rotor-drag` `K` and `wind` `v_w = kv / k_h` |
//! | `wind` | `d_x, d_y, d_z, F_wx, F_wy` | `linear-drag` `D` and `wind` `v_w = F_w / d̄` |
//! | `rotor-inertia` | `J_r` \[kg m²\] | `rotor-inertia`, `J_r` times `1 + κ` (as the inertia) |
//! | `rotor-inflow` | `k_in` \[kg/rad\] | `rotor-inflow`, the same `k_in` |
//! | `rotor-imbalance` | `d_eps1, d_eps2, d_eps3` \[1\] | `rotor-imbalance`, `ε = (d₁, d₂, d₃, −d₁ − d₂ − d₃)` |
//! | `battery-voltage` | `beta` \[1\] | `battery-voltage`, the same `β` at `V_ref = 3.8 V`; the Crazyflie battery (it logs `vbat`) |
//!
//! `thrust-gain` is fitted on the thrust alone: the diagnosis's torques stay in units of the
//! logged torque, so its inertia is the true one over `1 + κ`. The plant's gain scales the
//! rotors' torques too, so the inertia (`I_xx … I_zz`) is flown times `1 + κ`. The mass and
//! the first moment are flown as fitted.
//!
//! `d̄` is the mean of `d_x` and `d_y`, as the diagnosis reports the wind. The wind is
//! horizontal (the diagnosis fits no vertical wind). The motor lag's start-of-log columns
//! (`start_…`) are transients of the log, not physics: they are not flown.
//!
//! Skipped, with a reason ([`SkippedEffect`]): the accelerometer bias (`accel-bias`), a sensor
//! error, not a force on the vehicle. Refused ([`ModelPlantError::NotFlyable`]): a custom
//! effect (`spec`): its columns are log signals, not a law of the state the plant can evaluate.
//! Fly a user's effect through `tagk_sim::PlantEffect` instead.

use std::sync::Arc;

use tagk_diagnose::{ACCEL_BIAS, ModelEffect, ModelFile};
use tagk_dynamics::EffectKind;
use tagk_sim::plant_effects::{EffectState, GroundEffect, QuadraticDrag};
use tagk_sim::plant_model::PlantModel;
use tagk_sim::{PlantEffect, SimConfig, SimError};

/// Why a model file cannot be flown.
#[derive(Debug, thiserror::Error)]
pub enum ModelPlantError {
    /// The model file has no `[vehicle]`: the plant needs its rotors.
    #[error(
        "the model file has no [vehicle]: the simulator needs its rotors (run `tagk diagnose` with --vehicle NAME|FILE)"
    )]
    NoVehicle,
    /// An effect the simulator cannot fly.
    #[error("effect `{effect}` cannot be flown: {reason}")]
    NotFlyable {
        /// The effect's name in the model file.
        effect: String,
        /// Why.
        reason: &'static str,
    },
    /// An effect without a number the plant needs.
    #[error("effect `{effect}` has no `{name}` in the model file")]
    Missing {
        /// The effect's name.
        effect: String,
        /// The coefficient or scanned parameter missing.
        name: &'static str,
    },
    /// The simulator refused the vehicle, the parameters or a coefficient.
    #[error("{0}")]
    Sim(#[from] SimError),
}

/// An effect of the model file that is not flown, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkippedEffect {
    /// The effect's name.
    pub effect: String,
    /// Why it is not flown.
    pub reason: &'static str,
}

/// The ground effect with a fitted gain: the rotors' thrust factor `1 + c_ge (T_IGE/T_OGE − 1)`.
///
/// `T_IGE/T_OGE` is the plant's Cheeseman–Bennett ratio ([`GroundEffect::thrust_ratio`]) at
/// the body origin's height \[m\]. The diagnosis fits the gain `c_ge` (dimensionless) on that
/// law's excess thrust, so `c_ge = 1` is the plant's own ground effect.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundEffectGain {
    /// The law, with its rotor radius \[m\].
    pub law: GroundEffect,
    /// The gain `c_ge` on the excess thrust \[1\].
    pub gain: f64,
}

impl PlantEffect for GroundEffectGain {
    fn name(&self) -> &str {
        EffectKind::GroundEffect.name()
    }
    /// No wrench of its own: it scales the rotors.
    fn wrench(&self, _s: &EffectState<'_>) -> tagk_dynamics::Wrench {
        tagk_dynamics::Wrench::zero()
    }
    /// `1 + c_ge (T_IGE/T_OGE − 1)` at the body origin's height.
    fn thrust_factor(&self, s: &EffectState<'_>) -> f64 {
        1.0 + self.gain * (self.law.thrust_ratio(s.position.z) - 1.0)
    }
}

/// A model file as a plant: the built-ins, the effects flown as [`PlantEffect`]s and those
/// skipped.
#[derive(Debug, Clone)]
pub struct ModelPlant {
    /// The vehicle, the inertial parameters and the built-in effects.
    pub plant: PlantModel,
    /// Effects flown through [`PlantEffect`] (the ground effect with its gain).
    pub extra: Vec<Arc<dyn PlantEffect>>,
    /// Effects of the file not flown.
    pub skipped: Vec<SkippedEffect>,
}

impl ModelPlant {
    /// `config` flying this model: its vehicle and effects replace the configuration's.
    #[must_use]
    pub fn configure(&self, config: SimConfig) -> SimConfig {
        let mut config = self.plant.configure(config);
        config.user_effects.0.extend(self.extra.iter().cloned());
        config
    }
}

/// The coefficient `name` of `effect`, required.
fn coef(effect: &ModelEffect, name: &'static str) -> Result<f64, ModelPlantError> {
    effect
        .coefficient(name)
        .ok_or_else(|| ModelPlantError::Missing {
            effect: effect.name.clone(),
            name,
        })
}

/// The scanned parameter `name` of `effect`, required.
fn scanned(effect: &ModelEffect, name: &'static str) -> Result<f64, ModelPlantError> {
    match &effect.scanned {
        Some(s) if s.name == name => Ok(s.value),
        _ => Err(ModelPlantError::Missing {
            effect: effect.name.clone(),
            name,
        }),
    }
}

/// The plant of the model file `model`: its vehicle, its inertial parameters and its effects
/// with their fitted coefficients (the module's table).
///
/// # Errors
/// [`ModelPlantError::NoVehicle`]; [`ModelPlantError::NotFlyable`] for a custom effect;
/// [`ModelPlantError::Missing`] for an effect without a coefficient it needs;
/// [`ModelPlantError::Sim`] for a vehicle, parameters or coefficients the simulator refuses.
pub fn model_plant(model: &ModelFile) -> Result<ModelPlant, ModelPlantError> {
    let vehicle = model.vehicle.as_ref().ok_or(ModelPlantError::NoVehicle)?;
    let mut builtins: Vec<(EffectKind, Vec<f64>)> = Vec::new();
    let mut extra: Vec<Arc<dyn PlantEffect>> = Vec::new();
    let mut skipped = Vec::new();
    // The thrust gain's factor on the inertia (see the module's documentation).
    let mut inertia_scale = 1.0;
    // The rotor inertia, scaled with the body's inertia once the thrust gain is known.
    let mut rotor_inertia = None;
    for effect in &model.effects {
        if effect.spec.is_some() {
            return Err(ModelPlantError::NotFlyable {
                effect: effect.name.clone(),
                reason: "a custom effect's columns are log signals, not a law of the state; fly it as a tagk_sim::PlantEffect",
            });
        }
        let wanted = effect.name.trim().to_ascii_lowercase().replace('_', "-");
        if wanted == ACCEL_BIAS || wanted == "accelerometer-bias" {
            skipped.push(SkippedEffect {
                effect: effect.name.clone(),
                reason: "a sensor error (accelerometer offset), not a force on the vehicle",
            });
            continue;
        }
        let kind =
            EffectKind::from_name(&effect.name).ok_or_else(|| ModelPlantError::NotFlyable {
                effect: effect.name.clone(),
                reason: "not an effect of the vocabulary (docs/CONVENTIONS.md §7)",
            })?;
        let c = |name| coef(effect, name);
        match kind {
            EffectKind::LinearDrag => {
                builtins.push((kind, vec![c("d_x")?, c("d_y")?, c("d_z")?]));
            }
            EffectKind::QuadraticDrag => {
                let rho = QuadraticDrag::crazyflie().air_density;
                let cd_area = |v: f64| 2.0 * v / rho;
                builtins.push((
                    kind,
                    vec![
                        cd_area(c("c_x")?),
                        cd_area(c("c_y")?),
                        cd_area(c("c_z")?),
                        rho,
                    ],
                ));
            }
            EffectKind::RotorDrag => {
                let (kh, kz) = (c("k_h")?, c("k_z")?);
                builtins.push((kind, vec![kh, kh, kz]));
            }
            EffectKind::BodyBias => builtins.push((
                kind,
                vec![0.0, 0.0, 0.0, c("bias_tx")?, c("bias_ty")?, c("bias_tz")?],
            )),
            EffectKind::ThrustGain => {
                let kappa = c("kappa")?;
                inertia_scale = 1.0 + kappa;
                builtins.push((kind, vec![kappa]));
            }
            EffectKind::GroundEffect => extra.push(Arc::new(GroundEffectGain {
                law: GroundEffect::crazyflie(),
                gain: c("c_ge")?,
            })),
            EffectKind::MotorLag => builtins.push((kind, vec![scanned(effect, "tau")?])),
            EffectKind::RotorInertia => rotor_inertia = Some(c("J_r")?),
            // The diagnosis's delay is positive for an early actuator log; the plant's delays
            // (makes late) the logged wrench.
            EffectKind::TimeDelay => builtins.push((kind, vec![-scanned(effect, "delay")?])),
            EffectKind::Wind => {
                if effect.coefficient("kv_wx").is_some() {
                    // The rotor drag (at the hubs, or scaled by Σ|ω_i|) and `K v_w`.
                    let kz = c("k_z")?;
                    let (drag, kxy) = match effect.coefficient("k_h") {
                        Some(kh) => (vec![kh, kh, kz], kh),
                        None => {
                            let (kx, ky) = (c("k_x")?, c("k_y")?);
                            (vec![kx, ky, kz], 0.5 * (kx + ky))
                        }
                    };
                    builtins.push((EffectKind::RotorDrag, drag));
                    builtins.push((kind, vec![c("kv_wx")? / kxy, c("kv_wy")? / kxy, 0.0]));
                } else {
                    let d = [c("d_x")?, c("d_y")?, c("d_z")?];
                    let mean = 0.5 * (d[0] + d[1]);
                    builtins.push((EffectKind::LinearDrag, d.to_vec()));
                    builtins.push((kind, vec![c("F_wx")? / mean, c("F_wy")? / mean, 0.0]));
                }
            }
            EffectKind::RotorInflow => builtins.push((kind, vec![c("k_in")?])),
            // The contrasts; their common part is the thrust gain's (or the mass's).
            EffectKind::RotorImbalance => {
                let d = [c("d_eps1")?, c("d_eps2")?, c("d_eps3")?];
                builtins.push((kind, vec![d[0], d[1], d[2], -(d[0] + d[1] + d[2])]));
            }
            // The diagnosis's reference voltage is the plant's default; the battery's
            // discharge and sag are the Crazyflie's (not identified).
            EffectKind::BatteryVoltage => builtins.push((
                kind,
                vec![c("beta")?, tagk_dynamics::BATTERY_REFERENCE_VOLTAGE],
            )),
            _ => {
                return Err(ModelPlantError::NotFlyable {
                    effect: effect.name.clone(),
                    reason: "the simulator has no plant term for it",
                });
            }
        }
    }
    if let Some(j) = rotor_inertia {
        builtins.push((EffectKind::RotorInertia, vec![j * inertia_scale]));
    }
    let mut theta: [f64; 10] = model.inertial.theta().to_array();
    for i in &mut theta[4..] {
        *i *= inertia_scale;
    }
    let plant = PlantModel::new(vehicle, &theta, &builtins)?;
    Ok(ModelPlant {
        plant,
        extra,
        skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tagk_diagnose::model_file::{ModelCoefficient, ScannedParameter};
    use tagk_dynamics::QuadrotorModel;
    use tagk_dynamics::vehicle::Vehicle;

    fn coefficient(name: &str, value: f64) -> ModelCoefficient {
        ModelCoefficient {
            name: name.into(),
            unit: String::new(),
            value,
            std_error: None,
            interval: None,
        }
    }

    fn effect(name: &str, coefficients: &[(&str, f64)]) -> ModelEffect {
        ModelEffect {
            name: name.into(),
            spec: None,
            scanned: None,
            coefficients: coefficients
                .iter()
                .map(|(n, v)| coefficient(n, *v))
                .collect(),
        }
    }

    fn model(effects: Vec<ModelEffect>) -> ModelFile {
        let mut file = ModelFile::rigid_body(QuadrotorModel::crazyflie_2_1().params.to_array());
        file.vehicle = Some(Vehicle::crazyflie_2_1());
        file.effects = effects;
        file
    }

    #[test]
    fn coefficients_map_to_the_plant() {
        let mut lag = effect("motor-lag", &[("g_lag", 1.0), ("start_w1", 3.0)]);
        lag.scanned = Some(ScannedParameter {
            name: "tau".into(),
            unit: "s".into(),
            value: 0.03,
            interval: None,
        });
        let file = model(vec![
            effect(
                "quadratic-drag",
                &[("c_x", 0.01), ("c_y", 0.02), ("c_z", 0.03)],
            ),
            effect(
                "body-bias",
                &[("bias_tx", 1e-5), ("bias_ty", 2e-5), ("bias_tz", 3e-5)],
            ),
            effect("thrust-gain", &[("kappa@1", -0.1), ("kappa@2", -0.2)]),
            effect(
                "wind",
                &[
                    ("k_h", 2e-7),
                    ("k_z", 3e-7),
                    ("kv_wx", 1e-7),
                    ("kv_wy", -4e-8),
                ],
            ),
            effect("accel-bias", &[("b_x", 0.1)]),
            lag,
        ]);
        let plant = model_plant(&file).unwrap();
        let e = plant.plant.effects;
        // ½ ρ C_d A = c, independently: C_d A = c / (½ · 1.225).
        let q = e.quadratic_drag.unwrap();
        for (k, c) in [0.01, 0.02, 0.03].into_iter().enumerate() {
            assert!((0.5 * q.air_density * q.cd_area[k] - c).abs() < 1e-15);
            assert!((q.cd_area[k] - c / 0.6125).abs() < 1e-15);
        }
        let b = e.body_bias.unwrap();
        assert_eq!((b.force, b.torque), ([0.0; 3], [1e-5, 2e-5, 3e-5]));
        // The mean over the logs of a joint fit.
        assert!((e.thrust_gain.unwrap().relative_error + 0.15).abs() < 1e-15);
        // The inertia times 1 + κ, the mass as fitted.
        let nominal = QuadrotorModel::crazyflie_2_1().params.to_array();
        let flown = plant.plant.vehicle.params.to_array();
        assert_eq!(flown[0], nominal[0]);
        for k in 4..10 {
            assert!((flown[k] - 0.85 * nominal[k]).abs() < 1e-15 * nominal[k].abs());
        }
        assert_eq!(e.rotor_drag.unwrap().coefficients, [2e-7, 2e-7, 3e-7]);
        assert_eq!(e.wind.unwrap().velocity, [0.5, -0.2, 0.0]);
        assert_eq!(e.motor_lag.unwrap().time_constant, 0.03);
        assert_eq!(plant.skipped.len(), 1);
        assert_eq!(plant.skipped[0].effect, "accel-bias");
    }

    #[test]
    fn ground_effect_gain_scales_the_excess_thrust() {
        let file = model(vec![effect("ground-effect", &[("c_ge", 2.0)])]);
        let plant = model_plant(&file).unwrap();
        assert_eq!(plant.extra.len(), 1);
        let law = GroundEffect::crazyflie();
        let gain = GroundEffectGain { law, gain: 2.0 };
        // At z = R: (R/4R)² = 1/16, so the excess is 1/15 and the factor 1 + 2/15.
        let r = law.rotor_radius;
        let excess = 1.0 / (1.0 - (r / (4.0 * r)).powi(2)) - 1.0;
        assert!((excess - 1.0 / 15.0).abs() < 1e-15);
        assert!((1.0 + gain.gain * (law.thrust_ratio(r) - 1.0) - (1.0 + 2.0 / 15.0)).abs() < 1e-15);
    }

    #[test]
    fn what_cannot_be_flown_is_named() {
        let mut custom = effect("tether", &[("k", 0.05)]);
        custom.spec = Some("tether=pz@fz".into());
        let err = model_plant(&model(vec![custom])).unwrap_err();
        assert!(matches!(&err, ModelPlantError::NotFlyable { effect, .. } if effect == "tether"));
        let err = model_plant(&model(vec![effect("linear-drag", &[("d_x", 0.01)])])).unwrap_err();
        assert!(
            matches!(err, ModelPlantError::Missing { name: "d_y", .. }),
            "{err}"
        );
        let mut file = model(Vec::new());
        file.vehicle = None;
        assert!(matches!(
            model_plant(&file),
            Err(ModelPlantError::NoVehicle)
        ));
        let err = model_plant(&model(vec![effect("motor-lag", &[])])).unwrap_err();
        assert!(
            matches!(err, ModelPlantError::Missing { name: "tau", .. }),
            "{err}"
        );
    }
}
