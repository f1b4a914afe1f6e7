//! What a real vehicle knows of its rotor speeds (issue #27): a brushed Crazyflie 2.1 knows
//! only its PWM commands and its battery voltage; a Crazyflie 2.1 Brushless reads eRPM back
//! by bidirectional DShot. [`RotorSensing`] picks one; the flight stack turns it into the
//! rotor speeds behind the measured wrench.
//!
//! Each model is a pure function of its inputs and a random stream, so tests measure its
//! rate, step and noise from its output.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::SimError;

/// PWM resolution of the brushed Crazyflie 2.x motor driver \[bits\]. Source: crazyflie-firmware
/// `src/drivers/interface/motors.h`, `MOTORS_PWM_BITS 8` ("a PWM of 8 bits at ~328 kHz"); the
/// 16-bit thrust ratio is shifted down to it (`motorsConv16ToBits`).
pub const CRAZYFLIE_PWM_BITS: u32 = 8;
/// Nominal battery voltage of the brushed Crazyflie's 1S LiPo \[V\] (3.7 V mid-charge, as the
/// firmware's comment in `motors.c` states: "4.2V charged, 3.7V mid-charge and 3V discharged").
pub const CRAZYFLIE_BATTERY_VOLTAGE: f64 = 3.7;
/// σ of the battery-voltage reading the brushed firmware divides by \[V\] (a chosen figure:
/// a few ADC counts plus the ripple under motor load; an assumption, not a data-sheet value).
/// The firmware sets the PWM duty as `volts_needed / V_measured` (`motorsSetRatio`), so a
/// reading off by `δV` makes every motor's speed off by `δV / V`.
pub const CRAZYFLIE_BATTERY_NOISE: f64 = 0.02;
/// eRPM telemetry rate of the Crazyflie 2.1 Brushless \[Hz\] (an assumption: one bidirectional
/// DShot frame per 1 kHz stabilizer loop, each answered with a telemetry frame; the firmware
/// sends DShot synchronously with the power distribution, `motorsBurstDshot` in `motors.c`).
pub const BRUSHLESS_TELEMETRY_RATE: f64 = 1000.0;
/// Pole pairs of the Crazyflie 2.1 Brushless motors (an assumption: 12N14P stators, the
/// usual winding of 08xx–11xx brushless motors; eRPM = pole pairs × mechanical RPM).
pub const BRUSHLESS_POLE_PAIRS: u32 = 7;
/// Mantissa bits of the eRPM period in a bidirectional DShot telemetry frame. Source: the
/// frame is `[3-bit shift][9-bit period base][4-bit CRC]`, period = base << shift in µs
/// (betaflight `src/main/drivers/dshot.c`; docs.rs `dshot-frame`, `ErpmTelemetry`).
pub const ERPM_MANTISSA_BITS: u32 = 9;
/// Time unit of the eRPM period field \[s\] (1 µs, same sources as [`ERPM_MANTISSA_BITS`]).
pub const ERPM_PERIOD_UNIT: f64 = 1e-6;
/// σ of the ESC's electrical-period measurement before quantisation \[s\] (a chosen figure:
/// 1 µs of zero-crossing timing jitter; an assumption).
pub const ERPM_PERIOD_JITTER: f64 = 1e-6;

/// The brushed Crazyflie's knowledge of its rotor speeds: its own PWM commands.
///
/// - The speed command is quantised to the PWM's `2^bits − 1` duty steps of the rotors'
///   maximum speed (duty ∝ speed: a DC motor's speed follows its mean voltage).
/// - The duty is set for the **measured** battery voltage: with a reading off by `δV`, every
///   rotor spins at `(1 + δV / V)` of the quantised command (one `δV` per control interval).
/// - The flight stack predicts each motor's speed from its quantised commands through a
///   first-order motor model of time constant `model_time_constant` (none: `0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BrushedPwm {
    /// PWM resolution \[bits\] ([`CRAZYFLIE_PWM_BITS`]).
    pub pwm_bits: u32,
    /// Nominal battery voltage \[V\].
    pub battery_voltage: f64,
    /// σ of the battery-voltage reading \[V\].
    pub battery_noise: f64,
    /// Time constant of the flight stack's motor model \[s\] (`0`: the command itself).
    pub model_time_constant: f64,
}

/// The brushless Crazyflie's eRPM telemetry by bidirectional DShot.
///
/// Readings come at `rate` (one every `1/rate` s, on a grid from `t = 0`). Each is the
/// motor's electrical period `2π / (pole_pairs ω)` plus Gaussian jitter of σ `jitter`, sent as
/// a `mantissa_bits` mantissa with a power-of-two shift in units of `period_unit`. The flight
/// stack takes the latest reading at the control interval's midpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ErpmTelemetry {
    /// Telemetry rate \[Hz\] (at least 100 Hz: a reading within the interval's first half).
    pub rate: f64,
    /// Motor pole pairs.
    pub pole_pairs: u32,
    /// Bits of the period mantissa.
    pub mantissa_bits: u32,
    /// Time unit of the period \[s\].
    pub period_unit: f64,
    /// σ of the period measurement \[s\].
    pub jitter: f64,
}

/// Where the measured rotor speeds come from.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum RotorSensing {
    /// The read-back speeds (commanded, or the motors' with
    /// [`FlightStack::motor_telemetry`](crate::FlightStack::motor_telemetry)) plus the
    /// profile's Gaussian rotor-speed noise: the simulator before issue #27.
    #[default]
    Telemetry,
    /// A brushed vehicle's PWM commands ([`BrushedPwm`]).
    BrushedPwm(BrushedPwm),
    /// A brushless vehicle's eRPM telemetry ([`ErpmTelemetry`]).
    Erpm(ErpmTelemetry),
}

impl BrushedPwm {
    /// The brushed Crazyflie 2.1: [`CRAZYFLIE_PWM_BITS`], [`CRAZYFLIE_BATTERY_VOLTAGE`],
    /// [`CRAZYFLIE_BATTERY_NOISE`], and a motor model of time constant `model_time_constant`.
    pub const fn crazyflie(model_time_constant: f64) -> Self {
        Self {
            pwm_bits: CRAZYFLIE_PWM_BITS,
            battery_voltage: CRAZYFLIE_BATTERY_VOLTAGE,
            battery_noise: CRAZYFLIE_BATTERY_NOISE,
            model_time_constant,
        }
    }

    /// The speed step of one PWM count for rotors of maximum speed `max_speed` \[rad/s\].
    pub fn speed_step(&self, max_speed: f64) -> f64 {
        max_speed / f64::from((1u32 << self.pwm_bits) - 1)
    }

    /// The quantised command of `speed` \[rad/s\]: the nearest PWM count's speed, within
    /// `[0, max_speed]`.
    pub fn quantise(&self, speed: f64, max_speed: f64) -> f64 {
        let step = self.speed_step(max_speed);
        ((speed / step).round() * step).clamp(0.0, max_speed)
    }

    /// The relative speed error of one interval's battery reading (draws one normal from
    /// `rng`; none at σ = 0).
    pub fn voltage_factor(&self, rng: &mut ChaCha8Rng) -> f64 {
        if self.battery_noise == 0.0 {
            return 1.0;
        }
        1.0 + self.battery_noise * gaussian(rng) / self.battery_voltage
    }
}

impl ErpmTelemetry {
    /// The Crazyflie 2.1 Brushless: [`BRUSHLESS_TELEMETRY_RATE`], [`BRUSHLESS_POLE_PAIRS`],
    /// [`ERPM_MANTISSA_BITS`], [`ERPM_PERIOD_UNIT`], [`ERPM_PERIOD_JITTER`].
    pub const fn crazyflie_brushless() -> Self {
        Self {
            rate: BRUSHLESS_TELEMETRY_RATE,
            pole_pairs: BRUSHLESS_POLE_PAIRS,
            mantissa_bits: ERPM_MANTISSA_BITS,
            period_unit: ERPM_PERIOD_UNIT,
            jitter: ERPM_PERIOD_JITTER,
        }
    }

    /// The time of the latest reading at or before `t` \[s\].
    pub fn reading_time(&self, t: f64) -> f64 {
        // A hair of tolerance so that a reading due exactly at `t` counts despite round-off.
        (t * self.rate + 1e-9).floor() / self.rate
    }

    /// The electrical period \[s\] as the frame carries it: `period` rounded to a mantissa of
    /// [`ErpmTelemetry::mantissa_bits`] bits with the smallest shift that fits (at most 7).
    pub fn quantise_period(&self, period: f64) -> f64 {
        let max_mantissa = f64::from((1u32 << self.mantissa_bits) - 1);
        let units = (period / self.period_unit).max(0.0);
        let mut shift = 0;
        while shift < 7 && (units / f64::from(1u32 << shift)).round() > max_mantissa {
            shift += 1;
        }
        let scale = f64::from(1u32 << shift);
        (units / scale).round().clamp(0.0, max_mantissa) * scale * self.period_unit
    }

    /// One reading of the mechanical speed `speed` \[rad/s\]: its electrical period plus jitter
    /// (one normal from `rng`; none at σ = 0), quantised, turned back into a speed. A period
    /// of 0 (a stopped motor, or a jitter below zero) reads 0.
    pub fn read(&self, speed: f64, rng: &mut ChaCha8Rng) -> f64 {
        if speed <= 0.0 {
            return 0.0;
        }
        let pp = f64::from(self.pole_pairs);
        let mut period = std::f64::consts::TAU / (pp * speed);
        if self.jitter > 0.0 {
            period += self.jitter * gaussian(rng);
        }
        let q = self.quantise_period(period);
        if q <= 0.0 {
            0.0
        } else {
            std::f64::consts::TAU / (pp * q)
        }
    }
}

impl RotorSensing {
    /// Checks the model's settings.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |name: &'static str, value: f64, reason: &'static str| {
            Err(SimError::InvalidParameter {
                name,
                value,
                reason,
            })
        };
        match self {
            RotorSensing::Telemetry => Ok(()),
            RotorSensing::BrushedPwm(p) => {
                if !(1..=16).contains(&p.pwm_bits) {
                    return bad(
                        "rotor_sensing.pwm_bits",
                        f64::from(p.pwm_bits),
                        "must be 1 to 16",
                    );
                }
                if !(p.battery_voltage > 0.0 && p.battery_voltage.is_finite()) {
                    return bad(
                        "rotor_sensing.battery_voltage",
                        p.battery_voltage,
                        "must be positive and finite",
                    );
                }
                for (name, v) in [
                    ("rotor_sensing.battery_noise", p.battery_noise),
                    ("rotor_sensing.model_time_constant", p.model_time_constant),
                ] {
                    if !(v >= 0.0 && v.is_finite()) {
                        return bad(name, v, "must be non-negative and finite");
                    }
                }
                Ok(())
            }
            RotorSensing::Erpm(e) => {
                if !(e.rate >= 100.0 && e.rate.is_finite()) {
                    return bad(
                        "rotor_sensing.rate",
                        e.rate,
                        "must be at least 100 Hz and finite",
                    );
                }
                if e.pole_pairs == 0 {
                    return bad("rotor_sensing.pole_pairs", 0.0, "must be at least 1");
                }
                if !(1..=16).contains(&e.mantissa_bits) {
                    return bad(
                        "rotor_sensing.mantissa_bits",
                        f64::from(e.mantissa_bits),
                        "must be 1 to 16",
                    );
                }
                if !(e.period_unit > 0.0 && e.period_unit.is_finite()) {
                    return bad(
                        "rotor_sensing.period_unit",
                        e.period_unit,
                        "must be positive and finite",
                    );
                }
                if !(e.jitter >= 0.0 && e.jitter.is_finite()) {
                    return bad(
                        "rotor_sensing.jitter",
                        e.jitter,
                        "must be non-negative and finite",
                    );
                }
                Ok(())
            }
        }
    }
}

/// Standard normal draw (Box–Muller), as the sensors draw theirs.
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The flight stack's first-order motor model of a brushed vehicle: its prediction of each
/// rotor's speed from the commands alone.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MotorModel {
    /// Predicted speeds at the start of the current interval \[rad/s\].
    speeds: [f64; 4],
}

impl MotorModel {
    /// A model starting at `speeds` \[rad/s\].
    pub(crate) fn new(speeds: [f64; 4]) -> Self {
        Self { speeds }
    }

    /// Advances over one interval of length `dt` \[s\] with the command `cmd` held, time constant
    /// `tau` \[s\] (`0`: the command at once); returns the prediction at the midpoint (the
    /// closed form of `ω̇ = (ω_cmd − ω)/τ`).
    pub(crate) fn step(&mut self, cmd: &[f64; 4], tau: f64, dt: f64) -> [f64; 4] {
        if tau == 0.0 {
            self.speeds = *cmd;
            return *cmd;
        }
        let half = (-0.5 * dt / tau).exp();
        let full = (-dt / tau).exp();
        let mid = std::array::from_fn(|i| cmd[i] + (self.speeds[i] - cmd[i]) * half);
        self.speeds = std::array::from_fn(|i| cmd[i] + (self.speeds[i] - cmd[i]) * full);
        mid
    }
}
