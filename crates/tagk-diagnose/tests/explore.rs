mod common;
use tagk_diagnose::{DiagnoseOptions, Model, Signals, diagnose, };
use tagk_sim::EffectKind;

#[test]
#[ignore]
fn explore() {
    let kinds: Vec<Option<EffectKind>> = std::iter::once(None).chain(EffectKind::ALL.iter().copied().map(Some)).collect();
    for k in kinds {
        let log = common::sim_log(k, 1);
        let s = Signals::from_log(&log).unwrap();
        let m = if k == Some(EffectKind::ThrustError) { Model::rigid_body().with_known_mass(0.035) } else { Model::rigid_body() };
        let d = diagnose(&m, &s, &DiagnoseOptions::default()).unwrap();
        println!("##### {:?} verdict {}", k, d.verdict);
        for c in &d.channels { print!("{} {:.2e} ", c.name, c.rms); }
        println!();
        for w in &d.warnings { println!("W {w}"); }
        for f in &d.findings { println!("F {f}"); }
        for c in d.ranking.iter().take(4) { println!("   {}", c.explanation); }
    }
}
