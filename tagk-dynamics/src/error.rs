//! The crate's error type.

use thiserror::Error;

/// Every failure of `tagk-dynamics`: bad numbers, wrong buffer sizes, and URDF problems (each
/// URDF error names the link or joint at fault).
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DynamicsError {
    /// A quantity that must be finite was NaN or infinite.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// A mass was negative.
    #[error("negative mass {mass} kg")]
    NegativeMass {
        /// The offending mass \[kg\].
        mass: f64,
    },
    /// An inertia matrix was not symmetric.
    #[error("inertia matrix is not symmetric (largest asymmetry {asymmetry:e} kg m^2)")]
    AsymmetricInertia {
        /// `max |I − Iᵀ|` \[kg m²\].
        asymmetry: f64,
    },
    /// An inertia matrix about the centre of mass had a negative eigenvalue.
    #[error(
        "inertia about the centre of mass is not positive semi-definite (smallest eigenvalue {min_eigenvalue:e} kg m^2)"
    )]
    InertiaNotPositiveSemiDefinite {
        /// Smallest eigenvalue \[kg m²\].
        min_eigenvalue: f64,
    },
    /// The 6×6 spatial inertia was singular or indefinite, so the forward dynamics has no
    /// unique solution (needs `m > 0` and inertia about the centre of mass `≻ 0`).
    #[error(
        "spatial inertia is not positive definite (mass {mass} kg); forward dynamics undefined"
    )]
    SingularSpatialInertia {
        /// The mass of the parameters that were given \[kg\].
        mass: f64,
    },
    /// A buffer or vector had the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    DimensionMismatch {
        /// Which argument.
        what: &'static str,
        /// Required length.
        expected: usize,
        /// Length that was passed.
        got: usize,
    },
    /// A window length of zero frames was requested.
    #[error("a window needs at least one frame")]
    EmptyWindow,
    /// The URDF text could not be read or parsed as XML / URDF.
    #[error("URDF parse error: {message}")]
    UrdfParse {
        /// The parser's message.
        message: String,
    },
    /// The URDF has no links.
    #[error("URDF has no links")]
    UrdfNoLinks,
    /// Two links share one name.
    #[error("URDF link `{link}` is defined twice")]
    DuplicateLink {
        /// The repeated link name.
        link: String,
    },
    /// Two joints share one name.
    #[error("URDF joint `{joint}` is defined twice")]
    DuplicateJoint {
        /// The repeated joint name.
        joint: String,
    },
    /// A moving link (one that starts a body) has no `<inertial>`, and no link fixed to it
    /// carries mass either.
    #[error("URDF link `{link}` has no <inertial> (and nothing with mass is fixed to it)")]
    MissingInertial {
        /// The link.
        link: String,
    },
    /// A link's mass is negative.
    #[error("URDF link `{link}` has negative mass {mass} kg")]
    UrdfNegativeMass {
        /// The link.
        link: String,
        /// Its mass \[kg\].
        mass: f64,
    },
    /// A link's inertial contains NaN or infinity.
    #[error("URDF link `{link}` has a non-finite inertial value")]
    UrdfNonFiniteInertial {
        /// The link.
        link: String,
    },
    /// A link with positive mass has an inertia tensor (about its centre of mass) that is not
    /// positive definite, or a massless link has a non-zero inertia.
    #[error(
        "URDF link `{link}` has an inertia that is not positive definite (smallest eigenvalue {min_eigenvalue:e} kg m^2)"
    )]
    NonPositiveDefiniteInertia {
        /// The link.
        link: String,
        /// Smallest eigenvalue of the inertia about the centre of mass \[kg m²\].
        min_eigenvalue: f64,
    },
    /// The joints form a closed loop.
    #[error("URDF joints form a cycle (closed by joint `{joint}`)")]
    JointCycle {
        /// A joint on the cycle.
        joint: String,
    },
    /// A link is the child of more than one joint.
    #[error("URDF link `{link}` is the child of two joints (`{first_joint}` and `{second_joint}`)")]
    MultipleParents {
        /// The link.
        link: String,
        /// One parent joint.
        first_joint: String,
        /// Another parent joint.
        second_joint: String,
    },
    /// The links do not form one tree (more than one link has no parent joint).
    #[error("URDF has more than one root link (`{first}` and `{second}`)")]
    MultipleRoots {
        /// One root link.
        first: String,
        /// Another root link.
        second: String,
    },
    /// A joint names a parent link that does not exist.
    #[error("URDF joint `{joint}` names parent link `{link}`, which does not exist")]
    MissingParentLink {
        /// The joint.
        joint: String,
        /// The missing link name.
        link: String,
    },
    /// A joint names a child link that does not exist.
    #[error("URDF joint `{joint}` names child link `{link}`, which does not exist")]
    MissingChildLink {
        /// The joint.
        joint: String,
        /// The missing link name.
        link: String,
    },
    /// A joint type this crate does not model (floating, planar, spherical).
    #[error(
        "URDF joint `{joint}` has unsupported type `{kind}` (supported: revolute, continuous, prismatic, fixed)"
    )]
    UnsupportedJointType {
        /// The joint.
        joint: String,
        /// The type as written in the URDF.
        kind: String,
    },
    /// A joint name (for example in [`UrdfOptions::locked_joints`](crate::UrdfOptions)) that
    /// the URDF does not define.
    #[error("URDF has no joint named `{joint}`")]
    UnknownJoint {
        /// The name that was asked for.
        joint: String,
    },
    /// A joint axis of zero length or with non-finite entries.
    #[error("URDF joint `{joint}` has an invalid axis (zero or non-finite)")]
    InvalidJointAxis {
        /// The joint.
        joint: String,
    },
    /// A joint origin with non-finite entries.
    #[error("URDF joint `{joint}` has a non-finite origin")]
    NonFiniteJointOrigin {
        /// The joint.
        joint: String,
    },
    /// The robot has no movable joint.
    #[error("URDF robot has no movable joint")]
    NoMovableJoint,
    /// A link name was not found in the model.
    #[error("no link named `{link}` in the model")]
    UnknownLink {
        /// The name that was asked for.
        link: String,
    },
    /// The joint-space mass matrix was not positive definite.
    #[error("joint-space mass matrix is not positive definite")]
    SingularMassMatrix,
}
