//! Per-update time of every estimator on synthetic windows from a fixed seed.
//!
//! `n = 10, m = 30` is the quadrotor case; `n ∈ {40, 60, 80, 100, 120}, m = 30` is the TAG-K
//! paper's Table III sweep. Each iteration feeds the next window of a pre-generated stream of
//! consistent-plus-noise windows, so warm starts behave as in use.

mod common;

use common::{M, bench_updates, windows};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use tagk::baselines::{KalmanFilter, Rls};
use tagk::core::{
    GreedyKaczmarz, OnlineEstimator, RandomizedKaczmarz, TagK, TailAveragedKaczmarz,
    tagk_paper_config,
};

fn estimators(n: usize) -> Vec<Box<dyn OnlineEstimator<f64>>> {
    let cfg = tagk_paper_config().with_seed(1);
    vec![
        Box::new(TagK::<f64, Vec<f64>>::new(n, M, cfg).unwrap()),
        Box::new(GreedyKaczmarz::<f64, Vec<f64>>::new(n, M, cfg).unwrap()),
        Box::new(TailAveragedKaczmarz::<f64, Vec<f64>>::new(n, M, cfg).unwrap()),
        Box::new(RandomizedKaczmarz::<f64, Vec<f64>>::new(n, M, cfg).unwrap()),
        Box::new(Rls::rls_low(n, M).unwrap()),
        Box::new(Rls::rls_high(n, M).unwrap()),
        Box::new(KalmanFilter::kf_low(n, M).unwrap()),
        Box::new(KalmanFilter::kf_high(n, M).unwrap()),
    ]
}

fn bench(c: &mut Criterion) {
    for n in [10, 40, 60, 80, 100, 120] {
        let stream = windows(n);
        let mut group = c.benchmark_group(format!("update/n={n},m={M}"));
        for mut est in estimators(n) {
            let name = est.name().to_string();
            bench_updates(
                &mut group,
                BenchmarkId::from_parameter(&name),
                est.as_mut(),
                &stream,
            );
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
