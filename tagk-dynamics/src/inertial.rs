//! Inertial parameters of one rigid body (docs/CONVENTIONS.md §1): construction, conversions,
//! payloads, frame changes and physical-consistency checks.

use core::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

use nalgebra::{Matrix3, Matrix4, Vector3};
use thiserror::Error;

use crate::DynamicsError;
use crate::math::parallel_axis;

/// Inertial parameters of one rigid body,
/// `θ = [m, h_x, h_y, h_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]` (SI units).
///
/// `m` is the mass \[kg\]. `h = m c` is the first mass moment \[kg m\], with `c` the centre of
/// mass in the body frame \[m\]. `I` is the rotational inertia about the body-frame **origin**,
/// expressed in body axes \[kg m²\] (Pinocchio's `toDynamicParameters` order). The vector is
/// stored as is: an estimate may be physically inconsistent, and the checks
/// ([`is_physically_consistent`](Self::is_physically_consistent),
/// [`safety_gate`](Self::safety_gate)) say so.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct InertialParams([f64; 10]);

/// Thresholds of the TAG-K paper's safety gate (docs/CONVENTIONS.md §1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SafetyGate {
    /// `L_arm`: largest allowed distance of the centre of mass from the body origin \[m\].
    pub max_com_offset: f64,
    /// `α`: largest allowed eigenvalue of the inertia about the origin \[kg m²\].
    pub max_inertia_eigenvalue: f64,
}

impl SafetyGate {
    /// The paper's thresholds for the Crazyflie: `L_arm = 0.0325 m`, `α = 1e-4 kg m²`.
    pub fn crazyflie() -> Self {
        Self {
            max_com_offset: crate::quadrotor::CRAZYFLIE_ARM_OFFSET,
            max_inertia_eigenvalue: 1e-4,
        }
    }

    /// The paper's gate scaled to another vehicle: `L_arm` is its airframe radius \[m\], and
    /// `α` keeps the Crazyflie's ratio to the largest eigenvalue of the inertia about the
    /// origin (`1e-4 / 2.93e-5 ≈ 3.4`) times the vehicle's, `nominal` \[kg m²\]. The
    /// Crazyflie's own numbers give [`SafetyGate::crazyflie`] (to rounding). A vehicle ten
    /// times heavier in inertia gets a ten times larger `α`: the paper's `1e-4` would refuse
    /// its every estimate.
    pub fn for_vehicle(airframe_radius: f64, nominal: &InertialParams) -> Self {
        let crazyflie = Self::crazyflie();
        let largest = |p: &InertialParams| p.inertia_origin().symmetric_eigenvalues().max();
        let ratio = crazyflie.max_inertia_eigenvalue
            / largest(&crate::quadrotor::QuadrotorModel::crazyflie_2_1().params);
        Self {
            max_com_offset: airframe_radius,
            max_inertia_eigenvalue: ratio * largest(nominal),
        }
    }
}

/// Why a parameter vector failed the [`SafetyGate`]; the first failed check is reported, in
/// the order finite, mass, centre of mass, inertia definiteness, inertia size.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum GateViolation {
    /// Some entry is NaN or infinite.
    #[error("parameters are not finite")]
    NonFinite,
    /// `m ≤ 0`.
    #[error("mass {mass} kg is not positive")]
    NonPositiveMass {
        /// The estimated mass \[kg\].
        mass: f64,
    },
    /// `‖c‖ > L_arm`.
    #[error("centre of mass is {offset} m from the origin (limit {limit} m)")]
    ComOffsetTooLarge {
        /// `‖c‖` \[m\].
        offset: f64,
        /// `L_arm` \[m\].
        limit: f64,
    },
    /// The inertia about the origin is not positive definite.
    #[error("inertia is not positive definite (smallest eigenvalue {min_eigenvalue:e} kg m^2)")]
    InertiaNotPositiveDefinite {
        /// Smallest eigenvalue of `I` \[kg m²\].
        min_eigenvalue: f64,
    },
    /// `λ_max(I) > α`.
    #[error("largest inertia eigenvalue {max_eigenvalue:e} kg m^2 exceeds {limit:e}")]
    InertiaEigenvalueTooLarge {
        /// Largest eigenvalue of `I` \[kg m²\].
        max_eigenvalue: f64,
        /// `α` \[kg m²\].
        limit: f64,
    },
}

/// Packs a symmetric matrix's six independent entries in the order of θ
/// `[I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]`.
#[inline]
fn pack_inertia(i: &Matrix3<f64>) -> [f64; 6] {
    [
        i[(0, 0)],
        i[(0, 1)],
        i[(1, 1)],
        i[(0, 2)],
        i[(1, 2)],
        i[(2, 2)],
    ]
}

impl InertialParams {
    /// All ten parameters zero (a massless body).
    pub const ZERO: Self = Self([0.0; 10]);

    /// Wraps a 10-vector in the order of `θ` (docs/CONVENTIONS.md §1); no checks: estimates
    /// may be inconsistent.
    pub const fn from_array(theta: [f64; 10]) -> Self {
        Self(theta)
    }

    /// Reads a 10-vector from a slice.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] unless `theta.len() == 10`.
    pub fn from_slice(theta: &[f64]) -> Result<Self, DynamicsError> {
        let arr: [f64; 10] = theta
            .try_into()
            .map_err(|_| DynamicsError::DimensionMismatch {
                what: "inertial parameter vector",
                expected: 10,
                got: theta.len(),
            })?;
        Ok(Self(arr))
    }

    /// The 10-vector in the order of `θ` (docs/CONVENTIONS.md §1).
    pub const fn to_array(&self) -> [f64; 10] {
        self.0
    }

    /// The 10-vector as a slice.
    pub fn as_slice(&self) -> &[f64] {
        &self.0
    }

    /// The 10-vector by reference.
    pub const fn as_array(&self) -> &[f64; 10] {
        &self.0
    }

    /// Builds θ from mass `m` \[kg\], first moment `h = m c` \[kg m\] and inertia about the body
    /// origin \[kg m²\] (only its upper triangle is read). No checks.
    pub fn from_mass_first_moment_inertia(
        mass: f64,
        first_moment: Vector3<f64>,
        inertia_origin: Matrix3<f64>,
    ) -> Self {
        let p = pack_inertia(&inertia_origin);
        Self([
            mass,
            first_moment.x,
            first_moment.y,
            first_moment.z,
            p[0],
            p[1],
            p[2],
            p[3],
            p[4],
            p[5],
        ])
    }

    /// Builds θ from mass `m` \[kg\], centre of mass `c` in the body frame \[m\] and the inertia
    /// about the centre of mass in body axes \[kg m²\], using `I_O = I_C + m (cᵀc·1 − c cᵀ)`.
    ///
    /// # Errors
    /// [`DynamicsError::NonFinite`] for NaN/∞ input, [`DynamicsError::NegativeMass`],
    /// [`DynamicsError::AsymmetricInertia`] if `I_C` is not symmetric (relative tolerance
    /// 1e-9), [`DynamicsError::InertiaNotPositiveSemiDefinite`] if `I_C` has an eigenvalue
    /// below `−1e-12·max|I_C|`. (The triangle inequalities are not enforced here; see
    /// [`is_physically_consistent`](Self::is_physically_consistent).)
    pub fn from_mass_com_inertia(
        mass: f64,
        com: Vector3<f64>,
        inertia_com: Matrix3<f64>,
    ) -> Result<Self, DynamicsError> {
        if !mass.is_finite() {
            return Err(DynamicsError::NonFinite { what: "mass" });
        }
        if !com.iter().all(|v| v.is_finite()) {
            return Err(DynamicsError::NonFinite {
                what: "centre of mass",
            });
        }
        if !inertia_com.iter().all(|v| v.is_finite()) {
            return Err(DynamicsError::NonFinite { what: "inertia" });
        }
        if mass < 0.0 {
            return Err(DynamicsError::NegativeMass { mass });
        }
        let scale = inertia_com.amax();
        let asymmetry = (inertia_com - inertia_com.transpose()).amax();
        if asymmetry > 1e-9 * scale {
            return Err(DynamicsError::AsymmetricInertia { asymmetry });
        }
        let sym = (inertia_com + inertia_com.transpose()) * 0.5;
        let min_eigenvalue = sym.symmetric_eigenvalues().min();
        if min_eigenvalue < -1e-12 * scale {
            return Err(DynamicsError::InertiaNotPositiveSemiDefinite { min_eigenvalue });
        }
        let inertia_origin = sym + parallel_axis(&com) * mass;
        Ok(Self::from_mass_first_moment_inertia(
            mass,
            com * mass,
            inertia_origin,
        ))
    }

    /// A point mass `mass` \[kg\] at `position` \[m, body frame\].
    pub fn point_mass(mass: f64, position: Vector3<f64>) -> Self {
        Self::from_mass_first_moment_inertia(mass, position * mass, parallel_axis(&position) * mass)
    }

    /// A homogeneous axis-aligned solid box of `mass` \[kg\], centred at `centre` \[m, body frame\],
    /// with full edge lengths `size` \[m\] along the body axes.
    pub fn solid_box(mass: f64, centre: Vector3<f64>, size: Vector3<f64>) -> Self {
        let s2 = size.component_mul(&size);
        let ic = Matrix3::from_diagonal(&Vector3::new(s2.y + s2.z, s2.x + s2.z, s2.x + s2.y))
            * (mass / 12.0);
        Self::from_mass_first_moment_inertia(
            mass,
            centre * mass,
            ic + parallel_axis(&centre) * mass,
        )
    }

    /// Mass `m` \[kg\].
    pub const fn mass(&self) -> f64 {
        self.0[0]
    }

    /// First mass moment `h = m c` \[kg m\], body frame.
    pub fn first_moment(&self) -> Vector3<f64> {
        Vector3::new(self.0[1], self.0[2], self.0[3])
    }

    /// Centre of mass `c = h / m` \[m\], body frame; the zero vector when `m == 0` (use
    /// [`try_com`](Self::try_com) to tell that case apart).
    pub fn com(&self) -> Vector3<f64> {
        self.try_com().unwrap_or_else(Vector3::zeros)
    }

    /// Centre of mass `c = h / m` \[m\], or `None` when `m == 0` or θ is not finite.
    pub fn try_com(&self) -> Option<Vector3<f64>> {
        let m = self.mass();
        (m != 0.0 && self.is_finite()).then(|| self.first_moment() / m)
    }

    /// Rotational inertia about the body origin, body axes \[kg m²\] (symmetric).
    pub fn inertia_origin(&self) -> Matrix3<f64> {
        let t = &self.0;
        Matrix3::new(t[4], t[5], t[7], t[5], t[6], t[8], t[7], t[8], t[9])
    }

    /// Rotational inertia about the centre of mass, body axes \[kg m²\]:
    /// `I_C = I_O − (hᵀh·1 − h hᵀ)/m`; equals `I_O` when `m == 0`.
    pub fn inertia_com(&self) -> Matrix3<f64> {
        let m = self.mass();
        if m == 0.0 {
            return self.inertia_origin();
        }
        self.inertia_origin() - parallel_axis(&self.first_moment()) / m
    }

    /// `true` when all ten entries are finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }

    /// This body with a point mass `mass` \[kg\] rigidly attached at `position` \[m, body frame\].
    pub fn with_point_mass(&self, mass: f64, position: Vector3<f64>) -> Self {
        *self + Self::point_mass(mass, position)
    }

    /// This body with a point mass `mass` \[kg\] at `position` \[m, body frame\] taken off (the
    /// exact inverse of [`with_point_mass`](Self::with_point_mass)).
    pub fn without_point_mass(&self, mass: f64, position: Vector3<f64>) -> Self {
        *self - Self::point_mass(mass, position)
    }

    /// This body with an axis-aligned solid box attached (see [`solid_box`](Self::solid_box)).
    pub fn with_box(&self, mass: f64, centre: Vector3<f64>, size: Vector3<f64>) -> Self {
        *self + Self::solid_box(mass, centre, size)
    }

    /// This body with an axis-aligned solid box taken off (inverse of [`with_box`](Self::with_box)).
    pub fn without_box(&self, mass: f64, centre: Vector3<f64>, size: Vector3<f64>) -> Self {
        *self - Self::solid_box(mass, centre, size)
    }

    /// The same body's parameters about another origin: `new_origin_offset` \[m\] is the new
    /// origin's position in the current body frame, axes unchanged. Mass is kept,
    /// `h' = h − m d`, and `I'` follows the parallel-axis rule (no division by `m`, so it is
    /// exact for any θ).
    pub fn shifted(&self, new_origin_offset: Vector3<f64>) -> Self {
        self.transformed(&Matrix3::identity(), &(-new_origin_offset))
    }

    /// The same body's parameters in another frame `F'`.
    ///
    /// A point `x` of the current frame has coordinates `x' = R x + p` in `F'`.
    /// `rotation` = `R` holds the current axes expressed in `F'`.
    /// `translation` = `p` \[m\] is the current origin in `F'`.
    /// Then `h' = R h + m p` and, with `g = R h`,
    /// `I' = R I Rᵀ + (2 pᵀg + m pᵀp)·1 − g pᵀ − p gᵀ − m p pᵀ`
    /// (expand `Σ m_i (x'ᵀx'·1 − x' x'ᵀ)` with `x' = R x + p`).
    pub fn transformed(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>) -> Self {
        let m = self.mass();
        let p = translation;
        let hr = rotation * self.first_moment();
        let ir = rotation * self.inertia_origin() * rotation.transpose();
        let cross = p * hr.transpose();
        let i_new = ir + Matrix3::identity() * (2.0 * p.dot(&hr) + m * p.norm_squared())
            - cross
            - cross.transpose()
            - p * p.transpose() * m;
        Self::from_mass_first_moment_inertia(m, hr + p * m, i_new)
    }

    /// The 4×4 pseudo-inertia `J = [[½ tr(I)·1 − I, h], [hᵀ, m]]` (Wensing, Kim & Slotine 2017);
    /// its upper-left block is the second moment `Σ = ∫ x xᵀ dm` about the origin \[kg m²\].
    pub fn pseudo_inertia(&self) -> Matrix4<f64> {
        let i = self.inertia_origin();
        let sigma = Matrix3::identity() * (0.5 * i.trace()) - i;
        let h = self.first_moment();
        let mut j = Matrix4::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
        j.fixed_view_mut::<3, 1>(0, 3).copy_from(&h);
        j.fixed_view_mut::<1, 3>(3, 0).copy_from(&h.transpose());
        j[(3, 3)] = self.mass();
        j
    }

    /// Inverse of [`pseudo_inertia`](Self::pseudo_inertia): `m = J₃₃`, `h = J₀..₂,₃`,
    /// `I = tr(Σ)·1 − Σ` with `Σ` the symmetrised upper-left block.
    pub fn from_pseudo_inertia(j: &Matrix4<f64>) -> Self {
        let s = j.fixed_view::<3, 3>(0, 0);
        let sigma = (s + s.transpose()) * 0.5;
        let h = (j.fixed_view::<3, 1>(0, 3) + j.fixed_view::<1, 3>(3, 0).transpose()) * 0.5;
        let i = Matrix3::identity() * sigma.trace() - sigma;
        Self::from_mass_first_moment_inertia(j[(3, 3)], h, i)
    }

    /// Smallest eigenvalue of the pseudo-inertia \[kg m²-ish units\], or `None` if θ is not
    /// finite. Positive iff the parameters are physically consistent.
    pub fn min_pseudo_inertia_eigenvalue(&self) -> Option<f64> {
        self.is_finite()
            .then(|| self.pseudo_inertia().symmetric_eigenvalues().min())
    }

    /// `true` iff θ is finite and the pseudo-inertia `J` is positive definite (a Cholesky
    /// factorisation of `J` succeeds), i.e. θ is realisable by a mass density with positive
    /// mass. Implies `m > 0`, `I_C ≻ 0` and the triangle inequalities on `I_C`.
    pub fn is_physically_consistent(&self) -> bool {
        self.is_finite() && self.pseudo_inertia().cholesky().is_some()
    }

    /// The TAG-K paper's safety gate: `m > 0`, `‖c‖ ≤ L_arm`, `I ≻ 0` and `λ_max(I) ≤ α`,
    /// where `I` is the inertia about the body origin (the one stored in θ).
    ///
    /// # Errors
    /// The first [`GateViolation`] found.
    pub fn safety_gate(&self, gate: &SafetyGate) -> Result<(), GateViolation> {
        if !self.is_finite() {
            return Err(GateViolation::NonFinite);
        }
        let m = self.mass();
        if m <= 0.0 {
            return Err(GateViolation::NonPositiveMass { mass: m });
        }
        let offset = (self.first_moment() / m).norm();
        if offset > gate.max_com_offset {
            return Err(GateViolation::ComOffsetTooLarge {
                offset,
                limit: gate.max_com_offset,
            });
        }
        let eig = self.inertia_origin().symmetric_eigenvalues();
        let (lo, hi) = (eig.min(), eig.max());
        if lo <= 0.0 {
            return Err(GateViolation::InertiaNotPositiveDefinite { min_eigenvalue: lo });
        }
        if hi > gate.max_inertia_eigenvalue {
            return Err(GateViolation::InertiaEigenvalueTooLarge {
                max_eigenvalue: hi,
                limit: gate.max_inertia_eigenvalue,
            });
        }
        Ok(())
    }

    /// Projects θ onto the physically consistent set by eigenvalue clipping of the
    /// pseudo-inertia: `J = V diag(λ) Vᵀ ↦ V diag(max(λ, ε)) Vᵀ`, then back to θ.
    ///
    /// This is the nearest matrix to `J` in the Frobenius norm among symmetric matrices with
    /// all eigenvalues `≥ ε`. So the result is consistent (strictly, for `ε > 0`). It is close to
    /// the estimate in the pseudo-inertia metric, not in the Euclidean θ metric. A θ that already
    /// has `λ_min(J) ≥ ε` is returned unchanged. `min_eigenvalue` is `ε` (units of `J`; it is
    /// clamped to `≥ 0`). Pick it well below the body's smallest second moment: e.g. `1e-9` for a
    /// Crazyflie, whose `Σ` eigenvalues are ≈ 1.6e-6 … 1.5e-5 kg m². Non-finite θ cannot be
    /// projected and is returned unchanged; it still fails
    /// [`is_physically_consistent`](Self::is_physically_consistent).
    pub fn project_to_consistent(&self, min_eigenvalue: f64) -> Self {
        if !self.is_finite() {
            return *self;
        }
        let eps = eigenvalue_floor(min_eigenvalue);
        let eig = self.pseudo_inertia().symmetric_eigen();
        if eig.eigenvalues.min() >= eps {
            return *self;
        }
        let clipped = eig.eigenvalues.map(|l| l.max(eps));
        let j = eig.eigenvectors * Matrix4::from_diagonal(&clipped) * eig.eigenvectors.transpose();
        Self::from_pseudo_inertia(&j)
    }
}

impl InertialParams {
    /// The physically consistent parameters nearest to θ in the metric of an information
    /// matrix `information` (`P`: the inverse of an estimate's covariance, SI units of θ).
    /// They minimise `(θ' − θ)ᵀ P (θ' − θ)` over θ' whose pseudo-inertia has every eigenvalue
    /// at least `min_eigenvalue` (`ε ≥ 0`, units of `J`). An `ε > 0` keeps θ' off the
    /// boundary, where the body would be flat and its spatial inertia singular. With `P` the inverse covariance of a least-squares estimate, it is the
    /// most likely consistent θ' under Gaussian errors: it moves an estimate most along the
    /// directions the data determine least.
    ///
    /// A θ whose smallest pseudo-inertia eigenvalue is at least `ε` is returned unchanged. The
    /// search runs over the Cholesky factor of the pseudo-inertia, `J = C Cᵀ + ε 1`
    /// (Levenberg–Marquardt from the eigenvalue clipping of
    /// [`project_to_consistent`](Self::project_to_consistent)).
    /// `P` is regularised by `1e-9` of its own diagonal, so that a singular `P` still has a
    /// unique answer. A parameter without information (a zero diagonal) is weighted like the
    /// least determined one, relative to the Frobenius metric of `J`. A non-finite θ or `P`
    /// falls back to [`project_to_consistent`](Self::project_to_consistent).
    pub fn nearest_consistent(&self, information: &[[f64; 10]; 10], min_eigenvalue: f64) -> Self {
        use nalgebra::{SMatrix, SVector};
        type M10 = SMatrix<f64, 10, 10>;
        type V10 = SVector<f64, 10>;
        if !self.is_finite() {
            return *self;
        }
        let eps = eigenvalue_floor(min_eigenvalue);
        if self.pseudo_inertia().symmetric_eigenvalues().min() >= eps {
            return *self;
        }
        let clipped = self.project_to_consistent(eps);
        let p = M10::from_fn(|i, j| 0.5 * (information[i][j] + information[j][i]));
        if !p.iter().all(|x| x.is_finite()) {
            return clipped;
        }
        // The Frobenius metric of J: ‖J(θ)‖²_F = θᵀ F θ (J is linear in θ).
        let unit = |k: usize| {
            let mut e = [0.0; 10];
            e[k] = 1.0;
            Self(e).pseudo_inertia()
        };
        let units: Vec<Matrix4<f64>> = (0..10).map(unit).collect();
        let frobenius = M10::from_fn(|i, j| units[i].dot(&units[j]));
        // A parameter without information (a zero diagonal) is weighted like the least
        // determined one is, relative to the Frobenius metric.
        let scale = (0..10)
            .filter(|&i| p[(i, i)] > 0.0)
            .map(|i| p[(i, i)] / frobenius[(i, i)])
            .fold(f64::INFINITY, f64::min);
        let scale = if scale.is_finite() { scale } else { 1.0 };
        let diagonal = V10::from_fn(|i, _| {
            if p[(i, i)] > 0.0 {
                p[(i, i)]
            } else {
                scale * frobenius[(i, i)]
            }
        });
        let metric = p + M10::from_diagonal(&diagonal) * 1e-9;
        let Some(chol) = metric.cholesky() else {
            return clipped;
        };
        let root = chol.l().transpose();
        let target = V10::from_column_slice(&self.0);
        // J = C Cᵀ, C lower triangular: its ten entries, row by row.
        const ENTRIES: [(usize, usize); 10] = [
            (0, 0),
            (1, 0),
            (1, 1),
            (2, 0),
            (2, 1),
            (2, 2),
            (3, 0),
            (3, 1),
            (3, 2),
            (3, 3),
        ];
        let factor = |x: &V10| {
            let mut c = Matrix4::zeros();
            for (k, &(i, j)) in ENTRIES.iter().enumerate() {
                c[(i, j)] = x[k];
            }
            c
        };
        let theta_of = |j: &Matrix4<f64>| V10::from_column_slice(&Self::from_pseudo_inertia(j).0);
        let lifted = Matrix4::identity() * eps;
        let residual = |x: &V10| {
            let c = factor(x);
            root * (theta_of(&(c * c.transpose() + lifted)) - target)
        };
        // The start: the Cholesky factor of the clipped J − ε 1, nudged inside the cone.
        let j0 = clipped.pseudo_inertia() - lifted;
        let nudge = 1e-12 * j0.symmetric_eigenvalues().amax().max(f64::MIN_POSITIVE);
        let Some(c0) = (j0 + Matrix4::identity() * nudge).cholesky() else {
            return clipped;
        };
        let c0 = c0.l();
        let mut x = V10::from_fn(|k, _| c0[ENTRIES[k]]);
        let mut r = residual(&x);
        let mut cost = r.norm_squared();
        let mut mu = 1e-3;
        for _ in 0..200 {
            let c = factor(&x);
            // ∂J/∂C_ab = E_ab Cᵀ + C E_ba; θ is linear in J.
            let mut jac = M10::zeros();
            for (k, &(a, b)) in ENTRIES.iter().enumerate() {
                let mut e = Matrix4::zeros();
                e[(a, b)] = 1.0;
                let dj = e * c.transpose() + c * e.transpose();
                jac.set_column(k, &(root * theta_of(&dj)));
            }
            let jtj = jac.transpose() * jac;
            let g = jac.transpose() * r;
            let mut improved = false;
            for _ in 0..30 {
                let damped =
                    jtj + M10::from_diagonal(&jtj.diagonal()) * mu + M10::identity() * (mu * 1e-30);
                let Some(step) = damped.cholesky().map(|f| f.solve(&(-g))) else {
                    mu *= 10.0;
                    continue;
                };
                let trial = x + step;
                let tr = residual(&trial);
                let tc = tr.norm_squared();
                if tc.is_finite() && tc < cost {
                    let done = cost - tc <= 1e-15 * cost;
                    (x, r, cost) = (trial, tr, tc);
                    mu = (mu * 0.3).max(1e-15);
                    improved = !done;
                    break;
                }
                mu *= 10.0;
            }
            if !improved {
                break;
            }
        }
        let c = factor(&x);
        Self::from_pseudo_inertia(&(c * c.transpose() + lifted))
    }
}

/// A smallest allowed pseudo-inertia eigenvalue as given, clamped to `≥ 0` (0 if not finite).
fn eigenvalue_floor(min_eigenvalue: f64) -> f64 {
    if min_eigenvalue.is_finite() {
        min_eigenvalue.max(0.0)
    } else {
        0.0
    }
}

impl From<[f64; 10]> for InertialParams {
    fn from(theta: [f64; 10]) -> Self {
        Self(theta)
    }
}

impl From<InertialParams> for [f64; 10] {
    fn from(theta: InertialParams) -> Self {
        theta.0
    }
}

impl Add for InertialParams {
    type Output = Self;
    /// Parameters of two bodies rigidly joined (both in the same frame).
    fn add(mut self, rhs: Self) -> Self {
        self += rhs;
        self
    }
}

impl AddAssign for InertialParams {
    fn add_assign(&mut self, rhs: Self) {
        for (a, b) in self.0.iter_mut().zip(rhs.0) {
            *a += b;
        }
    }
}

impl Sub for InertialParams {
    type Output = Self;
    /// Parameters with a rigidly attached part taken off (both in the same frame).
    fn sub(mut self, rhs: Self) -> Self {
        self -= rhs;
        self
    }
}

impl SubAssign for InertialParams {
    fn sub_assign(&mut self, rhs: Self) {
        for (a, b) in self.0.iter_mut().zip(rhs.0) {
            *a -= b;
        }
    }
}

impl Neg for InertialParams {
    type Output = Self;
    fn neg(self) -> Self {
        Self(self.0.map(|v| -v))
    }
}

impl Mul<f64> for InertialParams {
    type Output = Self;
    /// Scales every parameter (a body of the same shape with density scaled by `rhs`).
    fn mul(self, rhs: f64) -> Self {
        Self(self.0.map(|v| v * rhs))
    }
}
