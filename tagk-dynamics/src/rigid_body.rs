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
/// Solves the 6×6 spatial-inertia system by its Schur complement.
///
/// The system is `[[m·1, −S(h)], [S(h), I]] [a; ω̇] = [f − ω×(ω×h); τ − ω×(Iω)]`.
/// Its solution is `I_C ω̇ = τ̃ − h × f̃ / m` and `a = (f̃ + h × ω̇) / m`.
///
/// # Errors
/// [`DynamicsError::NonFinite`] for NaN/∞ input; [`DynamicsError::SingularSpatialInertia`]
/// unless `m > 0` and the inertia about the centre of mass is positive definite.
pub fn try_forward_dynamics(
    theta: &InertialParams,
    wrench: &Wrench,
    omega: &Vector3<f64>,
) -> Result<(Vector3<f64>, Vector3<f64>), DynamicsError> {
    ForwardDynamics::new(theta)?.accelerations(wrench, omega)
}

/// [`try_forward_dynamics`] with the parameters' part prepared once: the mass, the first
/// moment, the inertia about the origin and the Cholesky factor of the inertia about the
/// centre of mass. A simulator whose body changes only at events keeps one per body and
/// solves each integration stage with it; the accelerations are bit-identical to
/// [`try_forward_dynamics`] (which is this, prepared afresh).
#[derive(Debug, Clone)]
pub struct ForwardDynamics {
    /// Mass `m` \[kg\].
    mass: f64,
    /// First moment `h = m c` \[kg m\], body frame.
    first_moment: Vector3<f64>,
    /// Rotational inertia about the body origin \[kg m²\], body axes.
    inertia_origin: Matrix3<f64>,
    /// Lower Cholesky factor `L` of the inertia about the centre of mass, `I_C = L Lᵀ`:
    /// `[l00, l10, l11, l20, l21, l22]`.
    chol: [f64; 6],
}

impl ForwardDynamics {
    /// Prepares the solve for `theta`.
    ///
    /// # Errors
    /// [`DynamicsError::NonFinite`] for non-finite parameters;
    /// [`DynamicsError::SingularSpatialInertia`] unless `m > 0` and the inertia about the
    /// centre of mass is positive definite.
    pub fn new(theta: &InertialParams) -> Result<Self, DynamicsError> {
        if !theta.is_finite() {
            return Err(DynamicsError::NonFinite {
                what: "inertial parameters",
            });
        }
        let mass = theta.mass();
        if mass <= 0.0 {
            return Err(DynamicsError::SingularSpatialInertia { mass });
        }
        let l = theta
            .inertia_com()
            .cholesky()
            .ok_or(DynamicsError::SingularSpatialInertia { mass })?
            .unpack();
        Ok(Self {
            mass,
            first_moment: theta.first_moment(),
            inertia_origin: theta.inertia_origin(),
            chol: [
                l[(0, 0)],
                l[(1, 0)],
                l[(1, 1)],
                l[(2, 0)],
                l[(2, 1)],
                l[(2, 2)],
            ],
        })
    }

    /// `I_C⁻¹ v` by the two triangular solves `L y = v`, `Lᵀ x = y`, written out for 3 × 3. They
    /// follow nalgebra's order of operations (`Cholesky::solve`). The forward solve goes column by
    /// column. The backward one computes `(y_i − Σ_(j>i) L_ji x_j) / L_ii`, the sum taken from
    /// `j = i + 1` up. So the bits are those of `Cholesky::solve` (tested), at a fraction of its
    /// cost.
    fn solve_inertia_com(&self, v: &Vector3<f64>) -> Vector3<f64> {
        let [l00, l10, l11, l20, l21, l22] = self.chol;
        let y0 = v.x / l00;
        let b1 = v.y - y0 * l10;
        let b2 = v.z - y0 * l20;
        let y1 = b1 / l11;
        let y2 = (b2 - y1 * l21) / l22;
        let x2 = y2 / l22;
        let x1 = (y1 - l21 * x2) / l11;
        let x0 = (y0 - (l10 * x1 + l20 * x2)) / l00;
        Vector3::new(x0, x1, x2)
    }

    /// The proper acceleration `a` \[m/s², body frame\] of the origin and the angular
    /// acceleration `ω̇` \[rad/s², body frame\] produced by `wrench` at angular velocity
    /// `omega` \[rad/s\] (the equations of [`try_forward_dynamics`]).
    ///
    /// # Errors
    /// [`DynamicsError::NonFinite`] for a non-finite wrench or angular velocity.
    pub fn accelerations(
        &self,
        wrench: &Wrench,
        omega: &Vector3<f64>,
    ) -> Result<(Vector3<f64>, Vector3<f64>), DynamicsError> {
        if !wrench.is_finite() {
            return Err(DynamicsError::NonFinite { what: "wrench" });
        }
        if !omega.iter().all(|v| v.is_finite()) {
            return Err(DynamicsError::NonFinite {
                what: "angular velocity",
            });
        }
        let (m, h, i) = (self.mass, &self.first_moment, &self.inertia_origin);
        let f = wrench.force - omega.cross(&omega.cross(h));
        let t = wrench.torque - omega.cross(&(i * omega));
        let omega_dot = self.solve_inertia_com(&(t - h.cross(&f) / m));
        let accel = (f + h.cross(&omega_dot)) / m;
        Ok((accel, omega_dot))
    }
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
