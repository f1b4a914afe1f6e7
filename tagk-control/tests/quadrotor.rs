//! Quadrotor trim, linearisation and discretisation against the nonlinear model of
//! `tagk-dynamics` (finite differences) and closed forms.

use nalgebra::{DMatrix, Matrix2, SMatrix, UnitQuaternion, Vector2, Vector3};
use proptest::prelude::*;
use tagk_control::quadrotor::{
    ErrorState, InputMatrix, OperatingPoint, QuadrotorState, StateMatrix, apply_error,
    to_heading_frame, trim_within_limits,
};
use tagk_control::{
    ControlError, discretize, discretize_zoh, error_state, hover_trim, linearize, trim_thrusts,
};
use tagk_dynamics::{GRAVITY_WORLD, InertialParams, QuadrotorModel, try_forward_dynamics};

fn model() -> QuadrotorModel {
    QuadrotorModel::crazyflie_2_1()
}

/// 50 % payload at 30 % of the arm along +x (the protocol's worst case).
fn payload_x() -> InertialParams {
    let m = model();
    m.params
        .with_point_mass(0.5 * m.params.mass(), Vector3::new(0.3 * m.arm, 0.0, 0.0))
}

/// 30 % payload at 20 % of the arm, diagonal, hanging 2 cm below the rotor plane.
fn payload_diag_below() -> InertialParams {
    let m = model();
    let d = 0.2 * m.arm / 2f64.sqrt();
    m.params
        .with_point_mass(0.3 * m.params.mass(), Vector3::new(d, -d, -0.02))
}

/// Nonlinear model: world acceleration `p̈ = R a + g_w` and `ω̇` from the forward dynamics.
fn accelerations(
    params: &InertialParams,
    x: &QuadrotorState,
    u: &[f64; 4],
) -> (Vector3<f64>, Vector3<f64>) {
    let w = model().wrench_from_thrusts(u);
    let (a, wd) = try_forward_dynamics(params, &w, &x.body_rate).unwrap();
    (x.attitude * a + GRAVITY_WORLD, wd)
}

/// Rate of the error state `x ⊟ x_r` for `x = x_r ⊞ e` under input `u`, with the reference
/// moving along its own nominal motion under `u_r`. The attitude-error rate is a central
/// difference in time of `log(R_r(t)ᵀ R(t))` with `R(t+s) = R exp(S(ω s))`.
fn error_rate(
    params: &InertialParams,
    op: &OperatingPoint,
    e: &ErrorState,
    u: &[f64; 4],
) -> ErrorState {
    let x = apply_error(&op.state, e);
    let (acc, wd) = accelerations(params, &x, u);
    let (acc_r, wd_r) = accelerations(params, &op.state, &op.thrusts);
    let delta_at = |s: f64| {
        let r = x.attitude * UnitQuaternion::from_scaled_axis(x.body_rate * s);
        let rr = op.state.attitude * UnitQuaternion::from_scaled_axis(op.state.body_rate * s);
        (rr.inverse() * r).scaled_axis()
    };
    let eps = 1e-4;
    let ddelta = (delta_at(eps) - delta_at(-eps)) / (2.0 * eps);
    let mut out = ErrorState::zeros();
    out.fixed_rows_mut::<3>(0)
        .copy_from(&(x.velocity - op.state.velocity));
    out.fixed_rows_mut::<3>(3).copy_from(&(acc - acc_r));
    out.fixed_rows_mut::<3>(6).copy_from(&ddelta);
    out.fixed_rows_mut::<3>(9).copy_from(&(wd - wd_r));
    out
}

fn finite_difference_jacobians(
    params: &InertialParams,
    op: &OperatingPoint,
) -> (StateMatrix, InputMatrix) {
    let h = 1e-5;
    let mut a = StateMatrix::zeros();
    for j in 0..12 {
        let mut ep = ErrorState::zeros();
        ep[j] = h;
        let col = (error_rate(params, op, &ep, &op.thrusts)
            - error_rate(params, op, &(-ep), &op.thrusts))
            / (2.0 * h);
        a.set_column(j, &col);
    }
    let hu = 1e-6;
    let mut b = InputMatrix::zeros();
    for j in 0..4 {
        let (mut up, mut um) = (op.thrusts, op.thrusts);
        up[j] += hu;
        um[j] -= hu;
        let z = ErrorState::zeros();
        b.set_column(
            j,
            &((error_rate(params, op, &z, &up) - error_rate(params, op, &z, &um)) / (2.0 * hu)),
        );
    }
    (a, b)
}

fn assert_close<const R: usize, const C: usize>(
    what: &str,
    got: &SMatrix<f64, R, C>,
    want: &SMatrix<f64, R, C>,
    rel: f64,
) {
    let scale = want.amax().max(1.0);
    let err = (got - want).amax();
    assert!(
        err <= rel * scale,
        "{what}: max error {err:e} (scale {scale:e})\n{got}\n{want}"
    );
}

#[test]
fn hover_trim_holds_in_the_nonlinear_model() {
    let m = model();
    for (name, params) in [
        ("nominal", m.params),
        ("payload +x", payload_x()),
        ("payload diagonal, below", payload_diag_below()),
    ] {
        for yaw in [0.0, 0.7, -2.5] {
            let op = hover_trim(&m, &params, Vector3::new(1.0, -2.0, 0.5), yaw).unwrap();
            let (acc, wd) = accelerations(&params, &op.state, &op.thrusts);
            assert!(acc.norm() < 1e-12, "{name}: p̈ = {acc}");
            assert!(wd.norm() < 1e-9, "{name}: ω̇ = {wd}");
            let total: f64 = op.thrusts.iter().sum();
            assert!((total - params.mass() * 9.81).abs() < 1e-14);
        }
    }
    // Symmetric vehicle: equal thrusts. Payload at +x: the front rotors (M1, M4) carry more.
    let t = hover_trim(&m, &m.params, Vector3::zeros(), 0.0)
        .unwrap()
        .thrusts;
    assert!(t.iter().all(|x| (x - t[0]).abs() < 1e-15));
    let t = hover_trim(&m, &payload_x(), Vector3::zeros(), 0.0)
        .unwrap()
        .thrusts;
    assert!(t[0] > t[1] + 0.03 && (t[0] - t[3]).abs() < 1e-12 && (t[1] - t[2]).abs() < 1e-12);
}

#[test]
fn trim_feasibility_and_errors() {
    let m = model();
    // The protocol's worst case (50 % payload at 30 % of the arm) needs more than the
    // per-rotor maximum k_f ω_max² = 0.14375 N on the front rotors; 30 % at 20 % does not.
    let worst = hover_trim(&m, &payload_x(), Vector3::zeros(), 0.0).unwrap();
    assert!(!trim_within_limits(&m, &worst));
    let mild = hover_trim(&m, &payload_diag_below(), Vector3::zeros(), 0.0).unwrap();
    assert!(trim_within_limits(&m, &mild));
    // A tilted vehicle cannot hold zero acceleration.
    let mut tilted = QuadrotorState::hover(Vector3::zeros(), 0.0);
    tilted.attitude = UnitQuaternion::from_scaled_axis(Vector3::new(0.2, 0.0, 0.0));
    assert!(matches!(
        trim_thrusts(&m, &m.params, &tilted, &Vector3::zeros(), &Vector3::zeros()),
        Err(ControlError::TrimInfeasible { .. })
    ));
    // ... but it can hold the matching lateral acceleration.
    let acc = tilted.attitude * Vector3::new(0.0, 0.0, 9.81) + GRAVITY_WORLD;
    let u = trim_thrusts(&m, &m.params, &tilted, &acc, &Vector3::zeros()).unwrap();
    let (acc_check, _) = accelerations(&m.params, &tilted, &u);
    assert!((acc_check - acc).norm() < 1e-12);
    // Bad parameters.
    let zero_mass = InertialParams::from_array([0.0; 10]);
    assert!(matches!(
        hover_trim(&m, &zero_mass, Vector3::zeros(), 0.0),
        Err(ControlError::InvalidParams { .. })
    ));
    let mut nan = m.params.to_array();
    nan[4] = f64::NAN;
    assert!(matches!(
        hover_trim(&m, &InertialParams::from_array(nan), Vector3::zeros(), 0.0),
        Err(ControlError::NonFinite { .. })
    ));
}

#[test]
fn linearisation_at_hover_matches_finite_differences() {
    let m = model();
    for params in [m.params, payload_x(), payload_diag_below()] {
        let op = hover_trim(&m, &params, Vector3::new(0.3, 0.1, 1.0), 0.4).unwrap();
        let lin = linearize(&m, &params, &op).unwrap();
        let (a_fd, b_fd) = finite_difference_jacobians(&params, &op);
        assert_close("A", &lin.a, &a_fd, 1e-7);
        assert_close("B", &lin.b, &b_fd, 1e-7);
    }
}

#[test]
fn linearisation_at_a_general_reference_matches_finite_differences() {
    // Tilted, moving and spinning fast enough for the gyroscopic and centripetal terms to
    // matter, with arbitrary (non-trim) thrusts and a centre of mass off all axes.
    let m = model();
    let params = payload_diag_below();
    let op = OperatingPoint {
        state: QuadrotorState {
            position: Vector3::new(1.0, 2.0, 3.0),
            velocity: Vector3::new(0.4, -0.1, 0.2),
            attitude: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
            body_rate: Vector3::new(2.0, -1.5, 3.0),
        },
        thrusts: [0.09, 0.11, 0.10, 0.12],
    };
    let lin = linearize(&m, &params, &op).unwrap();
    let (a_fd, b_fd) = finite_difference_jacobians(&params, &op);
    assert_close("A", &lin.a, &a_fd, 1e-7);
    assert_close("B", &lin.b, &b_fd, 1e-7);
    // The gyroscopic block is really exercised.
    assert!(lin.a.fixed_view::<3, 3>(9, 9).amax() > 0.1);
}

#[test]
fn zoh_at_hover_equals_the_finite_series() {
    // At hover A is nilpotent (A⁴ = 0: ω → δ → v → p), so the ZOH is a finite sum:
    // A_d = Σ_{k<4} (A dt)^k / k!,  B_d = Σ_{k<4} A^k dt^{k+1} / (k+1)! · B.
    let m = model();
    let params = payload_diag_below();
    let op = hover_trim(&m, &params, Vector3::zeros(), 0.3).unwrap();
    let lin = linearize(&m, &params, &op).unwrap();
    let a = lin.a;
    assert!((a * a * a * a).amax() < 1e-12);
    let dt = 0.02;
    let d = discretize(&lin, dt).unwrap();
    let i = StateMatrix::identity();
    let a2 = a * a;
    let a3 = a2 * a;
    let ad = i + a * dt + a2 * (dt * dt / 2.0) + a3 * (dt.powi(3) / 6.0);
    let bd =
        (i * dt + a * (dt * dt / 2.0) + a2 * (dt.powi(3) / 6.0) + a3 * (dt.powi(4) / 24.0)) * lin.b;
    assert_close("A_d", &d.a, &ad, 1e-13);
    assert_close("B_d", &d.b, &bd, 1e-12);
}

#[test]
fn zoh_of_a_harmonic_oscillator_matches_closed_form() {
    // ẋ = [[0, 1], [−w², 0]] x + [0, 1]ᵀ u:
    // A_d = [[c, s/w], [−w s, c]],  B_d = [(1 − c)/w², s/w]ᵀ with c = cos(w dt), s = sin(w dt).
    // The larger w·dt need several squarings.
    for &(w, dt) in &[(2.0f64, 0.02f64), (30.0, 0.7), (5.0, 3.0), (0.5, 1e-6)] {
        let (s, c) = (w * dt).sin_cos();
        let ad_exact = Matrix2::new(c, s / w, -w * s, c);
        let bd_exact = Vector2::new((1.0 - c) / (w * w), s / w);
        // Static path.
        let a = Matrix2::new(0.0, 1.0, -w * w, 0.0);
        let b = Vector2::new(0.0, 1.0);
        let (ad, bd) = discretize_zoh(&a, &b, dt).unwrap();
        let tol = 1e-12 * (w * dt).max(1.0).powi(2);
        assert!(
            (ad - ad_exact).amax() < tol * w.max(1.0),
            "w={w} dt={dt}: {ad} vs {ad_exact}"
        );
        assert!(
            (bd - bd_exact).amax() < tol,
            "w={w} dt={dt}: {bd} vs {bd_exact}"
        );
        // Dynamic path: same numbers.
        let (add, bdd) = discretize_zoh(
            &DMatrix::from_column_slice(2, 2, a.as_slice()),
            &DMatrix::from_column_slice(2, 1, b.as_slice()),
            dt,
        )
        .unwrap();
        assert_eq!(add.as_slice(), ad.as_slice());
        assert_eq!(bdd.as_slice(), bd.as_slice());
        // nalgebra's Padé exponential of the augmented matrix (the oracle of the tests
        // below) against the same closed form.
        let (ade, bde) = zoh_by_augmented_expm(
            &DMatrix::from_column_slice(2, 2, a.as_slice()),
            &DMatrix::from_column_slice(2, 1, b.as_slice()),
            dt,
        );
        for i in 0..2 {
            for j in 0..2 {
                assert!((ade[(i, j)] - ad_exact[(i, j)]).abs() < tol * w.max(1.0));
            }
            assert!((bde[(i, 0)] - bd_exact[i]).abs() < tol);
        }
    }
}

/// `exp([[A, B], [0, 0]] dt)` by nalgebra's Padé scaling-and-squaring exponential.
fn zoh_by_augmented_expm(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    dt: f64,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = b.shape();
    let mut aug = DMatrix::<f64>::zeros(n + m, n + m);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * dt));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * dt));
    let e = aug.exp();
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

#[test]
fn zoh_of_the_spinning_quadrotor_matches_the_augmented_matrix_exponential() {
    // Non-nilpotent A (gyroscopic and attitude-rate coupling), at 50 Hz and at 2 Hz (squaring).
    let m = model();
    let params = payload_diag_below();
    let op = OperatingPoint {
        state: QuadrotorState {
            position: Vector3::zeros(),
            velocity: Vector3::new(0.4, -0.1, 0.2),
            attitude: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
            body_rate: Vector3::new(2.0, -1.5, 3.0),
        },
        thrusts: [0.09, 0.11, 0.10, 0.12],
    };
    let lin = linearize(&m, &params, &op).unwrap();
    for dt in [0.02, 0.5] {
        let d = discretize(&lin, dt).unwrap();
        let (ad, bd) = zoh_by_augmented_expm(
            &DMatrix::from_column_slice(12, 12, lin.a.as_slice()),
            &DMatrix::from_column_slice(12, 4, lin.b.as_slice()),
            dt,
        );
        let ea = (DMatrix::from_column_slice(12, 12, d.a.as_slice()) - &ad).amax() / ad.amax();
        let eb = (DMatrix::from_column_slice(12, 4, d.b.as_slice()) - &bd).amax() / bd.amax();
        assert!(ea < 1e-12 && eb < 1e-12, "dt={dt}: {ea:e} {eb:e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    /// Random 5×5 / 5×2 systems, norms from tiny to large: the Taylor ZOH agrees with the
    /// augmented Padé exponential.
    #[test]
    fn zoh_matches_augmented_expm_on_random_systems(
        entries in prop::collection::vec(-1.0f64..1.0, 35),
        log_scale in -3.0f64..1.5,
    ) {
        let scale = 10f64.powf(log_scale);
        let a = DMatrix::from_column_slice(5, 5, &entries[..25]) * scale;
        let b = DMatrix::from_column_slice(5, 2, &entries[25..]);
        let (ad, bd) = discretize_zoh(&a, &b, 0.1).unwrap();
        let (ad_ref, bd_ref) = zoh_by_augmented_expm(&a, &b, 0.1);
        prop_assert!((&ad - &ad_ref).amax() <= 1e-11 * ad_ref.amax());
        prop_assert!((&bd - &bd_ref).amax() <= 1e-11 * bd_ref.amax().max(1e-300));
    }
}

#[test]
fn discretisation_errors() {
    let m = model();
    let op = hover_trim(&m, &m.params, Vector3::zeros(), 0.0).unwrap();
    let lin = linearize(&m, &m.params, &op).unwrap();
    for dt in [0.0, -0.01, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            discretize(&lin, dt),
            Err(ControlError::InvalidTimeStep { .. })
        ));
    }
    let a = DMatrix::<f64>::zeros(2, 3);
    let b = DMatrix::<f64>::zeros(2, 1);
    assert!(matches!(
        discretize_zoh(&a, &b, 0.1),
        Err(ControlError::ShapeMismatch { .. })
    ));
    let a = DMatrix::from_element(2, 2, f64::NAN);
    assert!(matches!(
        discretize_zoh(&a, &b, 0.1),
        Err(ControlError::NonFinite { .. })
    ));
}

#[test]
fn hover_model_is_yaw_equivariant() {
    // A(ψ) = T A(0) Tᵀ and B(ψ) = T B(0), T = blockdiag(R_z(ψ), R_z(ψ), 1, 1): what
    // `to_heading_frame` and `Lqr::command_for` rely on.
    let m = model();
    let params = payload_diag_below();
    let psi = 1.234;
    let lin0 = linearize(
        &m,
        &params,
        &hover_trim(&m, &params, Vector3::zeros(), 0.0).unwrap(),
    )
    .unwrap();
    let lin = linearize(
        &m,
        &params,
        &hover_trim(&m, &params, Vector3::zeros(), psi).unwrap(),
    )
    .unwrap();
    // Tᵀ applied column-wise is `to_heading_frame`.
    let mut tt = StateMatrix::zeros();
    for j in 0..12 {
        let mut ej = ErrorState::zeros();
        ej[j] = 1.0;
        tt.set_column(j, &to_heading_frame(&ej, psi));
    }
    let t = tt.transpose();
    assert_close("A(ψ)", &lin.a, &(t * lin0.a * tt), 1e-12);
    assert_close("B(ψ)", &lin.b, &(t * lin0.b), 1e-12);
}

proptest! {
    #![proptest_config(ProptestConfig {
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    #[test]
    fn error_state_round_trips(
        p in prop::array::uniform3(-5.0f64..5.0),
        v in prop::array::uniform3(-2.0f64..2.0),
        att in prop::array::uniform3(-1.5f64..1.5),
        w in prop::array::uniform3(-3.0f64..3.0),
        e in prop::array::uniform12(-1.0f64..1.0),
    ) {
        let reference = QuadrotorState {
            position: Vector3::from(p),
            velocity: Vector3::from(v),
            attitude: UnitQuaternion::from_scaled_axis(Vector3::from(att)),
            body_rate: Vector3::from(w),
        };
        let e = ErrorState::from_column_slice(&e);
        let x = apply_error(&reference, &e);
        let back = error_state(&x, &reference);
        prop_assert!((back - e).amax() < 1e-12);
        prop_assert!(error_state(&reference, &reference).amax() < 1e-15);
    }
}
