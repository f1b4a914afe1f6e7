//! Fixed-base kinematic trees (serial chains and branched arms) with one-DoF revolute or
//! prismatic joints: forward kinematics, recursive Newton–Euler inverse dynamics, the
//! joint-torque regressor `τ = Y(q, q̇, q̈) θ`, mass matrix, forward dynamics and energies.
//!
//! Each moving body is the rigid union of the URDF link attached by a movable joint and every link
//! welded to it by fixed joints. Its frame is that child link's frame (= the joint frame), its
//! inertial parameters are in that frame about its origin (docs/CONVENTIONS.md §1), and bodies are
//! numbered in depth-first preorder (a parent before its children, each subtree contiguous).
//! `q[i]`, `τ[i]` belong to the joint of body `i`. Gravity is a vector in the base frame.

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, SMatrix, Translation3, UnitQuaternion, Vector3, Vector6,
};

use crate::math::axis_angle;
use crate::{DynamicsError, InertialParams, newton_euler, rigid_body_regressor};

/// The kind of a movable joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum JointKind {
    /// Rotation about the axis \[rad\], with position limits in the URDF (not enforced here).
    Revolute,
    /// Rotation about the axis \[rad\] without limits.
    Continuous,
    /// Translation along the axis \[m\].
    Prismatic,
}

impl JointKind {
    /// `true` for revolute and continuous joints.
    pub fn is_rotational(self) -> bool {
        !matches!(self, JointKind::Prismatic)
    }
}

/// A rigid transform: `x_parent = rotation · x_child + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pose {
    /// Child axes expressed in the parent frame.
    pub rotation: Matrix3<f64>,
    /// Child origin in the parent frame \[m\].
    pub translation: Vector3<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// `self ∘ other`: the pose of `other`'s child frame in `self`'s parent frame.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Maps a point from the child frame to the parent frame \[m\].
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    /// The same transform as an nalgebra isometry.
    pub fn to_isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation),
            UnitQuaternion::from_matrix(&self.rotation),
        )
    }
}

/// A joint's `<limit>` as the URDF states it.
///
/// A continuous joint's URDF has no position limits: `lower` and `upper` are then both 0.
/// A missing velocity or effort limit reads 0.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointLimit {
    /// Lower position limit \[rad\] (m for a prismatic joint).
    pub lower: f64,
    /// Upper position limit \[rad\] (m for a prismatic joint).
    pub upper: f64,
    /// Largest speed \[rad/s\] (m/s for a prismatic joint).
    pub velocity: f64,
    /// Largest effort \[N m\] (N for a prismatic joint).
    pub effort: f64,
}

/// One moving body of a [`KinematicTree`] and the joint that carries it.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    pub(crate) link: String,
    pub(crate) joint: String,
    pub(crate) kind: JointKind,
    pub(crate) parent: Option<usize>,
    pub(crate) tree: Pose,
    pub(crate) axis: Vector3<f64>,
    pub(crate) params: InertialParams,
    pub(crate) merged_links: Vec<String>,
    pub(crate) mimic: Option<String>,
    pub(crate) limit: JointLimit,
}

impl Body {
    /// Name of the URDF link whose frame is this body's frame.
    pub fn link(&self) -> &str {
        &self.link
    }

    /// Name of the joint that carries this body.
    pub fn joint(&self) -> &str {
        &self.joint
    }

    /// Kind of that joint.
    pub fn kind(&self) -> JointKind {
        self.kind
    }

    /// Index of the parent body, `None` for a body attached to the fixed base.
    pub fn parent(&self) -> Option<usize> {
        self.parent
    }

    /// Joint frame in the parent body's frame at `q = 0` (URDF joint origin, composed with
    /// any fixed joints in between).
    pub fn tree_pose(&self) -> &Pose {
        &self.tree
    }

    /// Unit joint axis in the body (joint) frame.
    pub fn axis(&self) -> &Vector3<f64> {
        &self.axis
    }

    /// Nominal inertial parameters in the body frame about its origin.
    pub fn params(&self) -> &InertialParams {
        &self.params
    }

    /// URDF links welded to this body by fixed (or locked) joints, whose inertials were merged.
    pub fn merged_links(&self) -> &[String] {
        &self.merged_links
    }

    /// The joint this one mimics in the URDF, if any. The coupling is **not** enforced: every
    /// joint is an independent coordinate.
    pub fn mimic(&self) -> Option<&str> {
        self.mimic.as_deref()
    }

    /// The joint's limits from the URDF (not enforced by the dynamics).
    pub fn limit(&self) -> &JointLimit {
        &self.limit
    }
}

/// Preallocated scratch space for the allocation-free `*_into` methods of a [`KinematicTree`];
/// get one from [`KinematicTree::workspace`].
#[derive(Debug, Clone)]
pub struct TreeWorkspace {
    pose: Vec<Pose>,
    omega: Vec<Vector3<f64>>,
    omega_dot: Vec<Vector3<f64>>,
    accel: Vec<Vector3<f64>>,
    force: Vec<Vector3<f64>>,
    torque: Vec<Vector3<f64>>,
    regressor: Vec<SMatrix<f64, 6, 10>>,
    zeta: Vec<Vector6<f64>>,
}

impl TreeWorkspace {
    fn new(n: usize) -> Self {
        Self {
            pose: vec![Pose::identity(); n],
            omega: vec![Vector3::zeros(); n],
            omega_dot: vec![Vector3::zeros(); n],
            accel: vec![Vector3::zeros(); n],
            force: vec![Vector3::zeros(); n],
            torque: vec![Vector3::zeros(); n],
            regressor: vec![SMatrix::zeros(); n],
            zeta: vec![Vector6::zeros(); n],
        }
    }

    fn bodies(&self) -> usize {
        self.pose.len()
    }
}

/// Where a URDF link sits: the body it belongs to (`None`: welded to the base) and its fixed
/// pose in that body's frame.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinkPlacement {
    pub(crate) name: String,
    pub(crate) body: Option<usize>,
    pub(crate) pose: Pose,
}

/// A fixed-base kinematic tree of one-DoF joints (see the [module docs](self)). Build one
/// from URDF with [`KinematicTree::from_urdf_str`] or [`KinematicTree::from_urdf_file`].
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicTree {
    pub(crate) name: String,
    pub(crate) base_link: String,
    pub(crate) bodies: Vec<Body>,
    pub(crate) subtree_end: Vec<usize>,
    pub(crate) gravity: Vector3<f64>,
    pub(crate) links: Vec<LinkPlacement>,
    pub(crate) base_params: InertialParams,
}

impl KinematicTree {
    #[cfg(feature = "urdf")]
    /// Assembles a tree from bodies in depth-first preorder (the URDF loader's output).
    pub(crate) fn from_parts(
        name: String,
        base_link: String,
        bodies: Vec<Body>,
        links: Vec<LinkPlacement>,
        base_params: InertialParams,
    ) -> Self {
        let n = bodies.len();
        let mut subtree_end: Vec<usize> = (1..=n).collect();
        for i in (0..n).rev() {
            if let Some(p) = bodies[i].parent {
                subtree_end[p] = subtree_end[p].max(subtree_end[i]);
            }
        }
        Self {
            name,
            base_link,
            bodies,
            subtree_end,
            gravity: crate::GRAVITY_WORLD,
            links,
            base_params,
        }
    }

    /// The robot's name from the URDF.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The fixed root link.
    pub fn base_link(&self) -> &str {
        &self.base_link
    }

    /// Number of joint coordinates (= number of moving bodies).
    pub fn dof(&self) -> usize {
        self.bodies.len()
    }

    /// Number of moving bodies.
    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// Number of inertial parameters, `10 · n_bodies`.
    pub fn n_params(&self) -> usize {
        10 * self.bodies.len()
    }

    /// The moving bodies in joint-coordinate order.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The body a payload held by the robot attaches to: the deepest body that carries every
    /// leaf of the tree. For a serial arm that is its last body. For an arm with a two-finger
    /// gripper it is the hand's body, from which both fingers hang. It is the last body when
    /// no body carries every leaf (two chains from the base). `None` without moving bodies.
    pub fn payload_body(&self) -> Option<usize> {
        let n = self.bodies.len();
        let first_leaf = (0..n).find(|&i| self.subtree_end[i] == i + 1)?;
        // Subtrees are index ranges `[i, subtree_end[i])`; the last body is always a leaf.
        (0..=first_leaf)
            .rev()
            .find(|&i| self.subtree_end[i] == n)
            .or(Some(n - 1))
    }

    /// Joint names in coordinate order.
    pub fn joint_names(&self) -> Vec<&str> {
        self.bodies.iter().map(|b| b.joint.as_str()).collect()
    }

    /// Gravity in the base frame \[m/s²\] (default `(0, 0, −9.81)`).
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }

    /// Sets gravity in the base frame \[m/s²\].
    pub fn set_gravity(&mut self, gravity: Vector3<f64>) {
        self.gravity = gravity;
    }

    /// This chain with another gravity vector \[m/s², base frame\].
    pub fn with_gravity(mut self, gravity: Vector3<f64>) -> Self {
        self.gravity = gravity;
        self
    }

    /// Merged inertial parameters of the links welded to the fixed base (base-link frame).
    /// They do not enter the joint torques.
    pub fn base_params(&self) -> &InertialParams {
        &self.base_params
    }

    /// Nominal inertial parameters of every body, in coordinate order.
    pub fn params(&self) -> Vec<InertialParams> {
        self.bodies.iter().map(|b| b.params).collect()
    }

    /// Nominal parameters stacked into one `10·n_bodies` vector (the `θ` of `τ = Y θ`).
    pub fn params_vector(&self) -> DVector<f64> {
        DVector::from_iterator(
            self.n_params(),
            self.bodies.iter().flat_map(|b| b.params.to_array()),
        )
    }

    /// Replaces the nominal parameters (one entry per body, in coordinate order).
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] for a wrong count, [`DynamicsError::NonFinite`]
    /// for NaN/∞ entries.
    pub fn set_params(&mut self, params: &[InertialParams]) -> Result<(), DynamicsError> {
        self.check_params(params)?;
        for (b, p) in self.bodies.iter_mut().zip(params) {
            b.params = *p;
        }
        Ok(())
    }

    /// Scratch space for the `*_into` methods.
    pub fn workspace(&self) -> TreeWorkspace {
        TreeWorkspace::new(self.bodies.len())
    }

    // ----------------------------------------------------------------------------- checks

    fn check_vec(&self, what: &'static str, v: &[f64]) -> Result<(), DynamicsError> {
        if v.len() != self.dof() {
            return Err(DynamicsError::DimensionMismatch {
                what,
                expected: self.dof(),
                got: v.len(),
            });
        }
        if !v.iter().all(|x| x.is_finite()) {
            return Err(DynamicsError::NonFinite { what });
        }
        Ok(())
    }

    fn check_params(&self, params: &[InertialParams]) -> Result<(), DynamicsError> {
        if params.len() != self.n_bodies() {
            return Err(DynamicsError::DimensionMismatch {
                what: "body parameters",
                expected: self.n_bodies(),
                got: params.len(),
            });
        }
        if !params.iter().all(InertialParams::is_finite) {
            return Err(DynamicsError::NonFinite {
                what: "body parameters",
            });
        }
        Ok(())
    }

    fn check_workspace(&self, ws: &TreeWorkspace) -> Result<(), DynamicsError> {
        if ws.bodies() != self.n_bodies() {
            return Err(DynamicsError::DimensionMismatch {
                what: "workspace",
                expected: self.n_bodies(),
                got: ws.bodies(),
            });
        }
        Ok(())
    }

    // ------------------------------------------------------------------------- kinematics

    /// Pose of body `i`'s frame in its parent's frame at joint position `qi`.
    #[inline]
    fn joint_pose(&self, i: usize, qi: f64) -> Pose {
        let b = &self.bodies[i];
        if b.kind.is_rotational() {
            Pose {
                rotation: b.tree.rotation * axis_angle(&b.axis, qi),
                translation: b.tree.translation,
            }
        } else {
            Pose {
                rotation: b.tree.rotation,
                translation: b.tree.translation + b.tree.rotation * b.axis * qi,
            }
        }
    }

    /// Pose of every body frame in the base frame at joint positions `q`.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] / [`DynamicsError::NonFinite`] for bad `q`.
    pub fn forward_kinematics(&self, q: &[f64]) -> Result<Vec<Pose>, DynamicsError> {
        self.check_vec("q", q)?;
        let mut out: Vec<Pose> = Vec::with_capacity(self.dof());
        for (i, &qi) in q.iter().enumerate() {
            let local = self.joint_pose(i, qi);
            let pose = match self.bodies[i].parent {
                Some(p) => out[p].compose(&local),
                None => local,
            };
            out.push(pose);
        }
        Ok(out)
    }

    /// Pose in the base frame of any URDF link (including links merged by fixed joints).
    ///
    /// # Errors
    /// [`DynamicsError::UnknownLink`], or a bad `q`.
    pub fn link_pose(&self, q: &[f64], link: &str) -> Result<Pose, DynamicsError> {
        let placement = self.links.iter().find(|l| l.name == link).ok_or_else(|| {
            DynamicsError::UnknownLink {
                link: link.to_string(),
            }
        })?;
        let fk = self.forward_kinematics(q)?;
        Ok(match placement.body {
            Some(b) => fk[b].compose(&placement.pose),
            None => placement.pose,
        })
    }

    /// Forward pass: body poses in their parents, and body-frame `ω`, `ω̇` and proper
    /// acceleration `a` of each body origin (base: `a = −g`).
    fn forward_pass(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        gravity: &Vector3<f64>,
        ws: &mut TreeWorkspace,
    ) {
        for i in 0..self.dof() {
            let b = &self.bodies[i];
            let pose = self.joint_pose(i, q[i]);
            let (w_p, wd_p, a_p) = match b.parent {
                Some(p) => (ws.omega[p], ws.omega_dot[p], ws.accel[p]),
                None => (Vector3::zeros(), Vector3::zeros(), -gravity),
            };
            let r = pose.translation;
            let a_t = a_p + wd_p.cross(&r) + w_p.cross(&w_p.cross(&r));
            let rt = pose.rotation.transpose();
            let w_in = rt * w_p;
            let wd_in = rt * wd_p;
            let a_in = rt * a_t;
            let s = b.axis;
            let (w, wd, a) = if b.kind.is_rotational() {
                (
                    w_in + s * qd[i],
                    wd_in + s * qdd[i] + w_in.cross(&s) * qd[i],
                    a_in,
                )
            } else {
                (
                    w_in,
                    wd_in,
                    a_in + s * qdd[i] + w_in.cross(&s) * (2.0 * qd[i]),
                )
            };
            ws.pose[i] = pose;
            ws.omega[i] = w;
            ws.omega_dot[i] = wd;
            ws.accel[i] = a;
        }
    }

    // --------------------------------------------------------------------------- dynamics

    #[allow(clippy::too_many_arguments)]
    fn rnea_core(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        params: &[InertialParams],
        gravity: &Vector3<f64>,
        ws: &mut TreeWorkspace,
        tau: &mut [f64],
    ) {
        self.forward_pass(q, qd, qdd, gravity, ws);
        for (i, th) in params.iter().enumerate() {
            let w = newton_euler(th, &ws.accel[i], &ws.omega[i], &ws.omega_dot[i]);
            ws.force[i] = w.force;
            ws.torque[i] = w.torque;
        }
        for i in (0..self.dof()).rev() {
            let b = &self.bodies[i];
            tau[i] = if b.kind.is_rotational() {
                b.axis.dot(&ws.torque[i])
            } else {
                b.axis.dot(&ws.force[i])
            };
            if let Some(p) = b.parent {
                let pose = ws.pose[i];
                let f = pose.rotation * ws.force[i];
                let n = pose.rotation * ws.torque[i] + pose.translation.cross(&f);
                ws.force[p] += f;
                ws.torque[p] += n;
            }
        }
    }

    /// Inverse dynamics by the recursive Newton–Euler algorithm with the nominal parameters:
    /// joint torques \[N m\] / forces \[N\] for positions `q`, velocities `q̇` and accelerations
    /// `q̈` (rad or m, per second, per second²), under this tree's gravity.
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] / [`DynamicsError::NonFinite`] for bad inputs.
    pub fn rnea(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<DVector<f64>, DynamicsError> {
        self.rnea_with_params(q, qd, qdd, &self.params())
    }

    /// [`rnea`](Self::rnea) with other inertial parameters (one per body).
    ///
    /// # Errors
    /// As [`rnea`](Self::rnea), and for a wrong parameter count.
    pub fn rnea_with_params(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        params: &[InertialParams],
    ) -> Result<DVector<f64>, DynamicsError> {
        let mut ws = self.workspace();
        let mut tau = DVector::zeros(self.dof());
        self.rnea_into(q, qd, qdd, params, &mut ws, tau.as_mut_slice())?;
        Ok(tau)
    }

    /// Allocation-free [`rnea_with_params`](Self::rnea_with_params) writing `τ` into `tau`
    /// (length `dof`).
    ///
    /// # Errors
    /// As [`rnea_with_params`](Self::rnea_with_params), and for a wrong `tau` length or a
    /// workspace of another tree.
    #[allow(clippy::too_many_arguments)]
    pub fn rnea_into(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        params: &[InertialParams],
        ws: &mut TreeWorkspace,
        tau: &mut [f64],
    ) -> Result<(), DynamicsError> {
        self.check_vec("q", q)?;
        self.check_vec("qd", qd)?;
        self.check_vec("qdd", qdd)?;
        self.check_params(params)?;
        self.check_workspace(ws)?;
        if tau.len() != self.dof() {
            return Err(DynamicsError::DimensionMismatch {
                what: "tau",
                expected: self.dof(),
                got: tau.len(),
            });
        }
        self.rnea_core(q, qd, qdd, params, &self.gravity, ws, tau);
        Ok(())
    }

    /// The joint-torque regressor `Y(q, q̇, q̈)` (`dof × 10·n_bodies`) with
    /// `τ = Y θ` for the stacked parameters θ of [`params_vector`](Self::params_vector).
    ///
    /// # Errors
    /// [`DynamicsError::DimensionMismatch`] / [`DynamicsError::NonFinite`] for bad inputs.
    pub fn joint_torque_regressor(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<DMatrix<f64>, DynamicsError> {
        let mut ws = self.workspace();
        let mut rows = vec![0.0; self.dof() * self.n_params()];
        self.joint_torque_regressor_into(q, qd, qdd, &mut ws, &mut rows)?;
        Ok(DMatrix::from_row_slice(self.dof(), self.n_params(), &rows))
    }

    /// Allocation-free [`joint_torque_regressor`](Self::joint_torque_regressor), row-major
    /// into `out` (`dof · 10·n_bodies` values; `out[r·10n_b + c] = Y[r][c]`).
    ///
    /// Body `j`'s wrench `Y_j θ_j` (6×10 Newton–Euler regressor at its kinematics) reaches
    /// joint `k` (an ancestor or `j` itself) as `ζ_kjᵀ Y_j θ_j`, where `ζ_kj` is joint `k`'s
    /// motion axis expressed at body `j`'s origin in body `j`'s frame; `ζ` is carried down the
    /// tree like a velocity. Entries for non-ancestors are zero.
    ///
    /// # Errors
    /// As [`joint_torque_regressor`](Self::joint_torque_regressor), and for a wrong `out`
    /// length or a workspace of another tree.
    pub fn joint_torque_regressor_into(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        ws: &mut TreeWorkspace,
        out: &mut [f64],
    ) -> Result<(), DynamicsError> {
        self.check_vec("q", q)?;
        self.check_vec("qd", qd)?;
        self.check_vec("qdd", qdd)?;
        self.check_workspace(ws)?;
        let n = self.dof();
        let cols = self.n_params();
        if out.len() != n * cols {
            return Err(DynamicsError::DimensionMismatch {
                what: "regressor buffer",
                expected: n * cols,
                got: out.len(),
            });
        }
        self.forward_pass(q, qd, qdd, &self.gravity, ws);
        for j in 0..n {
            ws.regressor[j] = rigid_body_regressor(&ws.accel[j], &ws.omega[j], &ws.omega_dot[j]);
        }
        out.fill(0.0);
        for k in 0..n {
            let b = &self.bodies[k];
            let s = b.axis;
            // ζ = [linear; angular], paired with the wrench [f; τ].
            ws.zeta[k] = if b.kind.is_rotational() {
                Vector6::new(0.0, 0.0, 0.0, s.x, s.y, s.z)
            } else {
                Vector6::new(s.x, s.y, s.z, 0.0, 0.0, 0.0)
            };
            let row = &mut out[k * cols..(k + 1) * cols];
            for j in k..self.subtree_end[k] {
                if j > k {
                    // Parent of j lies in [k, j): its ζ is already set.
                    let p = self.bodies[j].parent.unwrap_or(k);
                    let zp = ws.zeta[p];
                    let v = Vector3::new(zp[0], zp[1], zp[2]);
                    let w = Vector3::new(zp[3], zp[4], zp[5]);
                    let pose = &ws.pose[j];
                    let rt = pose.rotation.transpose();
                    let w_new = rt * w;
                    let v_new = rt * (v + w.cross(&pose.translation));
                    ws.zeta[j] = Vector6::new(v_new.x, v_new.y, v_new.z, w_new.x, w_new.y, w_new.z);
                }
                let block = ws.regressor[j].tr_mul(&ws.zeta[j]);
                row[10 * j..10 * j + 10].copy_from_slice(block.as_slice());
            }
        }
        Ok(())
    }

    /// Joint-space mass matrix `M(q)` (`dof × dof`), column `i` = RNEA with `q̇ = 0`,
    /// `q̈ = e_i` and no gravity.
    ///
    /// # Errors
    /// For bad `q`.
    pub fn mass_matrix(&self, q: &[f64]) -> Result<DMatrix<f64>, DynamicsError> {
        self.check_vec("q", q)?;
        let n = self.dof();
        let params = self.params();
        let mut ws = self.workspace();
        let zeros = vec![0.0; n];
        let mut e = vec![0.0; n];
        let mut col = vec![0.0; n];
        let mut m = DMatrix::zeros(n, n);
        for i in 0..n {
            e[i] = 1.0;
            self.rnea_core(q, &zeros, &e, &params, &Vector3::zeros(), &mut ws, &mut col);
            e[i] = 0.0;
            m.column_mut(i).copy_from_slice(&col);
        }
        // Symmetric in exact arithmetic; remove round-off asymmetry.
        Ok((&m + m.transpose()) * 0.5)
    }

    /// Coriolis, centrifugal and gravity torques `h(q, q̇) = RNEA(q, q̇, 0)`.
    ///
    /// # Errors
    /// For bad inputs.
    pub fn bias_forces(&self, q: &[f64], qd: &[f64]) -> Result<DVector<f64>, DynamicsError> {
        self.rnea(q, qd, &vec![0.0; self.dof()])
    }

    /// Forward dynamics `q̈ = M(q)⁻¹ (τ − h(q, q̇))` (Cholesky of the mass matrix).
    ///
    /// # Errors
    /// For bad inputs; [`DynamicsError::SingularMassMatrix`] if `M` is not positive definite
    /// (for example a massless body at the end of a branch).
    pub fn forward_dynamics(
        &self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
    ) -> Result<DVector<f64>, DynamicsError> {
        self.check_vec("tau", tau)?;
        let m = self.mass_matrix(q)?;
        let h = self.bias_forces(q, qd)?;
        let chol = m.cholesky().ok_or(DynamicsError::SingularMassMatrix)?;
        Ok(chol.solve(&(DVector::from_column_slice(tau) - h)))
    }

    /// Kinetic energy \[J\]: `Σ ½ m vᵀv + vᵀ(ω × h) + ½ ωᵀ I ω` over the bodies, with `v`, `ω`
    /// the body-frame velocity of each body origin and angular velocity.
    ///
    /// # Errors
    /// For bad inputs.
    pub fn kinetic_energy(&self, q: &[f64], qd: &[f64]) -> Result<f64, DynamicsError> {
        self.check_vec("q", q)?;
        self.check_vec("qd", qd)?;
        let n = self.dof();
        let mut v: Vec<Vector3<f64>> = Vec::with_capacity(n);
        let mut w: Vec<Vector3<f64>> = Vec::with_capacity(n);
        let mut energy = 0.0;
        for i in 0..n {
            let b = &self.bodies[i];
            let pose = self.joint_pose(i, q[i]);
            let (v_p, w_p) = match b.parent {
                Some(p) => (v[p], w[p]),
                None => (Vector3::zeros(), Vector3::zeros()),
            };
            let rt = pose.rotation.transpose();
            let mut vi = rt * (v_p + w_p.cross(&pose.translation));
            let mut wi = rt * w_p;
            if b.kind.is_rotational() {
                wi += b.axis * qd[i];
            } else {
                vi += b.axis * qd[i];
            }
            let th = &b.params;
            energy += 0.5 * th.mass() * vi.norm_squared()
                + vi.dot(&wi.cross(&th.first_moment()))
                + 0.5 * wi.dot(&(th.inertia_origin() * wi));
            v.push(vi);
            w.push(wi);
        }
        Ok(energy)
    }

    /// Potential energy in this tree's gravity field \[J\], `−Σ m gᵀ p_com` with the centres of
    /// mass in the base frame (zero at the base origin).
    ///
    /// # Errors
    /// For bad `q`.
    pub fn potential_energy(&self, q: &[f64]) -> Result<f64, DynamicsError> {
        let fk = self.forward_kinematics(q)?;
        Ok(fk
            .iter()
            .zip(&self.bodies)
            .map(|(pose, b)| {
                let mc =
                    pose.translation * b.params.mass() + pose.rotation * b.params.first_moment();
                -self.gravity.dot(&mc)
            })
            .sum())
    }
}
