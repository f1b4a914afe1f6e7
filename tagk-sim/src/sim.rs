//! One closed-loop flight: plant, measurement model, LQR, payload events, estimator and
//! safety gate (see the crate docs for the whole loop).

use std::time::Instant;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use serde::{Deserialize, Serialize};
use tagk_control::{
    DareOptions, Lqr, LqrWeights, QuadrotorState, RiccatiSolver, error_state, hover_trim,
};
use tagk_core::OnlineEstimator;
use tagk_dynamics::{
    GRAVITY_WORLD, InertialParams, QuadrotorModel, SafetyGate, WindowBuilder, Wrench,
};

use crate::estimators::{EstimatorSpec, N_PARAMS, build_kind, column_scales, noise_floor};
use crate::log::LogSample;
use crate::metrics::{
    ABORT_THRESHOLD, GroupErrors, group_errors, is_aborted, is_success, parameter_error,
    position_error_cm, t_plus_one_error,
};
use crate::plant::{Plant, PlantState, validate_params};
use crate::trajectory::{ReferenceSample, Trajectory, TrajectoryKind};
use crate::{EstimatorKind, PlantEffects, SimError};

/// Arm length used for payload offsets and the relative first-moment error: the paper's
/// `L_arm = 0.0325 m` (motor offset along each body axis, CONVENTIONS §1/§4).
pub const ARM_LENGTH: f64 = 0.0325;

/// Noise on the velocity and acceleration fed to the controller and the estimator
/// (CONVENTIONS §5).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, clap::ValueEnum,
)]
pub enum NoiseLevel {
    /// σ_v = 0, σ_a = 0.
    #[default]
    None,
    /// σ_v = 0.05 cm/s, σ_a = 0.005 cm/s².
    Low,
    /// σ_v = 0.5 cm/s, σ_a = 0.05 cm/s².
    Medium,
    /// σ_v = 2.5 cm/s, σ_a = 0.25 cm/s².
    High,
}

impl NoiseLevel {
    /// The four levels of Table II.
    pub const ALL: [NoiseLevel; 4] = [
        NoiseLevel::None,
        NoiseLevel::Low,
        NoiseLevel::Medium,
        NoiseLevel::High,
    ];

    /// Standard deviation of each velocity component [m/s].
    pub fn sigma_velocity(self) -> f64 {
        match self {
            NoiseLevel::None => 0.0,
            NoiseLevel::Low => 0.05e-2,
            NoiseLevel::Medium => 0.5e-2,
            NoiseLevel::High => 2.5e-2,
        }
    }

    /// Standard deviation of each acceleration component [m/s²].
    pub fn sigma_acceleration(self) -> f64 {
        match self {
            NoiseLevel::None => 0.0,
            NoiseLevel::Low => 0.005e-2,
            NoiseLevel::Medium => 0.05e-2,
            NoiseLevel::High => 0.25e-2,
        }
    }

    /// Display name.
    pub fn name(self) -> &'static str {
        match self {
            NoiseLevel::None => "none",
            NoiseLevel::Low => "low",
            NoiseLevel::Medium => "medium",
            NoiseLevel::High => "high",
        }
    }
}

/// Shape of a payload.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum PayloadShape {
    /// A point mass.
    PointMass,
    /// An axis-aligned solid box with edge lengths `size` [m], centred at the offset.
    Box {
        /// Edge lengths along body x, y, z [m].
        size: [f64; 3],
    },
}

/// A payload attached at `attach_time` and (optionally) removed at `remove_time`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Payload {
    /// Mass [kg].
    pub mass: f64,
    /// Position of its centre of mass in the body frame [m].
    pub offset: [f64; 3],
    /// Shape.
    pub shape: PayloadShape,
    /// Attach time [s].
    pub attach_time: f64,
    /// Removal time [s] (`None`: carried to the end).
    pub remove_time: Option<f64>,
}

impl Payload {
    /// The inertial parameters of the payload alone, about the body origin.
    pub fn params(&self) -> InertialParams {
        let c = Vector3::from(self.offset);
        match self.shape {
            PayloadShape::PointMass => InertialParams::point_mass(self.mass, c),
            PayloadShape::Box { size } => {
                InertialParams::solid_box(self.mass, c, Vector3::from(size))
            }
        }
    }

    /// The protocol's random payload (CONVENTIONS §5) for a vehicle of mass `vehicle_mass`:
    /// a point mass of `U[0.3, 0.5]·m`, at `U[0.2, 0.3]·L_arm` from the origin in a direction
    /// uniform on the sphere, attached at `U[4, 6] s`, removed at `U[12, 14] s`.
    pub fn random_protocol<R: rand::Rng + ?Sized>(vehicle_mass: f64, rng: &mut R) -> Self {
        let mass = vehicle_mass * rng.random_range(0.3..0.5);
        let dist = ARM_LENGTH * rng.random_range(0.2..0.3);
        let z: f64 = rng.random_range(-1.0..1.0);
        let az: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let r = (1.0 - z * z).sqrt();
        Self {
            mass,
            offset: [dist * r * az.cos(), dist * r * az.sin(), dist * z],
            shape: PayloadShape::PointMass,
            attach_time: rng.random_range(4.0..6.0),
            remove_time: Some(rng.random_range(12.0..14.0)),
        }
    }
}

/// Which payloads a flight carries.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub enum PayloadSchedule {
    /// No payload.
    None,
    /// One random payload per the protocol ([`Payload::random_protocol`]), drawn from the seed;
    /// draws the rotors cannot hover are redrawn.
    #[default]
    Protocol,
    /// One random payload as in [`Protocol`](Self::Protocol) but attached and removed at these
    /// fixed times [s] (aligns the events across trials for averaged time curves).
    ProtocolAt {
        /// Attach time [s].
        attach: f64,
        /// Removal time [s].
        remove: f64,
    },
    /// These payloads.
    Fixed(Vec<Payload>),
}

/// What parameters the controller is designed for.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Adaptation {
    /// The nominal (payload-free) vehicle throughout: no estimation.
    Nominal,
    /// The true parameters, redesigned at every payload event (an oracle; no estimation).
    Oracle,
    /// An online estimator through the safety gate.
    Estimator(EstimatorSpec),
}

/// The simulator's default LQR weights (Bryson's rule, `Q_ii = 1/x_max²`, `R_ii = 1/u_max²`)
/// for trajectory tracking with payloads:
///
/// | state | acceptable deviation | weight |
/// |---|---|---|
/// | position x, y | 1.6 cm | 4000 |
/// | position z | 1 cm | 10 000 |
/// | velocity x, y / z | 10 / 7 cm/s | 100 / 200 |
/// | roll, pitch / yaw error | 0.05 / 0.2 rad | 400 / 25 |
/// | body rates | 1 rad/s | 1 |
/// | each rotor thrust deviation | 0.02 N | 2500 |
///
/// `tagk_control::LqrWeights::crazyflie` (5 cm position tolerance) is a gentler hover design:
/// with it, a 30–50 % payload drops the vehicle by more than the 5 cm success threshold before
/// any estimator at 2.5 Hz can respond (see the crate README's study).
pub fn tracking_weights() -> LqrWeights {
    LqrWeights::from_diagonals(
        [
            4000.0, 4000.0, 10000.0, 100.0, 100.0, 200.0, 400.0, 400.0, 25.0, 1.0, 1.0, 1.0,
        ],
        [2500.0; 4],
    )
}

/// Configuration of one flight. [`SimConfig::default`] is the paper's protocol (figure-8,
/// 20 s, random payload, ideal plant, no noise, TAG-K).
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Reference path shape (size, centre and phase are drawn from the seed).
    pub trajectory: TrajectoryKind,
    /// Flight duration [s].
    pub duration: f64,
    /// Seed of every random choice of the flight.
    pub seed: u64,
    /// Velocity/acceleration noise.
    pub noise: NoiseLevel,
    /// Standard deviation of rate-gyro noise on each axis [rad/s] (0: off).
    pub gyro_noise: f64,
    /// Payload events.
    pub payload: PayloadSchedule,
    /// Plant effects (all off by default).
    pub effects: PlantEffects,
    /// Controller parameters: nominal, oracle, or estimated.
    pub adaptation: Adaptation,
    /// Height of the path centre [m] (`None`: random in `[0.8, 1.5]`).
    pub altitude: Option<f64>,
    /// RK4 physics step [s] (must divide the control period; ≤ 2 ms).
    pub physics_dt: f64,
    /// Control period [s] (50 Hz).
    pub control_dt: f64,
    /// Control steps between estimator updates (20 → 2.5 Hz).
    pub estimator_period: usize,
    /// Frames per estimator window (5 → `A` is 30×10).
    pub window_frames: usize,
    /// Safety gate between estimator and controller.
    pub gate: SafetyGate,
    /// Stop the flight when the tracking error exceeds 30 cm (an abort).
    pub stop_on_abort: bool,
    /// Keep a [`LogSample`] per control step.
    pub record_log: bool,
    /// Keep a [`TraceSample`] per control step.
    pub record_trace: bool,
    /// Actuator layout and nominal parameters of the vehicle.
    pub vehicle: QuadrotorModel,
    /// LQR cost weights.
    pub weights: LqrWeights,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            trajectory: TrajectoryKind::Figure8,
            duration: 20.0,
            seed: 0,
            noise: NoiseLevel::None,
            gyro_noise: 0.0,
            payload: PayloadSchedule::Protocol,
            effects: PlantEffects::none(),
            adaptation: Adaptation::Estimator(EstimatorSpec::new(EstimatorKind::TagK)),
            altitude: None,
            physics_dt: 0.002,
            control_dt: 0.02,
            estimator_period: 20,
            window_frames: 5,
            gate: SafetyGate::crazyflie(),
            stop_on_abort: true,
            record_log: false,
            record_trace: false,
            vehicle: QuadrotorModel::crazyflie_2_1(),
            weights: tracking_weights(),
        }
    }
}

/// A payload change as it happened.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// Time [s] (quantised to the control step).
    pub time: f64,
    /// Control step index.
    pub step: usize,
    /// `true` for an attach, `false` for a removal.
    pub attach: bool,
    /// True parameters after the event.
    pub params: [f64; 10],
}

/// One estimator update.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UpdateRecord {
    /// Time [s].
    pub time: f64,
    /// The estimator's output `θ̂`.
    pub estimate: [f64; 10],
    /// True parameters at that time.
    pub truth: [f64; 10],
    /// Whether the safety gate (and the controller redesign) accepted it.
    pub accepted: bool,
    /// Wall-clock time of the estimator update alone [µs].
    pub micros: f64,
}

/// Per-control-step trace for figures.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TraceSample {
    /// Time [s].
    pub t: f64,
    /// True position [m].
    pub position: [f64; 3],
    /// Reference position [m].
    pub reference: [f64; 3],
    /// `‖θ̂ − θ‖₂` of the latest estimator output (of the controller's parameters without
    /// an estimator).
    pub parameter_error: f64,
}

/// Metrics of one flight (definitions in [`crate::metrics`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialMetrics {
    /// Position error [cm].
    pub position_error_cm: f64,
    /// Largest tracking error [cm].
    pub max_tracking_error_cm: f64,
    /// Mean parameter error `‖θ̂ − θ‖₂` over the estimator's updates (NaN without updates).
    pub parameter_error: f64,
    /// Mean per-group relative errors over the updates.
    pub group_errors: GroupErrors,
    /// (t+1) error (NaN without an event followed by an update).
    pub t1_error: f64,
    /// Success (CONVENTIONS §5: judged 10 control steps after each payload event).
    pub success: bool,
    /// Success judged instead 10 control steps after the first estimator update following
    /// each payload event (the window in which an estimator can act; equals the controller's
    /// redesign for the oracle, judged at the event).
    pub success_after_update: bool,
    /// Aborted.
    pub aborted: bool,
    /// Control steps flown.
    pub steps: usize,
}

/// Everything one flight produced.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    /// The reference path flown.
    pub trajectory: Trajectory,
    /// Metrics.
    pub metrics: TrialMetrics,
    /// Payload events.
    pub events: Vec<EventRecord>,
    /// Estimator updates.
    pub updates: Vec<UpdateRecord>,
    /// Flight log (empty unless [`SimConfig::record_log`]).
    pub log: Vec<LogSample>,
    /// Trace (empty unless [`SimConfig::record_trace`]).
    pub trace: Vec<TraceSample>,
    /// Tracking error per control step [m].
    pub tracking_errors: Vec<f64>,
}

/// Relative change `‖P_{k+1} − P_k‖_F / ‖P_{k+1}‖_F` at which the warm-started Riccati
/// iteration of a redesign stops: the gain is then accurate to about this relative level,
/// far below what the closed loop can notice, at a fraction of the iterations of the
/// `1e-11` default.
pub const REDESIGN_TOLERANCE: f64 = 1e-8;

/// LQR trajectory-tracking controller: the hover LQR of `tagk-control` around a reference
/// that carries the path's feedforward. The reference attitude tilts body `z` along the
/// desired specific force `a_ref − g_w` (yaw 0), and the collective thrust gets the
/// feedforward `m̂ (‖a_ref − g_w‖ − g) / 4` per rotor; rotor thrusts are clipped to
/// `[0, T_max]` and converted to speeds `ω = sqrt(T / k_f)`.
#[derive(Debug, Clone)]
pub struct Controller {
    lqr: Lqr,
}

impl Controller {
    /// Designs for `params` at period `dt` [s] (Riccati doubling for the first design, warm
    /// started Riccati iteration for every redesign, stopping at a relative change of
    /// [`REDESIGN_TOLERANCE`]).
    ///
    /// # Errors
    /// [`SimError::Control`].
    pub fn new(
        model: &QuadrotorModel,
        params: &InertialParams,
        weights: LqrWeights,
        dt: f64,
    ) -> Result<Self, SimError> {
        let mut lqr = Lqr::with_solver(
            model,
            params,
            weights,
            dt,
            RiccatiSolver::Doubling,
            DareOptions {
                tolerance: REDESIGN_TOLERANCE,
                ..DareOptions::default()
            },
        )?;
        lqr.set_solver(RiccatiSolver::Iteration);
        Ok(Self { lqr })
    }

    /// Re-linearises at `params` and warm-starts the Riccati solve; unchanged on error.
    ///
    /// # Errors
    /// [`SimError::Control`].
    pub fn redesign(&mut self, params: &InertialParams) -> Result<(), SimError> {
        self.lqr.redesign(params)?;
        Ok(())
    }

    /// The underlying LQR.
    pub fn lqr(&self) -> &Lqr {
        &self.lqr
    }

    /// Rotor speeds [rad/s] for the measured `state` tracking `reference`.
    pub fn rotor_speeds(&self, state: &QuadrotorState, reference: &ReferenceSample) -> [f64; 4] {
        let model = self.lqr.model();
        let specific = reference.acceleration - GRAVITY_WORLD;
        let norm = specific.norm();
        let attitude = if norm > 1e-6 {
            let z = specific / norm;
            let y = z.cross(&Vector3::x()).normalize();
            let x = y.cross(&z);
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
                Matrix3::from_columns(&[x, y, z]),
            ))
        } else {
            UnitQuaternion::identity()
        };
        let r = QuadrotorState {
            position: reference.position,
            velocity: reference.velocity,
            attitude,
            body_rate: Vector3::zeros(),
        };
        let e = error_state(state, &r);
        let extra = self.lqr.params().mass() * (norm - GRAVITY_WORLD.z.abs()) / 4.0;
        let hi = model.max_thrust_per_rotor();
        let thrusts = prioritise_attitude(self.lqr.command_unclamped(&e).map(|t| t + extra), hi);
        model.rotor_speeds_from_thrusts(&thrusts)
    }
}

/// Saturation with attitude priority: when some rotor thrust leaves `[0, hi]` [N], all four
/// are shifted by the same amount (changing only the collective thrust, not the torques)
/// as far as that brings them inside; whatever still exceeds is clipped per rotor. Clipping
/// each rotor independently instead would turn a collective demand beyond the limits into
/// spurious torques and tip the vehicle over while it recovers from a payload drop.
pub fn prioritise_attitude(thrusts: [f64; 4], hi: f64) -> [f64; 4] {
    let max = thrusts.iter().copied().fold(f64::MIN, f64::max);
    let min = thrusts.iter().copied().fold(f64::MAX, f64::min);
    let shift = if max > hi {
        (hi - max).max(-min.max(0.0))
    } else if min < 0.0 {
        (-min).min(hi - max)
    } else {
        0.0
    };
    thrusts.map(|t| (t + shift).clamp(0.0, hi))
}

/// Standard normal draw (Box–Muller).
pub(crate) fn gaussian<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn noise3<R: rand::Rng + ?Sized>(rng: &mut R, sigma: f64) -> Vector3<f64> {
    if sigma == 0.0 {
        return Vector3::zeros();
    }
    Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma
}

/// Independent random stream `stream` of a flight seeded with `seed` (SplitMix64 mixing).
pub(crate) fn sub_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut z = seed
        .wrapping_add(stream.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ChaCha8Rng::seed_from_u64(z ^ (z >> 31))
}

fn positive(what: &'static str, value: f64) -> Result<(), SimError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(SimError::InvalidDuration { what, value })
    }
}

impl SimConfig {
    /// Checks the configuration without flying: durations and steps, the vehicle, the
    /// effects, fixed payloads (positive mass, and hover feasible within the rotor limits).
    ///
    /// # Errors
    /// The first problem found, as a typed [`SimError`].
    pub fn validate(&self) -> Result<(), SimError> {
        positive("duration", self.duration)?;
        positive("physics_dt", self.physics_dt)?;
        positive("control_dt", self.control_dt)?;
        if self.physics_dt > 0.002 + 1e-15 {
            return Err(SimError::InvalidParameter {
                name: "physics_dt",
                value: self.physics_dt,
                reason: "must be at most 2 ms",
            });
        }
        let ratio = self.control_dt / self.physics_dt;
        if (ratio - ratio.round()).abs() > 1e-9 || ratio.round() < 1.0 {
            return Err(SimError::InvalidParameter {
                name: "control_dt / physics_dt",
                value: ratio,
                reason: "must be a positive integer",
            });
        }
        if self.estimator_period == 0 || self.window_frames == 0 {
            return Err(SimError::InvalidParameter {
                name: "estimator_period / window_frames",
                value: 0.0,
                reason: "must be positive",
            });
        }
        if !(self.gyro_noise >= 0.0 && self.gyro_noise.is_finite()) {
            return Err(SimError::InvalidParameter {
                name: "gyro_noise",
                value: self.gyro_noise,
                reason: "must be non-negative and finite",
            });
        }
        validate_params(&self.vehicle.params)?;
        self.effects.validate()?;
        if let PayloadSchedule::Fixed(list) = &self.payload {
            for p in list {
                check_payload(&self.vehicle, p)?;
            }
        }
        if let Adaptation::Estimator(spec) = &self.adaptation
            && !(0.0..1.0).contains(&spec.burn_in)
        {
            return Err(SimError::InvalidParameter {
                name: "burn_in",
                value: spec.burn_in,
                reason: "must be in [0, 1)",
            });
        }
        Ok(())
    }
}

/// Checks one payload: positive finite mass, finite offset and times, and a hover trim of
/// vehicle plus payload within the rotor limits.
///
/// # Errors
/// [`SimError::NonPositiveMass`], [`SimError::InvalidParameter`],
/// [`SimError::PayloadBeyondThrust`].
pub fn check_payload(vehicle: &QuadrotorModel, p: &Payload) -> Result<(), SimError> {
    if !(p.mass > 0.0 && p.mass.is_finite()) {
        return Err(SimError::NonPositiveMass {
            what: "payload",
            mass: p.mass,
        });
    }
    let times = [p.attach_time, p.remove_time.unwrap_or(p.attach_time)];
    if let Some(&v) = p.offset.iter().chain(&times).find(|v| !v.is_finite()) {
        return Err(SimError::InvalidParameter {
            name: "payload offset/time",
            value: v,
            reason: "must be finite",
        });
    }
    let with = vehicle.params + p.params();
    validate_params(&with)?;
    let trim = hover_trim(vehicle, &with, Vector3::zeros(), 0.0)?;
    let required = trim.thrusts.iter().copied().fold(f64::MIN, f64::max);
    let available = vehicle.max_thrust_per_rotor();
    if required > available || trim.thrusts.iter().any(|t| *t < 0.0) {
        return Err(SimError::PayloadBeyondThrust {
            required,
            available,
        });
    }
    Ok(())
}

/// A scheduled change of the true parameters.
#[derive(Debug, Clone, Copy)]
struct ScheduledEvent {
    step: usize,
    attach: bool,
    payload: InertialParams,
}

struct EstimatorSlot {
    main: Box<dyn OnlineEstimator<f64> + Send>,
    early: Option<Box<dyn OnlineEstimator<f64> + Send>>,
}

/// Flies one trial (see the crate docs for the loop, the measurement model and the timing).
///
/// # Errors
/// An invalid configuration ([`SimConfig::validate`]) or a controller that cannot be
/// designed for the nominal vehicle. Estimator rejections and gate violations during the
/// flight are not errors: the controller keeps its previous parameters.
pub fn simulate(config: &SimConfig) -> Result<SimOutput, SimError> {
    config.validate()?;
    let vehicle = &config.vehicle;
    let nominal = vehicle.params;
    let dt_c = config.control_dt;
    let substeps = (dt_c / config.physics_dt).round() as usize;
    let h = dt_c / substeps as f64;
    let steps = (config.duration / dt_c).round().max(1.0) as usize;

    // Independent random streams: setup, measurement noise, estimator seeds.
    let mut setup = sub_rng(config.seed, 1);
    let mut noise = sub_rng(config.seed, 2);
    let est_seed = sub_rng(config.seed, 3).random::<u64>();

    let trajectory = Trajectory::random(
        config.trajectory,
        config.duration,
        config.altitude,
        &mut setup,
    )?;
    let payloads: Vec<Payload> = match &config.payload {
        PayloadSchedule::None => Vec::new(),
        PayloadSchedule::Protocol | PayloadSchedule::ProtocolAt { .. } => {
            // Rejection sampling: a heavy payload far out along a diagonal can need more than
            // the rotors' limit to hover (the protocol's corner case); such draws are redrawn.
            let mut draw = Payload::random_protocol(nominal.mass(), &mut setup);
            let mut attempts = 1;
            while let Err(e) = check_payload(vehicle, &draw) {
                if attempts >= 1000 {
                    return Err(e);
                }
                draw = Payload::random_protocol(nominal.mass(), &mut setup);
                attempts += 1;
            }
            if let PayloadSchedule::ProtocolAt { attach, remove } = config.payload {
                draw.attach_time = attach;
                draw.remove_time = Some(remove);
            }
            vec![draw]
        }
        PayloadSchedule::Fixed(list) => list.clone(),
    };
    let mut schedule: Vec<ScheduledEvent> = Vec::new();
    for p in &payloads {
        let theta = p.params();
        let step_of = |t: f64| (t / dt_c).ceil().max(0.0) as usize;
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

    // Initial state: near the path's start, at rest, slightly tilted.
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
    let mut plant = Plant::new(*vehicle, nominal, config.effects, init)?;
    let mut controller = Controller::new(vehicle, &nominal, config.weights, dt_c)?;

    let m_max = 6 * config.window_frames;
    let scales = match &config.adaptation {
        Adaptation::Estimator(spec) if spec.scaled => {
            column_scales(&nominal.to_array(), ARM_LENGTH)
        }
        _ => [1.0; 10],
    };
    let drop_lateral =
        matches!(&config.adaptation, Adaptation::Estimator(spec) if spec.actuated_rows_only);
    let prior: Vec<f64> = nominal
        .as_slice()
        .iter()
        .zip(&scales)
        .map(|(t, d)| t / d)
        .collect();
    let mut estimator = match &config.adaptation {
        Adaptation::Estimator(spec) => {
            let tol = spec.noise_tolerance
                * noise_floor(
                    nominal.mass(),
                    config.noise.sigma_acceleration(),
                    config.window_frames,
                );
            let mut main = spec.build(m_max, est_seed, tol)?;
            main.reset(&prior)?;
            let early = if spec.early_tagk {
                let mut e = build_kind(EstimatorKind::TagK, spec.burn_in, m_max, est_seed, tol)?;
                e.reset(&prior)?;
                Some(e)
            } else {
                None
            };
            Some(EstimatorSlot { main, early })
        }
        _ => None,
    };
    let mut window = WindowBuilder::new(config.window_frames)?;
    let mut a_buf = vec![0.0; m_max * N_PARAMS];
    let mut b_buf = vec![0.0; m_max];

    let sigma_v = config.noise.sigma_velocity();
    let sigma_a = config.noise.sigma_acceleration();
    let sigma_g = config.gyro_noise;

    let mut events = Vec::new();
    let mut updates: Vec<UpdateRecord> = Vec::new();
    let mut log = Vec::new();
    let mut trace = Vec::new();
    let mut tracking = Vec::with_capacity(steps + 1);
    let mut first_after_event: Vec<(Vec<f64>, InertialParams)> = Vec::new();
    let mut pending_event = false;
    let mut first_update_steps: Vec<usize> = Vec::new();
    let mut next_event = 0;
    let mut latest_estimate: [f64; 10] = nominal.to_array();
    let mut gyro_prev = plant.state().body_rate + noise3(&mut noise, sigma_g);

    for k in 0..steps {
        let t = k as f64 * dt_c;
        // Payload events at the start of the control step.
        while next_event < schedule.len() && schedule[next_event].step <= k {
            let ev = schedule[next_event];
            let theta = if ev.attach {
                *plant.params() + ev.payload
            } else {
                *plant.params() - ev.payload
            };
            plant.set_params(theta)?;
            events.push(EventRecord {
                time: t,
                step: k,
                attach: ev.attach,
                params: theta.to_array(),
            });
            if !matches!(config.adaptation, Adaptation::Estimator(_)) {
                first_update_steps.push(k);
            }
            if matches!(config.adaptation, Adaptation::Oracle) {
                controller.redesign(&theta)?;
            }
            pending_event = true;
            next_event += 1;
        }

        // Tracking error and abort check on the true state.
        let reference = trajectory.sample(t);
        let s = *plant.state();
        let err = (s.position - reference.position).norm();
        tracking.push(if err.is_finite() { err } else { f64::INFINITY });
        if config.record_trace {
            let pe = match &estimator {
                Some(_) => parameter_error(&latest_estimate, plant.params()),
                None => parameter_error(controller.lqr().params().as_slice(), plant.params()),
            };
            trace.push(TraceSample {
                t,
                position: s.position.into(),
                reference: reference.position.into(),
                parameter_error: pe,
            });
        }
        if (err.is_nan() || err > ABORT_THRESHOLD) && config.stop_on_abort {
            break;
        }

        // Measurement for the controller: mocap position and attitude, noisy velocity, gyro.
        let measured = QuadrotorState {
            position: s.position,
            velocity: s.velocity + noise3(&mut noise, sigma_v),
            attitude: s.attitude,
            body_rate: gyro_prev,
        };
        let cmd = plant.clamp_speeds(&controller.rotor_speeds(&measured, &reference));
        let wrench_cmd: Wrench = vehicle.wrench_from_rotor_speeds(&cmd);

        // Physics: RK4 substeps, sampling the midpoint of the interval.
        let mut mid = None;
        for j in 0..substeps {
            if 2 * j == substeps {
                mid = Some((*plant.state(), plant.accelerations(&cmd)));
            }
            plant.step(&cmd, h);
        }
        let (mid_state, mid_acc) = match mid {
            Some(m) => m,
            None => (*plant.state(), plant.accelerations(&cmd)),
        };
        if !plant.is_finite() {
            tracking.push(f64::INFINITY);
            break;
        }
        let gyro_next = plant.state().body_rate + noise3(&mut noise, sigma_g);

        // Estimator frame of this interval, at its midpoint: accelerometer, gyro, differenced
        // gyro, commanded wrench.
        let accel_meas = mid_acc.proper + noise3(&mut noise, sigma_a);
        let omega_meas = mid_state.body_rate + noise3(&mut noise, sigma_g);
        let omega_dot = (gyro_next - gyro_prev) / dt_c;
        gyro_prev = gyro_next;
        if config.record_log {
            let q = mid_state.attitude;
            log.push(LogSample {
                t: t + 0.5 * dt_c,
                position: mid_state.position.into(),
                velocity: (mid_state.velocity + noise3(&mut noise, sigma_v)).into(),
                attitude: [q.w, q.i, q.j, q.k],
                body_rate: omega_meas.into(),
                wrench: wrench_cmd.to_array(),
                accel_world: (q * accel_meas + GRAVITY_WORLD).into(),
                omega_dot: omega_dot.into(),
                rotor_speeds: cmd,
            });
        }
        let Some(slot) = estimator.as_mut() else {
            continue;
        };
        window.push(&accel_meas, &omega_meas, &omega_dot, &wrench_cmd)?;
        if (k + 1) % config.estimator_period != 0 || !window.is_full() {
            continue;
        }
        let rows = window.build(&mut a_buf, &mut b_buf)?;
        for row in a_buf[..rows * N_PARAMS].chunks_exact_mut(N_PARAMS) {
            for (x, d) in row.iter_mut().zip(&scales) {
                *x *= d;
            }
        }
        if drop_lateral {
            // Rows 0 and 1 of every frame: the lateral forces, whose measurement is always 0.
            for r in 0..rows {
                if r % 6 < 2 {
                    a_buf[r * N_PARAMS..(r + 1) * N_PARAMS].fill(0.0);
                    b_buf[r] = 0.0;
                }
            }
        }
        let (a, b) = (&a_buf[..rows * N_PARAMS], &b_buf[..rows]);
        let start = Instant::now();
        let result = slot.main.update(a, b);
        let micros = start.elapsed().as_secs_f64() * 1e6;
        if let Some(e) = slot.early.as_mut() {
            // Estimator errors leave the state unchanged; the flight goes on.
            let _ = e.update(a, b);
        }
        if result.is_err() {
            continue;
        }
        if pending_event && let Some(e) = slot.early.as_ref() {
            let tagk_estimate = e.estimate().to_vec();
            slot.main.reset(&tagk_estimate)?;
        }
        let estimate: [f64; 10] = core::array::from_fn(|i| slot.main.estimate()[i] * scales[i]);
        latest_estimate = estimate;
        let truth = *plant.params();
        if pending_event {
            first_after_event.push((estimate.to_vec(), truth));
            first_update_steps.push(k + 1);
            pending_event = false;
        }
        let theta = InertialParams::from_array(estimate);
        let accepted =
            theta.safety_gate(&config.gate).is_ok() && controller.redesign(&theta).is_ok();
        updates.push(UpdateRecord {
            time: t + dt_c,
            estimate,
            truth: truth.to_array(),
            accepted,
            micros,
        });
    }

    let aborted = is_aborted(&tracking);
    let event_steps: Vec<usize> = events.iter().map(|e| e.step).collect();
    let success = is_success(&tracking, &event_steps, aborted);
    let success_after_update = is_success(&tracking, &first_update_steps, aborted);
    let finite: Vec<f64> = tracking.iter().copied().filter(|e| e.is_finite()).collect();
    let n_up = updates.len() as f64;
    let (pe, ge) = if updates.is_empty() {
        (
            f64::NAN,
            GroupErrors {
                mass: f64::NAN,
                first_moment: f64::NAN,
                inertia: f64::NAN,
            },
        )
    } else {
        let mut pe = 0.0;
        let mut ge = GroupErrors::default();
        for u in &updates {
            let truth = InertialParams::from_array(u.truth);
            pe += parameter_error(&u.estimate, &truth);
            let g = group_errors(&u.estimate, &truth, ARM_LENGTH);
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
    };
    let metrics = TrialMetrics {
        position_error_cm: position_error_cm(&finite),
        max_tracking_error_cm: 100.0 * tracking.iter().copied().fold(0.0, f64::max),
        parameter_error: pe,
        group_errors: ge,
        t1_error: t_plus_one_error(&first_after_event),
        success,
        success_after_update,
        aborted,
        steps: tracking.len(),
    };
    Ok(SimOutput {
        trajectory,
        metrics,
        events,
        updates,
        log,
        trace,
        tracking_errors: tracking,
    })
}
