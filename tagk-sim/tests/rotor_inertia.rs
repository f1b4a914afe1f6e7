//! The plant's `rotor-inertia` conserves angular momentum. With no external torque about the
//! centre of mass the total `L = R (I_c Ω + h_r)` stays constant while the rotors change speed.
//! Here `h_r = −J_r Σ sᵢ ωᵢ e_z` is the rotors' own momentum, written out in this test (not
//! through the plant's helpers). Thrust and drag torque are switched off (`k_f ≈ 0`, `k_m = 0`);
//! gravity acts at the centre of mass.

use nalgebra::{Matrix3, Vector3};
use tagk_dynamics::{InertialParams, QuadrotorModel};
use tagk_sim::plant_effects::{MotorLag, RotorInertia};
use tagk_sim::{Plant, PlantEffects, PlantState};

/// A large rotor inertia (kg m²; eight Crazyflie rotors), so that the rotors' momentum is far
/// above rounding. The gyroscopic coupling `J_r H / I` stays slow next to the 1 ms step.
const J_R: f64 = 2e-7;

/// The body with its centre of mass off the origin (so the jump's linear part is tested too).
fn body() -> InertialParams {
    QuadrotorModel::crazyflie_2_1()
        .params
        .with_point_mass(0.006, Vector3::new(0.012, -0.007, 0.009))
}

/// No thrust to speak of (`k_f = 10⁻³⁰`: the mixer divides by it), no drag torque: the rotors
/// act on the body through their inertia only.
fn silent_rotors() -> QuadrotorModel {
    let mut model = QuadrotorModel::crazyflie_2_1();
    model.k_f = 1e-30;
    model.k_m = 0.0;
    model
}

/// The rotor commands at step `k`: each rotor on its own slow wave, so `Σ sᵢ ωᵢ` changes.
fn command(k: usize) -> [f64; 4] {
    let t = k as f64 * 1e-3;
    [
        1500.0 + 600.0 * (7.0 * t).sin(),
        1400.0 + 500.0 * (5.0 * t + 1.0).sin(),
        1600.0 - 700.0 * (3.0 * t).cos(),
        1500.0 + 400.0 * (11.0 * t).sin(),
    ]
}

/// The total angular momentum about the centre of mass, world frame \[kg m²/s\], and the
/// velocity of the centre of mass, world frame \[m/s\].
fn momentum(
    state: &PlantState,
    params: &InertialParams,
    spins: &[f64; 4],
) -> (Vector3<f64>, Vector3<f64>) {
    let c = params.com();
    let m = params.mass();
    // I_c = I_o − m (|c|² 1 − c cᵀ) (parallel axis), written out here.
    let i_c: Matrix3<f64> =
        params.inertia_origin() - m * (Matrix3::identity() * c.dot(&c) - c * c.transpose());
    let spin_sum: f64 = state
        .rotor_speeds
        .iter()
        .zip(spins)
        .map(|(w, s)| s * w)
        .sum();
    let h_rotors = Vector3::new(0.0, 0.0, -J_R * spin_sum);
    let l_body = i_c * state.body_rate + h_rotors;
    let v_com = state.velocity + state.attitude * state.body_rate.cross(&c);
    (state.attitude * l_body, v_com)
}

/// Flies `steps` steps of 1 ms under [`command`] and returns the largest drift of the
/// angular momentum relative to its start, and of the centre of mass's velocity net of
/// gravity \[m/s\].
fn drift(effects: PlantEffects, steps: usize) -> (f64, f64) {
    let params = body();
    let model = silent_rotors();
    let spins = model.spin_directions;
    let mut state = PlantState::at_rest(Vector3::new(0.0, 0.0, 5.0));
    state.body_rate = Vector3::new(0.4, -0.7, 1.3);
    state.rotor_speeds = command(0);
    let mut plant = Plant::new(model, params, effects, state).unwrap();
    let (l0, v0) = momentum(plant.state(), &params, &spins);
    let (mut worst_l, mut worst_v) = (0.0f64, 0.0f64);
    let dt = 1e-3;
    for k in 0..steps {
        plant.step(&command(k + 1), dt);
        assert!(plant.is_finite(), "the state diverged at step {k}");
        let (l, v) = momentum(plant.state(), &params, &spins);
        let t = (k + 1) as f64 * dt;
        let gravity = Vector3::new(0.0, 0.0, -9.81) * t;
        worst_l = worst_l.max((l - l0).norm() / l0.norm());
        worst_v = worst_v.max((v - v0 - gravity).norm());
    }
    (worst_l, worst_v)
}

#[test]
fn angular_momentum_is_conserved_with_a_motor_lag() {
    let effects = PlantEffects {
        motor_lag: Some(MotorLag {
            time_constant: 0.02,
        }),
        rotor_inertia: Some(RotorInertia { inertia: J_R }),
        ..PlantEffects::none()
    };
    let (l, v) = drift(effects, 3000);
    // RK4 on the lag: 2·10⁻⁹ over 3 s at 1 ms.
    assert!(l < 1e-8, "relative drift of L {l:e}");
    assert!(v < 1e-9, "drift of the centre of mass's velocity {v:e} m/s");
}

#[test]
fn angular_momentum_is_conserved_across_the_jumps_without_a_motor_lag() {
    let effects = PlantEffects {
        rotor_inertia: Some(RotorInertia { inertia: J_R }),
        ..PlantEffects::none()
    };
    let (l, v) = drift(effects, 3000);
    assert!(l < 1e-9, "relative drift of L {l:e}");
    assert!(v < 1e-9, "drift of the centre of mass's velocity {v:e} m/s");
}

/// The check can fail: without the effect the rotors' momentum changes and the body's does
/// not follow, so the total drifts far beyond the tolerance above.
#[test]
fn without_the_effect_the_total_drifts() {
    let effects = PlantEffects {
        motor_lag: Some(MotorLag {
            time_constant: 0.02,
        }),
        ..PlantEffects::none()
    };
    let (l, _) = drift(effects, 3000);
    assert!(l > 1e-3, "relative drift of L {l:e}");
}

/// The yaw reaction has the sign of the drag reaction: speeding up a rotor with `s = +1`
/// turns the body about `+z`, from rest.
#[test]
fn speeding_up_a_positive_rotor_turns_the_body_positive() {
    let model = silent_rotors();
    assert_eq!(model.spin_directions[0], 1.0);
    let effects = PlantEffects {
        motor_lag: Some(MotorLag {
            time_constant: 0.02,
        }),
        rotor_inertia: Some(RotorInertia { inertia: J_R }),
        ..PlantEffects::none()
    };
    let mut state = PlantState::at_rest(Vector3::new(0.0, 0.0, 5.0));
    state.rotor_speeds = [1000.0; 4];
    let mut plant = Plant::new(
        model,
        QuadrotorModel::crazyflie_2_1().params,
        effects,
        state,
    )
    .unwrap();
    for _ in 0..50 {
        plant.step(&[2000.0, 1000.0, 1000.0, 1000.0], 1e-3);
    }
    assert!(
        plant.state().body_rate.z > 0.0,
        "{}",
        plant.state().body_rate
    );
}
