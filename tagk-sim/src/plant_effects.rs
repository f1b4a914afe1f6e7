//! Optional plant effects: the physics a real Crazyflie has and the paper's ideal model
//! leaves out. Each effect is a switch (`Option`) in [`PlantEffects`]; all are off by default
//! (the TAG-K paper's experiments), and every effect's `crazyflie()` constructor (also its
//! `Default`) gives a realistic magnitude for a Crazyflie 2.x with its source.
//!
//! The effects are named by the shared vocabulary [`tagk_dynamics::EffectKind`] (the names
//! `tagk simulate --effect` and `tagk diagnose --with` accept). The parameter structs of this
//! module are reached through the module path only (`tagk_sim::plant_effects::RotorDrag`), not
//! from the crate root: the diagnosis has model candidates of the same physics, and a plant
//! parameter set is not a model candidate.
//!
//! | [`EffectKind`] | plant parameters | [`PlantEffects`] field |
//! |---|---|---|
//! | `linear-drag` | [`LinearDrag`] | `linear_drag` |
//! | `quadratic-drag` | [`QuadraticDrag`] | `quadratic_drag` |
//! | `rotor-drag` | [`RotorDrag`] | `rotor_drag` |
//! | `motor-lag` | [`MotorLag`] | `motor_lag` |
//! | `ground-effect` | [`GroundEffect`] | `ground_effect` |
//! | `body-bias` | [`BodyBias`] | `body_bias` |
//! | `wind` | [`Wind`] | `wind` |
//! | `thrust-gain` | [`ThrustGain`] | `thrust_gain` |
//! | `time-delay` | [`TimeDelay`] (acts on the log, not on the physics) | `time_delay` |
//! | `rotor-inertia` | [`RotorInertia`] (rotor dynamics, applied by the plant) | `rotor_inertia` |
//! | `rotor-inflow` | [`RotorInflow`] | `rotor_inflow` |
//! | `rotor-imbalance` | [`RotorImbalance`] (per-rotor factors) | `rotor_imbalance` |
//! | `battery-voltage` | [`BatteryVoltage`] (thrust factor; logs `vbat`) | `battery_voltage` |
//!
//! # The extension point: [`PlantEffect`]
//!
//! A physical effect on the simulated vehicle is a type implementing [`PlantEffect`]. Given
//! the plant state ([`EffectState`]: time, position, velocity, attitude, body rate, rotor
//! speeds), it returns the wrench it adds (body frame, about the body origin,
//! docs/CONVENTIONS.md §1) and, optionally, a factor on every rotor's thrust. The built-in
//! wrench-like effects implement it: [`LinearDrag`], [`QuadraticDrag`], [`RotorDrag`],
//! [`BodyBias`], [`RotorInflow`] (additive wrenches), [`ThrustGain`] and [`GroundEffect`] (thrust factors).
//! [`PlantEffects::acting`] lists them in the order the plant applies them. A user's own effect
//! is flown with [`crate::Plant::with_effect`] or [`crate::SimConfig::with_plant_effect`].
//!
//! Three built-ins are not wrenches and stay outside the trait:
//! - [`MotorLag`] is rotor dynamics: it adds state (the four lagging rotor speeds) that the
//!   integrator carries, not a force.
//! - [`Wind`] is the air the drag effects move in: it changes their air-relative velocity
//!   ([`EffectState::air_velocity_body`]), and adds no wrench of its own.
//! - [`TimeDelay`] acts on the log (the sensing), not on the physics; so do the sensor errors
//!   of [`crate::Sensing`].
//! - [`RotorInertia`] needs the rotors' spin directions and accelerations, which an
//!   [`EffectState`] does not carry; the plant applies it itself ([`RotorInertia::torque`]).
//!
//! The effects act on the **plant only**. The measured wrench `b` the estimator sees is always
//! computed from the measured rotor speeds, with the nominal `k_f`, `k_m` through the mixer.
//! The measured speeds are the commanded ones plus the sensing profile's rotor-speed noise
//! ([`crate::Sensing`]). So every effect shows up as a model mismatch `b − Y θ ≠ 0` that a
//! diagnosis tool can look for.

use std::fmt::Debug;

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use tagk_dynamics::quadrotor::{CRAZYFLIE_K_F, CRAZYFLIE_MASS};
use tagk_dynamics::{EffectKind, Wrench};

use crate::SimError;

/// The plant state a [`PlantEffect`] sees, at one evaluation of the dynamics (every
/// Runge–Kutta stage).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectState<'a> {
    /// Time since the plant was built \[s\] (the sum of its step lengths, plus the stage's
    /// fraction of the current step).
    pub time: f64,
    /// Position of the body origin, world frame (z up) \[m\].
    pub position: Vector3<f64>,
    /// Velocity of the body origin, world frame \[m/s\].
    pub velocity: Vector3<f64>,
    /// Attitude, body → world (Hamilton, scalar first).
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity, body frame \[rad/s\].
    pub body_rate: Vector3<f64>,
    /// Air-relative velocity of the body origin, body frame, `Rᵀ (v − v_wind)` \[m/s\]
    /// (the velocity itself, rotated, without a [`Wind`]).
    pub air_velocity_body: Vector3<f64>,
    /// Actual rotor speeds \[rad/s\], in the order `w1..w4` (the lagging ones with a
    /// [`MotorLag`]).
    pub rotor_speeds: [f64; 4],
    /// Rotor hub positions, body frame \[m\].
    pub rotor_positions: &'a [Vector3<f64>; 4],
}

/// A physical effect acting on the simulated vehicle: the simulator's extension point.
///
/// At every evaluation of the dynamics the plant asks each effect for
/// - [`wrench`](PlantEffect::wrench): the wrench it adds, body frame, about the body origin
///   (force \[N\], torque \[N m\]), summed with the rotors' wrench;
/// - [`thrust_factor`](PlantEffect::thrust_factor): a factor on every rotor's thrust and
///   reaction torque (default 1).
///
/// The controller feels the effect; the logged wrench does not contain it. The log's wrench
/// is the rotors' nominal wrench from the read-back rotor speeds (docs/CONVENTIONS.md §6).
/// An effect must be a pure function of its state (no interior mutability): the integrator
/// evaluates it at the intermediate Runge–Kutta stages too. Hence the `RefUnwindSafe` bound:
/// a flight may be run under `catch_unwind`.
pub trait PlantEffect: Debug + Send + Sync + std::panic::RefUnwindSafe {
    /// A short name (the vocabulary's name for a built-in, e.g. `linear-drag`).
    fn name(&self) -> &str;

    /// The wrench this effect adds at state `s`: body frame, about the body origin; force
    /// \[N\], torque \[N m\].
    fn wrench(&self, s: &EffectState<'_>) -> Wrench;

    /// Factor on every rotor's thrust `k_f ω²` and reaction torque `k_m ω²` at state `s`
    /// (dimensionless; 1 when the effect does not act on the rotors).
    fn thrust_factor(&self, _s: &EffectState<'_>) -> f64 {
        1.0
    }

    /// Factor on each rotor's thrust and reaction torque at state `s`, in the order `w1..w4`
    /// (dimensionless; all 1 by default). It multiplies [`PlantEffect::thrust_factor`].
    fn rotor_factors(&self, _s: &EffectState<'_>) -> [f64; 4] {
        [1.0; 4]
    }
}

/// Linear rotor drag (blade flapping and induced drag) at each rotor hub.
///
/// Rotor `i` at hub `rᵢ` (body frame, the vehicle's rotor layout) spins at `ωᵢ`. It makes the
/// in-plane force `Hᵢ = −K ωᵢ v_hub,i`, with `v_hub,i = v_b + Ω × rᵢ` the air-relative velocity
/// of its hub, body frame \[m/s\]. Here `v_b = Rᵀ (v − v_wind)` is that of the body origin and
/// `Ω` the body rate \[rad/s\]. The moment about the origin is `rᵢ × Hᵢ`.
///
/// The net force is `Σ Hᵢ = −K (Σ ωᵢ) v_b − K Σ ωᵢ (Ω × rᵢ)`. To first order it is the
/// body-origin form `−K (Σ ωᵢ) v_b`: the second term vanishes at `Ω = 0`. The moments are what
/// the body-origin form leaves out. They are a yaw torque from differential rotor speeds times
/// the in-plane velocity, roll and pitch torques from the vertical component, and a damping of
/// the body rate. With equal rotor speeds, `Ω = 0` and a symmetric layout (`Σ rᵢ = 0`) the
/// moments cancel ([`RotorDrag::wrench`]).
///
/// Model and Crazyflie coefficients: J. Förster, "System identification of the Crazyflie 2.0
/// nano quadrocopter", ETH Zürich, 2015 (`K = diag(9.1785, 9.1785, 10.311)·10⁻⁷ kg/rad`,
/// identified per rotor); the per-rotor linear form is also the one of M. Faessler, A. Franchi,
/// D. Scaramuzza, "Differential flatness of quadrotor dynamics subject to rotor drag", IEEE
/// RA-L 2018. At the nominal 35 g vehicle's hover (`Σω ≈ 7.7·10³ rad/s`) the net force is
/// about `7.1·10⁻³ N s/m` horizontally ([`LinearDrag::crazyflie`]).
///
/// The vocabulary's `rotor-drag` (called `linear-drag` by the simulator before the shared
/// vocabulary).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RotorDrag {
    /// Diagonal of `K` [kg/rad] (body x, y, z).
    pub coefficients: [f64; 3],
}

impl RotorDrag {
    /// Förster (2015)'s identified Crazyflie 2.0 coefficients.
    pub fn crazyflie() -> Self {
        Self {
            coefficients: [9.1785e-7, 9.1785e-7, 10.311e-7],
        }
    }

    /// The drag wrench of the four rotors, body frame, about the origin: force `Σ Hᵢ` \[N\] and
    /// torque `Σ rᵢ × Hᵢ` \[N m\], with `Hᵢ = −K ωᵢ (v_air_b + Ω × rᵢ)`. The inputs are the
    /// air-relative body-frame velocity of the origin `v_air_b` \[m/s\], the body rate `body_rate`
    /// \[rad/s\], the actual rotor speeds `rotor_speeds` \[rad/s\] and the hub positions
    /// `rotor_positions` (body frame) \[m\].
    pub fn wrench(
        &self,
        v_air_b: &Vector3<f64>,
        body_rate: &Vector3<f64>,
        rotor_speeds: &[f64; 4],
        rotor_positions: &[Vector3<f64>; 4],
    ) -> Wrench {
        let k = Vector3::from(self.coefficients);
        let mut w = Wrench::zero();
        for (omega, r) in rotor_speeds.iter().zip(rotor_positions) {
            let v_hub = v_air_b + body_rate.cross(r);
            let h = -k.component_mul(&v_hub) * *omega;
            w.force += h;
            w.torque += r.cross(&h);
        }
        w
    }
}

impl Default for RotorDrag {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Body-frame drag linear in the air-relative velocity alone, `f_b = −D v_b` with
/// `D = diag(d_x, d_y, d_z)` [N s/m] and `v_b = Rᵀ (v − v_wind)` [m/s]: the usual
/// first-order aerodynamic model of a multirotor when rotor speeds are not logged.
///
/// Default ([`LinearDrag::crazyflie`]): [`RotorDrag::crazyflie`]'s coefficients (Förster 2015)
/// at the nominal Crazyflie's hover rotor-speed sum `Σω = 4 √(m g / (4 k_f))`
/// (`≈ 7.7·10³ rad/s` for 35 g and `k_f = 2.3·10⁻⁸`), i.e. rotor drag linearised at hover:
/// `D ≈ diag(7.1, 7.1, 8.0)·10⁻³ N s/m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearDrag {
    /// Diagonal of `D` [N s/m] (body x, y, z).
    pub coefficients: [f64; 3],
}

impl LinearDrag {
    /// Förster (2015)'s rotor drag at the nominal Crazyflie 2.1's hover.
    pub fn crazyflie() -> Self {
        let hover_speed_sum = 4.0 * (CRAZYFLIE_MASS * 9.81 / (4.0 * CRAZYFLIE_K_F)).sqrt();
        Self {
            coefficients: RotorDrag::crazyflie()
                .coefficients
                .map(|k| k * hover_speed_sum),
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
/// Standard form of pressure drag (S. F. Hoerner, "Fluid-Dynamic Drag", 1965). The Crazyflie
/// numbers take `C_d ≈ 1` for its frame, and a frontal area of about `3·10⁻³ m²` sideways and
/// `6·10⁻³ m²` from above (92 mm × 92 mm frame, mostly open). So it is small next to rotor
/// drag below 1 m/s, as Faessler et al. (2018) observe for quadrotors at low speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QuadraticDrag {
    /// `C_d A` per body axis \[m²\].
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
    /// Time constant `τ_m` \[s\].
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
    /// Rotor radius `R` \[m\].
    pub rotor_radius: f64,
}

impl GroundEffect {
    /// Crazyflie 2.x propellers: 45 mm diameter, `R = 0.0225 m`.
    pub fn crazyflie() -> Self {
        Self {
            rotor_radius: tagk_dynamics::quadrotor::CRAZYFLIE_ROTOR_RADIUS,
        }
    }

    /// Thrust multiplier at height `z` \[m\].
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
/// effects; if no drag effect ([`RotorDrag`], [`LinearDrag`], [`QuadraticDrag`]) is on, the
/// wind uses [`RotorDrag::crazyflie`] (without drag, air motion would exert no force).
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

/// Thrust gain (the vocabulary's `thrust-gain`): the true rotors make `(1 + ε) k_f ω²` (and
/// `(1 + ε) k_m ω²` of reaction torque) while the vehicle computes its wrench with the
/// nominal `k_f`, `k_m`. Default `ε = −0.1`: battery sag and propeller wear, which Förster
/// (2015) shows change the Crazyflie's thrust map by this order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ThrustGain {
    /// Relative error `ε` (dimensionless, `> −1`).
    pub relative_error: f64,
}

impl ThrustGain {
    /// `ε = −0.1`.
    pub fn crazyflie() -> Self {
        Self {
            relative_error: -0.1,
        }
    }
}

impl Default for ThrustGain {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Body bias (the vocabulary's `body-bias`): a constant body-frame force \[N\] and torque about
/// the origin [N m] not produced by the commanded rotors (an unmodelled cable, a bent arm or
/// unbalanced propeller). Default: 2 mN along body x and 3·10⁻⁵ N m about body x (about a
/// 1 % thrust imbalance of one rotor at hover times its lever `L_arm`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodyBias {
    /// Force, body frame \[N\].
    pub force: [f64; 3],
    /// Torque about the body origin, body frame [N m].
    pub torque: [f64; 3],
}

impl BodyBias {
    /// 2 mN along body x, 3·10⁻⁵ N m about body x.
    pub fn crazyflie() -> Self {
        Self {
            force: [2e-3, 0.0, 0.0],
            torque: [3e-5, 0.0, 0.0],
        }
    }
}

impl Default for BodyBias {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Time delay (the vocabulary's `time-delay`) between the wrench stream and the motion stream
/// of the flight log. The logged wrench and rotor speeds at time `t` are the ones commanded at
/// `t − delay`; commands are held over each control interval. The motion columns are those of
/// `t`. It models two log streams stamped with misaligned clocks. The vehicle itself (plant,
/// controller, onboard estimator) is not affected.
///
/// Default: one period of the simulator's 50 Hz control loop, 0.02 s — the smallest
/// misalignment a logger sampling at the control rate produces (a chosen magnitude, not a
/// measured Crazyflie value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimeDelay {
    /// Delay of the wrench stream behind the motion stream \[s\] (`≥ 0`).
    pub delay: f64,
}

impl TimeDelay {
    /// One 50 Hz control period, 0.02 s.
    pub fn crazyflie() -> Self {
        Self { delay: 0.02 }
    }
}

impl Default for TimeDelay {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Rotor-speed telemetry delay and filtering (the vocabulary's `telemetry-lag`): each rotor's
/// reported speed lags its read-back speed. It acts on the log only, as [`TimeDelay`] does: the
/// rotors, the controller and the plant are not affected.
///
/// The reported speed of rotor `i` at log sample `k` is the discrete first-order filter
/// `y_k = α y_{k−1} + (1 − α) x_{k−n}` with `α = e^{−Δt/τ_tel}` (`Δt` the control period),
/// started at `y = x_0`. Here `x_j` is the read-back speed of control interval `j` (before
/// noise) and `n = round(d/Δt)` whole periods of delay. It is a continuous first-order
/// filter of time constant `τ_tel` \[s\] of the held reading, sampled at each period's end.
/// The rotor-speed noise is added after it (the reading's own quantisation), and the logged
/// wrench is the nominal mixer of the reported speeds (docs/CONVENTIONS.md §7).
///
/// Default: `τ_tel` = 0.02 s, `d` = 0: one 50 Hz period, an ESC's eRPM averaged by the flight
/// controller (a chosen magnitude, not a measured Crazyflie value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TelemetryLag {
    /// Time constant `τ_tel` of the first-order filter \[s\] (`≥ 0`; 0: no filter).
    pub time_constant: f64,
    /// Delay `d` of the reported speeds \[s\] (`≥ 0`), applied in whole control periods.
    pub delay: f64,
}

impl TelemetryLag {
    /// `τ_tel` = 0.02 s, no delay.
    pub fn crazyflie() -> Self {
        Self {
            time_constant: 0.02,
            delay: 0.0,
        }
    }

    /// The filter's factor `α = e^{−Δt/τ_tel}` for a period `dt` \[s\] (0 without a filter).
    pub fn alpha(&self, dt: f64) -> f64 {
        if self.time_constant > 0.0 {
            (-dt / self.time_constant).exp()
        } else {
            0.0
        }
    }

    /// The delay in whole periods of `dt` \[s\].
    pub fn delay_periods(&self, dt: f64) -> usize {
        if dt > 0.0 {
            (self.delay / dt).round().max(0.0) as usize
        } else {
            0
        }
    }

    /// The reported speeds of a log of read-back speeds `x` (one per control interval of
    /// `dt` \[s\]): the filter of the type docs, run over the whole series.
    pub fn reported(&self, x: &[[f64; 4]], dt: f64) -> Vec<[f64; 4]> {
        let (alpha, n) = (self.alpha(dt), self.delay_periods(dt));
        let mut out = Vec::with_capacity(x.len());
        let mut y = x.first().copied().unwrap_or([0.0; 4]);
        for k in 0..x.len() {
            let input = x[k.saturating_sub(n)];
            for r in 0..4 {
                y[r] = alpha * y[r] + (1.0 - alpha) * input[r];
            }
            out.push(y);
        }
        out
    }
}

impl Default for TelemetryLag {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Rotor inertia (the vocabulary's `rotor-inertia`): each rotor with its motor bell has the
/// axial inertia `J_r` \[kg m²\] about its spin axis, body `+z`.
///
/// Rotor `i` turns at `ωᵢ ≥ 0` \[rad/s\]; its reaction-torque sign `sᵢ` (docs/CONVENTIONS.md §4)
/// means it spins about `−sᵢ e_z` (a clockwise rotor, `sᵢ = +1`, spins about `−z`). The rotors'
/// angular momentum, body frame, is `h_r = −J_r H e_z` with `H = Σ sᵢ ωᵢ` \[rad/s\]. The body's
/// Euler equation `d/dt(I Ω + h_r) + Ω × (I Ω + h_r) = τ` gives it the extra torque
/// `τ_r = −ḣ_r − Ω × h_r = J_r Ḣ e_z + J_r H (Ω × e_z)` ([`RotorInertia::torque`]). Speeding up a
/// rotor turns the body the way its drag reaction `sᵢ k_m ωᵢ²` does.
///
/// `Ḣ` is the plant's actual rotor acceleration: the [`MotorLag`]'s derivative. Without a motor
/// lag the rotor speeds jump to each new command; the plant then conserves the total angular
/// momentum across the jump. The body takes the impulsive torque `J_r ΔH e_z` (a change of its
/// angular and linear velocity through the spatial inertia, [`crate::Plant::step`]).
///
/// Default [`RotorInertia::crazyflie`]: `J_r = 2.5·10⁻⁸ kg m²`. It is an estimate from the parts,
/// not a measured value (no published measurement was found). A 45 mm propeller of about
/// 0.2 g, as a tapered blade, gives about `2·10⁻⁸`; the coreless motor's rotating cup (about
/// 0.5 g at 3 mm radius) about `0.5·10⁻⁸`. A realistic range is `1·10⁻⁸ … 6·10⁻⁸ kg m²`.
/// The four rotors hold well under 1 % of the Crazyflie's `I_zz = 2.93·10⁻⁵ kg m²`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RotorInertia {
    /// Axial inertia of one rotor with its motor bell `J_r` \[kg m²\] (physically `≥ 0`; any
    /// finite value is flown).
    pub inertia: f64,
}

impl RotorInertia {
    /// `J_r = 2.5·10⁻⁸ kg m²` (an estimate from the Crazyflie 2.x parts).
    pub fn crazyflie() -> Self {
        Self { inertia: 2.5e-8 }
    }

    /// The signed spin sum `H = Σ sᵢ ωᵢ` \[rad/s\] of rotor speeds `speeds` \[rad/s\] with
    /// reaction-torque signs `spins`.
    pub fn spin_sum(speeds: &[f64; 4], spins: &[f64; 4]) -> f64 {
        speeds.iter().zip(spins).map(|(w, s)| s * w).sum()
    }

    /// The torque the spinning rotors exert on the body, body frame \[N m\]:
    /// `J_r Ḣ e_z + J_r H (Ω × e_z)`. The inputs are the body rate `body_rate` \[rad/s\], the
    /// actual rotor speeds `speeds` \[rad/s\], their rates of change `accelerations`
    /// \[rad/s²\] and the reaction-torque signs `spins`.
    pub fn torque(
        &self,
        body_rate: &Vector3<f64>,
        speeds: &[f64; 4],
        accelerations: &[f64; 4],
        spins: &[f64; 4],
    ) -> Vector3<f64> {
        let h = Self::spin_sum(speeds, spins);
        let h_dot = Self::spin_sum(accelerations, spins);
        let gyro = body_rate.cross(&Vector3::z()) * (self.inertia * h);
        gyro + Vector3::new(0.0, 0.0, self.inertia * h_dot)
    }
}

impl Default for RotorInertia {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Rotor inflow (the vocabulary's `rotor-inflow`): each rotor loses thrust with its own axial
/// air speed. Rotor `i` at hub `rᵢ` makes `T_i = k_f ωᵢ² − k_in ωᵢ v_a,i`, with
/// `v_a,i = v_z + (Ω × rᵢ)_z` the body-`z` air velocity of its hub \[m/s\]. Here `v_z` is the
/// body-`z` air-relative velocity of the origin (wind subtracted) and `Ω` the body rate.
///
/// A rotor climbing into its own stream (`v_a,i > 0`) sees a larger inflow angle and makes less
/// thrust; a descending one makes more. The extra force is `−k_in Σ ωᵢ v_a,i` along body `z`.
/// Its moments `rᵢ × f_i` damp the roll and pitch rates: at `v = 0` the power
/// `τ·Ω = −k_in Σ ωᵢ (Ω × rᵢ)_z² ≤ 0`.
///
/// It is the same law as the vertical row of [`RotorDrag`] (`k_z`). The plant adds the two
/// when both are on. The diagnosis tells them apart by their columns (docs/CONVENTIONS.md §7).
///
/// Default `k_in = 1.0311·10⁻⁶ kg/rad` (= N s²/(m rad)): the axial coefficient Förster (2015)
/// identified on the Crazyflie 2.0. Blade-element momentum theory for a 45 mm, two-blade
/// propeller (chord about 6 mm, lift slope 5.7) at hover gives about `3.5·10⁻⁶`, the same
/// order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RotorInflow {
    /// `k_in` \[N s²/(m rad)\] (`≥ 0`).
    pub coefficient: f64,
}

impl RotorInflow {
    /// Förster (2015)'s axial coefficient, `k_in = 1.0311·10⁻⁶ kg/rad`.
    pub fn crazyflie() -> Self {
        Self {
            coefficient: 1.0311e-6,
        }
    }

    /// The inflow wrench of the four rotors, body frame, about the origin: force
    /// `Σ f_i` \[N\] and torque `Σ rᵢ × f_i` \[N m\], with `f_i = −k_in ωᵢ v_a,i e_z`. The
    /// inputs are the air-relative body-frame velocity of the origin `v_air_b` \[m/s\], the
    /// body rate `body_rate` \[rad/s\], the rotor speeds `rotor_speeds` \[rad/s\] and the hub
    /// positions `rotor_positions` (body frame) \[m\]. It is [`RotorDrag::wrench`] with
    /// `K = diag(0, 0, k_in)`: one law, written once.
    pub fn wrench(
        &self,
        v_air_b: &Vector3<f64>,
        body_rate: &Vector3<f64>,
        rotor_speeds: &[f64; 4],
        rotor_positions: &[Vector3<f64>; 4],
    ) -> Wrench {
        RotorDrag {
            coefficients: [0.0, 0.0, self.coefficient],
        }
        .wrench(v_air_b, body_rate, rotor_speeds, rotor_positions)
    }
}

impl Default for RotorInflow {
    fn default() -> Self {
        Self::crazyflie()
    }
}

/// Rotor imbalance (the vocabulary's `rotor-imbalance`): rotor `i` makes `(1 + εᵢ)` times its
/// nominal thrust `k_f ωᵢ²` and reaction torque `k_m ωᵢ²` (a chipped propeller, a tired
/// motor). The vehicle computes its wrench with the nominal coefficients. A per-rotor factor
/// ([`PlantEffect::rotor_factors`]); it multiplies the common factors of `thrust-gain` and
/// `ground-effect`.
///
/// Default: rotor M1 10 % weak, `ε = (−0.1, 0, 0, 0)`. A chosen magnitude: a propeller with a
/// chipped tip loses thrust of this order. Förster (2015) identified one thrust map for all
/// four Crazyflie rotors and reports their spread as a few per cent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RotorImbalance {
    /// `εᵢ` of rotors M1..M4 (dimensionless, each `> −1`).
    pub relative_errors: [f64; 4],
}

impl RotorImbalance {
    /// Rotor M1 10 % weak.
    pub fn crazyflie() -> Self {
        Self {
            relative_errors: [-0.1, 0.0, 0.0, 0.0],
        }
    }
}

impl Default for RotorImbalance {
    fn default() -> Self {
        Self::crazyflie()
    }
}

impl PlantEffect for RotorImbalance {
    fn name(&self) -> &str {
        EffectKind::RotorImbalance.name()
    }
    /// No wrench of its own: it scales the rotors one by one.
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench::zero()
    }
    /// `1 + εᵢ` per rotor.
    fn rotor_factors(&self, _s: &EffectState<'_>) -> [f64; 4] {
        self.relative_errors.map(|e| 1.0 + e)
    }
}

/// Battery-voltage dependence of the rotor map (the vocabulary's `battery-voltage`): the
/// rotors make `(1 + β (V − V_ref)/V_ref)` times their nominal thrust `k_f ωᵢ²` and reaction
/// torque `k_m ωᵢ²`. A common factor ([`PlantEffect::thrust_factor`]).
///
/// The battery voltage \[V\] is a simple discharge and sag model ([`BatteryVoltage::voltage`]):
/// `V = V₀ − r t − s Σ ωᵢ²`. The open-circuit voltage falls linearly in time (a near-constant
/// hover current drains charge linearly); the sag is an internal resistance times a current
/// taken proportional to the total nominal thrust. The simulator logs `V` as the column `vbat`
/// ([`tagk_dynamics::BATTERY_COLUMN`]).
///
/// Defaults (Crazyflie 2.x, 1S 250 mAh LiPo):
/// - `β = 1`: a reasoned value, not a measurement. Stock Crazyflies log no rotor speed; the
///   speeds come from a command calibrated at one voltage. The motor voltage is duty × `V` and
///   the thrust grows about with its square (Bitcraze thrust-stand tests), so `β ≤ 2`; a loaded
///   motor's speed grows less than its voltage, so `β` is smaller. With measured speeds `β = 0`.
/// - `V_ref = 3.8 V` ([`tagk_dynamics::BATTERY_REFERENCE_VOLTAGE`]), `V₀ = 4.1 V`.
/// - `r = 1.5e-3 V/s`: 4.15 → 3.5 V over a 7-minute flight.
/// - `s = 2.8e-8 V s²/rad²`: Bitcraze's PWM-to-thrust table drops 0.34 V at 28.6 g of thrust,
///   1.2 V/N, times `k_f = 2.3e-8 N s²`. Near hover it sags 0.33 V.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BatteryVoltage {
    /// `β`, the relative thrust change per relative voltage change (dimensionless).
    pub beta: f64,
    /// `V_ref` \[V\], the voltage at which the nominal coefficients hold (`> 0`).
    pub reference_voltage: f64,
    /// `V₀` \[V\], the open-circuit voltage at time 0 (`> 0`).
    pub initial_voltage: f64,
    /// `r` \[V/s\], the open-circuit voltage's fall per second (`≥ 0`).
    pub discharge_rate: f64,
    /// `s` \[V s²/rad²\], the sag per unit of `Σ ωᵢ²` (`≥ 0`).
    pub sag: f64,
}

impl BatteryVoltage {
    /// The Crazyflie 2.x defaults (type docs).
    pub fn crazyflie() -> Self {
        Self {
            beta: 1.0,
            reference_voltage: tagk_dynamics::BATTERY_REFERENCE_VOLTAGE,
            initial_voltage: 4.1,
            discharge_rate: 1.5e-3,
            sag: 2.8e-8,
        }
    }

    /// The battery voltage \[V\] at time `t` \[s\] with rotor speeds `rotor` \[rad/s\]:
    /// `V₀ − r t − s Σ ωᵢ²`, floored at 0.
    pub fn voltage(&self, t: f64, rotor: &[f64; 4]) -> f64 {
        let sq: f64 = rotor.iter().map(|w| w * w).sum();
        (self.initial_voltage - self.discharge_rate * t - self.sag * sq).max(0.0)
    }

    /// The factor `1 + β (V − V_ref)/V_ref` at voltage `v` \[V\].
    pub fn factor(&self, v: f64) -> f64 {
        1.0 + self.beta * (v - self.reference_voltage) / self.reference_voltage
    }
}

impl Default for BatteryVoltage {
    fn default() -> Self {
        Self::crazyflie()
    }
}

impl PlantEffect for BatteryVoltage {
    fn name(&self) -> &str {
        EffectKind::BatteryVoltage.name()
    }
    /// No wrench of its own: it scales the rotors.
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench::zero()
    }
    /// `1 + β (V − V_ref)/V_ref` at the state's time and rotor speeds.
    fn thrust_factor(&self, s: &EffectState<'_>) -> f64 {
        self.factor(self.voltage(s.time, &s.rotor_speeds))
    }
}

impl PlantEffect for RotorInflow {
    fn name(&self) -> &str {
        EffectKind::RotorInflow.name()
    }
    /// [`RotorInflow::wrench`] of the air-relative velocity.
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        RotorInflow::wrench(
            self,
            &s.air_velocity_body,
            &s.body_rate,
            &s.rotor_speeds,
            s.rotor_positions,
        )
    }
}

impl PlantEffect for RotorDrag {
    fn name(&self) -> &str {
        EffectKind::RotorDrag.name()
    }
    /// [`RotorDrag::wrench`] of the air-relative velocity.
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        RotorDrag::wrench(
            self,
            &s.air_velocity_body,
            &s.body_rate,
            &s.rotor_speeds,
            s.rotor_positions,
        )
    }
}

impl PlantEffect for LinearDrag {
    fn name(&self) -> &str {
        EffectKind::LinearDrag.name()
    }
    /// `f_b = −D v_b` on the air-relative velocity; no torque.
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        Wrench {
            force: -Vector3::from(self.coefficients).component_mul(&s.air_velocity_body),
            torque: Vector3::zeros(),
        }
    }
}

impl PlantEffect for QuadraticDrag {
    fn name(&self) -> &str {
        EffectKind::QuadraticDrag.name()
    }
    /// `f_b,i = −½ ρ (C_d A)_i |v_i| v_i` on the air-relative velocity; no torque.
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        let v = &s.air_velocity_body;
        Wrench {
            force: Vector3::from_fn(|i, _| {
                -(0.5 * self.air_density * self.cd_area[i] * v[i].abs() * v[i])
            }),
            torque: Vector3::zeros(),
        }
    }
}

impl PlantEffect for BodyBias {
    fn name(&self) -> &str {
        EffectKind::BodyBias.name()
    }
    /// The constant body-frame force and torque.
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench {
            force: Vector3::from(self.force),
            torque: Vector3::from(self.torque),
        }
    }
}

impl PlantEffect for ThrustGain {
    fn name(&self) -> &str {
        EffectKind::ThrustGain.name()
    }
    /// No wrench of its own: it scales the rotors.
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench::zero()
    }
    /// `1 + ε`.
    fn thrust_factor(&self, _s: &EffectState<'_>) -> f64 {
        1.0 + self.relative_error
    }
}

impl PlantEffect for GroundEffect {
    fn name(&self) -> &str {
        EffectKind::GroundEffect.name()
    }
    /// No wrench of its own: it scales the rotors.
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench::zero()
    }
    /// [`GroundEffect::thrust_ratio`] at the body origin's height.
    fn thrust_factor(&self, s: &EffectState<'_>) -> f64 {
        self.thrust_ratio(s.position.z)
    }
}

/// The factor on each rotor's thrust of `effects` at state `s`: the product of their
/// [`PlantEffect::rotor_factors`], in order, from 1 (rotors `w1..w4`).
pub fn rotor_factors(effects: &[std::sync::Arc<dyn PlantEffect>], s: &EffectState<'_>) -> [f64; 4] {
    effects.iter().fold([1.0; 4], |k, e| {
        let f = e.rotor_factors(s);
        std::array::from_fn(|i| k[i] * f[i])
    })
}

/// The factor on the rotors' thrust of `effects` at state `s`: the product of their
/// [`PlantEffect::thrust_factor`]s, in order, from 1.
pub fn thrust_factor(effects: &[std::sync::Arc<dyn PlantEffect>], s: &EffectState<'_>) -> f64 {
    effects.iter().fold(1.0, |k, e| k * e.thrust_factor(s))
}

/// The summed wrench of `effects` at state `s` (body frame, about the origin \[N, N m\]),
/// added in order from zero.
pub fn summed_wrench(effects: &[std::sync::Arc<dyn PlantEffect>], s: &EffectState<'_>) -> Wrench {
    let mut w = Wrench::zero();
    for e in effects {
        let x = e.wrench(s);
        w.force += x.force;
        w.torque += x.torque;
    }
    w
}

/// The user's own [`PlantEffect`]s of a [`crate::SimConfig`], shared between the flights of a
/// sweep. Two lists are equal when they hold the same effect objects (pointer equality).
#[derive(Clone, Default)]
pub struct UserEffects(pub Vec<std::sync::Arc<dyn PlantEffect>>);

impl UserEffects {
    /// No user effect.
    pub fn none() -> Self {
        Self::default()
    }

    /// `true` when there is no user effect.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl PartialEq for UserEffects {
    fn eq(&self, other: &Self) -> bool {
        self.0.len() == other.0.len()
            && self
                .0
                .iter()
                .zip(&other.0)
                .all(|(a, b)| std::sync::Arc::ptr_eq(a, b))
    }
}

impl Debug for UserEffects {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.0.iter()).finish()
    }
}

/// Which plant effects are on (all off by default: the paper's ideal plant).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlantEffects {
    /// Body-frame linear drag on the air-relative velocity.
    pub linear_drag: Option<LinearDrag>,
    /// Body-frame rotor drag, proportional to the rotor-speed sum.
    pub rotor_drag: Option<RotorDrag>,
    /// Quadratic parasitic drag.
    pub quadratic_drag: Option<QuadraticDrag>,
    /// First-order motor lag.
    pub motor_lag: Option<MotorLag>,
    /// Ground effect.
    pub ground_effect: Option<GroundEffect>,
    /// Constant wind.
    pub wind: Option<Wind>,
    /// Thrust gain error.
    pub thrust_gain: Option<ThrustGain>,
    /// Constant body force/torque bias.
    pub body_bias: Option<BodyBias>,
    /// Delay of the logged wrench behind the logged motion (the log only).
    pub time_delay: Option<TimeDelay>,
    /// Rotor and motor-bell spin inertia (left out of serialised sets when off, so that they
    /// read as before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotor_inertia: Option<RotorInertia>,
    /// Thrust loss with each rotor's axial air speed.
    #[serde(default)]
    pub rotor_inflow: Option<RotorInflow>,
    /// Per-rotor thrust and torque coefficients.
    #[serde(default)]
    pub rotor_imbalance: Option<RotorImbalance>,
    /// Battery-voltage dependence of the rotor map (logs `vbat`).
    #[serde(default)]
    pub battery_voltage: Option<BatteryVoltage>,
    /// Rotor-speed telemetry delay and filtering (the log only; left out of serialised sets
    /// when off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub telemetry_lag: Option<TelemetryLag>,
}

impl PlantEffects {
    /// No effect: the ideal plant.
    pub fn none() -> Self {
        Self::default()
    }

    /// The effects of the vocabulary the simulator can produce (today every [`EffectKind`]),
    /// in the vocabulary's order.
    pub fn supported() -> impl Iterator<Item = EffectKind> {
        EffectKind::ALL
            .into_iter()
            .filter(|k| Self::none().with(*k).is_ok())
    }

    /// Exactly one effect on, at its Crazyflie default magnitude.
    ///
    /// # Errors
    /// [`SimError::UnsupportedEffect`] for an effect the plant cannot produce.
    pub fn only(kind: EffectKind) -> Result<Self, SimError> {
        Self::none().with(kind)
    }

    /// This set with `kind` switched on at its Crazyflie default magnitude.
    ///
    /// # Errors
    /// [`SimError::UnsupportedEffect`] for an effect of the vocabulary the simulator cannot
    /// produce (none today; the vocabulary may grow first).
    pub fn with(mut self, kind: EffectKind) -> Result<Self, SimError> {
        match kind {
            EffectKind::LinearDrag => self.linear_drag = Some(LinearDrag::crazyflie()),
            EffectKind::RotorDrag => self.rotor_drag = Some(RotorDrag::crazyflie()),
            EffectKind::QuadraticDrag => self.quadratic_drag = Some(QuadraticDrag::crazyflie()),
            EffectKind::MotorLag => self.motor_lag = Some(MotorLag::crazyflie()),
            EffectKind::GroundEffect => self.ground_effect = Some(GroundEffect::crazyflie()),
            EffectKind::Wind => self.wind = Some(Wind::crazyflie()),
            EffectKind::ThrustGain => self.thrust_gain = Some(ThrustGain::crazyflie()),
            EffectKind::BodyBias => self.body_bias = Some(BodyBias::crazyflie()),
            EffectKind::TimeDelay => self.time_delay = Some(TimeDelay::crazyflie()),
            EffectKind::RotorInertia => self.rotor_inertia = Some(RotorInertia::crazyflie()),
            EffectKind::RotorInflow => self.rotor_inflow = Some(RotorInflow::crazyflie()),
            EffectKind::RotorImbalance => {
                self.rotor_imbalance = Some(RotorImbalance::crazyflie());
            }
            EffectKind::BatteryVoltage => {
                self.battery_voltage = Some(BatteryVoltage::crazyflie());
            }
            EffectKind::TelemetryLag => self.telemetry_lag = Some(TelemetryLag::crazyflie()),
            other => return Err(SimError::UnsupportedEffect { effect: other }),
        }
        Ok(self)
    }

    /// The names of the coefficients [`PlantEffects::with_coefficients`] takes for `kind`,
    /// in order, with their units: the fields of the effect's parameter struct.
    pub fn coefficient_names(kind: EffectKind) -> &'static str {
        match kind {
            EffectKind::LinearDrag => "d_x, d_y, d_z [N s/m]",
            EffectKind::RotorDrag => "k_x, k_y, k_z [kg/rad]",
            EffectKind::QuadraticDrag => "CdA_x, CdA_y, CdA_z [m^2], air density [kg/m^3]",
            EffectKind::MotorLag => "time constant [s]",
            EffectKind::GroundEffect => "rotor radius [m]",
            EffectKind::Wind => "v_x, v_y, v_z (world) [m/s]",
            EffectKind::ThrustGain => "relative error [1]",
            EffectKind::BodyBias => "f_x, f_y, f_z [N], t_x, t_y, t_z [N m] (body)",
            EffectKind::TimeDelay => "delay [s]",
            EffectKind::RotorInertia => "J_r (one rotor) [kg m^2]",
            EffectKind::RotorInflow => "k_in [N s^2/(m rad)]",
            EffectKind::RotorImbalance => "eps_1, eps_2, eps_3, eps_4 [1] (rotors M1..M4)",
            EffectKind::BatteryVoltage => "beta [1], v_ref [V]",
            EffectKind::TelemetryLag => "time constant [s], delay [s]",
            _ => "",
        }
    }

    /// This set with `kind` switched on at the given coefficients, in the order of
    /// [`PlantEffects::coefficient_names`] (SI units, the fields of the effect's parameter
    /// struct). No coefficient: the Crazyflie default ([`PlantEffects::with`]).
    ///
    /// # Errors
    /// [`SimError::UnsupportedEffect`] as [`PlantEffects::with`];
    /// [`SimError::EffectCoefficients`] for a wrong number of coefficients;
    /// [`SimError::InvalidParameter`] for a bad value ([`PlantEffects::validate`]).
    pub fn with_coefficients(self, kind: EffectKind, c: &[f64]) -> Result<Self, SimError> {
        let mut e = self.with(kind)?;
        if c.is_empty() {
            return Ok(e);
        }
        let three = |c: &[f64]| [c[0], c[1], c[2]];
        let expected = match kind {
            EffectKind::LinearDrag | EffectKind::RotorDrag | EffectKind::Wind => 3,
            EffectKind::QuadraticDrag => 4,
            EffectKind::BodyBias => 6,
            EffectKind::RotorImbalance => 4,
            EffectKind::BatteryVoltage | EffectKind::TelemetryLag => 2,
            _ => 1,
        };
        if c.len() != expected {
            return Err(SimError::EffectCoefficients {
                effect: kind,
                expected,
                names: Self::coefficient_names(kind),
                got: c.len(),
            });
        }
        match kind {
            EffectKind::LinearDrag => {
                e.linear_drag = Some(LinearDrag {
                    coefficients: three(c),
                })
            }
            EffectKind::RotorDrag => {
                e.rotor_drag = Some(RotorDrag {
                    coefficients: three(c),
                })
            }
            EffectKind::QuadraticDrag => {
                e.quadratic_drag = Some(QuadraticDrag {
                    cd_area: three(c),
                    air_density: c[3],
                });
            }
            EffectKind::MotorLag => {
                e.motor_lag = Some(MotorLag {
                    time_constant: c[0],
                })
            }
            EffectKind::GroundEffect => e.ground_effect = Some(GroundEffect { rotor_radius: c[0] }),
            EffectKind::Wind => e.wind = Some(Wind { velocity: three(c) }),
            EffectKind::ThrustGain => {
                e.thrust_gain = Some(ThrustGain {
                    relative_error: c[0],
                })
            }
            EffectKind::BodyBias => {
                e.body_bias = Some(BodyBias {
                    force: three(c),
                    torque: three(&c[3..]),
                });
            }
            EffectKind::TimeDelay => e.time_delay = Some(TimeDelay { delay: c[0] }),
            EffectKind::RotorInertia => e.rotor_inertia = Some(RotorInertia { inertia: c[0] }),
            EffectKind::RotorInflow => e.rotor_inflow = Some(RotorInflow { coefficient: c[0] }),
            EffectKind::RotorImbalance => {
                e.rotor_imbalance = Some(RotorImbalance {
                    relative_errors: [c[0], c[1], c[2], c[3]],
                });
            }
            // The battery's discharge and sag keep their defaults.
            EffectKind::BatteryVoltage => {
                e.battery_voltage = Some(BatteryVoltage {
                    beta: c[0],
                    reference_voltage: c[1],
                    ..BatteryVoltage::crazyflie()
                });
            }
            EffectKind::TelemetryLag => {
                e.telemetry_lag = Some(TelemetryLag {
                    time_constant: c[0],
                    delay: c[1],
                });
            }
            other => return Err(SimError::UnsupportedEffect { effect: other }),
        }
        e.validate()?;
        Ok(e)
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
        if let Some(d) = &self.rotor_drag {
            finite("rotor_drag.coefficients", &d.coefficients)?;
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
        if let Some(e) = &self.thrust_gain {
            finite("thrust_gain.relative_error", &[e.relative_error])?;
            if e.relative_error <= -1.0 {
                return Err(SimError::InvalidParameter {
                    name: "thrust_gain.relative_error",
                    value: e.relative_error,
                    reason: "must be > -1",
                });
            }
        }
        if let Some(b) = &self.body_bias {
            finite("body_bias.force", &b.force)?;
            finite("body_bias.torque", &b.torque)?;
        }
        if let Some(i) = &self.rotor_inflow
            && !(i.coefficient >= 0.0 && i.coefficient.is_finite())
        {
            return Err(SimError::InvalidParameter {
                name: "rotor_inflow.coefficient",
                value: i.coefficient,
                reason: "must be non-negative and finite",
            });
        }
        if let Some(b) = &self.battery_voltage {
            finite("battery_voltage.beta", &[b.beta])?;
            let positive = [
                ("battery_voltage.reference_voltage", b.reference_voltage),
                ("battery_voltage.initial_voltage", b.initial_voltage),
            ];
            let non_negative = [
                ("battery_voltage.discharge_rate", b.discharge_rate),
                ("battery_voltage.sag", b.sag),
            ];
            if let Some(&(name, value)) =
                positive.iter().find(|(_, v)| !(*v > 0.0 && v.is_finite()))
            {
                return Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "must be positive and finite",
                });
            }
            if let Some(&(name, value)) = non_negative
                .iter()
                .find(|(_, v)| !(*v >= 0.0 && v.is_finite()))
            {
                return Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "must be non-negative and finite",
                });
            }
        }
        if let Some(b) = &self.rotor_imbalance {
            finite("rotor_imbalance.relative_errors", &b.relative_errors)?;
            if let Some(&value) = b.relative_errors.iter().find(|e| **e <= -1.0) {
                return Err(SimError::InvalidParameter {
                    name: "rotor_imbalance.relative_errors",
                    value,
                    reason: "must be > -1",
                });
            }
        }
        if let Some(l) = &self.telemetry_lag {
            for (name, value) in [
                ("telemetry_lag.time_constant", l.time_constant),
                ("telemetry_lag.delay", l.delay),
            ] {
                if !(value >= 0.0 && value.is_finite()) {
                    return Err(SimError::InvalidParameter {
                        name,
                        value,
                        reason: "must be non-negative and finite",
                    });
                }
            }
        }
        if let Some(d) = &self.time_delay
            && !(d.delay >= 0.0 && d.delay.is_finite())
        {
            return Err(SimError::InvalidParameter {
                name: "time_delay.delay",
                value: d.delay,
                reason: "must be non-negative and finite",
            });
        }
        if let Some(r) = &self.rotor_inertia {
            // Finite only, as the drag coefficients: a fitted `J_r` may be negative within
            // its noise, and flying it is the model file's business.
            finite("rotor_inertia.inertia", &[r.inertia])?;
        }
        Ok(())
    }

    /// The wrench-like effects that are on, as [`PlantEffect`]s, in the order the plant
    /// applies them: `thrust-gain`, `ground-effect` (thrust factors), then the acting rotor
    /// drag ([`PlantEffects::acting_rotor_drag`]), `linear-drag`, `quadratic-drag`,
    /// `body-bias`, `rotor-inflow` (wrenches), `rotor-imbalance` (per-rotor factors),
    /// `battery-voltage` (a thrust factor). Motor
    /// lag, wind and time delay are not among them (module docs).
    pub fn acting(&self) -> Vec<std::sync::Arc<dyn PlantEffect>> {
        let mut v: Vec<std::sync::Arc<dyn PlantEffect>> = Vec::new();
        if let Some(e) = self.thrust_gain {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.ground_effect {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.acting_rotor_drag() {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.linear_drag {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.quadratic_drag {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.body_bias {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.rotor_inflow {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.rotor_imbalance {
            v.push(std::sync::Arc::new(e));
        }
        if let Some(e) = self.battery_voltage {
            v.push(std::sync::Arc::new(e));
        }
        v
    }

    /// The wind velocity, world frame \[m/s\] (zero without a [`Wind`]).
    pub fn wind_velocity(&self) -> Vector3<f64> {
        self.wind
            .map_or_else(Vector3::zeros, |w| Vector3::from(w.velocity))
    }

    /// Multiplier on every rotor's thrust and reaction torque at height `z` \[m\]
    /// (thrust gain times ground effect; 1 for the ideal plant): [`thrust_factor`] of
    /// [`PlantEffects::acting`].
    pub fn thrust_multiplier(&self, z: f64) -> f64 {
        let positions = [Vector3::zeros(); 4];
        let s = EffectState {
            time: 0.0,
            position: Vector3::new(0.0, 0.0, z),
            velocity: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            body_rate: Vector3::zeros(),
            air_velocity_body: Vector3::zeros(),
            rotor_speeds: [0.0; 4],
            rotor_positions: &positions,
        };
        thrust_factor(&self.acting(), &s)
    }

    /// The rotor drag that acts: the `rotor_drag` effect, or the Crazyflie's rotor drag that
    /// a `wind` without any drag effect pushes through; `None` otherwise.
    pub fn acting_rotor_drag(&self) -> Option<RotorDrag> {
        let no_drag = self.linear_drag.is_none() && self.quadratic_drag.is_none();
        match (&self.rotor_drag, &self.wind) {
            (Some(d), _) => Some(*d),
            (None, Some(_)) if no_drag => Some(RotorDrag::crazyflie()),
            _ => None,
        }
    }

    /// The wrench of the aerodynamic effects and the bias, body frame, about the origin: force
    /// \[N\], torque \[N m\] ([`summed_wrench`] of [`PlantEffects::acting`]). The inputs are the
    /// world velocity `velocity` \[m/s\], the attitude `attitude`, the body rate `body_rate`
    /// \[rad/s\], and the actual rotor speeds `rotor_speeds` \[rad/s\] of the rotors at
    /// `rotor_positions` (body frame \[m\]). The drag effects act on the air-relative velocity
    /// (`wind` subtracted). Rotor drag acts at each hub with its moments
    /// ([`RotorDrag::wrench`]); a `wind` without any drag effect uses it too. No built-in
    /// wrench depends on the position or the time.
    pub fn extra_wrench(
        &self,
        velocity: &Vector3<f64>,
        attitude: &UnitQuaternion<f64>,
        body_rate: &Vector3<f64>,
        rotor_speeds: &[f64; 4],
        rotor_positions: &[Vector3<f64>; 4],
    ) -> Wrench {
        let s = EffectState {
            time: 0.0,
            position: Vector3::zeros(),
            velocity: *velocity,
            attitude: *attitude,
            body_rate: *body_rate,
            air_velocity_body: attitude
                .inverse_transform_vector(&(velocity - self.wind_velocity())),
            rotor_speeds: *rotor_speeds,
            rotor_positions,
        };
        summed_wrench(&self.acting(), &s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_effect_of_the_vocabulary_has_a_simulator_model() {
        for kind in EffectKind::ALL {
            let e = PlantEffects::only(kind).unwrap();
            assert!(!e.is_ideal() && e.validate().is_ok(), "{kind}");
        }
        assert_eq!(PlantEffects::supported().count(), EffectKind::ALL.len());
        let bad = PlantEffects {
            time_delay: Some(TimeDelay { delay: -0.01 }),
            ..PlantEffects::none()
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn linear_drag_default_is_rotor_drag_at_hover() {
        let d = LinearDrag::crazyflie().coefficients;
        // Förster's K times Σω at hover, computed independently: ω = sqrt(m g / (4 k_f)).
        let omega = (0.035_f64 * 9.81 / 4.0 / 2.3e-8).sqrt();
        assert!((d[0] - 9.1785e-7 * 4.0 * omega).abs() < 1e-12);
        assert!((7.0e-3..7.2e-3).contains(&d[0]) && (7.9e-3..8.1e-3).contains(&d[2]));
        let v = Vector3::new(1.0, 0.0, 0.0);
        let w = PlantEffects::only(EffectKind::LinearDrag)
            .unwrap()
            .extra_wrench(
                &v,
                &UnitQuaternion::identity(),
                &Vector3::zeros(),
                &[0.0; 4],
                &[Vector3::zeros(); 4],
            );
        let f = w.force;
        assert!((f.x + d[0]).abs() < 1e-15 && f.y == 0.0 && f.z == 0.0);
        assert_eq!(w.torque, Vector3::zeros());
    }

    /// The Crazyflie's hubs, written out (M1..M4, docs/CONVENTIONS.md §4).
    fn hubs() -> [Vector3<f64>; 4] {
        let l = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
        [
            Vector3::new(l, -l, 0.0),
            Vector3::new(-l, -l, 0.0),
            Vector3::new(-l, l, 0.0),
            Vector3::new(l, l, 0.0),
        ]
    }

    /// One state, summed by hand in scalars: `v_hub = v + Ω × r` with `r_z = 0` is
    /// `(v_x − r y, v_y + r x, v_z + p y − q x)`, `H = −ω K v_hub`, and `r × H` with `r_z = 0`
    /// is `(y H_z, −x H_z, x H_y − y H_x)`.
    #[test]
    fn rotor_drag_wrench_is_the_hand_written_sum_over_the_hubs() {
        let d = RotorDrag::crazyflie();
        let [kx, ky, kz] = d.coefficients;
        let (vx, vy, vz) = (0.4, -0.3, 0.2);
        let (p, q, r) = (0.7, -1.1, 0.9);
        let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
        let (mut f, mut t) = ([0.0; 3], [0.0; 3]);
        for (w, h) in speeds.iter().zip(hubs()) {
            let (x, y) = (h.x, h.y);
            let hx = -w * kx * (vx - r * y);
            let hy = -w * ky * (vy + r * x);
            let hz = -w * kz * (vz + p * y - q * x);
            f = [f[0] + hx, f[1] + hy, f[2] + hz];
            t = [t[0] + y * hz, t[1] - x * hz, t[2] + x * hy - y * hx];
        }
        let w = d.wrench(
            &Vector3::new(vx, vy, vz),
            &Vector3::new(p, q, r),
            &speeds,
            &hubs(),
        );
        for i in 0..3 {
            assert!((w.force[i] - f[i]).abs() < 1e-15, "force {i}");
            assert!((w.torque[i] - t[i]).abs() < 1e-17, "torque {i}");
        }
        // The moments are not negligible: the yaw torque is of the order of the
        // reaction-torque differences the mixer commands.
        assert!(w.torque.norm() > 1e-6);
    }

    /// Closed forms and symmetry.
    /// - Equal speeds at `Ω = 0` give the body-origin force `−K (Σω) v` and no moment (the hubs
    ///   sum to zero).
    /// - At `Ω = 0` with differential speeds, the yaw torque is `k_x v_x Σ yᵢωᵢ − k_y v_y Σ xᵢωᵢ`,
    ///   roll `−k_z v_z Σ yᵢωᵢ`, pitch `k_z v_z Σ xᵢωᵢ`.
    /// - At `v = 0` the torque dissipates: `τ·Ω = −Σ ωᵢ (Ω×rᵢ)ᵀ K (Ω×rᵢ) < 0`.
    #[test]
    fn rotor_drag_moments_follow_their_closed_forms() {
        let d = RotorDrag::crazyflie();
        let k = Vector3::from(d.coefficients);
        let v = Vector3::new(0.5, -0.2, 0.3);
        let w = d.wrench(&v, &Vector3::zeros(), &[2000.0; 4], &hubs());
        assert!((w.force + k.component_mul(&v) * 8000.0).norm() < 1e-15);
        assert!(w.torque.norm() < 1e-20);

        let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
        let w = d.wrench(&v, &Vector3::zeros(), &speeds, &hubs());
        let sum_y: f64 = speeds.iter().zip(hubs()).map(|(s, h)| s * h.y).sum();
        let sum_x: f64 = speeds.iter().zip(hubs()).map(|(s, h)| s * h.x).sum();
        let expected = Vector3::new(
            -k.z * v.z * sum_y,
            k.z * v.z * sum_x,
            k.x * v.x * sum_y - k.y * v.y * sum_x,
        );
        assert!(
            (w.torque - expected).norm() < 1e-18,
            "{}",
            w.torque - expected
        );
        let sum: f64 = speeds.iter().sum();
        assert!((w.force + k.component_mul(&v) * sum).norm() < 1e-15);

        let rate = Vector3::new(1.5, -0.8, 2.0);
        let w = d.wrench(&Vector3::zeros(), &rate, &speeds, &hubs());
        let power: f64 = speeds
            .iter()
            .zip(hubs())
            .map(|(s, h)| {
                let u = rate.cross(&h);
                -s * (k.x * u.x * u.x + k.y * u.y * u.y + k.z * u.z * u.z)
            })
            .sum();
        assert!(power < 0.0);
        assert!((w.torque.dot(&rate) - power).abs() < 1e-18);
    }

    /// A wind without a drag effect pushes through the same hub model.
    #[test]
    fn wind_without_drag_uses_rotor_drag_at_the_hubs() {
        let wind = PlantEffects::only(EffectKind::Wind).unwrap();
        let drag = PlantEffects::only(EffectKind::RotorDrag).unwrap();
        let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
        let rate = Vector3::new(0.1, 0.2, -0.3);
        let q = UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7);
        let a = wind.extra_wrench(&Vector3::zeros(), &q, &rate, &speeds, &hubs());
        let b = drag.extra_wrench(&Vector3::new(-0.3, 0.0, 0.0), &q, &rate, &speeds, &hubs());
        assert_eq!(a, b);
        assert!(a.torque.norm() > 0.0);
    }
    /// The inflow wrench summed by hand in scalars: `v_a = v_z + p y − q x` (hubs with
    /// `r_z = 0`), `f_z = −k ω v_a`, and `r × (0, 0, f_z) = (y f_z, −x f_z, 0)`. At `v = 0` the
    /// torque damps the rate: `τ·Ω = −k Σ ω (p y − q x)² < 0`.
    #[test]
    fn rotor_inflow_wrench_is_the_hand_written_sum_over_the_hubs() {
        let e = RotorInflow::crazyflie();
        let k = e.coefficient;
        let (vx, vy, vz) = (0.4, -0.3, 0.25);
        let (p, q, r) = (0.7, -1.1, 0.9);
        let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
        let (mut fz, mut tx, mut ty) = (0.0, 0.0, 0.0);
        for (w, h) in speeds.iter().zip(hubs()) {
            let (x, y) = (h.x, h.y);
            let f = -k * w * (vz + p * y - q * x);
            fz += f;
            tx += y * f;
            ty -= x * f;
        }
        let w = e.wrench(
            &Vector3::new(vx, vy, vz),
            &Vector3::new(p, q, r),
            &speeds,
            &hubs(),
        );
        assert!(w.force.x == 0.0 && w.force.y == 0.0 && w.torque.z == 0.0);
        assert!((w.force.z - fz).abs() < 1e-16, "{} {fz}", w.force.z);
        assert!((w.torque.x - tx).abs() < 1e-18 && (w.torque.y - ty).abs() < 1e-18);
        // A climb (v_z > 0) loses thrust: the extra force points down.
        assert!(fz < 0.0);
        let rate = Vector3::new(1.5, -0.8, 2.0);
        let d = e.wrench(&Vector3::zeros(), &rate, &speeds, &hubs());
        let power: f64 = speeds
            .iter()
            .zip(hubs())
            .map(|(w, h)| -k * w * (rate.x * h.y - rate.y * h.x).powi(2))
            .sum();
        assert!(power < 0.0);
        assert!((d.torque.dot(&rate) - power).abs() < 1e-18);
        // Through the plant's effect list, on the air-relative velocity (the wind subtracted).
        let plant = PlantEffects {
            wind: Some(Wind {
                velocity: [0.0, 0.0, 0.5],
            }),
            rotor_drag: Some(RotorDrag {
                coefficients: [0.0; 3],
            }),
            ..PlantEffects::only(EffectKind::RotorInflow).unwrap()
        };
        let via = plant.extra_wrench(
            &Vector3::new(vx, vy, vz + 0.5),
            &UnitQuaternion::identity(),
            &Vector3::new(p, q, r),
            &speeds,
            &hubs(),
        );
        assert!((via.force.z - fz).abs() < 1e-16 && (via.torque.x - tx).abs() < 1e-18);
    }
}
