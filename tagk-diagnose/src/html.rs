//! Self-contained HTML report with hand-written SVG plots (no fonts, scripts or external
//! files): measured vs predicted per channel, residual over time with the failure windows
//! shaded, residual against the top candidate's driving signal, the ranking, before/after.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::diagnose::Diagnosis;
use crate::error::DiagnoseError;
use crate::format::{change_percent, percent_cell};
use crate::report::Report;
use crate::signals::{CHANNEL_NAMES, CHANNEL_UNITS};
use crate::stats;

/// File name of the report inside the report directory.
pub const REPORT_FILE: &str = "index.html";

const W: f64 = 460.0;
const H: f64 = 230.0;
const ML: f64 = 64.0;
const MR: f64 = 16.0;
/// Top margin: the title, then the legend row (outside the data).
const MT: f64 = 40.0;
const MB: f64 = 38.0;
pub(crate) const MAX_POINTS: usize = 1200;
/// Most lags of the correlation plots (`resid`'s default is 25).
const MAX_LAG: usize = 25;

/// How the flights read through a column mapping were merged: the warnings first, a table of
/// the streams (rate, span, offset, overlap, dropped samples), then the terminal's lines
/// ([`tagk_dynamics::log_input::MergeReport::text`]).
fn section_inputs(html: &mut String, report: &Report) {
    if report.inputs.is_empty() {
        return;
    }
    let _ = write!(html, "<h2 id=\"inputs\">Inputs</h2>");
    for (k, m) in report.inputs.iter().enumerate() {
        for w in &m.warnings {
            let _ = write!(
                html,
                "<p class=\"warn input-warning\">warning: {}</p>",
                text(w)
            );
        }
        let _ = write!(
            html,
            "<table id=\"input-streams-{k}\"><tr><th>stream</th><th>rate [Hz]</th>\
             <th>samples</th><th>t [s]</th><th>offset [s]</th><th>overlap</th>\
             <th>dropped</th><th>provides</th></tr>"
        );
        for s in &m.streams {
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{:.1}</td><td>{}</td><td>{:.3} to {:.3}</td><td>{}</td>\
                 <td>{:.0} %</td><td>{}</td><td>{}</td></tr>",
                escape(&s.stream),
                s.rate,
                s.samples,
                s.start,
                s.end,
                s.offset,
                s.overlap_fraction * 100.0,
                s.dropped,
                escape(&s.provides.join(", "))
            );
        }
        let _ = write!(
            html,
            "</table><pre id=\"merge-report-{k}\">{}</pre>",
            text(&m.text())
        );
    }
}

/// Escapes text for HTML/SVG.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Escapes text for HTML and sets the spans between backticks (`` `rotor-drag` ``) as code,
/// so that no literal backtick reaches the page.
pub(crate) fn text(s: &str) -> String {
    let mut out = String::new();
    for (k, part) in escape(s).split('`').enumerate() {
        if k % 2 == 1 {
            let _ = write!(out, "<code>{part}</code>");
        } else {
            out.push_str(part);
        }
    }
    out
}

/// The same text for an SVG `<text>` element (no markup there): backticks dropped.
fn svg_text(s: &str) -> String {
    escape(&s.replace('`', ""))
}

/// A plot axis with rounded ticks: the range widened to whole steps of 1, 2 or 5 × 10ᵏ,
/// and the tick labels printed with the decimals that step needs; values beyond 10⁴ or below
/// 10⁻² are labelled in units of a common power of ten, named by [`Axis::scale_note`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Axis {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// Tick positions.
    pub ticks: Vec<f64>,
    /// Decimals of the tick labels (after the common power of ten).
    decimals: usize,
    /// The common power of ten of the labels.
    exponent: i32,
}

impl Axis {
    /// Rounded ticks (about `target` of them) covering `[lo, hi]`.
    pub fn new(lo: f64, hi: f64, target: usize) -> Self {
        let (lo, hi) = if lo.is_finite() && hi.is_finite() && hi > lo {
            (lo, hi)
        } else if lo.is_finite() {
            let d = if lo != 0.0 { 0.1 * lo.abs() } else { 1.0 };
            (lo - d, lo + d)
        } else {
            (0.0, 1.0)
        };
        let raw = (hi - lo) / target.max(1) as f64;
        let mag = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .into_iter()
            .map(|f| f * mag)
            .find(|st| *st >= raw * (1.0 - 1e-9))
            .unwrap_or(10.0 * mag);
        // Ends on whole steps (a value a hair past a step stays on it).
        let first = (lo / step + 1e-9).floor();
        let last = (hi / step - 1e-9).ceil();
        let ticks: Vec<f64> = (0..=((last - first) as usize))
            .map(|k| {
                let v = (first + k as f64) * step;
                if v.abs() < 1e-12 * step { 0.0 } else { v }
            })
            .collect();
        let largest = ticks.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let exponent = if !(1e-2..1e4).contains(&largest) && largest > 0.0 {
            largest.log10().floor() as i32
        } else {
            0
        };
        let scaled_step = step / 10f64.powi(exponent);
        let decimals = (-(scaled_step.log10().floor()) as i32).max(0) as usize;
        Self {
            lo: first * step,
            hi: last * step,
            ticks,
            decimals,
            exponent,
        }
    }

    /// The label of a tick.
    pub fn label(&self, v: f64) -> String {
        let x = v / 10f64.powi(self.exponent);
        let s = format!("{x:.*}", self.decimals);
        if s.trim_start_matches('-')
            .chars()
            .all(|c| c == '0' || c == '.')
        {
            "0".to_string()
        } else {
            s.replace('-', "−")
        }
    }

    /// ` (×10⁻³)` when the labels are in units of a power of ten, else empty.
    pub fn scale_note(&self) -> String {
        if self.exponent == 0 {
            String::new()
        } else {
            format!(" (×1e{})", self.exponent)
        }
    }

    fn map(&self, v: f64, a: f64, b: f64) -> f64 {
        a + (v - self.lo) / (self.hi - self.lo) * (b - a)
    }
}

/// The data range of some values (finite ones only).
fn extent(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    vals.filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// A line series: label, colour, dash pattern, x, y.
struct LineSeries<'a> {
    label: &'a str,
    color: &'a str,
    /// SVG `stroke-dasharray` (empty: solid).
    dash: &'a str,
    x: &'a [f64],
    y: &'a [f64],
}

/// A shaded x-interval of a time plot.
struct Span {
    start: f64,
    end: f64,
    /// A start transient (grey) rather than a failure (red).
    transient: bool,
}

/// The plot frame: title, legend row above the data, axes with rounded ticks, axis labels.
fn frame(
    out: &mut String,
    title: &str,
    xa: &Axis,
    ya: &Axis,
    xlabel: &str,
    legend: &[(&str, &str, &str)],
) {
    let _ = write!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" class="plot" data-ylo="{:e}" data-yhi="{:e}"><rect x="0" y="0" width="{W}" height="{H}" fill="white"/><text x="{}" y="15" font-size="13" text-anchor="middle" font-family="sans-serif">{}{}</text>"#,
        ya.lo,
        ya.hi,
        W / 2.0,
        svg_text(title),
        svg_text(&ya.scale_note())
    );
    // Legend: one row between the title and the data.
    let mut lx = ML;
    for (label, color, dash) in legend {
        let _ = write!(
            out,
            r#"<line x1="{lx}" y1="29" x2="{}" y2="29" stroke="{color}" stroke-width="2" stroke-dasharray="{dash}"/><text x="{}" y="33" font-size="11" font-family="sans-serif">{}</text>"#,
            lx + 18.0,
            lx + 22.0,
            svg_text(label)
        );
        lx += 30.0 + 6.5 * label.chars().count() as f64;
    }
    let (x0, x1, y0, y1) = (ML, W - MR, MT, H - MB);
    for &v in &ya.ticks {
        let py = ya.map(v, y1, y0);
        let _ = write!(
            out,
            r##"<line x1="{x0}" y1="{py:.1}" x2="{x1}" y2="{py:.1}" stroke="#e4e4e4"/><text x="{}" y="{:.1}" font-size="10" text-anchor="end" font-family="sans-serif">{}</text>"##,
            x0 - 4.0,
            py + 3.5,
            ya.label(v)
        );
    }
    for &v in &xa.ticks {
        let px = xa.map(v, x0, x1);
        let _ = write!(
            out,
            r##"<line x1="{px:.1}" y1="{y1}" x2="{px:.1}" y2="{}" stroke="#444"/><text x="{px:.1}" y="{}" font-size="10" text-anchor="middle" font-family="sans-serif">{}</text>"##,
            y1 + 4.0,
            y1 + 15.0,
            xa.label(v)
        );
    }
    let _ = write!(
        out,
        r##"<rect x="{x0}" y="{y0}" width="{}" height="{}" fill="none" stroke="#444"/><text x="{}" y="{}" font-size="11" text-anchor="middle" font-family="sans-serif">{}{}</text>"##,
        x1 - x0,
        y1 - y0,
        (x0 + x1) / 2.0,
        H - 6.0,
        svg_text(xlabel),
        svg_text(&xa.scale_note())
    );
}

/// A line plot as an SVG element; `spans` are shaded x-intervals, `hlines` dashed horizontal
/// reference lines `(y, label)` (e.g. the noise floor), named in the legend. The y-range is
/// the series' own: a reference line widens it at most to three times the data's range; one
/// farther off is left out and its legend entry says so, with its value.
fn line_plot(
    title: &str,
    xlabel: &str,
    series: &[LineSeries<'_>],
    spans: &[Span],
    hlines: &[(f64, &str)],
) -> String {
    let (xlo, xhi) = extent(series.iter().flat_map(|s| s.x.iter().copied()));
    let (dlo, dhi) = extent(series.iter().flat_map(|s| s.y.iter().copied()));
    let span = dhi - dlo;
    let shown: Vec<(f64, &str)> = hlines
        .iter()
        .filter(|h| {
            h.0.is_finite() && (!dlo.is_finite() || (h.0 >= dlo - span && h.0 <= dhi + span))
        })
        .copied()
        .collect();
    let (ylo, yhi) = extent([dlo, dhi].into_iter().chain(shown.iter().map(|h| h.0)));
    // A few whole-number abscissae (steps, updates) get one tick each.
    let whole = series
        .iter()
        .all(|s| s.x.len() <= 12 && s.x.iter().all(|v| v.fract() == 0.0));
    let xa = if whole && xhi > xlo {
        Axis::new(xlo, xhi, (xhi - xlo) as usize)
    } else {
        Axis::new(xlo, xhi, 6)
    };
    let ya = Axis::new(ylo, yhi, 5);
    let mut legend: Vec<(&str, &str, &str)> =
        series.iter().map(|s| (s.label, s.color, s.dash)).collect();
    let off_scale;
    if let Some((_, label)) = shown.first() {
        legend.push((label, "#36c", "4 3"));
    } else if let Some((y, label)) = hlines.first() {
        off_scale = format!("{label} {:.1e}: off scale", y.abs());
        legend.push((&off_scale, "#36c", "4 3"));
    }
    if spans.iter().any(|s| !s.transient) {
        legend.push(("large residual", "#f3b4b4", ""));
    }
    if spans.iter().any(|s| s.transient) {
        legend.push(("start transient", "#c8c8c8", ""));
    }
    let mut out = String::new();
    frame(&mut out, title, &xa, &ya, xlabel, &legend);
    let (x0, x1, y0, y1) = (ML, W - MR, MT, H - MB);
    for sp in spans {
        let pa = xa.map(sp.start.max(xa.lo), x0, x1);
        let pb = xa.map(sp.end.min(xa.hi), x0, x1);
        let (fill, class) = if sp.transient {
            ("#888", "transient")
        } else {
            ("#e33", "failure")
        };
        let _ = write!(
            out,
            r#"<rect x="{pa:.1}" y="{y0}" width="{:.1}" height="{}" fill="{fill}" fill-opacity="0.2" class="{class}"/>"#,
            (pb - pa).max(1.0),
            y1 - y0
        );
    }
    for (y, _) in &shown {
        let py = ya.map(*y, y1, y0);
        let _ = write!(
            out,
            r##"<line x1="{x0}" y1="{py:.1}" x2="{x1}" y2="{py:.1}" stroke="#36c" stroke-width="1.2" stroke-dasharray="4 3"/>"##
        );
    }
    for s in series {
        let n = s.x.len().min(s.y.len());
        let step = n.div_ceil(MAX_POINTS).max(1);
        let mut pts = String::new();
        for i in (0..n).step_by(step) {
            if s.x[i].is_finite() && s.y[i].is_finite() {
                let _ = write!(
                    pts,
                    "{:.1},{:.1} ",
                    xa.map(s.x[i], x0, x1),
                    ya.map(s.y[i], y1, y0)
                );
            }
        }
        let _ = write!(
            out,
            r#"<polyline points="{pts}" fill="none" stroke="{}" stroke-width="1.2" stroke-dasharray="{}"/>"#,
            s.color, s.dash
        );
        if whole {
            // Markers on the few points of a step plot.
            for i in 0..n {
                let _ = write!(
                    out,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{}"/>"#,
                    xa.map(s.x[i], x0, x1),
                    ya.map(s.y[i], y1, y0),
                    s.color
                );
            }
        }
    }
    out.push_str("</svg>");
    out
}

/// A scatter plot as an SVG element.
fn scatter_plot(title: &str, xlabel: &str, x: &[f64], y: &[f64], color: &str) -> String {
    let (xlo, xhi) = extent(x.iter().copied());
    let (ylo, yhi) = extent(y.iter().copied());
    let xa = Axis::new(xlo, xhi, 6);
    let ya = Axis::new(ylo, yhi, 5);
    let mut out = String::new();
    frame(&mut out, title, &xa, &ya, xlabel, &[]);
    let n = x.len().min(y.len());
    let step = n.div_ceil(MAX_POINTS).max(1);
    for i in (0..n).step_by(step) {
        if x[i].is_finite() && y[i].is_finite() {
            let _ = write!(
                out,
                r#"<circle cx="{:.1}" cy="{:.1}" r="1.6" fill="{color}" fill-opacity="0.6"/>"#,
                xa.map(x[i], ML, W - MR),
                ya.map(y[i], H - MB, MT)
            );
        }
    }
    out.push_str("</svg>");
    out
}

/// A correlation plot as MATLAB's `resid` draws it: one stem per lag, the band of an
/// uncorrelated residual (`±band`, named `band_label` in the legend) shaded, the stems outside
/// it in red.
fn correlation_plot(
    title: &str,
    xlabel: &str,
    lags: &[f64],
    rho: &[f64],
    band: f64,
    band_label: &str,
) -> String {
    let (lo, hi) = extent(rho.iter().copied().chain([band, -band]));
    let (xlo, xhi) = extent(lags.iter().copied());
    let xa = Axis::new(xlo, xhi, 6);
    let ya = Axis::new(lo.min(-band), hi.max(band), 4);
    let mut out = String::new();
    frame(
        &mut out,
        title,
        &xa,
        &ya,
        xlabel,
        &[(band_label, "#9bd", ""), ("outside", "#c22", "")],
    );
    let (x0, x1, y0, y1) = (ML, W - MR, MT, H - MB);
    let (pb_hi, pb_lo) = (ya.map(band, y1, y0), ya.map(-band, y1, y0));
    let _ = write!(
        out,
        r##"<rect x="{x0}" y="{pb_hi:.1}" width="{}" height="{:.1}" fill="#9bd" fill-opacity="0.35" class="band"/>"##,
        x1 - x0,
        pb_lo - pb_hi
    );
    let pz = ya.map(0.0, y1, y0);
    let _ = write!(
        out,
        r##"<line x1="{x0}" y1="{pz:.1}" x2="{x1}" y2="{pz:.1}" stroke="#444"/>"##
    );
    for (&l, &r) in lags.iter().zip(rho) {
        if !r.is_finite() {
            continue;
        }
        let px = xa.map(l, x0, x1);
        let py = ya.map(r, y1, y0);
        let color = if r.abs() > band { "#c22" } else { "#333" };
        let _ = write!(
            out,
            r#"<line x1="{px:.1}" y1="{pz:.1}" x2="{px:.1}" y2="{py:.1}" stroke="{color}" stroke-width="1.5"/><circle cx="{px:.1}" cy="{py:.1}" r="2" fill="{color}"/>"#
        );
    }
    out.push_str("</svg>");
    out
}

/// Bar chart of the held-out residual change of each candidate, in percent (negative =
/// the candidate lowers the residual), bars from a zero line, clipped at ±100 % (the label
/// gives the value, as the explanation does: [`change_percent`]).
fn change_chart(title: &str, bars: &[(String, f64, bool)]) -> String {
    let h = MT + 22.0 * bars.len().max(1) as f64 + 24.0;
    let mut out = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{h}" viewBox="0 0 {W} {h}" class="plot"><rect width="{W}" height="{h}" fill="white"/><text x="{}" y="15" font-size="13" text-anchor="middle" font-family="sans-serif">{}</text>"#,
        W / 2.0,
        svg_text(title)
    );
    let left = 130.0;
    let right = W - 70.0;
    let zero = (left + right) / 2.0;
    let half = (right - left) / 2.0;
    let _ = write!(
        out,
        r##"<text x="{left}" y="33" font-size="10" font-family="sans-serif">← lowers the residual</text><text x="{right}" y="33" font-size="10" text-anchor="end" font-family="sans-serif">raises it →</text><line x1="{zero}" y1="{}" x2="{zero}" y2="{}" stroke="#444"/>"##,
        MT - 4.0,
        h - 20.0
    );
    for tick in [-100.0, -50.0, 0.0, 50.0, 100.0] {
        let x = zero + half * tick / 100.0;
        let _ = write!(
            out,
            r#"<text x="{x:.1}" y="{}" font-size="10" text-anchor="middle" font-family="sans-serif">{}</text>"#,
            h - 6.0,
            if tick == 0.0 {
                "0".to_string()
            } else {
                format!("{tick:+.0} %").replace('-', "−")
            }
        );
    }
    for (k, (label, change, good)) in bars.iter().enumerate() {
        let y = MT + 22.0 * k as f64;
        let frac = if change.is_finite() {
            change.clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let color = if *good { "#2a7" } else { "#999" };
        let (bx, bw) = if frac < 0.0 {
            (zero + half * frac, -half * frac)
        } else {
            (zero, half * frac)
        };
        let (tx, anchor) = if frac < 0.0 {
            (zero + 4.0, "start")
        } else {
            (zero - 4.0, "end")
        };
        let _ = write!(
            out,
            r#"<text x="{}" y="{}" font-size="11" text-anchor="end" font-family="sans-serif">{}</text><rect x="{bx:.1}" y="{}" width="{:.1}" height="14" fill="{color}"/><text x="{tx:.1}" y="{}" font-size="10" text-anchor="{anchor}" font-family="sans-serif">{}</text>"#,
            left - 6.0,
            y + 11.0,
            svg_text(label),
            y,
            bw.max(0.5),
            y + 11.0,
            svg_text(&change_percent(*change, 1))
        );
    }
    out.push_str("</svg>");
    out
}

fn section_diagnosis(html: &mut String, title: &str, d: &Diagnosis) {
    let _ = write!(
        html,
        "<h2>{}</h2><p class=\"verdict\">{}</p>",
        text(title),
        text(&d.verdict)
    );
    html.push_str(
        "<table><tr><th>channel</th><th>fit %</th><th>err %</th><th>residual RMS</th></tr>",
    );
    for c in &d.channels {
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.4e} {}</td></tr>",
            c.name,
            c.fit_percent.map_or("n/a".into(), |f| format!("{f:.1}")),
            percent_cell(c.error_percent, 0),
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
        text(&d.safety_gate)
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
            text(&coefs.join(", ")),
            if e.plausible { "" } else { " (IMPLAUSIBLE)" }
        );
    }
    for w in &d.warnings {
        let _ = write!(html, "<p class=\"warn\">⚠ {}</p>", text(w));
    }
    if !d.findings.is_empty() {
        html.push_str("<h3>Where it fails</h3><ul>");
        for f in &d.findings {
            let _ = write!(html, "<li>{}</li>", text(f));
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
                    dash: "",
                    x: &d.t,
                    y: &m,
                },
                LineSeries {
                    label: "predicted",
                    color: "#d60",
                    dash: "5 3",
                    x: &d.t,
                    y: &p,
                },
            ],
            &[],
            &[],
        ));
    }
    html.push_str("</div>");
    // Residual over time with the failure windows and the noise floor.
    html.push_str(
        "<h3>Residual over time</h3><p class=\"note\">Dashed: ± the channel's noise (what no model can predict). \
         A residual outside it throughout is missing physics; red: windows where the residual is \
         significantly larger than in the rest of the flight; grey: the start transient.</p><div class=\"grid\">",
    );
    for c in 0..6 {
        let r = d.fit.residual_channel(c);
        let spans: Vec<Span> = d
            .failure_windows
            .iter()
            .filter(|f| f.channels.iter().any(|n| n == CHANNEL_NAMES[c]))
            .map(|f| Span {
                start: f.t_start,
                end: f.t_end,
                transient: f.transient,
            })
            .collect();
        let floor = d.noise_floor.rms[c];
        let ratio = d.held_out_rms[c] / floor;
        html.push_str(&line_plot(
            &format!(
                "residual {} [{}], held-out RMS {:.1}× noise",
                CHANNEL_NAMES[c], CHANNEL_UNITS[c], ratio
            ),
            "time [s]",
            &[LineSeries {
                label: "residual",
                color: "#c22",
                dash: "",
                x: &d.t,
                y: &r,
            }],
            &spans,
            &[(floor, "± noise"), (-floor, "")],
        ));
    }
    html.push_str("</div>");
    section_correlations(html, d);
    // Residual vs the top candidate's driver.
    if let (Some(top), Some((dname, dsig))) = (d.ranking.first(), &d.top_driver) {
        let _ = write!(
            html,
            "<h3>Residual against the top candidate's own columns (<code>{}</code>): a line where it is missing</h3><div class=\"grid\">",
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
            // The partial-residual plot: the residual against the candidate's own regressor
            // column on this channel lines up with the coefficient as slope (no loop).
            if let Some(p) = d.partial_residuals.iter().find(|p| p.channel == c) {
                html.push_str(&scatter_plot(
                    &format!(
                        "residual {} [{}] vs column {} of {}",
                        CHANNEL_NAMES[c], CHANNEL_UNITS[c], p.column, p.effect
                    ),
                    &format!(
                        "{} column {} on {} [{}/unit]",
                        p.effect, p.column, CHANNEL_NAMES[c], CHANNEL_UNITS[c]
                    ),
                    &p.x,
                    &p.y,
                    "#36c",
                ));
                continue;
            }
            let r = d.fit.residual_channel(c);
            html.push_str(&scatter_plot(
                &format!(
                    "residual {} [{}] vs {}",
                    CHANNEL_NAMES[c], CHANNEL_UNITS[c], dname
                ),
                dname,
                dsig,
                &r,
                "#36c",
            ));
        }
        html.push_str("</div>");
    }
    // Ranking: the change of the held-out residual, signed as in the explanations.
    html.push_str("<h3>What is missing: ranking (held-out residual change, blocked CV)</h3>");
    let bars: Vec<(String, f64, bool)> = d
        .ranking
        .iter()
        .map(|c| (c.effect.clone(), -c.reduction, c.status.qualifies()))
        .collect();
    html.push_str(&change_chart(
        "held-out residual change per candidate (green: qualifies)",
        &bars,
    ));
    html.push_str("<ol>");
    for c in &d.ranking {
        let _ = write!(html, "<li>{}</li>", text(&c.explanation));
    }
    html.push_str("</ol>");
    for u in &d.unavailable {
        let _ = write!(
            html,
            "<p>{}: skipped, {}</p>",
            escape(&u.effect),
            text(&u.reason)
        );
    }
}

/// MATLAB `resid`'s two kinds of panel: per channel the residual's autocorrelation at lags
/// `0..=MAX_LAG` with the 95 % band of a white residual `±z₀.₉₇₅/√N`; then its
/// cross-correlation with each actual input ([`section_input_correlations`]).
fn section_correlations(html: &mut String, d: &Diagnosis) {
    let n = d.t.len();
    if n < 8 {
        return;
    }
    let dt = (d.t[n - 1] - d.t[0]) / (n - 1) as f64;
    let max_lag = MAX_LAG.min(n / 4);
    let band = crate::fit::Z_95 / (n as f64).sqrt();
    let _ = write!(
        html,
        "<h3>Residual autocorrelation</h3><p class=\"note\">Lags of {} samples ({:.3} s each); \
         shaded: the 95 % band of a white residual (±1.96/√N, N = {n}). Stems outside it: the \
         residual is predictable from its own past, so the model misses a dynamic.</p><div class=\"grid\">",
        max_lag, dt
    );
    for c in 0..6 {
        let r = d.fit.residual_channel(c);
        let rho = stats::autocorrelation(&r, max_lag);
        let lags: Vec<f64> = (0..=max_lag).map(|k| k as f64 * dt).collect();
        html.push_str(&correlation_plot(
            &format!("autocorrelation of residual {}", CHANNEL_NAMES[c]),
            "lag [s]",
            &lags,
            &rho,
            band,
            "95 % band",
        ));
    }
    html.push_str("</div>");
    section_input_correlations(html, d);
}

/// MATLAB `resid`'s cross-correlation of the residual with each actual input
/// ([`crate::input_correlation`]): a matrix of channels × inputs (the largest correlation, its
/// lag and its size in units of the 99 % band), and per channel the stems of the input
/// farthest outside its band.
fn section_input_correlations(html: &mut String, d: &Diagnosis) {
    let xc = &d.input_correlation;
    if xc.is_empty() || !xc.len().is_multiple_of(6) {
        return;
    }
    let per = xc.len() / 6;
    let _ = write!(
        html,
        "<h3>Residual–input cross-correlation (each actual input, as MATLAB <code>resid</code>)</h3>\
         <p class=\"note\">Per channel and input: the correlation of largest magnitude over lags \
         −{l} … {l} samples, its lag (positive: the input leads the residual) and its size in units \
         of the pair's 99 % band (±2.576 √(P/N), Bartlett's P: wider for a smooth residual and a \
         smooth input). Red: outside the band, the residual still depends on that input, so the \
         model misses how it acts. Velocities are body-frame, signed. Grey rows: channels whose \
         held-out residual is within {f}× their noise; a stem outside the band there is the \
         sensors' (the measured wrench is built from the measured rotor speeds: their noise is \
         in both at lag 0), not missing physics.</p><table id=\"xcorr\"><tr><th>residual</th><th>held-out / noise</th>",
        l = (xc[0].correlation.len().saturating_sub(1)) / 2,
        f = crate::ADEQUACY_FACTOR
    );
    for x in &xc[..per] {
        let _ = write!(html, "<th>{} [{}]</th>", escape(&x.input), escape(&x.unit));
    }
    html.push_str("</tr>");
    for c in 0..6 {
        let ratio = d.adequacy.get(c).map_or(f64::NAN, |a| a.ratio);
        let quiet = ratio <= crate::ADEQUACY_FACTOR;
        let _ = write!(
            html,
            "<tr class=\"{}\"><td>{}</td><td>{ratio:.2}</td>",
            if quiet { "quiet" } else { "" },
            CHANNEL_NAMES[c]
        );
        for x in &xc[c * per..(c + 1) * per] {
            let _ = write!(
                html,
                "<td class=\"{}\">{:+.2} @ {:+.2} s ({:.1}×)</td>",
                if x.outside() && !quiet { "warn" } else { "" },
                x.peak,
                x.peak_lag,
                x.peak_over_band
            );
        }
        html.push_str("</tr>");
    }
    html.push_str("</table><div class=\"grid\">");
    for c in 0..6 {
        let row = &xc[c * per..(c + 1) * per];
        let Some(x) = row
            .iter()
            .max_by(|a, b| a.peak_over_band.total_cmp(&b.peak_over_band))
        else {
            continue;
        };
        let l = (x.correlation.len().saturating_sub(1)) / 2;
        let lags: Vec<f64> = (0..x.correlation.len())
            .map(|k| (k as f64 - l as f64) * x.lag_step)
            .collect();
        html.push_str(&correlation_plot(
            &format!(
                "residual {} vs {} (the farthest of {per} inputs){}",
                CHANNEL_NAMES[c],
                x.input,
                if d.adequacy
                    .get(c)
                    .is_some_and(|a| a.ratio <= crate::ADEQUACY_FACTOR)
                {
                    ", at its noise"
                } else {
                    ""
                }
            ),
            "lag [s]",
            &lags,
            &x.correlation,
            x.band,
            "99 % band",
        ));
    }
    html.push_str("</div>");
}

/// Channel colours of the staircase plot (fx … tz).
const CHANNEL_COLORS: [&str; 6] = ["#c22", "#2a7", "#36c", "#d60", "#839", "#555"];
/// Channel dash patterns of the staircase plot, so that equal series stay apart.
const CHANNEL_DASHES: [&str; 6] = ["", "6 3", "2 2", "8 3 2 3", "1 3", "12 4"];

/// The stepwise search: the staircase table (held-out RMS per channel and step, the floor),
/// why it stopped, the command that reproduces the final model, each log's own verdict, and a
/// plot of each channel's held-out RMS over the floor step by step.
fn section_staircase(html: &mut String, report: &Report) {
    html.push_str("<h2 id=\"staircase\">Stepwise: held-out residual RMS per channel (blocked CV), against each channel's noise</h2>");
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
    let noise = &report.noise_floor;
    for (label, values) in [
        ("noise", noise.rms),
        ("of it: measured wrench", noise.from_wrench),
        ("of it: motion sensors", noise.from_motion),
    ] {
        let _ = write!(html, "<tr><td>{label}</td>");
        for f in values {
            let _ = write!(html, "<td>{f:.3e}</td>");
        }
        html.push_str("</tr>");
    }
    html.push_str("</table>");
    let _ = write!(
        html,
        "<p id=\"stopped\">stopped: {}</p><p>final model: <b>{}</b></p>",
        text(&report.stopped),
        text(&report.final_model.label)
    );
    for e in &report.equivalents {
        let _ = write!(html, "<p class=\"equivalent\">{}</p>", text(&e.sentence()));
    }
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
                dash: CHANNEL_DASHES[c],
                x: &x,
                y: &ratios[c],
            })
            .collect();
        html.push_str(&line_plot(
            "log10(held-out RMS / noise) per step (0 = at the noise)",
            "step",
            &series,
            &[],
            &[],
        ));
    }
    if !report.logs.is_empty() {
        html.push_str("<h3>Each log alone</h3><table id=\"logs\"><tr><th>log</th><th>samples</th><th>its own staircase</th><th>its own parameters (95 %), against the others</th><th>verdict</th></tr>");
        for l in &report.logs {
            let params: Vec<String> = l
                .parameters
                .iter()
                .map(|p| {
                    format!(
                        "<span class=\"{}\">{}</span>",
                        if p.consistent { "" } else { "warn" },
                        escape(&p.describe())
                    )
                })
                .collect();
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                escape(&l.log),
                l.samples,
                escape(&l.added.join(" → ")),
                params.join("<br>"),
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
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>tagk diagnose report</title><style>body{font-family:sans-serif;margin:20px;max-width:1450px}table{border-collapse:collapse;margin:8px 16px 8px 0;display:inline-table;vertical-align:top}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}.grid{display:flex;flex-wrap:wrap;gap:6px}.warn{color:#a00}.quiet{color:#999}.verdict{font-weight:bold;font-size:1.1em}.note{color:#444;max-width:1100px}pre{background:#f4f4f4;padding:8px;white-space:pre-wrap}</style></head><body><h1 id=\"title\">tagk diagnose report</h1>",
    );
    // The staircase's first step, and — separately — whether the final model is adequate: a
    // model with nothing left to add need not be at its noise.
    let first_step = if report.final_model.added.is_empty() {
        "nothing (no admissible set of effects)".to_string()
    } else {
        report.final_model.added.join(" + ")
    };
    let _ = write!(
        html,
        "<p id=\"summary\">found: <b>{}</b>; final model {}</p>",
        escape(&first_step),
        if report.adequate {
            "<b>adequate</b> (what remains is the noise)".to_string()
        } else {
            format!(
                "<b class=\"warn\">not adequate</b>: {}",
                escape(&report.final_diagnosis().verdict)
            )
        }
    );
    section_inputs(&mut html, report);
    if !report.streams.is_empty() {
        // The terminal's lines: one wording for both (docs/CONVENTIONS.md §7.2).
        let _ = write!(
            html,
            "<h2 id=\"streams\">Stream timing</h2><pre id=\"stream-timing\">{}</pre>",
            text(
                crate::streams::streams_table(&report.streams)
                    .split_once('\n')
                    .map_or("", |(_, rows)| rows)
            )
        );
    }
    if !report.accelerometer_offsets.is_empty() {
        // The terminal's lines.
        let lines: Vec<String> = report
            .accelerometer_offsets
            .iter()
            .map(crate::accel_offset::AccelerometerOffset::text)
            .collect();
        let _ = write!(
            html,
            "<h2 id=\"accelerometer-offset\">Accelerometer offset</h2><pre>{}</pre>",
            text(&lines.join("\n"))
        );
    }
    if !report.sampling.is_empty() {
        // Every log's findings in the terminal's words, a regular one's rate included.
        let lines: Vec<String> = report
            .sampling
            .iter()
            .map(|f| {
                let body = if f.is_regular() {
                    format!("{} (regular: no gaps, no irregular steps)", f.sampling)
                } else {
                    f.text()
                };
                if f.log.is_empty() {
                    body
                } else {
                    format!("{}:\n{body}", f.log)
                }
            })
            .collect();
        let _ = write!(
            html,
            "<h2 id=\"sampling\">Sampling</h2><pre id=\"sampling-findings\">{}</pre>",
            text(&lines.join("\n"))
        );
    }
    let glitches = crate::glitches::glitches_text(&report.glitches, report.glitch_samples_excluded);
    if !glitches.is_empty() {
        let _ = write!(
            html,
            "<h2 id=\"glitches\">Glitches</h2><pre id=\"glitch-list\">{}</pre>",
            text(&glitches)
        );
    }
    if !report.scale_checks.is_empty() {
        let _ = write!(
            html,
            "<h2 id=\"scale-checks\">Scale checks</h2><pre id=\"scale-findings\" class=\"warn\">{}</pre>",
            text(&crate::scales::scales_text(&report.scale_checks))
        );
    }
    section_staircase(&mut html, report);
    if let (Some(after), Some(change)) = (&report.after, &report.change) {
        let _ = write!(
            html,
            "<h2>Before / after adding {}</h2>",
            escape(&report.with.join(", "))
        );
        html.push_str("<table id=\"before-after\"><tr><th>channel</th><th>fit % before</th><th>fit % after</th><th>err % before</th><th>err % after</th><th>RMS before</th><th>RMS after</th><th>change</th></tr>");
        for c in change {
            let _ = write!(
                html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4e}</td><td>{:.4e}</td><td>{}</td></tr>",
                c.name,
                c.fit_percent_before
                    .map_or("n/a".into(), |f| format!("{f:.1}")),
                c.fit_percent_after
                    .map_or("n/a".into(), |f| format!("{f:.1}")),
                percent_cell(c.error_percent_before, 0),
                percent_cell(c.error_percent_after, 0),
                c.rms_before,
                c.rms_after,
                change_percent(-c.rms_reduction, 1)
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
                        dash: "",
                        x: &report.before.t,
                        y: &rb,
                    },
                    LineSeries {
                        label: "after",
                        color: "#2a7",
                        dash: "5 3",
                        x: &after.t,
                        y: &ra,
                    },
                ],
                &[],
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
    if let Some(v) = &report.validation {
        let _ = write!(
            html,
            "<h2>Validation on {}</h2><p>{} samples; each model as fitted on the diagnosed log (not refitted): residual RMS per channel (N, N m)</p><table><tr><th>model</th>",
            escape(&v.log),
            v.samples
        );
        for c in crate::signals::CHANNEL_NAMES {
            let _ = write!(html, "<th>{c}</th>");
        }
        html.push_str("</tr>");
        for step in &v.steps {
            let _ = write!(html, "<tr><td>{}</td>", escape(&step.model));
            for r in step.rms {
                let _ = write!(html, "<td>{r:.3e}</td>");
            }
            html.push_str("</tr>");
        }
        html.push_str("</table>");
    }
    if let Some(o) = &report.online {
        let t: Vec<f64> = (0..o.mass_history.len()).map(|k| k as f64).collect();
        let _ = write!(
            html,
            "<h2>Online TAG-K pass</h2><p>{} updates on the {} rows; mass {:.4} kg (tail average) against the batch {:.4} kg ({:+.1} %); tail-average distance to the batch estimate {:.3e} (relative)</p>",
            o.updates,
            escape(&o.rows.join(", ")),
            o.tail_average[0],
            o.batch_estimate[0],
            100.0 * o.mass_error_to_batch,
            o.distance_to_batch
        );
        html.push_str(&line_plot(
            "TAG-K mass estimate [kg]",
            "update",
            &[LineSeries {
                label: "mass",
                color: "#36c",
                dash: "",
                x: &t,
                y: &o.mass_history,
            }],
            &[],
            &[],
        ));
    }
    let _ = write!(
        html,
        "<p class=\"note\" id=\"fit-measures\">{}</p>",
        escape(crate::report::FIT_MEASURES).replace('\n', "<br>")
    );
    if let Some(next) = report.next_step() {
        let _ = write!(
            html,
            "<h2 id=\"next\">Next</h2><p>{}:</p><pre><code id=\"next-command\">{}</code></pre>",
            text(&next.why),
            escape(&next.command)
        );
    }
    html.push_str("</body></html>\n");
    html
}

/// Line colours of the models of a comparison, in their order.
const MODEL_COLORS: [&str; 6] = ["#c22", "#36c", "#393", "#c80", "#808", "#088"];

/// The HTML page of a k-step comparison (`tagk compare --report`): per quantity, the mean
/// error against the horizon, one line per model; then per overlay horizon the logged and
/// predicted components over time (the first log only); then the numbers as tables.
pub fn render_comparison(comparison: &crate::predict::Comparison) -> String {
    const COLORS: [&str; 6] = MODEL_COLORS;
    let mut html = String::from(
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>tagk compare</title><style>body{font-family:sans-serif;margin:20px;max-width:1450px}table{border-collapse:collapse;margin:8px 16px 8px 0}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}.grid{display:flex;flex-wrap:wrap;gap:6px}</style></head><body><h1>tagk compare: k-step prediction error</h1><ol id=\"models\">",
    );
    for m in &comparison.models {
        let _ = write!(html, "<li>{}</li>", escape(&m.model));
    }
    html.push_str("</ol><div class=\"grid\">");
    let labels: Vec<String> = comparison
        .models
        .iter()
        .enumerate()
        .map(|(k, m)| {
            if m.model == crate::predict::CONSTANT_RATE {
                m.model.clone()
            } else {
                format!("model {}", k + 1)
            }
        })
        .collect();
    for q in crate::predict::QUANTITIES {
        let (name, unit, get) = (q.name, q.unit, q.error);
        let data: Vec<(Vec<f64>, Vec<f64>)> = comparison
            .models
            .iter()
            .map(|m| {
                (
                    m.horizons.iter().map(|e| e.h as f64).collect(),
                    m.horizons.iter().map(get).collect(),
                )
            })
            .collect();
        let series: Vec<LineSeries<'_>> = data
            .iter()
            .enumerate()
            .map(|(k, (x, y))| LineSeries {
                label: &labels[k],
                color: COLORS[k % COLORS.len()],
                dash: "",
                x,
                y,
            })
            .collect();
        html.push_str(&line_plot(
            &format!("mean {name} error [{unit}]"),
            "horizon [steps]",
            &series,
            &[],
            &[],
        ));
    }
    html.push_str("</div>");
    section_overlays(&mut html, comparison, &labels);
    let _ = writeln!(
        html,
        "<h2>Numbers</h2><pre id=\"table\">{}</pre></body></html>",
        escape(&comparison.table())
    );
    html
}

/// One section per overlay horizon (`id="overlay-h{h}"`): per quantity, each model's error
/// norm over time, then per component the logged series and each model's `h`-step prediction
/// over time, on the first log. Lines are
/// drawn through at most [`MAX_POINTS`] evenly strided samples; the JSON holds every sample.
fn section_overlays(html: &mut String, comparison: &crate::predict::Comparison, labels: &[String]) {
    use crate::predict::{COMPONENTS, QUANTITIES};
    let mut hs: Vec<(usize, f64)> = Vec::new();
    for o in comparison.models.iter().flat_map(|m| &m.overlays) {
        if !hs.iter().any(|(h, _)| *h == o.h) {
            hs.push((o.h, o.dt));
        }
    }
    let several = comparison
        .models
        .iter()
        .flat_map(|m| &m.overlays)
        .any(|o| o.log > 0);
    for (h, dt) in hs {
        let overlays: Vec<Option<&crate::predict::Overlay>> = comparison
            .models
            .iter()
            .map(|m| m.overlays.iter().find(|o| o.h == h && o.log == 0))
            .collect();
        let Some(logged) = overlays.iter().flatten().next() else {
            continue;
        };
        let n = logged.t.len();
        let stride = n.div_ceil(MAX_POINTS).max(1);
        let _ = write!(
            html,
            "<h2 id=\"overlay-h{h}\">Overlay at h = {h} steps ({:.3} s)</h2><p>Per quantity, each model's error norm over time; then per component the logged state (black) and each model's prediction made {h} steps earlier (dashed), plotted at the time the prediction ends.{} Drawn through every {}th of {n} samples (for the page's size only: the JSON holds every sample).</p><div class=\"grid\">",
            h as f64 * dt,
            if several { " First log only." } else { "" },
            stride
        );
        for (q, quantity) in QUANTITIES.iter().enumerate() {
            // The error norm over time, one line per model.
            let errors: Vec<(&[f64], &[f64])> = overlays
                .iter()
                .map(|o| o.map_or((&[][..], &[][..]), |o| (&o.t[..], o.error.of(q))))
                .collect();
            let series: Vec<LineSeries<'_>> = errors
                .iter()
                .enumerate()
                .map(|(k, (x, y))| LineSeries {
                    label: &labels[k],
                    color: MODEL_COLORS[k % MODEL_COLORS.len()],
                    dash: "",
                    x,
                    y,
                })
                .collect();
            html.push_str(&line_plot(
                &format!("{} error [{}], h = {h}", quantity.name, quantity.unit),
                "time [s]",
                &series,
                &[],
                &[],
            ));
            for (c, component) in COMPONENTS[q].iter().enumerate() {
                let ys: Vec<Vec<f64>> = std::iter::once(logged.logged.of(q))
                    .chain(
                        overlays
                            .iter()
                            .map(|o| o.map_or(&[][..], |o| o.predicted.of(q))),
                    )
                    .map(|v| v.iter().map(|r| r[c]).collect())
                    .collect();
                let xs: Vec<&[f64]> = std::iter::once(&logged.t[..])
                    .chain(overlays.iter().map(|o| o.map_or(&[][..], |o| &o.t[..])))
                    .collect();
                let mut series = vec![LineSeries {
                    label: "logged",
                    color: "#000",
                    dash: "",
                    x: xs[0],
                    y: &ys[0],
                }];
                for k in 0..overlays.len() {
                    series.push(LineSeries {
                        label: &labels[k],
                        color: MODEL_COLORS[k % MODEL_COLORS.len()],
                        dash: "4 2",
                        x: xs[k + 1],
                        y: &ys[k + 1],
                    });
                }
                html.push_str(&line_plot(
                    &format!("{} {component} [{}], h = {h}", quantity.name, quantity.unit),
                    "time [s]",
                    &series,
                    &[],
                    &[],
                ));
            }
        }
        html.push_str("</div>");
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_data() {
        // The issue's case: a time axis from 0.01 to 24.99 s.
        let a = Axis::new(0.01, 24.99, 6);
        let labels: Vec<String> = a.ticks.iter().map(|&v| a.label(v)).collect();
        assert_eq!(labels, ["0", "5", "10", "15", "20", "25"]);
        assert!(a.lo <= 0.01 && a.hi >= 24.99);
        // Lags from 0: the axis starts at 0, not a step before it.
        let lags = Axis::new(0.0, 0.5, 6);
        assert_eq!(lags.lo, 0.0);
        assert_eq!(lags.label(0.3), "0.3");
        // Small values are labelled in units of a power of ten, named once.
        let small = Axis::new(-2.1e-3, 2.9e-3, 5);
        assert_eq!(small.scale_note(), " (×1e-3)");
        assert!(small.ticks.iter().all(|&v| {
            let l = small.label(v);
            l.chars().count() <= 2 && !l.contains('e')
        }));
        assert_eq!(small.label(-2e-3), "−2");
    }

    #[test]
    fn backticks_become_code_and_never_reach_the_page() {
        assert_eq!(
            text("missing physics: `rotor-drag` (-45 %) <b>"),
            "missing physics: <code>rotor-drag</code> (-45 %) &lt;b&gt;"
        );
        assert_eq!(svg_text("a `b`"), "a b");
    }

    #[test]
    fn the_change_chart_signs_match_the_text() {
        // A candidate that lowers the residual by 45 % is drawn left of zero and labelled
        // −45.0 %, as the explanation says; one that makes it 190 times larger is clipped
        // at +100 % and labelled ×190.
        let svg = change_chart(
            "t",
            &[("good".into(), -0.45, true), ("bad".into(), 189.0, false)],
        );
        assert!(svg.contains("-45.0 %"));
        assert!(svg.contains("×190"));
        let zero = (130.0 + (W - 70.0)) / 2.0;
        let good_x: f64 = svg
            .split("<rect x=\"")
            .nth(1)
            .and_then(|r| r.split('"').next())
            .and_then(|v| v.parse().ok())
            .unwrap();
        assert!(
            good_x < zero,
            "the good bar starts at {good_x}, zero at {zero}"
        );
    }
}
