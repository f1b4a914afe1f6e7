//! The before/after report: the whole loop in one value, its terminal table and its JSON.

use serde::Serialize;

use crate::diagnose::{Candidate, DiagnoseOptions, Diagnosis, diagnose};
use crate::effects::EffectRef;
use crate::error::DiagnoseError;
use crate::fit::{ChannelFit, Model};
use crate::online::OnlineSummary;
use crate::signals::Signals;

/// One entry of the JSON `ranking`.
#[derive(Debug, Clone, Serialize)]
pub struct RankingEntry {
    /// Effect name.
    pub effect: String,
    /// Held-out residual reduction (fraction).
    pub reduction: f64,
    /// p-value of the significance test.
    pub p_value: f64,
    /// Physically plausible coefficients.
    pub plausible: bool,
    /// One-line explanation.
    pub explanation: String,
}

impl From<&Candidate> for RankingEntry {
    fn from(c: &Candidate) -> Self {
        Self {
            effect: c.effect.clone(),
            reduction: c.reduction,
            p_value: c.p_value,
            plausible: c.plausible,
            explanation: c.explanation.clone(),
        }
    }
}

/// Before/after comparison of one channel.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelChange {
    /// Channel.
    pub name: String,
    /// Residual RMS before.
    pub rms_before: f64,
    /// Residual RMS after.
    pub rms_after: f64,
    /// `1 − after/before`.
    pub rms_reduction: f64,
    /// Fit % before.
    pub fit_percent_before: Option<f64>,
    /// Fit % after.
    pub fit_percent_after: Option<f64>,
}

/// The whole loop on one log: diagnose the rigid-body model (`before`), and if effects were
/// added with `with`, diagnose the augmented model (`after`, ranking recomputed).
///
/// The top-level `recommended`, `ranking` and `channels` describe the FINAL model (the
/// `after` one when effects were added, otherwise `before`).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Recommended effect for the final model, or `null` when it is adequate.
    pub recommended: Option<String>,
    /// Ranking for the final model.
    pub ranking: Vec<RankingEntry>,
    /// Channel fit of the final model.
    pub channels: Vec<ChannelFit>,
    /// Effects added (`--with`).
    pub with: Vec<String>,
    /// Diagnosis of the starting model.
    pub before: Diagnosis,
    /// Diagnosis after adding `with` (absent if nothing was added).
    pub after: Option<Diagnosis>,
    /// Per-channel before/after (absent if nothing was added).
    pub change: Option<Vec<ChannelChange>>,
    /// Online TAG-K pass, if requested.
    pub online: Option<OnlineSummary>,
}

impl Report {
    /// The final diagnosis (after, or before if nothing was added).
    pub fn last(&self) -> &Diagnosis {
        self.after.as_ref().unwrap_or(&self.before)
    }

    /// The report as pretty JSON.
    ///
    /// # Errors
    /// [`DiagnoseError::Output`] if serialisation fails (non-finite numbers become `null`).
    pub fn to_json(&self) -> Result<String, DiagnoseError> {
        serde_json::to_string_pretty(self).map_err(|e| DiagnoseError::Output {
            path: "<json>".into(),
            message: e.to_string(),
        })
    }
}

/// Runs the loop: diagnose `base`, then `base + with` if `with` is not empty.
///
/// # Errors
/// As [`diagnose`].
pub fn run_loop(
    s: &Signals,
    base: &Model,
    with: &[EffectRef],
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let before = diagnose(base, s, opts)?;
    loop_from(before, s, base, with, opts)
}

/// The whole loop in one call: diagnose `base`; if an effect is recommended, add it and
/// diagnose again (the ranking is recomputed for the new model, so a second missing effect
/// shows up in `report.recommended`). `report.after` is `None` when `base` was adequate.
///
/// # Errors
/// As [`diagnose`].
pub fn add_recommended(
    s: &Signals,
    base: &Model,
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let before = diagnose(base, s, opts)?;
    // The recommendation is one of the candidates (built-in or the user's own).
    let with: Vec<EffectRef> = before
        .recommended
        .iter()
        .filter_map(|name| opts.candidates.iter().find(|c| c.name() == name))
        .cloned()
        .collect();
    loop_from(before, s, base, &with, opts)
}

/// [`run_loop`] from an existing diagnosis of `base`.
fn loop_from(
    before: Diagnosis,
    s: &Signals,
    base: &Model,
    with: &[EffectRef],
    opts: &DiagnoseOptions,
) -> Result<Report, DiagnoseError> {
    let (after, change) = if with.is_empty() {
        (None, None)
    } else {
        let mut m = base.clone();
        for e in with {
            m = m.with_ref(e.clone());
        }
        let after = diagnose(&m, s, opts)?;
        let change = before
            .channels
            .iter()
            .zip(&after.channels)
            .map(|(b, a)| ChannelChange {
                name: b.name.clone(),
                rms_before: b.rms,
                rms_after: a.rms,
                rms_reduction: if b.rms > 0.0 {
                    1.0 - a.rms / b.rms
                } else {
                    0.0
                },
                fit_percent_before: b.fit_percent,
                fit_percent_after: a.fit_percent,
            })
            .collect();
        (Some(after), Some(change))
    };
    let last = after.as_ref().unwrap_or(&before);
    Ok(Report {
        recommended: last.recommended.clone(),
        ranking: last.ranking.iter().map(RankingEntry::from).collect(),
        channels: last.channels.clone(),
        with: with.iter().map(|e| e.name().to_string()).collect(),
        before,
        after,
        change,
        online: None,
    })
}

fn fmt_fit(f: Option<f64>) -> String {
    f.map_or("   n/a".to_string(), |x| format!("{x:6.1}"))
}

/// Terminal summary of one diagnosis.
pub fn diagnosis_table(d: &Diagnosis) -> String {
    let mut s = String::new();
    s.push_str(&format!(
        "model: {}  ({} samples, {:.1} s{})\n",
        d.model,
        d.samples,
        d.duration,
        if d.derived_accelerations {
            ", accelerations derived by Savitzky-Golay"
        } else {
            ""
        }
    ));
    s.push_str("channel   fit %        residual RMS\n");
    for c in &d.channels {
        s.push_str(&format!(
            "{:<8} {}   {:>12.4e} {}\n",
            c.name,
            fmt_fit(c.fit_percent),
            c.rms,
            c.unit
        ));
    }
    s.push_str("parameters (± 1 s.e.):\n");
    for p in &d.parameters {
        s.push_str(&format!(
            "  {:<5} = {:>11.4e} ± {:<10} {}\n",
            p.name,
            p.value,
            p.std_error.map_or("n/a".into(), |e| format!("{e:.1e}")),
            p.unit
        ));
    }
    s.push_str(&format!(
        "  centre of mass = ({:.2}, {:.2}, {:.2}) cm; physically consistent: {}; safety gate: {}\n",
        d.com[0] * 100.0,
        d.com[1] * 100.0,
        d.com[2] * 100.0,
        if d.physically_consistent { "yes" } else { "NO" },
        d.safety_gate
    ));
    for e in &d.effects {
        s.push_str(&format!("  effect {}:", e.effect));
        for c in &e.coefficients {
            s.push_str(&format!(" {} = {:.4e} {}", c.name, c.value, c.unit));
        }
        if let Some((n, v, u)) = &e.scanned {
            s.push_str(&format!(", {n} = {v:.3} {u}"));
        }
        s.push_str(if e.plausible {
            "\n"
        } else {
            "  (IMPLAUSIBLE)\n"
        });
    }
    for w in &d.warnings {
        s.push_str(&format!("WARNING: {w}\n"));
    }
    if !d.findings.is_empty() {
        s.push_str("where it fails:\n");
        for f in &d.findings {
            s.push_str(&format!("  - {f}\n"));
        }
    }
    s.push_str("what is missing (held-out residual reduction, blocked CV):\n");
    for (k, c) in d.ranking.iter().enumerate() {
        s.push_str(&format!("  {:>2}. {}\n", k + 1, c.explanation));
    }
    for u in &d.unavailable {
        s.push_str(&format!("   -  {}: skipped, {}\n", u.effect, u.reason));
    }
    s.push_str(&format!("verdict: {}\n", d.verdict));
    s
}

/// Terminal summary of a whole report, with the before/after table.
pub fn report_table(r: &Report) -> String {
    let mut s = String::from("=== before ===\n");
    s.push_str(&diagnosis_table(&r.before));
    if let (Some(a), Some(ch)) = (&r.after, &r.change) {
        s.push_str(&format!("\n=== after adding {} ===\n", r.with.join(", ")));
        s.push_str(&diagnosis_table(a));
        s.push_str("\n=== before / after ===\n");
        s.push_str("channel   fit % before  fit % after   RMS before    RMS after   change\n");
        for c in ch {
            s.push_str(&format!(
                "{:<8}  {:>11}  {:>11}  {:>11.4e}  {:>11.4e}  {:>6.1} %\n",
                c.name,
                fmt_fit(c.fit_percent_before),
                fmt_fit(c.fit_percent_after),
                c.rms_before,
                c.rms_after,
                -100.0 * c.rms_reduction
            ));
        }
    }
    if let Some(o) = &r.online {
        s.push_str(&format!(
            "\nonline TAG-K pass: {} updates, final mass {:.4} kg (batch {:.4} kg), parameter distance to batch {:.3e}\n",
            o.updates, o.final_estimate[0], o.batch_estimate[0], o.distance_to_batch
        ));
    }
    s
}
