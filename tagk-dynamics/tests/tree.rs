//! Kinematic trees from URDF: closed-form dynamics, regressor identity, power balance,
//! frame handling of inertials and fixed joints.

use nalgebra::{DVector, Matrix3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_dynamics::math::rotation_from_rpy;
use tagk_dynamics::*;

fn robot_path(name: &str) -> String {
    format!("{}/robots/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn planar() -> KinematicTree {
    KinematicTree::from_urdf_file(robot_path("planar_2link.urdf"))
        .unwrap()
        .with_gravity(Vector3::new(0.0, -9.81, 0.0))
}

fn panda_arm() -> KinematicTree {
    let opts = UrdfOptions {
        locked_joints: vec!["panda_finger_joint1".into(), "panda_finger_joint2".into()],
    };
    KinematicTree::from_urdf_file_with(robot_path("panda.urdf"), &opts).unwrap()
}

fn all_robots() -> Vec<(&'static str, KinematicTree)> {
    vec![
        ("planar_2link", planar()),
        (
            "panda (9 dof, fingers)",
            KinematicTree::from_urdf_file(robot_path("panda.urdf")).unwrap(),
        ),
        ("panda arm (7 dof)", panda_arm()),
        (
            "ur5",
            KinematicTree::from_urdf_file(robot_path("ur5.urdf")).unwrap(),
        ),
    ]
}

fn random_state(rng: &mut ChaCha8Rng, n: usize, s: f64) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-s..s)).collect()
}

fn assert_close(a: &[f64], b: &[f64], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    let scale = b.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= tol * scale, "{what}: {a:?} vs {b:?}");
    }
}

// Textbook vertical 2R arm (Spong, Hutchinson & Vidyasagar, §7.3), q from the x axis,
// gravity along −y.
const L1: f64 = 1.0;
const L2: f64 = 0.8;
const M1: f64 = 2.0;
const M2: f64 = 1.5;
const LC1: f64 = 0.5;
const LC2: f64 = 0.4;
const I1: f64 = 0.17;
const I2: f64 = 0.08;
const G: f64 = 9.81;

fn two_link_closed_form(q: &[f64], qd: &[f64], qdd: &[f64]) -> ([f64; 2], [[f64; 2]; 2]) {
    let (c1, c2, s2, c12) = (q[0].cos(), q[1].cos(), q[1].sin(), (q[0] + q[1]).cos());
    let m11 = M1 * LC1 * LC1 + M2 * (L1 * L1 + LC2 * LC2 + 2.0 * L1 * LC2 * c2) + I1 + I2;
    let m12 = M2 * (LC2 * LC2 + L1 * LC2 * c2) + I2;
    let m22 = M2 * LC2 * LC2 + I2;
    let h = -M2 * L1 * LC2 * s2;
    let g1 = (M1 * LC1 + M2 * L1) * G * c1 + M2 * LC2 * G * c12;
    let g2 = M2 * LC2 * G * c12;
    let tau1 = m11 * qdd[0] + m12 * qdd[1] + h * qd[1] * qd[1] + 2.0 * h * qd[0] * qd[1] + g1;
    let tau2 = m12 * qdd[0] + m22 * qdd[1] - h * qd[0] * qd[0] + g2;
    ([tau1, tau2], [[m11, m12], [m12, m22]])
}

#[test]
fn two_link_rnea_matches_closed_form() {
    let arm = planar();
    assert_eq!(arm.dof(), 2);
    assert_eq!(arm.joint_names(), vec!["joint1", "joint2"]);
    assert_eq!(arm.bodies()[1].kind(), JointKind::Continuous);
    assert_eq!(arm.bodies()[1].merged_links(), &["tool0".to_string()]);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..200 {
        let q = random_state(&mut rng, 2, 3.2);
        let qd = random_state(&mut rng, 2, 4.0);
        let qdd = random_state(&mut rng, 2, 10.0);
        let (tau, m) = two_link_closed_form(&q, &qd, &qdd);
        let got = arm.rnea(&q, &qd, &qdd).unwrap();
        assert_close(got.as_slice(), &tau, 1e-12, "2-link τ");
        let mm = arm.mass_matrix(&q).unwrap();
        assert_close(
            mm.as_slice(),
            &[m[0][0], m[1][0], m[0][1], m[1][1]],
            1e-12,
            "2-link M",
        );
        // Potential energy and forward kinematics in closed form.
        let pe = G * (M1 * LC1 * q[0].sin() + M2 * (L1 * q[0].sin() + LC2 * (q[0] + q[1]).sin()));
        assert!((arm.potential_energy(&q).unwrap() - pe).abs() < 1e-12);
        let tip = arm.link_pose(&q, "tool0").unwrap().translation;
        let expected = Vector3::new(
            L1 * q[0].cos() + L2 * (q[0] + q[1]).cos(),
            L1 * q[0].sin() + L2 * (q[0] + q[1]).sin(),
            0.0,
        );
        assert!((tip - expected).norm() < 1e-14);
        // Forward dynamics inverts RNEA.
        let qdd_back = arm.forward_dynamics(&q, &qd, &tau).unwrap();
        assert_close(qdd_back.as_slice(), &qdd, 1e-10, "2-link forward dynamics");
    }
}

/// Revolute + prismatic polar arm in a vertical plane, in closed form: exercises the
/// prismatic Coriolis term 2 m r ṙ θ̇ and centrifugal term −m r θ̇².
#[test]
fn polar_rp_arm_matches_closed_form() {
    let urdf = r#"<robot name="rp">
      <link name="base"/>
      <joint name="theta" type="continuous"><parent link="base"/><child link="boom"/><axis xyz="0 0 1"/></joint>
      <link name="boom"><inertial><origin xyz="0.3 0 0"/><mass value="1.2"/>
        <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
      <joint name="r" type="prismatic"><parent link="boom"/><child link="slider"/><axis xyz="1 0 0"/>
        <limit lower="0" upper="2" effort="10" velocity="1"/></joint>
      <link name="slider"><inertial><mass value="0.7"/>
        <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.004"/></inertial></link>
    </robot>"#;
    let arm = KinematicTree::from_urdf_str(urdf)
        .unwrap()
        .with_gravity(Vector3::new(0.0, -G, 0.0));
    assert_eq!(arm.bodies()[1].kind(), JointKind::Prismatic);
    let (m1, lc1, i1, m2, i2) = (1.2, 0.3, 0.05, 0.7, 0.004);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..100 {
        let q = [rng.random_range(-3.0..3.0), rng.random_range(0.1..2.0)];
        let qd = random_state(&mut rng, 2, 3.0);
        let qdd = random_state(&mut rng, 2, 5.0);
        let (th, r) = (q[0], q[1]);
        let inertia = i1 + m1 * lc1 * lc1 + i2 + m2 * r * r;
        let tau1 =
            inertia * qdd[0] + 2.0 * m2 * r * qd[1] * qd[0] + G * th.cos() * (m1 * lc1 + m2 * r);
        let tau2 = m2 * qdd[1] - m2 * r * qd[0] * qd[0] + m2 * G * th.sin();
        let got = arm.rnea(&q, &qd, &qdd).unwrap();
        assert_close(got.as_slice(), &[tau1, tau2], 1e-12, "RP arm");
    }
}

#[test]
fn regressor_times_theta_equals_rnea_on_every_robot() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (name, robot) in all_robots() {
        let n = robot.dof();
        let theta = robot.params_vector();
        let mut ws = robot.workspace();
        let mut rows = vec![0.0; n * robot.n_params()];
        for _ in 0..50 {
            let q = random_state(&mut rng, n, 3.0);
            let qd = random_state(&mut rng, n, 2.0);
            let qdd = random_state(&mut rng, n, 5.0);
            let y = robot.joint_torque_regressor(&q, &qd, &qdd).unwrap();
            assert_eq!(y.shape(), (n, 10 * robot.n_bodies()));
            let tau = robot.rnea(&q, &qd, &qdd).unwrap();
            assert_close((&y * &theta).as_slice(), tau.as_slice(), 1e-11, name);
            // Other parameters (random, not necessarily consistent): linear in θ.
            let other: Vec<InertialParams> = (0..robot.n_bodies())
                .map(|_| {
                    InertialParams::from_array(std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
                })
                .collect();
            let theta2 = DVector::from_iterator(10 * n, other.iter().flat_map(|p| p.to_array()));
            let tau2 = robot.rnea_with_params(&q, &qd, &qdd, &other).unwrap();
            assert_close((&y * &theta2).as_slice(), tau2.as_slice(), 1e-11, name);
            // The allocation-free variant agrees.
            robot
                .joint_torque_regressor_into(&q, &qd, &qdd, &mut ws, &mut rows)
                .unwrap();
            let y_rows = nalgebra::DMatrix::from_row_slice(n, robot.n_params(), &rows);
            assert_eq!(y_rows, y);
            // A joint's torque does not depend on bodies that are not its descendants.
            for k in 0..n {
                for j in 0..n {
                    let mut anc = Some(j);
                    let mut is_desc = false;
                    while let Some(a) = anc {
                        is_desc |= a == k;
                        anc = robot.bodies()[a].parent();
                    }
                    if !is_desc {
                        assert!(y.view((k, 10 * j), (1, 10)).iter().all(|v| *v == 0.0));
                    }
                }
            }
        }
    }
}

/// Kinetic energy from finite differences of forward kinematics (world-frame velocities of
/// each body), independent of the velocity recursion.
fn kinetic_energy_from_fk(robot: &KinematicTree, q: &[f64], qd: &[f64]) -> f64 {
    let h = 1e-6;
    let at = |t: f64| {
        let qt: Vec<f64> = q.iter().zip(qd).map(|(a, b)| a + b * t).collect();
        robot.forward_kinematics(&qt).unwrap()
    };
    let (fp, fm, f0) = (at(h), at(-h), at(0.0));
    let mut ke = 0.0;
    for (i, body) in robot.bodies().iter().enumerate() {
        let v = (fp[i].translation - fm[i].translation) / (2.0 * h);
        let rdot = (fp[i].rotation - fm[i].rotation) / (2.0 * h);
        let s = rdot * f0[i].rotation.transpose();
        let w = Vector3::new(
            s[(2, 1)] - s[(1, 2)],
            s[(0, 2)] - s[(2, 0)],
            s[(1, 0)] - s[(0, 1)],
        ) * 0.5;
        let r = f0[i].rotation;
        let th = body.params();
        ke += 0.5 * th.mass() * v.norm_squared()
            + v.dot(&w.cross(&(r * th.first_moment())))
            + 0.5 * w.dot(&(r * th.inertia_origin() * r.transpose() * w));
    }
    ke
}

#[test]
fn energies_and_mass_matrix_agree_with_kinematics() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for (name, robot) in all_robots() {
        let n = robot.dof();
        for _ in 0..10 {
            let q = random_state(&mut rng, n, 3.0);
            let qd = random_state(&mut rng, n, 2.0);
            let ke = robot.kinetic_energy(&q, &qd).unwrap();
            let ke_fk = kinetic_energy_from_fk(&robot, &q, &qd);
            assert!(
                (ke - ke_fk).abs() < 1e-6 * (1.0 + ke),
                "{name}: {ke} vs {ke_fk}"
            );
            let m = robot.mass_matrix(&q).unwrap();
            let qv = DVector::from_column_slice(&qd);
            assert!(
                (0.5 * qv.dot(&(&m * &qv)) - ke).abs() < 1e-10 * (1.0 + ke),
                "{name}"
            );
            assert!(m.clone().cholesky().is_some(), "{name}: M not PD");
            // Gravity torques are the gradient of the potential energy.
            let g = robot.rnea(&q, &vec![0.0; n], &vec![0.0; n]).unwrap();
            for i in 0..n {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[i] += 1e-6;
                qm[i] -= 1e-6;
                let dpe = (robot.potential_energy(&qp).unwrap()
                    - robot.potential_energy(&qm).unwrap())
                    / 2e-6;
                assert!(
                    (dpe - g[i]).abs() < 1e-6 * (1.0 + g[i].abs()),
                    "{name} joint {i}: {dpe} vs {}",
                    g[i]
                );
            }
        }
    }
}

/// Integrates the forward dynamics (M from unit-acceleration RNEA columns) with RK4 under a
/// known torque and checks d/dt (KE + PE) = q̇ᵀτ along the trajectory.
#[test]
fn power_balance_along_simulated_trajectory() {
    for (name, robot) in [("planar", planar()), ("panda arm", panda_arm())] {
        let n = robot.dof();
        let torque =
            |t: f64| -> Vec<f64> { (0..n).map(|i| 2.0 * (1.3 * t + i as f64).sin()).collect() };
        let deriv = |t: f64, x: &[f64]| -> Vec<f64> {
            let (q, qd) = x.split_at(n);
            let qdd = robot.forward_dynamics(q, qd, &torque(t)).unwrap();
            qd.iter().copied().chain(qdd.iter().copied()).collect()
        };
        let dt = 1e-3;
        let mut x: Vec<f64> = (0..n)
            .map(|i| 0.3 * i as f64 - 0.5)
            .chain((0..n).map(|_| 0.2))
            .collect();
        let mut t = 0.0;
        let mut energy = Vec::new();
        let mut power = Vec::new();
        for _ in 0..300 {
            let (q, qd) = x.split_at(n);
            energy.push(robot.kinetic_energy(q, qd).unwrap() + robot.potential_energy(q).unwrap());
            power.push(qd.iter().zip(torque(t)).map(|(a, b)| a * b).sum::<f64>());
            let k1 = deriv(t, &x);
            let add = |x: &[f64], k: &[f64], s: f64| -> Vec<f64> {
                x.iter().zip(k).map(|(a, b)| a + s * b).collect()
            };
            let k2 = deriv(t + dt / 2.0, &add(&x, &k1, dt / 2.0));
            let k3 = deriv(t + dt / 2.0, &add(&x, &k2, dt / 2.0));
            let k4 = deriv(t + dt, &add(&x, &k3, dt));
            for i in 0..2 * n {
                x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            t += dt;
        }
        let scale = power.iter().fold(1e-3f64, |m, p| m.max(p.abs()));
        let mut max_err = 0.0f64;
        for k in 2..energy.len() - 2 {
            let de = (energy[k - 2] - 8.0 * energy[k - 1] + 8.0 * energy[k + 1] - energy[k + 2])
                / (12.0 * dt);
            max_err = max_err.max((de - power[k]).abs());
        }
        assert!(
            max_err < 1e-6 * scale,
            "{name}: max |dE/dt − q̇ᵀτ| = {max_err}, scale {scale}"
        );
        // The energy did change: the test is not vacuous.
        assert!(
            (energy[energy.len() - 1] - energy[0]).abs() > 1e-3,
            "{name}"
        );
    }
}

#[test]
fn fixed_joints_merge_like_a_joint_held_still() {
    // link2 is split in two parts; the second is welded (fixed, rotated frame) in one model
    // and carried by an extra revolute joint held at q = q̇ = q̈ = 0 in the other.
    let make = |kind: &str| {
        format!(
            r#"<robot name="split">
          <link name="base"/>
          <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
            <origin xyz="0 0 0.3" rpy="0.1 0.2 0.3"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <link name="a"><inertial><origin xyz="0.1 0.05 0.2" rpy="0.4 -0.3 1.0"/><mass value="2.0"/>
            <inertia ixx="0.03" ixy="0.001" ixz="-0.002" iyy="0.04" iyz="0.003" izz="0.02"/></inertial></link>
          <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
            <origin xyz="0.4 0 0.1" rpy="-0.5 0 0.2"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <link name="b"><inertial><origin xyz="0.2 0.0 -0.05" rpy="0.1 0.2 0.3"/><mass value="1.0"/>
            <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.015"/></inertial></link>
          <joint name="weld" type="{kind}"><parent link="b"/><child link="c"/><axis xyz="0.3 0.5 0.8"/>
            <origin xyz="0.3 -0.1 0.05" rpy="1.0 0.5 -0.7"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
          <link name="c"><inertial><origin xyz="0.05 0.02 0.1" rpy="-0.2 0.9 0.4"/><mass value="0.6"/>
            <inertia ixx="0.004" ixy="0.0005" ixz="0" iyy="0.006" iyz="0" izz="0.005"/></inertial></link>
          <joint name="tip" type="fixed"><parent link="c"/><child link="d"/><origin xyz="0.1 0 0" rpy="0 0 1"/></joint>
          <link name="d"/>
        </robot>"#
        )
    };
    let welded = KinematicTree::from_urdf_str(&make("fixed")).unwrap();
    let jointed = KinematicTree::from_urdf_str(&make("revolute")).unwrap();
    let locked = KinematicTree::from_urdf_str_with(
        &make("revolute"),
        &UrdfOptions {
            locked_joints: vec!["weld".into()],
        },
    )
    .unwrap();
    assert_eq!((welded.dof(), jointed.dof(), locked.dof()), (2, 3, 2));
    assert_eq!(
        welded.bodies()[1].merged_links(),
        &["c".to_string(), "d".to_string()]
    );
    assert_eq!(welded, locked);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..50 {
        let q = random_state(&mut rng, 2, 3.0);
        let qd = random_state(&mut rng, 2, 2.0);
        let qdd = random_state(&mut rng, 2, 5.0);
        let ext = |v: &[f64]| vec![v[0], v[1], 0.0];
        let tau_w = welded.rnea(&q, &qd, &qdd).unwrap();
        let tau_j = jointed.rnea(&ext(&q), &ext(&qd), &ext(&qdd)).unwrap();
        assert_close(
            tau_w.as_slice(),
            &tau_j.as_slice()[..2],
            1e-12,
            "weld vs held joint",
        );
        // Merged link frames follow the body.
        let pd = welded.link_pose(&q, "d").unwrap();
        let pd_j = jointed.link_pose(&ext(&q), "d").unwrap();
        assert!((pd.translation - pd_j.translation).norm() < 1e-14);
        assert!((pd.rotation - pd_j.rotation).amax() < 1e-14);
    }
    assert!(matches!(
        welded.link_pose(&[0.0, 0.0], "nope"),
        Err(DynamicsError::UnknownLink { .. })
    ));
}

#[test]
fn inertial_origin_is_rotated_and_shifted_into_link_frame() {
    // Inertial frame rotated 90° about z and offset: I_xx ↔ I_yy, then parallel axis.
    let urdf = r#"<robot name="r"><link name="base"/>
      <joint name="j" type="revolute"><parent link="base"/><child link="l"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <link name="l"><inertial><origin xyz="0.1 0.2 0.3" rpy="0 0 1.5707963267948966"/><mass value="2.0"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.02"/></inertial></link></robot>"#;
    let chain = KinematicTree::from_urdf_str(urdf).unwrap();
    let th = chain.bodies()[0].params();
    let c = Vector3::new(0.1, 0.2, 0.3);
    let ic = Matrix3::from_diagonal(&Vector3::new(0.03, 0.01, 0.02));
    let expected = ic + 2.0 * (Matrix3::identity() * c.norm_squared() - c * c.transpose());
    assert!((th.mass() - 2.0).abs() < 1e-15);
    assert!((th.com() - c).norm() < 1e-12);
    assert!((th.inertia_origin() - expected).amax() < 1e-12);
    // A generic rotation: R I_C Rᵀ.
    let r = rotation_from_rpy(0.3, -0.4, 0.5);
    let urdf2 = urdf.replace(r#"rpy="0 0 1.5707963267948966""#, r#"rpy="0.3 -0.4 0.5""#);
    let th2 = *KinematicTree::from_urdf_str(&urdf2).unwrap().bodies()[0].params();
    let ic0 = Matrix3::from_diagonal(&Vector3::new(0.01, 0.03, 0.02));
    assert!((th2.inertia_com() - r * ic0 * r.transpose()).amax() < 1e-12);
}

#[test]
fn shipped_robots_have_expected_structure() {
    let panda = KinematicTree::from_urdf_file(robot_path("panda.urdf")).unwrap();
    assert_eq!(panda.dof(), 9);
    assert_eq!(panda.base_link(), "panda_link0");
    assert_eq!(panda.bodies()[8].mimic(), Some("panda_finger_joint1"));
    assert_eq!(panda.bodies()[7].parent(), Some(6));
    assert_eq!(panda.bodies()[8].parent(), Some(6));
    let arm = panda_arm();
    assert_eq!(arm.dof(), 7);
    // Hand (0.73 kg) and fingers (2 × 0.015 kg) merged into link 7.
    let m7 = arm.bodies()[6].params().mass();
    assert!((m7 - (0.735522 + 0.73 + 0.03)).abs() < 1e-12);
    let total: f64 = arm.params().iter().map(|p| p.mass()).sum();
    // Link masses 1..7 of the URDF, plus hand and fingers.
    let listed =
        4.970684 + 0.646926 + 3.228604 + 3.587895 + 1.225946 + 1.666555 + 0.735522 + 0.73 + 0.03;
    assert!((total - listed).abs() < 1e-12, "{total}");
    assert!((arm.base_params().mass() - 0.629769).abs() < 1e-15);
    // Panda zero pose: flange at 0.088 m forward, 0.333 + 0.316 + 0.384 − 0.107 m up (link8 frame).
    let flange = arm.link_pose(&[0.0; 7], "panda_link8").unwrap();
    assert!(
        (flange.translation - Vector3::new(0.088, 0.0, 0.926)).norm() < 1e-9,
        "{:?}",
        flange.translation
    );
    let ur5 = KinematicTree::from_urdf_file(robot_path("ur5.urdf")).unwrap();
    assert_eq!(ur5.dof(), 6);
    for p in arm.params().iter().chain(ur5.params().iter()) {
        assert!(p.mass() > 0.0);
    }
}

#[test]
fn chain_input_errors() {
    let arm = planar();
    assert!(matches!(
        arm.rnea(&[0.0], &[0.0, 0.0], &[0.0, 0.0]),
        Err(DynamicsError::DimensionMismatch { .. })
    ));
    assert!(matches!(
        arm.rnea(&[f64::NAN, 0.0], &[0.0; 2], &[0.0; 2]),
        Err(DynamicsError::NonFinite { .. })
    ));
    let mut ws = panda_arm().workspace();
    let mut out = vec![0.0; 2 * 20];
    assert!(matches!(
        arm.joint_torque_regressor_into(&[0.0; 2], &[0.0; 2], &[0.0; 2], &mut ws, &mut out),
        Err(DynamicsError::DimensionMismatch { .. })
    ));
    let mut ws = arm.workspace();
    assert!(matches!(
        arm.joint_torque_regressor_into(&[0.0; 2], &[0.0; 2], &[0.0; 2], &mut ws, &mut out[..39]),
        Err(DynamicsError::DimensionMismatch { .. })
    ));
    let mut a2 = arm.clone();
    assert!(a2.set_params(&[InertialParams::ZERO]).is_err());
    let new = [InertialParams::point_mass(1.0, Vector3::x()); 2];
    a2.set_params(&new).unwrap();
    assert_eq!(a2.params(), new.to_vec());
    // A massless tip makes M singular: forward dynamics reports it.
    a2.set_params(&[
        InertialParams::point_mass(1.0, Vector3::x()),
        InertialParams::ZERO,
    ])
    .unwrap();
    assert!(matches!(
        a2.forward_dynamics(&[0.0; 2], &[0.0; 2], &[0.0; 2]),
        Err(DynamicsError::SingularMassMatrix)
    ));
}

/// Each joint's `<limit>` reaches its body: the UR5 file's numbers, read here from the XML text
/// by a plain search, are the tree's.
#[test]
fn joint_limits_are_the_urdf_s() {
    let path = robot_path("ur5.urdf");
    let text = std::fs::read_to_string(&path).unwrap();
    let tree = KinematicTree::from_urdf_file(&path).unwrap();
    let attribute = |tag: &str, key: &str| -> f64 {
        let start = tag.find(&format!("{key}=\"")).unwrap() + key.len() + 2;
        let end = start + tag[start..].find('"').unwrap();
        tag[start..end].parse().unwrap()
    };
    for body in tree.bodies() {
        let joint = text
            .find(&format!("<joint name=\"{}\"", body.joint()))
            .unwrap();
        let limit = joint + text[joint..].find("<limit").unwrap();
        let tag = &text[limit..limit + text[limit..].find("/>").unwrap()];
        let l = body.limit();
        assert_eq!(l.lower, attribute(tag, "lower"), "{}", body.joint());
        assert_eq!(l.upper, attribute(tag, "upper"), "{}", body.joint());
        assert_eq!(l.velocity, attribute(tag, "velocity"), "{}", body.joint());
        assert_eq!(l.effort, attribute(tag, "effort"), "{}", body.joint());
    }
    let planar = planar();
    assert_eq!(planar.bodies()[0].limit().velocity, 5.0);
    assert_eq!(planar.bodies()[1].kind(), JointKind::Continuous);
}

/// The payload body: the last body of a serial arm, the Panda's hand (link 7 with the hand
/// welded on) when its fingers move, the last body of two chains from the base.
#[test]
fn payload_body_is_the_body_that_carries_every_leaf() {
    for (name, tree) in all_robots() {
        let b = tree.payload_body().unwrap();
        // Independently: every body without children hangs below `b` (or is `b`).
        let has_child = |i: usize| tree.bodies().iter().any(|x| x.parent() == Some(i));
        for leaf in (0..tree.n_bodies()).filter(|&i| !has_child(i)) {
            let mut at = Some(leaf);
            while at.is_some_and(|i| i != b) {
                at = tree.bodies()[at.unwrap()].parent();
            }
            assert_eq!(at, Some(b), "{name}: leaf {leaf} not below body {b}");
        }
        if name.starts_with("panda (9") {
            let hand = &tree.bodies()[b];
            assert_eq!(hand.link(), "panda_link7", "{name}");
            assert!(hand.merged_links().iter().any(|l| l == "panda_hand"));
            assert_eq!(b, 6);
        } else {
            assert_eq!(b, tree.n_bodies() - 1, "{name}: a serial arm's last body");
        }
    }
    let two_chains = r#"<robot name="two">
      <link name="base"/>
      <joint name="a" type="revolute"><parent link="base"/><child link="la"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
      <link name="la"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
      <joint name="b" type="revolute"><parent link="base"/><child link="lb"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
      <link name="lb"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
    </robot>"#;
    let tree = KinematicTree::from_urdf_str(two_chains).unwrap();
    assert_eq!(tree.payload_body(), Some(1));
}
