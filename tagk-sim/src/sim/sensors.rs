//! The measurement model: seeded random streams, Gaussian noise, and what the controller and
//! the estimator see of the true state (see the crate docs for the timing).
//!
//! The order of the noise draws is part of the simulator's determinism: the same seed gives
//! the same bits only if every draw happens in the same order, so each method says what it
//! draws.

use nalgebra::Vector3;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use tagk_control::QuadrotorState;

use crate::plant::PlantState;
use crate::sim::NoiseLevel;

/// Standard normal draw (Box–Muller).
fn gaussian<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Three independent `N(0, σ²)` draws (none at all when `σ = 0`).
fn noise3<R: rand::Rng + ?Sized>(rng: &mut R, sigma: f64) -> Vector3<f64> {
    if sigma == 0.0 {
        return Vector3::zeros();
    }
    Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma
}

/// Independent random stream `stream` of a flight seeded with `seed` (SplitMix64 mixing).
pub(crate) fn sub_rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut z = seed
        .wrapping_add(stream.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ChaCha8Rng::seed_from_u64(z ^ (z >> 31))
}

/// What the estimator sees of one control interval, at its midpoint.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    /// Accelerometer: proper acceleration plus noise, body frame [m/s²].
    pub(crate) accel: Vector3<f64>,
    /// Gyro at the midpoint [rad/s].
    pub(crate) omega: Vector3<f64>,
    /// Difference of the gyro readings at the interval's ends over its length [rad/s²].
    pub(crate) omega_dot: Vector3<f64>,
}

/// The sensors of one flight: motion capture (exact position and attitude), noisy velocity,
/// accelerometer and rate gyro, all drawn from one random stream.
#[derive(Debug, Clone)]
pub(crate) struct Sensors {
    rng: ChaCha8Rng,
    sigma_velocity: f64,
    sigma_acceleration: f64,
    sigma_gyro: f64,
    /// Gyro reading at the start of the current control interval [rad/s].
    gyro_start: Vector3<f64>,
}

impl Sensors {
    /// Sensors with the noise of `noise` and `gyro_noise` [rad/s]; draws the first gyro
    /// reading of the body rate `initial_rate`.
    pub(crate) fn new(
        mut rng: ChaCha8Rng,
        noise: NoiseLevel,
        gyro_noise: f64,
        initial_rate: Vector3<f64>,
    ) -> Self {
        let gyro_start = initial_rate + noise3(&mut rng, gyro_noise);
        Self {
            rng,
            sigma_velocity: noise.sigma_velocity(),
            sigma_acceleration: noise.sigma_acceleration(),
            sigma_gyro: gyro_noise,
            gyro_start,
        }
    }

    /// What the controller sees at the start of an interval: mocap position and attitude,
    /// noisy velocity (draws 3 velocity noises), the interval's first gyro reading.
    pub(crate) fn controller_measurement(&mut self, s: &PlantState) -> QuadrotorState {
        QuadrotorState {
            position: s.position,
            velocity: s.velocity + noise3(&mut self.rng, self.sigma_velocity),
            attitude: s.attitude,
            body_rate: self.gyro_start,
        }
    }

    /// The estimator frame of an interval of length `dt` \[s\] that ended with the body rate
    /// `end_rate`, from the true midpoint body rate and proper acceleration. Draws the gyro
    /// reading at the end, the accelerometer noise, then the midpoint gyro noise; the end
    /// reading becomes the next interval's first.
    pub(crate) fn frame(
        &mut self,
        end_rate: Vector3<f64>,
        mid_rate: Vector3<f64>,
        mid_proper_acceleration: Vector3<f64>,
        dt: f64,
    ) -> Frame {
        let gyro_end = end_rate + noise3(&mut self.rng, self.sigma_gyro);
        let accel = mid_proper_acceleration + noise3(&mut self.rng, self.sigma_acceleration);
        let omega = mid_rate + noise3(&mut self.rng, self.sigma_gyro);
        let omega_dot = (gyro_end - self.gyro_start) / dt;
        self.gyro_start = gyro_end;
        Frame {
            accel,
            omega,
            omega_dot,
        }
    }

    /// The logged velocity: `velocity` plus a fresh velocity noise (draws 3).
    pub(crate) fn logged_velocity(&mut self, velocity: Vector3<f64>) -> Vector3<f64> {
        velocity + noise3(&mut self.rng, self.sigma_velocity)
    }
}
