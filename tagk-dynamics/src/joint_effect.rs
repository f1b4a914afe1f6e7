//! Joint-space effects that a rigid-body model of an arm leaves out.
//!
//! The arm simulator puts them into its plant, and the joint-torque diagnosis fits them.
//! Both read the closed forms here, so the two cannot disagree.
//!
//! Sign convention: the torque a joint's motor delivers is
//! `τ = M(q) q̈ + h(q, q̇) + τ_e(q̇, q̈)`, where `M q̈ + h = Y(q, q̇, q̈) θ` is the rigid body
//! ([`KinematicTree::joint_torque_regressor`](crate::KinematicTree::joint_torque_regressor)).
//! Every effect is diagonal: joint `j`'s term depends on joint `j`'s motion only.
//!
//! | effect | term on joint `j` | coefficient unit |
//! |---|---|---|
//! | `viscous-friction` | `b_j q̇_j` | N m s/rad |
//! | `coulomb-friction` | `c_j tanh(q̇_j / v_c)` | N m |
//! | `armature` | `a_j q̈_j` | kg m² |
//! | `torque-offset` | `o_j` | N m |
//!
//! Units are for revolute joints; a prismatic joint reads N for N m and m for rad.
//! The Coulomb term is smoothed over [`COULOMB_VELOCITY_SCALE`] so that a simulated arm can
//! pass through zero velocity. A payload is no effect of its own here: it changes the last
//! link's inertial parameters.

use core::fmt;
use core::str::FromStr;

use nalgebra::DVector;

use crate::DynamicsError;

/// Velocity scale `v_c` \[rad/s\] of the smoothed Coulomb friction `c tanh(q̇ / v_c)`.
///
/// At `|q̇| = 3 v_c` the term is within 0.5 % of `±c`.
pub const COULOMB_VELOCITY_SCALE: f64 = 0.01;

/// A joint-space effect missing from the rigid-body model of an arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum JointEffectKind {
    /// Viscous friction `b_j q̇_j` \[N m s/rad\].
    ViscousFriction,
    /// Coulomb friction `c_j tanh(q̇_j / v_c)` \[N m\].
    CoulombFriction,
    /// Armature (reflected rotor inertia) `a_j q̈_j` \[kg m²\].
    Armature,
    /// A constant torque offset `o_j` \[N m\] (sensor or current offset).
    TorqueOffset,
}

/// A joint-effect name that is not in the vocabulary.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown joint effect `{name}` (known: viscous-friction, coulomb-friction, armature, torque-offset)"
)]
pub struct UnknownJointEffect {
    /// The name as given.
    pub name: String,
}

impl JointEffectKind {
    /// Every joint effect, in the order of [`JointEffects`]' fields.
    pub const ALL: [JointEffectKind; 4] = [
        JointEffectKind::ViscousFriction,
        JointEffectKind::CoulombFriction,
        JointEffectKind::Armature,
        JointEffectKind::TorqueOffset,
    ];

    /// The kebab-case name used on the command line and in files.
    pub const fn name(self) -> &'static str {
        match self {
            JointEffectKind::ViscousFriction => "viscous-friction",
            JointEffectKind::CoulombFriction => "coulomb-friction",
            JointEffectKind::Armature => "armature",
            JointEffectKind::TorqueOffset => "torque-offset",
        }
    }

    /// The unit of the coefficient for a revolute joint.
    pub const fn unit(self) -> &'static str {
        match self {
            JointEffectKind::ViscousFriction => "N m s/rad",
            JointEffectKind::CoulombFriction => "N m",
            JointEffectKind::Armature => "kg m^2",
            JointEffectKind::TorqueOffset => "N m",
        }
    }

    /// The effect of a name.
    ///
    /// # Errors
    /// [`UnknownJointEffect`] for a name outside the vocabulary.
    pub fn from_name(name: &str) -> Result<Self, UnknownJointEffect> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| UnknownJointEffect {
                name: name.to_owned(),
            })
    }

    /// The regressor column of one joint: its torque \[N m\] per unit coefficient.
    ///
    /// `qd` is the joint velocity \[rad/s\], `qdd` its acceleration \[rad/s²\].
    pub fn column(self, qd: f64, qdd: f64) -> f64 {
        match self {
            JointEffectKind::ViscousFriction => qd,
            JointEffectKind::CoulombFriction => (qd / COULOMB_VELOCITY_SCALE).tanh(),
            JointEffectKind::Armature => qdd,
            JointEffectKind::TorqueOffset => 1.0,
        }
    }
}

impl fmt::Display for JointEffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for JointEffectKind {
    type Err = UnknownJointEffect;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s)
    }
}

/// Per-joint coefficients of every joint effect; zero means absent.
#[derive(Debug, Clone, PartialEq)]
pub struct JointEffects {
    /// Viscous friction `b_j` per joint \[N m s/rad\].
    pub viscous: Vec<f64>,
    /// Coulomb friction `c_j` per joint \[N m\].
    pub coulomb: Vec<f64>,
    /// Armature `a_j` per joint \[kg m²\].
    pub armature: Vec<f64>,
    /// Torque offset `o_j` per joint \[N m\].
    pub offset: Vec<f64>,
}

impl JointEffects {
    /// No effect on any of `dof` joints.
    pub fn none(dof: usize) -> Self {
        Self {
            viscous: vec![0.0; dof],
            coulomb: vec![0.0; dof],
            armature: vec![0.0; dof],
            offset: vec![0.0; dof],
        }
    }

    /// The number of joints.
    pub fn dof(&self) -> usize {
        self.viscous.len()
    }

    /// The coefficients of one effect, one per joint.
    pub fn coefficients(&self, kind: JointEffectKind) -> &[f64] {
        match kind {
            JointEffectKind::ViscousFriction => &self.viscous,
            JointEffectKind::CoulombFriction => &self.coulomb,
            JointEffectKind::Armature => &self.armature,
            JointEffectKind::TorqueOffset => &self.offset,
        }
    }

    /// The coefficients of one effect, mutable.
    pub fn coefficients_mut(&mut self, kind: JointEffectKind) -> &mut [f64] {
        match kind {
            JointEffectKind::ViscousFriction => &mut self.viscous,
            JointEffectKind::CoulombFriction => &mut self.coulomb,
            JointEffectKind::Armature => &mut self.armature,
            JointEffectKind::TorqueOffset => &mut self.offset,
        }
    }

    /// The effects' torque `τ_e(q̇, q̈)` \[N m\] on every joint.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] if a vector's length differs from the joints',
    /// [`DynamicsError::NonFinite`] for a non-finite input.
    pub fn torque(&self, qd: &[f64], qdd: &[f64]) -> Result<DVector<f64>, DynamicsError> {
        self.check(qd, qdd)?;
        Ok(DVector::from_iterator(
            self.dof(),
            (0..self.dof()).map(|j| {
                JointEffectKind::ALL
                    .into_iter()
                    .map(|k| self.coefficients(k)[j] * k.column(qd[j], qdd[j]))
                    .sum::<f64>()
            }),
        ))
    }

    /// The part of the torque that does not depend on `q̈` \[N m\] (all but the armature).
    ///
    /// A forward-dynamics step adds the armature to the mass matrix's diagonal instead.
    ///
    /// # Errors
    /// As [`torque`](Self::torque).
    pub fn velocity_torque(&self, qd: &[f64]) -> Result<DVector<f64>, DynamicsError> {
        let mut e = self.clone();
        e.armature.fill(0.0);
        e.torque(qd, &vec![0.0; qd.len()])
    }

    fn check(&self, qd: &[f64], qdd: &[f64]) -> Result<(), DynamicsError> {
        let n = self.dof();
        for (what, len) in [
            ("coulomb", self.coulomb.len()),
            ("armature", self.armature.len()),
            ("offset", self.offset.len()),
            ("qd", qd.len()),
            ("qdd", qdd.len()),
        ] {
            if len != n {
                return Err(DynamicsError::DimensionMismatch {
                    what,
                    expected: n,
                    got: len,
                });
            }
        }
        let all = [
            &self.viscous[..],
            &self.coulomb,
            &self.armature,
            &self.offset,
            qd,
            qdd,
        ];
        if all.iter().any(|v| v.iter().any(|x| !x.is_finite())) {
            return Err(DynamicsError::NonFinite {
                what: "joint effect input",
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_is_an_error() {
        for k in JointEffectKind::ALL {
            assert_eq!(k.name().parse::<JointEffectKind>().unwrap(), k);
        }
        assert!("stiction".parse::<JointEffectKind>().is_err());
    }

    #[test]
    fn torque_matches_hand_computation() {
        let mut e = JointEffects::none(2);
        e.viscous = vec![0.5, 0.0];
        e.coulomb = vec![0.0, 2.0];
        e.armature = vec![0.1, 0.2];
        e.offset = vec![-0.3, 0.4];
        let t = e.torque(&[2.0, -1.0], &[3.0, 4.0]).unwrap();
        // Joint 0: 0.5·2 + 0.1·3 − 0.3; joint 1: 2·tanh(−100) + 0.2·4 + 0.4.
        assert!((t[0] - 1.0).abs() < 1e-15);
        assert!((t[1] - (-2.0 * 100f64.tanh() + 1.2)).abs() < 1e-15);
        let v = e.velocity_torque(&[2.0, -1.0]).unwrap();
        assert!((v[0] - 0.7).abs() < 1e-15);
    }

    #[test]
    fn bad_lengths_and_nan_are_errors() {
        let e = JointEffects::none(2);
        assert!(matches!(
            e.torque(&[0.0], &[0.0, 0.0]),
            Err(DynamicsError::DimensionMismatch { .. })
        ));
        assert!(matches!(
            e.torque(&[f64::NAN, 0.0], &[0.0, 0.0]),
            Err(DynamicsError::NonFinite { .. })
        ));
    }
}
