//! Sensing profiles: the noise and biases of the vehicle's own sensors (IMU, velocity,
//! rotor-speed reading), on top of the paper's swept [`NoiseLevel`](crate::NoiseLevel).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::SimError;

/// BMI088 gyroscope output noise density \[deg/s/sqrt(Hz)\] (Bosch BMI088 data sheet
/// BST-BMI088-DS001, gyroscope specification: 0.014 deg/s/sqrt(Hz)).
pub const BMI088_GYRO_NOISE_DENSITY_DEG: f64 = 0.014;
/// Gyroscope filter bandwidth the Crazyflie firmware configures \[Hz\]
/// (`BMI088_GYRO_BW_116_ODR_1000_HZ` in `sensors_bmi088_bmp388.c`).
pub const CRAZYFLIE_GYRO_BANDWIDTH: f64 = 116.0;
/// BMI088 accelerometer output noise density \[g/sqrt(Hz)\] (BMI088 data sheet, accelerometer
/// specification: 175 micro-g/sqrt(Hz)).
pub const BMI088_ACCEL_NOISE_DENSITY_G: f64 = 175e-6;
/// Accelerometer filter bandwidth of the Crazyflie's in-flight setting \[Hz\] (OSR4 at a
/// 1600 Hz output rate, "145 Hz cut-off according to datasheet" in `sensors_bmi088_bmp388.c`).
pub const CRAZYFLIE_ACCEL_BANDWIDTH: f64 = 145.0;
/// Factor by which propeller vibration raises the IMU's in-flight noise above the data
/// sheet's at-rest white noise (a chosen figure). The Crazyflie's motors sit on the IMU's
/// circuit board. Its own Kalman filter assumes a far more conservative 0.1 rad/s of gyro
/// noise (`measNoiseGyro_rollpitch` in `kalman_core.c`).
pub const PROPELLER_VIBRATION_FACTOR: f64 = 3.0;
/// BMI088 gyroscope zero-rate offset drift with temperature \[deg/s/K\] (data sheet: TCO
/// 0.015 deg/s/K).
pub const BMI088_GYRO_OFFSET_DRIFT_DEG: f64 = 0.015;
/// Warm-up between the Crazyflie's at-rest gyro calibration and flight \[K\] (a chosen
/// figure: the board heats by about this much once the motors run).
pub const WARM_UP_KELVIN: f64 = 10.0;
/// BMI088 accelerometer zero-g offset, typical \[g\] (data sheet: 20 mg).
pub const BMI088_ACCEL_OFFSET_G: f64 = 20e-3;
/// Motion-capture position noise, σ per axis \[m\] (0.5 mm: OptiTrack and Vicon systems quote
/// sub-millimetre 3-D accuracy for small markers in a room-sized volume; a chosen figure at
/// the upper end of that range, for a small quadrotor's few markers).
pub const MOCAP_POSITION_NOISE: f64 = 0.5e-3;
/// Motion-capture attitude noise, σ per axis \[rad\] (0.2 deg; a chosen figure). 0.5 mm
/// marker noise over the Crazyflie's ≈ 10 cm marker baseline gives ≈ 5 mrad per marker.
/// Averaged over 4 markers, as two independent marker pairs, that is 5/√2 ≈ 3.5 mrad.
pub const MOCAP_ATTITUDE_NOISE: f64 = 3.5e-3;
/// Relative thrust-coefficient error of the `realistic` experiment profile (−5 %: half the
/// battery-sag and propeller-wear range that Förster 2015 measured on the Crazyflie's thrust
/// map, for a map identified on the same battery; a chosen figure).
pub const REALISTIC_THRUST_GAIN_ERROR: f64 = -0.05;
/// Motor time constant of the `realistic` experiment profile \[s\]: 0.01 s, the fast end of
/// small-quadrotor motors (a chosen figure). The Crazyflie's coreless motors are slower, about
/// 0.02 s ([`MotorLag::crazyflie`](crate::plant_effects::MotorLag::crazyflie)). The
/// simulator's LQR is designed without actuator dynamics. At 0.02 s it loses 7 of 20 of even
/// the oracle's flights in this profile; at 0.01 s, 1 of 20, as without lag (low noise,
/// 20-trial probe). A table at 0.02 s would measure the controller, not the estimators.
pub const REALISTIC_MOTOR_LAG: f64 = 0.01;
/// Standard gravity \[m/s²\] (to convert the data sheet's `g` units).
const STANDARD_GRAVITY: f64 = 9.806_65;

/// The vehicle's own sensors: per-sample white noise and per-flight constant biases.
///
/// Every σ is per axis (per rotor for the rotor speeds) and per logged sample (one a 20 ms
/// control interval). The profile is **added** to the paper's swept
/// [`NoiseLevel`](crate::NoiseLevel): where both give a σ for one signal (velocity,
/// acceleration), the two are independent and combine in quadrature,
/// `σ = sqrt(σ_level² + σ_sensing²)` ([`Sensing::combined`]).
///
/// What each field does in the flight (see the crate README, "Measurement model"):
///
/// | field | signal | used by |
/// |---|---|---|
/// | `gyro_noise`, `gyro_bias` | rate gyro `ω` (and `ω̇`, the difference of two readings: a constant bias cancels there) | controller, estimator, log `wx..wz`, `dwx..dwz` |
/// | `accel_noise`, `accel_bias` | accelerometer (proper acceleration, body frame) | estimator, log `ax..az` |
/// | `velocity_noise` | velocity (motion capture) | controller, log `vx..vz` |
/// | `rotor_speed_noise` | measured rotor speeds = commanded + noise | log `w1..w4`, and through the nominal mixer the measured wrench `b` of the estimator and log `fx..tz` |
///
/// Biases are drawn once per flight from the seed (a stream of their own, so that a profile
/// with zero biases draws exactly what it drew before biases existed).
///
/// **An accelerometer bias is a constant body force in the data**: `m (a + b_a)` differs from
/// the wrench by `m b_a`, exactly the signature of a force bias. A diagnosis of a log with
/// [`Sensing::realistic`] therefore correctly reports `body-bias`; use
/// [`Sensing::realistic_calibrated`] for logs whose accelerometer was calibrated in flight.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sensing {
    /// Rate-gyro white noise, σ per axis per sample \[rad/s\].
    pub gyro_noise: f64,
    /// σ of the rate gyro's constant per-flight bias, per axis \[rad/s\].
    pub gyro_bias: f64,
    /// Accelerometer white noise, σ per axis per sample `[m/s²]` (combined in quadrature with
    /// the noise level's σ_a).
    pub accel_noise: f64,
    /// σ of the accelerometer's constant per-flight bias, per body axis `[m/s²]`.
    pub accel_bias: f64,
    /// Velocity white noise, σ per axis per sample \[m/s\] (combined in quadrature with the
    /// noise level's σ_v).
    pub velocity_noise: f64,
    /// White noise on each measured rotor speed, σ per rotor per sample \[rad/s\].
    pub rotor_speed_noise: f64,
    /// Motion-capture position white noise seen by the controller, σ per axis \[m\].
    #[serde(default)]
    pub position_noise: f64,
    /// Motion-capture attitude white noise seen by the controller, σ per axis of a small
    /// rotation \[rad\].
    #[serde(default)]
    pub attitude_noise: f64,
}

impl Default for Sensing {
    /// [`Sensing::ideal`].
    fn default() -> Self {
        Self::ideal()
    }
}

impl Sensing {
    /// Ideal sensors: every σ zero. With it a flight is bit-identical to the simulator before
    /// sensing profiles existed (only the [`NoiseLevel`](crate::NoiseLevel) adds noise).
    pub const fn ideal() -> Self {
        Self {
            gyro_noise: 0.0,
            gyro_bias: 0.0,
            accel_noise: 0.0,
            accel_bias: 0.0,
            velocity_noise: 0.0,
            rotor_speed_noise: 0.0,
            position_noise: 0.0,
            attitude_noise: 0.0,
        }
    }

    /// A Crazyflie 2.1 in flight: BMI088 IMU with propeller vibration, motion-capture
    /// velocity, rotor speeds read back as an ESC's eRPM telemetry.
    ///
    /// | field | value | from |
    /// |---|---|---|
    /// | `gyro_noise` | 7.9e-3 rad/s (0.45 deg/s) | data sheet 0.014 deg/s/sqrt(Hz) × sqrt(116 Hz) = 0.15 deg/s, × 3 for propeller vibration ([`PROPELLER_VIBRATION_FACTOR`], chosen) |
    /// | `gyro_bias` | 2.6e-3 rad/s (0.15 deg/s) | what remains after the firmware's at-rest calibration: data sheet offset drift 0.015 deg/s/K × 10 K warm-up ([`WARM_UP_KELVIN`], chosen) |
    /// | `accel_noise` | 0.062 m/s² | data sheet 175 micro-g/sqrt(Hz) × sqrt(145 Hz) = 2.1 mg, × 3 for propeller vibration |
    /// | `accel_bias` | 0.196 m/s² (20 mg) | data sheet typical zero-g offset (the firmware only rescales the magnitude at rest) |
    /// | `velocity_noise` | 0.01 m/s | motion capture (sub-millimetre position, differenced at 100 Hz and filtered); a chosen figure |
    /// | `rotor_speed_noise` | 20 rad/s | about 1 % of the hover speed (≈ 1930 rad/s): eRPM period quantisation (≈ 0.3 % at hover with 1 µs steps) plus commutation jitter; a chosen figure |
    ///
    /// The accelerometer bias is realistic for an uncalibrated BMI088 and shows in the data as a
    /// constant body force (see [`Sensing`]).
    pub fn realistic() -> Self {
        let deg = std::f64::consts::PI / 180.0;
        Self {
            gyro_noise: BMI088_GYRO_NOISE_DENSITY_DEG
                * deg
                * CRAZYFLIE_GYRO_BANDWIDTH.sqrt()
                * PROPELLER_VIBRATION_FACTOR,
            gyro_bias: BMI088_GYRO_OFFSET_DRIFT_DEG * WARM_UP_KELVIN * deg,
            accel_noise: BMI088_ACCEL_NOISE_DENSITY_G
                * STANDARD_GRAVITY
                * CRAZYFLIE_ACCEL_BANDWIDTH.sqrt()
                * PROPELLER_VIBRATION_FACTOR,
            accel_bias: BMI088_ACCEL_OFFSET_G * STANDARD_GRAVITY,
            velocity_noise: 0.01,
            rotor_speed_noise: 20.0,
            position_noise: 0.0,
            attitude_noise: 0.0,
        }
    }

    /// [`Sensing::realistic`] with the accelerometer calibrated in flight (`accel_bias = 0`):
    /// a log whose only constant body force is the plant's.
    pub fn realistic_calibrated() -> Self {
        Self {
            accel_bias: 0.0,
            ..Self::realistic()
        }
    }

    /// This profile with motion-capture noise on the controller's position \[m\] and attitude
    /// \[rad\] ([`MOCAP_POSITION_NOISE`], [`MOCAP_ATTITUDE_NOISE`] for a typical system).
    pub fn with_motion_capture(self, position_noise: f64, attitude_noise: f64) -> Self {
        Self {
            position_noise,
            attitude_noise,
            ..self
        }
    }

    /// This profile with the rate-gyro noise `gyro_noise` \[rad/s\].
    pub fn with_gyro_noise(self, gyro_noise: f64) -> Self {
        Self { gyro_noise, ..self }
    }

    /// The σ of two independent noises on one signal, `sqrt(a² + b²)`; exactly `a` when
    /// `b = 0` (and `b` when `a = 0`), so that an ideal profile leaves the noise level's σ
    /// bit-for-bit unchanged.
    pub fn combined(a: f64, b: f64) -> f64 {
        if b == 0.0 {
            a
        } else if a == 0.0 {
            b
        } else {
            a.hypot(b)
        }
    }

    /// Checks every σ is non-negative and finite.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<(), SimError> {
        for (name, value) in [
            ("sensing.gyro_noise", self.gyro_noise),
            ("sensing.gyro_bias", self.gyro_bias),
            ("sensing.accel_noise", self.accel_noise),
            ("sensing.accel_bias", self.accel_bias),
            ("sensing.velocity_noise", self.velocity_noise),
            ("sensing.rotor_speed_noise", self.rotor_speed_noise),
            ("sensing.position_noise", self.position_noise),
            ("sensing.attitude_noise", self.attitude_noise),
        ] {
            if !(value >= 0.0 && value.is_finite()) {
                return Err(SimError::InvalidParameter {
                    name,
                    value,
                    reason: "must be non-negative and finite",
                });
            }
        }
        Ok(())
    }
}

/// The experiment profiles of Table II (`noise_sweep --profile NAME`): what the vehicle's
/// sensors and actuators add on top of the swept [`NoiseLevel`](crate::NoiseLevel).
///
/// | profile | sensing | plant | flight stack |
/// |---|---|---|---|
/// | `paper` | [`Sensing::ideal`] | ideal rotors (the TAG-K paper's setting, reproduces the earlier tables) | [`FlightStack::paper`](crate::FlightStack::paper): bare LQR |
/// | `realistic` | [`Sensing::realistic`] (BMI088 gyro and accelerometer noise and bias, velocity noise, 1 % rotor-speed noise) plus motion capture ([`MOCAP_POSITION_NOISE`], [`MOCAP_ATTITUDE_NOISE`]) | motor lag [`REALISTIC_MOTOR_LAG`] and a thrust-coefficient error [`REALISTIC_THRUST_GAIN_ERROR`] | [`FlightStack::realistic`](crate::FlightStack::realistic): integral action on position, payloads within a thrust margin, the controller's inertia completed from mass and first moment, motor telemetry |
/// | `cf21` | as `realistic`, without the Gaussian rotor-speed noise; the noise level sets the IMU's vibration | as `realistic` | [`FlightStack::vehicle`](crate::FlightStack::vehicle) with [`BrushedPwm`](crate::sim::rotor_sensing::BrushedPwm): the wrench from 8-bit PWM commands and the battery reading |
/// | `cf21-brushless` | as `cf21` | as `realistic` | [`FlightStack::vehicle`](crate::FlightStack::vehicle) with [`ErpmTelemetry`](crate::sim::rotor_sensing::ErpmTelemetry): eRPM by bidirectional DShot |
///
/// Every figure's source is in the doc comment of its constant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum ExperimentProfile {
    /// The paper's ideal sensing and actuation.
    #[default]
    Paper,
    /// A Crazyflie's sensors and actuators with 1 kHz averaged rotor-speed telemetry (issue
    /// #14; kept for its tests and tables, superseded by the two vehicles below).
    Realistic,
    /// A brushed Crazyflie 2.1: no rotor-speed feedback, the measured wrench from its 8-bit
    /// PWM commands, its battery-voltage reading and a motor model
    /// ([`BrushedPwm`](crate::sim::rotor_sensing::BrushedPwm)).
    Cf21,
    /// A Crazyflie 2.1 Brushless: eRPM telemetry by bidirectional DShot at its own rate and
    /// resolution ([`ErpmTelemetry`](crate::sim::rotor_sensing::ErpmTelemetry)). The default
    /// of the experiments.
    Cf21Brushless,
}

impl ExperimentProfile {
    /// Every profile.
    pub const ALL: [ExperimentProfile; 4] = [
        ExperimentProfile::Paper,
        ExperimentProfile::Realistic,
        ExperimentProfile::Cf21,
        ExperimentProfile::Cf21Brushless,
    ];

    /// The real vehicles' profiles (issue #27).
    pub const VEHICLES: [ExperimentProfile; 2] =
        [ExperimentProfile::Cf21, ExperimentProfile::Cf21Brushless];

    /// Whether this is a real vehicle's profile ([`ExperimentProfile::VEHICLES`]).
    pub fn is_vehicle(self) -> bool {
        Self::VEHICLES.contains(&self)
    }

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ExperimentProfile::Paper => "paper",
            ExperimentProfile::Realistic => "realistic",
            ExperimentProfile::Cf21 => "cf21",
            ExperimentProfile::Cf21Brushless => "cf21-brushless",
        }
    }

    /// The sensing of this profile.
    pub fn sensing(self) -> Sensing {
        match self {
            ExperimentProfile::Paper => Sensing::ideal(),
            ExperimentProfile::Realistic => {
                Sensing::realistic().with_motion_capture(MOCAP_POSITION_NOISE, MOCAP_ATTITUDE_NOISE)
            }
            // The rotor speeds' errors come from the rotor-sensing model, not a Gaussian.
            ExperimentProfile::Cf21 | ExperimentProfile::Cf21Brushless => Sensing {
                rotor_speed_noise: 0.0,
                ..Sensing::realistic()
            }
            .with_motion_capture(MOCAP_POSITION_NOISE, MOCAP_ATTITUDE_NOISE),
        }
    }

    /// The plant effects of this profile.
    pub fn effects(self) -> crate::PlantEffects {
        match self {
            ExperimentProfile::Paper => crate::PlantEffects::none(),
            ExperimentProfile::Realistic
            | ExperimentProfile::Cf21
            | ExperimentProfile::Cf21Brushless => crate::PlantEffects {
                motor_lag: Some(crate::plant_effects::MotorLag {
                    time_constant: REALISTIC_MOTOR_LAG,
                }),
                thrust_gain: Some(crate::plant_effects::ThrustGain {
                    relative_error: REALISTIC_THRUST_GAIN_ERROR,
                }),
                ..crate::PlantEffects::none()
            },
        }
    }

    /// The flight stack of this profile (integral action, payload thrust margin).
    pub fn flight_stack(self) -> crate::sim::FlightStack {
        match self {
            ExperimentProfile::Paper => crate::sim::FlightStack::paper(),
            ExperimentProfile::Realistic => crate::sim::FlightStack::realistic(),
            ExperimentProfile::Cf21 => crate::sim::FlightStack::vehicle(
                crate::sim::rotor_sensing::RotorSensing::BrushedPwm(
                    crate::sim::rotor_sensing::BrushedPwm::crazyflie(REALISTIC_MOTOR_LAG),
                ),
            ),
            ExperimentProfile::Cf21Brushless => {
                crate::sim::FlightStack::vehicle(crate::sim::rotor_sensing::RotorSensing::Erpm(
                    crate::sim::rotor_sensing::ErpmTelemetry::crazyflie_brushless(),
                ))
            }
        }
    }

    /// `config` with this profile's sensing, plant effects and flight stack.
    pub fn apply(self, config: &mut crate::SimConfig) {
        config.sensing = self.sensing();
        config.effects = self.effects();
        config.flight_stack = self.flight_stack();
    }
}

impl fmt::Display for ExperimentProfile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for ExperimentProfile {
    type Err = SimError;

    /// Parses [`ExperimentProfile::name`].
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ExperimentProfile::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| SimError::Unknown {
                what: "experiment profile",
                value: s.to_string(),
                expected: "paper, realistic, cf21, cf21-brushless",
            })
    }
}

/// The named sensing profiles (`tagk simulate --sensing NAME`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum SensingProfile {
    /// [`Sensing::ideal`].
    #[default]
    Ideal,
    /// [`Sensing::realistic`].
    Realistic,
    /// [`Sensing::realistic_calibrated`].
    RealisticCalibrated,
    /// A Crazyflie 2.1 Brushless: the sensing of [`ExperimentProfile::Cf21Brushless`] and its
    /// rotor speeds read as eRPM telemetry
    /// ([`ErpmTelemetry`](crate::sim::rotor_sensing::ErpmTelemetry)), not with a Gaussian noise.
    Cf21Brushless,
}

impl SensingProfile {
    /// The synthetic profiles. The diagnosis benchmark draws its flights' sensing among
    /// these three.
    pub const SYNTHETIC: [SensingProfile; 3] = [
        SensingProfile::Ideal,
        SensingProfile::Realistic,
        SensingProfile::RealisticCalibrated,
    ];

    /// Every profile: [`SensingProfile::SYNTHETIC`] and the real vehicle's.
    pub const ALL: [SensingProfile; 4] = [
        SensingProfile::Ideal,
        SensingProfile::Realistic,
        SensingProfile::RealisticCalibrated,
        SensingProfile::Cf21Brushless,
    ];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SensingProfile::Ideal => "ideal",
            SensingProfile::Realistic => "realistic",
            SensingProfile::RealisticCalibrated => "realistic-calibrated",
            SensingProfile::Cf21Brushless => ExperimentProfile::Cf21Brushless.name(),
        }
    }

    /// The profile's figures.
    pub fn sensing(self) -> Sensing {
        match self {
            SensingProfile::Ideal => Sensing::ideal(),
            SensingProfile::Realistic => Sensing::realistic(),
            SensingProfile::RealisticCalibrated => Sensing::realistic_calibrated(),
            SensingProfile::Cf21Brushless => ExperimentProfile::Cf21Brushless.sensing(),
        }
    }

    /// Where the profile's measured rotor speeds come from:
    /// [`RotorSensing::Telemetry`](crate::sim::rotor_sensing::RotorSensing::Telemetry) (the
    /// read-back speeds plus [`Sensing::rotor_speed_noise`]) for the synthetic profiles, the
    /// vehicle's own model for [`SensingProfile::Cf21Brushless`].
    pub fn rotor_sensing(self) -> crate::sim::rotor_sensing::RotorSensing {
        match self {
            SensingProfile::Cf21Brushless => {
                ExperimentProfile::Cf21Brushless
                    .flight_stack()
                    .rotor_sensing
            }
            _ => crate::sim::rotor_sensing::RotorSensing::Telemetry,
        }
    }

    /// `stack` reading the rotor speeds as this profile does
    /// ([`SensingProfile::rotor_sensing`]); every other setting of `stack` kept.
    pub fn flight_stack(self, stack: crate::sim::FlightStack) -> crate::sim::FlightStack {
        crate::sim::FlightStack {
            rotor_sensing: self.rotor_sensing(),
            ..stack
        }
    }
}

impl fmt::Display for SensingProfile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SensingProfile {
    type Err = SimError;

    /// Parses [`SensingProfile::name`].
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        SensingProfile::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| SimError::Unknown {
                what: "sensing profile",
                value: s.to_string(),
                expected: "ideal, realistic, realistic-calibrated, cf21-brushless",
            })
    }
}
