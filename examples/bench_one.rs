//! Debug: one benchmark flight's report.
use tagk::diagnosis_benchmark::{BenchmarkOptions, draw_flight, run_diagnosis};
fn main() {
    let index: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    let options = BenchmarkOptions::default();
    let spec = draw_flight(&options, index).unwrap();
    println!("{:?}", spec.hidden_kinds());
    let out = tagk::sim::simulate(&spec.sim_config()).unwrap();
    let known = spec.known_mass.then(|| spec.true_mass());
    let report = run_diagnosis(out.log.clone(), known).unwrap();
    println!("{}", tagk::diagnose::report_table(&report));
    if let Some(p) = std::env::args().nth(2) { out.log.write_csv(&mut std::fs::File::create(p).unwrap()).unwrap(); }
}
