use tagk_sim::*;
use tagk_control::LqrWeights;
use tagk_dynamics::{InertialParams, SafetyGate};
fn main() {
    let w = LqrWeights::from_diagonals([400.0,400.0,4000.0,16.0,16.0,100.0,100.0,100.0,25.0,1.0,1.0,1.0],[2500.0;4]);
    for seed in 0..10u64 {
        let cfg = SimConfig { seed, trajectory: TrajectoryKind::ALL[(seed % 5) as usize], adaptation: Adaptation::Estimator(EstimatorSpec::new(EstimatorKind::TagK).with_scaling()), noise: NoiseLevel::High, weights: w, ..Default::default() };
        let out = simulate(&cfg).unwrap();
        if !out.metrics.aborted { continue; }
        println!("seed {seed} events {:?} steps {}", out.events.iter().map(|e| (e.time, e.params)).collect::<Vec<_>>(), out.metrics.steps);
        for u in out.updates.iter() {
            let th = InertialParams::from_array(u.estimate);
            let k = (u.time / 0.02).round() as usize;
            println!("t {:.2} acc {} err {:.3} gate {:?} dm {:.2e} h {:.2e} {:.2e} {:.2e} I {:.2e} {:.2e} {:.2e}", u.time, u.accepted, out.tracking_errors.get(k).copied().unwrap_or(f64::NAN), th.safety_gate(&SafetyGate::crazyflie()).err().map(|_|"x"), u.estimate[0]-u.truth[0], u.estimate[1]-u.truth[1], u.estimate[2]-u.truth[2], u.estimate[3]-u.truth[3], u.estimate[4]-u.truth[4], u.estimate[6]-u.truth[6], u.estimate[9]-u.truth[9]);
        }
        break;
    }
}
