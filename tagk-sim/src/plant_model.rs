//! A plant from a model's numbers: the library side of flying an identified model.
//!
//! [`PlantModel::new`] takes a [`Vehicle`] (the vehicle file of docs/VEHICLE.md), the inertial
//! parameters in the project's parameter order (docs/CONVENTIONS.md §1) and built-in effects
//! by their vocabulary names with coefficients. It checks them and gives the simulator's
//! vehicle and effects; [`PlantModel::configure`] puts them into a [`SimConfig`]. A model file
//! reader (`tagk simulate --model`) then only has to fill these arguments.
//!
//! ```
//! use tagk_dynamics::vehicle::Vehicle;
//! use tagk_dynamics::{EffectKind, QuadrotorModel};
//! use tagk_sim::plant_model::PlantModel;
//! use tagk_sim::SimConfig;
//!
//! let theta = QuadrotorModel::crazyflie_2_1().params.to_array();
//! let drag = (EffectKind::LinearDrag, vec![0.02, 0.02, 0.03]);
//! let model = PlantModel::new(&Vehicle::crazyflie_2_1(), &theta, &[drag])?;
//! let config = model.configure(SimConfig::default());
//! assert_eq!(config.effects.linear_drag.unwrap().coefficients, [0.02, 0.02, 0.03]);
//! # Ok::<(), tagk_sim::SimError>(())
//! ```

use tagk_dynamics::vehicle::Vehicle;
use tagk_dynamics::{EffectKind, InertialParams, QuadrotorModel};

use crate::{PlantEffects, SimConfig, SimError};

/// The simulator's vehicle and effects of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantModel {
    /// The vehicle, with the model's inertial parameters as its true (and nominal) ones.
    pub vehicle: QuadrotorModel,
    /// The built-in effects at the model's coefficients.
    pub effects: PlantEffects,
}

impl PlantModel {
    /// The plant of `vehicle` with inertial parameters `params` (parameter order: `m`,
    /// `m c_x`, `m c_y`, `m c_z` \[kg, kg m\], `I_xx`, `I_xy`, `I_yy`, `I_xz`, `I_yz`, `I_zz`
    /// about the origin \[kg m²\]) and `effects`: each a vocabulary name and its coefficients
    /// ([`PlantEffects::with_coefficients`]; none for the Crazyflie default).
    ///
    /// The vehicle file's `mass` and `inertia` need not be given: `params` replaces them.
    ///
    /// # Errors
    /// [`SimError::NotFlyable`] for a vehicle the simulator cannot fly;
    /// [`SimError::NonPositiveMass`], [`SimError::Dynamics`] for parameters without forward
    /// dynamics; the errors of [`PlantEffects::with_coefficients`].
    pub fn new(
        vehicle: &Vehicle,
        params: &[f64; 10],
        effects: &[(EffectKind, Vec<f64>)],
    ) -> Result<Self, SimError> {
        let params = InertialParams::from_array(*params);
        crate::plant::validate_params(&params)?;
        // The priors are not needed: the model's parameters replace them.
        let mut described = vehicle.clone();
        let theta = params.to_array();
        described.mass = Some(theta[0]);
        described.inertia = Some([theta[4], theta[5], theta[6], theta[7], theta[8], theta[9]]);
        let vehicle = QuadrotorModel::from_vehicle(&described)?.with_params(params);
        let effects = effects
            .iter()
            .try_fold(PlantEffects::none(), |e, (kind, c)| {
                e.with_coefficients(*kind, c)
            })?;
        Ok(Self { vehicle, effects })
    }

    /// `config` flying this plant: its vehicle and effects replace the configuration's.
    #[must_use]
    pub fn configure(&self, config: SimConfig) -> SimConfig {
        SimConfig {
            vehicle: self.vehicle,
            effects: self.effects,
            ..config
        }
    }
}
