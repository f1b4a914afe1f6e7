//! The synthetic workload of the TAG-K paper's Table III: seeded streams of windows
//! `b = A θ* + v`.
//!
//! The microcontroller harness (`tagk-mcu`), the host benchmarks and the simulator's
//! `dimension_sweep` share it, so that all of them time the same windows.
//!
//! A stream draws from ChaCha8 seeded with `seed` (Table III: [`SEED`]` + n`).
//! The entries of `A` are uniform in `[−1, 1)`, from stream 0.
//! `θ*` is uniform in `[−1, 1)ⁿ`, from stream 1.
//! The noise `v` is uniform in `[−NOISE, NOISE)` ([`NOISE`]); `b` is computed in `f64` and rounded to the
//! scalar type asked for. The same seed gives the same bits on every machine.

use rand_chacha::ChaCha8Rng;
use rand_core::{Rng, SeedableRng};

use crate::Real;

/// The seed of every Table III stream (plus `n`).
pub const SEED: u64 = 0x7461_676b_2d6d_6375;
/// Half-width of the uniform measurement noise added to `b` (units of `b`).
pub const NOISE: f64 = 1e-3;

/// A uniform draw in `[−1, 1)` with 53 random bits.
fn symmetric_unit(rng: &mut ChaCha8Rng) -> f64 {
    ((rng.next_u64() >> 11) as f64) * (2.0 / (1u64 << 53) as f64) - 1.0
}

/// A seeded stream of synthetic windows `b = A θ* + v` (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct SyntheticWindows {
    n: usize,
    m: usize,
    data: ChaCha8Rng,
    theta: ChaCha8Rng,
}

impl SyntheticWindows {
    /// A stream of `m × n` windows. `θ*` comes from stream 1 of ChaCha8 seeded with `seed`,
    /// the windows from stream 0.
    pub fn new(seed: u64, n: usize, m: usize) -> Self {
        let data = ChaCha8Rng::seed_from_u64(seed);
        let mut theta = data.clone();
        theta.set_stream(1);
        Self { n, m, data, theta }
    }

    /// The stream used by Table III for dimension `n` and `m` rows: seed [`SEED`]` + n`.
    pub fn for_table(n: usize, m: usize) -> Self {
        Self::new(SEED.wrapping_add(n as u64), n, m)
    }

    /// The true parameters `θ*` (length `n`; extra entries of `out` are left alone).
    pub fn theta(&self, out: &mut [f64]) {
        let mut rng = self.theta.clone();
        for t in out.iter_mut().take(self.n) {
            *t = symmetric_unit(&mut rng);
        }
    }

    /// The next `count` windows as owned `(A, b)` pairs (`A` row-major `m × n`): the workload of
    /// the host benchmarks and of the `dimension_sweep` experiment, so that they time the same
    /// windows as the microcontroller harness.
    #[cfg(feature = "alloc")]
    pub fn take_windows(
        &mut self,
        count: usize,
    ) -> alloc::vec::Vec<(alloc::vec::Vec<f64>, alloc::vec::Vec<f64>)> {
        (0..count)
            .map(|_| {
                let mut a = alloc::vec![0.0; self.m * self.n];
                let mut b = alloc::vec![0.0; self.m];
                self.next_window(&mut a, &mut b);
                (a, b)
            })
            .collect()
    }

    /// Draws the next window into `a` (`m n` values, row-major) and `b` (`m` values).
    /// Extra entries are left alone; shorter slices receive a prefix of the window.
    pub fn next_window<T: Real>(&mut self, a: &mut [T], b: &mut [T]) {
        let n = self.n;
        for i in 0..self.m {
            let mut theta = self.theta.clone();
            let mut bi = 0.0;
            for j in 0..n {
                let aij = symmetric_unit(&mut self.data);
                bi += aij * symmetric_unit(&mut theta);
                if let Some(slot) = a.get_mut(i * n + j) {
                    *slot = T::cast(aij);
                }
            }
            bi += NOISE * symmetric_unit(&mut self.data);
            if let Some(slot) = b.get_mut(i) {
                *slot = T::cast(bi);
            }
        }
    }
}
