//! The simulator's extension point, [`PlantEffect`]: built-ins through the trait fly as the
//! built-in switches, a user's effect acts as its closed form says, and a plant built from a
//! model's numbers ([`PlantModel`]) applies the coefficients it was given.

use nalgebra::{UnitQuaternion, Vector3};
use tagk_dynamics::vehicle::Vehicle;
use tagk_dynamics::{EffectKind, GRAVITY_WORLD, QuadrotorModel, Wrench};
use tagk_sim::plant_effects::{
    BodyBias, EffectState, GroundEffect, LinearDrag, QuadraticDrag, RotorDrag, ThrustGain,
};
use tagk_sim::plant_model::PlantModel;
use tagk_sim::*;

/// A force along world x growing linearly in time, `F(t) = (c t, 0, 0)` \[N\], applied at the
/// body origin (no torque).
#[derive(Debug)]
struct Ramp {
    /// Slope \[N/s\].
    slope: f64,
}

impl PlantEffect for Ramp {
    fn name(&self) -> &str {
        "ramp"
    }
    fn wrench(&self, s: &EffectState<'_>) -> Wrench {
        let f_world = Vector3::new(self.slope * s.time, 0.0, 0.0);
        Wrench {
            force: s.attitude.inverse_transform_vector(&f_world),
            torque: Vector3::zeros(),
        }
    }
}

/// A user's constant body force and torque: the built-in body bias written outside the crate.
#[derive(Debug)]
struct MyBias(BodyBias);

impl PlantEffect for MyBias {
    fn name(&self) -> &str {
        "my-bias"
    }
    fn wrench(&self, _s: &EffectState<'_>) -> Wrench {
        Wrench {
            force: Vector3::from(self.0.force),
            torque: Vector3::from(self.0.torque),
        }
    }
}

fn level_at(z: f64) -> PlantState {
    PlantState::at_rest(Vector3::new(0.0, 0.0, z))
}

/// Free fall (rotors stopped) under `F(t) = (c t, 0, 0)`: the body stays level, and the
/// closed form is `x(t) = c t³ / (6 m)`, `z(t) = z₀ − g t² / 2`. RK4 integrates both exactly
/// (their accelerations are polynomials of degree ≤ 1 in time), so they agree to rounding
/// only if every Runge–Kutta stage sees its own time.
#[test]
fn a_user_force_ramp_moves_the_body_as_its_closed_form() {
    let model = QuadrotorModel::crazyflie_2_1();
    let m = model.params.mass();
    let slope = 0.02;
    let mut plant = Plant::new(model, model.params, PlantEffects::none(), level_at(10.0))
        .unwrap()
        .with_effect(Box::new(Ramp { slope }));
    let dt = 0.002;
    for _ in 0..500 {
        plant.step(&[0.0; 4], dt);
    }
    let t = plant.time();
    assert!((t - 1.0).abs() < 1e-12);
    let s = plant.state();
    let x = slope * t.powi(3) / (6.0 * m);
    let z = 10.0 - 0.5 * 9.81 * t * t;
    assert!((s.position.x - x).abs() < 1e-12, "{} vs {x}", s.position.x);
    assert!((s.position.z - z).abs() < 1e-12, "{} vs {z}", s.position.z);
    assert!((s.velocity.x - slope * t * t / (2.0 * m)).abs() < 1e-12);
    assert_eq!(s.attitude, UnitQuaternion::identity());
    // The force the closed form describes is not small: 0.1 m in one second.
    assert!(x > 0.09);
}

/// The wrench that acts is the rotors' wrench plus the user's force, bit for bit.
#[test]
fn the_acting_wrench_is_the_rotors_plus_the_user_effect_exactly() {
    let model = QuadrotorModel::crazyflie_2_1();
    let bias = BodyBias {
        force: [0.004, -0.002, 0.001],
        torque: [1e-5, -2e-5, 3e-6],
    };
    let plant = Plant::new(model, model.params, PlantEffects::none(), level_at(1.0))
        .unwrap()
        .with_effect(Box::new(MyBias(bias)));
    let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
    let acting = plant.accelerations(&speeds).wrench;
    let rotors = model.wrench_from_rotor_speeds(&speeds);
    assert_eq!(acting.force, rotors.force + Vector3::from(bias.force));
    assert_eq!(acting.torque, rotors.torque + Vector3::from(bias.torque));
    assert_eq!(plant.acting_effects().len(), 1);
    assert_eq!(plant.acting_effects()[0].name(), "my-bias");
}

/// Each wrench-like built-in given to an ideal plant as a `Box<dyn PlantEffect>` flies the
/// same bits as its switch in [`PlantEffects`], over 2 s of changing commands with the body
/// turning and moving (and near the ground, for the ground effect).
#[test]
fn built_ins_through_the_trait_fly_as_their_switches() {
    let model = QuadrotorModel::crazyflie_2_1();
    let cases: Vec<(EffectKind, Box<dyn PlantEffect>)> = vec![
        (EffectKind::LinearDrag, Box::new(LinearDrag::crazyflie())),
        (
            EffectKind::QuadraticDrag,
            Box::new(QuadraticDrag::crazyflie()),
        ),
        (EffectKind::RotorDrag, Box::new(RotorDrag::crazyflie())),
        (EffectKind::BodyBias, Box::new(BodyBias::crazyflie())),
        (EffectKind::ThrustGain, Box::new(ThrustGain::crazyflie())),
        (
            EffectKind::GroundEffect,
            Box::new(GroundEffect::crazyflie()),
        ),
    ];
    let start = PlantState {
        position: Vector3::new(0.0, 0.0, 0.05),
        velocity: Vector3::new(0.8, -0.5, 0.3),
        attitude: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        body_rate: Vector3::new(0.5, -0.4, 0.2),
        rotor_speeds: [0.0; 4],
    };
    for (kind, effect) in cases {
        let switch = PlantEffects::only(kind).unwrap();
        let mut a = Plant::new(model, model.params, switch, start).unwrap();
        let mut b = Plant::new(model, model.params, PlantEffects::none(), start)
            .unwrap()
            .with_effect(effect);
        for k in 0..1000 {
            let u = 1900.0 + 300.0 * (0.01 * k as f64).sin();
            let speeds = [u, 2000.0, 4000.0 - u, 2050.0];
            a.step(&speeds, 0.002);
            b.step(&speeds, 0.002);
        }
        assert_eq!(a.state(), b.state(), "{kind}");
        assert_ne!(a.state().position, start.position, "{kind}");
    }
}

/// A user effect through the configuration's builder flies exactly as the built-in it
/// copies (a closed-loop flight with the controller), and differently from no effect.
#[test]
fn a_user_effect_through_the_builder_is_felt_by_the_controller() {
    let base = SimConfig {
        duration: 4.0,
        seed: 7,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        ..SimConfig::default()
    };
    let built_in = SimConfig {
        effects: PlantEffects::only(EffectKind::BodyBias).unwrap(),
        ..base.clone()
    };
    let user = base
        .clone()
        .with_plant_effect(Box::new(MyBias(BodyBias::crazyflie())));
    let a = simulate(&built_in).unwrap().log;
    let b = simulate(&user).unwrap().log;
    let none = simulate(&base).unwrap().log;
    assert_eq!(a, b);
    assert_ne!(a.position, none.position);
    // The controller holds the path against the bias with more roll torque (x torque bias).
    assert_ne!(a.wrench, none.wrench);
}

/// A vehicle flown through [`PlantModel`] with a chosen linear-drag coefficient `D`: the
/// drag force, recovered from the log alone as `m Rᵀ (p̈ − g) − b_force` (instantaneous
/// physics-rate samples, ideal sensing) and regressed per axis on the body velocity `Rᵀ v`,
/// is `−D v_b` with the `D` given.
#[test]
fn a_plant_from_a_model_applies_the_drag_it_was_given() {
    let vehicle = Vehicle::crazyflie_2_1();
    let theta = QuadrotorModel::crazyflie_2_1().params.to_array();
    let d = [0.03, 0.02, 0.04];
    let model = PlantModel::new(&vehicle, &theta, &[(EffectKind::LinearDrag, d.to_vec())]).unwrap();
    let config = model.configure(SimConfig {
        duration: 10.0,
        seed: 11,
        payload: PayloadSchedule::None,
        adaptation: Adaptation::Nominal,
        record_log: true,
        log_rate: LogRate::Physics,
        ..SimConfig::default()
    });
    let log = simulate(&config).unwrap().log;
    let accel = log.accel.as_ref().expect("physics-rate logs hold p̈");
    let m = theta[0];
    let (mut num, mut den) = ([0.0; 3], [0.0; 3]);
    for (((acc, att), vel), b) in accel
        .iter()
        .zip(&log.attitude)
        .zip(&log.velocity)
        .zip(&log.wrench)
    {
        let [w, x, y, z] = *att;
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
        let a_proper = q.inverse_transform_vector(&(Vector3::from(*acc) - GRAVITY_WORLD));
        let v_b = q.inverse_transform_vector(&Vector3::from(*vel));
        for k in 0..3 {
            let drag = m * a_proper[k] - b[k];
            num[k] -= drag * v_b[k];
            den[k] += v_b[k] * v_b[k];
        }
    }
    for k in 0..3 {
        let fitted = num[k] / den[k];
        assert!(
            (fitted / d[k] - 1.0).abs() < 1e-9,
            "axis {k}: fitted {fitted}, given {}",
            d[k]
        );
    }
}

#[test]
fn plant_model_refuses_bad_numbers_by_name() {
    let vehicle = Vehicle::crazyflie_2_1();
    let theta = QuadrotorModel::crazyflie_2_1().params.to_array();
    let wrong_count = PlantModel::new(&vehicle, &theta, &[(EffectKind::LinearDrag, vec![0.1])]);
    assert!(matches!(
        wrong_count,
        Err(SimError::EffectCoefficients {
            expected: 3,
            got: 1,
            ..
        })
    ));
    let bad_tau = PlantModel::new(&vehicle, &theta, &[(EffectKind::MotorLag, vec![-0.02])]);
    assert!(matches!(bad_tau, Err(SimError::InvalidParameter { .. })));
    let mut massless = theta;
    massless[0] = 0.0;
    assert!(matches!(
        PlantModel::new(&vehicle, &massless, &[]),
        Err(SimError::NonPositiveMass { .. })
    ));
    // No coefficient: the Crazyflie default.
    let default = PlantModel::new(&vehicle, &theta, &[(EffectKind::Wind, vec![])]).unwrap();
    assert_eq!(
        default.effects,
        PlantEffects::only(EffectKind::Wind).unwrap()
    );
}

/// The acting wrench of the plant before the trait, written out as it was: the thrust
/// multiplier `(1 + ε) · ground ratio`, the rotors' wrench of the scaled thrusts, plus the
/// closed struct's sum (rotor drag at the hubs, linear drag, quadratic drag, body bias, in this
/// order, on the air-relative velocity).
fn wrench_before_the_trait(
    model: &QuadrotorModel,
    e: &PlantEffects,
    s: &PlantState,
    rotor: &[f64; 4],
) -> Wrench {
    let mut k = 1.0;
    if let Some(g) = &e.thrust_gain {
        k *= 1.0 + g.relative_error;
    }
    if let Some(g) = &e.ground_effect {
        k *= g.thrust_ratio(s.position.z);
    }
    // Added after the trait: the battery's factor at time 0 (the plants here are new).
    if let Some(b) = &e.battery_voltage {
        let v = b.initial_voltage - b.sag * rotor.iter().map(|w| w * w).sum::<f64>();
        k *= 1.0 + b.beta * (v - b.reference_voltage) / b.reference_voltage;
    }
    // Added after the trait: the per-rotor factors of a rotor imbalance.
    let thrusts: [f64; 4] = match &e.rotor_imbalance {
        None => rotor.map(|w| k * model.k_f * w * w),
        Some(b) => std::array::from_fn(|i| {
            k * (1.0 + b.relative_errors[i]) * model.k_f * rotor[i] * rotor[i]
        }),
    };
    let mut wrench = model.wrench_from_thrusts(&thrusts);
    let mut f = Vector3::zeros();
    let mut torque = Vector3::zeros();
    let wind = e
        .wind
        .map_or_else(Vector3::zeros, |w| Vector3::from(w.velocity));
    let v_air_b = s.attitude.inverse_transform_vector(&(s.velocity - wind));
    if let Some(d) = e.acting_rotor_drag() {
        let w = d.wrench(&v_air_b, &s.body_rate, rotor, &model.rotor_positions);
        f += w.force;
        torque += w.torque;
    }
    if let Some(d) = &e.linear_drag {
        f -= Vector3::from(d.coefficients).component_mul(&v_air_b);
    }
    if let Some(d) = &e.quadratic_drag {
        for i in 0..3 {
            f[i] -= 0.5 * d.air_density * d.cd_area[i] * v_air_b[i].abs() * v_air_b[i];
        }
    }
    if let Some(b) = &e.body_bias {
        f += Vector3::from(b.force);
        torque += Vector3::from(b.torque);
    }
    // Added after the trait: each hub's thrust loss `−k_in ω_i (v_z + p y_i − q x_i)`.
    if let Some(inflow) = &e.rotor_inflow {
        let (mut fi, mut ti) = (Vector3::zeros(), Vector3::zeros());
        for (w, r) in rotor.iter().zip(&model.rotor_positions) {
            let axial = v_air_b.z + (s.body_rate.x * r.y - s.body_rate.y * r.x);
            let hub = Vector3::new(0.0, 0.0, -(inflow.coefficient * axial) * w);
            fi += hub;
            ti += r.cross(&hub);
        }
        f += fi;
        torque += ti;
    }
    wrench.force += f;
    wrench.torque += torque;
    // The rotor inertia without a motor lag: its gyroscopic torque J_r H (q, −p, 0) alone
    // (constant speeds within a step), H = Σ sᵢ ωᵢ, written out.
    if let Some(r) = &e.rotor_inertia {
        let h: f64 = (0..4).map(|i| model.spin_directions[i] * rotor[i]).sum();
        let (p, q) = (s.body_rate.x, s.body_rate.y);
        wrench.torque += Vector3::new(r.inertia * h * q, -(r.inertia * h) * p, 0.0);
    }
    wrench
}

/// Every set of built-ins (each alone, all wrench-like ones together, with and without wind)
/// acts through the trait with the bits of the closed struct it replaced, on states spread
/// over attitudes, velocities, rates, heights and rotor speeds.
#[test]
fn built_ins_through_the_trait_give_the_wrench_of_before() {
    let model = QuadrotorModel::crazyflie_2_1();
    let mut sets: Vec<PlantEffects> = PlantEffects::supported()
        .map(|k| PlantEffects::only(k).unwrap())
        .collect();
    let all = [
        EffectKind::LinearDrag,
        EffectKind::QuadraticDrag,
        EffectKind::RotorDrag,
        EffectKind::GroundEffect,
        EffectKind::BodyBias,
        EffectKind::ThrustGain,
    ]
    .into_iter()
    .try_fold(PlantEffects::none(), |e, k| e.with(k))
    .unwrap();
    sets.push(all);
    sets.push(all.with(EffectKind::Wind).unwrap());
    for effects in sets {
        let effects = PlantEffects {
            motor_lag: None,
            ..effects
        };
        for k in 0..50 {
            let x = k as f64;
            let s = PlantState {
                position: Vector3::new(0.1 * x.sin(), -0.2, 0.02 + 0.03 * x),
                velocity: Vector3::new(1.1 * (0.7 * x).cos(), -0.6 + 0.02 * x, 0.4 * x.sin()),
                attitude: UnitQuaternion::from_euler_angles(0.3 * x.sin(), -0.2, 0.1 * x),
                body_rate: Vector3::new(0.9 * x.cos(), -0.5, 0.3 * (1.3 * x).sin()),
                rotor_speeds: [0.0; 4],
            };
            let speeds = [
                1900.0 + 10.0 * x,
                2100.0,
                1800.0 + 7.0 * x,
                2300.0 - 5.0 * x,
            ];
            let plant = Plant::new(model, model.params, effects, s).unwrap();
            let now = plant.accelerations(&speeds).wrench;
            let before = wrench_before_the_trait(&model, &effects, &s, &speeds);
            assert_eq!(now, before, "{effects:?}, state {k}");
        }
    }
}

/// A rotor imbalance, written out by hand per rotor: `T_i = (1 + ε_i) k_f ω_i²` at the
/// Crazyflie's hubs `(±L, ±L)` (M1..M4, docs/CONVENTIONS.md §4), `f_z = Σ T_i`,
/// `τ = Σ (y_i T_i, −x_i T_i, s_i (k_m/k_f) T_i)`; with a thrust gain on too, every `T_i`
/// times `1 + g`.
#[test]
fn rotor_imbalance_scales_each_rotor_alone() {
    let model = QuadrotorModel::crazyflie_2_1();
    let l = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
    let hubs = [(l, -l), (-l, -l), (-l, l), (l, l)];
    let spins = [1.0, -1.0, 1.0, -1.0];
    let eps = [-0.1, 0.05, 0.0, 0.2];
    let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
    for gain in [0.0, -0.08] {
        let mut effects = PlantEffects::none()
            .with_coefficients(EffectKind::RotorImbalance, &eps)
            .unwrap();
        if gain != 0.0 {
            effects = effects
                .with_coefficients(EffectKind::ThrustGain, &[gain])
                .unwrap();
        }
        let plant = Plant::new(
            model,
            model.params,
            effects,
            PlantState::at_rest(Vector3::new(0.0, 0.0, 1.0)),
        )
        .unwrap();
        let w = plant.accelerations(&speeds).wrench;
        let (mut fz, mut tx, mut ty, mut tz) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..4 {
            let t = (1.0 + gain) * (1.0 + eps[i]) * 2.3e-8 * speeds[i] * speeds[i];
            fz += t;
            tx += hubs[i].1 * t;
            ty -= hubs[i].0 * t;
            tz += spins[i] * (7.8e-10 / 2.3e-8) * t;
        }
        assert!(w.force.x == 0.0 && w.force.y == 0.0);
        assert!((w.force.z - fz).abs() < 1e-12, "{} {fz}", w.force.z);
        assert!((w.torque.x - tx).abs() < 1e-14 && (w.torque.y - ty).abs() < 1e-14);
        assert!((w.torque.z - tz).abs() < 1e-15, "{} {tz}", w.torque.z);
    }
    // The default's weak M1 (at y = −L) raises τ_x by L times its lost thrust.
    let nominal = model.wrench_from_rotor_speeds(&speeds);
    let only_m1 = PlantEffects::only(EffectKind::RotorImbalance).unwrap();
    let plant = Plant::new(
        model,
        model.params,
        only_m1,
        PlantState::at_rest(Vector3::new(0.0, 0.0, 1.0)),
    )
    .unwrap();
    let w = plant.accelerations(&speeds).wrench;
    let t1 = 0.1 * 2.3e-8 * speeds[0] * speeds[0];
    assert!((w.torque.x - (nominal.torque.x + l * t1)).abs() < 1e-14);
    assert!(
        PlantEffects::none()
            .with_coefficients(EffectKind::RotorImbalance, &[-1.0, 0.0, 0.0, 0.0])
            .is_err()
    );
}

/// A battery-voltage effect, written out by hand per rotor: the voltage
/// `V = V₀ − r t − s Σ ωᵢ²`, the factor `b = 1 + β (V − V_ref)/V_ref`, `T_i = b k_f ω_i²` at the
/// Crazyflie's hubs `(±L, ±L)`, `τ_z = Σ s_i (k_m/k_f) T_i`; at time 0 and after 2 s of flight
/// (the open-circuit voltage has fallen by `2 r`). The simulator's logged `vbat` is `V` too.
#[test]
fn battery_voltage_scales_every_rotor_by_the_voltage() {
    let model = QuadrotorModel::crazyflie_2_1();
    let l = tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
    let hubs = [(l, -l), (-l, -l), (-l, l), (l, l)];
    let spins = [1.0, -1.0, 1.0, -1.0];
    let (beta, v_ref) = (1.3, 3.7);
    let effects = PlantEffects::none()
        .with_coefficients(EffectKind::BatteryVoltage, &[beta, v_ref])
        .unwrap();
    let battery = effects.battery_voltage.unwrap();
    let (v0, r, sag) = (4.1, 1.5e-3, 2.8e-8);
    assert_eq!(
        (battery.initial_voltage, battery.discharge_rate, battery.sag),
        (v0, r, sag)
    );
    let speeds = [1900.0, 2100.0, 1800.0, 2300.0];
    let mut plant = Plant::new(
        model,
        model.params,
        effects,
        PlantState::at_rest(Vector3::new(0.0, 0.0, 1.0)),
    )
    .unwrap();
    for step in 0..2 {
        if step == 1 {
            for _ in 0..1000 {
                plant.step(&speeds, 2e-3);
            }
            assert!((plant.time() - 2.0).abs() < 1e-9);
        }
        let t = plant.time();
        let sq: f64 = speeds.iter().map(|w| w * w).sum();
        let v = v0 - r * t - sag * sq;
        assert!((v - battery.voltage(t, &speeds)).abs() < 1e-12);
        let b = 1.0 + beta * (v - v_ref) / v_ref;
        let w = plant.accelerations(&speeds).wrench;
        let (mut fz, mut tx, mut ty, mut tz) = (0.0, 0.0, 0.0, 0.0);
        for i in 0..4 {
            let thrust = b * 2.3e-8 * speeds[i] * speeds[i];
            fz += thrust;
            tx += hubs[i].1 * thrust;
            ty -= hubs[i].0 * thrust;
            tz += spins[i] * (7.8e-10 / 2.3e-8) * thrust;
        }
        assert!((w.force.z - fz).abs() < 1e-12, "{} {fz}", w.force.z);
        assert!((w.torque.x - tx).abs() < 1e-14 && (w.torque.y - ty).abs() < 1e-14);
        assert!((w.torque.z - tz).abs() < 1e-15, "{} {tz}", w.torque.z);
        // A sagged battery: fewer newtons than nominal.
        assert!(fz < 2.3e-8 * sq, "t = {t}: {fz}");
    }
    for bad in [[1.0, 0.0], [1.0, -3.8], [f64::NAN, 3.8]] {
        assert!(
            PlantEffects::none()
                .with_coefficients(EffectKind::BatteryVoltage, &bad)
                .is_err()
        );
    }
}
