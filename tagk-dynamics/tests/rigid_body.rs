//! Rigid-body parameters, Newton–Euler wrench, regressor, quadrotor mixer and window builder,
//! each checked against an independent computation.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3, Vector4};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tagk_dynamics::math::{axis_angle, parallel_axis, rotation_from_rpy, skew};
use tagk_dynamics::*;

fn v3(rng: &mut ChaCha8Rng, s: f64) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-s..s),
        rng.random_range(-s..s),
        rng.random_range(-s..s),
    )
}

/// A physically consistent body made of a few point masses.
fn random_body(rng: &mut ChaCha8Rng) -> (InertialParams, Vec<(f64, Vector3<f64>)>) {
    let points: Vec<(f64, Vector3<f64>)> = (0..6)
        .map(|_| (rng.random_range(0.05..1.0), v3(rng, 0.4)))
        .collect();
    let theta = points.iter().fold(InertialParams::ZERO, |acc, (m, p)| {
        acc.with_point_mass(*m, *p)
    });
    (theta, points)
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= tol * (1.0 + y.abs()))
}

fn vec3() -> impl Strategy<Value = Vector3<f64>> {
    (-5.0..5.0f64, -5.0..5.0f64, -5.0..5.0f64).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

fn theta10() -> impl Strategy<Value = [f64; 10]> {
    proptest::array::uniform10(-3.0..3.0f64)
}

proptest! {
    #[test]
    fn regressor_times_theta_is_newton_euler(t in theta10(), a in vec3(), w in vec3(), wd in vec3()) {
        let theta = InertialParams::from_array(t);
        let y = rigid_body_regressor(&a, &w, &wd);
        let lhs = y * nalgebra::SVector::<f64, 10>::from_row_slice(&t);
        let rhs = newton_euler(&theta, &a, &w, &wd).to_array();
        prop_assert!(close(lhs.as_slice(), &rhs, 1e-12), "{lhs:?} vs {rhs:?}");
        // The row-major writer agrees with the matrix.
        let mut buf = [0.0; 61];
        buf[60] = 7.0;
        write_rigid_body_regressor(&a, &w, &wd, &mut buf).unwrap();
        for r in 0..6 { for c in 0..10 { prop_assert_eq!(buf[10 * r + c], y[(r, c)]); } }
        prop_assert_eq!(buf[60], 7.0);
    }

    #[test]
    fn forward_dynamics_inverts_newton_euler(seed in any::<u64>(), w in vec3(), f in vec3(), tq in vec3()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, _) = random_body(&mut rng);
        let wrench = Wrench::new(f, tq * 0.1);
        let (a, wd) = forward_dynamics(&theta, &wrench, &w);
        let back = newton_euler(&theta, &a, &w, &wd);
        prop_assert!(close(&back.to_array(), &wrench.to_array(), 1e-9));
        // And the other way round.
        let a0 = v3(&mut rng, 3.0);
        let wd0 = v3(&mut rng, 3.0);
        let w0 = newton_euler(&theta, &a0, &w, &wd0);
        let (a1, wd1) = try_forward_dynamics(&theta, &w0, &w).unwrap();
        prop_assert!(close(a1.as_slice(), a0.as_slice(), 1e-8));
        prop_assert!(close(wd1.as_slice(), wd0.as_slice(), 1e-8));
    }

    #[test]
    fn prepared_forward_dynamics_has_the_bits_of_nalgebras_cholesky_solve(seed in any::<u64>(), w in vec3(), f in vec3(), tq in vec3()) {
        // The written-out 3 × 3 solve of `ForwardDynamics` against the equations solved with
        // nalgebra's own `Cholesky::solve`: the same bits, not merely close.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, _) = random_body(&mut rng);
        let wrench = Wrench::new(f, tq * 0.1);
        let (a, wd) = ForwardDynamics::new(&theta).unwrap().accelerations(&wrench, &w).unwrap();
        let (m, h, i) = (theta.mass(), theta.first_moment(), theta.inertia_origin());
        let fr = wrench.force - w.cross(&w.cross(&h));
        let t = wrench.torque - w.cross(&(i * w));
        let wd_ref = theta.inertia_com().cholesky().unwrap().solve(&(t - h.cross(&fr) / m));
        let a_ref = (fr + h.cross(&wd_ref)) / m;
        for k in 0..3 {
            prop_assert_eq!(wd[k].to_bits(), wd_ref[k].to_bits());
            prop_assert_eq!(a[k].to_bits(), a_ref[k].to_bits());
        }
    }

    #[test]
    fn shifting_origin_is_parallel_axis_and_keeps_physics(seed in any::<u64>(), d in vec3(), a in vec3(), w in vec3(), wd in vec3()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, points) = random_body(&mut rng);
        let d = d * 0.1;
        let shifted = theta.shifted(d);
        // Parallel-axis rule through the centre of mass.
        let m = theta.mass();
        let c = theta.com();
        let c_new = c - d;
        let expected = InertialParams::from_mass_first_moment_inertia(
            m, c_new * m, theta.inertia_com() + parallel_axis(&c_new) * m);
        prop_assert!(close(shifted.as_slice(), expected.as_slice(), 1e-10));
        // Same as rebuilding the body from its point masses about the new origin.
        let rebuilt = points.iter().fold(InertialParams::ZERO, |acc, (mi, p)| acc.with_point_mass(*mi, p - d));
        prop_assert!(close(shifted.as_slice(), rebuilt.as_slice(), 1e-10));
        // Physics unchanged: the new origin's acceleration is a + ω̇×d + ω×(ω×d), and the wrench
        // about it is (f, τ − d × f).
        let wrench = newton_euler(&theta, &a, &w, &wd);
        let a_new = a + wd.cross(&d) + w.cross(&w.cross(&d));
        let wrench_new = newton_euler(&shifted, &a_new, &w, &wd);
        prop_assert!(close(wrench_new.force.as_slice(), wrench.force.as_slice(), 1e-9));
        let tq = wrench.torque - d.cross(&wrench.force);
        prop_assert!(close(wrench_new.torque.as_slice(), tq.as_slice(), 1e-9));
    }

    #[test]
    fn rotating_and_translating_frame_keeps_physics(seed in any::<u64>(), a in vec3(), w in vec3(), wd in vec3()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, points) = random_body(&mut rng);
        let r = rotation_from_rpy(rng.random_range(-3.0..3.0), rng.random_range(-1.5..1.5), rng.random_range(-3.0..3.0));
        let p = v3(&mut rng, 0.5);
        let moved = theta.transformed(&r, &p);
        let rebuilt = points.iter().fold(InertialParams::ZERO, |acc, (mi, x)| acc.with_point_mass(*mi, r * x + p));
        prop_assert!(close(moved.as_slice(), rebuilt.as_slice(), 1e-10));
        // New origin sits at x = −Rᵀp in the old frame.
        let o = -(r.transpose() * p);
        let wrench = newton_euler(&theta, &a, &w, &wd);
        let a_o = a + wd.cross(&o) + w.cross(&w.cross(&o));
        let wrench_new = newton_euler(&moved, &(r * a_o), &(r * w), &(r * wd));
        prop_assert!(close(wrench_new.force.as_slice(), (r * wrench.force).as_slice(), 1e-9));
        let tq = r * (wrench.torque - o.cross(&wrench.force));
        prop_assert!(close(wrench_new.torque.as_slice(), tq.as_slice(), 1e-9));
    }

    #[test]
    fn point_cloud_pseudo_inertia_and_consistency(seed in any::<u64>()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, points) = random_body(&mut rng);
        // J = Σ m_i [x_i; 1][x_i; 1]ᵀ.
        let mut j = Matrix4::zeros();
        for (m, x) in &points {
            let v = Vector4::new(x.x, x.y, x.z, 1.0);
            j += v * v.transpose() * *m;
        }
        prop_assert!((theta.pseudo_inertia() - j).amax() < 1e-12);
        prop_assert!(theta.is_physically_consistent());
        prop_assert!(theta.min_pseudo_inertia_eigenvalue().unwrap() > 0.0);
        let back = InertialParams::from_pseudo_inertia(&j);
        prop_assert!(close(back.as_slice(), theta.as_slice(), 1e-12));
    }

    #[test]
    fn projection_is_consistent_and_nearest_in_pseudo_inertia(t in theta10(), seed in any::<u64>()) {
        let theta = InertialParams::from_array(t);
        let eps = 1e-6;
        let proj = theta.project_to_consistent(eps);
        prop_assert!(proj.is_physically_consistent());
        prop_assert!(proj.min_pseudo_inertia_eigenvalue().unwrap() >= eps * (1.0 - 1e-6) - 1e-12);
        // No consistent body with λ_min(J) ≥ ε is closer in the Frobenius norm of J.
        let d_proj = (proj.pseudo_inertia() - theta.pseudo_inertia()).norm();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..50 {
            let (cand, _) = random_body(&mut rng);
            let cand = cand * rng.random_range(0.1..3.0);
            if cand.min_pseudo_inertia_eigenvalue().unwrap() >= eps {
                let d = (cand.pseudo_inertia() - theta.pseudo_inertia()).norm();
                prop_assert!(d_proj <= d + 1e-9);
            }
        }
        if theta.min_pseudo_inertia_eigenvalue().unwrap() >= eps {
            prop_assert_eq!(proj, theta);
        }
    }

    #[test]
    fn payload_add_remove_round_trip(seed in any::<u64>(), pm in 0.001..1.0f64, pos in vec3(), size in vec3()) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (theta, _) = random_body(&mut rng);
        let back = theta.with_point_mass(pm, pos).without_point_mass(pm, pos);
        prop_assert!(close(back.as_slice(), theta.as_slice(), 1e-10));
        let back = theta.with_box(pm, pos, size).without_box(pm, pos, size);
        prop_assert!(close(back.as_slice(), theta.as_slice(), 1e-10));
        // The combined centre of mass is the mass-weighted mean.
        let with = theta.with_point_mass(pm, pos);
        let c = (theta.com() * theta.mass() + pos * pm) / (theta.mass() + pm);
        prop_assert!((with.com() - c).norm() < 1e-10);
    }
}

#[test]
fn solid_box_matches_a_fine_point_grid() {
    let (m, centre, size) = (
        0.7,
        Vector3::new(0.1, -0.2, 0.05),
        Vector3::new(0.3, 0.12, 0.5),
    );
    let n = 40;
    let dm = m / (n * n * n) as f64;
    let mut grid = InertialParams::ZERO;
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let u = |idx: usize, s: f64| ((idx as f64 + 0.5) / n as f64 - 0.5) * s;
                let p = centre + Vector3::new(u(i, size.x), u(j, size.y), u(k, size.z));
                grid = grid.with_point_mass(dm, p);
            }
        }
    }
    let exact = InertialParams::solid_box(m, centre, size);
    // The midpoint rule misses m·Δ²/12 per axis in each second moment.
    let tol = m * (size.amax() / n as f64).powi(2) / 6.0 + 1e-12;
    for (a, b) in exact.as_slice().iter().zip(grid.as_slice()) {
        assert!((a - b).abs() <= tol, "{exact:?} vs {grid:?}");
    }
    assert!(exact.is_physically_consistent());
}

#[test]
fn mass_com_inertia_round_trip_and_errors() {
    let ic = Matrix3::new(
        0.02, 0.001, -0.002, 0.001, 0.03, 0.0005, -0.002, 0.0005, 0.04,
    );
    let c = Vector3::new(0.1, -0.05, 0.2);
    let theta = InertialParams::from_mass_com_inertia(1.5, c, ic).unwrap();
    assert!((theta.com() - c).norm() < 1e-15);
    assert!((theta.inertia_com() - ic).amax() < 1e-15);
    assert!((theta.first_moment() - c * 1.5).norm() < 1e-15);
    // I_O by hand: I_C + m (cᵀc·1 − c cᵀ).
    let i_o = ic + 1.5 * (Matrix3::identity() * c.dot(&c) - c * c.transpose());
    assert!((theta.inertia_origin() - i_o).amax() < 1e-15);
    assert_eq!(InertialParams::from_slice(theta.as_slice()).unwrap(), theta);
    assert!(matches!(
        InertialParams::from_slice(&[0.0; 9]),
        Err(DynamicsError::DimensionMismatch {
            expected: 10,
            got: 9,
            ..
        })
    ));
    assert!(matches!(
        InertialParams::from_mass_com_inertia(-1.0, c, ic),
        Err(DynamicsError::NegativeMass { .. })
    ));
    assert!(matches!(
        InertialParams::from_mass_com_inertia(f64::NAN, c, ic),
        Err(DynamicsError::NonFinite { .. })
    ));
    let mut asym = ic;
    asym[(0, 1)] += 0.01;
    assert!(matches!(
        InertialParams::from_mass_com_inertia(1.0, c, asym),
        Err(DynamicsError::AsymmetricInertia { .. })
    ));
    assert!(matches!(
        InertialParams::from_mass_com_inertia(
            1.0,
            c,
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.1))
        ),
        Err(DynamicsError::InertiaNotPositiveSemiDefinite { .. })
    ));
    assert_eq!(InertialParams::ZERO.try_com(), None);
    assert_eq!(InertialParams::ZERO.com(), Vector3::zeros());
}

#[test]
fn consistency_catches_triangle_inequality_and_negative_mass() {
    // I_C = diag(1, 1, 3): positive definite but I_zz > I_xx + I_yy, impossible for any density.
    let bad = InertialParams::from_mass_com_inertia(
        1.0,
        Vector3::zeros(),
        Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 3.0)),
    )
    .unwrap();
    assert!(bad.inertia_origin().symmetric_eigenvalues().min() > 0.0);
    assert!(!bad.is_physically_consistent());
    let fixed = bad.project_to_consistent(1e-9);
    assert!(fixed.is_physically_consistent());
    let neg = InertialParams::from_array([-0.1, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    assert!(!neg.is_physically_consistent());
    assert!(neg.project_to_consistent(1e-9).mass() > 0.0);
    let nan = InertialParams::from_array([f64::NAN; 10]);
    assert!(!nan.is_physically_consistent());
    assert_eq!(nan.min_pseudo_inertia_eigenvalue(), None);
}

#[test]
fn safety_gate_checks_each_condition() {
    let gate = SafetyGate::crazyflie();
    assert_eq!(gate.max_com_offset, 0.0325);
    assert_eq!(gate.max_inertia_eigenvalue, 1e-4);
    let cf = QuadrotorModel::crazyflie_2_1().params;
    assert_eq!(cf.safety_gate(&gate), Ok(()));
    assert!(cf.is_physically_consistent());
    let mut t = cf.to_array();
    t[0] = -0.01;
    assert!(matches!(
        InertialParams::from_array(t).safety_gate(&gate),
        Err(GateViolation::NonPositiveMass { .. })
    ));
    let far = cf.with_point_mass(0.035, Vector3::new(0.2, 0.0, 0.0));
    assert!(matches!(
        far.safety_gate(&gate),
        Err(GateViolation::ComOffsetTooLarge { .. })
    ));
    let mut t = cf.to_array();
    t[9] = -1e-5;
    assert!(matches!(
        InertialParams::from_array(t).safety_gate(&gate),
        Err(GateViolation::InertiaNotPositiveDefinite { .. })
    ));
    let mut t = cf.to_array();
    t[9] = 2e-4;
    assert!(matches!(
        InertialParams::from_array(t).safety_gate(&gate),
        Err(GateViolation::InertiaEigenvalueTooLarge { .. })
    ));
    assert_eq!(
        InertialParams::from_array([f64::INFINITY; 10]).safety_gate(&gate),
        Err(GateViolation::NonFinite)
    );
    // A looser gate accepts the heavy offset payload.
    let loose = SafetyGate {
        max_com_offset: 1.0,
        max_inertia_eigenvalue: 1.0,
    };
    assert_eq!(far.safety_gate(&loose), Ok(()));
}

#[test]
fn singular_spatial_inertia_is_an_error() {
    let w = Wrench::new(Vector3::new(0.0, 0.0, 1.0), Vector3::zeros());
    let zero = InertialParams::ZERO;
    assert!(matches!(
        try_forward_dynamics(&zero, &w, &Vector3::zeros()),
        Err(DynamicsError::SingularSpatialInertia { .. })
    ));
    // A point mass has no rotational inertia about its centre of mass.
    let pm = InertialParams::point_mass(1.0, Vector3::new(0.1, 0.0, 0.0));
    assert!(try_forward_dynamics(&pm, &w, &Vector3::zeros()).is_err());
    assert!(
        try_forward_dynamics(
            &QuadrotorModel::crazyflie_2_1().params,
            &w,
            &Vector3::new(f64::NAN, 0.0, 0.0)
        )
        .is_err()
    );
}

// ---------------------------------------------------------------------------------------------
// Newton–Euler against the rate of change of momentum of a body whose motion is prescribed
// analytically; derivatives by 5-point central differences.

fn d5<const N: usize>(
    f: impl Fn(f64) -> nalgebra::SVector<f64, N>,
    t: f64,
    h: f64,
) -> nalgebra::SVector<f64, N> {
    (f(t - 2.0 * h) - f(t - h) * 8.0 + f(t + h) * 8.0 - f(t + 2.0 * h)) / (12.0 * h)
}

fn d5m(f: impl Fn(f64) -> Matrix3<f64>, t: f64, h: f64) -> Matrix3<f64> {
    (f(t - 2.0 * h) - f(t - h) * 8.0 + f(t + h) * 8.0 - f(t + 2.0 * h)) / (12.0 * h)
}

fn vee(s: &Matrix3<f64>) -> Vector3<f64> {
    let a = (s - s.transpose()) * 0.5;
    Vector3::new(a[(2, 1)], a[(0, 2)], a[(1, 0)])
}

#[test]
fn newton_euler_equals_rate_of_change_of_momentum() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..5 {
        let (theta, _) = random_body(&mut rng);
        let m = theta.mass();
        let c = theta.com();
        let ic = theta.inertia_com();
        let (f1, f2, f3) = (
            rng.random_range(0.5..2.0),
            rng.random_range(0.5..2.0),
            rng.random_range(0.5..2.0),
        );
        let pos = move |t: f64| {
            Vector3::new(
                (f1 * t).sin(),
                0.5 * (f2 * t).cos(),
                0.2 * t * t + 0.1 * (f3 * t).sin(),
            )
        };
        let rot = move |t: f64| {
            rotation_from_rpy(
                0.4 * (1.1 * f1 * t).sin(),
                0.3 * (0.9 * f2 * t).cos(),
                0.8 * t + 0.2 * (2.0 * f3 * t).sin(),
            )
        };
        let h = 1e-3;
        // World angular velocity from Ṙ Rᵀ = S(ω_w).
        let omega_w = move |t: f64| vee(&(d5m(rot, t, 1e-4) * rot(t).transpose()));
        let com_w = move |t: f64| pos(t) + rot(t) * c;
        let lin_mom = move |t: f64| d5(com_w, t, 1e-4) * m;
        // Angular momentum about the fixed world origin.
        let ang_mom = move |t: f64| {
            let r = rot(t);
            r * ic * r.transpose() * omega_w(t) + com_w(t).cross(&lin_mom(t))
        };
        let t0 = 0.37;
        let r = rot(t0);
        let g = GRAVITY_WORLD;
        // Net external force/torque = momentum rates; remove gravity to get the actuator's.
        let f_act = d5(lin_mom, t0, h) - g * m;
        let n_act_world_origin = d5(ang_mom, t0, h) - com_w(t0).cross(&(g * m));
        let tau_act_body_origin = n_act_world_origin - pos(t0).cross(&f_act);
        let expected = Wrench::new(r.transpose() * f_act, r.transpose() * tau_act_body_origin);

        let p_ddot = d5(|t| d5(pos, t, 1e-4), t0, h);
        let accel = r.transpose() * (p_ddot - g);
        let omega_b = r.transpose() * omega_w(t0);
        let omega_dot_b = d5(|t| rot(t).transpose() * omega_w(t), t0, h);
        let got = newton_euler(&theta, &accel, &omega_b, &omega_dot_b);
        let scale = expected
            .to_array()
            .iter()
            .fold(1.0f64, |s, v| s.max(v.abs()));
        for (x, y) in got.to_array().iter().zip(expected.to_array()) {
            assert!((x - y).abs() < 1e-6 * scale, "{got:?} vs {expected:?}");
        }
        // The quaternion helper gives the same proper acceleration.
        let q = nalgebra::UnitQuaternion::from_matrix(&r);
        assert!((proper_acceleration(&q, &p_ddot) - accel).norm() < 1e-9);
    }
}

// ---------------------------------------------------------------------------------------------
// Quadrotor.

#[test]
fn crazyflie_numbers_and_mixer() {
    let q = QuadrotorModel::crazyflie_2_1();
    assert_eq!(q.params.mass(), 0.035);
    assert!((q.max_thrust_per_rotor() * 4.0 - 0.575).abs() < 1e-12);
    for p in &q.rotor_positions {
        assert!((p.norm() - q.arm).abs() < 1e-4);
    }
    // Hover: equal thrusts, total = weight, no torque.
    let weight = q.params.mass() * 9.81;
    let t = q.thrusts_from_wrench(weight, &Vector3::zeros());
    for ti in t {
        assert!((ti - weight / 4.0).abs() < 1e-12);
    }
    // Torques by hand: r × (0, 0, T) and the reaction torques.
    let thrusts = [0.1, 0.12, 0.09, 0.11];
    let w = q.wrench_from_thrusts(&thrusts);
    let d = 0.0325;
    let tx = d * (-thrusts[0] - thrusts[1] + thrusts[2] + thrusts[3]);
    let ty = d * (-thrusts[0] + thrusts[1] + thrusts[2] - thrusts[3]);
    let tz = q.k_m / q.k_f * (thrusts[0] - thrusts[1] + thrusts[2] - thrusts[3]);
    assert!((w.force - Vector3::new(0.0, 0.0, 0.42)).norm() < 1e-15);
    assert!((w.torque - Vector3::new(tx, ty, tz)).norm() < 1e-15);
    let mixed = q.mixer_matrix() * Vector4::from_row_slice(&thrusts);
    assert!((mixed - Vector4::new(w.force.z, w.torque.x, w.torque.y, w.torque.z)).norm() < 1e-15);
    // The inverse mixer round-trips.
    let back = q.thrusts_from_wrench(w.force.z, &w.torque);
    for (a, b) in back.iter().zip(thrusts) {
        assert!((a - b).abs() < 1e-12);
    }
    // Speeds: T = k_f ω².
    let speeds = q.rotor_speeds_from_thrusts(&[
        q.max_thrust_per_rotor(),
        0.0,
        -1.0,
        0.25 * q.max_thrust_per_rotor(),
    ]);
    assert!((speeds[0] - 2500.0).abs() < 1e-9);
    assert_eq!(speeds[1], 0.0);
    assert_eq!(speeds[2], 0.0);
    assert!((speeds[3] - 1250.0).abs() < 1e-9);
    let ws = q.wrench_from_rotor_speeds(&[2500.0, 0.0, 0.0, 0.0]);
    assert!((ws.force.z - q.max_thrust_per_rotor()).abs() < 1e-15);
    assert_eq!(
        q.clamp_thrusts(&[-1.0, 0.1, 1.0, 0.0]),
        [0.0, 0.1, q.max_thrust_per_rotor(), 0.0]
    );
}

#[test]
fn singular_mixer_falls_back_to_least_squares() {
    let mut q = QuadrotorModel::crazyflie_2_1();
    q.spin_directions = [1.0; 4]; // no yaw authority: the mixer is singular
    // A reachable wrench: yaw torque tied to total thrust.
    let kappa = q.k_m / q.k_f;
    let t = q.thrusts_from_wrench(0.4, &Vector3::new(0.001, -0.002, 0.4 * kappa));
    let w = q.wrench_from_thrusts(&t);
    assert!(t.iter().all(|v| v.is_finite()));
    assert!((w.force.z - 0.4).abs() < 1e-9);
    assert!((w.torque.x - 0.001).abs() < 1e-9 && (w.torque.y + 0.002).abs() < 1e-9);
    // Minimum norm: equal split of the collective part, so t1 + t3 = t2 + t4.
    assert!(((t[0] + t[2]) - (t[1] + t[3])).abs() < 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Window builder.

#[test]
fn window_stacks_latest_frames_in_order_and_recovers_theta() {
    let theta = QuadrotorModel::crazyflie_2_1()
        .params
        .with_point_mass(0.015, Vector3::new(0.01, -0.005, -0.01));
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let k = 5;
    let mut win = WindowBuilder::new(k).unwrap();
    assert!(win.is_empty());
    let mut frames = Vec::new();
    for i in 0..12 {
        let (a, w, wd) = (v3(&mut rng, 10.0), v3(&mut rng, 3.0), v3(&mut rng, 20.0));
        let wr = newton_euler(&theta, &a, &w, &wd);
        win.push(&a, &w, &wd, &wr).unwrap();
        frames.push((a, w, wd, wr));
        assert_eq!(win.len(), (i + 1).min(k));
    }
    assert!(win.is_full());
    assert_eq!(win.rows(), 30);
    let mut a_buf = vec![0.0; 300];
    let mut b_buf = vec![0.0; 30];
    assert_eq!(win.build(&mut a_buf, &mut b_buf).unwrap(), 30);
    for (f, (a, w, wd, wr)) in frames[12 - k..].iter().enumerate() {
        let y = rigid_body_regressor(a, w, wd);
        for r in 0..6 {
            for c in 0..10 {
                assert_eq!(a_buf[(6 * f + r) * 10 + c], y[(r, c)]);
            }
            assert_eq!(b_buf[6 * f + r], wr.to_array()[r]);
        }
    }
    let (a_s, b_s) = win.stacked();
    assert_eq!(a_s, &a_buf[..]);
    assert_eq!(b_s, &b_buf[..]);
    // Batch least squares on the window recovers θ.
    let a_mat = DMatrix::from_row_slice(30, 10, a_s);
    let b_vec = DVector::from_column_slice(b_s);
    let est = a_mat.clone().svd(true, true).solve(&b_vec, 1e-14).unwrap();
    assert!(close(est.as_slice(), theta.as_slice(), 1e-6), "{est:?}");

    // Raw rows and errors.
    assert!(matches!(
        win.build(&mut [0.0; 10], &mut b_buf),
        Err(DynamicsError::DimensionMismatch { .. })
    ));
    assert!(matches!(
        win.push_rows(&[0.0; 59], &[0.0; 6]),
        Err(DynamicsError::DimensionMismatch { .. })
    ));
    let nan = Vector3::new(f64::NAN, 0.0, 0.0);
    assert!(matches!(
        win.push(&nan, &nan, &nan, &Wrench::zero()),
        Err(DynamicsError::NonFinite { .. })
    ));
    assert_eq!(win.stacked().0, &a_buf[..]);
    win.push_rows(&[1.0; 60], &[2.0; 6]).unwrap();
    let (a_s, b_s) = win.stacked();
    assert_eq!(&a_s[240..], &[1.0; 60]);
    assert_eq!(&b_s[24..], &[2.0; 6]);
    assert_eq!(&a_s[..60], &a_buf[60..120]);
    win.clear();
    assert_eq!(win.stacked().0.len(), 0);
    assert!(matches!(
        WindowBuilder::new(0),
        Err(DynamicsError::EmptyWindow)
    ));
}

#[test]
fn helpers_are_consistent() {
    let a = Vector3::new(0.3, -0.2, 0.9);
    let r = axis_angle(&a.normalize(), 0.7);
    assert!((r * r.transpose() - Matrix3::identity()).amax() < 1e-14);
    assert!((skew(&a) * a).norm() < 1e-15);
}

/// The Frobenius metric of the pseudo-inertia as an information matrix on θ:
/// `θᵀ F θ = ‖J(θ)‖²_F`, entry by entry from `J` of the unit vectors.
fn frobenius_information() -> [[f64; 10]; 10] {
    let unit = |k: usize| {
        let mut e = [0.0; 10];
        e[k] = 1.0;
        InertialParams::from_array(e).pseudo_inertia()
    };
    std::array::from_fn(|i| std::array::from_fn(|j| unit(i).dot(&unit(j))))
}

/// `(a − b)ᵀ P (a − b)`.
fn mahalanobis(a: &InertialParams, b: &InertialParams, p: &[[f64; 10]; 10]) -> f64 {
    let d: Vec<f64> = a
        .as_slice()
        .iter()
        .zip(b.as_slice())
        .map(|(x, y)| x - y)
        .collect();
    (0..10)
        .map(|i| (0..10).map(|j| d[i] * p[i][j] * d[j]).sum::<f64>())
        .sum()
}

/// In the Frobenius metric of `J` the nearest consistent θ is the eigenvalue clipping at 0
/// (closed form: the nearest positive semidefinite matrix), which the metric-weighted search
/// must reproduce.
#[test]
fn nearest_consistent_in_the_frobenius_metric_is_the_eigenvalue_clipping() {
    let p = frobenius_information();
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let mut tried = 0;
    while tried < 40 {
        let (body, _) = random_body(&mut rng);
        // Break it: a too large inertia about one axis, or a negative second moment.
        let mut t: [f64; 10] = body.as_slice().try_into().unwrap();
        let k = [4, 6, 9][rng.random_range(0..3)];
        t[k] *= rng.random_range(2.5..6.0);
        let bad = InertialParams::from_array(t);
        if bad.min_pseudo_inertia_eigenvalue().unwrap() >= 0.0 {
            continue;
        }
        tried += 1;
        let scale = (bad.pseudo_inertia()).norm();
        let eps = [0.0, 1e-4 * scale][tried % 2];
        let want = bad.project_to_consistent(eps);
        let got = bad.nearest_consistent(&p, eps);
        let gap = (got.pseudo_inertia() - want.pseudo_inertia()).norm();
        assert!(
            gap <= 1e-6 * scale,
            "case {tried}: {gap:e} from the clipping (scale {scale:e})"
        );
        assert!(got.min_pseudo_inertia_eigenvalue().unwrap() >= eps - 1e-12 * scale);
    }
}

/// With a general information matrix: a consistent θ is kept, and an inconsistent one lands
/// on a consistent θ that no random consistent body beats in the metric. A quadrotor-like
/// estimate whose yaw inertia is poorly determined (and too large for the triangle
/// inequality) is repaired by lowering I_zz, not the well-determined I_xx and I_yy.
#[test]
fn nearest_consistent_moves_along_the_least_determined_direction() {
    let body = InertialParams::from_mass_com_inertia(
        0.035,
        Vector3::new(0.0, 0.0, 0.002),
        Matrix3::from_diagonal(&Vector3::new(1.6e-5, 1.6e-5, 2.9e-5)),
    )
    .unwrap();
    let se: [f64; 10] = [1e-4, 1e-5, 1e-5, 1e-5, 2e-7, 1e-7, 2e-7, 1e-7, 1e-7, 2e-5];
    let p: [[f64; 10]; 10] =
        std::array::from_fn(|i| std::array::from_fn(|j| if i == j { se[i].powi(-2) } else { 0.0 }));
    assert_eq!(body.nearest_consistent(&p, 0.0), body);
    let mut t: [f64; 10] = body.as_slice().try_into().unwrap();
    t[9] = 4.0e-5; // I_zz beyond I_xx + I_yy = 3.2e-5 (+ the offset's share)
    let bad = InertialParams::from_array(t);
    assert!(bad.min_pseudo_inertia_eigenvalue().unwrap() < 0.0);
    let got = bad.nearest_consistent(&p, 0.0);
    let scale = bad.pseudo_inertia().norm();
    assert!(got.min_pseudo_inertia_eigenvalue().unwrap() >= -1e-12 * scale);
    let i = got.inertia_origin();
    assert!(
        (i[(0, 0)] - 1.6e-5 - 0.035 * 0.002f64.powi(2)).abs() < 2e-7,
        "I_xx {}",
        i[(0, 0)]
    );
    assert!(
        (i[(1, 1)] - 1.6e-5 - 0.035 * 0.002f64.powi(2)).abs() < 2e-7,
        "I_yy {}",
        i[(1, 1)]
    );
    assert!(i[(2, 2)] < 3.3e-5, "I_zz {}", i[(2, 2)]);
    let clip = bad.project_to_consistent(0.0);
    assert!(mahalanobis(&got, &bad, &p) <= mahalanobis(&clip, &bad, &p));
    // No random consistent body near the estimate is closer in the metric.
    let best = mahalanobis(&got, &bad, &p);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..5_000 {
        let mut c: [f64; 10] = got.as_slice().try_into().unwrap();
        for (k, x) in c.iter_mut().enumerate() {
            *x += rng.random_range(-3.0..3.0) * se[k];
        }
        let cand = InertialParams::from_array(c);
        if cand.min_pseudo_inertia_eigenvalue().unwrap() >= 0.0 {
            assert!(
                mahalanobis(&cand, &bad, &p) >= best * (1.0 - 1e-9),
                "a consistent body beats the search"
            );
        }
    }
    // Non-finite information: the clipping.
    let nan = [[f64::NAN; 10]; 10];
    assert_eq!(
        bad.nearest_consistent(&nan, 0.0),
        bad.project_to_consistent(0.0)
    );
}

/// The gate scaled to a vehicle keeps the Crazyflie's numbers for the Crazyflie and scales
/// `α` with the largest inertia eigenvalue: a body with ten times the inertia gets ten times
/// the bound, and its own nominal parameters pass.
#[test]
fn the_safety_gate_scales_with_the_vehicle() {
    let cf = QuadrotorModel::crazyflie_2_1().params;
    let gate = SafetyGate::for_vehicle(0.0325, &cf);
    let paper = SafetyGate::crazyflie();
    assert_eq!(gate.max_com_offset, paper.max_com_offset);
    assert!((gate.max_inertia_eigenvalue - paper.max_inertia_eigenvalue).abs() < 1e-18);
    let mut big: [f64; 10] = cf.as_slice().try_into().unwrap();
    big[0] *= 10.0;
    for v in &mut big[4..] {
        *v *= 10.0;
    }
    let big = InertialParams::from_array(big);
    assert!(big.safety_gate(&paper).is_err(), "the paper's α refuses it");
    let scaled = SafetyGate::for_vehicle(0.1, &big);
    assert!((scaled.max_inertia_eigenvalue / paper.max_inertia_eigenvalue - 10.0).abs() < 1e-12);
    assert_eq!(big.safety_gate(&scaled), Ok(()));
}
