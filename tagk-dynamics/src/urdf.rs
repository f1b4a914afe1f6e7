//! Loading a [`KinematicTree`] from URDF (through `urdf-rs`).
//!
//! Supported joints: revolute, continuous, prismatic (one coordinate each) and fixed (the child
//! link is welded to its parent and their inertials are merged). Joint origins (`xyz`, fixed-axis
//! `rpy`, i.e. `R = Rz(yaw) Ry(pitch) Rx(roll)`) and axes are honoured. A link's `<inertial>` gives
//! the mass and the inertia about the centre of mass in the inertial frame (`<origin>` of the
//! inertial); it is rotated and shifted into the link frame, about the link origin
//! (docs/CONVENTIONS.md §1). `<mimic>` couplings are recorded but not enforced.
//!
//! urdf-rs fills a missing `<inertial>` with zeros, so "no inertial" and "an inertial with
//! zero mass and zero inertia" are the same here: a massless link. Massless links are fine
//! when welded to a body that has mass (tool frames, flanges); a moving body with no mass at
//! all is reported as [`DynamicsError::MissingInertial`].

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use urdf_rs::JointType;

use crate::math::rotation_from_rpy;
use crate::tree::{Body, JointKind, JointLimit, KinematicTree, LinkPlacement, Pose};
use crate::{DynamicsError, InertialParams};

/// Options for loading a URDF.
#[derive(Debug, Clone, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct UrdfOptions {
    /// Movable joints to treat as fixed at their zero position (for example a gripper's
    /// fingers, to study the arm alone). Each name must exist in the URDF.
    pub locked_joints: Vec<String>,
}

fn pose_of(origin: &urdf_rs::Pose) -> Pose {
    Pose {
        rotation: rotation_from_rpy(origin.rpy[0], origin.rpy[1], origin.rpy[2]),
        translation: Vector3::new(origin.xyz[0], origin.xyz[1], origin.xyz[2]),
    }
}

fn pose_is_finite(origin: &urdf_rs::Pose) -> bool {
    origin
        .xyz
        .iter()
        .chain(origin.rpy.iter())
        .all(|v| v.is_finite())
}

/// A link's inertial in the link frame about the link origin, or `None` for a massless link.
fn link_inertial(link: &urdf_rs::Link) -> Result<Option<InertialParams>, DynamicsError> {
    let inertial = &link.inertial;
    let m = inertial.mass.value;
    let i = &inertial.inertia;
    let values = [m, i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz];
    if !values.iter().all(|v| v.is_finite()) || !pose_is_finite(&inertial.origin) {
        return Err(DynamicsError::UrdfNonFiniteInertial {
            link: link.name.clone(),
        });
    }
    if m < 0.0 {
        return Err(DynamicsError::UrdfNegativeMass {
            link: link.name.clone(),
            mass: m,
        });
    }
    if values.iter().all(|v| *v == 0.0) {
        return Ok(None);
    }
    let ic = Matrix3::new(
        i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
    );
    let min_eigenvalue = ic.symmetric_eigenvalues().min();
    // Inputs are finite here, so the eigenvalues are too.
    if min_eigenvalue <= 0.0 {
        return Err(DynamicsError::NonPositiveDefiniteInertia {
            link: link.name.clone(),
            min_eigenvalue,
        });
    }
    let com_frame = pose_of(&inertial.origin);
    let theta_c =
        InertialParams::from_array([m, 0.0, 0.0, 0.0, i.ixx, i.ixy, i.iyy, i.ixz, i.iyz, i.izz]);
    Ok(Some(
        theta_c.transformed(&com_frame.rotation, &com_frame.translation),
    ))
}

fn joint_type_name(t: &JointType) -> &'static str {
    match t {
        JointType::Revolute => "revolute",
        JointType::Continuous => "continuous",
        JointType::Prismatic => "prismatic",
        JointType::Fixed => "fixed",
        JointType::Floating => "floating",
        JointType::Planar => "planar",
        JointType::Spherical => "spherical",
    }
}

impl KinematicTree {
    /// Parses URDF text (see the [`urdf`](crate::urdf) module for what is supported).
    ///
    /// # Errors
    /// [`DynamicsError::UrdfParse`] for malformed XML/URDF. A typed error naming the link or joint
    /// for each mistake in the model. The mistakes: a missing inertial, a negative mass, a
    /// non-positive-definite inertia, a joint cycle, an unsupported joint type (floating,
    /// planar, spherical), a missing parent or child link, duplicate names, several root links,
    /// an invalid axis.
    pub fn from_urdf_str(urdf: &str) -> Result<Self, DynamicsError> {
        Self::from_urdf_str_with(urdf, &UrdfOptions::default())
    }

    /// [`from_urdf_str`](Self::from_urdf_str) with options.
    ///
    /// # Errors
    /// As [`from_urdf_str`](Self::from_urdf_str), and [`DynamicsError::UnknownJoint`] for a
    /// locked joint the URDF does not have.
    pub fn from_urdf_str_with(urdf: &str, options: &UrdfOptions) -> Result<Self, DynamicsError> {
        let robot = urdf_rs::read_from_string(urdf).map_err(|e| DynamicsError::UrdfParse {
            message: e.to_string(),
        })?;
        build(&robot, options)
    }

    /// Reads and parses a URDF file.
    ///
    /// # Errors
    /// As [`from_urdf_str`](Self::from_urdf_str); an unreadable file is a
    /// [`DynamicsError::UrdfParse`] carrying the I/O message.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self, DynamicsError> {
        Self::from_urdf_file_with(path, &UrdfOptions::default())
    }

    /// [`from_urdf_file`](Self::from_urdf_file) with options.
    ///
    /// # Errors
    /// As [`from_urdf_str_with`](Self::from_urdf_str_with).
    pub fn from_urdf_file_with(
        path: impl AsRef<Path>,
        options: &UrdfOptions,
    ) -> Result<Self, DynamicsError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| DynamicsError::UrdfParse {
            message: format!("{}: {e}", path.display()),
        })?;
        Self::from_urdf_str_with(&text, options)
    }
}

fn build(robot: &urdf_rs::Robot, options: &UrdfOptions) -> Result<KinematicTree, DynamicsError> {
    if robot.links.is_empty() {
        return Err(DynamicsError::UrdfNoLinks);
    }
    let mut link_index: HashMap<&str, usize> = HashMap::new();
    for (i, l) in robot.links.iter().enumerate() {
        if link_index.insert(l.name.as_str(), i).is_some() {
            return Err(DynamicsError::DuplicateLink {
                link: l.name.clone(),
            });
        }
    }
    let mut joint_names: HashMap<&str, usize> = HashMap::new();
    for (i, j) in robot.joints.iter().enumerate() {
        if joint_names.insert(j.name.as_str(), i).is_some() {
            return Err(DynamicsError::DuplicateJoint {
                joint: j.name.clone(),
            });
        }
    }
    for name in &options.locked_joints {
        if !joint_names.contains_key(name.as_str()) {
            return Err(DynamicsError::UnknownJoint {
                joint: name.clone(),
            });
        }
    }

    // Per-joint checks; parent/child link indices.
    let mut edges: Vec<(usize, usize)> = Vec::with_capacity(robot.joints.len());
    for j in &robot.joints {
        match j.joint_type {
            JointType::Revolute
            | JointType::Continuous
            | JointType::Prismatic
            | JointType::Fixed => {}
            ref other => {
                return Err(DynamicsError::UnsupportedJointType {
                    joint: j.name.clone(),
                    kind: joint_type_name(other).to_string(),
                });
            }
        }
        let parent = *link_index.get(j.parent.link.as_str()).ok_or_else(|| {
            DynamicsError::MissingParentLink {
                joint: j.name.clone(),
                link: j.parent.link.clone(),
            }
        })?;
        let child = *link_index.get(j.child.link.as_str()).ok_or_else(|| {
            DynamicsError::MissingChildLink {
                joint: j.name.clone(),
                link: j.child.link.clone(),
            }
        })?;
        if !pose_is_finite(&j.origin) {
            return Err(DynamicsError::NonFiniteJointOrigin {
                joint: j.name.clone(),
            });
        }
        if j.joint_type != JointType::Fixed {
            let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
            if !a.iter().all(|v| v.is_finite()) || a.norm() < 1e-12 {
                return Err(DynamicsError::InvalidJointAxis {
                    joint: j.name.clone(),
                });
            }
        }
        edges.push((parent, child));
    }

    // Children lists in joint order.
    let n_links = robot.links.len();
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n_links];
    for (ji, &(p, _)) in edges.iter().enumerate() {
        children[p].push(ji);
    }

    // Cycle detection: iterative DFS with colours over the parent → child graph.
    let mut colour = vec![0u8; n_links]; // 0 new, 1 on stack, 2 done
    for start in 0..n_links {
        if colour[start] != 0 {
            continue;
        }
        let mut stack: Vec<(usize, usize)> = vec![(start, 0)];
        colour[start] = 1;
        while let Some(&mut (link, ref mut next)) = stack.last_mut() {
            if let Some(&ji) = children[link].get(*next) {
                *next += 1;
                let child = edges[ji].1;
                match colour[child] {
                    0 => {
                        colour[child] = 1;
                        stack.push((child, 0));
                    }
                    1 => {
                        return Err(DynamicsError::JointCycle {
                            joint: robot.joints[ji].name.clone(),
                        });
                    }
                    _ => {}
                }
            } else {
                colour[link] = 2;
                stack.pop();
            }
        }
    }

    // One parent joint per link, one root.
    let mut parent_joint: Vec<Option<usize>> = vec![None; n_links];
    for (ji, &(_, c)) in edges.iter().enumerate() {
        if let Some(first) = parent_joint[c] {
            return Err(DynamicsError::MultipleParents {
                link: robot.links[c].name.clone(),
                first_joint: robot.joints[first].name.clone(),
                second_joint: robot.joints[ji].name.clone(),
            });
        }
        parent_joint[c] = Some(ji);
    }
    let roots: Vec<usize> = (0..n_links)
        .filter(|&l| parent_joint[l].is_none())
        .collect();
    let root = match roots.as_slice() {
        [r] => *r,
        [a, b, ..] => {
            return Err(DynamicsError::MultipleRoots {
                first: robot.links[*a].name.clone(),
                second: robot.links[*b].name.clone(),
            });
        }
        // Unreachable after the cycle check (a finite acyclic graph has a source).
        [] => {
            return Err(DynamicsError::JointCycle {
                joint: robot.joints[0].name.clone(),
            });
        }
    };

    let inertials: Vec<Option<InertialParams>> = robot
        .links
        .iter()
        .map(link_inertial)
        .collect::<Result<_, _>>()?;

    // Depth-first preorder from the root.
    let mut bodies: Vec<Body> = Vec::new();
    let mut body_has_mass: Vec<bool> = Vec::new();
    let mut placements: Vec<LinkPlacement> = Vec::with_capacity(n_links);
    let mut base_params = inertials[root].unwrap_or(InertialParams::ZERO);
    placements.push(LinkPlacement {
        name: robot.links[root].name.clone(),
        body: None,
        pose: Pose::identity(),
    });
    // Stack entries: (joint index, owner body of the parent link, parent link pose in owner).
    let mut stack: Vec<(usize, Option<usize>, Pose)> = children[root]
        .iter()
        .rev()
        .map(|&ji| (ji, None, Pose::identity()))
        .collect();
    while let Some((ji, owner, parent_pose)) = stack.pop() {
        let joint = &robot.joints[ji];
        let child = edges[ji].1;
        let link = &robot.links[child];
        let origin = parent_pose.compose(&pose_of(&joint.origin));
        let locked = options.locked_joints.iter().any(|n| n == &joint.name);
        let (child_owner, child_pose) = if joint.joint_type == JointType::Fixed || locked {
            if let Some(th) = inertials[child] {
                let moved = th.transformed(&origin.rotation, &origin.translation);
                match owner {
                    Some(b) => {
                        bodies[b].params += moved;
                        bodies[b].merged_links.push(link.name.clone());
                        body_has_mass[b] = true;
                    }
                    None => base_params += moved,
                }
            } else if let Some(b) = owner {
                bodies[b].merged_links.push(link.name.clone());
            }
            (owner, origin)
        } else {
            let kind = match joint.joint_type {
                JointType::Revolute => JointKind::Revolute,
                JointType::Continuous => JointKind::Continuous,
                _ => JointKind::Prismatic,
            };
            let axis =
                Vector3::new(joint.axis.xyz[0], joint.axis.xyz[1], joint.axis.xyz[2]).normalize();
            bodies.push(Body {
                link: link.name.clone(),
                joint: joint.name.clone(),
                kind,
                parent: owner,
                tree: origin,
                axis,
                params: inertials[child].unwrap_or(InertialParams::ZERO),
                merged_links: Vec::new(),
                mimic: joint.mimic.as_ref().map(|m| m.joint.clone()),
                limit: JointLimit {
                    lower: joint.limit.lower,
                    upper: joint.limit.upper,
                    velocity: joint.limit.velocity,
                    effort: joint.limit.effort,
                },
            });
            body_has_mass.push(inertials[child].is_some());
            (Some(bodies.len() - 1), Pose::identity())
        };
        placements.push(LinkPlacement {
            name: link.name.clone(),
            body: child_owner,
            pose: child_pose,
        });
        for &cj in children[child].iter().rev() {
            stack.push((cj, child_owner, child_pose));
        }
    }
    if bodies.is_empty() {
        return Err(DynamicsError::NoMovableJoint);
    }
    if let Some(b) = body_has_mass.iter().position(|has| !has) {
        return Err(DynamicsError::MissingInertial {
            link: bodies[b].link.clone(),
        });
    }
    Ok(KinematicTree::from_parts(
        robot.name.clone(),
        robot.links[root].name.clone(),
        bodies,
        placements,
        base_params,
    ))
}
