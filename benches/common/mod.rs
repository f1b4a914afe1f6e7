//! What the estimator benches share: the workload and the timed loop.

use std::hint::black_box;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, BenchmarkId};
use tagk::core::OnlineEstimator;
use tagk::core::SyntheticWindows;

/// Rows per window (the paper's `m`).
pub const M: usize = 30;
/// Windows in the stream each estimator cycles through.
pub const STREAM: usize = 64;

/// The Table III stream (tagk-core's `SyntheticWindows`, also run by the microcontroller harness) (`θ, A ~ U[−1, 1]`,
/// `b = Aθ + 10⁻³·U[−1, 1]`), so host and firmware time the same windows.
pub fn windows(n: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
    SyntheticWindows::for_table(n, M).take_windows(STREAM)
}

/// Times `est.update` on successive windows of `stream`, so warm starts behave as in use.
pub fn bench_updates(
    group: &mut BenchmarkGroup<'_, WallTime>,
    id: BenchmarkId,
    est: &mut dyn OnlineEstimator<f64>,
    stream: &[(Vec<f64>, Vec<f64>)],
) {
    let mut k = 0;
    group.bench_function(id, |bench| {
        bench.iter(|| {
            let (a, b) = &stream[k % stream.len()];
            k += 1;
            black_box(est.update(black_box(a), black_box(b)).unwrap());
        })
    });
}
