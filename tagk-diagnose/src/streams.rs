//! Time delay per stream: before the model is fitted, each sensor stream that has a twin in the
//! pose (gyro, accelerometer, velocity) is timed against it without any model
//! ([`tagk_dynamics::alignment`]), and a significant offset is removed; the actuator stream's
//! offset needs the model and is the `time-delay` effect of the staircase. The rule is in
//! `docs/CONVENTIONS.md` §7.2.

use serde::Serialize;
use tagk_dynamics::alignment::{self, AlignmentError, DEFAULT_MAX_DELAY, DelayEstimate, Sensor};

use crate::error::DiagnoseError;
use crate::log::FlightLog;

/// How [`align_streams`] treats the streams of a log.
#[derive(Debug, Clone, PartialEq)]
pub struct AlignOptions {
    /// Remove every significant measured offset ([`DelayEstimate::significant`]), and the
    /// accelerometer's vertical offset against the velocity ([`crate::accel_offset`]): on by
    /// default. Off: measure and report only.
    pub auto: bool,
    /// Offsets given by the user \[s\] (positive: the sensor is late), applied as given and
    /// not measured; they take precedence over `auto` for their sensor.
    pub shifts: Vec<(Sensor, f64)>,
    /// The largest offset searched \[s\].
    pub max_delay: f64,
}

impl Default for AlignOptions {
    fn default() -> Self {
        Self {
            auto: true,
            shifts: Vec::new(),
            max_delay: DEFAULT_MAX_DELAY,
        }
    }
}

/// What was measured and done for one sensor stream of one log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StreamAlignment {
    /// The log (its file), for a diagnosis of several logs; empty for one.
    pub log: String,
    /// The sensor (`gyro`, `accelerometer`, `velocity`, `actuators`).
    pub sensor: Sensor,
    /// What it was timed against.
    pub reference: String,
    /// The measured offset, if it could be measured.
    pub estimate: Option<DelayEstimate>,
    /// Why it could not be measured (empty when it was, or when the offset was given).
    pub note: String,
    /// The offset removed \[s\] (0 when nothing was done).
    pub applied: f64,
    /// `"measured"` (removed because significant), `"given"` (`--shift`), or `"none"`.
    pub action: &'static str,
    /// Why the shifts given contradict this stream's measured offset (empty when they do
    /// not, or when nothing was given): [`shift_contradiction`].
    pub warning: String,
}

/// Whether the shifts given leave a stream off its measured offset: the offset they assume
/// against the pose, `given − given_pose` \[s\], lies outside the measured 95 % interval
/// widened by half a sampling period (what a shift can resolve). Returns the warning.
pub fn shift_contradiction(
    sensor: Sensor,
    estimate: &DelayEstimate,
    assumed: f64,
) -> Option<String> {
    let (lo, hi) = estimate.confidence_interval;
    let slack = 0.5 * estimate.sample_period;
    (assumed < lo - slack || assumed > hi + slack).then(|| {
        format!(
            "the shifts given assume the {} {:+.1} ms against the pose, but it measures {:+.1} ms \
             [{:+.1}, {:+.1}]: a wrong sign or stream in --shift?",
            sensor.name(),
            1e3 * assumed,
            1e3 * estimate.delay,
            1e3 * lo,
            1e3 * hi
        )
    })
}

/// Parses `SENSOR=SECONDS` (`gyro=0.012`): a `--shift` argument.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (field `shift`) naming the unknown sensor or the bad
/// number.
pub fn parse_shift(spec: &str) -> Result<(Sensor, f64), DiagnoseError> {
    let bad = |reason: String| DiagnoseError::InvalidOption {
        field: "shift",
        reason,
    };
    let (name, value) = spec
        .split_once('=')
        .ok_or_else(|| bad(format!("`{spec}` is not SENSOR=SECONDS (e.g. gyro=0.012)")))?;
    let sensor = Sensor::from_name(name).ok_or_else(|| {
        bad(format!(
            "unknown stream `{}` (known: {})",
            name.trim(),
            Sensor::ALL.map(Sensor::name).join(", ")
        ))
    })?;
    let delay: f64 = value
        .trim()
        .parse()
        .ok()
        .filter(|d: &f64| d.is_finite())
        .ok_or_else(|| {
            bad(format!(
                "`{}` is not a finite number of seconds",
                value.trim()
            ))
        })?;
    Ok((sensor, delay))
}

fn alignment_error(e: AlignmentError) -> DiagnoseError {
    match e {
        AlignmentError::Log(l) => DiagnoseError::Log(l),
        other => DiagnoseError::InvalidOption {
            field: "shift",
            reason: other.to_string(),
        },
    }
}

/// Times each sensor stream of `log` against the pose and aligns them, `docs/CONVENTIONS.md`
/// §7.2: with `shifts`, exactly the given offsets and nothing else; otherwise, with `auto`,
/// the IMU is the clock — a significant gyro offset moves the pose (position and attitude)
/// onto it, and the velocity follows the pose plus its own significant offset. The
/// accelerometer is never moved automatically: with the actuators it forms the two sides of
/// the regression, whose offset is the staircase's `time-delay`, and a logged acceleration
/// that is an interval mean sits half a sample behind an instantaneous pose by construction.
/// Returns the aligned log and one entry per stream measured or moved.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] (field `shift`) for a given shift the log cannot take (a
/// sensor it does not carry, longer than the log, a sensor given twice) or a `max_delay` that
/// is not a positive number of seconds; the log's validation errors.
pub fn align_streams(
    log: &FlightLog,
    options: &AlignOptions,
) -> Result<(FlightLog, Vec<StreamAlignment>), DiagnoseError> {
    align(std::borrow::Cow::Borrowed(log), options)
}

/// [`align_streams`] of a log it may consume: a log whose streams stay where they are is
/// returned as it is instead of copied (one copy of a long log less in memory).
///
/// # Errors
/// As [`align_streams`].
pub fn align_streams_owned(
    log: FlightLog,
    options: &AlignOptions,
) -> Result<(FlightLog, Vec<StreamAlignment>), DiagnoseError> {
    align(std::borrow::Cow::Owned(log), options)
}

/// [`align_streams`] of a borrowed or owned log.
fn align(
    log: std::borrow::Cow<'_, FlightLog>,
    options: &AlignOptions,
) -> Result<(FlightLog, Vec<StreamAlignment>), DiagnoseError> {
    if !(options.max_delay.is_finite() && options.max_delay > 0.0) {
        return Err(DiagnoseError::InvalidOption {
            field: "max_delay",
            reason: format!("{} is not a positive number of seconds", options.max_delay),
        });
    }
    for (k, (sensor, _)) in options.shifts.iter().enumerate() {
        if options.shifts[..k].iter().any(|(s, _)| s == sensor) {
            return Err(DiagnoseError::InvalidOption {
                field: "shift",
                reason: format!("the {sensor} stream is shifted twice"),
            });
        }
    }
    let entry = |sensor: Sensor| StreamAlignment {
        log: String::new(),
        sensor,
        reference: sensor.reference().to_string(),
        estimate: None,
        note: String::new(),
        applied: 0.0,
        action: "none",
        warning: String::new(),
    };
    // The shifted log, once a stream moves (`None`: the log as given).
    let mut out: Option<FlightLog> = None;
    let mut entries = Vec::new();
    for (sensor, delay) in &options.shifts {
        let from = out.as_ref().unwrap_or(&log);
        out = Some(alignment::shift(from, *sensor, *delay).map_err(alignment_error)?);
        entries.push(StreamAlignment {
            applied: *delay,
            action: "given",
            ..entry(*sensor)
        });
    }
    let auto = options.auto && options.shifts.is_empty();
    // Measured on the log as given.
    let mut significant = |sensor: Sensor, result: Result<DelayEstimate, AlignmentError>| {
        let mut e = entry(sensor);
        let d = match result {
            Ok(estimate) => {
                let d = estimate.significant().then_some(estimate.delay);
                e.estimate = Some(estimate);
                d
            }
            Err(err) => {
                e.note = err.to_string();
                None
            }
        };
        if !options.shifts.iter().any(|(s, _)| *s == sensor) {
            entries.push(e);
        }
        d
    };
    let mut offsets = [None; 3];
    let mut measured: Vec<DelayEstimate> = Vec::new();
    for (sensor, result) in alignment::estimate_delays(&log, options.max_delay) {
        if let Ok(estimate) = &result {
            measured.push(estimate.clone());
        }
        let d = significant(sensor, result);
        match sensor {
            Sensor::Gyro => offsets[0] = d,
            Sensor::Velocity => offsets[2] = d,
            _ => offsets[1] = d,
        }
    }
    // With shifts given: each measured stream against what they assume of it.
    if !options.shifts.is_empty() {
        let given = |sensor: Sensor| {
            options
                .shifts
                .iter()
                .find(|(s, _)| *s == sensor)
                .map(|(_, d)| *d)
        };
        let pose = given(Sensor::Pose).unwrap_or(0.0);
        for estimate in &measured {
            let own = given(estimate.sensor);
            if own.is_none() && pose == 0.0 {
                continue;
            }
            let assumed = own.unwrap_or(0.0) - pose;
            if let Some(w) = shift_contradiction(estimate.sensor, estimate, assumed) {
                // On the stream's entry, or on the pose's when only the pose was shifted.
                let on = if own.is_some() {
                    estimate.sensor
                } else {
                    Sensor::Pose
                };
                if let Some(e) = entries.iter_mut().find(|e| e.sensor == on) {
                    if !e.warning.is_empty() {
                        e.warning.push_str("; ");
                    }
                    e.warning.push_str(&w);
                }
            }
        }
    }
    if auto {
        let pose = offsets[0].unwrap_or(0.0);
        if pose != 0.0 {
            // The pose sample at t shows the motion of t + d on the gyro's clock: re-read it at
            // t − d.
            let from = out.as_ref().unwrap_or(&log);
            out = Some(alignment::shift(from, Sensor::Pose, -pose).map_err(alignment_error)?);
            entries.push(StreamAlignment {
                applied: -pose,
                action: "measured",
                ..entry(Sensor::Pose)
            });
        }
        let velocity = offsets[2].unwrap_or(0.0) - pose;
        if velocity != 0.0 {
            let from = out.as_ref().unwrap_or(&log);
            out =
                Some(alignment::shift(from, Sensor::Velocity, velocity).map_err(alignment_error)?);
            if let Some(v) = entries.iter_mut().find(|e| e.sensor == Sensor::Velocity) {
                v.applied = velocity;
                v.action = "measured";
            }
        }
    }
    let out = match out {
        Some(shifted) => shifted,
        None => log.into_owned(),
    };
    Ok((out, entries))
}

/// The stream timing in a few lines for the terminal: one line per stream.
pub fn streams_table(entries: &[StreamAlignment]) -> String {
    let mut s = String::from("=== stream timing (offset against the pose; + late) ===\n");
    for e in entries {
        let who = if e.log.is_empty() {
            e.sensor.name().to_string()
        } else {
            format!("{} ({})", e.sensor.name(), e.log)
        };
        let measured = e.estimate.as_ref().map(|d| {
            let (lo, hi) = d.confidence_interval;
            format!(
                "{:+.1} ms [{:+.1}, {:+.1}]",
                1e3 * d.delay,
                1e3 * lo,
                1e3 * hi
            )
        });
        let significant = e.estimate.as_ref().is_some_and(DelayEstimate::significant);
        let line = match (e.action, e.sensor) {
            ("given", _) => format!("moved by {:+.1} ms as given (--shift)", 1e3 * e.applied),
            ("measured", Sensor::Pose) => format!(
                "moved by {:+.1} ms onto the IMU's clock (the gyro's offset)",
                1e3 * e.applied
            ),
            ("measured", _) => format!(
                "{} → moved by {:+.1} ms (with the pose)",
                measured.unwrap_or_default(),
                1e3 * e.applied
            ),
            (_, Sensor::Gyro) if significant => format!(
                "{} → the pose is off the IMU's clock{}",
                measured.unwrap_or_default(),
                if entries.iter().any(|x| x.sensor == Sensor::Pose) {
                    ""
                } else {
                    " (kept: --no-align or --shift)"
                }
            ),
            (_, Sensor::Accelerometer) if significant => format!(
                "{} → kept (its offset against the actuators is `time-delay`'s)",
                measured.unwrap_or_default()
            ),
            (_, _) if significant => format!(
                "{} → kept (--no-align or --shift)",
                measured.unwrap_or_default()
            ),
            _ => match measured {
                Some(m) => format!("{m} → in step"),
                None => format!("not measured: {}", e.note),
            },
        };
        s.push_str(&format!("{who:<24} {line}\n"));
        if !e.warning.is_empty() {
            s.push_str(&format!("{:<24} warning: {}\n", "", e.warning));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_specs_parse_or_say_why() {
        assert_eq!(parse_shift("gyro=0.012").unwrap(), (Sensor::Gyro, 0.012));
        assert_eq!(
            parse_shift(" actuators = -0.03 ").unwrap(),
            (Sensor::Actuators, -0.03)
        );
        for bad in ["gyro", "lidar=0.1", "gyro=fast", "gyro=nan", "gyro=inf"] {
            let e = parse_shift(bad).unwrap_err().to_string();
            assert!(e.contains("shift"), "{bad}: {e}");
        }
    }
}
