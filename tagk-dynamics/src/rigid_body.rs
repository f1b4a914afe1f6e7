//! Newton–Euler equations of one rigid body and their 6×10 regressor (docs/CONVENTIONS.md §3).

use core::ops::{Add, AddAssign, Sub};

use nalgebra::{Matrix3, SMatrix, UnitQuaternion, Vector3};

use crate::{DynamicsError, InertialParams};

/// World-frame gravity `g_w = (0, 0, −9.81) m/s²` (docs/CONVENTIONS.md §2, z up).
pub const GRAVITY_WORLD: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

/// The 6×10 rigid-body regressor type: `[f; τ] = Y θ`.
pub type RigidBodyRegressor = SMatrix<f64, 6, 10>;

/// A wrench (force and torque) on a body, in the body frame, torque about the body origin.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Wrench {
    /// Force \[N\], body frame.
    pub force: Vector3<f64>,
    /// Torque about the body origin \[N m\], body frame.
    pub torque: Vector3<f64>,
}

impl Wrench {
    /// The zero wrench.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Builds a wrench from force \[N\] and torque \[N m\].
    pub fn new(force: Vector3<f64>, torque: Vector3<f64>) -> Self {
        Self { force, torque }
    }

    /// `[f_x, f_y, f_z, τ_x, τ_y, τ_z]`.
    pub fn to_array(&self) -> [f64; 6] {
        [
            self.force.x,
            self.force.y,
            self.force.z,
            self.torque.x,
            self.torque.y,
            self.torque.z,
        ]
    }

    /// Inverse of [`to_array`](Self::to_array).
    pub fn from_array(w: [f64; 6]) -> Self {
        Self {
            force: Vector3::new(w[0], w[1], w[2]),
            torque: Vector3::new(w[3], w[4], w[5]),
        }
    }

    /// `true` when all six entries are finite.
    pub fn is_finite(&self) -> bool {
        self.force
            .iter()
            .chain(self.torque.iter())
            .all(|v| v.is_finite())
    }
}

impl Add for Wrench {
    type Output = Self;
    fn add(self, rhs: Self) -> Self {
        Self {
            force: self.force + rhs.force,
            torque: self.torque + rhs.torque,
        }
    }
}

impl AddAssign for Wrench {
    fn add_assign(&mut self, rhs: Self) {
        self.force += rhs.force;
        self.torque += rhs.torque;
    }
}

impl Sub for Wrench {
    type Output = Self;
    fn sub(self, rhs: Self) -> Self {
        Self {
            force: self.force - rhs.force,
            torque: self.torque - rhs.torque,
        }
    }
}

/// Proper acceleration of the body origin in the body frame, `a = Rᵀ (p̈ − g_w)` — what an
/// ideal accelerometer at the origin reads — from the attitude (body → world) and the world
/// acceleration `p̈` \[m/s²\]. Uses [`GRAVITY_WORLD`].
pub fn proper_acceleration(
    attitude: &UnitQuaternion<f64>,
    accel_world: &Vector3<f64>,
) -> Vector3<f64> {
    attitude.inverse_transform_vector(&(accel_world - GRAVITY_WORLD))
}

/// Forward Newton–Euler: the wrench acting on the body (body frame, about the origin) that
/// produces the motion
///
/// `f = m a + ω̇ × h + ω × (ω × h)`, `τ = I ω̇ + ω × (I ω) + h × a`
///
/// with `accel` the proper acceleration `a = Rᵀ(p̈ − g_w)` of the origin \[m/s²\], `omega` the
/// body angular velocity `ω` \[rad/s\] and `omega_dot` its derivative `ω̇` \[rad/s²\], all in the
/// body frame. Gravity is inside `a`, so the result is the non-gravitational (actuator)
/// wrench.
pub fn newton_euler(
    theta: &InertialParams,
    accel: &Vector3<f64>,
    omega: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
) -> Wrench {
    let m = theta.mass();
    let h = theta.first_moment();
    let i = theta.inertia_origin();
    let force = accel * m + omega_dot.cross(&h) + omega.cross(&omega.cross(&h));
    let torque = i * omega_dot + omega.cross(&(i * omega)) + h.cross(accel);
    Wrench { force, torque }
}

/// Inverse of [`newton_euler`]: the proper acceleration `a` \[m/s², body frame\] of the origin
/// and the angular acceleration `ω̇` \[rad/s², body frame\] produced by `wrench` at angular
/// velocity `omega`.
///
/// Solves the 6×6 spatial-inertia system `[[m·1, −S(h)], [S(h), I]] [a; ω̇] = [f − ω×(ω×h);
/// τ − ω×(Iω)]` by its Schur complement: `I_C ω̇ = τ̃ − h × f̃ / m`, `a = (f̃ + h × ω̇) / m`.
///
/// # Errors
/// [`DynamicsError::NonFinite`] for NaN/∞ input; [`DynamicsError::SingularSpatialInertia`]
/// unless `m > 0` and the inertia about the centre of mass is positive definite.
pub fn try_forward_dynamics(
    theta: &InertialParams,
    wrench: &Wrench,
    omega: &Vector3<f64>,
) -> Result<(Vector3<f64>, Vector3<f64>), DynamicsError> {
    if !theta.is_finite() {
        return Err(DynamicsError::NonFinite {
            what: "inertial parameters",
        });
    }
    if !wrench.is_finite() {
        return Err(DynamicsError::NonFinite { what: "wrench" });
    }
    if !omega.iter().all(|v| v.is_finite()) {
        return Err(DynamicsError::NonFinite {
            what: "angular velocity",
        });
    }
    let m = theta.mass();
    if m <= 0.0 {
        return Err(DynamicsError::SingularSpatialInertia { mass: m });
    }
    let h = theta.first_moment();
    let i: Matrix3<f64> = theta.inertia_origin();
    let f = wrench.force - omega.cross(&omega.cross(&h));
    let t = wrench.torque - omega.cross(&(i * omega));
    let chol = theta
        .inertia_com()
        .cholesky()
        .ok_or(DynamicsError::SingularSpatialInertia { mass: m })?;
    let omega_dot = chol.solve(&(t - h.cross(&f) / m));
    let accel = (f + h.cross(&omega_dot)) / m;
    Ok((accel, omega_dot))
}

/// Inverse of [`newton_euler`] for trusted parameters (the simulator's plant); see
/// [`try_forward_dynamics`] for the equations. Returns `(a, ω̇)`: proper acceleration of the
/// origin \[m/s²\] and angular acceleration \[rad/s²\], both in the body frame.
///
/// # Panics
/// If [`try_forward_dynamics`] fails: non-finite input, `m ≤ 0`, or an inertia about the
/// centre of mass that is not positive definite. Use [`try_forward_dynamics`] for parameters
/// that come from an estimator.
pub fn forward_dynamics(
    theta: &InertialParams,
    wrench: &Wrench,
    omega: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    match try_forward_dynamics(theta, wrench, omega) {
        Ok(v) => v,
        Err(e) => panic!("forward_dynamics: {e}"),
    }
}

/// Writes the 6×10 regressor row-major into `out[..60]` (see [`rigid_body_regressor`]).
#[inline(always)]
fn fill_regressor(a: &Vector3<f64>, w: &Vector3<f64>, wd: &Vector3<f64>, out: &mut [f64; 60]) {
    let (ax, ay, az) = (a.x, a.y, a.z);
    let (wx, wy, wz) = (w.x, w.y, w.z);
    let (dx, dy, dz) = (wd.x, wd.y, wd.z);
    // S(ω̇) + S(ω)S(ω) = S(ω̇) + ω ωᵀ − |ω|²·1
    let (xx, yy, zz) = (wx * wx, wy * wy, wz * wz);
    let (xy, xz, yz) = (wx * wy, wx * wz, wy * wz);
    *out = [
        // f_x
        ax,
        -(yy + zz),
        xy - dz,
        xz + dy,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        // f_y
        ay,
        xy + dz,
        -(xx + zz),
        yz - dx,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        // f_z
        az,
        xz - dy,
        yz + dx,
        -(xx + yy),
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        // τ_x: −S(a) row 0 = [0, az, −ay]; L(ω̇)+S(ω)L(ω) row 0
        0.0,
        0.0,
        az,
        -ay,
        dx,
        dy - wx * wz,
        -yz,
        dz + xy,
        yy - zz,
        yz,
        // τ_y
        0.0,
        -az,
        0.0,
        ax,
        xz,
        dx + yz,
        dy,
        zz - xx,
        dz - xy,
        -xz,
        // τ_z
        0.0,
        ay,
        -ax,
        0.0,
        -xy,
        xx - yy,
        xy,
        dx - yz,
        dy + xz,
        dz,
    ];
}

/// The 6×10 Newton–Euler regressor `Y(a, ω, ω̇)` with `[f; τ] = Y θ`
/// (docs/CONVENTIONS.md §3):
///
/// ```text
/// rows f:  [ a | S(ω̇) + S(ω)S(ω) | 0₃ₓ₆ ]
/// rows τ:  [ 0 | −S(a)           | L(ω̇) + S(ω) L(ω) ]
/// ```
///
/// Inputs as in [`newton_euler`] (body frame; `a` the proper acceleration of the origin).
#[inline]
pub fn rigid_body_regressor(
    accel: &Vector3<f64>,
    omega: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
) -> RigidBodyRegressor {
    let mut buf = [0.0; 60];
    fill_regressor(accel, omega, omega_dot, &mut buf);
    RigidBodyRegressor::from_row_slice(&buf)
}

/// Writes the 6×10 regressor of [`rigid_body_regressor`] row-major into `out[..60]`
/// (`out[10 r + c] = Y[r][c]`) without allocating; entries past 60 are left untouched.
///
/// # Errors
/// [`DynamicsError::DimensionMismatch`] if `out.len() < 60`.
#[inline]
pub fn write_rigid_body_regressor(
    accel: &Vector3<f64>,
    omega: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
    out: &mut [f64],
) -> Result<(), DynamicsError> {
    let got = out.len();
    let block: &mut [f64; 60] = out.get_mut(..60).and_then(|s| s.try_into().ok()).ok_or(
        DynamicsError::DimensionMismatch {
            what: "regressor buffer",
            expected: 60,
            got,
        },
    )?;
    fill_regressor(accel, omega, omega_dot, block);
    Ok(())
}
