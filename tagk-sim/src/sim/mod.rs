//! One closed-loop flight: plant, measurement model, LQR, payload events, estimator and
//! safety gate (see the crate docs for the whole loop).
//!
//! The concerns live in submodules: the configuration and its validation
//! ([`SimConfig`], `config.rs`), the controller ([`Controller`], `controller.rs`), the sensors
//! (`sensors.rs`), what a flight produces ([`SimOutput`], `output.rs`); this file is the
//! flight loop, [`simulate`], as a sequence of named steps.

mod config;
mod controller;
mod output;
pub mod rotor_sensing;
mod sensing;
mod sensors;
mod truth;

use std::ops::ControlFlow;
use std::time::Instant;

use nalgebra::{UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use tagk_control::hover_trim;
use tagk_core::{FrontEnd, OnlineEstimator};
use tagk_dynamics::log::{FlightLog, LogSample};
use tagk_dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
use tagk_dynamics::{EffectKind, GRAVITY_WORLD, InertialParams, WindowBuilder, Wrench};

pub use config::{
    Adaptation, FlightStack, LogRate, MEMORY_BUDGET_BYTES, NoiseLevel, Payload, PayloadSchedule,
    PayloadShape, REALISTIC_HOVER_THRUST_LIMIT, REALISTIC_POSITION_INTEGRAL_GAIN,
    REALISTIC_POSITION_INTEGRAL_LIMIT, REALISTIC_ROTOR_TELEMETRY_SAMPLES, SimConfig,
    VEHICLE_POSITION_INTEGRAL_GAIN, check_payload, check_payload_within, tracking_weights,
};
pub use controller::{Controller, REDESIGN_TOLERANCE, prioritise_attitude};
pub use output::{EventRecord, SimOutput, TraceSample, TrialMetrics, UpdateRecord};
pub use sensing::{
    BMI088_ACCEL_NOISE_DENSITY_G, BMI088_ACCEL_OFFSET_G, BMI088_GYRO_NOISE_DENSITY_DEG,
    BMI088_GYRO_OFFSET_DRIFT_DEG, CRAZYFLIE_ACCEL_BANDWIDTH, CRAZYFLIE_GYRO_BANDWIDTH,
    ExperimentProfile, MOCAP_ATTITUDE_NOISE, MOCAP_POSITION_NOISE, PROPELLER_VIBRATION_FACTOR,
    REALISTIC_MOTOR_LAG, REALISTIC_THRUST_GAIN_ERROR, Sensing, SensingProfile, WARM_UP_KELVIN,
};
pub(crate) use sensors::{gaussian, sub_rng};
pub use truth::{FlightTruth, TruthSample};

use crate::EstimatorKind;
use crate::SimError;
use crate::estimators::{
    CHANGE_FALSE_ALARM, CHANGE_FRESH_FRAMES, DRAG_LIMIT_PER_MASS, DRAG_PARAMS, FORCE_BIAS_PARAMS,
    N_PARAMS, build_kind, change_scales, front_end_config, row_weights, spec_scales,
};
use crate::metrics::{
    ABORT_THRESHOLD, GroupErrors, group_errors, is_aborted, is_settled, is_success,
    parameter_error, position_error_all_cm, position_error_cm, settle_error_cm, t_plus_one_error,
};
use crate::plant::{Accelerations, Plant, PlantState};
use crate::trajectory::Trajectory;
use rotor_sensing::{MotorModel, RotorSensing};
use sensors::{Frame, Sensors};
use truth::{TruthInputs, TruthParts, acting_effects, truth_parts};

/// A control interval's plant states for its truth: the state (and accelerations) before the
/// first physics step, and after each.
type IntervalStates<'a> = (
    &'a (PlantState, Accelerations),
    &'a [(PlantState, Accelerations)],
);

/// A scheduled change of the true parameters.
#[derive(Debug, Clone, Copy)]
struct ScheduledEvent {
    step: usize,
    attach: bool,
    payload: InertialParams,
}

/// An estimator behind tagk-core's front end (column scales, row weights, noise-aware stop,
/// event-aware windows), in the caller's units.
type Fronted = FrontEnd<f64, Box<dyn OnlineEstimator<f64> + Send>, Vec<f64>>;

/// The estimator of a flight with what turns frames into its windows.
struct EstimatorStage {
    /// The estimator behind its front end, with the change detector around it (used only with
    /// [`EstimatorSpec::change_detector`](crate::EstimatorSpec::change_detector)).
    main: tagk_core::EventTriggered<f64, Fronted, Vec<f64>>,
    /// Whether the change detector runs.
    detect: bool,
    /// After an alarm: the control step whose window is the fresh one.
    fresh_due: Option<usize>,
    /// TAG-K run alongside for early adaptation (its first post-event estimate replaces the
    /// main estimator's state).
    early: Option<Fronted>,
    window: WindowBuilder,
    /// The built window and its effect columns.
    buffers: WindowBuffers,
    /// Row weights of a full window (`None`: every row 1).
    weights: Option<Vec<f64>>,
}

/// A built window's buffers, with the effect columns appended after θ's 10.
struct WindowBuffers {
    a_buf: Vec<f64>,
    b_buf: Vec<f64>,
    /// Unknowns per row: θ's 10, plus the nuisance force's 3
    /// ([`EstimatorSpec::force_bias`](crate::EstimatorSpec::force_bias)), plus the drag's 3
    /// ([`EstimatorSpec::drag`](crate::EstimatorSpec::drag)).
    unknowns: usize,
    /// The effect columns after θ.
    columns: EffectColumns,
    /// With drag columns: the measured body-frame velocity \[m/s\] of each frame in the
    /// window, oldest first (empty without them).
    velocities: std::collections::VecDeque<[f64; 3]>,
    /// The window with the effect columns (empty without them).
    a_wide: Vec<f64>,
}

/// Which effect columns follow θ's 10 in the estimator's window, in this order.
#[derive(Debug, Clone, Copy)]
struct EffectColumns {
    /// The nuisance force: identity on each frame's force rows.
    force_bias: bool,
    /// The linear drag: the frame's body-frame velocity on its force rows.
    drag: bool,
}

/// The state of a flight in progress.
struct Flight<'a> {
    config: &'a SimConfig,
    /// Physics substeps per control step and their length \[s\].
    substeps: usize,
    substep: f64,
    trajectory: Trajectory,
    schedule: Vec<ScheduledEvent>,
    next_event: usize,
    plant: Plant,
    controller: Controller,
    sensors: Sensors,
    estimator: Option<EstimatorStage>,
    events: Vec<EventRecord>,
    updates: Vec<UpdateRecord>,
    log: FlightLog,
    /// The battery voltage \[V\] at every log sample (only with a `battery-voltage` effect;
    /// logged as the extra column `vbat`).
    vbat: Vec<f64>,
    /// Rotor speeds and wrench commanded at every control step so far (kept only for a log
    /// with a `time-delay` effect, whose wrench stream lags the motion).
    commands: Vec<([f64; 4], [f64; 6])>,
    /// With a `telemetry-lag` effect: the read-back rotor speeds of every control interval so
    /// far (the delayed filter reads them) and the filter's state, the speeds last reported.
    telemetry: (Vec<[f64; 4]>, Option<[f64; 4]>),
    /// With [`SimConfig::record_truth`]: the truth of every logged sample so far, the effects
    /// that act, and the noise-free read-back actuator wrench of every control interval so far
    /// (the delayed one a `time-delay` log holds is one of them).
    truth: Option<TruthRecord>,
    trace: Vec<TraceSample>,
    tracking: Vec<f64>,
    /// Per event: the first estimate after it, the truth, and whether its window mixed
    /// pre- and post-event frames.
    first_after_event: Vec<(Vec<f64>, InertialParams, bool)>,
    pending_event: bool,
    first_update_steps: Vec<usize>,
    /// Control steps at which the change detector alarmed.
    alarms: Vec<usize>,
    latest_estimate: [f64; 10],
    /// The drag the controller compensates, `diag(d_x, d_y, d_z)` \[N s/m\] (body frame;
    /// zero unless the estimator has drag columns).
    drag_estimate: [f64; 3],
    /// Control steps of the whole flight.
    planned_steps: usize,
    /// `∫ (p̂ − p_ref) dt` of the flight stack's integral action \[m s\] (world frame).
    position_integral: Vector3<f64>,
    /// The states after each physics step of the current control interval (for a physics-rate
    /// log or the truth), a buffer kept from interval to interval.
    interval_steps: Vec<(PlantState, Accelerations)>,
    /// The flight stack's motor model (brushed rotor sensing only).
    motor_model: MotorModel,
    /// Stream of the rotor sensing's own draws (battery reading, eRPM jitter).
    rotor_sensing_rng: ChaCha8Rng,
}

/// What [`SimConfig::record_truth`] keeps during a flight.
struct TruthRecord {
    effects: Vec<EffectKind>,
    samples: Vec<TruthSample>,
    /// Noise-free read-back actuator wrench of each control interval so far.
    read_back: Vec<Wrench>,
    /// The nominal wrench of the reported rotor speeds of each control interval so far
    /// (`read_back` itself without a `telemetry-lag` effect).
    reported: Vec<Wrench>,
}

/// Flies one trial (see the crate docs for the loop, the measurement model and the timing).
///
/// # Errors
/// An invalid configuration ([`SimConfig::validate`]) or a controller that cannot be
/// designed for the nominal vehicle. Estimator rejections and gate violations during the
/// flight are not errors: the controller keeps its previous parameters.
pub fn simulate(config: &SimConfig) -> Result<SimOutput, SimError> {
    simulate_with_progress(config, |_, _| {})
}

/// [`simulate`], calling `progress(done, total)` after each control step: `done` of `total`
/// control steps flown.
///
/// It is for a progress display; the flight is the same bits as [`simulate`]'s. A flight that
/// aborts early never reports `done == total`.
///
/// # Errors
/// As [`simulate`].
pub fn simulate_with_progress(
    config: &SimConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<SimOutput, SimError> {
    config.validate()?;
    // Validated: finite, and within the memory budget, so it fits a usize.
    let steps = usize::try_from(config.control_steps().unwrap_or(1)).unwrap_or(usize::MAX);
    let mut flight = Flight::new(config, steps)?;
    for k in 0..steps {
        let flow = flight.step(k)?;
        progress(k + 1, steps);
        if flow.is_break() {
            break;
        }
    }
    Ok(flight.finish())
}

/// The payloads of a flight, drawn from the setup stream for the protocol schedules.
fn draw_payloads(config: &SimConfig, setup: &mut ChaCha8Rng) -> Result<Vec<Payload>, SimError> {
    let vehicle = &config.vehicle;
    let nominal_mass = vehicle.params.mass();
    Ok(match &config.payload {
        PayloadSchedule::None => Vec::new(),
        PayloadSchedule::Protocol | PayloadSchedule::ProtocolAt { .. } => {
            // Rejection sampling: a heavy payload far out along a diagonal can need more than
            // the rotors' limit to hover (the protocol's corner case); such draws are redrawn.
            // The true rotors' share of the nominal maximum thrust the payload may use.
            let fraction = if config.flight_stack.hover_thrust_limit == 1.0 {
                1.0
            } else {
                config.flight_stack.hover_thrust_limit
                    * config
                        .effects
                        .thrust_gain
                        .map_or(1.0, |g| 1.0 + g.relative_error)
            };
            let mut draw = Payload::random_protocol(nominal_mass, setup);
            let mut attempts = 1;
            while let Err(e) = check_payload_within(vehicle, &draw, fraction) {
                if attempts >= 1000 {
                    return Err(e);
                }
                draw = Payload::random_protocol(nominal_mass, setup);
                attempts += 1;
            }
            if let PayloadSchedule::ProtocolAt { attach, remove } = config.payload {
                draw.attach_time = attach;
                draw.remove_time = Some(remove);
            }
            vec![draw]
        }
        PayloadSchedule::Fixed(list) => list.clone(),
    })
}

/// Attach and removal events of `payloads` on the control-step grid of period `dt` \[s\], in
/// step order.
fn schedule_events(payloads: &[Payload], dt: f64) -> Vec<ScheduledEvent> {
    let mut schedule: Vec<ScheduledEvent> = Vec::new();
    let step_of = |t: f64| (t / dt).ceil().max(0.0) as usize;
    for p in payloads {
        let theta = p.params();
        schedule.push(ScheduledEvent {
            step: step_of(p.attach_time),
            attach: true,
            payload: theta,
        });
        if let Some(r) = p.remove_time {
            schedule.push(ScheduledEvent {
                step: step_of(r).max(step_of(p.attach_time) + 1),
                attach: false,
                payload: theta,
            });
        }
    }
    schedule.sort_by_key(|e| e.step);
    schedule
}

/// The estimator of `config` (none unless it adapts with one), reset to the nominal prior.
fn build_estimator(config: &SimConfig, seed: u64) -> Result<Option<EstimatorStage>, SimError> {
    let Adaptation::Estimator(spec) = &config.adaptation else {
        return Ok(None);
    };
    let nominal = config.vehicle.params;
    let m_max = 6 * config.window_frames;
    let scales = spec_scales(spec, &nominal.to_array(), CRAZYFLIE_ARM_OFFSET);
    let seen = config
        .flight_stack
        .sensing_at(&config.sensing, config.noise);
    let front = front_end_config(
        spec,
        nominal.mass(),
        Sensing::combined(config.noise.sigma_acceleration(), seen.accel_noise),
    );
    let unknowns = spec.unknowns();
    // The prior: the nominal parameters and no nuisance force.
    let mut prior = nominal.as_slice().to_vec();
    prior.resize(unknowns, 0.0);
    let mut inner = spec.build_for_rows(m_max, seed, 0.0, front.row_noise)?;
    if spec.learning {
        // The fast estimate's precision: one row's noise per unit of a scaled parameter (the
        // estimate may be off by about its own magnitude).
        let config = tagk_core::AccumulateConfig {
            anchor_precision: front.row_noise * front.row_noise,
            ..tagk_core::AccumulateConfig::default()
        };
        inner = Box::new(tagk_core::Accumulate::new(inner, config)?);
    }
    let mut main = FrontEnd::new(inner, &scales, front)?;
    main.reset(&prior)?;
    let early = if spec.early_tagk {
        let tagk = build_kind(
            EstimatorKind::TagK,
            unknowns,
            spec.burn_in,
            m_max,
            seed,
            0.0,
        )?;
        let mut e = FrontEnd::new(tagk, &scales, front)?;
        e.reset(&prior)?;
        Some(e)
    } else {
        None
    };
    let change_scales = change_scales(&nominal.to_array(), CRAZYFLIE_ARM_OFFSET, unknowns);
    let detector = tagk_core::DetectorConfig {
        false_alarm: CHANGE_FALSE_ALARM,
        channels: 6,
        // One second of frames to measure the rows' noise.
        warmup: (1.0 / config.control_dt).round().max(1.0) as usize,
        ..tagk_core::DetectorConfig::default()
    };
    let main = tagk_core::EventTriggered::new(main, &change_scales, detector)?;
    Ok(Some(EstimatorStage {
        main,
        detect: spec.change_detector,
        fresh_due: None,
        early,
        window: WindowBuilder::new(config.window_frames)?,
        buffers: WindowBuffers {
            a_buf: vec![0.0; m_max * N_PARAMS],
            b_buf: vec![0.0; m_max],
            unknowns,
            columns: EffectColumns {
                force_bias: spec.force_bias,
                drag: spec.drag,
            },
            velocities: std::collections::VecDeque::with_capacity(if spec.drag {
                config.window_frames
            } else {
                0
            }),
            a_wide: if unknowns > N_PARAMS {
                vec![0.0; m_max * unknowns]
            } else {
                Vec::new()
            },
        },
        weights: row_weights(spec, m_max),
    }))
}

impl<'a> Flight<'a> {
    /// Sets a flight up: independent random streams (setup, measurement noise, estimator
    /// seeds), the reference path, the payload schedule, the initial state near the path's
    /// start (at rest, slightly tilted), the plant, the controller and the estimator.
    fn new(config: &'a SimConfig, steps: usize) -> Result<Self, SimError> {
        let vehicle = &config.vehicle;
        let nominal = vehicle.params;
        let substeps = (config.control_dt / config.physics_dt).round() as usize;
        let mut setup = sub_rng(config.seed, 1);
        let noise = sub_rng(config.seed, 2);
        let estimator_seed = sub_rng(config.seed, 3).random::<u64>();

        let trajectory = Trajectory::random(
            config.trajectory,
            config.duration,
            config.altitude,
            &mut setup,
        )?;
        let payloads = draw_payloads(config, &mut setup)?;
        let schedule = schedule_events(&payloads, config.control_dt);

        let r0 = trajectory.sample(0.0);
        let offset = Vector3::new(
            setup.random_range(-0.02..0.02),
            setup.random_range(-0.02..0.02),
            setup.random_range(-0.02..0.02),
        );
        let attitude = UnitQuaternion::from_euler_angles(
            setup.random_range(-0.02..0.02),
            setup.random_range(-0.02..0.02),
            setup.random_range(-0.05..0.05),
        );
        let hover = hover_trim(vehicle, &nominal, Vector3::zeros(), 0.0)?;
        let init = PlantState {
            position: r0.position + offset,
            velocity: Vector3::zeros(),
            attitude,
            body_rate: Vector3::zeros(),
            rotor_speeds: vehicle.rotor_speeds_from_thrusts(&hover.thrusts),
        };
        let plant = Plant::new(*vehicle, nominal, config.effects, init)?
            .with_shared_effects(&config.user_effects.0);
        let controller = Controller::new(vehicle, &nominal, config.weights, config.control_dt)?;
        let estimator = build_estimator(config, estimator_seed)?;
        // Streams 4, 5 (and 6, the physics-rate log) were added with the sensing profiles: streams 1–3 draw exactly as
        // before, so an ideal profile flies bit-identically to the simulator before them.
        let sensors = Sensors::new(
            noise,
            sub_rng(config.seed, 4),
            sub_rng(config.seed, 5),
            sub_rng(config.seed, 6),
            sub_rng(config.seed, 7),
            config.noise,
            &config
                .flight_stack
                .sensing_at(&config.sensing, config.noise),
            plant.state().body_rate,
        );
        Ok(Self {
            config,
            substeps,
            substep: config.control_dt / substeps as f64,
            trajectory,
            schedule,
            next_event: 0,
            plant,
            controller,
            sensors,
            estimator,
            events: Vec::new(),
            updates: Vec::new(),
            log: FlightLog::new(),
            vbat: Vec::new(),
            commands: Vec::new(),
            telemetry: (Vec::new(), None),
            truth: (config.record_truth && config.record_log).then(|| TruthRecord {
                effects: acting_effects(&config.effects),
                samples: Vec::new(),
                read_back: Vec::with_capacity(steps),
                reported: Vec::with_capacity(steps),
            }),
            trace: Vec::new(),
            tracking: Vec::with_capacity(steps + 1),
            first_after_event: Vec::new(),
            pending_event: false,
            first_update_steps: Vec::new(),
            alarms: Vec::new(),
            latest_estimate: nominal.to_array(),
            drag_estimate: [0.0; 3],
            planned_steps: steps,
            position_integral: Vector3::zeros(),
            interval_steps: Vec::new(),
            motor_model: MotorModel::new(init.rotor_speeds),
            // Stream 8, added with the rotor-sensing models: the others draw as before.
            rotor_sensing_rng: sub_rng(config.seed, 8),
        })
    }

    /// Control step `k`: payload events, tracking error and abort check, control, physics,
    /// sensing, logging and the estimator update. `Break` ends the flight (an abort or a
    /// diverged plant).
    fn step(&mut self, k: usize) -> Result<ControlFlow<()>, SimError> {
        let dt = self.config.control_dt;
        let t = k as f64 * dt;
        self.apply_payload_events(k, t)?;
        let state = *self.plant.state();
        if self.track(t, &state).is_break() {
            return Ok(ControlFlow::Break(()));
        }
        let yaw_rate = self.config.yaw_rate;
        let mut reference = self
            .trajectory
            .sample(t)
            .with_heading(yaw_rate * t, yaw_rate);
        let measured = self.sensors.controller_measurement(&state);
        let stack = &self.config.flight_stack;
        if stack.position_integral_gain > 0.0 {
            // Integral action: the reference shifted by −k_i ∫ e dt, each axis limited.
            let k = stack.position_integral_gain;
            let limit = stack.position_integral_limit / k;
            self.position_integral += (measured.position - reference.position) * dt;
            self.position_integral = self.position_integral.map(|v| v.clamp(-limit, limit));
            reference.position -= self.position_integral * k;
        }
        // The estimated drag's body force `−D v_b` is compensated: the desired specific force
        // gains `R D v_b / m̂` (measured attitude and velocity, the controller's mass).
        let velocity_body = measured
            .attitude
            .inverse_transform_vector(&measured.velocity);
        if self.drag_estimate != [0.0; 3] {
            let drag_body = Vector3::from(self.drag_estimate).component_mul(&velocity_body);
            reference.acceleration +=
                measured.attitude * drag_body / self.controller.lqr().params().mass();
        }
        let cmd = self
            .plant
            .clamp_speeds(&self.controller.rotor_speeds(&measured, &reference));
        let rotor_sensing = self.config.flight_stack.rotor_sensing;
        // A brushed vehicle sends quantised PWM duties set for its measured battery voltage:
        // the motors get the quantised command times the reading's error; the flight stack
        // believes the quantised command.
        let (cmd, believed) = match rotor_sensing {
            RotorSensing::BrushedPwm(pwm) => {
                let max = self.config.vehicle.max_rotor_speed;
                let q = cmd.map(|w| pwm.quantise(w, max));
                let f = pwm.voltage_factor(&mut self.rotor_sensing_rng);
                (self.plant.clamp_speeds(&q.map(|w| w * f)), q)
            }
            _ => (cmd, cmd),
        };
        let start_speeds = state.rotor_speeds;
        let physics_log = self.config.record_log && self.config.log_rate == LogRate::Physics;
        // The truth of a control-rate sample averages over the interval's physics steps (the
        // state before the first one, and after each): collected without changing anything.
        let start = self
            .truth
            .is_some()
            .then(|| (*self.plant.state(), self.plant.accelerations(&cmd)));
        let mut steps = std::mem::take(&mut self.interval_steps);
        steps.clear();
        let (mid_state, mid_acc) =
            self.fly_interval(&cmd, (physics_log || start.is_some()).then_some(&mut steps));
        // What the vehicle measures of its actuators: the rotor speeds read back (+ noise) and,
        // through the nominal mixer, the wrench they make: the commanded speeds, or with
        // `FlightStack::motor_telemetry` and a motor lag the lagging speeds at the interval's
        // midpoint (the frame's time).
        let read_back = match rotor_sensing {
            RotorSensing::Telemetry => {
                if self.config.flight_stack.motor_telemetry
                    && self.config.effects.motor_lag.is_some()
                {
                    mid_state.rotor_speeds
                } else {
                    cmd
                }
            }
            RotorSensing::BrushedPwm(pwm) => {
                self.motor_model
                    .step(&believed, pwm.model_time_constant, dt)
            }
            RotorSensing::Erpm(erpm) => {
                // The motors' speeds at the latest reading before the midpoint (the closed
                // form of the motor lag within the interval, from its start).
                let t_mid = t + 0.5 * dt;
                let age = (t_mid - erpm.reading_time(t_mid)).clamp(0.0, 0.5 * dt);
                let since_start = 0.5 * dt - age;
                match self.config.effects.motor_lag {
                    Some(lag) => {
                        let decay = (-since_start / lag.time_constant).exp();
                        std::array::from_fn(|i| cmd[i] + (start_speeds[i] - cmd[i]) * decay)
                    }
                    None => cmd,
                }
            }
        };
        // With a `telemetry-lag` effect the speeds reported are the read-back ones delayed and
        // filtered (TelemetryLag): the log's, not the plant's.
        let reported = self.reported_speeds(read_back);
        if let Some(truth) = self.truth.as_mut() {
            let now = self.config.vehicle.wrench_from_rotor_speeds(&read_back);
            truth.read_back.push(now);
            truth.reported.push(if reported == read_back {
                now
            } else {
                self.config.vehicle.wrench_from_rotor_speeds(&reported)
            });
        }
        let measured_speeds = match rotor_sensing {
            RotorSensing::Erpm(erpm) => reported.map(|w| erpm.read(w, &mut self.rotor_sensing_rng)),
            _ => self.sensors.measured_rotor_speeds(&reported),
        };
        let wrench_measured: Wrench = self
            .config
            .vehicle
            .wrench_from_rotor_speeds(&measured_speeds);
        if !self.plant.is_finite() {
            self.tracking.push(f64::INFINITY);
            return Ok(ControlFlow::Break(()));
        }
        let frame = self.sensors.frame(
            self.plant.state().body_rate,
            mid_state.body_rate,
            mid_acc.proper,
            dt,
        );
        if physics_log {
            self.log_physics_samples(k, &mid_state, &steps, &wrench_measured, measured_speeds);
            for (i, (s, acc)) in steps.iter().enumerate() {
                let stamp = k as f64 + (i + 1) as f64 / steps.len() as f64;
                let t_s = k as f64 * dt + (i + 1) as f64 * self.substep;
                if let Some(v) = self.plant.battery_voltage(s, &cmd, t_s) {
                    self.vbat.push(v);
                }
                self.record_truth(k, stamp, t_s, (s, acc), None, &cmd);
            }
        } else if self.config.record_log {
            self.log_sample(k, &mid_state, &frame, &wrench_measured, measured_speeds);
            let t_s = k as f64 * dt + 0.5 * dt;
            if let Some(v) = self.plant.battery_voltage(&mid_state, &cmd, t_s) {
                self.vbat.push(v);
            }
            if let Some(start) = &start {
                let interval = (start, steps.as_slice());
                let mid = (&mid_state, &mid_acc);
                self.record_truth(k, k as f64 + 0.5, t_s, mid, Some(interval), &cmd);
            }
        }
        self.interval_steps = steps;
        self.update_estimator(k, t, &frame, &wrench_measured, &velocity_body)?;
        Ok(ControlFlow::Continue(()))
    }

    /// Applies the payload events due at the start of step `k` (time `t` \[s\]); the oracle
    /// redesigns its controller at once.
    fn apply_payload_events(&mut self, k: usize, t: f64) -> Result<(), SimError> {
        while self.next_event < self.schedule.len() && self.schedule[self.next_event].step <= k {
            let ev = self.schedule[self.next_event];
            let theta = if ev.attach {
                *self.plant.params() + ev.payload
            } else {
                *self.plant.params() - ev.payload
            };
            self.plant.set_params(theta)?;
            self.events.push(EventRecord {
                time: t,
                step: k,
                attach: ev.attach,
                params: theta.to_array(),
            });
            if !matches!(self.config.adaptation, Adaptation::Estimator(_)) {
                self.first_update_steps.push(k);
            }
            if matches!(self.config.adaptation, Adaptation::Oracle) {
                self.controller.redesign(&theta)?;
            }
            self.pending_event = true;
            self.next_event += 1;
        }
        Ok(())
    }

    /// Records the tracking error of the true `state` at time `t` (and the trace);
    /// `Break` on an abort when the configuration stops there.
    fn track(&mut self, t: f64, state: &PlantState) -> ControlFlow<()> {
        let reference = self.trajectory.sample(t);
        let err = (state.position - reference.position).norm();
        self.tracking
            .push(if err.is_finite() { err } else { f64::INFINITY });
        if self.config.record_trace {
            let pe = match &self.estimator {
                Some(_) => parameter_error(
                    &self.latest_estimate,
                    &self.config.identifiable_params(self.plant.params()),
                ),
                None => parameter_error(
                    self.controller.lqr().params().as_slice(),
                    self.plant.params(),
                ),
            };
            self.trace.push(TraceSample {
                t,
                position: state.position.into(),
                reference: reference.position.into(),
                parameter_error: pe,
            });
        }
        if (err.is_nan() || err > ABORT_THRESHOLD) && self.config.stop_on_abort {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }

    /// RK4 substeps over one control interval with the rotor speeds `cmd`; returns the state
    /// and accelerations at the interval's midpoint. With `steps`, also collects the state and
    /// accelerations after every substep (the physics-rate log).
    fn fly_interval(
        &mut self,
        cmd: &[f64; 4],
        mut steps: Option<&mut Vec<(PlantState, Accelerations)>>,
    ) -> (PlantState, Accelerations) {
        let mut mid = None;
        for j in 0..self.substeps {
            if 2 * j == self.substeps {
                mid = Some((*self.plant.state(), self.plant.accelerations(cmd)));
            }
            self.plant.step(cmd, self.substep);
            if let Some(steps) = steps.as_deref_mut() {
                steps.push((*self.plant.state(), self.plant.accelerations(cmd)));
            }
        }
        mid.unwrap_or_else(|| (*self.plant.state(), self.plant.accelerations(cmd)))
    }

    /// The measured rotor speeds and wrench a log sample of control interval `k` carries,
    /// stamped at `stamp` control periods (`k + ½` for the midpoint, `k + s` with `0 < s ≤ 1`
    /// within the interval): this interval's, or with a `time-delay` effect those measured
    /// `delay` earlier. Interval `j` holds its command over `(j dt, (j+1) dt]`, so the command
    /// at `stamp − delay/dt` is that of `ceil(stamp − delay/dt) − 1` (stamps within 1e-9 of an
    /// interval boundary count as on it; before the flight began, the first interval). Keeps the
    /// history it needs.
    fn logged_actuators(
        &mut self,
        k: usize,
        stamp: f64,
        wrench: &Wrench,
        rotor_speeds: [f64; 4],
    ) -> ([f64; 4], [f64; 6]) {
        match self.config.effects.time_delay {
            None => (rotor_speeds, wrench.to_array()),
            Some(_) => {
                if self.commands.len() == k {
                    self.commands.push((rotor_speeds, wrench.to_array()));
                }
                self.commands[self.logged_interval(k, stamp)]
            }
        }
    }

    /// The control interval (`≤ k`) whose actuator sample a log sample of interval `k` stamped
    /// at `stamp` control periods holds: `k` itself, or with a `time-delay` effect the interval
    /// the time `stamp − delay/dt` falls in ([`Flight::logged_actuators`]).
    fn logged_interval(&self, k: usize, stamp: f64) -> usize {
        let Some(d) = self.config.effects.time_delay else {
            return k;
        };
        let x = stamp - d.delay / self.config.control_dt;
        let x = if (x - x.round()).abs() < 1e-9 {
            x.round()
        } else {
            x
        };
        let j = (x.ceil() - 1.0).max(0.0) as usize;
        j.min(k)
    }

    /// The rotor speeds reported for this control interval, whose read-back speeds are
    /// `read_back`: these, or with a `telemetry-lag` effect the delayed and filtered ones
    /// ([`crate::plant_effects::TelemetryLag`]; the same recursion as its `reported`). Keeps
    /// the history and the filter's state it needs.
    fn reported_speeds(&mut self, read_back: [f64; 4]) -> [f64; 4] {
        let Some(lag) = self.config.effects.telemetry_lag else {
            return read_back;
        };
        let dt = self.config.control_dt;
        let (history, state) = &mut self.telemetry;
        history.push(read_back);
        let k = history.len() - 1;
        let input = history[k.saturating_sub(lag.delay_periods(dt))];
        let alpha = lag.alpha(dt);
        let mut y = state.unwrap_or(history[0]);
        for r in 0..4 {
            y[r] = alpha * y[r] + (1.0 - alpha) * input[r];
        }
        *state = Some(y);
        y
    }

    /// With [`SimConfig::record_truth`], appends the truth of a log sample of control interval
    /// `k` stamped at `stamp` control periods (time `t` \[s\]): the plant state `sample.0` with
    /// its accelerations `sample.1` under the clamped command `cmd`; for a control-rate sample
    /// also the interval's states (before its first physics step, and after each), whose
    /// torques the logged `ω̇` averages. Reads the states only: draws nothing, changes nothing
    /// of the flight.
    fn record_truth(
        &mut self,
        k: usize,
        stamp: f64,
        t: f64,
        sample: (&PlantState, &Accelerations),
        interval: Option<IntervalStates<'_>>,
        cmd: &[f64; 4],
    ) {
        let j = self.logged_interval(k, stamp);
        let Some(truth) = self.truth.as_mut() else {
            return;
        };
        let (now, reported, logged) = (truth.read_back[k], truth.reported[k], truth.reported[j]);
        let start = k as f64 * self.config.control_dt;
        let substep = self.substep;
        let parts = |(state, acc): (&PlantState, &Accelerations), time: f64| {
            let inputs = TruthInputs {
                state,
                acc,
                motor_speeds: self.plant.acting_rotor_speeds(state, cmd),
                motor_accelerations: self
                    .plant
                    .rotor_accelerations(state, &self.plant.clamp_speeds(cmd)),
                now,
                reported,
                logged,
                time,
            };
            truth_parts(
                &self.config.vehicle,
                &self.config.effects,
                &truth.effects,
                &inputs,
            )
        };
        let at_sample = parts(sample, t);
        let over_interval = interval.map(|((s0, a0), steps)| {
            let points: Vec<TruthParts> = std::iter::once(parts((s0, a0), start))
                .chain(
                    steps
                        .iter()
                        .enumerate()
                        .map(|(i, (s, a))| parts((s, a), start + (i + 1) as f64 * substep)),
                )
                .collect();
            let rate_change = steps
                .last()
                .map_or_else(Vector3::zeros, |(s, _)| s.body_rate - s0.body_rate);
            // Without a motor lag the rotor inertia's jump at the interval's start is an
            // impulse: the differenced gyro sees it spread over the interval.
            let jump = self
                .plant
                .rotor_jump_impulse(s0, &self.plant.clamp_speeds(cmd))
                / self.config.control_dt;
            let inertia = truth
                .effects
                .iter()
                .position(|e| *e == EffectKind::RotorInertia);
            (
                TruthParts::mean(&points).with_torque(inertia, &jump),
                rate_change / self.config.control_dt,
            )
        });
        let sample = TruthSample::new(
            t,
            *self.plant.params(),
            sample,
            logged,
            at_sample,
            over_interval,
        );
        truth.samples.push(sample);
    }

    /// Appends the log sample of control interval `k` (stamped at its midpoint) with the
    /// measured rotor speeds and wrench; with a `time-delay` effect, the wrench and rotor speeds
    /// are those measured `delay` earlier.
    fn log_sample(
        &mut self,
        k: usize,
        mid: &PlantState,
        frame: &Frame,
        wrench: &Wrench,
        rotor_speeds: [f64; 4],
    ) {
        let dt = self.config.control_dt;
        let (rotor_speeds, wrench) = self.logged_actuators(k, k as f64 + 0.5, wrench, rotor_speeds);
        let q = mid.attitude;
        let velocity = self.sensors.logged_velocity(mid.velocity);
        self.log.push(&LogSample {
            t: k as f64 * dt + 0.5 * dt,
            position: mid.position.into(),
            velocity: velocity.into(),
            attitude: [q.w, q.i, q.j, q.k],
            omega: frame.omega.into(),
            wrench,
            accel: Some((q * frame.accel + GRAVITY_WORLD).into()),
            omega_dot: Some(frame.omega_dot.into()),
            rotor_speeds: Some(rotor_speeds),
        });
    }

    /// Appends the physics-rate log samples of control interval `k` ([`LogRate::Physics`]):
    /// one per RK4 step, stamped at the step's end, with instantaneous IMU-style readings of
    /// the states in `steps` (after each step, with their accelerations). Draws the control-rate
    /// log's velocity noise too (and discards it), so that the noise stream, hence the flight,
    /// is that of a control-rate log.
    fn log_physics_samples(
        &mut self,
        k: usize,
        mid: &PlantState,
        steps: &[(PlantState, Accelerations)],
        wrench: &Wrench,
        rotor_speeds: [f64; 4],
    ) {
        let _ = self.sensors.logged_velocity(mid.velocity);
        let dt = self.config.control_dt;
        for (i, (s, acc)) in steps.iter().enumerate() {
            let t_s = k as f64 * dt + (i + 1) as f64 * self.substep;
            let stamp = k as f64 + (i + 1) as f64 / steps.len() as f64;
            let (speeds, w) = self.logged_actuators(k, stamp, wrench, rotor_speeds);
            let (omega, accel, velocity) =
                self.sensors.imu_sample(s.body_rate, acc.proper, s.velocity);
            let q = s.attitude;
            self.log.push(&LogSample {
                t: t_s,
                position: s.position.into(),
                velocity: velocity.into(),
                attitude: [q.w, q.i, q.j, q.k],
                omega: omega.into(),
                wrench: w,
                accel: Some((q * accel + GRAVITY_WORLD).into()),
                omega_dot: None,
                rotor_speeds: Some(speeds),
            });
        }
    }

    /// Pushes the frame (with the measured body-frame velocity `velocity_body` \[m/s\] of the
    /// drag columns) into the estimator's window and, every `estimator_period` steps with a full
    /// window, updates the estimator and hands its estimate through the safety gate to the
    /// controller.
    fn update_estimator(
        &mut self,
        k: usize,
        t: f64,
        frame: &Frame,
        wrench: &Wrench,
        velocity_body: &Vector3<f64>,
    ) -> Result<(), SimError> {
        let Some(stage) = self.estimator.as_mut() else {
            return Ok(());
        };
        stage
            .window
            .push(&frame.accel, &frame.omega, &frame.omega_dot, wrench)?;
        let buffers = &mut stage.buffers;
        if buffers.columns.drag {
            if buffers.velocities.len() == self.config.window_frames {
                buffers.velocities.pop_front();
            }
            buffers.velocities.push_back((*velocity_body).into());
        }
        let periodic =
            (k + 1).is_multiple_of(self.config.estimator_period) && stage.window.is_full();
        // The window is built at most once per step (the check and the update share it).
        let mut built: Option<usize> = None;
        // The change detector: the newest frame against the current estimate, every step.
        let mut fresh = false;
        if stage.detect {
            if let Some(due) = stage.fresh_due {
                fresh = k >= due;
            } else {
                let rows = stage.window.build(&mut buffers.a_buf, &mut buffers.b_buf)?;
                built = Some(rows);
                let first = rows.saturating_sub(6);
                let (a, b) = buffers.rows(first, rows);
                let weights = stage.weights.as_deref().map(|w| &w[..rows - first]);
                if let Ok(check) = stage.main.check(a, b, weights)
                    && check.alarm
                {
                    self.alarms.push(k);
                    stage.fresh_due = Some(k + CHANGE_FRESH_FRAMES - 1);
                    fresh = CHANGE_FRESH_FRAMES <= 1;
                }
            }
        }
        // While an alarm awaits its fresh window, no periodic update mixes in older frames.
        if !(fresh || periodic && stage.fresh_due.is_none()) {
            return Ok(());
        }
        let rows = match built {
            Some(rows) => rows,
            None => stage.window.build(&mut buffers.a_buf, &mut buffers.b_buf)?,
        };
        let first = if fresh {
            rows.saturating_sub(6 * CHANGE_FRESH_FRAMES)
        } else {
            0
        };
        if fresh {
            stage.fresh_due = None;
        }
        let (a, b) = buffers.rows(first, rows);
        let weights = stage.weights.as_deref().map(|w| &w[..rows - first]);
        if fresh {
            // A failed solve keeps the restarted estimator; the update below goes on.
            let _ = stage.main.first_estimate(a, b, weights);
        }
        let start = Instant::now();
        let result = stage.main.inner_mut().update_weighted(a, b, weights);
        let micros = start.elapsed().as_secs_f64() * 1e6;
        if let Some(e) = stage.early.as_mut() {
            // Estimator errors leave the state unchanged; the flight goes on.
            let _ = e.update_weighted(a, b, weights);
        }
        if result.is_err() {
            return Ok(());
        }
        if self.pending_event
            && let Some(e) = stage.early.as_ref()
        {
            let tagk_estimate = e.estimate().to_vec();
            stage.main.inner_mut().reset(&tagk_estimate)?;
        }
        let estimate: [f64; 10] = core::array::from_fn(|i| stage.main.inner().estimate()[i]);
        self.latest_estimate = estimate;
        if stage.buffers.columns.drag {
            // The drag dissipates: each coefficient is clamped to [0, limit].
            let first = N_PARAMS
                + if stage.buffers.columns.force_bias {
                    FORCE_BIAS_PARAMS
                } else {
                    0
                };
            let limit = DRAG_LIMIT_PER_MASS * self.config.vehicle.params.mass();
            let full = stage.main.inner().estimate();
            self.drag_estimate = core::array::from_fn(|c| {
                let d = full[first + c];
                if d.is_finite() {
                    d.clamp(0.0, limit)
                } else {
                    0.0
                }
            });
        }
        let truth = *self.plant.params();
        // Scored against what the data identify (θ/(1+ε)), not θ itself.
        let scored = self.config.identifiable_params(&truth);
        if self.pending_event {
            // The window holds the frames of steps k − frames + 1 ..= k; the event applied at
            // the start of its step, so the window is clean when that step is the first frame
            // or earlier.
            let event_step = self.events.last().map_or(0, |e| e.step);
            let mixed = k + 1 < event_step + (rows - first) / 6;
            self.first_after_event
                .push((estimate.to_vec(), scored, mixed));
            self.first_update_steps.push(k + 1);
            self.pending_event = false;
        }
        let theta = self.config.flight_stack.controller_params(
            &InertialParams::from_array(estimate),
            &self.config.vehicle.params,
        );
        let accepted = theta.safety_gate(&self.config.gate).is_ok()
            && self.controller.redesign(&theta).is_ok();
        self.updates.push(UpdateRecord {
            time: t + self.config.control_dt,
            estimate,
            truth: truth.to_array(),
            accepted,
            micros,
            drag: self.drag_estimate,
        });
        Ok(())
    }

    /// The metrics of the flight flown and everything it recorded.
    fn finish(mut self) -> SimOutput {
        if self.config.effects.battery_voltage.is_some() && self.vbat.len() == self.log.len() {
            let vbat = std::mem::take(&mut self.vbat);
            self.log.add_extra(tagk_dynamics::BATTERY_COLUMN, vbat);
        }
        let tracking = self.tracking;
        let aborted = is_aborted(&tracking);
        let event_steps: Vec<usize> = self.events.iter().map(|e| e.step).collect();
        let success = is_success(&tracking, &event_steps, aborted);
        let success_after_update = is_success(&tracking, &self.first_update_steps, aborted);
        let finite: Vec<f64> = tracking.iter().copied().filter(|e| e.is_finite()).collect();
        let split = |keep: fn(bool) -> bool| -> Vec<(Vec<f64>, InertialParams)> {
            self.first_after_event
                .iter()
                .filter(|(_, _, mixed)| keep(*mixed))
                .map(|(e, t, _)| (e.clone(), *t))
                .collect()
        };
        let t1_all = split(|_| true);
        let t1_clean = split(|mixed| !mixed);
        let t1_mixed = split(|mixed| mixed);
        let (pe, ge) = mean_update_errors(&self.updates, self.config.identifiable_scale());
        let metrics = TrialMetrics {
            position_error_cm: position_error_cm(&finite),
            max_tracking_error_cm: 100.0 * tracking.iter().copied().fold(0.0, f64::max),
            parameter_error: pe,
            group_errors: ge,
            t1_error: t_plus_one_error(&t1_all),
            t1_error_clean: t_plus_one_error(&t1_clean),
            t1_error_mixed: t_plus_one_error(&t1_mixed),
            position_error_all_cm: position_error_all_cm(&tracking, self.planned_steps),
            settled: is_settled(&tracking, &event_steps, aborted),
            settle_error_cm: settle_error_cm(&tracking, &event_steps, aborted),
            success,
            success_after_update,
            aborted,
            steps: tracking.len(),
        };
        let (gyro_bias, accel_bias) = self.sensors.biases();
        let truth = self.truth.map(|t| FlightTruth {
            effects: t.effects,
            accel_bias: accel_bias.into(),
            gyro_bias: gyro_bias.into(),
            samples: t.samples,
        });
        SimOutput {
            trajectory: self.trajectory,
            truth,
            metrics,
            events: self.events,
            alarms: self.alarms,
            updates: self.updates,
            log: self.log,
            trace: self.trace,
            tracking_errors: tracking,
        }
    }
}

impl WindowBuffers {
    /// Rows `first..rows` of the built window (`a_buf`: θ's 10 columns). With effect columns
    /// ([`EffectColumns`]) they are appended in `a_wide`: the nuisance force's identity on each
    /// frame's force rows, then the drag's body-frame velocity of the frame on its force rows.
    fn rows(&mut self, first: usize, rows: usize) -> (&[f64], &[f64]) {
        let n = self.unknowns;
        let b = &self.b_buf[first..rows];
        if n == N_PARAMS {
            return (&self.a_buf[first * N_PARAMS..rows * N_PARAMS], b);
        }
        // The window's frames are the newest `rows / 6` velocities; row r is frame r / 6.
        let skipped = self.velocities.len().saturating_sub(rows / 6);
        for r in first..rows {
            let (src, dst) = (
                &self.a_buf[r * N_PARAMS..(r + 1) * N_PARAMS],
                &mut self.a_wide[(r - first) * n..(r - first + 1) * n],
            );
            dst[..N_PARAMS].copy_from_slice(src);
            let channel = r % 6;
            let mut j = N_PARAMS;
            if self.columns.force_bias {
                for c in 0..FORCE_BIAS_PARAMS {
                    dst[j + c] = if channel == c { 1.0 } else { 0.0 };
                }
                j += FORCE_BIAS_PARAMS;
            }
            if self.columns.drag {
                let v = self
                    .velocities
                    .get(skipped + r / 6)
                    .copied()
                    .unwrap_or([0.0; 3]);
                for c in 0..DRAG_PARAMS {
                    dst[j + c] = if channel == c { v[c] } else { 0.0 };
                }
            }
        }
        (&self.a_wide[..(rows - first) * n], b)
    }
}

/// Mean parameter error and mean per-group relative errors over the estimator's updates
/// (NaN without updates), against the identifiable parameters: the recorded truth times
/// `scale` ([`SimConfig::identifiable_scale`]).
fn mean_update_errors(updates: &[UpdateRecord], scale: f64) -> (f64, GroupErrors) {
    if updates.is_empty() {
        return (
            f64::NAN,
            GroupErrors {
                mass: f64::NAN,
                first_moment: f64::NAN,
                inertia: f64::NAN,
            },
        );
    }
    let n_up = updates.len() as f64;
    let mut pe = 0.0;
    let mut ge = GroupErrors::default();
    for u in updates {
        let truth = if scale == 1.0 {
            InertialParams::from_array(u.truth)
        } else {
            InertialParams::from_array(u.truth.map(|x| x * scale))
        };
        pe += parameter_error(&u.estimate, &truth);
        let g = group_errors(&u.estimate, &truth, CRAZYFLIE_ARM_OFFSET);
        ge.mass += g.mass;
        ge.first_moment += g.first_moment;
        ge.inertia += g.inertia;
    }
    (
        pe / n_up,
        GroupErrors {
            mass: ge.mass / n_up,
            first_moment: ge.first_moment / n_up,
            inertia: ge.inertia / n_up,
        },
    )
}
