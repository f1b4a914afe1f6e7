use tagk_diagnose::*;
use tagk_sim::{plant_effects::MotorLag, Adaptation, NoiseLevel, PayloadSchedule, PlantEffects, Sensing, SimConfig, TrajectoryKind};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = args[1].parse().unwrap();
    let kinds: Vec<EffectKind> = args[2..].iter().map(|n| EffectKind::from_name(n).unwrap()).collect();
    let mut effects = kinds.iter().try_fold(PlantEffects::none(), |e, k| e.with(*k)).unwrap();
    if effects.motor_lag.is_some() { effects.motor_lag = Some(MotorLag { time_constant: 0.02 }); }
    let cfg = SimConfig { trajectory: TrajectoryKind::Figure8, duration: 25.0, seed, noise: NoiseLevel::Medium,
        sensing: Sensing { rotor_speed_noise: 6.0, ..Sensing::realistic_calibrated() }, payload: PayloadSchedule::None,
        effects, adaptation: Adaptation::Nominal, record_log: true, stop_on_abort: false, yaw_rate: 0.3, ..SimConfig::default() };
    let out = tagk_sim::simulate(&cfg).unwrap();
    let s = Signals::from_log(&out.log).unwrap();
    let rep = run_loop(&s, &Model::rigid_body(), &[], &DiagnoseOptions::default()).unwrap();
    println!("{}", report_table(&rep));
}
