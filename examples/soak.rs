//! Soak test: 10⁶ updates of every estimator on one long, realistic stream.
//!
//! The stream has sensor noise, outliers, payload steps and rank-deficient stretches.
//! The soak checks that nothing turns NaN. It checks that the covariance of RLS and the Kalman
//! filter stays bounded, with and without the wind-up guard. And it checks that the estimate
//! comes back within tolerance after every payload step.
//!
//! The stream is seeded, the same for every estimator. Its windows hold 5 frames of the
//! rigid-body regressor (`A` 30 × 10, as the TAG-K paper's estimator builds them). The target
//! is the wrench `A θ` plus Gaussian noise (5 mN, 50 µN m). Each row has, with probability
//! 10⁻³, an outlier of 100 σ.
//! It runs in cycles of [`CYCLE`] windows. At the start of each cycle a payload of 40 % of the
//! vehicle mass, at a quarter of the arm length, is attached (even cycles) or dropped (odd
//! cycles). Windows [`FLAT_START`]..[`FLAT_END`] of a cycle are a **rank-deficient stretch**:
//! steady hover, no rotation, constant acceleration, so only a few directions of `θ` are
//! excited. The rest is random excitation about hover.
//!
//! Checks per estimator:
//! - finite estimates at every update;
//! - the largest covariance trace (RLS, KF);
//! - for every payload step, the number of windows until the mass error is within
//!   [`MASS_TOLERANCE`] of the payload mass, which must happen before the rank-deficient
//!   stretch;
//! - the largest mass error inside the stretches (the estimate must hold, not drift).
//!
//! RLS-high
//! (`λ = 0.96`) runs twice, without and with the wind-up guard `trace(P) ≤ p₀ n`.
//!
//! ```text
//! cargo run --release --example soak [-- --updates 1000000 --seed 7 --windup 2000]
//! cargo run --release --example soak -- --updates 20000   # a shortened run (seconds)
//! ```
//!
//! `-- --help` lists the options; a progress bar on stderr counts the updates (`--quiet`
//! hides it).
//!
//! A shortened version (a few thousand updates) runs in the test suite (`tests/soak.rs`).

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use tagk::baselines::{KalmanFilter, Rls, RlsConfig, WindupGuard};
use tagk::core::{
    GreedyKaczmarz, KaczmarzConfig, OnlineEstimator, RandomizedKaczmarz, TagK, TailAveragedKaczmarz,
};
use tagk::dynamics::nalgebra::Vector3;
use tagk::dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
use tagk::dynamics::{InertialParams, QuadrotorModel, write_rigid_body_regressor};

const FRAMES: usize = 5;
const ROWS: usize = 6 * FRAMES;
const N: usize = 10;
/// Windows per payload cycle.
pub const CYCLE: usize = 1000;
/// First window of a cycle's rank-deficient stretch.
pub const FLAT_START: usize = 500;
/// End (exclusive) of a cycle's rank-deficient stretch.
pub const FLAT_END: usize = 700;
/// Mass error within which an estimate counts as recovered, as a fraction of the payload mass.
pub const MASS_TOLERANCE: f64 = 0.1;
/// Probability of an outlier per row.
const OUTLIER_PROBABILITY: f64 = 1e-3;
/// Outlier size in noise standard deviations.
const OUTLIER_SIGMAS: f64 = 100.0;

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn uniform(rng: &mut ChaCha8Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

/// The stream of windows (regenerated from the seed for each estimator: 10⁶ windows would
/// take 2.4 GB).
pub struct Stream {
    rng: ChaCha8Rng,
    nominal: InertialParams,
    loaded: InertialParams,
    /// Window index.
    k: usize,
    /// Every window from this one on is rank-deficient (the wind-up run; `usize::MAX`: the
    /// cycles).
    flat_from: usize,
    /// The current window `A` (row-major, 30 × 10) and `b`.
    pub a: Vec<f64>,
    /// The current measured wrench.
    pub b: Vec<f64>,
}

impl Stream {
    /// A stream from `seed` for the Crazyflie 2.1.
    pub fn new(seed: u64) -> Self {
        let nominal = QuadrotorModel::crazyflie_2_1().params;
        let payload_at = Vector3::new(
            0.25 * CRAZYFLIE_ARM_OFFSET,
            -0.25 * CRAZYFLIE_ARM_OFFSET,
            -0.01,
        );
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            nominal,
            loaded: nominal.with_point_mass(Self::payload_mass_of(&nominal), payload_at),
            k: 0,
            flat_from: usize::MAX,
            a: vec![0.0; ROWS * N],
            b: vec![0.0; ROWS],
        }
    }

    fn payload_mass_of(nominal: &InertialParams) -> f64 {
        0.4 * nominal.mass()
    }

    /// The payload's mass \[kg\].
    pub fn payload_mass(&self) -> f64 {
        Self::payload_mass_of(&self.nominal)
    }

    /// The nominal parameters (the estimators' prior).
    pub fn nominal(&self) -> &InertialParams {
        &self.nominal
    }

    /// The true parameters of window `k`: the payload is attached at the start of cycles 1,
    /// 3, 5, … and dropped at the start of cycles 2, 4, ….
    pub fn truth(&self, k: usize) -> &InertialParams {
        if (k / CYCLE) % 2 == 1 {
            &self.loaded
        } else {
            &self.nominal
        }
    }

    /// Fills [`Stream::a`] and [`Stream::b`] with the next window; returns its index.
    pub fn next_window(&mut self) -> usize {
        let k = self.k;
        self.k += 1;
        let flat = k >= self.flat_from || (FLAT_START..FLAT_END).contains(&(k % CYCLE));
        let truth = *self.truth(k);
        let rng = &mut self.rng;
        let (sigma_f, sigma_t) = (5e-3, 5e-5);
        for f in 0..FRAMES {
            let (accel, omega, omega_dot) = if flat {
                (
                    Vector3::new(0.0, 0.0, 9.81),
                    Vector3::zeros(),
                    Vector3::zeros(),
                )
            } else {
                (
                    Vector3::new(gauss(rng), gauss(rng), 9.81 + gauss(rng)),
                    Vector3::new(gauss(rng), gauss(rng), gauss(rng)) * 0.5,
                    Vector3::new(gauss(rng), gauss(rng), gauss(rng)) * 5.0,
                )
            };
            let block = &mut self.a[f * 6 * N..(f + 1) * 6 * N];
            write_rigid_body_regressor(&accel, &omega, &omega_dot, block).expect("60 entries");
            for r in 0..6 {
                let exact: f64 = (0..N).map(|c| block[r * N + c] * truth.as_slice()[c]).sum();
                let sigma = if r < 3 { sigma_f } else { sigma_t };
                let mut noise = sigma * gauss(rng);
                if uniform(rng) < OUTLIER_PROBABILITY {
                    noise += OUTLIER_SIGMAS * sigma * if uniform(rng) < 0.5 { -1.0 } else { 1.0 };
                }
                self.b[f * 6 + r] = exact + noise;
            }
        }
        k
    }
}

/// An estimator under test, with access to its covariance trace where it has one.
pub enum Subject {
    /// A Kaczmarz method (no covariance).
    Kaczmarz(Box<dyn OnlineEstimator<f64>>),
    /// Recursive least squares.
    Rls(Rls),
    /// The random-walk Kalman filter.
    Kf(KalmanFilter),
}

impl Subject {
    fn estimator(&mut self) -> &mut dyn OnlineEstimator<f64> {
        match self {
            Subject::Kaczmarz(e) => e.as_mut(),
            Subject::Rls(e) => e,
            Subject::Kf(e) => e,
        }
    }

    fn covariance_trace(&self) -> Option<f64> {
        match self {
            Subject::Kaczmarz(_) => None,
            Subject::Rls(e) => Some(e.covariance_trace()),
            Subject::Kf(e) => Some(e.covariance_trace()),
        }
    }
}

/// Every estimator of tagk (the paper's presets), plus RLS-high with the wind-up guard
/// `trace(P) ≤ p₀ n`.
pub fn subjects(seed: u64) -> Vec<(String, Subject)> {
    let cfg = KaczmarzConfig::default().with_seed(seed);
    let guard =
        RlsConfig::HIGH.with_windup_guard(WindupGuard::MaxTrace(RlsConfig::HIGH.p0 * N as f64));
    vec![
        (
            "TAG-K".into(),
            Subject::Kaczmarz(Box::new(
                TagK::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid"),
            )),
        ),
        (
            "GRK".into(),
            Subject::Kaczmarz(Box::new(
                GreedyKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid"),
            )),
        ),
        (
            "TARK".into(),
            Subject::Kaczmarz(Box::new(
                TailAveragedKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid"),
            )),
        ),
        (
            "RK".into(),
            Subject::Kaczmarz(Box::new(
                RandomizedKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid"),
            )),
        ),
        (
            "RLS-low".into(),
            Subject::Rls(Rls::rls_low(N, ROWS).expect("valid")),
        ),
        (
            "RLS-high".into(),
            Subject::Rls(Rls::rls_high(N, ROWS).expect("valid")),
        ),
        (
            "RLS-high+guard".into(),
            Subject::Rls(Rls::new(N, ROWS, guard).expect("valid")),
        ),
        (
            "KF-low".into(),
            Subject::Kf(KalmanFilter::kf_low(N, ROWS).expect("valid")),
        ),
        (
            "KF-high".into(),
            Subject::Kf(KalmanFilter::kf_high(N, ROWS).expect("valid")),
        ),
    ]
}

/// What one estimator did over the soak.
#[derive(Debug, Clone, PartialEq)]
pub struct SoakResult {
    /// Updates run.
    pub updates: usize,
    /// Updates after which an estimate entry was NaN or infinite.
    pub non_finite: usize,
    /// Updates the estimator rejected with a typed error (the estimate is then kept).
    pub rejected: usize,
    /// Largest covariance trace seen (RLS, KF) \[squared units of θ\].
    pub max_trace: Option<f64>,
    /// Payload steps in the soak.
    pub steps: usize,
    /// Steps after which the mass came within tolerance before the rank-deficient stretch.
    pub recovered: usize,
    /// Most windows a recovery took.
    pub worst_recovery: usize,
    /// Largest mass error inside the rank-deficient stretches, over the payload mass.
    pub worst_flat_error: f64,
    /// Mass error at the last update, over the payload mass.
    pub final_error: f64,
}

/// Runs `updates` windows of the stream of `seed` through `subject`.
pub fn soak(subject: &mut Subject, updates: usize, seed: u64) -> SoakResult {
    soak_with_progress(subject, updates, seed, |_| {})
}

/// Updates between two calls of a progress callback.
const PROGRESS_EVERY: usize = 1024;

/// [`soak`], calling `progress(n)` with the updates run since its last call (every
/// [`PROGRESS_EVERY`] updates, and at the end); the result is the same.
pub fn soak_with_progress(
    subject: &mut Subject,
    updates: usize,
    seed: u64,
    mut progress: impl FnMut(usize),
) -> SoakResult {
    let mut stream = Stream::new(seed);
    let payload = stream.payload_mass();
    let tolerance = MASS_TOLERANCE * payload;
    subject
        .estimator()
        .reset(stream.nominal().as_slice())
        .expect("finite prior");
    let mut r = SoakResult {
        updates,
        non_finite: 0,
        rejected: 0,
        max_trace: None,
        steps: 0,
        recovered: 0,
        worst_recovery: 0,
        worst_flat_error: 0.0,
        final_error: 0.0,
    };
    let mut pending_since: Option<usize> = None;
    for i in 0..updates {
        if i % PROGRESS_EVERY == 0 && i > 0 {
            progress(PROGRESS_EVERY);
        }
        let k = stream.next_window();
        let phase = k % CYCLE;
        if phase == 0 && k > 0 {
            r.steps += 1;
            pending_since = Some(k);
        }
        let est = subject.estimator();
        if est.update(&stream.a, &stream.b).is_err() {
            r.rejected += 1;
        }
        let theta = est.estimate();
        if theta.iter().any(|x| !x.is_finite()) {
            r.non_finite += 1;
        }
        let error = (theta[0] - stream.truth(k).mass()).abs();
        r.final_error = error / payload;
        if let Some(since) = pending_since {
            if phase >= FLAT_START {
                pending_since = None; // not recovered before the stretch
            } else if error <= tolerance {
                r.recovered += 1;
                r.worst_recovery = r.worst_recovery.max(k - since + 1);
                pending_since = None;
            }
        }
        if (FLAT_START..FLAT_END).contains(&phase) {
            r.worst_flat_error = r.worst_flat_error.max(error / payload);
        }
        if let Some(tr) = subject.covariance_trace() {
            r.max_trace = Some(r.max_trace.map_or(tr, |m: f64| m.max(tr)));
        }
    }
    if updates > 0 {
        progress(updates - (updates - 1) / PROGRESS_EVERY * PROGRESS_EVERY);
    }
    r
}

/// The wind-up run: [`FLAT_START`] excited windows, then `flat` rank-deficient ones in a row
/// (no payload step); returns the largest covariance trace and the last mass error over the
/// payload mass.
pub fn windup(subject: &mut Subject, flat: usize, seed: u64) -> (f64, f64) {
    let mut stream = Stream::new(seed);
    stream.flat_from = FLAT_START;
    let payload = stream.payload_mass();
    subject
        .estimator()
        .reset(stream.nominal().as_slice())
        .expect("finite prior");
    let mut max_trace: f64 = 0.0;
    let mut error = 0.0;
    for _ in 0..FLAT_START + flat {
        let k = stream.next_window();
        let est = subject.estimator();
        let _ = est.update(&stream.a, &stream.b);
        error = (est.estimate()[0] - stream.truth(k).mass()).abs() / payload;
        max_trace = max_trace.max(subject.covariance_trace().unwrap_or(0.0));
    }
    (max_trace, error)
}

/// Soak test: many updates of every estimator on one long, realistic stream (noise,
/// outliers, payload steps, rank-deficient stretches); NaNs, covariance bounds and recovery
/// after each payload step, then the covariance wind-up over a long rank-deficient stretch.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Updates (windows) per estimator; shorten the run with fewer (e.g. 20000).
    #[arg(long, default_value_t = 1_000_000)]
    updates: usize,
    /// Seed of the stream and of the randomised estimators.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Rank-deficient windows in a row in the wind-up run.
    #[arg(long, default_value_t = 2000)]
    windup: usize,
    /// Hide the progress bar.
    #[arg(long)]
    quiet: bool,
}

#[allow(dead_code)] // the test suite includes this file for `soak` and does not call `main`
fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args = <Args as clap::Parser>::parse();
    let (updates, seed, flat) = (args.updates, args.seed, args.windup);
    println!(
        "soak: {updates} updates per estimator, seed {seed}; payload step every {CYCLE} windows, \
         rank-deficient windows {FLAT_START}..{FLAT_END} of each cycle, outliers of \
         {OUTLIER_SIGMAS} σ on {OUTLIER_PROBABILITY:e} of the rows; tolerance {:.0} % of the payload mass\n",
        100.0 * MASS_TOLERANCE
    );
    println!(
        "{:<15} {:>9} {:>9} {:>11} {:>11} {:>10} {:>11} {:>11} {:>9}",
        "estimator",
        "NaN",
        "rejected",
        "max tr(P)",
        "recovered",
        "worst win",
        "flat err",
        "final err",
        "time s"
    );
    let estimators = subjects(seed).len();
    let covariances = subjects(seed)
        .iter()
        .filter(|(_, s)| !matches!(s, Subject::Kaczmarz(_)))
        .count();
    let total = estimators * updates + covariances * (FLAT_START + flat);
    let bar = tagk::cli::progress::Progress::counting(!args.quiet, total as u64, "updates");
    for (name, mut subject) in subjects(seed) {
        bar.message(name.clone());
        let start = std::time::Instant::now();
        let r = soak_with_progress(&mut subject, updates, seed, |n| bar.inc_by(n as u64));
        bar.suspend(|| {
            println!(
                "{:<15} {:>9} {:>9} {:>11} {:>11} {:>10} {:>10.1}% {:>10.1}% {:>9.1}",
                name,
                r.non_finite,
                r.rejected,
                r.max_trace.map_or("-".into(), |t| format!("{t:.2e}")),
                format!("{}/{}", r.recovered, r.steps),
                r.worst_recovery,
                100.0 * r.worst_flat_error,
                100.0 * r.final_error,
                start.elapsed().as_secs_f64()
            )
        });
    }
    bar.suspend(|| {
        println!(
            "\nwind-up: {FLAT_START} excited windows, then {flat} rank-deficient ones in a row:"
        )
    });
    for (name, mut subject) in subjects(seed)
        .into_iter()
        .filter(|(_, s)| !matches!(s, Subject::Kaczmarz(_)))
    {
        bar.message(format!("wind-up {name}"));
        let (trace, error) = windup(&mut subject, flat, seed);
        bar.inc_by((FLAT_START + flat) as u64);
        bar.suspend(|| {
            println!(
                "{name:<15} max tr(P) {trace:.2e}, mass error at the end {:.1}% of the payload",
                100.0 * error
            )
        });
    }
    bar.finish();
    println!(
        "\nrecovered: payload steps after which the mass came within tolerance before the \
         rank-deficient stretch; worst win: most windows that took; flat err: largest mass \
         error inside a rank-deficient stretch (over the payload mass, outliers included)."
    );
}
