//! Shared helpers: flight logs from the simulator with one hidden plant effect.
#![allow(dead_code)]

use tagk_diagnose::{FlightLog, LogSample};
use tagk_dynamics::EffectKind as Vocabulary;
use tagk_sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, TrajectoryKind,
};

/// Log duration [s] of the proof tests.
pub const DURATION: f64 = 25.0;

/// The simulator configuration of a proof log: no payload, nominal controller, the paper's
/// medium noise, exactly `effect` on (none: clean).
pub fn config(effect: Option<EffectKind>, seed: u64) -> SimConfig {
    let mut c = SimConfig {
        trajectory: TrajectoryKind::Figure8,
        duration: DURATION,
        seed,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: effect.map_or(PlantEffects::none(), PlantEffects::only),
        adaptation: Adaptation::Nominal,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    match effect {
        // Ground effect needs height changes close to the ground: a helix climbing from a
        // few centimetres (its climb is 0.3-0.6 m around the centre altitude).
        Some(EffectKind::GroundEffect) => {
            c.trajectory = TrajectoryKind::Helix;
            c.altitude = Some(0.32);
        }
        // The simulator's default 50 ms lag destabilises the nominal LQR (the vehicle falls);
        // 20 ms is still in the range reported for Crazyflie-class motors.
        Some(EffectKind::MotorLag) => {
            c.effects.motor_lag = Some(tagk_sim::MotorLag {
                time_constant: 0.02,
            });
        }
        _ => {}
    }
    c
}

/// Converts simulator samples into a diagnosis log.
pub fn to_log(samples: &[tagk_sim::LogSample]) -> FlightLog {
    let mut log = FlightLog::new();
    for s in samples {
        log.push(&LogSample {
            t: s.t,
            position: s.position,
            velocity: s.velocity,
            attitude: s.attitude,
            omega: s.body_rate,
            wrench: s.wrench,
            accel: Some(s.accel_world),
            omega_dot: Some(s.omega_dot),
            rotor_speeds: Some(s.rotor_speeds),
        });
    }
    log
}

/// A simulated log with `effect` hidden (panics if the flight aborted: the data would not be
/// a flight).
pub fn sim_log(effect: Option<EffectKind>, seed: u64) -> FlightLog {
    let out = tagk_sim::simulate(&config(effect, seed)).expect("simulation runs");
    assert!(
        !out.metrics.aborted,
        "flight with {effect:?} seed {seed} aborted"
    );
    to_log(&out.log)
}

/// The effect of the shared vocabulary (`tagk_dynamics::EffectKind`) that models a simulator
/// plant effect.
///
/// TO SWITCH AFTER THE MERGE of the simulator's effect enum into `tagk_dynamics::EffectKind`:
/// delete this table, make `config`/`sim_log` take a `tagk_dynamics::EffectKind`, and call the
/// tests with the vocabulary's names. The simulator's `LinearDrag` (today rotor drag,
/// `K (Σ ωᵢ) v_b`) becomes `EffectKind::RotorDrag`, `ThrustError` becomes `ThrustGain` and
/// `Bias` becomes `BodyBias`.
pub fn vocabulary_kind(kind: EffectKind) -> Vocabulary {
    match kind {
        EffectKind::LinearDrag => Vocabulary::RotorDrag,
        EffectKind::QuadraticDrag => Vocabulary::QuadraticDrag,
        EffectKind::MotorLag => Vocabulary::MotorLag,
        EffectKind::GroundEffect => Vocabulary::GroundEffect,
        EffectKind::Wind => Vocabulary::Wind,
        EffectKind::ThrustError => Vocabulary::ThrustGain,
        EffectKind::Bias => Vocabulary::BodyBias,
    }
}
