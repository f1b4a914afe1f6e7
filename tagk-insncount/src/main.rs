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
//!
//! `TAGK_KERNELS=avx2 tagk-insncount gate [N...]` is the timing gate beside the instruction
//! gate (see `gate`). It times TAG-K (`f64`, default `N` = 10 and 120) on three kernel sets
//! in one process, interleaved: the AVX2 kernels, the same with the previous AVX2 Gram kernel,
//! and the portable kernels. It prints the medians and the median time ratios. It exits
//! non-zero only when a ratio is clearly lost: above `GATE_LIMITS`.

use std::process::ExitCode;
use std::time::Instant;

use tagk_baselines::{KalmanFilter, Rls};
use tagk_core::{KernelChoice, OnlineEstimator, Real, SyntheticWindows, TagK, tagk_paper_config};

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

/// Interleaved rounds of the timing gate.
const GATE_ROUNDS: usize = 301;
/// Updates per timed batch of the timing gate.
const GATE_BATCH: usize = 40;
/// Largest median time ratios the timing gate accepts: AVX2 over the previous AVX2 Gram
/// kernel, and AVX2 over portable. Generous on purpose. On a loaded 2-core AMD EPYC (Zen 4,
/// AVX2 forced) the first measured 0.88–1.01 and the second 0.32–0.34 at n = 10 to 120.
/// A CPU whose multiplies and adds share their ports (Intel) may find the tiles no faster.
const GATE_LIMITS: (f64, f64) = (1.15, 0.6);

/// The timing gate at dimension `n`. Three TAG-K estimators (AVX2, AVX2 with the previous
/// Gram kernel, portable) take the same windows. Each round times a batch of
/// [`GATE_BATCH`] updates on each, in a rotating order. Per round, the two ratios of batch
/// times; over [`GATE_ROUNDS`] rounds, their medians. Load on a shared machine slows all
/// three alike within a round, so the ratios hold where absolute times do not. Returns
/// whether both ratios are within [`GATE_LIMITS`].
fn gate(n: usize) -> Result<bool, String> {
    let pool = pool::<f64>(n);
    let cfg = tagk_paper_config();
    let kernels = [
        KernelChoice::Detected,
        KernelChoice::PreviousGram,
        KernelChoice::Portable,
    ];
    let mut est: Vec<TagK<f64, Vec<f64>>> = kernels
        .iter()
        .map(|_| TagK::new(n, M, cfg).map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    // A batch from window `k` of the pool on.
    let batch = |e: &mut TagK<f64, Vec<f64>>, kernel: KernelChoice, k: usize| {
        let start = Instant::now();
        for i in 0..GATE_BATCH {
            let (a, b) = &pool[(k + i) % pool.len()];
            e.update_on(kernel, std::hint::black_box(a), std::hint::black_box(b))
                .map_err(|err| format!("update: {err}"))?;
        }
        Ok::<f64, String>(start.elapsed().as_secs_f64() / GATE_BATCH as f64 * 1e6)
    };
    for round in 0..20 {
        for (e, &kernel) in est.iter_mut().zip(&kernels) {
            batch(e, kernel, round * GATE_BATCH)?;
        }
    }
    let mut times = [const { Vec::new() }; 3];
    for round in 0..GATE_ROUNDS {
        for j in 0..3 {
            let which = (round + j) % 3;
            times[which].push(batch(&mut est[which], kernels[which], round * GATE_BATCH)?);
        }
    }
    // The same bits on every kernel set: the same work was timed.
    let bits = |e: &TagK<f64, Vec<f64>>| e.estimate().iter().map(|x| x.to_bits()).collect();
    let first: Vec<u64> = bits(&est[0]);
    if est.iter().any(|e| bits(e) != first) {
        return Err(format!("n={n}: the kernel sets computed different bits"));
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ratio = |j: usize| median(times[0].iter().zip(&times[j]).map(|(x, y)| x / y).collect());
    let (previous, portable) = (ratio(1), ratio(2));
    let (limit_previous, limit_portable) = GATE_LIMITS;
    let us: Vec<f64> = times.iter().map(|t| median(t.clone())).collect();
    let best: Vec<f64> = times
        .iter()
        .map(|t| t.iter().copied().fold(f64::INFINITY, f64::min))
        .collect();
    let ok = previous <= limit_previous && portable <= limit_portable;
    println!(
        "tagk n={n} m={M} µs/update median (best batch): avx2 {:.3} ({:.3}), previous avx2 Gram \
         {:.3} ({:.3}), portable {:.3} ({:.3}); median ratios: avx2/previous {previous:.3} \
         (limit {limit_previous}), avx2/portable {portable:.3} (limit {limit_portable}): {}",
        us[0],
        best[0],
        us[1],
        best[1],
        us[2],
        best[2],
        if ok { "ok" } else { "LOST" }
    );
    Ok(ok)
}

/// Runs [`gate`] for every `n`; failure when the AVX2 kernels are not the ones timed.
fn gates(ns: &[usize]) -> ExitCode {
    if std::env::var("TAGK_KERNELS").as_deref() != Ok("avx2") {
        eprintln!("tagk-insncount gate: run it with TAGK_KERNELS=avx2 (it times the AVX2 kernels)");
        return ExitCode::from(2);
    }
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    if !avx2 {
        println!("tagk-insncount gate: no AVX2 on this CPU, nothing to time");
        return ExitCode::SUCCESS;
    }
    let mut lost = false;
    for &n in ns {
        match gate(n) {
            Ok(ok) => lost |= !ok,
            Err(e) => {
                eprintln!("tagk-insncount gate: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    if lost {
        eprintln!("tagk-insncount gate: a time ratio is lost (see the lines above)");
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
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
    if args.first().map(String::as_str) == Some("gate") {
        let ns: Option<Vec<usize>> = args[1..].iter().map(|a| a.parse().ok()).collect();
        return match ns {
            Some(ns) if ns.is_empty() => gates(&[10, 120]),
            Some(ns) if ns.iter().all(|&n| n > 0) => gates(&ns),
            _ => {
                eprintln!("usage: TAGK_KERNELS=avx2 tagk-insncount gate [N...]");
                ExitCode::from(2)
            }
        };
    }
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
             tagk-insncount time (tagk|tagk-f32|rls-low|kf-low) N\n       \
             TAGK_KERNELS=avx2 tagk-insncount gate [N...]"
        );
        return ExitCode::from(2);
    };
    dispatch(name, n, updates).unwrap_or_else(|e| {
        eprintln!("tagk-insncount: {e}");
        ExitCode::FAILURE
    })
}
