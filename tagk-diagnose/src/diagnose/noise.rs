//! The noise of each wrench channel: what no model can predict, measured from the data (or
//! given from the sensors' specification), and the yardstick every decision of the
//! diagnosis is made against.
//!
//! **Estimate.** The noise of a channel is the high-frequency part of the residual of the best
//! model at hand, by second differences: for white noise `e`, `Δ²e_i = e_{i+1} − 2 e_i +
//! e_{i−1}` has variance `6 σ²`, while a residual that varies slowly with the flight (a missing
//! drag, a bias) has almost none. The median of `(Δ²e)²` over `6 × 0.4549` (the median of a
//! χ²₁ variable) makes it robust against a few glitches. Second differences never cross a
//! join of several logs or a gap.
//!
//! **Floor.** No channel's noise is taken below its **resolution**: 10⁻⁴ of the RMS of the
//! measured force magnitude for the forces, times the airframe radius for the torques — below
//! that no effect matters to a flight-dynamics model, and a noise-free simulator log would
//! otherwise chase rounding.
//!
//! **Split.** The noise of a channel comes from two sides of the regression: the measured
//! wrench itself (rotor speeds read back, or the logged command) and the motion sensors that
//! build the regressor (accelerometer for the forces, gyro for the torques). With the
//! measured wrench `b`, the model's prediction `p = b − e` and the residual `e`, and `J` the
//! high-frequency motion both share, `HF(b)² = J² + σ_b²`, `HF(p)² = J² + σ_m²` and
//! `HF(e)² = σ_b² + σ_m²`, so `σ_b² = (HF(b)² − HF(p)² + HF(e)²)/2` and `σ_m²` the rest: which
//! sensor limits each channel ([`NoiseFloor::limited_by`]).

use serde::Serialize;

use crate::fit::{Fit, Model, channel_filters, estimate_noise, model_filters};
use crate::signals::Signals;

/// Resolution of the noise, relative to the RMS measured force magnitude (10⁻⁴).
pub const FLOOR_RESOLUTION: f64 = 1e-4;

/// Where the noise per channel came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FloorSource {
    /// The data: the high-frequency estimate of the best model's residual (or the resolution).
    Data,
    /// The user's per-channel noise level (a sensor specification).
    Given,
}

/// The noise of a log, per channel `fx … tz` (N, N m).
#[derive(Debug, Clone, Serialize)]
pub struct NoiseFloor {
    /// The noise σ per channel that every decision is made against: `√(σ_b² + σ_m²)` of the
    /// two sources (or the given value), never below the resolution.
    pub rms: [f64; 6],
    /// Where it came from.
    pub source: FloorSource,
    /// The high-frequency (second-difference) estimate of the residual per channel, as
    /// measured (also when the noise was given; with a lag in the model, of the residual
    /// mapped back through the inverse lag, which raises the motion sensors' part).
    pub noise_estimate: [f64; 6],
    /// The resolution per channel (module docs).
    pub resolution: [f64; 6],
    /// The part of each channel's noise from the measured wrench (rotor speeds or the logged
    /// command) (N, N m).
    pub from_wrench: [f64; 6],
    /// The part of each channel's noise from the motion sensors through the model
    /// (accelerometer for the forces, gyro for the torques) (N, N m).
    pub from_motion: [f64; 6],
    /// The model whose residual the estimate was taken on.
    pub model: String,
}

impl NoiseFloor {
    /// The sensor quantity whose noise limits the coefficients of an effect acting on
    /// `channels`: the larger of the two sources summed over them, each channel in units of its
    /// total noise (the measured wrench's side or the motion sensors').
    pub fn limits(&self, channels: &[usize]) -> &'static str {
        let share = |v: &[f64; 6]| -> f64 {
            channels
                .iter()
                .filter(|&&c| c < 6 && self.rms[c] > 0.0)
                .map(|&c| (v[c] / self.rms[c]).powi(2))
                .sum()
        };
        let forces = channels.iter().all(|&c| c < 3);
        match (share(&self.from_wrench) >= share(&self.from_motion), forces) {
            (true, _) => "the measured wrench (rotor speeds or logged command)",
            (false, true) => "the accelerometer",
            (false, false) => "the motion sensors (accelerometer, gyro)",
        }
    }

    /// The sensor quantity that limits channel `c`: the measured wrench's or the motion
    /// sensors' side of its noise, whichever is larger.
    pub fn limited_by(&self, c: usize) -> &'static str {
        if self.from_wrench[c] >= self.from_motion[c] {
            if c < 3 {
                "the measured thrust (rotor speeds or logged command)"
            } else {
                "the measured torques (rotor speeds or logged command)"
            }
        } else if c < 3 {
            "the accelerometer"
        } else {
            "the gyro (angular acceleration)"
        }
    }
}

/// The noise of a log from the fit `fit` of `model` (its residual of the measured wrench),
/// or the `given` noise per channel; never below the resolution.
pub(crate) fn noise_floor(
    s: &Signals,
    fit: &Fit,
    model: &Model,
    given: Option<[f64; 6]>,
    airframe_radius: f64,
) -> NoiseFloor {
    let filt = model_filters(model, s, &fit.params);
    let filters = channel_filters(&filt, s);
    let (split, estimate) = estimate_noise(s, &fit.residual, &filters);
    let resolution = crate::fit::resolution(s, airframe_radius);
    let (rms, source) = match given {
        Some(g) => (g, FloorSource::Given),
        None => (
            std::array::from_fn(|c| split.variance(c).sqrt().max(resolution[c])),
            FloorSource::Data,
        ),
    };
    NoiseFloor {
        rms,
        source,
        noise_estimate: estimate,
        resolution,
        from_wrench: split.wrench,
        from_motion: split.motion,
        model: fit.label.clone(),
    }
}
