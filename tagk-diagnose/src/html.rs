//! Self-contained HTML report with hand-written SVG plots (no fonts, scripts or external
//! files): measured vs predicted per channel, residual over time with the failure windows
//! shaded, residual against the top candidate's driving signal, the ranking, before/after.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::diagnose::Diagnosis;
use crate::error::DiagnoseError;
use crate::report::Report;
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS};

/// File name of the report inside the report directory.
pub const REPORT_FILE: &str = "index.html";

const W: f64 = 460.0;
const H: f64 = 220.0;
const ML: f64 = 70.0;
const MR: f64 = 26.0;
const MT: f64 = 26.0;
const MB: f64 = 34.0;
const MAX_POINTS: usize = 1200;

/// Escapes text for HTML/SVG.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn fmt_tick(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-2 && v.abs() < 1e4 {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.2e}")
    }
}

/// A line series: label, colour, x, y.
struct LineSeries<'a> {
    /// Legend label.
    pub label: &'a str,
    /// CSS colour.
    pub color: &'a str,
    /// Abscissae.
    pub x: &'a [f64],
    /// Ordinates.
    pub y: &'a [f64],
}

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if hi - lo <= 1e-300 {
        let d = if lo.abs() > 0.0 { lo.abs() * 0.1 } else { 1.0 };
        return (lo - d, hi + d);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

fn frame(out: &mut String, title: &str, xr: (f64, f64), yr: (f64, f64), xlabel: &str) {
    let _ = write!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" class="plot"><rect x="0" y="0" width="{W}" height="{H}" fill="white"/><text x="{}" y="16" font-size="13" text-anchor="middle" font-family="sans-serif">{}</text>"#,
        W / 2.0,
        escape(title)
    );
    let (x0, x1, y0, y1) = (ML, W - MR, MT, H - MB);
    let _ = write!(
        out,
        r##"<rect x="{x0}" y="{y0}" width="{}" height="{}" fill="none" stroke="#444"/>"##,
        x1 - x0,
        y1 - y0
    );
    for k in 0..=4 {
        let f = k as f64 / 4.0;
        let yv = yr.0 + f * (yr.1 - yr.0);
        let py = y1 - f * (y1 - y0);
        let xv = xr.0 + f * (xr.1 - xr.0);
        let px = x0 + f * (x1 - x0);
        let _ = write!(
            out,
            r##"<line x1="{x0}" y1="{py:.1}" x2="{x1}" y2="{py:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" font-size="10" text-anchor="end" font-family="sans-serif">{}</text><text x="{px:.1}" y="{}" font-size="10" text-anchor="middle" font-family="sans-serif">{}</text>"##,
            x0 - 4.0,
            py + 3.0,
            fmt_tick(yv),
            y1 + 13.0,
            fmt_tick(xv)
        );
    }
    let _ = write!(
        out,
        r#"<text x="{}" y="{}" font-size="11" text-anchor="middle" font-family="sans-serif">{}</text>"#,
        (x0 + x1) / 2.0,
        H - 4.0,
        escape(xlabel)
    );
}

fn map(v: f64, r: (f64, f64), a: f64, b: f64) -> f64 {
    a + (v - r.0) / (r.1 - r.0) * (b - a)
}

/// A line plot as an SVG element; `shade` are x-intervals drawn as red bands.
fn line_plot(title: &str, xlabel: &str, series: &[LineSeries<'_>], shade: &[(f64, f64)]) -> String {
    let xr = {
        let (lo, hi) = range(series.iter().flat_map(|s| s.x.iter().copied()));
        let pad = (hi - lo) / 1.1 * 0.05;
        (lo + pad, hi - pad)
    };
    let yr = range(series.iter().flat_map(|s| s.y.iter().copied()));
    let mut out = String::new();
    frame(&mut out, title, xr, yr, xlabel);
    for &(a, b) in shade {
        let pa = map(a.max(xr.0), xr, ML, W - MR);
        let pb = map(b.min(xr.1), xr, ML, W - MR);
        let _ = write!(
            out,
            r##"<rect x="{pa:.1}" y="{MT}" width="{:.1}" height="{}" fill="#e33" fill-opacity="0.18" class="failure"/>"##,
            (pb - pa).max(1.0),
            H - MB - MT
        );
    }
    for (k, s) in series.iter().enumerate() {
        let n = s.x.len().min(s.y.len());
        let step = n.div_ceil(MAX_POINTS).max(1);
        let mut pts = String::new();
        let mut i = 0;
        while i < n {
            if s.x[i].is_finite() && s.y[i].is_finite() {
                let _ = write!(
                    pts,
                    "{:.1},{:.1} ",
                    map(s.x[i], xr, ML, W - MR),
                    map(s.y[i], yr, H - MB, MT)
                );
            }
            i += step;
        }
        let _ = write!(
            out,
            r#"<polyline points="{pts}" fill="none" stroke="{}" stroke-width="1.2"/><text x="{}" y="{}" font-size="10" fill="{}" font-family="sans-serif">{}</text>"#,
            s.color,
            ML + 6.0 + 110.0 * k as f64,
            MT + 12.0,
            s.color,
            escape(s.label)
        );
    }
    out.push_str("</svg>");
    out
}

/// A scatter plot as an SVG element.
fn scatter_plot(title: &str, xlabel: &str, x: &[f64], y: &[f64], color: &str) -> String {
    let xr = range(x.iter().copied());
    let yr = range(y.iter().copied());
    let mut out = String::new();
    frame(&mut out, title, xr, yr, xlabel);
    let n = x.len().min(y.len());
    let step = n.div_ceil(MAX_POINTS).max(1);
    let mut i = 0;
    while i < n {
        if x[i].is_finite() && y[i].is_finite() {
            let _ = write!(
                out,
                r#"<circle cx="{:.1}" cy="{:.1}" r="1.6" fill="{color}" fill-opacity="0.6"/>"#,
                map(x[i], xr, ML, W - MR),
                map(y[i], yr, H - MB, MT)
            );
        }
        i += step;
    }
    out.push_str("</svg>");
    out
}

/// Horizontal bar chart of `(label, value)` in percent.
fn bar_chart(title: &str, bars: &[(String, f64, bool)]) -> String {
    let h = MT + 22.0 * bars.len().max(1) as f64 + 20.0;
    let mut out = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" viewBox="0 0 {W} {h}" class="plot"><rect width="{W}" height="{h}" fill="white"/><text x="{}" y="16" font-size="13" text-anchor="middle" font-family="sans-serif">{}</text>"#,
        W / 2.0,
        escape(title)
    );
    let x0 = 130.0;
    let span = W - x0 - 60.0;
    for (k, (label, v, good)) in bars.iter().enumerate() {
        let y = MT + 22.0 * k as f64;
        let frac = (v / 100.0).clamp(0.0, 1.0);
        let color = if *good { "#2a7" } else { "#999" };
        let _ = write!(
            out,
            r#"<text x="{}" y="{}" font-size="11" text-anchor="end" font-family="sans-serif">{}</text><rect x="{x0}" y="{}" width="{:.1}" height="14" fill="{color}"/><text x="{:.1}" y="{}" font-size="10" font-family="sans-serif">{:.1} %</text>"#,
            x0 - 6.0,
            y + 11.0,
            escape(label),
            y,
            (span * frac).max(0.5),
            x0 + span * frac + 4.0,
            y + 11.0,
            v
        );
    }
    out.push_str("</svg>");
    out
}

fn section_diagnosis(html: &mut String, title: &str, d: &Diagnosis) {
    let _ = write!(
        html,
        "<h2>{}</h2><p class=\"verdict\">{}</p>",
        escape(title),
        escape(&d.verdict)
    );
    html.push_str("<table><tr><th>channel</th><th>fit %</th><th>residual RMS</th></tr>");
    for c in &d.channels {
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{:.4e} {}</td></tr>",
            c.name,
            c.fit_percent.map_or("n/a".into(), |f| format!("{f:.1}")),
            c.rms,
            escape(&c.unit)
        );
    }
    html.push_str("</table>");
    html.push_str("<table><tr><th>parameter</th><th>estimate</th><th>± s.e.</th></tr>");
    for p in &d.parameters {
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{:.4e} {}</td><td>{}</td></tr>",
            escape(&p.name),
            p.value,
            escape(&p.unit),
            p.std_error.map_or("n/a".into(), |e| format!("{e:.1e}"))
        );
    }
    let _ = write!(
        html,
        "</table><p>centre of mass ({:.2}, {:.2}, {:.2}) cm; physically consistent: {}; safety gate: {}</p>",
        d.com[0] * 100.0,
        d.com[1] * 100.0,
        d.com[2] * 100.0,
        if d.physically_consistent { "yes" } else { "NO" },
        escape(&d.safety_gate)
    );
    for e in &d.effects {
        let coefs: Vec<String> = e
            .coefficients
            .iter()
            .map(|c| format!("{} = {:.4e} {}", c.name, c.value, c.unit))
            .collect();
        let _ = write!(
            html,
            "<p>effect <b>{}</b>: {}{}</p>",
            escape(&e.effect),
            escape(&coefs.join(", ")),
            if e.plausible { "" } else { " (IMPLAUSIBLE)" }
        );
    }
    for w in &d.warnings {
        let _ = write!(html, "<p class=\"warn\">⚠ {}</p>", escape(w));
    }
    if !d.findings.is_empty() {
        html.push_str("<h3>Where it fails</h3><ul>");
        for f in &d.findings {
            let _ = write!(html, "<li>{}</li>", escape(f));
        }
        html.push_str("</ul>");
    }
    // Measured vs predicted.
    html.push_str("<h3>Measured vs predicted</h3><div class=\"grid\">");
    for c in 0..6 {
        let m: Vec<f64> = d.measured.iter().map(|w| w[c]).collect();
        let p: Vec<f64> = d.fit.predicted.iter().map(|w| w[c]).collect();
        html.push_str(&line_plot(
            &format!("{} [{}]", CHANNEL_NAMES[c], CHANNEL_UNITS[c]),
            "time [s]",
            &[
                LineSeries {
                    label: "measured",
                    color: "#222",
                    x: &d.t,
                    y: &m,
                },
                LineSeries {
                    label: "predicted",
                    color: "#d60",
                    x: &d.t,
                    y: &p,
                },
            ],
            &[],
        ));
    }
    html.push_str("</div>");
    // Residual over time with failure windows.
    html.push_str("<h3>Residual over time (failure windows shaded)</h3><div class=\"grid\">");
    for c in 0..6 {
        let r = d.fit.residual_channel(c);
        let shade: Vec<(f64, f64)> = d
            .failure_windows
            .iter()
            .filter(|f| f.channels.iter().any(|n| n == CHANNEL_NAMES[c]))
            .map(|f| (f.t_start, f.t_end))
            .collect();
        html.push_str(&line_plot(
            &format!("residual {} [{}]", CHANNEL_NAMES[c], CHANNEL_UNITS[c]),
            "time [s]",
            &[LineSeries {
                label: "residual",
                color: "#c22",
                x: &d.t,
                y: &r,
            }],
            &shade,
        ));
    }
    html.push_str("</div>");
    // Residual vs the top candidate's driver.
    if let (Some(top), Some((dname, dsig))) = (d.ranking.first(), &d.top_driver) {
        let _ = write!(
            html,
            "<h3>Residual against the top candidate's signal ({})</h3><div class=\"grid\">",
            escape(&top.effect)
        );
        let mut chans: Vec<usize> = top
            .affected_channels
            .iter()
            .filter_map(|n| CHANNEL_NAMES.iter().position(|c| c == n))
            .collect();
        if chans.is_empty() {
            chans.push(
                (0..6)
                    .max_by(|&a, &b| {
                        top.reduction_per_channel[a].total_cmp(&top.reduction_per_channel[b])
                    })
                    .unwrap_or(0),
            );
        }
        for c in chans {
            let r = d.fit.residual_channel(c);
            html.push_str(&scatter_plot(
                &format!("residual {} vs {}", CHANNEL_NAMES[c], dname),
                dname,
                dsig,
                &r,
                "#36c",
            ));
        }
        html.push_str("</div>");
    }
    // Ranking.
    html.push_str("<h3>What is missing: ranking (held-out residual reduction, blocked CV)</h3>");
    let bars: Vec<(String, f64, bool)> = d
        .ranking
        .iter()
        .map(|c| {
            (
                c.effect.clone(),
                100.0 * c.reduction,
                c.significant && c.plausible,
            )
        })
        .collect();
    html.push_str(&bar_chart("held-out residual reduction", &bars));
    html.push_str("<ol>");
    for c in &d.ranking {
        let _ = write!(html, "<li>{}</li>", escape(&c.explanation));
    }
    html.push_str("</ol>");
    for u in &d.unavailable {
        let _ = write!(
            html,
            "<p>{}: skipped, {}</p>",
            escape(&u.effect),
            escape(&u.reason)
        );
    }
}

/// Channel colours of the staircase plot (fx … tz).
const CHANNEL_COLORS: [&str; 6] = ["#c22", "#2a7", "#36c", "#d60", "#839", "#555"];

/// The stepwise search: the staircase table (held-out RMS per channel and step, the floor),
/// why it stopped, the command that reproduces the final model, each log's own verdict, and a
/// plot of each channel's held-out RMS over the floor step by step.
fn section_staircase(html: &mut String, report: &Report) {
    html.push_str("<h2 id=\"staircase\">Stepwise: held-out residual RMS per channel (blocked CV), down to the noise floor</h2>");
    html.push_str("<table id=\"steps\"><tr><th>step</th>");
    for c in 0..6 {
        let _ = write!(html, "<th>{} [{}]</th>", CHANNEL_NAMES[c], CHANNEL_UNITS[c]);
    }
    html.push_str("</tr>");
    for (k, step) in report.steps.iter().enumerate() {
        let label = match &step.effect {
            None => format!("{k}. {}", step.model),
            Some(e) => format!("{k}. + {e}"),
        };
        let _ = write!(html, "<tr><td>{}</td>", escape(&label));
        for ch in &step.channels {
            if step.effect.is_some() {
                let _ = write!(
                    html,
                    "<td>{:.3e} ({:+.0} %)</td>",
                    ch.held_out_rms,
                    100.0 * ch.change
                );
            } else {
                let _ = write!(html, "<td>{:.3e}</td>", ch.held_out_rms);
            }
        }
        html.push_str("</tr>");
    }
    html.push_str("<tr><td>noise floor</td>");
    for f in report.noise_floor.rms {
        let _ = write!(html, "<td>{f:.3e}</td>");
    }
    html.push_str("</tr><tr><td>HF noise estimate</td>");
    for f in report.noise_floor.noise_estimate {
        let _ = write!(html, "<td>{f:.3e}</td>");
    }
    html.push_str("</tr></table>");
    let _ = write!(
        html,
        "<p id=\"stopped\">stopped: {}</p><p>final model: <b>{}</b></p>",
        escape(&report.stopped),
        escape(&report.final_model.label)
    );
    if let Some(cmd) = &report.final_model.command {
        let _ = write!(
            html,
            "<p>reproduce it: <code id=\"command\">{}</code></p>",
            escape(cmd)
        );
    }
    if report.steps.len() > 1 {
        let x: Vec<f64> = (0..report.steps.len()).map(|k| k as f64).collect();
        let ratios: Vec<Vec<f64>> = (0..6)
            .map(|c| {
                report
                    .steps
                    .iter()
                    .map(|s| s.channels[c].ratio_to_floor.max(1e-3).log10())
                    .collect()
            })
            .collect();
        let series: Vec<LineSeries<'_>> = (0..6)
            .map(|c| LineSeries {
                label: CHANNEL_NAMES[c],
                color: CHANNEL_COLORS[c],
                x: &x,
                y: &ratios[c],
            })
            .collect();
        html.push_str(&line_plot(
            "log10(held-out RMS / noise floor) per step (0 = at the floor)",
            "step",
            &series,
            &[],
        ));
    }
    if !report.logs.is_empty() {
        html.push_str("<h3>Each log alone</h3><table id=\"logs\"><tr><th>log</th><th>samples</th><th>its own staircase</th><th>verdict</th></tr>");
        for l in &report.logs {
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                escape(&l.log),
                l.samples,
                escape(&l.added.join(" → ")),
                if l.agrees { "" } else { "warn" },
                if l.agrees {
                    "agrees".to_string()
                } else {
                    escape(&format!("disagrees: {}", l.note))
                }
            );
        }
        html.push_str("</table>");
    }
}

/// The report as one HTML document.
pub fn render(report: &Report) -> String {
    let mut html = String::from(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>tagk diagnose report</title><style>body{font-family:sans-serif;margin:20px;max-width:1450px}table{border-collapse:collapse;margin:8px 16px 8px 0;display:inline-table;vertical-align:top}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}.grid{display:flex;flex-wrap:wrap;gap:6px}.warn{color:#a00}.verdict{font-weight:bold;font-size:1.1em}</style></head><body><h1 id=\"title\">tagk diagnose report</h1>",
    );
    let _ = write!(
        html,
        "<p id=\"summary\">recommended: <b>{}</b></p>",
        escape(
            report
                .recommended
                .as_deref()
                .unwrap_or("none — model adequate")
        )
    );
    section_staircase(&mut html, report);
    if let (Some(after), Some(change)) = (&report.after, &report.change) {
        let _ = write!(
            html,
            "<h2>Before / after adding {}</h2>",
            escape(&report.with.join(", "))
        );
        html.push_str("<table id=\"before-after\"><tr><th>channel</th><th>fit % before</th><th>fit % after</th><th>RMS before</th><th>RMS after</th><th>change</th></tr>");
        for c in change {
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4e}</td><td>{:.4e}</td><td>{:.1} %</td></tr>",
                c.name,
                c.fit_percent_before
                    .map_or("n/a".into(), |f| format!("{f:.1}")),
                c.fit_percent_after
                    .map_or("n/a".into(), |f| format!("{f:.1}")),
                c.rms_before,
                c.rms_after,
                -100.0 * c.rms_reduction
            );
        }
        html.push_str("</table><div class=\"grid\">");
        for c in 0..6 {
            let rb = report.before.fit.residual_channel(c);
            let ra = after.fit.residual_channel(c);
            html.push_str(&line_plot(
                &format!("residual {} before/after", CHANNEL_NAMES[c]),
                "time [s]",
                &[
                    LineSeries {
                        label: "before",
                        color: "#c22",
                        x: &report.before.t,
                        y: &rb,
                    },
                    LineSeries {
                        label: "after",
                        color: "#2a7",
                        x: &after.t,
                        y: &ra,
                    },
                ],
                &[],
            ));
        }
        html.push_str("</div>");
    }
    section_diagnosis(
        &mut html,
        &format!("Model: {}", report.before.model),
        &report.before,
    );
    if let Some(after) = &report.after {
        section_diagnosis(&mut html, &format!("Model: {}", after.model), after);
    }
    if let Some(f) = &report.final_diagnosis {
        section_diagnosis(
            &mut html,
            &format!("What remains: final model {}", f.model),
            f,
        );
    }
    if let Some(o) = &report.online {
        let t: Vec<f64> = (0..o.mass_history.len()).map(|k| k as f64).collect();
        let _ = write!(
            html,
            "<h2>Online TAG-K pass</h2><p>{} updates; tail-average distance to the batch estimate {:.3e} (relative)</p>",
            o.updates, o.distance_to_batch
        );
        html.push_str(&line_plot(
            "TAG-K mass estimate [kg]",
            "update",
            &[LineSeries {
                label: "mass",
                color: "#36c",
                x: &t,
                y: &o.mass_history,
            }],
            &[],
        ));
    }
    html.push_str("</body></html>\n");
    html
}

/// Writes [`render`] to `dir/index.html` (creating `dir`) and returns the file's path.
///
/// # Errors
/// [`DiagnoseError::Output`] on an I/O failure.
pub fn write_report(report: &Report, dir: &Path) -> Result<PathBuf, DiagnoseError> {
    let io = |e: std::io::Error| DiagnoseError::Output {
        path: dir.display().to_string(),
        message: e.to_string(),
    };
    std::fs::create_dir_all(dir).map_err(io)?;
    let path = dir.join(REPORT_FILE);
    std::fs::write(&path, render(report)).map_err(io)?;
    Ok(path)
}
