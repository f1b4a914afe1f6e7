use tagk_diagnose::*;
use tagk_sim::{Adaptation, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig};
fn cpu() -> f64 {
    let st = std::fs::read_to_string("/proc/self/stat").unwrap();
    let f: Vec<&str> = st.rsplit(')').next().unwrap().split_whitespace().collect();
    (f[11].parse::<f64>().unwrap() + f[12].parse::<f64>().unwrap()) / 100.0
}
fn main() {
    let effects = [EffectKind::RotorDrag, EffectKind::MotorLag].iter().try_fold(PlantEffects::none(), |e, k| e.with(*k)).unwrap();
    let cfg = SimConfig { duration: 600.0, seed: 11, noise: NoiseLevel::Medium, payload: PayloadSchedule::None, effects,
        adaptation: Adaptation::Nominal, control_dt: 0.01, record_log: true, stop_on_abort: false, ..SimConfig::default() };
    let out = tagk_sim::simulate(&cfg).unwrap();
    let s = Signals::from_log(&out.log).unwrap();
    println!("sim done");
    let c0 = cpu();
    let t0 = std::time::Instant::now();
    let d = diagnose(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
    println!("diagnose {:.2} s ({:.2} s CPU): {:?}", t0.elapsed().as_secs_f64(), cpu() - c0, d.recommended_set);
    let c0 = cpu();
    let t0 = std::time::Instant::now();
    let found = discover(&Model::rigid_body(), &s, &DiagnoseOptions::default()).unwrap();
    println!("discover {:.2} s ({:.2} s CPU): {:?} ({})", t0.elapsed().as_secs_f64(), cpu() - c0, found.added, found.stopped);
}
