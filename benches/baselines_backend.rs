//! Dense-algebra backends of the RLS and Kalman-filter baselines, per update.
//!
//! Run: `cargo bench --bench baselines_backend -- --warm-up-time 1 --measurement-time 2`.
//! Same synthetic windows as the `estimators` bench (entries U[−1, 1], consistent plus 1e-3
//! noise, fixed seed), `m = 30`. The figures decide `tagk_baselines::Backend::Auto`.

mod common;

use common::{M, bench_updates, windows};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use tagk::baselines::{Backend, KalmanConfig, KalmanFilter, Rls, RlsConfig};
use tagk::core::OnlineEstimator;

fn bench(c: &mut Criterion) {
    let sizes: Vec<usize> = std::env::var("TAGK_BACKEND_SIZES")
        .ok()
        .map(|s| s.split(',').filter_map(|v| v.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![10, 20, 40, 80, 120]);
    for n in sizes {
        let stream = windows(n);
        let mut group = c.benchmark_group(format!("backend/n={n},m={M}"));
        for backend in [Backend::Loops, Backend::Faer] {
            let ests: Vec<(&str, Box<dyn OnlineEstimator<f64>>)> = vec![
                (
                    "RLS",
                    Box::new(Rls::new(n, M, RlsConfig::LOW.with_backend(backend)).unwrap()),
                ),
                (
                    "KF",
                    Box::new(
                        KalmanFilter::new(n, M, KalmanConfig::LOW.with_backend(backend)).unwrap(),
                    ),
                ),
            ];
            for (label, mut est) in ests {
                bench_updates(
                    &mut group,
                    BenchmarkId::new(label, format!("{backend:?}")),
                    est.as_mut(),
                    &stream,
                );
            }
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
