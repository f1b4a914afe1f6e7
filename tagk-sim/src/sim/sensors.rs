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
use crate::sim::{NoiseLevel, Sensing};

/// Standard normal draw (Box–Muller); the closed loops of the quadrotor and the arm share it.
pub(crate) fn gaussian<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
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

/// `v + bias`, or `v` itself (bit for bit) without a bias.
fn biased(v: Vector3<f64>, bias: &Vector3<f64>) -> Vector3<f64> {
    if *bias == Vector3::zeros() {
        v
    } else {
        v + bias
    }
}

/// The sensors of one flight. Motion capture gives exact position and attitude. Velocity,
/// accelerometer and rate gyro are noisy; their white noise is all drawn from one random stream,
/// in a fixed order. Gyro and accelerometer biases are constant, drawn once from a stream of
/// their own. The rotor-speed reading takes its noise from a third stream.
#[derive(Debug, Clone)]
pub(crate) struct Sensors {
    rng: ChaCha8Rng,
    /// Stream of the rotor-speed noise.
    rotor_rng: ChaCha8Rng,
    /// Stream of the physics-rate log's IMU noise.
    imu_rng: ChaCha8Rng,
    mocap_rng: ChaCha8Rng,
    sigma_position: f64,
    sigma_attitude: f64,
    sigma_velocity: f64,
    sigma_acceleration: f64,
    sigma_gyro: f64,
    sigma_rotor_speed: f64,
    /// Constant gyro bias of the flight, body frame [rad/s].
    gyro_bias: Vector3<f64>,
    /// Constant accelerometer bias of the flight, body frame [m/s²].
    accel_bias: Vector3<f64>,
    /// Gyro reading at the start of the current control interval [rad/s].
    gyro_start: Vector3<f64>,
}

impl Sensors {
    /// Sensors with the noise of `noise` and the profile `sensing`: σ's of both combined in
    /// quadrature ([`Sensing::combined`]).
    /// - White noise comes from `rng`.
    /// - The biases come from `bias_rng`: always 6 standard normal draws (gyro x, y, z, then
    ///   accelerometer x, y, z), scaled by the profile's σ's. A seed fixes the bias direction
    ///   whatever the σ.
    /// - The rotor-speed noise comes from `rotor_rng`, the physics-rate log's noise from
    ///   `imu_rng`.
    ///
    /// Draws the first gyro reading of the body rate `initial_rate`.
    // One independent, named random stream per sensor (so that adding one leaves the others'
    // draws unchanged), plus the noise level, the profile and the initial rate.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        mut rng: ChaCha8Rng,
        mut bias_rng: ChaCha8Rng,
        rotor_rng: ChaCha8Rng,
        imu_rng: ChaCha8Rng,
        mocap_rng: ChaCha8Rng,
        noise: NoiseLevel,
        sensing: &Sensing,
        initial_rate: Vector3<f64>,
    ) -> Self {
        let gyro_bias = noise3(&mut bias_rng, 1.0) * sensing.gyro_bias;
        let accel_bias = noise3(&mut bias_rng, 1.0) * sensing.accel_bias;
        let gyro_start = biased(initial_rate, &gyro_bias) + noise3(&mut rng, sensing.gyro_noise);
        Self {
            rng,
            rotor_rng,
            imu_rng,
            mocap_rng,
            sigma_position: sensing.position_noise,
            sigma_attitude: sensing.attitude_noise,
            sigma_velocity: Sensing::combined(noise.sigma_velocity(), sensing.velocity_noise),
            sigma_acceleration: Sensing::combined(noise.sigma_acceleration(), sensing.accel_noise),
            sigma_gyro: sensing.gyro_noise,
            sigma_rotor_speed: sensing.rotor_speed_noise,
            gyro_bias,
            accel_bias,
            gyro_start,
        }
    }

    /// The flight's constant gyro bias \[rad/s\] and accelerometer bias `[m/s²]`, body frame.
    pub(crate) fn biases(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.gyro_bias, self.accel_bias)
    }

    /// The measured rotor speeds of the commanded `speeds` \[rad/s\]: plus `N(0, σ²)` per rotor
    /// (draws 4 from the rotor-speed stream; none, and `speeds` unchanged, when `σ = 0`),
    /// floored at 0.
    pub(crate) fn measured_rotor_speeds(&mut self, speeds: &[f64; 4]) -> [f64; 4] {
        if self.sigma_rotor_speed == 0.0 {
            return *speeds;
        }
        speeds.map(|w| (w + self.sigma_rotor_speed * gaussian(&mut self.rotor_rng)).max(0.0))
    }

    /// What the controller sees at the start of an interval: mocap position and attitude,
    /// noisy velocity (draws 3 velocity noises), the interval's first gyro reading.
    pub(crate) fn controller_measurement(&mut self, s: &PlantState) -> QuadrotorState {
        // Motion-capture noise from its own stream (nothing drawn at σ = 0), so that profiles
        // without it fly bit-identically to the simulator before it.
        let velocity = s.velocity + noise3(&mut self.rng, self.sigma_velocity);
        let position = if self.sigma_position > 0.0 {
            s.position + noise3(&mut self.mocap_rng, self.sigma_position)
        } else {
            s.position
        };
        let attitude = if self.sigma_attitude > 0.0 {
            s.attitude
                * nalgebra::UnitQuaternion::from_scaled_axis(noise3(
                    &mut self.mocap_rng,
                    self.sigma_attitude,
                ))
        } else {
            s.attitude
        };
        QuadrotorState {
            position,
            velocity,
            attitude,
            body_rate: self.gyro_start,
        }
    }

    /// The estimator frame of an interval of length `dt` \[s\] that ended with the body rate
    /// `end_rate`, from the true midpoint body rate and proper acceleration (the biases added
    /// to the gyro readings and the accelerometer). Draws the gyro
    /// reading at the end, the accelerometer noise, then the midpoint gyro noise; the end
    /// reading becomes the next interval's first.
    pub(crate) fn frame(
        &mut self,
        end_rate: Vector3<f64>,
        mid_rate: Vector3<f64>,
        mid_proper_acceleration: Vector3<f64>,
        dt: f64,
    ) -> Frame {
        let gyro_end = biased(end_rate, &self.gyro_bias) + noise3(&mut self.rng, self.sigma_gyro);
        let accel = biased(mid_proper_acceleration, &self.accel_bias)
            + noise3(&mut self.rng, self.sigma_acceleration);
        let omega = biased(mid_rate, &self.gyro_bias) + noise3(&mut self.rng, self.sigma_gyro);
        let omega_dot = (gyro_end - self.gyro_start) / dt;
        self.gyro_start = gyro_end;
        Frame {
            accel,
            omega,
            omega_dot,
        }
    }

    /// An instantaneous IMU-style sample for the physics-rate log, from the true body rate
    /// `rate`, proper acceleration `proper` and world velocity `velocity`. Gyro and accelerometer
    /// carry their bias. Gyro, accelerometer and velocity each get fresh noise from the IMU
    /// stream: 3 draws each, in that order, none for a zero σ.
    pub(crate) fn imu_sample(
        &mut self,
        rate: Vector3<f64>,
        proper: Vector3<f64>,
        velocity: Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let omega = biased(rate, &self.gyro_bias) + noise3(&mut self.imu_rng, self.sigma_gyro);
        let accel =
            biased(proper, &self.accel_bias) + noise3(&mut self.imu_rng, self.sigma_acceleration);
        let velocity = velocity + noise3(&mut self.imu_rng, self.sigma_velocity);
        (omega, accel, velocity)
    }

    /// The logged velocity: `velocity` plus a fresh velocity noise (draws 3).
    pub(crate) fn logged_velocity(&mut self, velocity: Vector3<f64>) -> Vector3<f64> {
        velocity + noise3(&mut self.rng, self.sigma_velocity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sample mean and standard deviation of `x`.
    fn mean_std(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var.sqrt())
    }

    fn sensors(seed: u64, noise: NoiseLevel, sensing: &Sensing) -> Sensors {
        Sensors::new(
            sub_rng(seed, 2),
            sub_rng(seed, 4),
            sub_rng(seed, 5),
            sub_rng(seed, 6),
            sub_rng(seed, 7),
            noise,
            sensing,
            Vector3::zeros(),
        )
    }

    /// Every per-sample noise has the profile's σ: the sample std is within 3 % over 20 000
    /// samples per axis, where the standard error of a std is 0.5 %. The per-sample mean is the
    /// flight's constant bias, within 5 standard errors.
    #[test]
    fn realistic_noise_has_the_stated_sigma_around_a_constant_bias() {
        let s = Sensing::realistic();
        let mut sensors = sensors(11, NoiseLevel::None, &s);
        let (gyro_bias, accel_bias) = sensors.biases();
        let n = 20_000;
        let mut omega = [vec![], vec![], vec![]];
        let mut accel = [vec![], vec![], vec![]];
        let mut velocity = [vec![], vec![], vec![]];
        let mut rotor = [vec![], vec![], vec![], vec![]];
        for _ in 0..n {
            let f = sensors.frame(Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), 0.02);
            let v = sensors.logged_velocity(Vector3::zeros());
            for i in 0..3 {
                omega[i].push(f.omega[i]);
                accel[i].push(f.accel[i]);
                velocity[i].push(v[i]);
            }
            let w = sensors.measured_rotor_speeds(&[2000.0; 4]);
            for i in 0..4 {
                rotor[i].push(w[i] - 2000.0);
            }
        }
        let se = 5.0 / (n as f64).sqrt();
        let check = |what: &str, x: &[f64], sigma: f64, bias: f64| {
            let (m, sd) = mean_std(x);
            assert!(
                (sd / sigma - 1.0).abs() < 0.03,
                "{what}: std {sd} vs sigma {sigma}"
            );
            assert!(
                (m - bias).abs() < se * sigma,
                "{what}: mean {m} vs bias {bias}"
            );
        };
        for i in 0..3 {
            check("gyro", &omega[i], s.gyro_noise, gyro_bias[i]);
            check("accel", &accel[i], s.accel_noise, accel_bias[i]);
            check("velocity", &velocity[i], s.velocity_noise, 0.0);
        }
        for r in &rotor {
            check("rotor speed", r, s.rotor_speed_noise, 0.0);
        }
    }

    /// The noise level and the profile combine in quadrature.
    #[test]
    fn noise_level_and_profile_add_in_quadrature() {
        let s = Sensing {
            accel_noise: 0.05e-2 * 0.75,
            velocity_noise: 0.5e-2 * 0.75,
            ..Sensing::ideal()
        };
        let mut sensors = sensors(3, NoiseLevel::Medium, &s);
        let n = 20_000;
        let (mut a, mut v) = (vec![], vec![]);
        for _ in 0..n {
            let f = sensors.frame(Vector3::zeros(), Vector3::zeros(), Vector3::zeros(), 0.02);
            a.push(f.accel.x);
            v.push(sensors.logged_velocity(Vector3::zeros()).y);
        }
        // sqrt(1 + 0.75²) = 1.25 times the level's σ.
        let (_, sa) = mean_std(&a);
        let (_, sv) = mean_std(&v);
        assert!((sa / (1.25 * 0.05e-2) - 1.0).abs() < 0.03, "{sa}");
        assert!((sv / (1.25 * 0.5e-2) - 1.0).abs() < 0.03, "{sv}");
    }

    /// The biases are drawn once per flight from the seed: the same seed gives the same
    /// biases, and across seeds they scatter with the profile's σ (std within 5 % over 4000
    /// flights, 3 axes each).
    #[test]
    fn biases_are_seeded_with_the_stated_sigma() {
        let s = Sensing::realistic();
        assert_eq!(
            sensors(7, NoiseLevel::None, &s).biases(),
            sensors(7, NoiseLevel::None, &s).biases()
        );
        assert_ne!(
            sensors(7, NoiseLevel::None, &s).biases(),
            sensors(8, NoiseLevel::None, &s).biases()
        );
        let (mut g, mut a) = (vec![], vec![]);
        for seed in 0..4000 {
            let (bg, ba) = sensors(seed, NoiseLevel::None, &s).biases();
            g.extend(bg.iter());
            a.extend(ba.iter());
        }
        let (mg, sg) = mean_std(&g);
        let (ma, sa) = mean_std(&a);
        assert!((sg / s.gyro_bias - 1.0).abs() < 0.05, "{sg}");
        assert!((sa / s.accel_bias - 1.0).abs() < 0.05, "{sa}");
        assert!(mg.abs() < 0.05 * s.gyro_bias && ma.abs() < 0.05 * s.accel_bias);
        // The calibrated profile keeps the gyro bias and has no accelerometer bias.
        let (bg, ba) = sensors(7, NoiseLevel::None, &Sensing::realistic_calibrated()).biases();
        assert_eq!(bg, sensors(7, NoiseLevel::None, &s).biases().0);
        assert_eq!(ba, Vector3::zeros());
    }

    /// A constant gyro bias cancels in `ω̇` (the difference of two readings).
    #[test]
    fn gyro_bias_cancels_in_the_rate_derivative() {
        let s = Sensing {
            gyro_bias: 0.01,
            ..Sensing::ideal()
        };
        let mut sensors = sensors(5, NoiseLevel::None, &s);
        let (bg, _) = sensors.biases();
        assert!(bg.norm() > 0.0);
        let rate = Vector3::new(0.1, -0.2, 0.3);
        let f = sensors.frame(rate, rate * 0.5, Vector3::zeros(), 0.02);
        assert!((f.omega_dot - rate / 0.02).norm() < 1e-12);
        assert!((f.omega - (rate * 0.5 + bg)).norm() < 1e-15);
    }
}
