use tagk_sim::*;
use tagk_control::LqrWeights;
fn main() {
    let n_trials: u64 = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(40);
    let wsets = [
      ("stiff-z", LqrWeights::from_diagonals([400.0,400.0,4000.0,16.0,16.0,100.0,100.0,100.0,25.0,1.0,1.0,1.0],[2500.0;4])),
      ("stiff-all", LqrWeights::from_diagonals([4000.0,4000.0,10000.0,100.0,100.0,200.0,400.0,400.0,25.0,1.0,1.0,1.0],[2500.0;4])),
    ];
    for (wn, w) in wsets {
    for noise in [NoiseLevel::None, NoiseLevel::Medium, NoiseLevel::High] {
    let t = EstimatorSpec::new(EstimatorKind::TagK);
    let ads = vec![Adaptation::Estimator(t), Adaptation::Estimator(t.with_scaling()), Adaptation::Estimator(t.with_noise_tolerance(3.0)), Adaptation::Estimator(t.with_scaling().with_noise_tolerance(3.0)),Adaptation::Estimator(t.with_scaling().with_noise_tolerance(10.0)), Adaptation::Estimator(EstimatorSpec::new(EstimatorKind::KfHigh)), Adaptation::Estimator(EstimatorSpec::new(EstimatorKind::RlsHigh))];
    for ad in ads {
        let mut n = 0; let mut succ = 0; let mut ab = 0; let mut pe = 0.0; let mut e10 = vec![];
        for seed in 0..n_trials {
            let cfg = SimConfig { seed, trajectory: TrajectoryKind::ALL[(seed % 5) as usize], adaptation: ad, noise, weights: w, ..Default::default() };
            let out = simulate(&cfg).unwrap();
            n += 1; if out.metrics.success { succ += 1; } if out.metrics.aborted { ab += 1; }
            if !out.metrics.aborted { pe += out.metrics.position_error_cm; }
            for e in &out.events { if let Some(x) = out.tracking_errors.get(e.step + 10) { e10.push((x*1000.0).round()/10.0); } }
        }
        e10.sort_by(|a,b| a.partial_cmp(b).unwrap());
        let name = match ad { Adaptation::Estimator(s) => s.label(), a => format!("{a:?}") };
        println!("{wn} {noise:?} {name:22}: succ {succ}/{n} aborted {ab} pos {:.3} cm  e10 median {:?} p90 {:?} max {:?}", pe / (n - ab).max(1) as f64, e10.get(e10.len()/2), e10.get(e10.len()*9/10), e10.last());
    }}}
}
