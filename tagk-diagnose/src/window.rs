//! Time windows of a log (`tagk diagnose --window 5..40`): the rows a diagnosis keeps.
//!
//! A window is `START..END` in log time (the `t` column) \[s\], both ends included. Several
//! windows keep the rows within any of them. The time between two windows is a gap: the
//! diagnosis splits the log there and never differentiates across it.

use crate::error::DiagnoseError;
use crate::log::FlightLog;

/// A time window `[start, end]` in log time \[s\], both ends included.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeWindow {
    /// Start \[s\].
    pub start: f64,
    /// End \[s\].
    pub end: f64,
}

impl TimeWindow {
    /// The window `[start, end]` \[s\].
    ///
    /// # Errors
    /// [`DiagnoseError::BadWindow`] for a bound that is not finite, or `start ≥ end`.
    pub fn new(start: f64, end: f64) -> Result<Self, DiagnoseError> {
        let w = Self { start, end };
        if !(start.is_finite() && end.is_finite()) {
            return Err(w.bad("its bounds must be finite numbers of seconds"));
        }
        if start >= end {
            return Err(w.bad("its start is not before its end"));
        }
        Ok(w)
    }

    fn bad(&self, reason: &str) -> DiagnoseError {
        DiagnoseError::BadWindow {
            window: self.to_string(),
            reason: reason.to_string(),
        }
    }

    /// Whether time `t` \[s\] is in the window.
    pub fn contains(&self, t: f64) -> bool {
        (self.start..=self.end).contains(&t)
    }
}

impl std::fmt::Display for TimeWindow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}..{}", self.start, self.end)
    }
}

impl std::str::FromStr for TimeWindow {
    type Err = DiagnoseError;

    /// Parses `START..END` in seconds (e.g. `5..40`, `12.5..20`).
    fn from_str(text: &str) -> Result<Self, DiagnoseError> {
        let bad = |reason: &str| DiagnoseError::BadWindow {
            window: text.to_string(),
            reason: reason.to_string(),
        };
        let (a, b) = text
            .split_once("..")
            .ok_or_else(|| bad("expected START..END in seconds of log time, e.g. 5..40"))?;
        let number = |s: &str| {
            s.trim()
                .parse::<f64>()
                .map_err(|_| bad(&format!("`{}` is not a number of seconds", s.trim())))
        };
        Self::new(number(a)?, number(b)?).map_err(|e| match e {
            DiagnoseError::BadWindow { reason, .. } => bad(&reason),
            other => other,
        })
    }
}

/// The rows of `log` within any of `windows` (all of it for no window).
///
/// A window must lie within the log's time span (to half a median step) and keep at least
/// one row.
///
/// # Errors
/// [`DiagnoseError::BadWindow`]: `start ≥ end` or a bound not finite, a window that begins
/// before the log or ends after it, a window without a row.
pub fn keep_windows(log: FlightLog, windows: &[TimeWindow]) -> Result<FlightLog, DiagnoseError> {
    if windows.is_empty() || log.is_empty() {
        return Ok(log);
    }
    let keep = window_mask(&log, windows)?;
    let mut out: Option<FlightLog> = None;
    let mut i = 0;
    while i < keep.len() {
        if !keep[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i < keep.len() && keep[i] {
            i += 1;
        }
        let part = log.slice(start..i);
        match &mut out {
            None => out = Some(part),
            Some(o) => o.append(part),
        }
    }
    Ok(out.unwrap_or_default())
}

/// For each row of `log`, whether it lies within one of `windows` (every row for no window).
///
/// # Errors
/// As [`keep_windows`].
pub fn window_mask(log: &FlightLog, windows: &[TimeWindow]) -> Result<Vec<bool>, DiagnoseError> {
    if windows.is_empty() || log.is_empty() {
        return Ok(vec![true; log.len()]);
    }
    let (first, last) = (log.t[0], log.t[log.t.len() - 1]);
    let slack = 0.5 * log.sampling().median_step;
    for w in windows {
        let w = TimeWindow::new(w.start, w.end)?;
        if w.start < first - slack || w.end > last + slack {
            return Err(w.bad(&format!(
                "outside the log, which spans {first}..{last} s (log time, the `t` column)"
            )));
        }
        if !log.t.iter().any(|&t| w.contains(t)) {
            return Err(w.bad(&format!(
                "no sample of the log lies in it (the log spans {first}..{last} s)"
            )));
        }
    }
    Ok(log
        .t
        .iter()
        .map(|&t| windows.iter().any(|w| w.contains(t)))
        .collect())
}
