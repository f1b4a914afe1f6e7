//! Quadrotor error model, hover trim, linearisation and zero-order-hold discretisation.
//!
//! # Nonlinear model (docs/CONVENTIONS.md §2–§4)
//!
//! State: world position `p` \[m\], world velocity `v` \[m/s\], attitude `R` (unit quaternion,
//! body → world), body rate `ω` \[rad/s\]. Input: the four rotor thrusts `u` \[N\], mapped by the
//! mixer to the actuator wrench `w(u) = [0, 0, f_z; τ]` (body frame, about the origin).
//! With the inertial parameters `θ` (mass `m`, first moment `h = m c`, inertia `I` about the
//! origin) the Newton–Euler equations (docs/CONVENTIONS.md §3) are the symmetric 6×6 system
//!
//! ```text
//! [ m·1   −S(h) ] [ a ]   [ f − ω×(ω×h) ]
//! [ S(h)    I   ] [ ω̇ ] = [ τ − ω×(Iω)  ]
//! ```
//!
//! solved by `tagk_dynamics::try_forward_dynamics`; `a = Rᵀ(p̈ − g_w)` is the proper
//! acceleration of the body origin. Hence `ṗ = v`, `v̇ = R a + g_w`, `Ṙ = R S(ω)`, `ω̇`.
//! With a centre-of-mass offset the translational and rotational equations couple.
//!
//! # Error state (12)
//!
//! About a reference `x_r = (p_r, v_r, R_r, ω_r)`:
//!
//! ```text
//! e = [ p − p_r ;  v − v_r ;  δ ;  ω − ω_r ],     R = R_r · exp(S(δ))
//! ```
//!
//! i.e. `δ = log(R_rᵀ R)` is the rotation vector \[rad\] of the attitude error **in the body
//! frame** (right perturbation); position and velocity errors are in the world frame.
//! See [`error_state`] / [`apply_error`].
//!
//! # Linearisation
//!
//! The reference is taken to move along the nominal motion through it (`Ṙ_r = R_r S(ω_r)`,
//! `ṗ_r = v_r`, ...), and the error dynamics are differentiated at `e = 0`, `u = u_r`:
//!
//! ```text
//! ė_p = e_v
//! ė_v = −R_r S(a_r) δ + R_r ∂a/∂ω e_ω + R_r ∂a/∂u Δu
//! δ̇   = −S(ω_r) δ + e_ω
//! ė_ω = ∂ω̇/∂ω e_ω + ∂ω̇/∂u Δu
//! ```
//!
//! with `[∂a/∂u; ∂ω̇/∂u] = M⁻¹ W` (`W` the 6×4 wrench-of-thrusts matrix from the mixer) and
//! `[∂a/∂ω; ∂ω̇/∂ω] = −M⁻¹ [(ω·h)1 + ωhᵀ − 2hωᵀ ; S(ω)I − S(Iω)]`. At hover (`ω_r = 0`)
//! the gyroscopic terms vanish and `A` is nilpotent. The velocity does not enter (no drag).
//!
//! # Hover trim
//!
//! Hovering means `p̈ = 0`, `ω = ω̇ = 0`, so `a = −Rᵀ g_w` and the required actuator wrench
//! is `f = m a`, `τ = h × a` (docs/CONVENTIONS.md §3). A quadrotor can push only along body
//! `z`, so `f ∥ e_z` forces a level attitude (any yaw).
//! Then `a = (0, 0, g)`, `f_z = m g` and `τ = h × (0, 0, g) = g (h_y, −h_x, 0)`.
//! The rotors must cancel the gravity torque about the origin, `c × m g_b`.
//! So with a centre-of-mass offset the four trim thrusts differ.
//! They are `M_mix⁻¹ [m g, g h_y, −g h_x, 0]`.

use nalgebra::{Matrix3, Matrix6, SMatrix, SVector, UnitQuaternion, Vector3};
use tagk_dynamics::{
    GRAVITY_WORLD, InertialParams, QuadrotorModel, Wrench, math::skew, newton_euler,
    try_forward_dynamics,
};

use crate::ControlError;

/// Number of error states: position (3), velocity (3), attitude error (3), body rate (3).
pub const STATE_DIM: usize = 12;
/// Number of inputs: the four rotor thrusts.
pub const INPUT_DIM: usize = 4;

/// 12×12 state matrix.
pub type StateMatrix = SMatrix<f64, STATE_DIM, STATE_DIM>;
/// 12×4 input matrix.
pub type InputMatrix = SMatrix<f64, STATE_DIM, INPUT_DIM>;
/// 4×12 feedback gain.
pub type GainMatrix = SMatrix<f64, INPUT_DIM, STATE_DIM>;
/// 12-vector error state `[e_p, e_v, δ, e_ω]` (see the module docs).
pub type ErrorState = SVector<f64, STATE_DIM>;

/// Offsets of the blocks of the error state.
pub mod idx {
    /// Position error (world) \[m\].
    pub const POS: usize = 0;
    /// Velocity error (world) \[m/s\].
    pub const VEL: usize = 3;
    /// Attitude error rotation vector (body) \[rad\].
    pub const ATT: usize = 6;
    /// Body-rate error (body) \[rad/s\].
    pub const RATE: usize = 9;
}

/// Full nonlinear state of the quadrotor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadrotorState {
    /// Position of the body origin, world frame \[m\].
    pub position: Vector3<f64>,
    /// Velocity of the body origin, world frame \[m/s\].
    pub velocity: Vector3<f64>,
    /// Attitude, body → world (docs/CONVENTIONS.md §2).
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity, body frame \[rad/s\].
    pub body_rate: Vector3<f64>,
}

impl QuadrotorState {
    /// At rest at `position` \[m\], level, heading `yaw` \[rad\] about world `z`.
    pub fn hover(position: Vector3<f64>, yaw: f64) -> Self {
        Self {
            position,
            velocity: Vector3::zeros(),
            attitude: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
            body_rate: Vector3::zeros(),
        }
    }

    /// `true` if every component is finite.
    pub fn is_finite(&self) -> bool {
        self.position.iter().all(|v| v.is_finite())
            && self.velocity.iter().all(|v| v.is_finite())
            && self.attitude.coords.iter().all(|v| v.is_finite())
            && self.body_rate.iter().all(|v| v.is_finite())
    }
}

/// Error state `x ⊟ x_r = [p − p_r, v − v_r, log(R_rᵀR), ω − ω_r]` (module docs).
/// The attitude error is the body-frame rotation vector in `[0, π]` rad.
pub fn error_state(state: &QuadrotorState, reference: &QuadrotorState) -> ErrorState {
    let delta = (reference.attitude.inverse() * state.attitude).scaled_axis();
    let mut e = ErrorState::zeros();
    e.fixed_rows_mut::<3>(idx::POS)
        .copy_from(&(state.position - reference.position));
    e.fixed_rows_mut::<3>(idx::VEL)
        .copy_from(&(state.velocity - reference.velocity));
    e.fixed_rows_mut::<3>(idx::ATT).copy_from(&delta);
    e.fixed_rows_mut::<3>(idx::RATE)
        .copy_from(&(state.body_rate - reference.body_rate));
    e
}

/// Inverse of [`error_state`]: `x_r ⊞ e` with `R = R_r exp(S(δ))`.
pub fn apply_error(reference: &QuadrotorState, e: &ErrorState) -> QuadrotorState {
    let delta: Vector3<f64> = e.fixed_rows::<3>(idx::ATT).into_owned();
    QuadrotorState {
        position: reference.position + e.fixed_rows::<3>(idx::POS),
        velocity: reference.velocity + e.fixed_rows::<3>(idx::VEL),
        attitude: reference.attitude * UnitQuaternion::from_scaled_axis(delta),
        body_rate: reference.body_rate + e.fixed_rows::<3>(idx::RATE),
    }
}

/// A reference state with the rotor thrusts \[N\] applied there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    /// Reference state.
    pub state: QuadrotorState,
    /// Reference rotor thrusts \[N\] (M1..M4 as in `tagk_dynamics::quadrotor`).
    pub thrusts: [f64; 4],
}

/// Continuous-time linear error model `ė = A e + B Δu` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuousModel {
    /// State matrix \[1/s\].
    pub a: StateMatrix,
    /// Input matrix: rows in the units of `ė` per newton of rotor thrust.
    pub b: InputMatrix,
}

/// Discrete-time linear error model `e⁺ = A_d e + B_d Δu` (zero-order hold over `dt`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscreteModel {
    /// State transition `exp(A dt)`.
    pub a: StateMatrix,
    /// Input matrix `∫₀^dt exp(A s) ds B`.
    pub b: InputMatrix,
    /// Sample time \[s\].
    pub dt: f64,
}

fn check_params(params: &InertialParams) -> Result<(), ControlError> {
    if params.as_slice().iter().any(|v| !v.is_finite()) {
        return Err(ControlError::NonFinite {
            what: "inertial parameters",
        });
    }
    Ok(())
}

/// 6×6 spatial inertia about the origin, `[[m·1, −S(h)], [S(h), I]]` (symmetric).
fn spatial_inertia(params: &InertialParams) -> Matrix6<f64> {
    let mut m6 = Matrix6::zeros();
    let sh = skew(&params.first_moment());
    m6.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(Matrix3::identity() * params.mass()));
    m6.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-sh));
    m6.fixed_view_mut::<3, 3>(3, 0).copy_from(&sh);
    m6.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&params.inertia_origin());
    m6
}

/// Hover trim at `position` \[m\] and heading `yaw` \[rad\]: level attitude, zero velocity and
/// rate, and the (generally unequal) rotor thrusts `M_mix⁻¹ [m g, g h_y, −g h_x, 0]` that
/// hold it (module docs). The thrusts are **not** clipped: compare them with
/// `model.max_thrust_per_rotor()` (see [`trim_within_limits`]).
///
/// # Errors
/// [`ControlError::NonFinite`] for non-finite input, [`ControlError::InvalidParams`] if
/// `m ≤ 0`.
pub fn hover_trim(
    model: &QuadrotorModel,
    params: &InertialParams,
    position: Vector3<f64>,
    yaw: f64,
) -> Result<OperatingPoint, ControlError> {
    let state = QuadrotorState::hover(position, yaw);
    let thrusts = trim_thrusts(model, params, &state, &Vector3::zeros(), &Vector3::zeros())?;
    Ok(OperatingPoint { state, thrusts })
}

/// Rotor thrusts \[N\] that realise world acceleration `accel_world` \[m/s²\] and body angular
/// acceleration `omega_dot` \[rad/s²\] at `state` (inverse dynamics `newton_euler`,
/// docs/CONVENTIONS.md §3, then the inverse mixer). For hover pass zeros.
///
/// # Errors
/// [`ControlError::TrimInfeasible`] if the required force has a component across body `z`
/// larger than `1e-9·|f| + 1e-12` N (the rotors push only along body `z`: the attitude does
/// not match the acceleration); [`ControlError::NonFinite`]; [`ControlError::InvalidParams`]
/// if `m ≤ 0`.
pub fn trim_thrusts(
    model: &QuadrotorModel,
    params: &InertialParams,
    state: &QuadrotorState,
    accel_world: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
) -> Result<[f64; 4], ControlError> {
    check_params(params)?;
    if !state.is_finite() {
        return Err(ControlError::NonFinite { what: "state" });
    }
    if !(accel_world
        .iter()
        .chain(omega_dot.iter())
        .all(|v| v.is_finite()))
    {
        return Err(ControlError::NonFinite {
            what: "reference acceleration",
        });
    }
    if params.mass() <= 0.0 {
        return Err(ControlError::InvalidParams {
            reason: "mass must be positive",
        });
    }
    let a = state
        .attitude
        .inverse_transform_vector(&(accel_world - GRAVITY_WORLD));
    let w = newton_euler(params, &a, &state.body_rate, omega_dot);
    let lateral = w.force.x.hypot(w.force.y);
    if lateral > 1e-9 * w.force.norm() + 1e-12 {
        return Err(ControlError::TrimInfeasible {
            lateral_force: lateral,
        });
    }
    Ok(model.thrusts_from_wrench(w.force.z, &w.torque))
}

/// `true` if every trim thrust lies in `[0, model.max_thrust_per_rotor()]`.
pub fn trim_within_limits(model: &QuadrotorModel, op: &OperatingPoint) -> bool {
    let hi = model.max_thrust_per_rotor();
    op.thrusts.iter().all(|t| (0.0..=hi).contains(t))
}

/// Continuous-time linearisation of the error dynamics at `op` for parameters `params`
/// (which replace `model.params`; only the actuator layout of `model` is used).
///
/// # Errors
/// [`ControlError::NonFinite`], or [`ControlError::InvalidParams`] if the spatial inertia is
/// not positive definite (`m ≤ 0` or inertia about the centre of mass not `≻ 0`).
pub fn linearize(
    model: &QuadrotorModel,
    params: &InertialParams,
    op: &OperatingPoint,
) -> Result<ContinuousModel, ControlError> {
    check_params(params)?;
    if !op.state.is_finite() || op.thrusts.iter().any(|t| !t.is_finite()) {
        return Err(ControlError::NonFinite {
            what: "operating point",
        });
    }
    let m6 = spatial_inertia(params);
    let chol = m6.cholesky().ok_or(ControlError::InvalidParams {
        reason: "spatial inertia not positive definite (need m > 0, inertia about the COM > 0)",
    })?;
    let omega = op.state.body_rate;
    let wrench: Wrench = model.wrench_from_thrusts(&op.thrusts);
    let (a_ref, _omega_dot_ref) =
        try_forward_dynamics(params, &wrench, &omega).map_err(ControlError::Dynamics)?;

    // Wrench of thrusts: rows f_x, f_y = 0; f_z, τ from the mixer.
    let mix = model.mixer_matrix();
    let mut w6 = SMatrix::<f64, 6, 4>::zeros();
    w6.fixed_view_mut::<4, 4>(2, 0).copy_from(&mix);
    let d_u = chol.solve(&w6); // [∂a/∂u; ∂ω̇/∂u]

    // Bias derivatives.
    let h = params.first_moment();
    let inertia = params.inertia_origin();
    let mut d_bias = SMatrix::<f64, 6, 3>::zeros();
    d_bias.fixed_view_mut::<3, 3>(0, 0).copy_from(
        &(Matrix3::identity() * omega.dot(&h) + omega * h.transpose()
            - h * omega.transpose() * 2.0),
    );
    d_bias
        .fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(skew(&omega) * inertia - skew(&(inertia * omega))));
    let d_w = -chol.solve(&d_bias); // [∂a/∂ω; ∂ω̇/∂ω]

    let r: Matrix3<f64> = op.state.attitude.to_rotation_matrix().into_inner();
    let mut a = StateMatrix::zeros();
    let mut b = InputMatrix::zeros();
    a.fixed_view_mut::<3, 3>(idx::POS, idx::VEL)
        .copy_from(&Matrix3::identity());
    a.fixed_view_mut::<3, 3>(idx::VEL, idx::ATT)
        .copy_from(&(-r * skew(&a_ref)));
    a.fixed_view_mut::<3, 3>(idx::VEL, idx::RATE)
        .copy_from(&(r * d_w.fixed_view::<3, 3>(0, 0)));
    a.fixed_view_mut::<3, 3>(idx::ATT, idx::ATT)
        .copy_from(&(-skew(&omega)));
    a.fixed_view_mut::<3, 3>(idx::ATT, idx::RATE)
        .copy_from(&Matrix3::identity());
    a.fixed_view_mut::<3, 3>(idx::RATE, idx::RATE)
        .copy_from(&d_w.fixed_view::<3, 3>(3, 0));
    b.fixed_view_mut::<3, 4>(idx::VEL, 0)
        .copy_from(&(r * d_u.fixed_view::<3, 4>(0, 0)));
    b.fixed_view_mut::<3, 4>(idx::RATE, 0)
        .copy_from(&d_u.fixed_view::<3, 4>(3, 0));
    Ok(ContinuousModel { a, b })
}

/// Zero-order-hold discretisation of the 12-state model over `dt` \[s\] by
/// [`discretize_zoh`](crate::zoh::discretize_zoh) (scaling-and-squaring Taylor series of
/// `exp(A dt)` and `∫₀^dt exp(A s) ds`, no heap allocation).
///
/// # Errors
/// [`ControlError::InvalidTimeStep`] unless `dt > 0` and finite; [`ControlError::NonFinite`].
pub fn discretize(model: &ContinuousModel, dt: f64) -> Result<DiscreteModel, ControlError> {
    let (a, b) = crate::zoh::discretize_zoh(&model.a, &model.b, dt)?;
    Ok(DiscreteModel { a, b, dt })
}

/// Rotates the position and velocity blocks of an error state from the world frame into
/// the heading frame of yaw `yaw` \[rad\] (`e_p ← R_z(yaw)ᵀ e_p`, same for `e_v`); attitude
/// and rate errors are body-frame already. A hover design at yaw 0 applied to such rotated
/// errors equals the hover design at yaw `yaw` (the hover model is yaw-equivariant).
pub fn to_heading_frame(e: &ErrorState, yaw: f64) -> ErrorState {
    let (s, c) = yaw.sin_cos();
    let mut out = *e;
    for base in [idx::POS, idx::VEL] {
        let (x, y) = (e[base], e[base + 1]);
        out[base] = c * x + s * y;
        out[base + 1] = -s * x + c * y;
    }
    out
}

/// Yaw \[rad\] of an attitude (ZYX Euler angle about world `z`).
pub fn yaw_of(attitude: &UnitQuaternion<f64>) -> f64 {
    attitude.euler_angles().2
}
