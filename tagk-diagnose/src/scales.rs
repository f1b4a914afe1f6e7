//! Scale and consistency checks: do the log's signals agree with each other in *gain*, and
//! the fit with the vehicle file? A unit mistake (deg/s read as rad/s, mm/s as m/s, g as
//! m/s²), a flipped sign or swapped rotor spins gives a plausible but wrong answer; these
//! checks name it before the fit is believed (docs/CONVENTIONS.md §7.3).
//!
//! | check | compares | an error names |
//! |---|---|---|
//! | `gyro` | the gyro `ω` integrated over windows of [`GYRO_ROTATION_WINDOW`] with the attitude's rotation over them | deg/s ↔ rad/s (57.3), a flipped sign |
//! | `velocity` | the velocity with the position's derivative | mm/s, cm/s, km/h, ft/s ↔ m/s |
//! | `accelerometer` | the logged `p̈` with the velocity's derivative | g ↔ m/s² (9.81) |
//! | `specific-force` | the logged `p̈`'s mean on z with the velocity's change over the log, `Δv_z / T` (off by more than `g/2`) | the world-frame specific force in `ax..az` |
//! | `thrust` | the mass `fz` implies (`fz` on the proper acceleration `a_z`) with the known or vehicle mass | a thrust or mass in the wrong unit |
//! | `yaw-torque` | the fitted yaw inertia `I_zz`: negative by [`SIGN_Z`] standard errors with a wrench from the vehicle's rotors | rotor spins swapped |
//! | `mass` | the fitted mass with the vehicle file's | the accelerations' or the wrench's unit |
//! | `inertia` | the fitted `I_xx, I_yy, I_zz` with the vehicle file's | the gyro's unit, the arm length |
//!
//! **The gyro's gain** is measured on rotations, where its noise averages out
//! (`gyro_rotation_gain`). Over each window of [`GYRO_ROTATION_WINDOW`], the gyro integrated
//! in the window's first body frame is regressed on the rotation vector between the window's
//! two attitudes. Each is averaged over the windows shifted by up to
//! [`GYRO_ENDPOINT_SMOOTHING`]. The windows do not overlap (one independent value each). The
//! README's realistic example, whose gyro noise hid the attitude's rate from a comparison of
//! rates (correlation 0.24), gives a correlation of 0.99 this way.
//!
//! **The gain** of the other pairs. Both signals of a pair go through the same filters: the
//! derivative's Savitzky–Golay window, then a smoothing over [`COMPARISON_WINDOW`]. Then their
//! changes over half that window are compared (a bias or a slow drift cancels). They are pooled
//! over the axes and the segments between gaps, the filters' edges left out. Noise on the twin
//! biases the regression of the measured signal on it (`Sxy/Sxx`) low. Noise on the measured
//! signal biases the inverse regression (`Syy/Sxy`) high. The true gain lies between them,
//! each widened by its standard error. That is the residual's, with the samples counted per
//! smoothing window, as neighbouring filtered samples are not independent. A pair with little
//! motion or much noise has a wide bracket and is not judged. A fit's parameter is compared
//! through its standard error.
//!
//! **The verdicts.** With `z` = [`CHECK_Z`] standard errors:
//!
//! - an **error** when the gain's bracket (or a parameter's `± z·se`) lies wholly outside
//!   `[1/ERROR_FACTOR, ERROR_FACTOR]` (a factor of 2 and more: a unit, not a calibration) or
//!   below zero (a flipped sign);
//! - a **warning** when it lies wholly outside `[1/WARNING_FACTOR, WARNING_FACTOR]`.
//!
//! The inertia, less well determined by a flight, uses [`INERTIA_ERROR_FACTOR`] and the
//! warning at [`ERROR_FACTOR`]. An error stops the diagnosis ([`DiagnoseError::ScaleMismatch`])
//! unless accepted (`--accept-scales`, [`crate::DiagnosisPlan::accept_scales`]). It is then
//! reported like a warning.

use std::ops::Range;

use nalgebra::Vector3;
use serde::Serialize;
use tagk_dynamics::GRAVITY_WORLD;
use tagk_dynamics::log::accel_looks_like_specific_force;
use tagk_dynamics::vehicle::Vehicle;

use crate::deriv::{DEFAULT_HALF_WIDTH, savitzky_golay_derivative3, savitzky_golay_smooth};
use crate::error::DiagnoseError;
use crate::log::FlightLog;
use crate::report::Report;

/// Standard errors around a gain before it counts as off (two-sided 99.99 %).
pub const CHECK_Z: f64 = 3.89;

/// Standard errors by which a fitted yaw inertia must be negative for the rotor spins to be
/// named (as the centre-of-mass rule's 2: a negative inertia is no body at all).
pub const SIGN_Z: f64 = 2.0;

/// A gain off by this factor or more (either way) is an error: a unit, not a calibration.
pub const ERROR_FACTOR: f64 = 2.0;

/// A gain off by this factor or more (and less than [`ERROR_FACTOR`]) is a warning. Not
/// tighter: on the diagnosis benchmark's flights the gyro's gain against the attitude's
/// rate reaches 1.3 on valid logs (the attitude's derivative loses the fastest rotations).
pub const WARNING_FACTOR: f64 = 1.5;

/// The fitted inertia off the vehicle file's by this factor or more is an error (a warning
/// from [`ERROR_FACTOR`] on).
pub const INERTIA_ERROR_FACTOR: f64 = 4.0;

/// The window the gyro is integrated over and compared with the attitude's rotation \[s\].
/// The gyro's white noise averages out as `1/√T` against the rotation. A flight's rotation
/// over a second stays small enough for its rotation vector to be the integral.
pub const GYRO_ROTATION_WINDOW: f64 = 1.0;

/// The shifts each window of the gyro's rotation is averaged over, on each side \[s\].
pub const GYRO_ENDPOINT_SMOOTHING: f64 = 0.1;

/// The window both signals of a pair are smoothed over before they are compared \[s\]:
/// flight motion lies below a few hertz, white sensor noise is spread over the whole band.
pub const COMPARISON_WINDOW: f64 = 0.5;

/// The most samples the gain checks read, from the log's start: 100 000 (33 min at 50 Hz).
/// A unit does not change within a log, and more samples only narrow an interval that is
/// already narrow; a 1 000 000-row log would otherwise spend 1.2 s smoothing.
pub const MAX_SCALE_CHECK_SAMPLES: usize = 100_000;

/// Standard gravity \[m/s²\] (the `g` of an accelerometer in g).
const STANDARD_GRAVITY: f64 = 9.806_65;

/// How serious a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Severity {
    /// Off by a unit: the diagnosis stops unless the scales are accepted.
    Error,
    /// An error the user accepted (`--accept-scales`): reported, the diagnosis goes on.
    Accepted,
    /// Off by more than a calibration should be: reported.
    Warning,
}

/// One scale or consistency check that found something (module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScaleFinding {
    /// The log (its file; empty for a log in memory).
    pub log: String,
    /// The check: `gyro`, `velocity`, `accelerometer`, `specific-force`, `thrust`,
    /// `yaw-torque`, `mass`, `inertia`.
    pub check: String,
    /// The gain or ratio found (1 when consistent).
    pub ratio: f64,
    /// Its standard error, when it has one.
    pub std_error: Option<f64>,
    /// Error, accepted error or warning.
    pub severity: Severity,
    /// What was found and its likely cause, in plain words.
    pub message: String,
}

impl ScaleFinding {
    /// One line: `error (gyro): the gyro's rotation is 57.3× the attitude's: …`.
    pub fn text(&self) -> String {
        let severity = match self.severity {
            Severity::Error => "error",
            Severity::Accepted => "accepted",
            Severity::Warning => "warning",
        };
        let log = if self.log.is_empty() {
            String::new()
        } else {
            format!("{}: ", self.log)
        };
        format!("{log}{severity} ({}): {}", self.check, self.message)
    }
}

/// Known unit factors of a check: the factor and what it means.
type Causes = &'static [(f64, &'static str)];

const GYRO_CAUSES: Causes = &[
    (
        180.0 / std::f64::consts::PI,
        "deg/s mapped as rad/s? (give the gyro's unit in the mapping's [units])",
    ),
    (
        std::f64::consts::PI / 180.0,
        "rad/s mapped as deg/s? (check the gyro's unit in the mapping's [units])",
    ),
    (2.0 * std::f64::consts::PI / 60.0, "rpm mapped as rad/s?"),
];

const VELOCITY_CAUSES: Causes = &[
    (1000.0, "mm/s mapped as m/s?"),
    (100.0, "cm/s mapped as m/s?"),
    (0.001, "m/s mapped as mm/s?"),
    (0.01, "m/s mapped as cm/s?"),
    (3.6, "km/h mapped as m/s?"),
    (1.0 / 0.3048, "ft/s mapped as m/s?"),
    (0.3048, "m/s mapped as ft/s?"),
];

const ACCEL_CAUSES: Causes = &[
    (
        1.0 / STANDARD_GRAVITY,
        "an acceleration in g mapped as m/s²? (give its unit in the mapping's [units])",
    ),
    (STANDARD_GRAVITY, "m/s² mapped as g?"),
    (1000.0, "mm/s² mapped as m/s²?"),
];

const MASS_CAUSES: Causes = &[
    (
        STANDARD_GRAVITY,
        "accelerations in g taken as m/s², or a thrust in N read as kgf?",
    ),
    (
        1.0 / STANDARD_GRAVITY,
        "a thrust in kgf read as N, or accelerations in m/s² mapped as g?",
    ),
    (1000.0, "a thrust in mN or the mass in g?"),
    (
        0.001,
        "the mass in kg against a thrust in kN, or a vehicle mass in g?",
    ),
];

const INERTIA_CAUSES: Causes = &[
    (
        180.0 / std::f64::consts::PI,
        "a gyro in rad/s mapped as deg/s? (its angular accelerations shrink 57.3×)",
    ),
    (
        std::f64::consts::PI / 180.0,
        "a gyro in deg/s mapped as rad/s?",
    ),
];

/// The likely cause of a gain between `lo` and `hi` among `causes`: the factor within the
/// interval widened by 20 %, the closest to its geometric mean if several.
fn cause_in(lo: f64, hi: f64, causes: Causes) -> Option<&'static str> {
    let centre = (lo.max(f64::MIN_POSITIVE) * hi).sqrt();
    causes
        .iter()
        .filter(|(f, _)| *f >= lo / 1.2 && *f <= hi * 1.2)
        .min_by(|a, b| {
            (a.0 / centre)
                .ln()
                .abs()
                .total_cmp(&(b.0 / centre).ln().abs())
        })
        .map(|(_, c)| *c)
}

/// The likely cause of a ratio `g` among `causes` (within 20 % of a factor).
fn cause_of(g: f64, causes: Causes) -> Option<&'static str> {
    cause_in(g, g, causes)
}

/// A gain estimate of one pair: the bracket the true gain lies in.
#[derive(Debug, Clone, Copy)]
struct Gain {
    /// `Sxy / Sxx`: the measured signal regressed on its twin (right when the twin is the
    /// clean one).
    low: f64,
    /// Its standard error.
    low_se: f64,
    /// `Syy / Sxy`: the inverse of the twin regressed on the measured signal (right when
    /// the measured signal is the clean one).
    high: f64,
    /// Its standard error.
    high_se: f64,
    /// The correlation.
    rho: f64,
}

impl Gain {
    /// The gain reported: the geometric mean of the bracket's ends, signed.
    fn value(&self) -> f64 {
        self.rho.signum() * (self.low * self.high).abs().sqrt()
    }

    /// The bracket widened by [`CHECK_Z`] standard errors, ordered.
    fn interval(&self) -> (f64, f64) {
        let (a, b) = (
            self.low - CHECK_Z * self.low_se,
            self.low + CHECK_Z * self.low_se,
        );
        let (c, d) = (
            self.high - CHECK_Z * self.high_se,
            self.high + CHECK_Z * self.high_se,
        );
        (a.min(c), b.max(d))
    }

    /// A standard error for the report: the larger end's.
    fn se(&self) -> f64 {
        self.low_se.max(self.high_se)
    }
}

/// The gain of `measured` against `twin` (module docs), pooled over the axes of the samples
/// in `rows` (each a stretch of one segment); `width`: samples of the smoothing window.
fn gain(
    measured: &[[f64; 3]],
    twin: &[[f64; 3]],
    rows: &[Range<usize>],
    width: usize,
) -> Option<Gain> {
    // Changes over half a window: a bias or a slow drift of either signal cancels.
    let lag = width / 2;
    let (mut sxx, mut syy, mut sxy, mut n) = (0.0, 0.0, 0.0, 0usize);
    for r in rows {
        if r.len() < lag + 3 {
            continue;
        }
        for k in 0..3 {
            for i in r.start..r.end - lag {
                let x = twin[i + lag][k] - twin[i][k];
                let y = measured[i + lag][k] - measured[i][k];
                sxx += x * x;
                syy += y * y;
                sxy += x * y;
            }
        }
        n += 3 * (r.len() - lag);
    }
    gain_of(sxx, syy, sxy, n, width)
}

/// The [`Gain`] of the sums `Sxx`, `Syy`, `Sxy` over `n` values, `width` of which are one
/// independent value (module docs); `None` for fewer than `10 · width` values or no spread.
fn gain_of(sxx: f64, syy: f64, sxy: f64, n: usize, width: usize) -> Option<Gain> {
    let w = width as f64;
    if !(sxx > 0.0 && syy > 0.0 && sxy != 0.0 && (sxx * syy).is_finite()) || (n as f64) < 10.0 * w {
        return None;
    }
    let n = n as f64;
    let rho = sxy / (sxx * syy).sqrt();
    let low = sxy / sxx;
    let low_se = ((syy - low * sxy).max(0.0) / n / sxx * w).sqrt();
    let inv = sxy / syy;
    let inv_se = ((sxx - inv * sxy).max(0.0) / n / syy * w).sqrt();
    let high = 1.0 / inv;
    let high_se = inv_se / (inv * inv);
    Some(Gain {
        low,
        low_se,
        high,
        high_se,
        rho,
    })
}

/// The gain of the gyro against the attitude over windows of [`GYRO_ROTATION_WINDOW`]
/// (module docs). In each window `[a, b]` of a segment, the gyro integrated in the frame of
/// the window's first attitude, `Σ ½ (Rₐᵀ Rᵢ ωᵢ + Rₐᵀ Rᵢ₊₁ ωᵢ₊₁) Δtᵢ`, is set against the
/// rotation vector of `qₐ⁻¹ ⊗ q_b`, per axis. Each pair is averaged over the windows shifted
/// by up to [`GYRO_ENDPOINT_SMOOTHING`]. The attitude's fast jitter at the window's ends, and
/// a small offset between the streams, average out. The windows do not overlap: each is one
/// independent value.
fn gyro_rotation_gain(log: &FlightLog, segments: &[Range<usize>], dt: f64) -> Option<Gain> {
    let len = ((GYRO_ROTATION_WINDOW / dt).round() as usize).max(2);
    let k = (GYRO_ENDPOINT_SMOOTHING / dt).round() as usize;
    let unit = |q: [f64; 4]| tagk_dynamics::log::attitude_quaternion(&q);
    let pair = |a: usize, b: usize| {
        let qa_inv = unit(log.attitude[a]).inverse();
        let body = |i: usize| (qa_inv * unit(log.attitude[i])) * Vector3::from(log.omega[i]);
        let mut gyro = Vector3::zeros();
        for i in a..b {
            gyro += 0.5 * (body(i) + body(i + 1)) * (log.t[i + 1] - log.t[i]);
        }
        ((qa_inv * unit(log.attitude[b])).scaled_axis(), gyro)
    };
    let (mut sxx, mut syy, mut sxy, mut count) = (0.0, 0.0, 0.0, 0usize);
    for r in segments {
        let mut a = r.start + k;
        while a + len + k < r.end {
            let (mut x, mut y) = (Vector3::zeros(), Vector3::zeros());
            for s in a - k..=a + k {
                let (xs, ys) = pair(s, s + len);
                x += xs;
                y += ys;
            }
            sxx += x.norm_squared();
            syy += y.norm_squared();
            sxy += x.dot(&y);
            count += 1;
            a += len;
        }
    }
    gain_of(sxx, syy, sxy, 3 * count, 1)
}

/// The verdict on a gain whose interval is `(lo, hi)` against 1: an error when it lies
/// wholly outside `[1/f, f]` or below zero, a warning when wholly outside
/// `[1/w, w]` (`w`: `warn_factor`, else [`WARNING_FACTOR`]).
fn verdict_of(
    (lo, hi): (f64, f64),
    error_factor: f64,
    warn_factor: Option<f64>,
) -> Option<Severity> {
    let outside = |a: f64, b: f64| lo > b || hi < a;
    if outside(1.0 / error_factor, error_factor) {
        return Some(Severity::Error);
    }
    let w = warn_factor.unwrap_or(WARNING_FACTOR);
    outside(1.0 / w, w).then_some(Severity::Warning)
}

/// [`verdict_of`] a value with its standard error.
fn verdict(g: f64, se: f64, error_factor: f64, warn_factor: Option<f64>) -> Option<Severity> {
    verdict_of(
        (g - CHECK_Z * se, g + CHECK_Z * se),
        error_factor,
        warn_factor,
    )
}

/// The rows of each segment between gaps of `log`, without `edge` samples at either end.
fn inner_rows(segments: &[Range<usize>], edge: usize) -> Vec<Range<usize>> {
    segments
        .iter()
        .filter(|r| r.len() > 2 * edge + 2)
        .map(|r| r.start + edge..r.end - edge)
        .collect()
}

/// The `segments` cut to their first `most` samples in all.
fn first_samples(segments: Vec<Range<usize>>, most: usize) -> Vec<Range<usize>> {
    let mut left = most;
    let mut out = Vec::new();
    for r in segments {
        if left == 0 {
            break;
        }
        let take = r.len().min(left);
        left -= take;
        out.push(r.start..r.start + take);
    }
    out
}

/// `f` applied to the rows of each of the `segments` between a log's gaps, the results
/// concatenated; a segment too short to differentiate gets defaults (never read:
/// [`inner_rows`] leaves it out).
fn per_segment<T: Default + Clone>(
    segments: &[Range<usize>],
    min_len: usize,
    f: impl Fn(Range<usize>) -> Vec<T>,
) -> Vec<T> {
    let mut out = Vec::with_capacity(segments.last().map_or(0, |r| r.end));
    for r in segments {
        if r.len() < min_len {
            out.extend(std::iter::repeat_n(T::default(), r.len()));
        } else {
            out.extend(f(r.clone()));
        }
    }
    out
}

/// The Savitzky–Golay smoothing of each axis of `x` over `2 h + 1` samples.
fn smooth3(t: &[f64], x: &[[f64; 3]], h: usize) -> Vec<[f64; 3]> {
    let axes: Vec<Vec<f64>> = (0..3)
        .map(|k| {
            let v: Vec<f64> = x.iter().map(|a| a[k]).collect();
            savitzky_golay_smooth(t, &v, h)
        })
        .collect();
    (0..x.len())
        .map(|i| [axes[0][i], axes[1][i], axes[2][i]])
        .collect()
}

/// A finding of a gain check, if any.
fn gain_finding(
    name: &str,
    check: &str,
    g: Gain,
    what: impl Fn(&str) -> String,
    causes: Causes,
) -> Option<ScaleFinding> {
    let severity = verdict_of(g.interval(), ERROR_FACTOR, None)?;
    let value = g.value();
    let (lo, hi) = (g.low.min(g.high), g.low.max(g.high));
    // One figure when both regressions agree, else the bracket the gain lies in.
    let gain = if hi <= 1.1 * lo || value < 0.0 {
        times(value)
    } else {
        format!("between {} and {}", times(lo), times(hi))
    };
    let message = if value < 0.0 {
        format!(
            "{} (correlation {:.2}): a sign flipped (an axis convention, or a frame)?",
            what(&gain),
            g.rho
        )
    } else {
        match cause_in(lo, hi, causes) {
            Some(cause) => format!("{}: {cause}", what(&gain)),
            None if severity == Severity::Error => {
                format!("{}: a unit or scale mistake in this column?", what(&gain))
            }
            None => format!("{}: a calibration or scale error?", what(&gain)),
        }
    };
    Some(ScaleFinding {
        log: name.to_string(),
        check: check.to_string(),
        ratio: value,
        std_error: Some(g.se()),
        severity,
        message,
    })
}

/// `1.23×` for a ratio.
fn times(g: f64) -> String {
    if g.abs() >= 100.0 || (g != 0.0 && g.abs() < 0.01) {
        format!("{g:.3e}×")
    } else {
        format!("{g:.3}×")
    }
}

/// The checks of a log before the fit: the gyro, the velocity and the accelerometer against
/// the pose; the thrust against `mass` (the known mass, else the vehicle file's).
pub fn check_log(name: &str, log: &FlightLog, mass: Option<f64>) -> Vec<ScaleFinding> {
    let mut out = Vec::new();
    let sampling = log.sampling();
    let dt = sampling.median_step;
    if dt.is_nan() || dt <= 0.0 {
        return out;
    }
    let segments = first_samples(sampling.segments(), MAX_SCALE_CHECK_SAMPLES);
    // The comparison's smoothing: COMPARISON_WINDOW, at least the derivative's window.
    let h = ((0.5 * COMPARISON_WINDOW / dt).round() as usize).max(DEFAULT_HALF_WIDTH);
    let min_len = 2 * h + 1;
    let rows = inner_rows(&segments, h + 2 * DEFAULT_HALF_WIDTH);
    let width = 2 * h + 1;
    // The measured signal through the derivative's smoothing too: both sides filtered alike.
    let smoothed = |x: &[[f64; 3]]| {
        per_segment(&segments, min_len, |r| {
            let t = &log.t[r.clone()];
            smooth3(t, &smooth3(t, &x[r], DEFAULT_HALF_WIDTH), h)
        })
    };
    // The gyro's rotation against the attitude's, over windows.
    if let Some(g) = gyro_rotation_gain(log, &segments, dt) {
        out.extend(gain_finding(
            name,
            "gyro",
            g,
            |g| format!("the gyro's rotation is {g} the attitude's"),
            GYRO_CAUSES,
        ));
    }
    // The velocity against the position's derivative.
    let p_dot = per_segment(&segments, min_len, |r| {
        let t = &log.t[r.clone()];
        let d = savitzky_golay_derivative3(t, &log.position[r], DEFAULT_HALF_WIDTH);
        smooth3(t, &d, h)
    });
    if let Some(g) = gain(&smoothed(&log.velocity), &p_dot, &rows, width) {
        out.extend(gain_finding(
            name,
            "velocity",
            g,
            |g| format!("the velocity is {g} the position's derivative"),
            VELOCITY_CAUSES,
        ));
    }
    // The logged acceleration against the velocity's derivative.
    let v_dot = per_segment(&segments, min_len, |r| {
        savitzky_golay_derivative3(&log.t[r.clone()], &log.velocity[r], DEFAULT_HALF_WIDTH)
    });
    if let Some(a) = &log.accel
        && let Some(g) = gain(&smoothed(a), &smoothed(&v_dot), &rows, width)
    {
        out.extend(gain_finding(
            name,
            "accelerometer",
            g,
            |g| format!("the logged acceleration is {g} the velocity's derivative"),
            ACCEL_CAUSES,
        ));
    }
    // The logged p̈'s mean against the velocity's change: the specific force has g more.
    if let Some(a) = &log.accel
        && let Some((mean_z, from_velocity)) =
            accel_looks_like_specific_force(a, &log.t, &log.velocity)
    {
        out.push(ScaleFinding {
            log: name.to_string(),
            check: "specific-force".into(),
            ratio: (mean_z - from_velocity) / GRAVITY_WORLD.norm(),
            std_error: None,
            severity: Severity::Error,
            message: format!(
                "the logged acceleration ax, ay, az (p̈) averages {mean_z:.2} m/s² on z over the \
                 log, while the velocity's change accounts for {from_velocity:.2} m/s²: a \
                 flight's p̈ cannot average that, so these are most likely the world-frame \
                 specific force (+9.81 m/s² on z at hover). Remove the columns (p̈ is then \
                 derived from the velocity), subtract g, or read the file through a column \
                 mapping with `[frames] accel = \"specific-force\"` (docs/COLUMN_MAPPING.md)"
            ),
        });
    }
    if !log.has_wrench() {
        return out;
    }
    // The thrust against the mass: fz on the proper acceleration's body z.
    let accel = log.accel.as_deref().unwrap_or(&v_dot);
    let (mut sfa, mut saa, mut sff, mut n) = (0.0, 0.0, 0.0, 0usize);
    for r in &rows {
        for i in r.clone() {
            let q = log.attitude[i];
            let rot = tagk_dynamics::log::attitude_quaternion(&q);
            let a = rot.inverse_transform_vector(&(Vector3::from(accel[i]) - GRAVITY_WORLD));
            let f = log.wrench[i][2];
            sfa += f * a.z;
            saa += a.z * a.z;
            sff += f * f;
            n += 1;
        }
    }
    if let Some(m) = mass
        && saa > 0.0
        && sfa.is_finite()
        && n > 0
    {
        let implied = sfa / saa;
        let resid = (sff - implied * sfa).max(0.0) / n as f64;
        let se = (resid / saa * width as f64).sqrt();
        let ratio = implied / m;
        if let Some(Severity::Error) = verdict(ratio, se / m, ERROR_FACTOR, None) {
            let cause = cause_of(ratio, MASS_CAUSES).unwrap_or(
                "the thrust's unit (or the vehicle's thrust coefficient), the accelerations' unit, or the mass given?",
            );
            out.push(ScaleFinding {
                log: name.to_string(),
                check: "thrust".into(),
                ratio,
                std_error: Some(se / m),
                severity: Severity::Error,
                message: format!(
                    "the thrust fz implies a mass of {implied:.4} kg, {} the mass {m} kg: {cause}",
                    times(ratio)
                ),
            });
        }
    }
    out
}

/// The checks of a fit against the vehicle file. The fitted mass (when it was fitted) and
/// inertia are checked against the vehicle's priors. A negative yaw inertia is checked against
/// its rotor spins (`vehicle_wrench`: the log has rotor speeds, or its wrench came from them).
pub fn check_fit(
    name: &str,
    report: &Report,
    vehicle: &Vehicle,
    mass_fitted: bool,
    vehicle_wrench: bool,
) -> Vec<ScaleFinding> {
    let mut out = Vec::new();
    // The least-squares estimate (the data's answer), not the reported nearest consistent
    // body ([`crate::Fit::consistent_theta`]): a negative I_zz is the evidence looked for.
    let fit = &report.final_diagnosis().fit;
    let value = |j: usize| (fit.theta.as_slice()[j], fit.theta_se[j].unwrap_or(0.0));
    if mass_fitted && let Some(mv) = vehicle.mass {
        let (m, se) = value(0);
        let ratio = m / mv;
        if let Some(Severity::Error) = verdict(ratio, se / mv, ERROR_FACTOR, None) {
            let cause = cause_of(ratio, MASS_CAUSES).unwrap_or(
                "a unit mistake in the accelerations or the wrench, or the wrong vehicle file?",
            );
            out.push(ScaleFinding {
                log: name.to_string(),
                check: "mass".into(),
                ratio,
                std_error: Some(se / mv),
                severity: Severity::Error,
                message: format!(
                    "the fitted mass {m:.4} kg is {} vehicle `{}`'s {mv} kg: {cause}",
                    times(ratio),
                    vehicle.name
                ),
            });
        }
    }
    let Some(inertia) = vehicle.inertia else {
        return out;
    };
    // I_xx, I_yy, I_zz: θ entries 4, 6, 9; the prior's 0, 2, 5.
    for (axis, j, k) in [("I_xx", 4, 0), ("I_yy", 6, 2), ("I_zz", 9, 5)] {
        let prior = inertia[k];
        if prior <= 0.0 {
            continue;
        }
        let (v, se) = value(j);
        let ratio = v / prior;
        // Negative beyond SIGN_Z standard errors: not a body.
        if axis == "I_zz" && vehicle_wrench && v + SIGN_Z * se < 0.0 {
            out.push(ScaleFinding {
                log: name.to_string(),
                check: "yaw-torque".into(),
                ratio,
                std_error: Some(se / prior),
                severity: Severity::Error,
                message: format!(
                    "the fitted I_zz = {v:.3e} kg m² is negative: the rotor spins of vehicle `{}` may be swapped (its [[rotor]] `spin` keys, cw/ccw, in the order of w1..w4)",
                    vehicle.name
                ),
            });
            continue;
        }
        let Some(severity) = verdict(ratio, se / prior, INERTIA_ERROR_FACTOR, Some(ERROR_FACTOR))
        else {
            continue;
        };
        let cause = match cause_of(ratio, INERTIA_CAUSES) {
            Some(c) => c,
            None if ratio <= 0.0 => {
                "a negative inertia is no body: a torque missing from the model, or a flipped torque sign?"
            }
            None if severity == Severity::Error => {
                "a unit mistake in the gyro or the torques, the arm length, or the wrong vehicle file?"
            }
            None => "a payload, or an inertia prior that is not this vehicle's?",
        };
        out.push(ScaleFinding {
            log: name.to_string(),
            check: "inertia".into(),
            ratio,
            std_error: Some(se / prior),
            severity,
            message: format!(
                "the fitted {axis} = {v:.3e} kg m² is {} vehicle `{}`'s {prior:.3e}: {cause}",
                times(ratio),
                vehicle.name
            ),
        });
    }
    out
}

/// Accepts the errors among `findings` (`accept`), or returns the first as
/// [`DiagnoseError::ScaleMismatch`] with every error's message.
///
/// # Errors
/// [`DiagnoseError::ScaleMismatch`] when a finding is an error and `accept` is `false`.
pub fn settle(findings: &mut [ScaleFinding], accept: bool) -> Result<(), DiagnoseError> {
    let errors: Vec<&ScaleFinding> = findings
        .iter()
        .filter(|f| f.severity == Severity::Error)
        .collect();
    if let Some(first) = errors.first()
        && !accept
    {
        return Err(DiagnoseError::ScaleMismatch {
            check: first.check.clone(),
            message: errors
                .iter()
                .map(|f| f.text())
                .collect::<Vec<_>>()
                .join("; "),
        });
    }
    for f in findings.iter_mut() {
        if f.severity == Severity::Error {
            f.severity = Severity::Accepted;
        }
    }
    Ok(())
}

/// The findings as the report prints them, one a line, or nothing.
pub fn scales_text(findings: &[ScaleFinding]) -> String {
    findings
        .iter()
        .map(|f| format!("scale check: {}\n", f.text()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::first_samples;

    /// The segments are cut at the cap, in order; under the cap they are kept whole.
    #[test]
    fn the_gain_checks_read_the_first_samples_only() {
        let segments = vec![0..40, 50..100, 120..200];
        assert_eq!(first_samples(segments.clone(), 1000), segments);
        assert_eq!(first_samples(segments.clone(), 60), vec![0..40, 50..70]);
        assert_eq!(first_samples(segments.clone(), 40), vec![0..40]);
        assert_eq!(
            first_samples(segments, 0),
            Vec::<std::ops::Range<usize>>::new()
        );
    }
}
