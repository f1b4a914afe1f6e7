//! The arm's plant: rigid-body forward dynamics with joint effects and a flange payload.

use nalgebra::DVector;
use tagk_dynamics::{DynamicsError, InertialParams, JointEffects, KinematicTree};

use crate::SimError;

/// Joint positions \[rad\] and velocities \[rad/s\] of an arm.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmState {
    /// Joint positions `q` \[rad\].
    pub q: Vec<f64>,
    /// Joint velocities `q̇` \[rad/s\].
    pub qd: Vec<f64>,
}

/// The true arm: its rigid bodies, its joint effects and the payload at the flange.
///
/// Its motion is `(M(q) + diag(a)) q̈ = τ − h(q, q̇) − τ_v(q̇)`. Here `a` is the armature and
/// `τ_v` the velocity part of the [`JointEffects`] (friction, offset). `M` and `h` come from
/// the tree's mass matrix and bias forces with the true parameters.
#[derive(Debug, Clone)]
pub struct ArmPlant {
    tree: KinematicTree,
    links: Vec<InertialParams>,
    effects: JointEffects,
    payload: Option<InertialParams>,
}

impl ArmPlant {
    /// A plant with the tree's parameters as the links' truth, these effects and no payload.
    ///
    /// # Errors
    /// [`SimError::Dynamics`] if the effects are not one per joint.
    pub fn new(tree: KinematicTree, effects: JointEffects) -> Result<Self, SimError> {
        if effects.dof() != tree.dof() {
            return Err(DynamicsError::DimensionMismatch {
                what: "joint effects",
                expected: tree.dof(),
                got: effects.dof(),
            }
            .into());
        }
        // Checks every effect vector and finiteness.
        effects.torque(&vec![0.0; tree.dof()], &vec![0.0; tree.dof()])?;
        let links = tree.params();
        Ok(Self {
            tree,
            links,
            effects,
            payload: None,
        })
    }

    /// The rigid-body model with the true parameters (payload included).
    pub fn tree(&self) -> &KinematicTree {
        &self.tree
    }

    /// The joint effects of the plant.
    pub fn effects(&self) -> &JointEffects {
        &self.effects
    }

    /// The payload now at the flange, in the flange body's frame (`None`: empty).
    pub fn payload(&self) -> Option<&InertialParams> {
        self.payload.as_ref()
    }

    /// Grasps a payload (its parameters in the flange body's frame, about that body's
    /// origin) or releases it (`None`). The flange body's parameters become link + payload.
    ///
    /// # Errors
    /// [`SimError::Dynamics`] for non-finite payload parameters.
    pub fn set_payload(&mut self, payload: Option<InertialParams>) -> Result<(), SimError> {
        let mut params = self.links.clone();
        if let Some(p) = payload {
            let last = params.len() - 1;
            let sum: Vec<f64> = params[last]
                .as_slice()
                .iter()
                .zip(p.as_slice())
                .map(|(a, b)| a + b)
                .collect();
            params[last] = InertialParams::from_slice(&sum)?;
        }
        self.tree.set_params(&params)?;
        self.payload = payload;
        Ok(())
    }

    /// The true parameters of every body, stacked (`10·n` values, payload included).
    pub fn params_vector(&self) -> DVector<f64> {
        self.tree.params_vector()
    }

    /// Joint accelerations `q̈` \[rad/s²\] under joint torques `tau` \[N m\].
    ///
    /// # Errors
    /// [`SimError::Dynamics`] for bad inputs or a mass matrix that is not positive definite.
    pub fn acceleration(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
    ) -> Result<DVector<f64>, SimError> {
        let n = self.tree.dof();
        if tau.len() != n {
            return Err(DynamicsError::DimensionMismatch {
                what: "tau",
                expected: n,
                got: tau.len(),
            }
            .into());
        }
        let mut m = self.tree.mass_matrix(q)?;
        for j in 0..n {
            m[(j, j)] += self.effects.armature[j];
        }
        let rhs = DVector::from_column_slice(tau)
            - self.tree.bias_forces(q, qd)?
            - self.effects.velocity_torque(qd)?;
        let chol = m.cholesky().ok_or(DynamicsError::SingularMassMatrix)?;
        let qdd = chol.solve(&rhs);
        if qdd.iter().any(|x| !x.is_finite()) {
            return Err(DynamicsError::NonFinite {
                what: "joint acceleration",
            }
            .into());
        }
        Ok(qdd)
    }

    /// One classical Runge–Kutta (RK4) step of `dt` \[s\] with the torque held constant.
    ///
    /// Returns the acceleration at the step's start \[rad/s²\] (what a log records).
    ///
    /// # Errors
    /// As [`acceleration`](Self::acceleration); [`SimError::InvalidDuration`] for a bad `dt`.
    pub fn step_rk4(
        &self,
        state: &mut ArmState,
        tau: &[f64],
        dt: f64,
    ) -> Result<DVector<f64>, SimError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::InvalidDuration {
                what: "arm time step",
                value: dt,
            });
        }
        let n = state.q.len();
        let q0 = DVector::from_column_slice(&state.q);
        let v0 = DVector::from_column_slice(&state.qd);
        let a1 = self.acceleration(&state.q, &state.qd, tau)?;
        let q2 = &q0 + &v0 * (0.5 * dt);
        let v2 = &v0 + &a1 * (0.5 * dt);
        let a2 = self.acceleration(q2.as_slice(), v2.as_slice(), tau)?;
        let q3 = &q0 + &v2 * (0.5 * dt);
        let v3 = &v0 + &a2 * (0.5 * dt);
        let a3 = self.acceleration(q3.as_slice(), v3.as_slice(), tau)?;
        let q4 = &q0 + &v3 * dt;
        let v4 = &v0 + &a3 * dt;
        let a4 = self.acceleration(q4.as_slice(), v4.as_slice(), tau)?;
        for j in 0..n {
            state.q[j] = q0[j] + dt / 6.0 * (v0[j] + 2.0 * v2[j] + 2.0 * v3[j] + v4[j]);
            state.qd[j] = v0[j] + dt / 6.0 * (a1[j] + 2.0 * a2[j] + 2.0 * a3[j] + a4[j]);
        }
        Ok(a1)
    }
}
