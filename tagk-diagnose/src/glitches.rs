//! Glitches: isolated samples that jump off their neighbours (a spike, a corrupted row), found
//! by a robust screen and excluded from the fit so that one bad row cannot move a parameter.
//!
//! **The screen** (docs/CONVENTIONS.md §7.3). For each screened channel — the wrench
//! `fx..tz`, the position, the velocity, the gyro, and the accelerations when logged — the
//! residual of each sample against the straight line through its two neighbours,
//! `rᵢ = xᵢ − x̂ᵢ` (`x̂ᵢ` interpolated at `tᵢ` between `xᵢ₋₁` and `xᵢ₊₁`), is compared with the
//! channel's own spread: its robust standard deviation `σ = 1.4826 · MAD(r)` and its 99th
//! percentile `q₉₉(|r|)`. A sample is a glitch when
//!
//! - `|rᵢ| > GLITCH_SIGMAS · σ` and `|rᵢ| > GLITCH_PERCENTILE_FACTOR · q₉₉(|r|)`: far beyond the
//!   channel's noise (for Gaussian noise `10 σ` is never reached; the percentile keeps a
//!   quantised channel, whose MAD may be zero, from counting one quantum as a glitch), and
//! - both neighbours' residuals have the other sign and between a quarter and three quarters
//!   of its size: the signature of one sample off the line (`−½, 1, −½`), which a step, a
//!   kink or a smooth turn does not have.
//!
//! Samples next to a gap in the time stamps and the first and last sample are not screened.
//!
//! **The exclusion.** A glitch and the [`GLITCH_EXCLUSION_HALF_WIDTH`] samples on each side
//! (the widest window a derivative or smoothing of the diagnosis reads) are removed from the
//! log. The hole is a gap ([`FlightLog::sampling`]): the log is split there, and no derivative
//! or smoothing runs across it ([`crate::Signals::from_log_split`]).

use serde::Serialize;
use tagk_dynamics::log::{ACCEL_COLUMNS, OMEGA_DOT_COLUMNS, REQUIRED_COLUMNS, WRENCH_COLUMNS};

use crate::log::FlightLog;
use crate::signals::VELOCITY_SMOOTHING_HALF_WIDTH;

/// Robust standard deviations (`1.4826 · MAD`) a residual must exceed to be a glitch.
pub const GLITCH_SIGMAS: f64 = 10.0;

/// Times the 99th percentile of the channel's absolute residuals a residual must exceed to be
/// a glitch (for Gaussian noise `4 q₉₉ ≈ 10.3 σ`, the same level as [`GLITCH_SIGMAS`]).
pub const GLITCH_PERCENTILE_FACTOR: f64 = 4.0;

/// Samples excluded on each side of a glitch: the half-width of the widest window the
/// diagnosis differentiates or smooths over (the velocity's smoothing).
pub const GLITCH_EXCLUSION_HALF_WIDTH: usize = VELOCITY_SMOOTHING_HALF_WIDTH;

/// One glitch: a sample of one channel off the line through its neighbours.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Glitch {
    /// The log (its file; empty for a log in memory).
    pub log: String,
    /// The channel, by its column name in the project's format (`fz`, `vx`, `wy`, …).
    pub channel: String,
    /// Index of the sample in the log as read (0 = the first data row).
    pub sample: usize,
    /// Time of the sample \[s\].
    pub t: f64,
    /// The sample's value (in the channel's unit).
    pub value: f64,
    /// The value on the line through its neighbours.
    pub expected: f64,
    /// `|value − expected|` in robust standard deviations of the channel's residual.
    pub robust_sigmas: f64,
}

impl Glitch {
    /// One line: `fz = 30 N at t = 12.340 s (sample 617; expected 0.343, 8.7e4 robust σ off)`.
    pub fn text(&self) -> String {
        let unit = channel_unit(&self.channel);
        format!(
            "{} = {} {unit} at t = {:.3} s (sample {}; expected {}, {:.1e} robust σ off)",
            self.channel,
            short(self.value),
            self.t,
            self.sample,
            short(self.expected),
            self.robust_sigmas
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
        "wx" | "wy" | "wz" => "rad/s",
        "ax" | "ay" | "az" => "m/s²",
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

/// The glitches of a log, in time order (module docs). `name` is the log's name for the
/// report. A sample off on several channels is listed once per channel.
pub fn screen(name: &str, log: &FlightLog) -> Vec<Glitch> {
    let n = log.len();
    if n < 5 {
        return Vec::new();
    }
    // A sample next to a gap has no neighbour on that side.
    let mut breaks = vec![false; n];
    for g in log.sampling().gaps {
        breaks[g.index] = true;
        breaks[g.index - 1] = true;
    }
    let mut out = Vec::new();
    let mut channel = |column: &str, x: &dyn Fn(usize) -> f64| {
        screen_channel(name, column, &log.t, &breaks, x, &mut out);
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
    out.sort_by_key(|g| g.sample);
    out
}

/// The `q`-quantile (`0..=1`) of `v` (reordered).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    *v.select_nth_unstable_by(k, f64::total_cmp).1
}

/// Screens one channel (module docs), pushing its glitches to `out`.
fn screen_channel(
    name: &str,
    column: &str,
    t: &[f64],
    breaks: &[bool],
    x: &dyn Fn(usize) -> f64,
    out: &mut Vec<Glitch>,
) {
    let n = t.len();
    // r[i] for i in 1..n-1 (NaN where a neighbour lies across a gap).
    let mut r = vec![f64::NAN; n];
    for i in 1..n - 1 {
        if breaks[i] {
            continue;
        }
        let w = (t[i] - t[i - 1]) / (t[i + 1] - t[i - 1]);
        let expected = x(i - 1) + w * (x(i + 1) - x(i - 1));
        r[i] = x(i) - expected;
    }
    let mut abs: Vec<f64> = r.iter().filter(|v| !v.is_nan()).map(|v| v.abs()).collect();
    if abs.len() < 3 {
        return;
    }
    let sigma = 1.4826 * quantile(&mut abs, 0.5);
    let q99 = quantile(&mut abs, 0.99);
    let threshold = (GLITCH_SIGMAS * sigma).max(GLITCH_PERCENTILE_FACTOR * q99);
    for i in 2..n.saturating_sub(2) {
        let (ri, before, after) = (r[i], r[i - 1], r[i + 1]);
        if ri.is_nan() || ri.abs() <= threshold || before.is_nan() || after.is_nan() {
            continue;
        }
        let neighbour_ok = |rn: f64| {
            rn.signum() != ri.signum() && rn.abs() >= 0.25 * ri.abs() && rn.abs() <= 0.75 * ri.abs()
        };
        if neighbour_ok(before) && neighbour_ok(after) {
            let value = x(i);
            let w = (t[i] - t[i - 1]) / (t[i + 1] - t[i - 1]);
            let expected = x(i - 1) + w * (x(i + 1) - x(i - 1));
            out.push(Glitch {
                log: name.to_string(),
                channel: column.to_string(),
                sample: i,
                t: t[i],
                value,
                expected,
                robust_sigmas: if sigma > 0.0 {
                    ri.abs() / sigma
                } else {
                    f64::INFINITY
                },
            });
        }
    }
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
            .take((g.sample + h + 1).min(n))
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
    let mut samples: Vec<(&str, usize)> = glitches
        .iter()
        .map(|g| (g.log.as_str(), g.sample))
        .collect();
    samples.dedup();
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
