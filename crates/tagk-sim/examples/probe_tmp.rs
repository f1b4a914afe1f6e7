//! temporary probe
use tagk_sim::*;
fn main() {
    for kind in EffectKind::ALL {
        for tc in [None, Some(0.02), Some(0.05)] {
            if tc.is_some() && kind != EffectKind::MotorLag { continue; }
            let mut e = PlantEffects::only(kind);
            if let Some(t) = tc { e.motor_lag = Some(MotorLag { time_constant: t }); }
            let cfg = SimConfig { trajectory: TrajectoryKind::Helix, duration: 20.0, seed: 0, noise: NoiseLevel::Low, payload: PayloadSchedule::None, effects: e, adaptation: Adaptation::Nominal, ..Default::default() };
            let out = simulate(&cfg).unwrap();
            println!("{kind:?} {tc:?}: pos {:.3} cm max {:.2} aborted {} steps {}", out.metrics.position_error_cm, out.metrics.max_tracking_error_cm, out.metrics.aborted, out.metrics.steps);
        }
    }
}
