//! The trajectory-tracking controller: the hover LQR of `tagk-control` around a reference
//! with feedforward, and the attitude-priority saturation of the rotor thrusts.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use tagk_control::{DareOptions, Lqr, LqrWeights, QuadrotorState, RiccatiSolver, error_state};
use tagk_dynamics::{GRAVITY_WORLD, InertialParams, QuadrotorModel};

use crate::SimError;
use crate::trajectory::ReferenceSample;

/// Relative change `‖P_{k+1} − P_k‖_F / ‖P_{k+1}‖_F` at which the warm-started Riccati
/// iteration of a redesign stops. The gain is then accurate to about this relative level. That
/// is far below what the closed loop can notice, at a fraction of the iterations of the `1e-11`
/// default.
pub const REDESIGN_TOLERANCE: f64 = 1e-8;

/// LQR trajectory-tracking controller: the hover LQR of `tagk-control` around a reference that
/// carries the path's feedforward. The reference attitude tilts body `z` along the desired
/// specific force `a_ref − g_w`, with body `x` towards the reference heading `ψ`. The
/// collective thrust gets the feedforward `m̂ (‖a_ref − g_w‖ − g) / 4` per rotor. Rotor thrusts
/// are clipped to `[0, T_max]` and converted to speeds `ω = sqrt(T / k_f)`.
///
/// **Heading.** The LQR is designed at hover with yaw 0. The hover dynamics do not depend on
/// the yaw. So for a heading `ψ ≠ 0` the controller works in the heading frame: the world
/// rotated by `−ψ` about `+z`. Measured state and reference are rotated into it, where the
/// reference heading is 0 and the design applies unchanged. A turning heading (`ψ̇ ≠ 0`) adds
/// the reference body rate `R_refᵀ (0, 0, ψ̇)`. With `ψ = ψ̇ = 0` nothing is rotated; the
/// computation is bit-identical to a controller without headings.
#[derive(Debug, Clone)]
pub struct Controller {
    lqr: Lqr,
}

impl Controller {
    /// Designs for `params` at period `dt` \[s\] (Riccati doubling for the first design, warm
    /// started Riccati iteration for every redesign, stopping at a relative change of
    /// [`REDESIGN_TOLERANCE`]).
    ///
    /// # Errors
    /// [`SimError::Control`].
    pub fn new(
        model: &QuadrotorModel,
        params: &InertialParams,
        weights: LqrWeights,
        dt: f64,
    ) -> Result<Self, SimError> {
        let mut lqr = Lqr::with_solver(
            model,
            params,
            weights,
            dt,
            RiccatiSolver::Doubling,
            DareOptions {
                tolerance: REDESIGN_TOLERANCE,
                ..DareOptions::default()
            },
        )?;
        lqr.set_solver(RiccatiSolver::Iteration);
        Ok(Self { lqr })
    }

    /// Re-linearises at `params` and warm-starts the Riccati solve; unchanged on error.
    ///
    /// # Errors
    /// [`SimError::Control`].
    pub fn redesign(&mut self, params: &InertialParams) -> Result<(), SimError> {
        self.lqr.redesign(params)?;
        Ok(())
    }

    /// The underlying LQR.
    pub fn lqr(&self) -> &Lqr {
        &self.lqr
    }

    /// Rotor speeds [rad/s] for the measured `state` tracking `reference` (its path and
    /// heading).
    pub fn rotor_speeds(&self, state: &QuadrotorState, reference: &ReferenceSample) -> [f64; 4] {
        if reference.yaw == 0.0 && reference.yaw_rate == 0.0 {
            return self.rotor_speeds_in_heading_frame(state, reference);
        }
        let to_heading = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -reference.yaw);
        let state = QuadrotorState {
            position: to_heading * state.position,
            velocity: to_heading * state.velocity,
            attitude: to_heading * state.attitude,
            body_rate: state.body_rate,
        };
        let reference = ReferenceSample {
            position: to_heading * reference.position,
            velocity: to_heading * reference.velocity,
            acceleration: to_heading * reference.acceleration,
            yaw: 0.0,
            yaw_rate: reference.yaw_rate,
        };
        self.rotor_speeds_in_heading_frame(&state, &reference)
    }

    /// [`Controller::rotor_speeds`] for a `reference` of heading 0 (state and reference in the
    /// heading frame).
    fn rotor_speeds_in_heading_frame(
        &self,
        state: &QuadrotorState,
        reference: &ReferenceSample,
    ) -> [f64; 4] {
        let model = self.lqr.model();
        let specific = reference.acceleration - GRAVITY_WORLD;
        let norm = specific.norm();
        let attitude = if norm > 1e-6 {
            let z = specific / norm;
            let y = z.cross(&Vector3::x()).normalize();
            let x = y.cross(&z);
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
                Matrix3::from_columns(&[x, y, z]),
            ))
        } else {
            UnitQuaternion::identity()
        };
        let body_rate = if reference.yaw_rate == 0.0 {
            Vector3::zeros()
        } else {
            attitude.inverse_transform_vector(&Vector3::new(0.0, 0.0, reference.yaw_rate))
        };
        let r = QuadrotorState {
            position: reference.position,
            velocity: reference.velocity,
            attitude,
            body_rate,
        };
        let e = error_state(state, &r);
        let extra = self.lqr.params().mass() * (norm - GRAVITY_WORLD.z.abs()) / 4.0;
        let hi = model.max_thrust_per_rotor();
        let thrusts = prioritise_attitude(self.lqr.command_unclamped(&e).map(|t| t + extra), hi);
        model.rotor_speeds_from_thrusts(&thrusts)
    }
}

/// Saturation with attitude priority. When some rotor thrust leaves `[0, hi]` \[N\], all four
/// are shifted by the same amount, as far as that brings them inside. This changes only the
/// collective thrust, not the torques. Whatever still exceeds is clipped per rotor. Clipping
/// each rotor independently instead would turn a collective demand beyond the limits into
/// spurious torques. That would tip the vehicle over while it recovers from a payload drop.
pub fn prioritise_attitude(thrusts: [f64; 4], hi: f64) -> [f64; 4] {
    let max = thrusts.iter().copied().fold(f64::MIN, f64::max);
    let min = thrusts.iter().copied().fold(f64::MAX, f64::min);
    let shift = if max > hi {
        (hi - max).max(-min.max(0.0))
    } else if min < 0.0 {
        (-min).min(hi - max)
    } else {
        0.0
    };
    thrusts.map(|t| (t + shift).clamp(0.0, hi))
}
