//! The arm: a kinematic tree from a URDF and its joint limits.

use std::path::Path;

use tagk_dynamics::{JointEffects, KinematicTree, UrdfOptions};

use crate::SimError;

/// Position limits \[rad\] of a joint without any (continuous joints): `±π` around zero.
const CONTINUOUS_RANGE: f64 = std::f64::consts::PI;
/// Velocity limit \[rad/s\] of a joint whose URDF gives none.
const DEFAULT_VELOCITY_LIMIT: f64 = 2.0;
/// Effort limit \[N m\] of a joint whose URDF gives none.
const DEFAULT_EFFORT_LIMIT: f64 = 100.0;

/// Per-joint limits, in the tree's joint order.
#[derive(Debug, Clone, PartialEq)]
pub struct JointLimits {
    /// Lower position limit \[rad\] (m for a prismatic joint).
    pub lower: Vec<f64>,
    /// Upper position limit \[rad\].
    pub upper: Vec<f64>,
    /// Largest speed \[rad/s\].
    pub velocity: Vec<f64>,
    /// Largest torque \[N m\]; the simulator saturates the command there.
    pub effort: Vec<f64>,
}

/// A fixed-base arm: its kinematic tree (nominal inertial parameters) and its joint limits.
///
/// The last body in joint order carries the flange. A payload attaches to it.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmModel {
    /// The rigid-body model with the URDF's (nominal) inertial parameters.
    pub tree: KinematicTree,
    /// The joint limits.
    pub limits: JointLimits,
}

impl ArmModel {
    /// An arm from a tree and its limits.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] if a limit vector's length differs from the joints',
    /// a limit is not finite, `lower ≥ upper`, or a velocity or effort limit is not positive.
    pub fn new(tree: KinematicTree, limits: JointLimits) -> Result<Self, SimError> {
        let n = tree.dof();
        for v in [
            &limits.lower,
            &limits.upper,
            &limits.velocity,
            &limits.effort,
        ] {
            if v.len() != n {
                return Err(SimError::InvalidParameter {
                    name: "joint limits length",
                    value: v.len() as f64,
                    reason: "one limit per joint",
                });
            }
        }
        for j in 0..n {
            let (lo, hi) = (limits.lower[j], limits.upper[j]);
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(SimError::InvalidParameter {
                    name: "joint position limits",
                    value: hi - lo,
                    reason: "finite, lower < upper",
                });
            }
            for (name, v) in [
                ("joint velocity limit", limits.velocity[j]),
                ("joint effort limit", limits.effort[j]),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(SimError::InvalidParameter {
                        name,
                        value: v,
                        reason: "positive and finite",
                    });
                }
            }
        }
        Ok(Self { tree, limits })
    }

    /// Reads an arm from URDF text: the tree, and each movable joint's `<limit>`.
    ///
    /// A continuous joint gets `±π`. A missing velocity or effort limit becomes 2 rad/s or
    /// 100 N m. Locked joints (`options`) are welded, as in the tree.
    ///
    /// # Errors
    /// [`SimError::Dynamics`] for a URDF the tree loader rejects; [`SimError::InvalidParameter`]
    /// for unusable limits.
    pub fn from_urdf_str(urdf: &str, options: &UrdfOptions) -> Result<Self, SimError> {
        let tree = KinematicTree::from_urdf_str_with(urdf, options)?;
        let n = tree.dof();
        let mut limits = JointLimits {
            lower: Vec::with_capacity(n),
            upper: Vec::with_capacity(n),
            velocity: Vec::with_capacity(n),
            effort: Vec::with_capacity(n),
        };
        for body in tree.bodies() {
            let l = body.limit();
            let (lo, hi, vel, eff) = (l.lower, l.upper, l.velocity, l.effort);
            // A continuous joint has no position limits: it gets ±π.
            let continuous = body.kind() == tagk_dynamics::JointKind::Continuous;
            let (lo, hi) = if lo < hi && !continuous {
                (lo, hi)
            } else {
                (-CONTINUOUS_RANGE, CONTINUOUS_RANGE)
            };
            limits.lower.push(lo);
            limits.upper.push(hi);
            limits.velocity.push(if vel > 0.0 {
                vel
            } else {
                DEFAULT_VELOCITY_LIMIT
            });
            limits
                .effort
                .push(if eff > 0.0 { eff } else { DEFAULT_EFFORT_LIMIT });
        }
        Self::new(tree, limits)
    }

    /// Reads an arm from a URDF file (see [`from_urdf_str`](Self::from_urdf_str)).
    ///
    /// # Errors
    /// [`SimError::Io`] for an unreadable file, otherwise as
    /// [`from_urdf_str`](Self::from_urdf_str).
    pub fn from_urdf_file(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Self, SimError> {
        let text = std::fs::read_to_string(path)?;
        Self::from_urdf_str(&text, options)
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.tree.dof()
    }

    /// Index of the flange body (the last body in joint order).
    pub fn flange(&self) -> usize {
        self.tree.dof() - 1
    }

    /// The middle of each joint's range \[rad\], clamped to `±π/2`: a home posture.
    pub fn home(&self) -> Vec<f64> {
        let h = std::f64::consts::FRAC_PI_2;
        (0..self.dof())
            .map(|j| (0.5 * (self.limits.lower[j] + self.limits.upper[j])).clamp(-h, h))
            .collect()
    }

    /// Typical joint effects of a geared arm, scaled by each joint's effort limit `τ_max`.
    ///
    /// Viscous friction `0.01 τ_max` N m s/rad, Coulomb friction `0.01 τ_max` N m, armature
    /// `0.002 τ_max` kg m², no offset. For a UR5's 150 N m joints: 1.5, 1.5 and 0.3.
    pub fn typical_effects(&self) -> JointEffects {
        let mut e = JointEffects::none(self.dof());
        for (j, &eff) in self.limits.effort.iter().enumerate() {
            e.viscous[j] = 0.01 * eff;
            e.coulomb[j] = 0.01 * eff;
            e.armature[j] = 0.002 * eff;
        }
        e
    }
}
