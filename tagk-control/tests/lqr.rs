//! The Crazyflie LQR: DARE residual and solution against independent computations,
//! closed-loop stability, warm starts, saturation, and closed-loop flight of the nonlinear
//! model of `tagk-dynamics`.

mod common;

use nalgebra::{DMatrix, Quaternion, SMatrix, UnitQuaternion, Vector3};
use tagk_control::quadrotor::{ErrorState, QuadrotorState};
use tagk_control::{
    ControlError, DEFAULT_DT, DareError, DareOptions, Lqr, LqrWeights, RiccatiSolver,
};
use tagk_dynamics::{GRAVITY_WORLD, InertialParams, QuadrotorModel, try_forward_dynamics};

fn model() -> QuadrotorModel {
    QuadrotorModel::crazyflie_2_1()
}

fn payload(mass_fraction: f64, arm_fraction: f64) -> InertialParams {
    let m = model();
    m.params.with_point_mass(
        mass_fraction * m.params.mass(),
        Vector3::new(arm_fraction * m.arm, 0.0, 0.0),
    )
}

fn to_d<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_column_slice(R, C, m.as_slice())
}

/// `AᵀPA − P − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q`, written out with nalgebra's LU.
fn independent_residual(lqr: &Lqr) -> f64 {
    let d = lqr.discrete_model();
    let (a, b, p) = (d.a, d.b, *lqr.riccati_solution());
    let (q, r) = (lqr.weights().q, lqr.weights().r);
    let s = r + b.transpose() * p * b;
    let x = s.lu().solve(&(b.transpose() * p * a)).unwrap();
    let res = a.transpose() * p * a - p - a.transpose() * p * b * x + q;
    res.norm() / p.norm()
}

#[test]
fn quadrotor_dare_residual_and_kleinman_hewer_agreement() {
    let m = model();
    let nominal = Lqr::crazyflie_default().unwrap();
    for params in [m.params, payload(0.5, 0.3)] {
        for solver in [RiccatiSolver::Doubling, RiccatiSolver::Iteration] {
            let lqr = Lqr::with_solver(
                &m,
                &params,
                LqrWeights::crazyflie(),
                DEFAULT_DT,
                solver,
                DareOptions::default(),
            )
            .unwrap();
            let res = independent_residual(&lqr);
            assert!(res < 1e-9, "{solver:?}: residual {res:e}");
            assert!(lqr.last_solve().residual < 1e-9);

            // Kleinman–Hewer on the Kronecker form (144×144 solves), started from the
            // nominal design's gain, which must stabilise this model too.
            let d = lqr.discrete_model();
            let k0 = to_d(nominal.gain());
            let acl0 = to_d(&d.a) - to_d(&d.b) * &k0;
            assert!(acl0.complex_eigenvalues().iter().all(|l| l.norm() < 1.0));
            let p_kh = common::kleinman_hewer(
                &to_d(&d.a),
                &to_d(&d.b),
                &to_d(&lqr.weights().q),
                &to_d(&lqr.weights().r),
                &k0,
            );
            let err = (to_d(lqr.riccati_solution()) - &p_kh).norm() / p_kh.norm();
            assert!(err < 1e-9, "{solver:?}: ‖P − P_KH‖/‖P‖ = {err:e}");
        }
    }
}

#[test]
fn closed_loop_is_stable_nominal_and_with_offset_payloads() {
    let m = model();
    let nominal = Lqr::crazyflie_default().unwrap();
    // Default weights: slowest pole |z| ≈ 0.93 (time constant ≈ 0.27 s at 50 Hz).
    let rho = nominal.spectral_radius();
    assert!(rho < 0.95, "{rho}");
    for (mass_fraction, arm_fraction) in [(0.5, 0.3), (0.3, 0.2), (0.5, -0.3)] {
        let lqr = Lqr::new(
            &m,
            &payload(mass_fraction, arm_fraction),
            LqrWeights::crazyflie(),
            DEFAULT_DT,
        )
        .unwrap();
        let rho = lqr.spectral_radius();
        assert!(
            rho < 1.0 - 1e-3,
            "payload {mass_fraction}@{arm_fraction}: ρ = {rho}"
        );
        // Independent check of the eigenvalue moduli via the Schur-based `complex_eigenvalues`
        // of nalgebra on the dynamic matrix.
        let acl = to_d(&lqr.discrete_model().a) - to_d(&lqr.discrete_model().b) * to_d(lqr.gain());
        assert!(acl.complex_eigenvalues().iter().all(|l| l.norm() < 1.0));
    }
    // Also at a 100 Hz control rate.
    let fast = Lqr::new(&m, &m.params, LqrWeights::crazyflie(), 0.01).unwrap();
    assert!(fast.spectral_radius() < 1.0);
}

#[test]
fn warm_start_after_a_mass_change() {
    let m = model();
    let opts = DareOptions::default();
    let iteration = |p: &InertialParams| {
        Lqr::with_solver(
            &m,
            p,
            LqrWeights::crazyflie(),
            DEFAULT_DT,
            RiccatiSolver::Iteration,
            opts,
        )
        .unwrap()
    };
    // +40 % mass at the origin (pure mass change: h and I unchanged).
    let heavy = m
        .params
        .with_point_mass(0.4 * m.params.mass(), Vector3::zeros());
    let slightly = m
        .params
        .with_point_mass(0.01 * m.params.mass(), Vector3::zeros());
    let cold = iteration(&heavy);
    let mut warm = iteration(&m.params);
    let report = warm.redesign(&heavy).unwrap();
    assert!(report.warm_start);
    let cold_it = cold.last_solve().iterations;
    assert!(
        report.iterations < cold_it,
        "warm {} vs cold {}",
        report.iterations,
        cold_it
    );
    let diff =
        (warm.riccati_solution() - cold.riccati_solution()).norm() / cold.riccati_solution().norm();
    assert!(diff < 1e-9, "{diff:e}");
    // The smaller the change, the closer the warm start and the fewer iterations.
    let mut warm_small = iteration(&m.params);
    let small = warm_small.redesign(&slightly).unwrap();
    assert!(
        small.iterations < report.iterations,
        "{} vs {}",
        small.iterations,
        report.iterations
    );
    // Re-solving an unchanged model takes a single step.
    let again = warm.redesign(&heavy).unwrap();
    assert_eq!(again.iterations, 1);
    // Doubling: few steps, same answer.
    let mut sda = Lqr::crazyflie_default().unwrap();
    let r = sda.redesign(&heavy).unwrap();
    assert!(!r.warm_start && r.iterations <= 12);
    let diff =
        (sda.riccati_solution() - cold.riccati_solution()).norm() / cold.riccati_solution().norm();
    assert!(diff < 1e-9, "{diff:e}");
}

#[test]
fn commands_and_saturation() {
    let lqr = Lqr::crazyflie_default().unwrap();
    let t_max = model().max_thrust_per_rotor();
    let trim = lqr.trim_thrusts();
    assert_eq!(lqr.command(&ErrorState::zeros()), trim);
    // Unclamped command is affine in the error: u_trim − K e.
    let e = ErrorState::from_fn(|i, _| 0.01 * (i as f64 - 5.5));
    let u = lqr.command_unclamped(&e);
    let du = lqr.gain() * e;
    for i in 0..4 {
        assert!((u[i] - (trim[i] - du[i])).abs() < 1e-15);
    }
    // A large error saturates, but commands stay in [0, T_max].
    let big = e * 100.0;
    let raw = lqr.command_unclamped(&big);
    assert!(raw.iter().any(|t| *t < 0.0 || *t > t_max));
    let cmd = lqr.command(&big);
    for (c, r) in cmd.iter().zip(&raw) {
        assert!((0.0..=t_max).contains(c));
        assert_eq!(*c, r.clamp(0.0, t_max));
    }
    // Non-finite entries count as zero error.
    let mut nan = ErrorState::zeros();
    nan[3] = f64::NAN;
    assert_eq!(lqr.command(&nan), trim);
}

#[test]
fn redesign_errors_leave_the_controller_unchanged() {
    let mut lqr = Lqr::crazyflie_default().unwrap();
    let k = *lqr.gain();
    let p = *lqr.params();
    let zero_mass = InertialParams::from_array([0.0; 10]);
    assert!(matches!(
        lqr.redesign(&zero_mass),
        Err(ControlError::InvalidParams { .. })
    ));
    let mut nan = p.to_array();
    nan[0] = f64::NAN;
    assert!(matches!(
        lqr.redesign(&InertialParams::from_array(nan)),
        Err(ControlError::NonFinite { .. })
    ));
    // Inertia about the centre of mass not positive definite.
    let mut flat = p.to_array();
    flat[9] = 0.0;
    assert!(lqr.redesign(&InertialParams::from_array(flat)).is_err());
    assert_eq!(*lqr.gain(), k);
    assert_eq!(*lqr.params(), p);

    let m = model();
    assert!(matches!(
        Lqr::new(&m, &m.params, LqrWeights::crazyflie(), 0.0),
        Err(ControlError::InvalidTimeStep { .. })
    ));
    let mut w = LqrWeights::crazyflie();
    w.q[(0, 0)] = -1.0;
    assert!(matches!(
        Lqr::new(&m, &m.params, w, DEFAULT_DT),
        Err(ControlError::Dare(
            DareError::QNotPositiveSemidefinite { .. }
        ))
    ));
}

/// Rigid-body state derivative of the nonlinear plant.
fn derivative(
    params: &InertialParams,
    x: &QuadrotorState,
    u: &[f64; 4],
) -> (Vector3<f64>, Vector3<f64>, Quaternion<f64>, Vector3<f64>) {
    let w = model().wrench_from_thrusts(u);
    let (a, wd) = try_forward_dynamics(params, &w, &x.body_rate).unwrap();
    let qdot = x.attitude.quaternion() * Quaternion::from_imag(x.body_rate) * 0.5;
    (x.velocity, x.attitude * a + GRAVITY_WORLD, qdot, wd)
}

fn rk4_step(params: &InertialParams, x: &QuadrotorState, u: &[f64; 4], h: f64) -> QuadrotorState {
    let add = |x: &QuadrotorState,
               k: &(Vector3<f64>, Vector3<f64>, Quaternion<f64>, Vector3<f64>),
               s: f64| {
        QuadrotorState {
            position: x.position + k.0 * s,
            velocity: x.velocity + k.1 * s,
            attitude: UnitQuaternion::new_normalize(x.attitude.quaternion() + k.2 * s),
            body_rate: x.body_rate + k.3 * s,
        }
    };
    let k1 = derivative(params, x, u);
    let k2 = derivative(params, &add(x, &k1, h / 2.0), u);
    let k3 = derivative(params, &add(x, &k2, h / 2.0), u);
    let k4 = derivative(params, &add(x, &k3, h), u);
    let comb = (
        (k1.0 + k2.0 * 2.0 + k3.0 * 2.0 + k4.0) / 6.0,
        (k1.1 + k2.1 * 2.0 + k3.1 * 2.0 + k4.1) / 6.0,
        (k1.2 + k2.2 * 2.0 + k3.2 * 2.0 + k4.2) / 6.0,
        (k1.3 + k2.3 * 2.0 + k3.3 * 2.0 + k4.3) / 6.0,
    );
    add(x, &comb, h)
}

/// Flies the nonlinear plant with `plant` parameters under `lqr` for `seconds` (commands
/// held for one control period, RK4 at 1 kHz); returns the final state and the largest
/// commanded thrust.
fn fly(
    lqr: &Lqr,
    plant: &InertialParams,
    start: QuadrotorState,
    reference: &QuadrotorState,
    seconds: f64,
) -> (QuadrotorState, f64) {
    let substeps = 20;
    let h = lqr.dt() / substeps as f64;
    let mut x = start;
    let mut max_thrust = 0.0_f64;
    for _ in 0..(seconds / lqr.dt()).round() as usize {
        let u = lqr.command_for(&x, reference);
        max_thrust = u.iter().fold(max_thrust, |a, b| a.max(*b));
        for _ in 0..substeps {
            x = rk4_step(plant, &x, &u, h);
        }
    }
    (x, max_thrust)
}

#[test]
fn nonlinear_flight_converges_and_redesign_removes_the_payload_offset() {
    let m = model();
    let reference = QuadrotorState::hover(Vector3::new(0.0, 0.0, 1.0), 0.5);
    let start = QuadrotorState {
        position: Vector3::new(0.15, -0.1, 0.9),
        velocity: Vector3::new(-0.2, 0.1, 0.0),
        attitude: UnitQuaternion::from_euler_angles(0.1, -0.05, 0.2),
        body_rate: Vector3::new(0.5, -0.3, 0.2),
    };
    let nominal = Lqr::crazyflie_default().unwrap();
    let (x, max_thrust) = fly(&nominal, &m.params, start, &reference, 6.0);
    let e = tagk_control::error_state(&x, &reference);
    assert!(e.amax() < 1e-3, "nominal flight: final error {e}");
    assert!(max_thrust <= m.max_thrust_per_rotor());

    // 30 % payload at 20 % of the arm (diagonal, 2 cm below): without redesign the
    // proportional LQR sags; after redesign the new trim holds the reference exactly.
    let d = 0.2 * m.arm / 2f64.sqrt();
    let plant = m
        .params
        .with_point_mass(0.3 * m.params.mass(), Vector3::new(d, -d, -0.02));
    let (x_old, _) = fly(&nominal, &plant, reference, &reference, 6.0);
    let sag = (x_old.position - reference.position).norm();
    assert!(sag > 0.02, "sag {sag}");
    let mut redesigned = nominal.clone();
    redesigned.redesign(&plant).unwrap();
    let (x_new, _) = fly(&redesigned, &plant, start, &reference, 6.0);
    let e = tagk_control::error_state(&x_new, &reference);
    assert!(e.amax() < 1e-3, "redesigned flight: final error {e}");
}
