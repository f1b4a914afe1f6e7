//! Shared helpers: flight logs from the simulator with one hidden plant effect.
#![allow(dead_code)]

use tagk_diagnose::FlightLog;
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
        effects: effect
            .map_or(Ok(PlantEffects::none()), PlantEffects::only)
            .expect("the simulator produces the effect"),
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
            c.effects.motor_lag = Some(tagk_sim::plant_effects::MotorLag {
                time_constant: 0.02,
            });
        }
        _ => {}
    }
    c
}

/// A simulated log with `effect` hidden (panics if the flight aborted: the data would not be
/// a flight).
pub fn sim_log(effect: Option<EffectKind>, seed: u64) -> FlightLog {
    let out = tagk_sim::simulate(&config(effect, seed)).expect("simulation runs");
    assert!(
        !out.metrics.aborted,
        "flight with {effect:?} seed {seed} aborted"
    );
    out.log
}
