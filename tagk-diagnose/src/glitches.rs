//! Glitches: isolated samples, or short runs of them, that jump off their neighbours (a
//! spike, a few corrupted rows, an attitude jump the gyro does not show). They are found by a
//! robust screen and excluded from the fit, so that a few bad rows cannot move a parameter.
//!
//! **The screen** (docs/CONVENTIONS.md §7.3). Each screened channel — the wrench `fx..tz`,
//! the position, the velocity, the gyro, the rotor speeds and the accelerations when logged —
//! is compared with its running median over [`GLITCH_MEDIAN_HALF_WIDTH`] samples on each
//! side, `rᵢ = xᵢ − median(xᵢ₋ₕ..xᵢ₊ₕ)`. The median follows a trend, a step and a turn, and
//! ignores up to `h` bad samples in its window. Each residual is compared with the channel's
//! own spread: its robust standard deviation `σ = 1.4826 · median|r|` and its 99th
//! percentile `q₉₉(|r|)`. A run of at most [`MAX_GLITCH_RUN`] consecutive samples is a
//! glitch when
//!
//! - each of its residuals exceeds the threshold `T = max(GLITCH_SIGMAS · σ,
//!   GLITCH_PERCENTILE_FACTOR · q₉₉)`: far beyond the channel's noise. For Gaussian noise
//!   `10 σ` is never reached. The percentile keeps a quantised channel, whose median residual
//!   may be zero, from counting one quantum as a glitch. A smooth log without noise has
//!   `σ = 0`: the threshold is then at least `GLITCH_SIGMAS` times the window's median step
//!   `median|xⱼ − xⱼ₋₁|` (the signal's own local change; about `σ` for white noise); and
//! - the samples just before and after it have residuals of at most `T / 2`: the run stands
//!   alone. A smooth peak, which a median clips too, falls off gradually (its neighbour keeps
//!   three quarters of its residual) and is not a glitch.
//!
//! **The attitude** is screened against the gyro. Over each step the rotation between the
//! logged quaternions is compared with the rotation the gyro shows,
//! `q̂ᵢ = qᵢ₋₁ ⊗ exp(ω̄ Δt / 2)` with `ω̄` the mean of the two samples' rates. The error is
//! `eᵢ = angle(q̂ᵢ⁻¹ ⊗ qᵢ)`, with the same threshold on `e`. A quaternion's sign is no rotation
//! (`q` and `−q` are one attitude), so a sign flip is not a glitch. Two such steps at most
//! [`MAX_GLITCH_RUN`] samples apart enclose a run of bad attitudes. A lone one is a jump that
//! stays (a reset of the attitude estimate), reported at its first sample.
//!
//! Samples within `h` of a log's ends or of a gap in the time stamps are not screened (their
//! median has no window); the attitude is not screened across a gap.
//!
//! **Where.** With the lines the samples were read from ([`SampleSource`]), a glitch names its
//! file and line (`flight.csv:301`). A sample of a merged log whose channel comes from another
//! stream, interpolated onto the time base, has no line. Nor does a log in memory. The report
//! says so.
//!
//! **The exclusion.** A glitch's samples and the [`GLITCH_EXCLUSION_HALF_WIDTH`] samples on
//! each side (the widest window a derivative or smoothing of the diagnosis reads) are removed
//! from the log. The hole is a gap ([`FlightLog::sampling`]): the log is split there, and no
//! derivative or smoothing runs across it ([`crate::Signals::from_log_split`]).

use std::collections::BTreeSet;
use std::ops::Range;

use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;
use tagk_dynamics::log::{
    ACCEL_COLUMNS, OMEGA_DOT_COLUMNS, REQUIRED_COLUMNS, ROTOR_SPEED_COLUMNS, WRENCH_COLUMNS,
};

use crate::log::FlightLog;
use crate::signals::VELOCITY_SMOOTHING_HALF_WIDTH;

/// Robust standard deviations (`1.4826 · median|r|`) a residual must exceed to be a glitch.
pub const GLITCH_SIGMAS: f64 = 10.0;

/// Times the 99th percentile of the channel's absolute residuals a residual must exceed to be a glitch (for Gaussian noise `4 q₉₉ ≈ 10.3 σ`,
/// the same level as [`GLITCH_SIGMAS`]).
pub const GLITCH_PERCENTILE_FACTOR: f64 = 4.0;

/// Samples on each side of the running median a residual is taken against: the median
/// ignores up to this many bad samples in its window.
pub const GLITCH_MEDIAN_HALF_WIDTH: usize = 5;

/// The longest run of consecutive bad samples the screen calls a glitch (shorter than the
/// median's half-width, so that the median of a run's neighbours stays clean). A longer run
/// is a stretch of flight, not a glitch.
pub const MAX_GLITCH_RUN: usize = GLITCH_MEDIAN_HALF_WIDTH - 1;

/// Samples excluded on each side of a glitch: the half-width of the widest window the
/// diagnosis differentiates or smooths over (the velocity's smoothing).
pub const GLITCH_EXCLUSION_HALF_WIDTH: usize = VELOCITY_SMOOTHING_HALF_WIDTH;

/// The channel name of the attitude in a [`Glitch`] (its four columns `qw..qz` as one).
pub const ATTITUDE_CHANNEL: &str = "q";

/// Where a log's samples were read: the file and the line of each, so that a glitch names
/// the line the user opens.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SampleSource {
    /// The file the lines are in (the primary stream, the time base, of a merged log).
    pub file: String,
    /// The CSV line of each sample of the log (1-based; the header is line 1).
    pub lines: Vec<usize>,
    /// The primary stream's name in `sources` (empty for a log read from one file).
    pub primary: String,
    /// The stream each quantity was read from (`("force", "motors.csv")`, as
    /// [`tagk_dynamics::log_input::MergeReport::sources`]); empty for a log read from one
    /// file. A channel of another stream than `primary` has no line here.
    pub sources: Vec<(String, String)>,
}

impl SampleSource {
    /// The lines of a log read from one file in the project's format.
    pub fn of_file(file: impl Into<String>, lines: Vec<usize>) -> Self {
        Self {
            file: file.into(),
            lines,
            ..Self::default()
        }
    }

    /// The stream a channel's samples came from, when it is not `primary`: `None` when the
    /// sample's line is this file's.
    fn other_stream(&self, channel: &str) -> Option<&str> {
        let stream = |key: &str| {
            self.sources
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, s)| s.as_str())
        };
        let keys: &[&[&str]] = match channel {
            "fx" | "fy" | "fz" => &[&["force"], &["rotor_speeds"]],
            "tx" | "ty" | "tz" => &[&["torque"], &["rotor_speeds"]],
            "px" | "py" | "pz" => &[&["position"]],
            "vx" | "vy" | "vz" => &[&["velocity"]],
            "wx" | "wy" | "wz" => &[&["omega"]],
            "ax" | "ay" | "az" => &[&["accel"], &["specific_force", "attitude"]],
            "dwx" | "dwy" | "dwz" => &[&["omega_dot"]],
            "w1" | "w2" | "w3" | "w4" => &[&["rotor_speeds"]],
            ATTITUDE_CHANNEL => &[&["attitude", "omega"]],
            _ => &[],
        };
        // The first alternative whose first quantity was read decides (the wrench wins over
        // the rotor speeds, the world acceleration over the accelerometer).
        let used = keys.iter().find(|alt| stream(alt[0]).is_some())?;
        used.iter()
            .filter_map(|k| stream(k))
            .find(|s| *s != self.primary)
    }
}

/// One glitch: a sample, or a run of consecutive samples, of one channel off its neighbours.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Glitch {
    /// The log (its file; empty for a log in memory).
    pub log: String,
    /// The channel, by its column name in the project's format (`fz`, `vx`, `wy`, `w1`, …;
    /// [`ATTITUDE_CHANNEL`] for the attitude).
    pub channel: String,
    /// Index of the run's first sample in the log as read (0 = the first data row).
    pub sample: usize,
    /// Consecutive samples in the run (1: a single spike).
    pub samples: usize,
    /// The file the run was read from, when its line is known.
    pub file: Option<String>,
    /// The CSV line of the run's first sample (1-based; the header is line 1), when known.
    pub line: Option<usize>,
    /// The CSV line of the run's last sample, when known.
    pub last_line: Option<usize>,
    /// Why the line is not known (a log in memory, a channel interpolated from another
    /// stream), when it is not.
    pub line_unknown: Option<String>,
    /// Time of the run's first sample \[s\].
    pub t: f64,
    /// The value of the run's sample farthest off (in the channel's unit). For the attitude:
    /// the logged rotation over the step into the run \[rad\].
    pub value: f64,
    /// The running median at that sample. For the attitude: the gyro's rotation over the
    /// step \[rad\].
    pub expected: f64,
    /// The farthest residual in robust standard deviations of the channel's residual (the
    /// threshold counting as [`GLITCH_SIGMAS`]).
    pub robust_sigmas: f64,
}

impl Glitch {
    /// One line: `fz = 30 N at flight.csv:301 (t = 5.990 s, sample 299; expected 0.343,
    /// 8.7e4 robust σ off)`; a run says how many samples, `-303` on the line and `up to`
    /// before the value.
    pub fn text(&self) -> String {
        let place = match (&self.file, self.line, self.last_line) {
            (Some(f), Some(a), Some(b)) if b != a => format!("{f}:{a}-{b}"),
            (Some(f), Some(a), _) => format!("{f}:{a}"),
            _ => format!("t = {:.3} s", self.t),
        };
        let mut when = match self.line {
            Some(_) => format!("t = {:.3} s, sample {}", self.t, self.sample),
            None => format!("sample {}", self.sample),
        };
        if self.samples > 1 {
            when = format!("{} samples from {when}", self.samples);
        }
        if let Some(why) = &self.line_unknown {
            when.push_str(&format!(", line not known: {why}"));
        }
        let sigmas = format!("{:.1e} robust σ off", self.robust_sigmas);
        if self.channel == ATTITUDE_CHANNEL {
            return format!(
                "attitude q turns {} rad at {place} ({when}; the gyro shows {} rad over the \
                 step, {sigmas})",
                short(self.value),
                short(self.expected),
            );
        }
        let unit = channel_unit(&self.channel);
        let value = if self.samples > 1 {
            format!("up to {}", short(self.value))
        } else {
            short(self.value)
        };
        format!(
            "{} = {value} {unit} at {place} ({when}; expected {}, {sigmas})",
            self.channel,
            short(self.expected),
        )
    }
}

/// The unit of a screened channel.
fn channel_unit(channel: &str) -> &'static str {
    match channel {
        "fx" | "fy" | "fz" => "N",
        "tx" | "ty" | "tz" => "N m",
        "px" | "py" | "pz" => "m",
        "vx" | "vy" | "vz" => "m/s",
        "wx" | "wy" | "wz" | "w1" | "w2" | "w3" | "w4" => "rad/s",
        "ax" | "ay" | "az" => "m/s²",
        ATTITUDE_CHANNEL => "rad",
        _ => "rad/s²",
    }
}

/// A number in four significant digits.
fn short(x: f64) -> String {
    if x != 0.0 && (x.abs() >= 1e5 || x.abs() < 1e-3) {
        format!("{x:.3e}")
    } else {
        format!("{}", (x * 1e4).round() / 1e4)
    }
}

/// The glitches of a log, in sample order (module docs), without the lines it was read
/// from. `name` is the log's name for the report. A sample off on several channels is
/// listed once per channel.
pub fn screen(name: &str, log: &FlightLog) -> Vec<Glitch> {
    screen_located(name, log, None)
}

/// [`screen`], each glitch located by `source` (its file and lines) when given.
pub fn screen_located(name: &str, log: &FlightLog, source: Option<&SampleSource>) -> Vec<Glitch> {
    let n = log.len();
    let segments = log.sampling().segments();
    let mut out = Vec::new();
    let mut channel = |column: &str, x: &dyn Fn(usize) -> f64| {
        let x: Vec<f64> = (0..n).map(x).collect();
        for run in screen_channel(&segments, &x) {
            out.push(run.glitch(name, column, log, source));
        }
    };
    // px..pz, vx..vz (after t), wx..wz (after the attitude).
    for (k, column) in REQUIRED_COLUMNS[1..4].iter().enumerate() {
        channel(column, &|i| log.position[i][k]);
    }
    for (k, column) in REQUIRED_COLUMNS[4..7].iter().enumerate() {
        channel(column, &|i| log.velocity[i][k]);
    }
    for (k, column) in REQUIRED_COLUMNS[11..14].iter().enumerate() {
        channel(column, &|i| log.omega[i][k]);
    }
    if log.has_wrench() {
        for (c, column) in WRENCH_COLUMNS.iter().enumerate() {
            channel(column, &|i| log.wrench[i][c]);
        }
    }
    if let Some(a) = &log.accel {
        for (k, column) in ACCEL_COLUMNS.iter().enumerate() {
            channel(column, &|i| a[i][k]);
        }
    }
    if let Some(a) = &log.omega_dot {
        for (k, column) in OMEGA_DOT_COLUMNS.iter().enumerate() {
            channel(column, &|i| a[i][k]);
        }
    }
    if let Some(w) = &log.rotor_speeds {
        for (k, column) in ROTOR_SPEED_COLUMNS.iter().enumerate() {
            channel(column, &|i| w[i][k]);
        }
    }
    for run in screen_attitude(log, &segments) {
        out.push(run.glitch(name, ATTITUDE_CHANNEL, log, source));
    }
    out.sort_by_key(|g| g.sample);
    out
}

/// A run of bad samples of one channel, before it is named.
struct Run {
    /// Its samples.
    samples: Range<usize>,
    /// Its value farthest off (the attitude: the logged rotation into the run).
    value: f64,
    /// What was expected there (the running median; the gyro's rotation).
    expected: f64,
    /// Its residual farthest off in robust standard deviations.
    robust_sigmas: f64,
}

impl Run {
    /// The glitch of this run of `channel`, located by `source` when given.
    fn glitch(
        self,
        name: &str,
        channel: &str,
        log: &FlightLog,
        source: Option<&SampleSource>,
    ) -> Glitch {
        let (first, last) = (self.samples.start, self.samples.end - 1);
        let mut g = Glitch {
            log: name.to_string(),
            channel: channel.to_string(),
            sample: first,
            samples: self.samples.len(),
            file: None,
            line: None,
            last_line: None,
            line_unknown: None,
            t: log.t[first],
            value: self.value,
            expected: self.expected,
            robust_sigmas: self.robust_sigmas,
        };
        match source {
            None => g.line_unknown = Some("a log given in memory has no file lines".into()),
            Some(s) => match s.other_stream(channel) {
                Some(other) => {
                    g.line_unknown = Some(format!(
                        "{channel} comes from {other}, interpolated onto the time base of {}",
                        s.primary
                    ));
                }
                None => match (s.lines.get(first), s.lines.get(last)) {
                    (Some(&a), Some(&b)) => {
                        g.file = Some(s.file.clone());
                        g.line = Some(a);
                        g.last_line = Some(b);
                    }
                    _ => g.line_unknown = Some("the file's lines were not kept".into()),
                },
            },
        }
        g
    }
}

/// The `q`-quantile (`0..=1`) of `v` (reordered).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    *v.select_nth_unstable_by(k, f64::total_cmp).1
}

/// The threshold `T` of residuals `r` (NaN: not screened), from their robust standard
/// deviation and 99th percentile (module docs); `None` for fewer than three residuals.
fn threshold(r: &[f64]) -> Option<f64> {
    let mut abs: Vec<f64> = r.iter().filter(|v| !v.is_nan()).map(|v| v.abs()).collect();
    if abs.len() < 3 {
        return None;
    }
    let sigma = 1.4826 * quantile(&mut abs, 0.5);
    let q99 = quantile(&mut abs, 0.99);
    Some((GLITCH_SIGMAS * sigma).max(GLITCH_PERCENTILE_FACTOR * q99))
}

/// The runs of at most [`MAX_GLITCH_RUN`] residuals above their threshold whose
/// neighbours are both screened and at most half of theirs (module docs). `limit(i, f)` is
/// `f` times sample `i`'s threshold.
fn isolated_runs(r: &[f64], limit: &dyn Fn(usize, f64) -> f64) -> Vec<Range<usize>> {
    let n = r.len();
    let above = |i: usize| r[i].abs() > limit(i, 1.0);
    let quiet = |i: usize| !r[i].is_nan() && r[i].abs() <= limit(i, 0.5);
    let mut out = Vec::new();
    let mut i = 0;
    while i < n {
        if !above(i) {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && above(i) {
            i += 1;
        }
        if i - start <= MAX_GLITCH_RUN && start > 0 && i < n && quiet(start - 1) && quiet(i) {
            out.push(start..i);
        }
    }
    out
}

/// A residual in robust standard deviations, its `threshold` counting as [`GLITCH_SIGMAS`]
/// (infinite for a zero threshold).
fn in_sigmas(r: f64, threshold: f64) -> f64 {
    if threshold > 0.0 {
        GLITCH_SIGMAS * r.abs() / threshold
    } else {
        f64::INFINITY
    }
}

/// The glitches of one channel `x` of a log split in `segments` (module docs).
fn screen_channel(segments: &[Range<usize>], x: &[f64]) -> Vec<Run> {
    let h = GLITCH_MEDIAN_HALF_WIDTH;
    let n = x.len();
    let mut r = vec![f64::NAN; n];
    let mut median = vec![f64::NAN; n];
    // The running median: the window kept sorted, one sample out and one in per step.
    let mut window: Vec<f64> = Vec::with_capacity(2 * h + 1);
    let position = |w: &[f64], v: f64| w.partition_point(|y| y.total_cmp(&v).is_lt());
    for seg in segments.iter().filter(|s| s.len() > 2 * h) {
        window.clear();
        window.extend_from_slice(&x[seg.start..seg.start + 2 * h + 1]);
        window.sort_unstable_by(f64::total_cmp);
        for i in seg.start + h..seg.end - h {
            median[i] = window[h];
            r[i] = x[i] - median[i];
            if i + h + 1 < seg.end {
                let out = position(&window, x[i - h]);
                window.remove(out);
                let v = x[i + h + 1];
                window.insert(position(&window, v), v);
            }
        }
    }
    let Some(global) = threshold(&r) else {
        return Vec::new();
    };
    // The local threshold: the global one, or the window's median step (module docs),
    // computed only where the global one is passed.
    let local = |i: usize| {
        let mut steps = [0.0; 2 * GLITCH_MEDIAN_HALF_WIDTH];
        for (k, d) in steps.iter_mut().enumerate() {
            *d = (x[i - h + k + 1] - x[i - h + k]).abs();
        }
        global.max(GLITCH_SIGMAS * *steps.select_nth_unstable_by(h, f64::total_cmp).1)
    };
    let limit = |i: usize, scale: f64| {
        // Not screened (NaN) or within the global threshold: no need of the local one.
        if r[i].is_nan() || r[i].abs() <= scale * global {
            scale * global
        } else {
            scale * local(i)
        }
    };
    isolated_runs(&r, &limit)
        .into_iter()
        .map(|samples| {
            let worst = samples
                .clone()
                .max_by(|&a, &b| (r[a] / local(a)).abs().total_cmp(&(r[b] / local(b)).abs()))
                .unwrap_or(samples.start);
            Run {
                value: x[worst],
                expected: median[worst],
                robust_sigmas: in_sigmas(r[worst], local(worst)),
                samples,
            }
        })
        .collect()
}

/// The attitude's glitches: steps whose rotation the gyro does not show (module docs).
fn screen_attitude(log: &FlightLog, segments: &[Range<usize>]) -> Vec<Run> {
    let n = log.len();
    let unit = |q: [f64; 4]| tagk_dynamics::log::attitude_quaternion(&q);
    // e[i]: the step from sample i − 1 to i.
    let mut e = vec![f64::NAN; n];
    let mut logged = vec![f64::NAN; n];
    let mut gyro = vec![f64::NAN; n];
    for seg in segments {
        for i in seg.start + 1..seg.end {
            let dt = log.t[i] - log.t[i - 1];
            let w = 0.5 * (Vector3::from(log.omega[i - 1]) + Vector3::from(log.omega[i])) * dt;
            let (a, b) = (unit(log.attitude[i - 1]), unit(log.attitude[i]));
            e[i] = (a * UnitQuaternion::from_scaled_axis(w)).angle_to(&b);
            logged[i] = a.angle_to(&b);
            gyro[i] = w.norm();
        }
    }
    let Some(t) = threshold(&e) else {
        return Vec::new();
    };
    // Steps off, each with its neighbours quiet; a pair close together encloses a run.
    let steps = isolated_runs(&e, &|_, f| f * t);
    let mut out = Vec::new();
    let mut k = 0;
    while k < steps.len() {
        let entry = steps[k].start;
        let (samples, exit) = match steps.get(k + 1) {
            Some(next)
                if next.start - entry <= MAX_GLITCH_RUN
                    && e[entry..next.start].iter().all(|v| !v.is_nan()) =>
            {
                k += 1;
                (entry..next.start, Some(next.start))
            }
            _ => (entry..entry + 1, None),
        };
        k += 1;
        let sigmas = in_sigmas(e[entry], t).max(exit.map_or(0.0, |x| in_sigmas(e[x], t)));
        out.push(Run {
            samples,
            value: logged[entry],
            expected: gyro[entry],
            robust_sigmas: sigmas,
        });
    }
    out
}

/// The log without its glitches' samples and the [`GLITCH_EXCLUSION_HALF_WIDTH`] samples on
/// each side of each (module docs), and how many samples were removed.
pub fn exclude(log: FlightLog, glitches: &[Glitch]) -> (FlightLog, usize) {
    if glitches.is_empty() {
        return (log, 0);
    }
    let n = log.len();
    let h = GLITCH_EXCLUSION_HALF_WIDTH;
    let mut keep = vec![true; n];
    for g in glitches {
        for k in keep
            .iter_mut()
            .take((g.sample + g.samples + h).min(n))
            .skip(g.sample.saturating_sub(h))
        {
            *k = false;
        }
    }
    let removed = keep.iter().filter(|k| !**k).count();
    // The kept stretches, cut out and joined again.
    let mut out: Option<FlightLog> = None;
    let mut i = 0;
    while i < n {
        if !keep[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i < n && keep[i] {
            i += 1;
        }
        let part = log.slice(start..i);
        out = Some(match out {
            None => part,
            Some(mut joined) => {
                joined.append(part);
                joined
            }
        });
    }
    (out.unwrap_or_else(|| log.slice(0..0)), removed)
}

/// The glitches as the report prints them: a heading line and one line per glitch, or
/// nothing when there is none.
pub fn glitches_text(glitches: &[Glitch], excluded: usize) -> String {
    if glitches.is_empty() {
        return String::new();
    }
    let samples: BTreeSet<(&str, usize)> = glitches
        .iter()
        .flat_map(|g| (g.sample..g.sample + g.samples).map(|i| (g.log.as_str(), i)))
        .collect();
    let count = samples.len();
    let mut s = format!(
        "glitches: {count} sample{} excluded ({excluded} with the samples whose derivatives read {}):\n",
        if count == 1 { "" } else { "s" },
        if count == 1 { "it" } else { "them" },
    );
    for g in glitches {
        if g.log.is_empty() {
            s.push_str(&format!("  {}\n", g.text()));
        } else {
            s.push_str(&format!("  {}: {}\n", g.log, g.text()));
        }
    }
    s
}
