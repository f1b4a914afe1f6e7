//! The noise-free truth behind a flight log ([`SimConfig::record_truth`](crate::SimConfig)):
//! per logged sample the true motion, the true inertial parameters and each plant effect's own
//! wrench, so that a diagnosis of the log can be judged against the physics that made it.
//!
//! Every quantity here is computed from the plant's state and the commands after the flight
//! step that produced the sample. Nothing is drawn from any random stream, so a flight with
//! the truth recorded logs the same bits as one without.
//!
//! **The decomposition.** With `W(ω)` the nominal mixer's wrench of rotor speeds `ω`
//! (`QuadrotorModel::wrench_from_rotor_speeds`, the nominal `k_f`, `k_m`; docs/CONVENTIONS.md
//! §4), the total non-gravitational wrench acting on the body at a sample is
//!
//! ```text
//! Y(a, ω, ω̇) θ = W(ω_logged) + Σ_e w_e
//! ```
//!
//! where `ω_logged` are the noise-free rotor speeds the logged actuator columns stand for. These
//! are the commanded speeds of the interval whose actuator sample the log holds, or the
//! motors' own with `FlightStack::motor_telemetry`. Each effect's wrench `w_e` (body frame,
//! about the origin, `[fx, fy, fz, tx, ty, tz]` in N and N m) is the part of the acting wrench
//! that effect adds. It is in the sign convention of the diagnosis (`b = Y θ − Σ w_e`: what
//! acts on the body beyond the logged actuator wrench):
//!
//! | effect | `w_e` |
//! |---|---|
//! | `time-delay` | `W(ω_reported) − W(ω_logged)`: the actuator wrench reported for the current interval minus the delayed one the log holds |
//! | `telemetry-lag` | `W(ω_now) − W(ω_reported)`: the read-back speeds' wrench minus that of the speeds the telemetry reports (delayed and filtered) |
//! | `motor-lag` | `W(ω_motor) − W(ω_now)`: what the lagging motors deliver minus what was commanded (read back) |
//! | `thrust-gain` | `ε W(ω_motor)` |
//! | `ground-effect` | `(1 + ε) (T_IGE/T_OGE(z) − 1) W(ω_motor)` (`ε = 0` without a thrust gain) |
//! | `linear-drag`, `quadratic-drag`, `rotor-drag`, `rotor-inflow` | the drag law (the inflow law) at the **ground-relative** velocity |
//! | `wind` | the drag and inflow laws at the air-relative velocity minus the same at the ground-relative velocity |
//! | `body-bias` | the constant force and torque |
//! | `rotor-inertia` | the torque `J_r Ḣ e_z + J_r H (Ω × e_z)` of the spinning rotors; without a motor lag only its gyroscopic part (the jumps at new commands are impulses, not in any instant's wrench) |
//! | `rotor-imbalance` | `(1 + ε) (T_IGE/T_OGE(z)) Σ ε_i W_i(ω_motor)`: each rotor's share `W_i` times its `ε_i` |
//! | `battery-voltage` | `(1 + ε) (T_IGE/T_OGE(z)) (b − 1) Σ (1 + ε_i) W_i(ω_motor)`, `b = 1 + β (V − V_ref)/V_ref` at the instant's time |
//!
//! A `wind` with no drag effect acts through the plant's implicit Crazyflie rotor drag
//! ([`PlantEffects::extra_wrench`]): its truth then lists `rotor-drag` (that drag at the
//! ground-relative velocity) beside `wind`. The sum holds to rounding (a test). The thrust
//! gain's and the ground effect's shares split the plant's product `(1 + ε) T_IGE/T_OGE`.
//!
//! **As the log samples it.** A control-rate log sample holds the accelerometer at the
//! interval's midpoint but `ω̇` as the gyro's change across the whole 20 ms interval. So the
//! torque rows of `Y(a, ω, logged ω̇) θ` are the interval's **mean** torque, not the midpoint's.
//! They differ by far more than the noise when a motor lag shapes the torque within the
//! interval. [`TruthSample::logged_wrench`], [`TruthSample::logged_effect_wrenches`] and
//! [`TruthSample::logged_angular_acceleration`] are the truth on the log's terms. Forces are
//! taken at the midpoint, torques and `ω̇` averaged over the interval (Simpson's rule over the
//! physics steps). The plain fields are the instant's.
//!
//! The sensors' errors are not effects of the plant: the flight's constant accelerometer and
//! gyro biases are given ([`FlightTruth::accel_bias`], [`FlightTruth::gyro_bias`]); white
//! noise is whatever remains of `b_logged − Y(logged signals) θ − Σ w_e`.

use nalgebra::Vector3;
use tagk_dynamics::{EffectKind, InertialParams, QuadrotorModel, Wrench};

use crate::plant::{Accelerations, PlantState};
use crate::plant_effects::PlantEffects;

/// The noise-free truth of one logged sample (one per row of
/// [`SimOutput::log`](crate::SimOutput::log), same order).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthSample {
    /// Time stamp of the log sample \[s\] (the log's `t`, bit for bit).
    pub t: f64,
    /// True inertial parameters of the flying body, vehicle plus every attached payload, about
    /// the body origin (docs/CONVENTIONS.md §1).
    pub params: InertialParams,
    /// True proper acceleration of the body origin `a = Rᵀ (p̈ − g_w)`, body frame \[m/s²\]
    /// (instantaneous, at the sample's state).
    pub proper_acceleration: [f64; 3],
    /// True body rate `ω`, body frame \[rad/s\].
    pub body_rate: [f64; 3],
    /// True angular acceleration `ω̇`, body frame \[rad/s²\] (instantaneous, at the sample's
    /// state).
    pub angular_acceleration: [f64; 3],
    /// The noise-free counterpart of the log's `dwx..dwz`, body frame \[rad/s²\]. For a
    /// control-rate sample it is the true body rate's change across the control interval over its
    /// length (the interval mean of `ω̇`, which the differenced gyro measures). For a
    /// physics-rate sample (no `ω̇` logged) it is [`TruthSample::angular_acceleration`].
    pub logged_angular_acceleration: [f64; 3],
    /// The total non-gravitational wrench acting on the body, `Y(a, ω, ω̇) θ`, body frame, about
    /// the origin: `[fx, fy, fz]` \[N\], `[tx, ty, tz]` \[N m\].
    pub wrench: [f64; 6],
    /// [`TruthSample::wrench`] as the log samples it: for a control-rate sample the forces at
    /// the sample's instant (the accelerometer's) and the torques averaged over the control
    /// interval (what the differenced gyro sees; Simpson's rule over its physics steps), so
    /// that `Y(a, ω, logged ω̇) θ` equals it to second order in the interval; for a
    /// physics-rate sample the wrench itself \[N, N m\].
    pub logged_wrench: [f64; 6],
    /// The noise-free actuator wrench the log's `fx..tz` stand for, body frame, about the origin
    /// \[N, N m\]. It is the nominal mixer's wrench of the noise-free read-back rotor speeds of the
    /// interval whose actuator sample the log holds (with a `time-delay`, an earlier one).
    /// The logged wrench is this plus the rotor-speed noise.
    pub logged_actuator_wrench: [f64; 6],
    /// Each effect's wrench `w_e` (module docs), in the order of [`FlightTruth::effects`];
    /// body frame, about the origin \[N, N m\]. `wrench = logged_actuator_wrench + Σ
    /// effect_wrenches` to rounding.
    pub effect_wrenches: Vec<[f64; 6]>,
    /// Each effect's wrench as the log samples it (forces at the instant, torques averaged over
    /// the interval, as [`TruthSample::logged_wrench`]); `logged_wrench =
    /// logged_actuator_wrench + Σ logged_effect_wrenches` to rounding. What a diagnosis of the
    /// log should compare with \[N, N m\].
    pub logged_effect_wrenches: Vec<[f64; 6]>,
}

/// The noise-free truth of a flight ([`SimOutput::truth`](crate::SimOutput::truth)).
#[derive(Debug, Clone, PartialEq)]
pub struct FlightTruth {
    /// The plant effects that act, in [`EffectKind::ALL`] order (with `rotor-drag` for the
    /// implicit drag of a `wind` without drag effect); [`TruthSample::effect_wrenches`] follow
    /// this order.
    pub effects: Vec<EffectKind>,
    /// The flight's constant accelerometer bias, body frame \[m/s²\] (added to the proper
    /// acceleration the log's `ax..az` carry; zero without one).
    pub accel_bias: [f64; 3],
    /// The flight's constant rate-gyro bias, body frame \[rad/s\] (added to the log's
    /// `wx..wz`; it cancels in `dwx..dwz`).
    pub gyro_bias: [f64; 3],
    /// One sample per logged sample, in the log's order. Without
    /// [`SimConfig::record_log`](crate::SimConfig::record_log) there is no truth at all
    /// ([`SimOutput::truth`](crate::SimOutput::truth) is `None`).
    pub samples: Vec<TruthSample>,
}

/// The effects of `effects` that act, in [`EffectKind::ALL`] order, with the implicit rotor
/// drag of a wind without drag effect.
pub(crate) fn acting_effects(effects: &PlantEffects) -> Vec<EffectKind> {
    EffectKind::ALL
        .into_iter()
        .filter(|k| match k {
            EffectKind::LinearDrag => effects.linear_drag.is_some(),
            EffectKind::QuadraticDrag => effects.quadratic_drag.is_some(),
            EffectKind::RotorDrag => effects.acting_rotor_drag().is_some(),
            EffectKind::MotorLag => effects.motor_lag.is_some(),
            EffectKind::TimeDelay => effects.time_delay.is_some(),
            EffectKind::GroundEffect => effects.ground_effect.is_some(),
            EffectKind::BodyBias => effects.body_bias.is_some(),
            EffectKind::Wind => effects.wind.is_some(),
            EffectKind::ThrustGain => effects.thrust_gain.is_some(),
            EffectKind::RotorInertia => effects.rotor_inertia.is_some(),
            EffectKind::RotorInflow => effects.rotor_inflow.is_some(),
            EffectKind::RotorImbalance => effects.rotor_imbalance.is_some(),
            EffectKind::BatteryVoltage => effects.battery_voltage.is_some(),
            EffectKind::TelemetryLag => effects.telemetry_lag.is_some(),
            _ => false,
        })
        .collect()
}

/// What the truth of one instant is made of: the state and its accelerations, the rotor
/// speeds acting, and the noise-free read-back actuator wrenches (current and logged).
pub(crate) struct TruthInputs<'a> {
    pub(crate) state: &'a PlantState,
    pub(crate) acc: &'a Accelerations,
    pub(crate) motor_speeds: [f64; 4],
    /// The rates of change of `motor_speeds` \[rad/s²\] (zero without a motor lag).
    pub(crate) motor_accelerations: [f64; 4],
    pub(crate) now: Wrench,
    /// The nominal wrench of the speeds reported now (`now` without a `telemetry-lag`).
    pub(crate) reported: Wrench,
    pub(crate) logged: Wrench,
    /// The plant's time at `state` \[s\] (the battery's discharge reads it).
    pub(crate) time: f64,
}

/// The wrenches of one instant: the total acting and each effect's.
#[derive(Debug, Clone)]
pub(crate) struct TruthParts {
    wrench: [f64; 6],
    effects: Vec<[f64; 6]>,
}

impl TruthParts {
    /// The mean over equally spaced instants `points` (at least one): composite Simpson's rule
    /// over an even number of steps, else the trapezoidal rule.
    pub(crate) fn mean(points: &[TruthParts]) -> TruthParts {
        let n = points.len();
        let weights: Vec<f64> = if n < 2 {
            vec![1.0; n]
        } else if (n - 1).is_multiple_of(2) {
            (0..n)
                .map(|i| {
                    if i == 0 || i == n - 1 {
                        1.0
                    } else if !i.is_multiple_of(2) {
                        4.0
                    } else {
                        2.0
                    }
                })
                .collect()
        } else {
            (0..n)
                .map(|i| if i == 0 || i == n - 1 { 1.0 } else { 2.0 })
                .collect()
        };
        let total: f64 = weights.iter().sum();
        let avg = |get: &dyn Fn(&TruthParts) -> [f64; 6]| -> [f64; 6] {
            std::array::from_fn(|c| {
                points
                    .iter()
                    .zip(&weights)
                    .map(|(p, w)| w * get(p)[c])
                    .sum::<f64>()
                    / total
            })
        };
        let count = points.first().map_or(0, |p| p.effects.len());
        TruthParts {
            wrench: avg(&|p| p.wrench),
            effects: (0..count).map(|e| avg(&|p| p.effects[e])).collect(),
        }
    }
}

impl TruthParts {
    /// These parts with the torque `torque` (body frame \[N m\]) added to the total and to
    /// effect `effect` (an index into the effects; `None`: the total only). It spreads an
    /// impulse at the interval's start over the interval, as the differenced gyro sees it.
    pub(crate) fn with_torque(mut self, effect: Option<usize>, torque: &Vector3<f64>) -> Self {
        for c in 0..3 {
            self.wrench[3 + c] += torque[c];
            if let Some(w) = effect.and_then(|k| self.effects.get_mut(k)) {
                w[3 + c] += torque[c];
            }
        }
        self
    }
}

impl TruthSample {
    /// The truth of a log sample at time `t` \[s\] of a body with parameters `params`. It holds the
    /// state and accelerations at the sample, the logged actuator wrench and the wrenches at the
    /// sample. For a control-rate sample it also holds their means over the control interval, with
    /// the interval mean of `ω̇` (the change of the body rate over the interval's length).
    pub(crate) fn new(
        t: f64,
        params: InertialParams,
        (state, acc): (&PlantState, &Accelerations),
        logged: Wrench,
        at_sample: TruthParts,
        over_interval: Option<(TruthParts, Vector3<f64>)>,
    ) -> Self {
        let (logged_wrench, logged_effect_wrenches, logged_angular_acceleration) =
            match over_interval {
                // Forces at the sample's instant (the accelerometer's), torques over the
                // interval (the differenced gyro's).
                Some((mean, rate_change)) => {
                    let mix = |inst: &[f64; 6], avg: &[f64; 6]| -> [f64; 6] {
                        std::array::from_fn(|c| if c < 3 { inst[c] } else { avg[c] })
                    };
                    (
                        mix(&at_sample.wrench, &mean.wrench),
                        at_sample
                            .effects
                            .iter()
                            .zip(&mean.effects)
                            .map(|(i, a)| mix(i, a))
                            .collect(),
                        rate_change.into(),
                    )
                }
                None => (
                    at_sample.wrench,
                    at_sample.effects.clone(),
                    acc.angular.into(),
                ),
            };
        TruthSample {
            t,
            params,
            proper_acceleration: acc.proper.into(),
            body_rate: state.body_rate.into(),
            angular_acceleration: acc.angular.into(),
            logged_angular_acceleration,
            wrench: at_sample.wrench,
            logged_wrench,
            logged_actuator_wrench: logged.to_array(),
            effect_wrenches: at_sample.effects,
            logged_effect_wrenches,
        }
    }
}

/// The wrenches of `inputs` for the plant `effects` acting (`kinds` from [`acting_effects`]) on
/// a vehicle with actuator layout `model`: the total acting (from the accelerations) and each
/// effect's share (module docs).
pub(crate) fn truth_parts(
    model: &QuadrotorModel,
    effects: &PlantEffects,
    kinds: &[EffectKind],
    inputs: &TruthInputs<'_>,
) -> TruthParts {
    let s = inputs.state;
    let motor = model.wrench_from_rotor_speeds(&inputs.motor_speeds);
    let epsilon = effects.thrust_gain.map_or(0.0, |g| g.relative_error);
    // Drag laws at the state's velocity, with or without the wind.
    let drag_only = |law: PlantEffects, wind: Option<crate::plant_effects::Wind>| {
        PlantEffects { wind, ..law }.extra_wrench(
            &s.velocity,
            &s.attitude,
            &s.body_rate,
            &inputs.motor_speeds,
            &model.rotor_positions,
        )
    };
    let none = PlantEffects::none();
    let drag_laws = PlantEffects {
        linear_drag: effects.linear_drag,
        quadratic_drag: effects.quadratic_drag,
        rotor_drag: effects.acting_rotor_drag(),
        rotor_inflow: effects.rotor_inflow,
        ..none
    };
    let scaled = |w: &Wrench, k: f64| Wrench {
        force: w.force * k,
        torque: w.torque * k,
    };
    // The ground effect's thrust ratio at the state's height, and the rotors' imbalance.
    let ground_ratio = || {
        effects
            .ground_effect
            .map_or(1.0, |g| g.thrust_ratio(s.position.z))
    };
    let imbalance = || {
        effects
            .rotor_imbalance
            .map_or([0.0; 4], |b| b.relative_errors)
    };
    let effect_wrenches = kinds
        .iter()
        .map(|kind| {
            let w = match kind {
                EffectKind::TimeDelay => inputs.reported - inputs.logged,
                EffectKind::TelemetryLag => inputs.now - inputs.reported,
                EffectKind::MotorLag => motor - inputs.now,
                EffectKind::ThrustGain => scaled(&motor, epsilon),
                EffectKind::GroundEffect => {
                    scaled(&motor, (1.0 + epsilon) * (ground_ratio() - 1.0))
                }
                EffectKind::LinearDrag => drag_only(
                    PlantEffects {
                        linear_drag: effects.linear_drag,
                        ..none
                    },
                    None,
                ),
                EffectKind::QuadraticDrag => drag_only(
                    PlantEffects {
                        quadratic_drag: effects.quadratic_drag,
                        ..none
                    },
                    None,
                ),
                EffectKind::RotorDrag => drag_only(
                    PlantEffects {
                        rotor_drag: drag_laws.rotor_drag,
                        ..none
                    },
                    None,
                ),
                EffectKind::Wind => drag_only(drag_laws, effects.wind) - drag_only(drag_laws, None),
                EffectKind::BodyBias => effects.body_bias.map_or_else(Wrench::zero, |b| Wrench {
                    force: Vector3::from(b.force),
                    torque: Vector3::from(b.torque),
                }),
                EffectKind::RotorInertia => Wrench {
                    force: Vector3::zeros(),
                    torque: effects.rotor_inertia.map_or_else(Vector3::zeros, |r| {
                        r.torque(
                            &s.body_rate,
                            &inputs.motor_speeds,
                            &inputs.motor_accelerations,
                            &model.spin_directions,
                        )
                    }),
                },
                EffectKind::RotorInflow => drag_only(
                    PlantEffects {
                        rotor_inflow: effects.rotor_inflow,
                        ..none
                    },
                    None,
                ),
                EffectKind::RotorImbalance => {
                    let (ratio, eps) = (ground_ratio(), imbalance());
                    let k = (1.0 + epsilon) * ratio;
                    let w = &inputs.motor_speeds;
                    model.wrench_from_thrusts(&std::array::from_fn(|i| {
                        k * eps[i] * model.k_f * w[i] * w[i]
                    }))
                }
                EffectKind::BatteryVoltage => {
                    let (ratio, eps) = (ground_ratio(), imbalance());
                    let w = &inputs.motor_speeds;
                    let b = effects
                        .battery_voltage
                        .map_or(1.0, |b| b.factor(b.voltage(inputs.time, w)));
                    let k = (1.0 + epsilon) * ratio * (b - 1.0);
                    model.wrench_from_thrusts(&std::array::from_fn(|i| {
                        k * (1.0 + eps[i]) * model.k_f * w[i] * w[i]
                    }))
                }
                _ => Wrench::zero(),
            };
            w.to_array()
        })
        .collect();
    TruthParts {
        wrench: inputs.acc.wrench.to_array(),
        effects: effect_wrenches,
    }
}
