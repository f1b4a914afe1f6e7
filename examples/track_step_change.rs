//! The main demo: track a quadrotor's inertial parameters through a payload pick-up and drop
//! with every estimator in tagk, and print the error and the per-update time of each.
//!
//! Windows are built exactly as in the TAG-K paper's estimator: 5 frames of the rigid-body
//! Newton–Euler regressor (docs/CONVENTIONS.md §3), `A` 30 × 10. The kinematics are random
//! excitation about hover; the measured wrench is `Y θ_true` plus sensor noise. A payload of 40 %
//! of the vehicle mass at 25 % of the arm length is attached at window 20 and dropped at window 40.
//!
//! ```text
//! cargo run --release --example track_step_change [-- --seed 7 --windows 60]
//! ```

use std::time::Instant;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use tagk::baselines::{KalmanFilter, Rls};
use tagk::core::{
    GreedyKaczmarz, KaczmarzConfig, OnlineEstimator, RandomizedKaczmarz, TagK, TailAveragedKaczmarz,
};
use tagk::dynamics::nalgebra::Vector3;
use tagk::dynamics::quadrotor::CRAZYFLIE_ARM_OFFSET;
use tagk::dynamics::{InertialParams, QuadrotorModel, write_rigid_body_regressor};

const FRAMES: usize = 5;
const ROWS: usize = 6 * FRAMES;
const N: usize = 10;

fn gauss(rng: &mut ChaCha8Rng) -> f64 {
    let u1 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// Track a quadrotor's inertial parameters through a payload pick-up and drop with every
/// estimator, and print each one's error and per-update time.
#[derive(Debug, clap::Parser)]
struct Args {
    /// Seed of the excitation and the sensor noise.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Windows in the stream (the payload is attached at a third and dropped at two thirds).
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u64).range(3..))]
    windows: u64,
}

fn main() {
    tagk::cli::terminal::end_quietly_on_broken_pipe();
    let args = <Args as clap::Parser>::parse();
    let seed = args.seed;
    let windows = args.windows as usize;
    let (attach, drop) = (windows / 3, 2 * windows / 3);

    let vehicle = QuadrotorModel::crazyflie_2_1();
    let nominal = vehicle.params;
    let payload_mass = 0.4 * nominal.mass();
    let payload_at = Vector3::new(
        0.25 * CRAZYFLIE_ARM_OFFSET,
        -0.25 * CRAZYFLIE_ARM_OFFSET,
        -0.01,
    );
    let loaded = nominal.with_point_mass(payload_mass, payload_at);

    // The stream every estimator sees: windows of 5 frames of hover-like excitation.
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (sigma_f, sigma_t) = (5e-4, 5e-6); // N, N m: a good force/torque sensor
    let mut stream = Vec::with_capacity(windows);
    for w in 0..windows {
        let truth: InertialParams = if (attach..drop).contains(&w) {
            loaded
        } else {
            nominal
        };
        let mut a = vec![0.0; ROWS * N];
        let mut b = vec![0.0; ROWS];
        for f in 0..FRAMES {
            let accel = Vector3::new(gauss(&mut rng), gauss(&mut rng), 9.81 + gauss(&mut rng));
            let omega = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * 0.5;
            let omega_dot = Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * 5.0;
            let block = &mut a[f * 6 * N..(f + 1) * 6 * N];
            write_rigid_body_regressor(&accel, &omega, &omega_dot, block).expect("60 entries");
            for r in 0..6 {
                let exact: f64 = (0..N).map(|c| block[r * N + c] * truth.as_slice()[c]).sum();
                let sigma = if r < 3 { sigma_f } else { sigma_t };
                b[f * 6 + r] = exact + sigma * gauss(&mut rng);
            }
        }
        stream.push((a, b, truth));
    }

    let cfg = KaczmarzConfig::default().with_seed(seed);
    let mut estimators: Vec<Box<dyn OnlineEstimator<f64>>> = vec![
        Box::new(TagK::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid config")),
        Box::new(GreedyKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid config")),
        Box::new(TailAveragedKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid config")),
        Box::new(RandomizedKaczmarz::<f64, Vec<f64>>::new(N, ROWS, cfg).expect("valid config")),
        Box::new(Rls::rls_low(N, ROWS).expect("valid config")),
        Box::new(Rls::rls_high(N, ROWS).expect("valid config")),
        Box::new(KalmanFilter::kf_low(N, ROWS).expect("valid config")),
        Box::new(KalmanFilter::kf_high(N, ROWS).expect("valid config")),
    ];

    println!(
        "Crazyflie 2.1, {windows} windows of {FRAMES} frames (A is {ROWS}×{N}); payload {:.1} g at \
         ({:.1}, {:.1}, {:.1}) mm attached at window {attach}, dropped at window {drop}; seed {seed}.",
        payload_mass * 1e3,
        payload_at.x * 1e3,
        payload_at.y * 1e3,
        payload_at.z * 1e3,
    );
    println!(
        "Errors are ‖θ̂ − θ‖₂ in SI units (dominated by the mass, kg); times are per update.\n"
    );
    println!(
        "{:<9} {:>11} {:>12} {:>12} {:>12} {:>12} {:>10} {:>10}",
        "estimator",
        "mean error",
        "before pick",
        "(t+1) pick",
        "(t+1) drop",
        "final",
        "median µs",
        "p95 µs"
    );
    for est in &mut estimators {
        est.reset(nominal.as_slice()).expect("10 finite values");
        let mut errors = Vec::with_capacity(windows);
        let mut times = Vec::with_capacity(windows);
        for (a, b, truth) in &stream {
            let start = Instant::now();
            est.update(a, b).expect("finite windows");
            times.push(start.elapsed().as_secs_f64() * 1e6);
            let err: f64 = est
                .estimate()
                .iter()
                .zip(truth.as_slice())
                .map(|(x, t)| (x - t).powi(2))
                .sum::<f64>()
                .sqrt();
            errors.push(err);
        }
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let p95 = times[(times.len() * 95 / 100).min(times.len() - 1)];
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        println!(
            "{:<9} {:>11.2e} {:>12.2e} {:>12.2e} {:>12.2e} {:>12.2e} {:>10.2} {:>10.2}",
            est.name(),
            mean,
            errors[attach - 1],
            errors[attach],
            errors[drop],
            errors[windows - 1],
            median,
            p95
        );
    }
    println!(
        "\n(t+1): the error of the first estimate after the payload event. The payload changes θ by \
         {:.2e}.",
        loaded
            .as_slice()
            .iter()
            .zip(nominal.as_slice())
            .map(|(x, t)| (x - t).powi(2))
            .sum::<f64>()
            .sqrt()
    );
}
