//! The Table III harness: per-update cost of RLS-low, KF-low and TAG-K on synthetic windows,
//! `n ∈ {40, 60, 80, 100, 120}`, `m = 30`, in `f32` and `f64`. The arm cases ([`ARM_CASES`])
//! run the same estimators at a robot arm's sizes: `n ∈ {10, 70}`, `m = 70`.
//!
//! One [`Case`] runs as follows, identically on the host and on a microcontroller:
//!
//! 1. [`SyntheticWindows`] draws a pool of [`Case::POOL`] windows from ChaCha8 seeded with
//!    [`SEED`]` + n`: the same data for every estimator and both precisions at a given `n`.
//!    Entries of `A` are uniform in `[−1, 1)`. `b = A θ* + v`, with `θ*` uniform in `[−1, 1)ⁿ`
//!    and `v` uniform in `[−NOISE, NOISE)`, computed in `f64` and rounded to the case's scalar.
//! 2. **Verification:** the estimator (initial estimate 0) takes each pool window once; every
//!    estimate's bit pattern is folded into a [`Checksum`], which [`CaseReport::verify`]
//!    compares with a reference run's. IEEE-754 arithmetic without fused multiply-adds gives
//!    the same bits on any host and on a Cortex-M7, so the firmware embeds the checksums its
//!    build script computed on the host and fails on any difference.
//! 3. **Timing:** `reps` more updates, cycling through the pool, each read around with a
//!    [`CycleCounter`]; the report keeps the total, minimum and maximum ticks.
//!
//! Under QEMU the cycle counter does not run; `firmware/run.sh` counts executed instructions
//! instead, by differencing two runs of one case with different `reps`.

use core::fmt;

use tagk_core::{OnlineEstimator, Real};

use crate::counter::CycleCounter;
use crate::error::HarnessError;
use crate::estimators::{McuEstimator, buffer_len, state_bytes};
use tagk_baselines::EstimatorKind;

// The workload lives in tagk-core (the host benches and the simulator use it too).
pub use tagk_core::synthetic::{NOISE, SEED, SyntheticWindows};

/// The parameter dimensions of Table III.
pub const TABLE_N: [usize; 5] = [40, 60, 80, 100, 120];
/// Rows per window in Table III.
pub const TABLE_M: usize = 30;

/// The scalar type a case computes in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Precision {
    /// Single precision.
    F32,
    /// Double precision.
    F64,
}

impl Precision {
    /// `"f32"` or `"f64"`.
    pub const fn label(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::F64 => "f64",
        }
    }

    /// Bytes per scalar.
    pub const fn bytes(self) -> usize {
        match self {
            Self::F32 => 4,
            Self::F64 => 8,
        }
    }
}

/// One cell group of Table III: an estimator, a dimension, a window size and a precision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Case {
    /// Which estimator.
    pub kind: EstimatorKind,
    /// Parameter dimension `n`.
    pub n: usize,
    /// Rows per window `m`.
    pub m: usize,
    /// Scalar type.
    pub precision: Precision,
}

/// Every Table III case, `f64` first, then by `n`, then RLS, KF, TAG-K. The `f64` Kalman
/// filter is KF-low, the `f32` one KF-high (KF-low's `P₀/σ_R² = 10¹³` is beyond `f32`: its covariance loses positive definiteness
/// within a few windows; KF-high runs the same instructions per update).
pub const CASES: [Case; 30] = {
    let mut cases = [Case {
        kind: EstimatorKind::RlsLow,
        n: 0,
        m: TABLE_M,
        precision: Precision::F64,
    }; 30];
    let precisions = [Precision::F64, Precision::F32];
    let kinds = [
        [
            EstimatorKind::RlsLow,
            EstimatorKind::KfLow,
            EstimatorKind::TagK,
        ],
        [
            EstimatorKind::RlsLow,
            EstimatorKind::KfHigh,
            EstimatorKind::TagK,
        ],
    ];
    let mut i = 0;
    while i < 30 {
        cases[i] = Case {
            kind: kinds[i / 15][i % 3],
            n: TABLE_N[(i / 3) % 5],
            m: TABLE_M,
            precision: precisions[i / 15],
        };
        i += 1;
    }
    cases
};

/// The parameter dimensions of the arm cases (issue 28): a payload's 10 inertial
/// parameters, and 10 per link of a 7-joint arm such as the Panda (70).
pub const ARM_N: [usize; 2] = [10, 70];
/// Rows per window in the arm cases: tagk-sim's arm windows of 10 samples, one torque row per
/// joint of a 7-joint arm.
pub const ARM_M: usize = 70;

/// The arm cases: `f64` first, then by `n` in [`ARM_N`]; in `f64` RLS-low, KF-high and TAG-K,
/// in `f32` RLS-low and TAG-K; `m` = [`ARM_M`]. The firmware numbers them after [`CASES`]
/// (see [`case_at`]).
///
/// KF-low's first 70-row window at `n = 70` pins every direction far below its prior's
/// rounding level, and so does KF-high's in `f32` (`P₀/σ_R² = 10⁹`). In the compact buffer
/// that is a typed `NumericalFailure`, so the `f64` filter is KF-high and `f32` has none.
/// KF-high runs the same instructions per update as KF-low.
pub const ARM_CASES: [Case; 10] = {
    let mut cases = [Case {
        kind: EstimatorKind::RlsLow,
        n: 0,
        m: ARM_M,
        precision: Precision::F64,
    }; 10];
    let f64_kinds = [
        EstimatorKind::RlsLow,
        EstimatorKind::KfHigh,
        EstimatorKind::TagK,
    ];
    let f32_kinds = [EstimatorKind::RlsLow, EstimatorKind::TagK];
    let mut i = 0;
    while i < 10 {
        cases[i] = if i < 6 {
            Case {
                kind: f64_kinds[i % 3],
                n: ARM_N[i / 3],
                m: ARM_M,
                precision: Precision::F64,
            }
        } else {
            Case {
                kind: f32_kinds[(i - 6) % 2],
                n: ARM_N[(i - 6) / 2],
                m: ARM_M,
                precision: Precision::F32,
            }
        };
        i += 1;
    }
    cases
};

/// Cases the firmware runs: [`CASES`], then [`ARM_CASES`].
pub const CASE_COUNT: usize = CASES.len() + ARM_CASES.len();

/// The firmware's case `index`: [`CASES`]`[index]`, then [`ARM_CASES`] from
/// `CASES.len()` on; `None` past [`CASE_COUNT`].
pub const fn case_at(index: usize) -> Option<Case> {
    if index < CASES.len() {
        Some(CASES[index])
    } else if index < CASE_COUNT {
        Some(ARM_CASES[index - CASES.len()])
    } else {
        None
    }
}

impl Case {
    /// Windows in the pool (verification updates per case).
    pub const POOL: usize = 4;

    /// Position in the firmware's numbering ([`case_at`]: [`CASES`], then [`ARM_CASES`]), if
    /// the case is one of them.
    pub fn index(&self) -> Option<usize> {
        CASES.iter().chain(&ARM_CASES).position(|c| c == self)
    }

    /// Scalars one window occupies: `A` (`m n`) then `b` (`m`).
    pub const fn window_len(&self) -> usize {
        self.m * self.n + self.m
    }

    /// Scalars of arena [`run_case`] needs: the window pool plus the estimator's buffer.
    pub const fn arena_len(&self) -> usize {
        Self::POOL * self.window_len() + buffer_len(self.kind, self.n, self.m)
    }

    /// Bytes of RAM the estimator's state occupies (see [`state_bytes`]).
    pub const fn state_bytes(&self) -> usize {
        match self.precision {
            Precision::F32 => state_bytes::<f32>(self.kind, self.n, self.m),
            Precision::F64 => state_bytes::<f64>(self.kind, self.n, self.m),
        }
    }
}

/// The largest [`Case::arena_len`] over `cases`, in scalars.
const fn max_arena_len(cases: &[Case]) -> usize {
    let mut max = 0;
    let mut i = 0;
    while i < cases.len() {
        let len = cases[i].arena_len();
        if len > max {
            max = len;
        }
        i += 1;
    }
    max
}

/// The largest [`Case::arena_len`] over [`CASES`], in scalars of the case's type: size one
/// `f64` arena (or an `f32` one of the same length) with it to run every Table III case.
pub const ARENA_LEN: usize = max_arena_len(&CASES);

/// The largest [`Case::arena_len`] over [`ARM_CASES`], in scalars (more than [`ARENA_LEN`]:
/// four 70-row windows at `n = 70`). The firmware's arena is the larger of the two.
pub const ARM_ARENA_LEN: usize = max_arena_len(&ARM_CASES);

/// A fingerprint of a run's estimates: a hash of their bit patterns and the final sum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checksum {
    /// Hash of the `f64` bit patterns of every verification estimate, in order.
    pub hash: u64,
    /// Sum of the final verification estimate's entries, widened to `f64`.
    pub sum: f64,
}

impl Checksum {
    /// The hash before any value is folded in.
    const START: u64 = 0x6a09_e667_f3bc_c908;

    /// Folds one value into the hash: xor its bits, then SplitMix64's finaliser, so every
    /// input bit reaches every output bit.
    fn fold(hash: u64, x: f64) -> u64 {
        let mut z = hash ^ x.to_bits();
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// What one case measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaseReport {
    /// The case.
    pub case: Case,
    /// Fingerprint of the verification updates.
    pub checksum: Checksum,
    /// Timed updates.
    pub reps: usize,
    /// Ticks summed over the timed updates.
    pub total_ticks: u64,
    /// Fewest ticks of one timed update.
    pub min_ticks: u32,
    /// Most ticks of one timed update.
    pub max_ticks: u32,
    /// The counter's rate (0: the counter did not run).
    pub ticks_per_second: u64,
}

impl CaseReport {
    /// Mean ticks per timed update.
    pub fn mean_ticks(&self) -> f64 {
        self.total_ticks as f64 / self.reps as f64
    }

    /// Compares the checksum with a reference run's (for the firmware: the host's, computed
    /// at build time); hash and sum must match exactly.
    pub fn verify(&self, expected: Checksum) -> Result<(), HarnessError> {
        if self.checksum.hash == expected.hash
            && self.checksum.sum.to_bits() == expected.sum.to_bits()
        {
            Ok(())
        } else {
            Err(HarnessError::ChecksumMismatch {
                index: self.case.index().unwrap_or(usize::MAX),
                found_hash: self.checksum.hash,
                expected_hash: expected.hash,
                found_sum: self.checksum.sum,
                expected_sum: expected.sum,
            })
        }
    }

    /// The column titles matching [`Display`](fmt::Display) rows.
    pub const HEADER: &'static str = "estimator   n   m prec  state[B]  reps  mean[ticks]   min[ticks]   max[ticks]  hash               sum";
}

impl fmt::Display for CaseReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.case;
        write!(
            f,
            "{:<9} {:>3} {:>3} {:>4} {:>9} {:>5} {:>12.0} {:>12} {:>12}  {:016x}  {:+.12e}",
            c.kind.name(),
            c.n,
            c.m,
            c.precision.label(),
            c.state_bytes(),
            self.reps,
            self.mean_ticks(),
            self.min_ticks,
            self.max_ticks,
            self.checksum.hash,
            self.checksum.sum,
        )
    }
}

/// Runs one case (see the [module docs](self)) in `arena` (at least [`Case::arena_len`]
/// scalars) with `reps` timed updates. `T` must match `case.precision` for the checksum to
/// mean anything; [`run_case_in`] picks it for you.
pub fn run_case<T: Real, C: CycleCounter>(
    case: Case,
    reps: usize,
    arena: &mut [T],
    counter: &mut C,
) -> Result<CaseReport, HarnessError> {
    if reps == 0 || case.n == 0 || case.m == 0 {
        return Err(HarnessError::NothingToRun);
    }
    let needed = case.arena_len();
    if arena.len() < needed {
        return Err(HarnessError::ArenaTooSmall {
            needed,
            found: arena.len(),
        });
    }
    let (n, m) = (case.n, case.m);
    let stride = case.window_len();
    let (pool, rest) = arena.split_at_mut(Case::POOL * stride);
    let mut windows = SyntheticWindows::for_table(n, m);
    for w in pool.chunks_exact_mut(stride) {
        let (a, b) = w.split_at_mut(m * n);
        windows.next_window(a, b);
    }
    let pool: &[T] = pool;
    let window = |k: usize| {
        let w = &pool[(k % Case::POOL) * stride..][..stride];
        w.split_at(m * n)
    };

    let mut est = McuEstimator::build(case.kind, n, m, rest)?;
    let mut hash = Checksum::START;
    for k in 0..Case::POOL {
        let (a, b) = window(k);
        est.update(a, b)?;
        for x in est.estimate() {
            hash = Checksum::fold(hash, x.as_f64());
        }
    }
    let sum = est.estimate().iter().fold(0.0, |s, x| s + x.as_f64());

    let (mut total, mut min, mut max) = (0u64, u32::MAX, 0u32);
    for k in 0..reps {
        let (a, b) = window(k);
        let t0 = counter.now();
        est.update(a, b)?;
        let t1 = counter.now();
        let dt = counter.elapsed(t0, t1);
        total += u64::from(dt);
        min = min.min(dt);
        max = max.max(dt);
    }
    Ok(CaseReport {
        case,
        checksum: Checksum { hash, sum },
        reps,
        total_ticks: total,
        min_ticks: min,
        max_ticks: max,
        ticks_per_second: counter.ticks_per_second(),
    })
}

/// [`run_case`] in the arena of the case's precision.
pub fn run_case_in<C: CycleCounter>(
    case: Case,
    reps: usize,
    arena_f32: &mut [f32],
    arena_f64: &mut [f64],
    counter: &mut C,
) -> Result<CaseReport, HarnessError> {
    match case.precision {
        Precision::F32 => run_case(case, reps, arena_f32, counter),
        Precision::F64 => run_case(case, reps, arena_f64, counter),
    }
}
