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
//! error, not a force on the vehicle. A drag-like coefficient (a drag, the inflow, the rotor
//! inertia) below 0 within its noise is flown as 0 and named there too. One significantly below
//! 0 is refused ([`ModelPlantError::NegativeDrag`]): it would feed the motion energy. Refused ([`ModelPlantError::NotFlyable`]): a custom
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
    /// A drag-like coefficient significantly negative: it would feed the motion energy.
    #[error(
        "effect `{effect}`: {name} = {value:.3e} is significantly below 0 (95 % interval [{lo:.3e}, {hi:.3e}]): a drag cannot push along the motion; refit without the effect or with another drag law"
    )]
    NegativeDrag {
        /// The effect's name.
        effect: String,
        /// The coefficient's name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Its 95 % interval's lower end.
        lo: f64,
        /// Its 95 % interval's upper end.
        hi: f64,
    },
    /// The simulator refused the vehicle, the parameters or a coefficient.
    #[error("{0}")]
    Sim(#[from] SimError),
}

/// An effect of the model file that is not flown, or a coefficient of it flown as 0, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SkippedEffect {
    /// The effect's name, with the coefficient's for a coefficient flown as 0 (`linear-drag d_z`).
    pub effect: String,
    /// Why it is not flown.
    pub reason: String,
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

/// The drag-like coefficient `name` of `effect` (a drag, an inflow, a rotor inertia: physically
/// `≥ 0`), required. A negative value whose 95 % interval reaches 0 is noise about a small
/// drag: it is flown as 0, and `zeroed` says so. A value significantly below 0 is refused.
fn drag_coef(
    effect: &ModelEffect,
    name: &'static str,
    zeroed: &mut Vec<SkippedEffect>,
) -> Result<f64, ModelPlantError> {
    let value = coef(effect, name)?;
    if value >= 0.0 {
        return Ok(value);
    }
    let found = effect.coefficients.iter().find(|c| c.name == name);
    let interval = found.and_then(|c| {
        c.interval
            .or_else(|| c.std_error.map(|se| [value - 1.96 * se, value + 1.96 * se]))
    });
    match interval {
        Some([lo, hi]) if hi < 0.0 => Err(ModelPlantError::NegativeDrag {
            effect: effect.name.clone(),
            name,
            value,
            lo,
            hi,
        }),
        _ => {
            zeroed.push(SkippedEffect {
                effect: format!("{} {name}", effect.name),
                reason: format!(
                    "{value:.3e} is below 0 within its noise: a drag cannot push along the motion; flown as 0"
                ),
            });
            Ok(0.0)
        }
    }
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
                reason: "a sensor error (accelerometer offset), not a force on the vehicle".into(),
            });
            continue;
        }
        let kind =
            EffectKind::from_name(&effect.name).ok_or_else(|| ModelPlantError::NotFlyable {
                effect: effect.name.clone(),
                reason: "not an effect of the vocabulary (docs/CONVENTIONS.md §7)",
            })?;
        let c = |name| coef(effect, name);
        let mut d = |name| drag_coef(effect, name, &mut skipped);
        match kind {
            EffectKind::LinearDrag => {
                builtins.push((kind, vec![d("d_x")?, d("d_y")?, d("d_z")?]));
            }
            EffectKind::QuadraticDrag => {
                let rho = QuadraticDrag::crazyflie().air_density;
                let cd_area = |v: f64| 2.0 * v / rho;
                builtins.push((
                    kind,
                    vec![
                        cd_area(d("c_x")?),
                        cd_area(d("c_y")?),
                        cd_area(d("c_z")?),
                        rho,
                    ],
                ));
            }
            EffectKind::RotorDrag => {
                let (kh, kz) = (d("k_h")?, d("k_z")?);
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
            // The filter alone; the telemetry's delay is the model's `time-delay`.
            EffectKind::TelemetryLag => {
                builtins.push((kind, vec![scanned(effect, "tau_tel")?, 0.0]))
            }
            EffectKind::RotorInertia => rotor_inertia = Some(d("J_r")?),
            // The diagnosis's delay is positive for an early actuator log; the plant's delays
            // (makes late) the logged wrench.
            EffectKind::TimeDelay => builtins.push((kind, vec![-scanned(effect, "delay")?])),
            EffectKind::Wind => {
                if effect.coefficient("kv_wx").is_some() {
                    // The rotor drag (at the hubs, or scaled by Σ|ω_i|) and `K v_w`.
                    let kz = d("k_z")?;
                    let (drag, kxy) = match effect.coefficient("k_h") {
                        Some(_) => {
                            let kh = d("k_h")?;
                            (vec![kh, kh, kz], kh)
                        }
                        None => {
                            let (kx, ky) = (d("k_x")?, d("k_y")?);
                            (vec![kx, ky, kz], 0.5 * (kx + ky))
                        }
                    };
                    builtins.push((EffectKind::RotorDrag, drag));
                    builtins.push((kind, vec![c("kv_wx")? / kxy, c("kv_wy")? / kxy, 0.0]));
                } else {
                    let drag = [d("d_x")?, d("d_y")?, d("d_z")?];
                    let mean = 0.5 * (drag[0] + drag[1]);
                    builtins.push((EffectKind::LinearDrag, drag.to_vec()));
                    builtins.push((kind, vec![c("F_wx")? / mean, c("F_wy")? / mean, 0.0]));
                }
            }
            EffectKind::RotorInflow => builtins.push((kind, vec![d("k_in")?])),
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

    /// A negative drag within its noise is flown as 0 and named; one significantly below 0 is
    /// refused; without an interval a negative drag is taken as noise.
    #[test]
    fn a_negative_drag_is_flown_as_zero_within_its_noise_and_refused_beyond() {
        let mut drag = effect(
            "linear-drag",
            &[("d_x", 0.01), ("d_y", 0.01), ("d_z", -2e-3)],
        );
        drag.coefficients[2].std_error = Some(1.5e-3);
        let plant = model_plant(&model(vec![drag.clone()])).unwrap();
        let d = plant.plant.effects.linear_drag.unwrap().coefficients;
        assert_eq!(d, [0.01, 0.01, 0.0]);
        assert_eq!(plant.skipped.len(), 1);
        assert_eq!(plant.skipped[0].effect, "linear-drag d_z");
        assert!(plant.skipped[0].reason.contains("flown as 0"));
        drag.coefficients[2].std_error = Some(5e-4);
        let err = model_plant(&model(vec![drag.clone()])).unwrap_err();
        assert!(
            matches!(err, ModelPlantError::NegativeDrag { name: "d_z", .. }),
            "{err}"
        );
        assert!(err.to_string().contains("significantly below 0"), "{err}");
        // An interval, when given, decides.
        drag.coefficients[2].interval = Some([-3e-3, 1e-4]);
        assert!(model_plant(&model(vec![drag.clone()])).is_ok());
        drag.coefficients[2].std_error = None;
        drag.coefficients[2].interval = None;
        assert!(model_plant(&model(vec![drag])).is_ok());
        let inertia = effect("rotor-inertia", &[("J_r", -1e-9)]);
        let plant = model_plant(&model(vec![inertia])).unwrap();
        assert_eq!(plant.plant.effects.rotor_inertia.unwrap().inertia, 0.0);
    }
}
