//! `tagk-insncount ESTIMATOR N UPDATES` builds `ESTIMATOR` (`tagk`, `tagk-f32`, `rls-low`,
//! `kf-low`) for dimension `N` and windows of `m = 30` rows. It feeds it `UPDATES` windows of
//! the Table III stream: tagk-core's `SyntheticWindows`, seed `SEED + N`, a pool of 16 windows
//! cycled so that warm starts behave as in use. It prints one line:
//!
//! ```text
//! ESTIMATOR n=N m=30 updates=UPDATES fingerprint=HASH sum=SUM
//! ```
//!
//! `HASH` folds the bit pattern of the last estimate (FNV-1a over the `f64` bits, `f32`
//! widened exactly). Every update starts from the previous estimate. So two machines print the
//! same line when they computed the same bits all along. The program does nothing else. Take
//! the difference of the instructions two runs with different `UPDATES` execute, divided by
//! the difference of `UPDATES`. That is the cost of one update, with start-up and window
//! generation cancelling. `run.sh` beside this crate measures it with callgrind (x86-64) and a
//! QEMU plugin (aarch64).
//!
//! `tagk-insncount time ESTIMATOR N` prints instead the median time per update (µs) over 31
//! batches of 200 updates, after 2000 to warm up. It is a wall-clock figure, which moves with
//! the machine's load. `TAGK_KERNELS=avx2` or `portable` times those kernels on a CPU that has
//! better ones.

use std::process::ExitCode;
use std::time::Instant;

use tagk_baselines::{KalmanFilter, Rls};
use tagk_core::{OnlineEstimator, Real, SyntheticWindows, TagK, tagk_paper_config};

/// Rows per window (the TAG-K paper's `m`).
const M: usize = 30;
/// Windows in the pool the updates cycle through.
const POOL: usize = 16;

/// FNV-1a over the bytes of `x`'s bit pattern.
fn fold(hash: u64, x: f64) -> u64 {
    x.to_bits().to_le_bytes().iter().fold(hash, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Runs `updates` updates of `est` on the pool and returns the fingerprint line's values.
fn run<T: Real>(
    est: &mut dyn OnlineEstimator<T>,
    pool: &[(Vec<T>, Vec<T>)],
    updates: usize,
) -> Result<(u64, f64), String> {
    for k in 0..updates {
        let (a, b) = &pool[k % pool.len()];
        est.update(a, b).map_err(|e| format!("update {k}: {e}"))?;
    }
    // The last estimate carries every update's bits (each update starts from the previous
    // estimate); fingerprinting only it keeps the per-update loop the update alone.
    let hash = est
        .estimate()
        .iter()
        .fold(0xcbf2_9ce4_8422_2325, |h, x| fold(h, x.as_f64()));
    let sum = est.estimate().iter().map(|x| x.as_f64()).sum();
    Ok((hash, sum))
}

/// The median over 31 batches of 200 updates (after 2000 to warm up) of the time per
/// update, in µs.
fn time<T: Real>(
    est: &mut dyn OnlineEstimator<T>,
    pool: &[(Vec<T>, Vec<T>)],
) -> Result<f64, String> {
    let mut k = 0;
    let mut step = |est: &mut dyn OnlineEstimator<T>| {
        let (a, b) = &pool[k % pool.len()];
        k += 1;
        est.update(std::hint::black_box(a), std::hint::black_box(b))
            .map(|_| ())
            .map_err(|e| format!("update {k}: {e}"))
    };
    for _ in 0..2000 {
        step(est)?;
    }
    let mut batches = Vec::with_capacity(31);
    for _ in 0..31 {
        let start = Instant::now();
        for _ in 0..200 {
            step(est)?;
        }
        batches.push(start.elapsed().as_secs_f64() / 200.0 * 1e6);
    }
    batches.sort_by(f64::total_cmp);
    Ok(batches[15])
}

/// The pool of windows for dimension `n`, rounded to `T`.
fn pool<T: Real>(n: usize) -> Vec<(Vec<T>, Vec<T>)> {
    let cast = |v: Vec<f64>| v.into_iter().map(T::cast).collect();
    SyntheticWindows::for_table(n, M)
        .take_windows(POOL)
        .into_iter()
        .map(|(a, b)| (cast(a), cast(b)))
        .collect()
}

/// Runs (or, with `timing`, times) `est` on the pool for dimension `n` and prints the line.
fn report<T: Real>(
    name: &str,
    n: usize,
    updates: Option<usize>,
    est: &mut dyn OnlineEstimator<T>,
) -> ExitCode {
    let pool = pool::<T>(n);
    let result = match updates {
        None => {
            time(est, &pool).map(|us| println!("{name} n={n} m={M} median_us_per_update={us:.3}"))
        }
        Some(updates) => run(est, &pool, updates).map(|(hash, sum)| {
            println!("{name} n={n} m={M} updates={updates} fingerprint={hash:016x} sum={sum:+.17e}")
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("tagk-insncount: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Builds the estimator `name` and hands it to [`report`].
fn dispatch(name: &str, n: usize, updates: Option<usize>) -> Result<ExitCode, String> {
    let cfg = tagk_paper_config();
    let err = |e: tagk_core::ConfigError| e.to_string();
    Ok(match name {
        "tagk" => report(
            name,
            n,
            updates,
            &mut TagK::<f64, Vec<f64>>::new(n, M, cfg).map_err(err)?,
        ),
        "tagk-f32" => report(
            name,
            n,
            updates,
            &mut TagK::<f32, Vec<f32>>::new(n, M, cfg).map_err(err)?,
        ),
        "rls-low" => report(name, n, updates, &mut Rls::rls_low(n, M).map_err(err)?),
        "kf-low" => report(
            name,
            n,
            updates,
            &mut KalmanFilter::kf_low(n, M).map_err(err)?,
        ),
        _ => return Err(format!("unknown estimator {name:?}")),
    })
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let parsed = match args.as_slice() {
        [time, name, n] if time == "time" => n.parse::<usize>().ok().map(|n| (name, n, None)),
        [name, n, updates] => n
            .parse::<usize>()
            .ok()
            .zip(updates.parse::<usize>().ok())
            .map(|(n, u)| (name, n, Some(u))),
        _ => None,
    };
    let Some((name, n, updates)) = parsed else {
        eprintln!(
            "usage: tagk-insncount (tagk|tagk-f32|rls-low|kf-low) N UPDATES\n       \
             tagk-insncount time (tagk|tagk-f32|rls-low|kf-low) N"
        );
        return ExitCode::from(2);
    };
    dispatch(name, n, updates).unwrap_or_else(|e| {
        eprintln!("tagk-insncount: {e}");
        ExitCode::FAILURE
    })
}
