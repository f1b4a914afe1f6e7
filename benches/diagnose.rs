//! Diagnosis of a 10-minute flight log at 100 Hz (60 000 rows) against every built-in
//! candidate effect: log validation and signal derivation, the weighted QR fit,
//! whiteness/failure windows/regimes, and the blocked-CV ranking with the 1-D scans.
//!
//! - `10min_100Hz_all_builtins`: one diagnosis of the rigid-body model (with the noise floor:
//!   each channel's noise measured from the model's residual).
//! - `10min_100Hz_stepwise`: the full stepwise search ([`discover`]) on a log with two hidden
//!   effects (target ≤ 3 s on one core).
//!
//! The logs come from the simulator (seed 11, medium noise; rotor drag hidden, and rotor drag
//! plus motor lag for the stepwise search).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tagk::diagnose::{DiagnoseOptions, FlightLog, Model, Signals, diagnose, discover};
use tagk::sim::{
    Adaptation, EffectKind, NoiseLevel, PayloadSchedule, PlantEffects, SimConfig, simulate,
};

fn ten_minute_log(effects: &[EffectKind]) -> FlightLog {
    let effects = effects
        .iter()
        .try_fold(PlantEffects::none(), |e, k| e.with(*k))
        .expect("plant effects");
    let config = SimConfig {
        duration: 600.0,
        seed: 11,
        noise: NoiseLevel::Medium,
        payload: PayloadSchedule::None,
        effects,
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
    let log = ten_minute_log(&[EffectKind::RotorDrag]);
    assert_eq!(log.len(), 60_000, "10 min at 100 Hz");
    let two = ten_minute_log(&[EffectKind::RotorDrag, EffectKind::MotorLag]);
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
    g.bench_function("10min_100Hz_stepwise", |b| {
        b.iter(|| {
            let s = Signals::from_log(black_box(&two)).expect("valid log");
            let found = discover(&Model::rigid_body(), &s, &opts).expect("discovery");
            black_box(found.added)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
