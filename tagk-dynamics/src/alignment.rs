//! Time offsets between the sensor streams of one flight log, measured without any model.
//!
//! A log often joins streams from several sources. The pose (position and attitude) comes from
//! a motion-capture system; the angular rate and acceleration from the IMU; the velocity from a
//! state estimator; the rotor speeds or the wrench from the motor controllers. Each arrives
//! with its own latency. A few milliseconds between them show up in a diagnosis as a lag that
//! is not there, or hide one that is. Three of them measure a quantity that the pose also
//! gives, so their offset against the pose follows from the data alone:
//!
//! | sensor | its quantity | the same quantity from the pose |
//! |---|---|---|
//! | [`Sensor::Gyro`] | body angular velocity `ω` | `vee(Rᵀ Ṙ)` from the attitude |
//! | [`Sensor::Accelerometer`] | world acceleration `p̈` | `p̈` from the position |
//! | [`Sensor::Velocity`] | world velocity `v` | `ṗ` from the position |
//!
//! (Derivatives by the centred Savitzky–Golay filter of [`crate::deriv`]: symmetric, so it
//! shifts nothing in time.) [`Sensor::Actuators`] has no kinematic twin: its offset needs the
//! model, and the diagnosis estimates it as its `time-delay` effect. [`shift`] applies a known
//! offset to any stream, [`Sensor::Pose`] (position and attitude) included.
//!
//! **Estimate.** For a lag of `k` samples the cost is the variance of `x(tᵢ) − y(tᵢ₋ₖ)` over
//! the samples where both exist. It is the variance, not the mean square, so that a sensor bias
//! does not pull the estimate. The best whole lag in `±max_delay` is refined between samples by
//! the parabola through its neighbours. A delay `d > 0` means the sensor is **late**: its sample
//! at `t` shows the motion at `t − d`. The 95 % confidence interval comes from the spread of the
//! same estimate on [`BLOCKS`] consecutive blocks of the log (Student's `t` with `BLOCKS − 1`
//! degrees of freedom). It holds for coloured noise, where a formula for white noise would not.
//! The rule is in `docs/CONVENTIONS.md` §7.2.

use std::borrow::Cow;
use std::cell::OnceCell;

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3, savitzky_golay_derivatives};
use crate::log::{FlightLog, LogError, Sampling};

/// The largest offset searched by default \[s\]: 100 ms, beyond the latency of any
/// motion-capture system, IMU driver or telemetry link of a small robot.
pub const DEFAULT_MAX_DELAY: f64 = 0.1;

/// Number of consecutive blocks whose estimates give the confidence interval.
pub const BLOCKS: usize = 8;

/// Two-sided 95 % quantile of Student's `t` with `BLOCKS − 1 = 7` degrees of freedom.
const T_975_7: f64 = 2.364_624_251_592_785;

/// Samples left out at each end of the log and of each segment between gaps \[samples\]: two
/// filter half-widths, where the derivatives' windows reach past the data and the twins are
/// not comparable.
const FILTER_EDGE: usize = 2 * DEFAULT_HALF_WIDTH;

/// Fewest samples per block: a block must hold the lag window several times over.
const MIN_BLOCK_SAMPLES: usize = 50;

/// A stream of a flight log whose clock can be offset against the pose's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum Sensor {
    /// The rate gyro: `omega` and, if logged, `omega_dot`.
    Gyro,
    /// The accelerometer: the logged acceleration `accel`.
    Accelerometer,
    /// The logged velocity (a state estimator's or a differentiating filter's).
    Velocity,
    /// The actuator stream: the wrench and, if logged, the rotor speeds. Its offset is
    /// estimated by the diagnosis (`time-delay`), not here.
    Actuators,
    /// The pose: position and attitude (a motion-capture system's stream), the reference the
    /// others are timed against.
    Pose,
}

impl Sensor {
    /// Every stream, in the order of the table above.
    pub const ALL: [Sensor; 5] = [
        Sensor::Gyro,
        Sensor::Accelerometer,
        Sensor::Velocity,
        Sensor::Actuators,
        Sensor::Pose,
    ];

    /// The streams whose offset [`estimate_delay`] measures.
    pub const MEASURABLE: [Sensor; 3] = [Sensor::Gyro, Sensor::Accelerometer, Sensor::Velocity];

    /// The name used on the command line and in reports (`gyro`, `accelerometer`, `velocity`,
    /// `actuators`, `pose`).
    pub fn name(self) -> &'static str {
        match self {
            Sensor::Gyro => "gyro",
            Sensor::Accelerometer => "accelerometer",
            Sensor::Velocity => "velocity",
            Sensor::Actuators => "actuators",
            Sensor::Pose => "pose",
        }
    }

    /// The sensor of a name (ASCII case-insensitive; `imu` reads as `gyro`, `accel` as
    /// `accelerometer`, `wrench` and `motors` as `actuators`, `mocap` and `motion-capture` as
    /// `pose`).
    pub fn from_name(name: &str) -> Option<Sensor> {
        match name.trim().to_ascii_lowercase().as_str() {
            "gyro" | "imu" => Some(Sensor::Gyro),
            "accelerometer" | "accel" => Some(Sensor::Accelerometer),
            "velocity" => Some(Sensor::Velocity),
            "actuators" | "wrench" | "motors" => Some(Sensor::Actuators),
            "pose" | "mocap" | "motion-capture" => Some(Sensor::Pose),
            _ => None,
        }
    }

    /// What the pose side of the comparison is (for reports).
    pub fn reference(self) -> &'static str {
        match self {
            Sensor::Gyro => "angular velocity from the attitude",
            Sensor::Accelerometer => "acceleration from the position",
            Sensor::Velocity => "velocity from the position",
            Sensor::Actuators => "the model (the diagnosis' time-delay effect)",
            Sensor::Pose => "the IMU's clock (through the gyro)",
        }
    }
}

impl std::fmt::Display for Sensor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why an offset could not be measured or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AlignmentError {
    /// The log does not carry the sensor's quantity.
    #[error("the log has no {0} data")]
    NotLogged(Sensor),
    /// The sensor has no kinematic twin in the pose.
    #[error(
        "the offset of the {0} stream needs the model: the diagnosis estimates it (effect `time-delay`)"
    )]
    NeedsModel(Sensor),
    /// Too few samples for the block estimate.
    #[error("{samples} samples are too few to measure a {sensor} offset (at least {needed})")]
    TooShort {
        /// The sensor.
        sensor: Sensor,
        /// Samples in the log.
        samples: usize,
        /// Samples needed.
        needed: usize,
    },
    /// The best offset lies at the end of the searched range, or the cost has no minimum
    /// (a sensor that does not follow the motion, or a motion too slow to time it).
    #[error(
        "no {sensor} offset within ±{max_delay} s: the comparison with the {} has no minimum inside the range",
        sensor.reference()
    )]
    NoMinimum {
        /// The sensor.
        sensor: Sensor,
        /// The searched range \[s\].
        max_delay: f64,
    },
    /// A shift that is not a finite number of seconds, or longer than the log.
    #[error("cannot shift the {sensor} stream by {delay} s: {reason}")]
    BadShift {
        /// The sensor.
        sensor: Sensor,
        /// The requested shift \[s\].
        delay: f64,
        /// Why.
        reason: String,
    },
    /// The shifted log failed validation.
    #[error(transparent)]
    Log(#[from] LogError),
}

/// A measured offset of one sensor stream against the pose.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DelayEstimate {
    /// The sensor.
    pub sensor: Sensor,
    /// Delay \[s\]; positive: the sensor is late (its sample at `t` shows the motion at
    /// `t − delay`).
    pub delay: f64,
    /// 95 % confidence interval of the delay \[s\] (from [`BLOCKS`] blocks).
    pub confidence_interval: (f64, f64),
    /// Median sampling period of the log \[s\].
    pub sample_period: f64,
}

impl DelayEstimate {
    /// `true` when the confidence interval excludes zero and the delay is at least half a
    /// sampling period: a real offset, large enough that removing it changes the samples.
    pub fn significant(&self) -> bool {
        let (lo, hi) = self.confidence_interval;
        (lo > 0.0 || hi < 0.0) && self.delay.abs() >= 0.5 * self.sample_period
    }
}

/// A sensor's signal (borrowed from the log) and its twin from the pose, sample by sample
/// (borrowed when [`Shared`] keeps it).
type SignalPair<'a> = (&'a [[f64; 3]], Cow<'a, [[f64; 3]]>);

/// What the estimates of several sensors on one log share, each part computed on first use:
/// the median step with each sample's segment, and the velocity from the position (the
/// accelerometer's twin and the velocity's twin both start from it).
struct Shared<'a> {
    log: &'a FlightLog,
    /// The median step \[s\] and [`segment_ids`] with [`FILTER_EDGE`] left out.
    timing: OnceCell<(f64, Vec<Option<u32>>)>,
    /// `ṗ` from the position \[m/s\].
    velocity: OnceCell<Vec<[f64; 3]>>,
}

impl<'a> Shared<'a> {
    fn new(log: &'a FlightLog) -> Self {
        Self {
            log,
            timing: OnceCell::new(),
            velocity: OnceCell::new(),
        }
    }

    /// The median step \[s\] (a gap does not stretch it) and the segment of each sample,
    /// `None` within [`FILTER_EDGE`] samples of a segment's ends.
    fn timing(&self) -> (f64, &[Option<u32>]) {
        let (dt, seg) = self.timing.get_or_init(|| {
            let sampling = self.log.sampling();
            let seg = segment_ids(&sampling, self.log.len(), FILTER_EDGE);
            (sampling.median_step, seg)
        });
        (*dt, seg)
    }

    /// The velocity from the position \[m/s\].
    fn velocity(&self) -> &[[f64; 3]] {
        self.velocity.get_or_init(|| {
            savitzky_golay_derivative3(&self.log.t, &self.log.position, DEFAULT_HALF_WIDTH)
        })
    }
}

/// The sensor's signal and its twin from the pose.
fn pair<'s>(shared: &'s Shared<'_>, sensor: Sensor) -> Result<SignalPair<'s>, AlignmentError> {
    let log = shared.log;
    pair_available(log, sensor)?;
    let h = DEFAULT_HALF_WIDTH;
    Ok(match sensor {
        Sensor::Gyro => (
            &log.omega,
            Cow::Owned(omega_from_attitude(&log.t, &log.attitude)),
        ),
        Sensor::Accelerometer => {
            let v = shared.velocity();
            let accel = log
                .accel
                .as_deref()
                .ok_or(AlignmentError::NotLogged(sensor))?;
            (accel, Cow::Owned(savitzky_golay_derivative3(&log.t, v, h)))
        }
        Sensor::Velocity => (&log.velocity, Cow::Borrowed(shared.velocity())),
        Sensor::Actuators | Sensor::Pose => return Err(AlignmentError::NeedsModel(sensor)),
    })
}

/// Body angular velocity `vee(Rᵀ Ṙ)` from attitudes `(w, x, y, z)` (body → world), with `Ṙ`
/// by the Savitzky–Golay derivative of each entry of `R`.
pub fn omega_from_attitude(t: &[f64], attitude: &[[f64; 4]]) -> Vec<[f64; 3]> {
    let r: Vec<Matrix3<f64>> = attitude
        .iter()
        .map(|q| {
            UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
                .to_rotation_matrix()
                .into_inner()
        })
        .collect();
    // The nine entries' derivatives in one pass, entry (i, j) at 3 i + j.
    let n = t.len().min(r.len());
    let mut r_dot = savitzky_golay_derivatives(
        &t[..n],
        |k| std::array::from_fn(|e| r[k][(e / 3, e % 3)]),
        DEFAULT_HALF_WIDTH,
    );
    // Without a time for it, a sample's derivative is zero.
    r_dot.resize(r.len(), [0.0; 9]);
    r.iter()
        .zip(&r_dot)
        .map(|(r, rd)| {
            let rd = Matrix3::from_fn(|i, j| rd[3 * i + j]);
            let w = r.transpose() * rd;
            // The antisymmetric part: the derivative of a rotation is R [ω]×.
            let v = Vector3::new(
                w[(2, 1)] - w[(1, 2)],
                w[(0, 2)] - w[(2, 0)],
                w[(1, 0)] - w[(0, 1)],
            );
            [0.5 * v.x, 0.5 * v.y, 0.5 * v.z]
        })
        .collect()
}

/// The segment of each of the `n` samples between gaps (of `sampling`, the log's
/// [`FlightLog::sampling`]), `None` within `edge` samples of a segment's ends (where the
/// derivatives' windows reach past it).
fn segment_ids(sampling: &Sampling, n: usize, edge: usize) -> Vec<Option<u32>> {
    let mut out = vec![None; n];
    for (id, r) in sampling.segments().into_iter().enumerate() {
        if r.len() > 2 * edge {
            for v in &mut out[r.start + edge..r.end - edge] {
                *v = Some(id as u32);
            }
        }
    }
    out
}

/// Variance of `x(i) − y(i − k)` for every lag `k` in `−max_lag..=max_lag` (at index
/// `k + max_lag`). It runs over `i ∈ range` where `i − k` is a sample of the same segment
/// (`seg`): never across a gap, never at a segment's filtered edge. A lag without such a sample
/// gets infinity. One pass over the samples serves all lags. Each lag's sums add up its terms in
/// the order of `i`, as a pass per lag would.
fn lag_costs(
    x: &[[f64; 3]],
    y: &[[f64; 3]],
    seg: &[Option<u32>],
    max_lag: isize,
    range: std::ops::Range<usize>,
) -> Vec<f64> {
    // Per lag: the sum of each component's difference, the sum of squares, the count.
    let mut sums = vec![([0.0; 3], 0.0, 0usize); (2 * max_lag + 1) as usize];
    for i in range {
        if seg[i].is_none() {
            continue;
        }
        for ((sum, sq, count), k) in sums.iter_mut().zip(-max_lag..=max_lag) {
            let j = i as isize - k;
            if j < 0 || j as usize >= y.len() || seg[i] != seg[j as usize] {
                continue;
            }
            for c in 0..3 {
                let e = x[i][c] - y[j as usize][c];
                sum[c] += e;
                *sq += e * e;
            }
            *count += 1;
        }
    }
    sums.iter()
        .map(|(sum, sq, count)| {
            if *count == 0 {
                return f64::INFINITY;
            }
            let n = *count as f64;
            sq / n - sum.iter().map(|s| (s / n) * (s / n)).sum::<f64>()
        })
        .collect()
}

/// Best lag in samples (whole lag refined by a parabola), or `None` at the edge of `±max_lag`
/// or without a proper minimum.
fn best_lag(
    x: &[[f64; 3]],
    y: &[[f64; 3]],
    seg: &[Option<u32>],
    max_lag: isize,
    range: std::ops::Range<usize>,
) -> Option<f64> {
    let costs = lag_costs(x, y, seg, max_lag, range);
    let (best, _) = costs
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    if best == 0 || best + 1 == costs.len() {
        return None;
    }
    let (lo, mid, hi) = (costs[best - 1], costs[best], costs[best + 1]);
    let curvature = lo - 2.0 * mid + hi;
    if curvature <= 0.0 || !curvature.is_finite() {
        return None;
    }
    let offset = (0.5 * (lo - hi) / curvature).clamp(-0.5, 0.5);
    Some(best as f64 - max_lag as f64 + offset)
}

/// Measures the offset of one sensor stream against the pose, searching `±max_delay` \[s\].
///
/// # Errors
/// - [`AlignmentError::NotLogged`] when the log lacks the quantity.
/// - [`AlignmentError::NeedsModel`] for [`Sensor::Actuators`].
/// - [`AlignmentError::TooShort`] for fewer than `BLOCKS × 50` samples.
/// - [`AlignmentError::NoMinimum`] when the whole log's cost has no minimum inside the range.
/// - [`AlignmentError::BadShift`] for a `max_delay` that is not a positive finite number of
///   seconds.
pub fn estimate_delay(
    log: &FlightLog,
    sensor: Sensor,
    max_delay: f64,
) -> Result<DelayEstimate, AlignmentError> {
    estimate_delay_shared(&Shared::new(log), sensor, max_delay)
}

/// [`estimate_delay`] with what the sensors of one log share computed once.
fn estimate_delay_shared(
    shared: &Shared<'_>,
    sensor: Sensor,
    max_delay: f64,
) -> Result<DelayEstimate, AlignmentError> {
    if !(max_delay.is_finite() && max_delay > 0.0) {
        return Err(AlignmentError::BadShift {
            sensor,
            delay: max_delay,
            reason: "the searched range must be a positive number of seconds".into(),
        });
    }
    let (x, y) = pair(shared, sensor)?;
    let n = x.len();
    let needed = BLOCKS * MIN_BLOCK_SAMPLES;
    if n < needed || n < 2 {
        return Err(AlignmentError::TooShort {
            sensor,
            samples: n,
            needed,
        });
    }
    // The median step: a gap does not stretch it.
    let (dt, seg) = shared.timing();
    let max_lag = ((max_delay / dt).ceil() as isize).max(2);
    // The filters' edges (of the log and of each segment between gaps) are not comparable.
    let edge = FILTER_EDGE;
    let inner = edge..n.saturating_sub(edge);
    let no_minimum = AlignmentError::NoMinimum { sensor, max_delay };
    let whole = best_lag(x, &y, seg, max_lag, inner.clone()).ok_or(no_minimum.clone())?;
    let block = inner.len() / BLOCKS;
    let blocks: Vec<f64> = (0..BLOCKS)
        .filter_map(|b| {
            let start = inner.start + b * block;
            best_lag(x, &y, seg, max_lag, start..start + block)
        })
        .collect();
    let half_width = if blocks.len() == BLOCKS {
        let mean = blocks.iter().sum::<f64>() / BLOCKS as f64;
        let var = blocks.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / (BLOCKS - 1) as f64;
        T_975_7 * (var / BLOCKS as f64).sqrt()
    } else {
        // A block without a minimum: the offset is not resolved to better than the range.
        max_lag as f64
    };
    let delay = whole * dt;
    // Never tighter than the resolution of the sub-sample refinement (a tenth of a sample).
    let half_width = (half_width * dt).max(0.1 * dt);
    Ok(DelayEstimate {
        sensor,
        delay,
        confidence_interval: (delay - half_width, delay + half_width),
        sample_period: dt,
    })
}

/// Every offset [`estimate_delay`] can measure on this log (the sensors it carries), each
/// with its result.
pub fn estimate_delays(
    log: &FlightLog,
    max_delay: f64,
) -> Vec<(Sensor, Result<DelayEstimate, AlignmentError>)> {
    let shared = Shared::new(log);
    Sensor::MEASURABLE
        .into_iter()
        .filter(|s| !matches!(pair_available(log, *s), Err(AlignmentError::NotLogged(_))))
        .map(|s| (s, estimate_delay_shared(&shared, s, max_delay)))
        .collect()
}

/// Whether the log carries the sensor's quantity (cheap: no derivative computed).
fn pair_available(log: &FlightLog, sensor: Sensor) -> Result<(), AlignmentError> {
    let ok = match sensor {
        Sensor::Gyro => {
            log.omega.len() == log.len() && log.attitude.len() == log.len() && !log.is_empty()
        }
        Sensor::Accelerometer => log.accel.is_some(),
        Sensor::Velocity => log.velocity.len() == log.len() && !log.is_empty(),
        Sensor::Actuators | Sensor::Pose => return Err(AlignmentError::NeedsModel(sensor)),
    };
    if ok {
        Ok(())
    } else {
        Err(AlignmentError::NotLogged(sensor))
    }
}

/// Linear interpolation of `v` at the fractional index `q` (inside the samples).
fn lerp<const N: usize>(v: &[[f64; N]], q: f64) -> [f64; N] {
    let k = (q.floor() as usize).min(v.len() - 1);
    let f = q - k as f64;
    if f <= 0.0 || k + 1 >= v.len() {
        return v[k];
    }
    std::array::from_fn(|c| v[k][c] * (1.0 - f) + v[k + 1][c] * f)
}

/// Normalised linear interpolation of unit quaternions at the fractional index `q` (the
/// shorter way round).
fn nlerp(v: &[[f64; 4]], q: f64) -> [f64; 4] {
    let k = (q.floor() as usize).min(v.len() - 1);
    let f = q - k as f64;
    if f <= 0.0 || k + 1 >= v.len() {
        return v[k];
    }
    let (a, b) = (v[k], v[k + 1]);
    let sign = if a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() < 0.0 {
        -1.0
    } else {
        1.0
    };
    let m: [f64; 4] = std::array::from_fn(|c| a[c] * (1.0 - f) + sign * b[c] * f);
    let norm = m.iter().map(|x| x * x).sum::<f64>().sqrt();
    m.map(|x| x / norm)
}

/// Removes a sensor stream's delay: its quantities at `tᵢ` become its samples at `tᵢ + delay`
/// (linear interpolation between samples), every other column is kept. Rows whose
/// `tᵢ + delay` falls outside the log or inside a gap ([`FlightLog::sampling`]) are dropped,
/// so nothing is extrapolated or interpolated across a gap. A positive
/// `delay` undoes a late sensor (as [`DelayEstimate::delay`] reports it).
///
/// # Errors
/// [`AlignmentError::NotLogged`] when the log lacks the quantity, [`AlignmentError::BadShift`]
/// for a non-finite delay or one that leaves fewer than two rows, and the
/// [`FlightLog::validate`] errors of the result.
pub fn shift(log: &FlightLog, sensor: Sensor, delay: f64) -> Result<FlightLog, AlignmentError> {
    let bad = |reason: &str| AlignmentError::BadShift {
        sensor,
        delay,
        reason: reason.into(),
    };
    if !delay.is_finite() {
        return Err(bad("not a finite number of seconds"));
    }
    let available = match sensor {
        Sensor::Actuators => !log.wrench.is_empty() || log.rotor_speeds.is_some(),
        Sensor::Pose => !log.is_empty(),
        other => pair_available(log, other).is_ok(),
    };
    if !available {
        return Err(AlignmentError::NotLogged(sensor));
    }
    let n = log.len();
    let (t0, t1) = (log.t[0], log.t[n - 1]);
    let max_step = crate::log::GAP_FACTOR * log.sampling().median_step;
    // Fractional index of tᵢ + delay, by one monotone sweep.
    let mut keep = Vec::new();
    let mut at = Vec::new();
    let mut k = 0usize;
    for (i, &ti) in log.t.iter().enumerate() {
        let tq = ti + delay;
        if tq < t0 || tq > t1 {
            continue;
        }
        while k + 1 < n && log.t[k + 1] <= tq {
            k += 1;
        }
        let q = if k + 1 < n {
            if log.t[k + 1] - log.t[k] > max_step && tq > log.t[k] {
                // Inside a gap.
                continue;
            }
            k as f64 + (tq - log.t[k]) / (log.t[k + 1] - log.t[k])
        } else {
            k as f64
        };
        keep.push(i);
        at.push(q);
    }
    if keep.len() < 2 {
        return Err(bad("the shift is longer than the log"));
    }
    let pick = |v: &Vec<[f64; 3]>| -> Vec<[f64; 3]> { keep.iter().map(|&i| v[i]).collect() };
    let moved3 = |v: &Vec<[f64; 3]>| -> Vec<[f64; 3]> { at.iter().map(|&q| lerp(v, q)).collect() };
    let mut out = FlightLog {
        t: keep.iter().map(|&i| log.t[i]).collect(),
        position: pick(&log.position),
        velocity: pick(&log.velocity),
        attitude: keep.iter().map(|&i| log.attitude[i]).collect(),
        omega: pick(&log.omega),
        wrench: keep
            .iter()
            .filter_map(|&i| log.wrench.get(i).copied())
            .collect(),
        accel: log.accel.as_ref().map(pick),
        omega_dot: log.omega_dot.as_ref().map(pick),
        rotor_speeds: log
            .rotor_speeds
            .as_ref()
            .map(|w| keep.iter().map(|&i| w[i]).collect()),
        extra: log
            .extra
            .iter()
            .map(|(name, v)| (name.clone(), keep.iter().map(|&i| v[i]).collect()))
            .collect(),
    };
    match sensor {
        Sensor::Gyro => {
            out.omega = moved3(&log.omega);
            out.omega_dot = log.omega_dot.as_ref().map(moved3);
        }
        Sensor::Accelerometer => out.accel = log.accel.as_ref().map(moved3),
        Sensor::Velocity => out.velocity = moved3(&log.velocity),
        Sensor::Pose => {
            out.position = moved3(&log.position);
            out.attitude = at.iter().map(|&q| nlerp(&log.attitude, q)).collect();
        }
        Sensor::Actuators => {
            if !log.wrench.is_empty() {
                out.wrench = at.iter().map(|&q| lerp(&log.wrench, q)).collect();
            }
            out.rotor_speeds = log
                .rotor_speeds
                .as_ref()
                .map(|w| at.iter().map(|&q| lerp(w, q)).collect());
        }
    }
    out.validate()?;
    Ok(out)
}

#[cfg(test)]
// Sample-and-axis loops over parallel arrays read better with indices.
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    /// A log whose motion is a sum of sines (rich enough to time), sampled at `rate` \[Hz\]. The
    /// gyro, accelerometer and velocity are late by the given delays \[s\], exactly: the closed
    /// form is evaluated at `t − d`. White noise of σ `noise` is added to each.
    fn synthetic(rate: f64, seconds: f64, delays: [f64; 3], noise: f64, seed: u64) -> FlightLog {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut gauss = move || -> f64 {
            // Box–Muller.
            let u: f64 = rng.random::<f64>().max(1e-300);
            let v: f64 = rng.random();
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let freqs = [0.31, 0.73, 1.37];
        // Position, velocity, acceleration of p_c(t) = Σ a sin(2π f t + φ_c).
        let p = |t: f64, order: u32| -> [f64; 3] {
            std::array::from_fn(|c| {
                freqs
                    .iter()
                    .enumerate()
                    .map(|(j, f)| {
                        let w = std::f64::consts::TAU * f;
                        let phase = 0.7 * (c * 3 + j) as f64;
                        let a = 0.5 / (1.0 + j as f64);
                        let x = w * t + phase;
                        match order {
                            0 => a * x.sin(),
                            1 => a * w * x.cos(),
                            _ => -a * w * w * x.sin(),
                        }
                    })
                    .sum()
            })
        };
        // Attitude: yaw ψ(t) = 0.8 sin(2π 0.4 t) + 0.3 sin(2π 1.1 t) about z, roll φ(t) =
        // 0.2 sin(2π 0.9 t) about the yawed x: ω in the body.
        let angles = |t: f64| -> (f64, f64, f64, f64) {
            let (w1, w2, w3) = (
                std::f64::consts::TAU * 0.4,
                std::f64::consts::TAU * 1.1,
                std::f64::consts::TAU * 0.9,
            );
            (
                0.8 * (w1 * t).sin() + 0.3 * (w2 * t).sin(),
                0.8 * w1 * (w1 * t).cos() + 0.3 * w2 * (w2 * t).cos(),
                0.2 * (w3 * t).sin(),
                0.2 * w3 * (w3 * t).cos(),
            )
        };
        let rotation = |t: f64| {
            let (yaw, _, roll, _) = angles(t);
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
                * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll)
        };
        let omega_body = |t: f64| -> [f64; 3] {
            // R = Rz(ψ) Rx(φ): ω_body = Rx(φ)ᵀ (ψ̇ e_z) + φ̇ e_x.
            let (_, yaw_rate, roll, roll_rate) = angles(t);
            let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll);
            let w =
                rx.inverse() * Vector3::new(0.0, 0.0, yaw_rate) + Vector3::new(roll_rate, 0.0, 0.0);
            [w.x, w.y, w.z]
        };
        let n = (seconds * rate) as usize;
        let mut log = FlightLog::new();
        let mut accel = Vec::new();
        for i in 0..n {
            let t = i as f64 / rate;
            let q = rotation(t);
            let mut noisy = |v: [f64; 3]| v.map(|x| x + noise * gauss());
            log.t.push(t);
            log.position.push(p(t, 0));
            log.attitude.push([q.w, q.i, q.j, q.k]);
            log.omega.push(noisy(omega_body(t - delays[0])));
            accel.push(noisy(p(t - delays[1], 2)));
            log.velocity.push(noisy(p(t - delays[2], 1)));
            log.wrench.push([0.0, 0.0, 0.3, 0.0, 0.0, 0.0]);
        }
        log.accel = Some(accel);
        log
    }

    /// The cost of one lag as this module computed it before all lags shared one pass: the
    /// independent reference for [`lag_costs`].
    fn reference_lag_cost(
        x: &[[f64; 3]],
        y: &[[f64; 3]],
        seg: &[Option<u32>],
        k: isize,
        range: std::ops::Range<usize>,
    ) -> f64 {
        let (mut sum, mut sq, mut count) = ([0.0; 3], 0.0, 0usize);
        for i in range {
            let j = i as isize - k;
            if j < 0 || j as usize >= y.len() || seg[i].is_none() || seg[i] != seg[j as usize] {
                continue;
            }
            for c in 0..3 {
                let e = x[i][c] - y[j as usize][c];
                sum[c] += e;
                sq += e * e;
            }
            count += 1;
        }
        if count == 0 {
            return f64::INFINITY;
        }
        let n = count as f64;
        sq / n - sum.iter().map(|s| (s / n) * (s / n)).sum::<f64>()
    }

    #[test]
    fn one_pass_lag_costs_equal_a_pass_per_lag_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        let n = 400;
        let mut signal = || -> Vec<[f64; 3]> {
            (0..n)
                .map(|_| std::array::from_fn(|_| rng.random::<f64>() * 2.0 - 1.0))
                .collect()
        };
        let (x, y) = (signal(), signal());
        // Two segments with filtered edges, and a stretch that belongs to none.
        let seg: Vec<Option<u32>> = (0..n)
            .map(|i| match i {
                0..10 | 150..170 => None,
                10..150 => Some(0),
                _ => Some(1),
            })
            .collect();
        for max_lag in [2isize, 5, 30] {
            for range in [0..n, 5..n - 3, 140..180, 100..100, 0..4] {
                let costs = lag_costs(&x, &y[..n - 7], &seg, max_lag, range.clone());
                let reference: Vec<f64> = (-max_lag..=max_lag)
                    .map(|k| reference_lag_cost(&x, &y[..n - 7], &seg, k, range.clone()))
                    .collect();
                let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&costs),
                    bits(&reference),
                    "max_lag {max_lag}, {range:?}"
                );
            }
        }
    }

    #[test]
    fn attitude_rate_in_one_pass_equals_nine_derivatives_bit_for_bit() {
        let log = synthetic(100.0, 3.0, [0.0; 3], 0.01, 5);
        // The rate as computed before the nine entries shared their windows.
        let r: Vec<Matrix3<f64>> = log
            .attitude
            .iter()
            .map(|q| {
                UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
                    .to_rotation_matrix()
                    .into_inner()
            })
            .collect();
        let mut r_dot = vec![Matrix3::zeros(); r.len()];
        for i in 0..3 {
            for j in 0..3 {
                let entry: Vec<f64> = r.iter().map(|m| m[(i, j)]).collect();
                let d = crate::deriv::savitzky_golay_derivative(&log.t, &entry, DEFAULT_HALF_WIDTH);
                for (m, v) in r_dot.iter_mut().zip(d) {
                    m[(i, j)] = v;
                }
            }
        }
        let reference: Vec<[f64; 3]> = r
            .iter()
            .zip(&r_dot)
            .map(|(r, rd)| {
                let w = r.transpose() * rd;
                let v = Vector3::new(
                    w[(2, 1)] - w[(1, 2)],
                    w[(0, 2)] - w[(2, 0)],
                    w[(1, 0)] - w[(0, 1)],
                );
                [0.5 * v.x, 0.5 * v.y, 0.5 * v.z]
            })
            .collect();
        let bits = |v: &[[f64; 3]]| v.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&omega_from_attitude(&log.t, &log.attitude)),
            bits(&reference)
        );
    }

    #[test]
    fn attitude_rate_matches_the_closed_form() {
        // At 1 kHz the Savitzky–Golay derivative's truncation error on these tones is below
        // 1e-3 rad/s on rates up to 4 rad/s (it grows as (ω h Δt)²).
        let log = synthetic(1000.0, 10.0, [0.0; 3], 0.0, 1);
        let w = omega_from_attitude(&log.t, &log.attitude);
        for i in 20..log.len() - 20 {
            for c in 0..3 {
                assert!(
                    (w[i][c] - log.omega[i][c]).abs() < 2e-3,
                    "sample {i} axis {c}: {} vs {}",
                    w[i][c],
                    log.omega[i][c]
                );
            }
        }
    }

    #[test]
    fn known_delays_are_recovered_with_honest_intervals() {
        // 12 ms gyro, −7 ms accelerometer, 23 ms velocity at 200 Hz: sub-sample delays.
        let truth = [0.012, -0.007, 0.023];
        for seed in 0..5 {
            let log = synthetic(200.0, 30.0, truth, 0.02, seed);
            for (k, sensor) in Sensor::MEASURABLE.into_iter().enumerate() {
                let e = estimate_delay(&log, sensor, DEFAULT_MAX_DELAY).unwrap();
                assert!(
                    (e.delay - truth[k]).abs() < 1.5e-3,
                    "{sensor}: {} vs {}",
                    e.delay,
                    truth[k]
                );
                let (lo, hi) = e.confidence_interval;
                assert!(lo < hi && hi - lo < 0.01, "{sensor}: {lo}..{hi}");
                assert!(e.significant(), "{sensor}: {e:?}");
            }
        }
    }

    #[test]
    fn aligned_streams_are_not_significant() {
        let log = synthetic(100.0, 30.0, [0.0; 3], 0.02, 7);
        for (sensor, e) in estimate_delays(&log, DEFAULT_MAX_DELAY) {
            let e = e.unwrap();
            assert!(!e.significant(), "{sensor}: {e:?}");
            assert!(e.delay.abs() < 1e-3, "{sensor}: {e:?}");
        }
    }

    #[test]
    fn shifting_by_the_estimate_removes_the_delay() {
        let log = synthetic(200.0, 30.0, [0.015, 0.0, 0.0], 0.0, 3);
        let e = estimate_delay(&log, Sensor::Gyro, DEFAULT_MAX_DELAY).unwrap();
        assert!((e.delay - 0.015).abs() < 1e-3, "{e:?}");
        let aligned = shift(&log, Sensor::Gyro, e.delay).unwrap();
        // Rows whose t + d lies past the end are gone; nothing else moved.
        assert!(aligned.len() < log.len() && aligned.len() + 5 > log.len());
        assert_eq!(aligned.position[10], log.position[10]);
        let again = estimate_delay(&aligned, Sensor::Gyro, DEFAULT_MAX_DELAY).unwrap();
        assert!(again.delay.abs() < 5e-4, "{again:?}");
        assert!(!again.significant(), "{again:?}");
    }

    #[test]
    fn a_whole_sample_shift_moves_the_samples_exactly() {
        let log = synthetic(100.0, 5.0, [0.0; 3], 0.01, 4);
        let out = shift(&log, Sensor::Velocity, 0.03).unwrap();
        assert_eq!(out.len(), log.len() - 3);
        for i in 0..out.len() {
            for c in 0..3 {
                assert!((out.velocity[i][c] - log.velocity[i + 3][c]).abs() < 1e-12);
            }
            assert_eq!(out.omega[i], log.omega[i]);
        }
        let back = shift(&log, Sensor::Velocity, -0.03).unwrap();
        assert_eq!(back.t[0], log.t[3]);
    }

    #[test]
    fn a_gap_neither_stretches_the_period_nor_is_bridged() {
        // 24 s at 200 Hz with 4 s cut out of the middle; the gyro 10 ms late.
        let full = synthetic(200.0, 24.0, [0.01, 0.0, 0.0], 0.01, 9);
        let mut log = full.slice(0..0);
        for i in (0..full.len()).filter(|i| !(2000..2800).contains(i)) {
            log.push(&full.sample(i).unwrap());
        }
        let e = estimate_delay(&log, Sensor::Gyro, DEFAULT_MAX_DELAY).unwrap();
        assert!((e.sample_period - 0.005).abs() < 1e-9, "{e:?}");
        assert!((e.delay - 0.01).abs() < 1e-3, "{e:?}");
        // A shift drops the rows whose source time falls into the gap; it interpolates
        // nothing across it.
        let out = shift(&log, Sensor::Gyro, 0.012).unwrap();
        assert!(out.len() + 4 < log.len(), "{} of {}", out.len(), log.len());
        let after = out.t.iter().position(|&t| t > 9.995 + 1e-9).unwrap();
        assert!(out.t[after] >= 14.0 - 1e-9, "{}", out.t[after]);
        assert!(out.t[after - 1] < 9.995 - 0.01, "{}", out.t[after - 1]);
    }

    #[test]
    fn bad_requests_are_typed_errors() {
        let log = synthetic(100.0, 5.0, [0.0; 3], 0.01, 5);
        for s in [Sensor::Actuators, Sensor::Pose] {
            assert!(matches!(
                estimate_delay(&log, s, 0.1),
                Err(AlignmentError::NeedsModel(_))
            ));
        }
        // Moving the pose and the gyro by the same offset keeps them in step.
        let both = shift(
            &shift(&log, Sensor::Pose, 0.02).unwrap(),
            Sensor::Gyro,
            0.02,
        )
        .unwrap();
        let e = estimate_delay(&both, Sensor::Gyro, 0.1).unwrap();
        assert!(e.delay.abs() < 1e-3 && !e.significant(), "{e:?}");
        let pose_only = shift(&log, Sensor::Pose, 0.02).unwrap();
        let e = estimate_delay(&pose_only, Sensor::Gyro, 0.1).unwrap();
        assert!((e.delay - 0.02).abs() < 1e-3, "{e:?}");
        assert!(matches!(
            estimate_delay(&log, Sensor::Gyro, f64::NAN),
            Err(AlignmentError::BadShift { .. })
        ));
        assert!(matches!(
            shift(&log, Sensor::Gyro, 10.0),
            Err(AlignmentError::BadShift { .. })
        ));
        assert!(matches!(
            shift(&log, Sensor::Gyro, f64::INFINITY),
            Err(AlignmentError::BadShift { .. })
        ));
        let short = synthetic(100.0, 1.0, [0.0; 3], 0.01, 5);
        assert!(matches!(
            estimate_delay(&short, Sensor::Gyro, 0.1),
            Err(AlignmentError::TooShort { .. })
        ));
        let mut no_accel = log.clone();
        no_accel.accel = None;
        assert!(matches!(
            estimate_delay(&no_accel, Sensor::Accelerometer, 0.1),
            Err(AlignmentError::NotLogged(_))
        ));
        assert_eq!(estimate_delays(&no_accel, 0.1).len(), 2);
        for s in Sensor::ALL {
            assert_eq!(Sensor::from_name(s.name()), Some(s));
        }
        assert_eq!(Sensor::from_name("IMU"), Some(Sensor::Gyro));
        assert_eq!(Sensor::from_name("lidar"), None);
    }
}
