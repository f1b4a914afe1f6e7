//! Quadrotor actuator model: rotor layout, thrust/torque coefficients and the mixer
//! (docs/CONVENTIONS.md §4).
//!
//! Rotor numbering follows the Crazyflie: M1 front-right `(+x, −y)`, M2 back-right
//! `(−x, −y)`, M3 back-left `(−x, +y)`, M4 front-left `(+x, +y)` (body frame: x forward,
//! y left, z up). M1 and M3 spin clockwise seen from above, M2 and M4 counter-clockwise;
//! a clockwise rotor's drag reaction turns the body counter-clockwise (`+z`), so
//! `spin_directions = [+1, −1, +1, −1]` are the signs of each rotor's reaction torque about
//! body `+z`.

use nalgebra::{Matrix4, Vector3, Vector4};
use thiserror::Error;

use crate::vehicle::{ReactionTorque, ThrustCurve, Vehicle, VehicleError};
use crate::{InertialParams, Wrench};

/// Crazyflie 2.1: offset of each motor axis from the body origin along body x and along body
/// y, the paper's `L_arm` \[m\] (motors at `(±L_arm, ±L_arm, 0)`). Also the safety gate's
/// largest centre-of-mass offset and the scale of first-moment errors.
pub const CRAZYFLIE_ARM_OFFSET: f64 = 0.0325;
/// Crazyflie 2.1: distance from the body origin to each motor axis, `√2 · L_arm` rounded
/// \[m\].
pub const CRAZYFLIE_MOTOR_DISTANCE: f64 = 0.046;
/// Crazyflie 2.1: mass without payload \[kg\].
pub const CRAZYFLIE_MASS: f64 = 0.035;
/// Crazyflie 2.1: inertia about the centre of mass (at the origin), the upper triangle
/// `[I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]` \[kg m²\].
pub const CRAZYFLIE_INERTIA: [f64; 6] = [1.66e-5, 0.83e-6, 1.66e-5, 0.72e-6, 1.8e-6, 2.93e-5];
/// Crazyflie 2.1: thrust coefficient `k_f` in `T = k_f ω²` \[N/(rad/s)²\].
pub const CRAZYFLIE_K_F: f64 = 2.3e-8;
/// Crazyflie 2.1: reaction-torque coefficient `k_m` in `Q = k_m ω²` \[N m/(rad/s)²\].
pub const CRAZYFLIE_K_M: f64 = 7.8e-10;
/// Crazyflie 2.1: largest rotor speed \[rad/s\].
pub const CRAZYFLIE_MAX_ROTOR_SPEED: f64 = 2500.0;
/// Propeller radius of the Crazyflie 2.x \[m\] (45 mm propellers), the `R` of ground effect.
pub const CRAZYFLIE_ROTOR_RADIUS: f64 = 0.0225;

/// Rigid-body and actuator parameters of a quadrotor with rotors thrusting along body `+z`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct QuadrotorModel {
    /// Inertial parameters of the vehicle about the body origin (docs/CONVENTIONS.md §1).
    pub params: InertialParams,
    /// Distance from the body origin to each motor axis \[m\].
    pub arm: f64,
    /// Rotor hub positions in the body frame \[m\].
    pub rotor_positions: [Vector3<f64>; 4],
    /// Sign of each rotor's reaction torque about body `+z` (`+1`: rotor spins clockwise seen
    /// from above).
    pub spin_directions: [f64; 4],
    /// Thrust coefficient `k_f` in `T = k_f ω²` \[N/(rad/s)²\].
    pub k_f: f64,
    /// Reaction-torque coefficient `k_m` in `Q = k_m ω²` \[N m/(rad/s)²\].
    pub k_m: f64,
    /// Largest rotor speed \[rad/s\].
    pub max_rotor_speed: f64,
}

impl QuadrotorModel {
    /// The nominal Crazyflie 2.1: the `CRAZYFLIE_*` constants of this module.
    ///
    /// It weighs 0.035 kg, with its centre of mass at the origin and the tabulated inertia.
    /// In X configuration, its motors sit at `(±0.0325, ±0.0325, 0)` m, 0.046 m from the
    /// centre. `k_f = 2.3e-8`, `k_m = 7.8e-10`, `ω_max = 2500 rad/s`.
    pub fn crazyflie_2_1() -> Self {
        let d = CRAZYFLIE_ARM_OFFSET;
        let [ixx, ixy, iyy, ixz, iyz, izz] = CRAZYFLIE_INERTIA;
        Self {
            params: InertialParams::from_array([
                CRAZYFLIE_MASS,
                0.0,
                0.0,
                0.0,
                ixx,
                ixy,
                iyy,
                ixz,
                iyz,
                izz,
            ]),
            arm: CRAZYFLIE_MOTOR_DISTANCE,
            rotor_positions: [
                Vector3::new(d, -d, 0.0),
                Vector3::new(-d, -d, 0.0),
                Vector3::new(-d, d, 0.0),
                Vector3::new(d, d, 0.0),
            ],
            spin_directions: [1.0, -1.0, 1.0, -1.0],
            k_f: CRAZYFLIE_K_F,
            k_m: CRAZYFLIE_K_M,
            max_rotor_speed: CRAZYFLIE_MAX_ROTOR_SPEED,
        }
    }

    /// Torque-to-thrust ratio `k_m / k_f` \[m\].
    pub fn torque_coefficient(&self) -> f64 {
        self.k_m / self.k_f
    }

    /// Largest thrust of one rotor, `k_f ω_max²` \[N\].
    pub fn max_thrust_per_rotor(&self) -> f64 {
        self.k_f * self.max_rotor_speed * self.max_rotor_speed
    }

    /// The actuator wrench (body frame, about the origin) of the four rotor thrusts \[N\]:
    /// force `(0, 0, ΣT_i)`, torque `Σ r_i × (0, 0, T_i) + (0, 0, Σ s_i (k_m/k_f) T_i)`.
    pub fn wrench_from_thrusts(&self, thrusts: &[f64; 4]) -> Wrench {
        let kappa = self.torque_coefficient();
        rotor_wrench(
            &self.rotor_positions,
            &self.spin_directions,
            thrusts,
            &thrusts.map(|t| kappa * t),
        )
    }

    /// The actuator wrench of four rotor speeds \[rad/s\] (`T_i = k_f ω_i²`).
    pub fn wrench_from_rotor_speeds(&self, speeds: &[f64; 4]) -> Wrench {
        self.wrench_from_thrusts(&speeds.map(|w| self.k_f * w * w))
    }

    /// The 4×4 mixer `M` with `[f_z, τ_x, τ_y, τ_z]ᵀ = M [T_1, T_2, T_3, T_4]ᵀ`:
    /// rows `1`, `y_i`, `−x_i`, `s_i k_m/k_f`.
    pub fn mixer_matrix(&self) -> Matrix4<f64> {
        let kappa = self.torque_coefficient();
        Matrix4::from_fn(|r, c| {
            let p = &self.rotor_positions[c];
            match r {
                0 => 1.0,
                1 => p.y,
                2 => -p.x,
                _ => self.spin_directions[c] * kappa,
            }
        })
    }

    /// Rotor thrusts \[N\] that produce total thrust `f_z` \[N\] and torque `torque` \[N m\]: the
    /// inverse mixer, not clipped to `[0, max_thrust_per_rotor]` (see
    /// [`clamp_thrusts`](Self::clamp_thrusts)). For a layout whose mixer is singular (not the
    /// case for any X or + configuration), the minimum-norm least-squares thrusts are returned.
    pub fn thrusts_from_wrench(&self, f_z: f64, torque: &Vector3<f64>) -> [f64; 4] {
        let m = self.mixer_matrix();
        let rhs = Vector4::new(f_z, torque.x, torque.y, torque.z);
        let t = match m.lu().solve(&rhs) {
            Some(t) if t.iter().all(|v| v.is_finite()) => t,
            _ => m
                .svd(true, true)
                .solve(&rhs, 1e-12 * m.amax())
                .unwrap_or_else(|_| Vector4::zeros()),
        };
        [t[0], t[1], t[2], t[3]]
    }

    /// Clips each thrust to `[0, max_thrust_per_rotor]` \[N\].
    pub fn clamp_thrusts(&self, thrusts: &[f64; 4]) -> [f64; 4] {
        let hi = self.max_thrust_per_rotor();
        thrusts.map(|t| t.clamp(0.0, hi))
    }

    /// Rotor speeds \[rad/s\] for thrusts \[N\], `ω = sqrt(T / k_f)`; a negative thrust (which a
    /// fixed-pitch rotor cannot make) maps to speed 0.
    pub fn rotor_speeds_from_thrusts(&self, thrusts: &[f64; 4]) -> [f64; 4] {
        thrusts.map(|t| (t.max(0.0) / self.k_f).sqrt())
    }
}

/// Why a [`Vehicle`] cannot be flown as a [`QuadrotorModel`] (the simulator's vehicle).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum NotFlyable {
    /// The vehicle description itself is invalid ([`Vehicle::validate`]).
    #[error(transparent)]
    Invalid(#[from] VehicleError),
    /// The thrust curve is not `T = k_f ω²`: the simulator's rotors are quadratic.
    #[error(
        "vehicle `{vehicle}`: the simulator flies quadratic rotors T = k_f w^2 only (key `k_f`), not thrust_curve = {coefficients:?}"
    )]
    NonQuadraticThrust {
        /// The vehicle's name.
        vehicle: String,
        /// The thrust curve's coefficients, constant term first.
        coefficients: Vec<f64>,
    },
    /// A prior the simulator needs as the true value is missing.
    #[error(
        "vehicle `{vehicle}`: the simulator needs the key `{key}` (the {what} of the vehicle it flies)"
    )]
    MissingKey {
        /// The vehicle's name.
        vehicle: String,
        /// The missing key (`mass` or `inertia`).
        key: &'static str,
        /// What it is.
        what: &'static str,
    },
}

impl QuadrotorModel {
    /// The simulator's vehicle of a [`Vehicle`] description.
    ///
    /// - Rotor hubs and spin directions, `max_rotor_speed`: as given.
    /// - `k_f`: the file's `k_f`, or a `thrust_curve` whose only non-zero term is `c₂ ω²`.
    /// - `k_m`: the file's `k_m`, or `torque_ratio · k_f` \[N m/(rad/s)²\].
    /// - Inertial parameters: mass \[kg\] and inertia about the origin \[kg m²\] from the
    ///   `mass` and `inertia` keys, centre of mass at the origin ([`Vehicle::inertial_prior`]).
    /// - `arm`: the largest horizontal distance of a hub from the origin \[m\].
    ///
    /// [`Vehicle::from_quadrotor`] goes the other way. The round trip keeps every field but
    /// `arm`, which is computed here (the Crazyflie's `CRAZYFLIE_MOTOR_DISTANCE` is rounded).
    ///
    /// # Errors
    /// [`NotFlyable::Invalid`] for an invalid description;
    /// [`NotFlyable::NonQuadraticThrust`] for a thrust curve the simulator cannot fly;
    /// [`NotFlyable::MissingKey`] without `mass` or `inertia`.
    pub fn from_vehicle(vehicle: &Vehicle) -> Result<Self, NotFlyable> {
        vehicle.validate()?;
        let k_f = match &vehicle.thrust {
            ThrustCurve::Quadratic { k_f } => *k_f,
            ThrustCurve::Polynomial { coefficients } => {
                let quadratic_only = coefficients.len() >= 3
                    && coefficients
                        .iter()
                        .enumerate()
                        .all(|(k, c)| k == 2 || *c == 0.0);
                if !quadratic_only {
                    return Err(NotFlyable::NonQuadraticThrust {
                        vehicle: vehicle.name.clone(),
                        coefficients: coefficients.clone(),
                    });
                }
                coefficients[2]
            }
        };
        let k_m = match vehicle.reaction_torque {
            ReactionTorque::Coefficient { k_m } => k_m,
            ReactionTorque::Ratio { ratio } => ratio * k_f,
        };
        let missing = |key, what| NotFlyable::MissingKey {
            vehicle: vehicle.name.clone(),
            key,
            what,
        };
        if vehicle.mass.is_none() {
            return Err(missing("mass", "mass"));
        }
        let params = vehicle
            .inertial_prior()
            .ok_or_else(|| missing("inertia", "inertia about the origin"))?;
        let rotor_positions = vehicle.rotors.map(|r| r.position);
        let arm = rotor_positions
            .iter()
            .map(|p| p.x.hypot(p.y))
            .fold(0.0, f64::max);
        Ok(Self {
            params,
            arm,
            rotor_positions,
            spin_directions: vehicle.rotors.map(|r| r.spin.sign()),
            k_f,
            k_m,
            max_rotor_speed: vehicle.max_rotor_speed,
        })
    }

    /// This vehicle with the true inertial parameters `params` (e.g. a fitted model's).
    #[must_use]
    pub fn with_params(mut self, params: InertialParams) -> Self {
        self.params = params;
        self
    }
}

impl TryFrom<&Vehicle> for QuadrotorModel {
    type Error = NotFlyable;

    /// [`QuadrotorModel::from_vehicle`].
    fn try_from(vehicle: &Vehicle) -> Result<Self, NotFlyable> {
        Self::from_vehicle(vehicle)
    }
}

/// The body wrench (body frame, about the origin) of four rotors thrusting along body `+z`.
/// The force is `(0, 0, ΣT_i)` \[N\]. The torque is `Σ r_i × (0, 0, T_i) + (0, 0, Σ s_i Q_i)`
/// \[N m\]. Here `r_i` are the hub positions \[m\], `s_i` the spin directions (the sign of each
/// reaction torque about body `+z`), `T_i` the thrusts \[N\] and `Q_i ≥ 0` the magnitudes of
/// the rotors' reaction torques \[N m\]. This is the one formula behind
/// [`QuadrotorModel::wrench_from_thrusts`] and
/// [`Vehicle::wrench_from_rotor_speeds`](crate::vehicle::Vehicle::wrench_from_rotor_speeds).
pub fn rotor_wrench(
    rotor_positions: &[Vector3<f64>; 4],
    spin_directions: &[f64; 4],
    thrusts: &[f64; 4],
    reaction_torques: &[f64; 4],
) -> Wrench {
    let mut force = Vector3::zeros();
    let mut torque = Vector3::zeros();
    for (((t, q), r), s) in thrusts
        .iter()
        .zip(reaction_torques)
        .zip(rotor_positions)
        .zip(spin_directions)
    {
        let f = Vector3::new(0.0, 0.0, *t);
        force += f;
        torque += r.cross(&f);
        torque.z += s * q;
    }
    Wrench { force, torque }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Crazyflie preset flies as the simulator's Crazyflie: every field equal, `arm` the
    /// exact hub distance `√2 · L_arm` (the constant is rounded to 0.046 m).
    #[test]
    fn the_crazyflie_preset_is_the_simulators_crazyflie() {
        let q = QuadrotorModel::from_vehicle(&Vehicle::crazyflie_2_1()).unwrap();
        let cf = QuadrotorModel::crazyflie_2_1();
        assert_eq!(
            q.with_params(cf.params),
            QuadrotorModel { arm: q.arm, ..cf }
        );
        assert_eq!(q.params, cf.params);
        assert!((q.arm - 2f64.sqrt() * CRAZYFLIE_ARM_OFFSET).abs() < 1e-15);
        assert!((q.arm - CRAZYFLIE_MOTOR_DISTANCE).abs() < 1e-4);
    }

    #[test]
    fn torque_ratio_and_a_quadratic_only_curve_are_flown_others_are_refused() {
        let mut v = Vehicle::crazyflie_2_1();
        v.reaction_torque = ReactionTorque::Ratio { ratio: 0.02 };
        v.thrust = ThrustCurve::Polynomial {
            coefficients: vec![0.0, 0.0, 3e-8],
        };
        let q = QuadrotorModel::try_from(&v).unwrap();
        assert_eq!((q.k_f, q.k_m), (3e-8, 0.02 * 3e-8));

        v.thrust = ThrustCurve::Polynomial {
            coefficients: vec![0.01, 0.0, 3e-8],
        };
        assert!(matches!(
            QuadrotorModel::try_from(&v),
            Err(NotFlyable::NonQuadraticThrust { .. })
        ));
        let mut v = Vehicle::crazyflie_2_1();
        v.inertia = None;
        assert!(matches!(
            QuadrotorModel::try_from(&v),
            Err(NotFlyable::MissingKey { key: "inertia", .. })
        ));
        v.mass = None;
        assert!(matches!(
            QuadrotorModel::try_from(&v),
            Err(NotFlyable::MissingKey { key: "mass", .. })
        ));
        let mut v = Vehicle::crazyflie_2_1();
        v.max_rotor_speed = -1.0;
        assert!(matches!(
            QuadrotorModel::try_from(&v),
            Err(NotFlyable::Invalid(_))
        ));
    }
}
