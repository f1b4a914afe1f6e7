//! The simulated vehicle: a 6-DoF rigid body with the full Newton–Euler dynamics of
//! docs/CONVENTIONS.md §3, quaternion attitude, four rotors with speed limits, optional motor lag
//! and the other [`PlantEffects`], integrated by classical fourth-order Runge–Kutta.
//!
//! State: world position `p` and velocity `v` of the body origin [m, m/s], attitude `q`
//! (body → world, Hamilton, scalar first), body rate `ω` [rad/s] and, with motor lag, the four
//! actual rotor speeds [rad/s]. With the actuator wrench `w` (body frame, about the origin)
//! the accelerations come from `tagk_dynamics::forward_dynamics` (the one implementation of
//! the Newton–Euler equations): `(a, ω̇) = FD(θ, w, ω)`, `p̈ = R a + g_w`, `q̇ = ½ q ⊗ (0, ω)`.
//! The quaternion is renormalised after every step.
//!
//! The wrench `w` is the rotors' (each thrust scaled by the effects' thrust factors and
//! per-rotor factors) plus the wrench of every [`PlantEffect`]: the built-ins of
//! [`PlantEffects::acting`], then the user's own ([`Plant::with_effect`]).
//!
//! With a [`RotorInertia`] the body also feels the spinning
//! rotors: the torque `J_r Ḣ e_z + J_r H (Ω × e_z)`, `H = Σ sᵢ ωᵢ`, with `Ḣ` the motor lag's
//! rotor acceleration. Without a motor lag the rotor speeds jump at each new command. The
//! plant then conserves the total angular momentum across the jump ([`Plant::step`]).

use std::sync::Arc;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use tagk_dynamics::{ForwardDynamics, GRAVITY_WORLD, InertialParams, QuadrotorModel, Wrench};

use crate::plant_effects::{
    EffectState, PlantEffect, RotorInertia, rotor_factors, summed_wrench, thrust_factor,
};
use crate::{PlantEffects, SimError};

/// Full plant state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantState {
    /// Position of the body origin, world frame \[m\].
    pub position: Vector3<f64>,
    /// Velocity of the body origin, world frame [m/s].
    pub velocity: Vector3<f64>,
    /// Attitude, body → world.
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity, body frame [rad/s].
    pub body_rate: Vector3<f64>,
    /// Actual rotor speeds [rad/s] (equal to the clamped command without motor lag).
    pub rotor_speeds: [f64; 4],
}

impl PlantState {
    /// At rest at `position`, level, rotors stopped.
    pub fn at_rest(position: Vector3<f64>) -> Self {
        Self {
            position,
            velocity: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            body_rate: Vector3::zeros(),
            rotor_speeds: [0.0; 4],
        }
    }
}

/// Time derivative of the plant state (quaternion derivative as a raw 4-vector).
#[derive(Debug, Clone, Copy)]
struct Derivative {
    dp: Vector3<f64>,
    dv: Vector3<f64>,
    dq: Quaternion<f64>,
    dw: Vector3<f64>,
    dr: [f64; 4],
}

/// Instantaneous accelerations of the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accelerations {
    /// Proper acceleration of the origin `a = Rᵀ(p̈ − g_w)`, body frame [m/s²] (what an
    /// ideal accelerometer at the origin reads).
    pub proper: Vector3<f64>,
    /// World acceleration `p̈` [m/s²].
    pub world: Vector3<f64>,
    /// Angular acceleration `ω̇`, body frame [rad/s²].
    pub angular: Vector3<f64>,
    /// Total non-gravitational wrench acting on the body (rotors and effects), body frame.
    pub wrench: Wrench,
}

/// The simulated quadrotor.
#[derive(Debug, Clone)]
pub struct Plant {
    model: QuadrotorModel,
    params: InertialParams,
    /// The forward dynamics of `params`, prepared once per body (they change only at
    /// events; every integration stage solves with them).
    dynamics: ForwardDynamics,
    effects: PlantEffects,
    /// The effects that act as [`PlantEffect`]s: the built-ins, then the user's.
    acting: Vec<Arc<dyn PlantEffect>>,
    /// Time since the plant was built \[s\] (the sum of the step lengths).
    time: f64,
    state: PlantState,
}

impl Plant {
    /// A plant with actuator layout `model` (its `k_f`, `k_m`, speed limit, rotor positions),
    /// true inertial parameters `params`, the given effects and initial state.
    ///
    /// # Errors
    /// [`SimError::NonPositiveMass`] if `m ≤ 0`; [`SimError::Dynamics`] if the parameters
    /// admit no forward dynamics; [`SimError::InvalidParameter`] for bad effects or state.
    pub fn new(
        model: QuadrotorModel,
        params: InertialParams,
        effects: PlantEffects,
        state: PlantState,
    ) -> Result<Self, SimError> {
        let dynamics = validate_params(&params)?;
        effects.validate()?;
        let finite = state
            .position
            .iter()
            .chain(state.velocity.iter())
            .chain(state.body_rate.iter())
            .chain(state.attitude.coords.iter())
            .chain(state.rotor_speeds.iter())
            .all(|v| v.is_finite());
        if !finite {
            return Err(SimError::InvalidParameter {
                name: "initial state",
                value: f64::NAN,
                reason: "must be finite",
            });
        }
        Ok(Self {
            model,
            params,
            dynamics,
            acting: effects.acting(),
            effects,
            time: 0.0,
            state,
        })
    }

    /// This plant with the user's effect `effect` acting too, after the built-ins and the
    /// effects added before it (the builder of a custom physical effect).
    #[must_use]
    pub fn with_effect(mut self, effect: Box<dyn PlantEffect>) -> Self {
        self.acting.push(Arc::from(effect));
        self
    }

    /// This plant with each of `effects` acting too (shared, e.g. from
    /// [`SimConfig::user_effects`](crate::SimConfig::user_effects)).
    #[must_use]
    pub fn with_shared_effects(mut self, effects: &[Arc<dyn PlantEffect>]) -> Self {
        self.acting.extend(effects.iter().cloned());
        self
    }

    /// Every effect that acts as a [`PlantEffect`], in the order of application.
    pub fn acting_effects(&self) -> &[Arc<dyn PlantEffect>] {
        &self.acting
    }

    /// Time since the plant was built \[s\] (the sum of the step lengths).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Current state.
    pub fn state(&self) -> &PlantState {
        &self.state
    }

    /// True inertial parameters.
    pub fn params(&self) -> &InertialParams {
        &self.params
    }

    /// Replaces the true inertial parameters (a payload event).
    ///
    /// # Errors
    /// As [`Plant::new`]; the plant is unchanged on error.
    pub fn set_params(&mut self, params: InertialParams) -> Result<(), SimError> {
        self.dynamics = validate_params(&params)?;
        self.params = params;
        Ok(())
    }

    /// Actuator model.
    pub fn model(&self) -> &QuadrotorModel {
        &self.model
    }

    /// Plant effects.
    pub fn effects(&self) -> &PlantEffects {
        &self.effects
    }

    /// Clamps commanded rotor speeds to `[0, ω_max]` [rad/s] (NaN → 0).
    pub fn clamp_speeds(&self, speeds: &[f64; 4]) -> [f64; 4] {
        let hi = self.model.max_rotor_speed;
        speeds.map(|w| if w.is_nan() { 0.0 } else { w.clamp(0.0, hi) })
    }

    /// The battery voltage \[V\] at `state` under command `cmd` \[rad/s\] at time `time` \[s\]
    /// ([`crate::plant_effects::BatteryVoltage::voltage`] at the acting rotor speeds); `None`
    /// without a `battery-voltage` effect.
    pub fn battery_voltage(&self, state: &PlantState, cmd: &[f64; 4], time: f64) -> Option<f64> {
        let b = self.effects.battery_voltage?;
        Some(b.voltage(time, &self.acting_rotor_speeds(state, cmd)))
    }

    fn wrench_at(&self, s: &PlantState, rotor: &[f64; 4], time: f64) -> Wrench {
        let es = EffectState {
            time,
            position: s.position,
            velocity: s.velocity,
            attitude: s.attitude,
            body_rate: s.body_rate,
            air_velocity_body: s
                .attitude
                .inverse_transform_vector(&(s.velocity - self.effects.wind_velocity())),
            rotor_speeds: *rotor,
            rotor_positions: &self.model.rotor_positions,
        };
        let k = thrust_factor(&self.acting, &es);
        let each = rotor_factors(&self.acting, &es);
        let thrusts: [f64; 4] = if each == [1.0; 4] {
            rotor.map(|w| k * self.model.k_f * w * w)
        } else {
            std::array::from_fn(|i| k * each[i] * self.model.k_f * rotor[i] * rotor[i])
        };
        let mut wrench = self.model.wrench_from_thrusts(&thrusts);
        let extra = summed_wrench(&self.acting, &es);
        wrench.force += extra.force;
        wrench.torque += extra.torque;
        wrench
    }

    /// The rotor speeds that act at state `s` under the command `speeds` \[rad/s\] (clamped):
    /// the state's lagging speeds with a motor lag, else the clamped command.
    pub(crate) fn acting_rotor_speeds(&self, s: &PlantState, speeds: &[f64; 4]) -> [f64; 4] {
        self.actual_rotor(s, &self.clamp_speeds(speeds))
    }

    fn actual_rotor(&self, s: &PlantState, cmd: &[f64; 4]) -> [f64; 4] {
        if self.effects.motor_lag.is_some() {
            s.rotor_speeds
        } else {
            *cmd
        }
    }

    /// The rates of change of the actual rotor speeds at state `s` under the clamped command
    /// `cmd` \[rad/s²\]: the motor lag's `(ω_cmd − ω) / τ_m`; zero without a motor lag (the
    /// speeds then jump at the steps, [`Plant::step`]).
    pub(crate) fn rotor_accelerations(&self, s: &PlantState, cmd: &[f64; 4]) -> [f64; 4] {
        match &self.effects.motor_lag {
            Some(l) => core::array::from_fn(|i| (cmd[i] - s.rotor_speeds[i]) / l.time_constant),
            None => [0.0; 4],
        }
    }

    /// Accelerations at state `s` under clamped command `cmd` [rad/s].
    fn accelerations_at(&self, s: &PlantState, cmd: &[f64; 4], time: f64) -> Accelerations {
        let rotor = self.actual_rotor(s, cmd);
        let mut wrench = self.wrench_at(s, &rotor, time);
        if let Some(ri) = &self.effects.rotor_inertia {
            let rates = self.rotor_accelerations(s, cmd);
            wrench.torque += ri.torque(&s.body_rate, &rotor, &rates, &self.model.spin_directions);
        }
        // The parameters were validated on entry, so the solve succeeds for finite input;
        // a non-finite state (a diverged run) propagates as NaN and is caught by the caller.
        let (proper, angular) = self
            .dynamics
            .accelerations(&wrench, &s.body_rate)
            .unwrap_or((Vector3::repeat(f64::NAN), Vector3::repeat(f64::NAN)));
        let world = s.attitude * proper + GRAVITY_WORLD;
        Accelerations {
            proper,
            world,
            angular,
            wrench,
        }
    }

    /// Instantaneous accelerations of the current state under the command `speeds` [rad/s]
    /// (clamped to the rotor limits).
    pub fn accelerations(&self, speeds: &[f64; 4]) -> Accelerations {
        let cmd = self.clamp_speeds(speeds);
        self.accelerations_at(&self.state, &cmd, self.time)
    }

    fn derivative(&self, s: &PlantState, cmd: &[f64; 4], time: f64) -> Derivative {
        let acc = self.accelerations_at(s, cmd, time);
        let w = s.body_rate;
        let dq = s.attitude.into_inner() * Quaternion::new(0.0, w.x, w.y, w.z) * 0.5;
        let dr = self.rotor_accelerations(s, cmd);
        Derivative {
            dp: s.velocity,
            dv: acc.world,
            dq,
            dw: acc.angular,
            dr,
        }
    }

    fn advance(s: &PlantState, d: &Derivative, h: f64) -> PlantState {
        let q = s.attitude.into_inner() + d.dq * h;
        PlantState {
            position: s.position + d.dp * h,
            velocity: s.velocity + d.dv * h,
            // Intermediate RK stages renormalise so the attitude stays a rotation.
            attitude: UnitQuaternion::new_normalize(q),
            body_rate: s.body_rate + d.dw * h,
            rotor_speeds: core::array::from_fn(|i| s.rotor_speeds[i] + d.dr[i] * h),
        }
    }

    /// The jump of the body's velocities when the rotor speeds jump to `cmd` \[rad/s\] (no
    /// motor lag, a [`RotorInertia`] on). The rotors'
    /// angular momentum changes by `−J_r ΔH e_z`; the body takes the impulsive torque
    /// `J_r ΔH e_z` about the origin, so the total is conserved. Its velocity change is the
    /// spatial inertia's solve of that impulse (the forward dynamics at zero rate, where
    /// they are linear in the wrench).
    fn rotor_jump(&self, s: &mut PlantState, cmd: &[f64; 4]) {
        let angular = self.rotor_jump_impulse(s, cmd);
        if angular == Vector3::zeros() {
            return;
        }
        let impulse = Wrench {
            force: Vector3::zeros(),
            torque: angular,
        };
        if let Ok((dv_body, d_rate)) = self.dynamics.accelerations(&impulse, &Vector3::zeros()) {
            s.velocity += s.attitude * dv_body;
            s.body_rate += d_rate;
        }
        s.rotor_speeds = *cmd;
    }

    /// Advances the state by one RK4 step of `dt` \[s\] with the rotor-speed command `speeds`
    /// [rad/s] held constant (clamped to `[0, ω_max]`). Without motor lag the actual rotor
    /// speeds equal the clamped command. With a rotor inertia and no motor lag, a change of
    /// the command first changes the body's velocities by the impulse that conserves the
    /// total angular momentum (rotors and body).
    pub fn step(&mut self, speeds: &[f64; 4], dt: f64) {
        let cmd = self.clamp_speeds(speeds);
        self.rotor_jump_to(&cmd);
        let s0 = self.state;
        let t0 = self.time;
        let k1 = self.derivative(&s0, &cmd, t0);
        let k2 = self.derivative(&Self::advance(&s0, &k1, 0.5 * dt), &cmd, t0 + 0.5 * dt);
        let k3 = self.derivative(&Self::advance(&s0, &k2, 0.5 * dt), &cmd, t0 + 0.5 * dt);
        let k4 = self.derivative(&Self::advance(&s0, &k3, dt), &cmd, t0 + dt);
        let w = dt / 6.0;
        let comb3 = |a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>, d: Vector3<f64>| {
            (a + (b + c) * 2.0 + d) * w
        };
        let dq = (k1.dq + (k2.dq + k3.dq) * 2.0 + k4.dq) * w;
        let mut next = PlantState {
            position: s0.position + comb3(k1.dp, k2.dp, k3.dp, k4.dp),
            velocity: s0.velocity + comb3(k1.dv, k2.dv, k3.dv, k4.dv),
            attitude: UnitQuaternion::new_normalize(s0.attitude.into_inner() + dq),
            body_rate: s0.body_rate + comb3(k1.dw, k2.dw, k3.dw, k4.dw),
            rotor_speeds: core::array::from_fn(|i| {
                s0.rotor_speeds[i] + (k1.dr[i] + 2.0 * (k2.dr[i] + k3.dr[i]) + k4.dr[i]) * w
            }),
        };
        if self.effects.motor_lag.is_none() {
            next.rotor_speeds = cmd;
        }
        self.state = next;
        self.time = t0 + dt;
    }

    /// The angular impulse on the body when the rotor speeds of state `s` jump to the clamped
    /// command `cmd` \[rad/s\]: `J_r ΔH e_z`, body frame \[N m s\]. Zero without a
    /// [`RotorInertia`] or with a motor lag (the speeds
    /// then do not jump).
    pub(crate) fn rotor_jump_impulse(&self, s: &PlantState, cmd: &[f64; 4]) -> Vector3<f64> {
        match (&self.effects.rotor_inertia, &self.effects.motor_lag) {
            (Some(ri), None) => {
                let spins = &self.model.spin_directions;
                let dh = RotorInertia::spin_sum(cmd, spins)
                    - RotorInertia::spin_sum(&s.rotor_speeds, spins);
                Vector3::new(0.0, 0.0, ri.inertia * dh)
            }
            _ => Vector3::zeros(),
        }
    }

    /// Applies [`Plant::rotor_jump`] to the current state.
    fn rotor_jump_to(&mut self, cmd: &[f64; 4]) {
        let mut s = self.state;
        self.rotor_jump(&mut s, cmd);
        self.state = s;
    }

    /// `true` while every state component is finite.
    pub fn is_finite(&self) -> bool {
        let s = &self.state;
        s.position
            .iter()
            .chain(s.velocity.iter())
            .chain(s.body_rate.iter())
            .chain(s.attitude.coords.iter())
            .all(|v| v.is_finite())
    }
}

/// Checks true plant parameters: finite, `m > 0`, positive-definite inertia about the centre
/// of mass (so the forward dynamics exist); returns them, prepared.
///
/// # Errors
/// [`SimError::NonPositiveMass`], [`SimError::Dynamics`].
pub(crate) fn validate_params(params: &InertialParams) -> Result<ForwardDynamics, SimError> {
    let m = params.mass();
    if !(m > 0.0 && m.is_finite()) {
        return Err(SimError::NonPositiveMass {
            what: "vehicle",
            mass: m,
        });
    }
    Ok(ForwardDynamics::new(params)?)
}
