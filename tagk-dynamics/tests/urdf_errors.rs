//! Bad URDFs give typed errors that name the link or joint at fault.

use tagk_dynamics::{DynamicsError, KinematicTree, UrdfOptions};

const GOOD_INERTIAL: &str = r#"<inertial><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;

fn link(name: &str) -> String {
    format!(r#"<link name="{name}">{GOOD_INERTIAL}</link>"#)
}

fn joint(name: &str, kind: &str, parent: &str, child: &str) -> String {
    format!(
        r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#
    )
}

fn robot(parts: &[String]) -> String {
    format!(r#"<robot name="bad">{}</robot>"#, parts.concat())
}

fn err(urdf: &str) -> DynamicsError {
    KinematicTree::from_urdf_str(urdf).expect_err("URDF should be rejected")
}

#[test]
fn well_formed_reference_loads() {
    let ok = robot(&[link("base"), link("a"), joint("j", "revolute", "base", "a")]);
    assert_eq!(KinematicTree::from_urdf_str(&ok).unwrap().dof(), 1);
}

#[test]
fn missing_inertial() {
    let urdf = robot(&[
        link("base"),
        "<link name=\"arm\"/>".into(),
        joint("j", "revolute", "base", "arm"),
    ]);
    let e = err(&urdf);
    assert_eq!(e, DynamicsError::MissingInertial { link: "arm".into() });
    assert!(e.to_string().contains("arm"));
    // A massless link welded to a massive one is fine (a tool frame)…
    let tool = robot(&[
        link("base"),
        link("arm"),
        "<link name=\"tool\"/>".into(),
        joint("j", "revolute", "base", "arm"),
        joint("weld", "fixed", "arm", "tool"),
    ]);
    assert!(KinematicTree::from_urdf_str(&tool).is_ok());
    // …and a massless moving link whose welded child has mass is fine too.
    let carried = robot(&[
        link("base"),
        "<link name=\"arm\"/>".into(),
        link("load"),
        joint("j", "revolute", "base", "arm"),
        joint("weld", "fixed", "arm", "load"),
    ]);
    assert!(KinematicTree::from_urdf_str(&carried).is_ok());
}

#[test]
fn negative_mass() {
    let bad = r#"<link name="heavy"><inertial><mass value="-2.0"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>"#;
    let urdf = robot(&[
        link("base"),
        bad.into(),
        joint("j", "revolute", "base", "heavy"),
    ]);
    assert_eq!(
        err(&urdf),
        DynamicsError::UrdfNegativeMass {
            link: "heavy".into(),
            mass: -2.0
        }
    );
}

#[test]
fn non_positive_definite_inertia() {
    for inertia in [
        r#"ixx="0.01" ixy="0" ixz="0" iyy="-0.01" iyz="0" izz="0.01""#,
        r#"ixx="0.01" ixy="0.02" ixz="0" iyy="0.01" iyz="0" izz="0.01""#,
        r#"ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0""#,
    ] {
        let bad = format!(
            r#"<link name="wobbly"><inertial><mass value="1.0"/><inertia {inertia}/></inertial></link>"#
        );
        let urdf = robot(&[link("base"), bad, joint("j", "revolute", "base", "wobbly")]);
        match err(&urdf) {
            DynamicsError::NonPositiveDefiniteInertia {
                link,
                min_eigenvalue,
            } => {
                assert_eq!(link, "wobbly");
                assert!(min_eigenvalue <= 0.0);
            }
            other => panic!("unexpected {other:?}"),
        }
    }
}

#[test]
fn non_finite_inertial() {
    let bad = r#"<link name="nan"><inertial><mass value="NaN"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>"#;
    let urdf = robot(&[
        link("base"),
        bad.into(),
        joint("j", "revolute", "base", "nan"),
    ]);
    assert_eq!(
        err(&urdf),
        DynamicsError::UrdfNonFiniteInertial { link: "nan".into() }
    );
}

#[test]
fn joint_cycle() {
    let urdf = robot(&[
        link("base"),
        link("a"),
        link("b"),
        link("c"),
        joint("j0", "revolute", "base", "a"),
        joint("j1", "revolute", "a", "b"),
        joint("j2", "revolute", "b", "c"),
        joint("j3", "revolute", "c", "a"),
    ]);
    match err(&urdf) {
        DynamicsError::JointCycle { joint } => {
            assert!(["j1", "j2", "j3"].contains(&joint.as_str()), "{joint}")
        }
        other => panic!("unexpected {other:?}"),
    }
    // A loop with no way in from a root.
    let urdf = robot(&[
        link("a"),
        link("b"),
        joint("ab", "revolute", "a", "b"),
        joint("ba", "fixed", "b", "a"),
    ]);
    assert!(matches!(err(&urdf), DynamicsError::JointCycle { .. }));
}

#[test]
fn unsupported_joint_types() {
    for kind in ["floating", "planar"] {
        let urdf = robot(&[link("base"), link("a"), joint("free", kind, "base", "a")]);
        assert_eq!(
            err(&urdf),
            DynamicsError::UnsupportedJointType {
                joint: "free".into(),
                kind: kind.into()
            }
        );
    }
    // A type urdf-rs does not know at all is a parse error.
    let urdf = robot(&[link("base"), link("a"), joint("odd", "ball", "base", "a")]);
    assert!(matches!(err(&urdf), DynamicsError::UrdfParse { .. }));
}

#[test]
fn missing_parent_and_child_links() {
    let urdf = robot(&[
        link("base"),
        link("a"),
        joint("j", "revolute", "ghost", "a"),
    ]);
    assert_eq!(
        err(&urdf),
        DynamicsError::MissingParentLink {
            joint: "j".into(),
            link: "ghost".into()
        }
    );
    let urdf = robot(&[link("base"), joint("j", "revolute", "base", "phantom")]);
    assert_eq!(
        err(&urdf),
        DynamicsError::MissingChildLink {
            joint: "j".into(),
            link: "phantom".into()
        }
    );
}

#[test]
fn structural_errors() {
    let urdf = robot(&[
        link("base"),
        link("base"),
        joint("j", "revolute", "base", "base"),
    ]);
    assert_eq!(
        err(&urdf),
        DynamicsError::DuplicateLink {
            link: "base".into()
        }
    );
    let urdf = robot(&[
        link("base"),
        link("a"),
        link("b"),
        joint("j", "revolute", "base", "a"),
        joint("j", "revolute", "a", "b"),
    ]);
    assert_eq!(
        err(&urdf),
        DynamicsError::DuplicateJoint { joint: "j".into() }
    );
    let urdf = robot(&[
        link("base"),
        link("a"),
        link("b"),
        joint("j1", "revolute", "base", "b"),
        joint("j2", "revolute", "a", "b"),
    ]);
    assert!(matches!(err(&urdf), DynamicsError::MultipleParents { link, .. } if link == "b"));
    let urdf = robot(&[
        link("base"),
        link("a"),
        link("stray"),
        joint("j", "revolute", "base", "a"),
    ]);
    assert!(matches!(err(&urdf), DynamicsError::MultipleRoots { .. }));
    let urdf = robot(&[link("base"), link("a"), joint("j", "fixed", "base", "a")]);
    assert_eq!(err(&urdf), DynamicsError::NoMovableJoint);
    assert_eq!(
        err(r#"<robot name="empty"></robot>"#),
        DynamicsError::UrdfNoLinks
    );
    let zero_axis = robot(&[
        link("base"),
        link("a"),
        joint("j", "revolute", "base", "a").replace("0 0 1", "0 0 0"),
    ]);
    assert_eq!(
        err(&zero_axis),
        DynamicsError::InvalidJointAxis { joint: "j".into() }
    );
    assert!(matches!(
        err("<robot name=\"x\"><link name="),
        DynamicsError::UrdfParse { .. }
    ));
    let ok = robot(&[link("base"), link("a"), joint("j", "revolute", "base", "a")]);
    assert_eq!(
        KinematicTree::from_urdf_str_with(
            &ok,
            &UrdfOptions {
                locked_joints: vec!["nope".into()]
            }
        )
        .unwrap_err(),
        DynamicsError::UnknownJoint {
            joint: "nope".into()
        }
    );
    assert!(matches!(
        KinematicTree::from_urdf_file("/nonexistent/robot.urdf"),
        Err(DynamicsError::UrdfParse { .. })
    ));
}
