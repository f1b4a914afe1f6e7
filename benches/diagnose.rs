//! Diagnosis of a 10-minute flight log at 100 Hz (60 000 rows) against every built-in
//! candidate effect (target ≤ 2 s): log validation and signal derivation, the weighted QR fit,
//! whiteness/failure windows/regimes, and the blocked-CV ranking with the 1-D scans.
//! The log comes from the simulator (seed 11, rotor drag hidden, medium noise).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tagk::diagnose::{DiagnoseOptions, FlightLog, Model, Signals, diagnose};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, simulate,
};

fn ten_minute_log() -> FlightLog {
    let config = SimConfig {
        duration: 600.0,
        seed: 11,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects: PlantEffects::only(EffectKind::RotorDrag).expect("a plant effect"),
        adaptation: Adaptation::Nominal,
        control_dt: 0.01,
        record_log: true,
        stop_on_abort: false,
        ..SimConfig::default()
    };
    let out = simulate(&config).expect("simulation runs");
    // Through the CSV log format, as a user's own data would arrive.
    let mut csv = Vec::new();
    out.log.write_csv(&mut csv).expect("in-memory log");
    FlightLog::from_csv_reader(csv.as_slice()).expect("a valid log")
}

fn bench(c: &mut Criterion) {
    let log = ten_minute_log();
    assert_eq!(log.len(), 60_000, "10 min at 100 Hz");
    let opts = DiagnoseOptions::default();
    let mut g = c.benchmark_group("diagnose");
    g.sample_size(10);
    g.bench_function("10min_100Hz_all_builtins", |b| {
        b.iter(|| {
            let s = Signals::from_log(black_box(&log)).expect("valid log");
            let d = diagnose(&Model::rigid_body(), &s, &opts).expect("diagnosis");
            black_box(d.recommended)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
