//! Figures with plotters (PNG and SVG, no system libraries): the embedded DejaVu Sans font
//! (`assets/DejaVuSans.ttf`, licence in `assets/DejaVuSans-LICENSE.txt`) is registered with
//! plotters' ab_glyph backend as `"sans-serif"`.

use std::path::Path;
use std::sync::Once;

use std::ops::Range;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::SimError;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Registers the embedded font (idempotent).
pub fn register_embedded_font() {
    REGISTER.call_once(|| {
        // The embedded TTF is valid (a test renders a figure with it).
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

fn perr<E: std::fmt::Display>(e: E) -> SimError {
    SimError::Plot(e.to_string())
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

/// Colour of series `i`.
pub fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Ticks of one axis: the drawn range, the labelled ticks and the unlabelled grid lines.
///
/// [`linear_ticks`], [`log_ticks`] and [`category_ticks`] build it; every figure of this
/// module draws its axes from it (one source of truth for ticks and their labels).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisTicks {
    /// Drawn axis range `(lo, hi)` in data units, slightly wider than the labelled ticks.
    pub range: (f64, f64),
    /// Labelled ticks `(value, label)`, increasing; the first is ≤ the data minimum and the
    /// last ≥ the data maximum.
    pub labelled: Vec<(f64, String)>,
    /// Unlabelled grid lines between the labelled ticks, increasing.
    pub minor: Vec<f64>,
    /// Logarithmic axis.
    pub log: bool,
}

impl AxisTicks {
    /// The values of the labelled ticks.
    pub fn values(&self) -> Vec<f64> {
        self.labelled.iter().map(|(v, _)| *v).collect()
    }

    /// The label of the tick at `v` (empty if `v` is not a labelled tick).
    pub fn label_of(&self, v: f64) -> String {
        self.labelled
            .iter()
            .find(|(t, _)| (t - v).abs() <= 1e-9 * t.abs().max(v.abs()).max(1e-300))
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }
}

/// A power of ten in superscript digits (`10⁻³`).
fn power_of_ten(exp: i32) -> String {
    const SUP: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let digits: String = exp
        .unsigned_abs()
        .to_string()
        .chars()
        .map(|c| SUP[c.to_digit(10).unwrap_or(0) as usize])
        .collect();
    format!("10{}{digits}", if exp < 0 { "⁻" } else { "" })
}

/// `v` with `decimals` decimals, trailing zeros dropped, a Unicode minus (`−0.5`, `20`).
fn plain(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s.as_str()
    };
    if s == "-0" {
        "0".into()
    } else {
        s.replace('-', "−")
    }
}

/// `v` as `m×10ⁿ` (or `10ⁿ` when `m` is 1), `m` to three significant digits.
fn scientific(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let exp = v.abs().log10().floor() as i32;
    let mantissa = (v / 10f64.powi(exp) * 100.0).round() / 100.0;
    if (mantissa - 1.0).abs() < 1e-9 {
        power_of_ten(exp)
    } else if (mantissa + 1.0).abs() < 1e-9 {
        format!("−{}", power_of_ten(exp))
    } else {
        format!("{}×{}", plain(mantissa, 2), power_of_ten(exp))
    }
}

/// Labels of ticks whose values need at most `decimals` decimals: plain numbers while every
/// tick lies in `[0.001, 10⁵)` in magnitude (or is 0), else `m×10ⁿ` for all of them.
fn tick_labels(values: &[f64], decimals: usize) -> Vec<(f64, String)> {
    let plain_ok = values
        .iter()
        .all(|v| *v == 0.0 || (1e-3..1e5).contains(&v.abs()));
    values
        .iter()
        .map(|v| {
            let l = if plain_ok {
                plain(*v, decimals)
            } else {
                scientific(*v)
            };
            (*v, l)
        })
        .collect()
}

/// Decimals needed to print `v` (a 1-2-5 step or a tick `m·10ᵏ`) exactly.
fn decimals_of(v: f64) -> usize {
    (-(v.abs().log10() + 1e-9).floor()).max(0.0) as usize
}

/// Share of the labelled span added on each side of an axis, so that markers on the extreme
/// ticks are drawn whole.
const AXIS_PAD: f64 = 0.03;

/// Ticks of a linear axis holding the data range `[lo, hi]`: 1-2-5 steps, 4 to 7 intervals,
/// the outer labelled ticks bracketing the data. An empty or single-valued range is widened;
/// a range beyond `f64` falls back to `[0, 1]`.
pub fn linear_ticks(lo: f64, hi: f64) -> AxisTicks {
    let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() && lo <= hi {
        (lo, hi)
    } else {
        (0.0, 1.0)
    };
    if hi - lo <= 1e-12 * lo.abs().max(hi.abs()).max(1e-300) {
        let d = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
        lo -= d;
        hi += d;
    }
    let span = hi - lo;
    if !span.is_finite() {
        // Beyond f64's range: no tick could bracket it.
        return linear_ticks(0.0, 1.0);
    }
    // The smallest 1-2-5 step giving at most 7 intervals.
    let mut k = (span / 7.0).log10().floor() as i32 - 1;
    let (step, mantissa) = 'search: loop {
        for m in [1.0, 2.0, 5.0] {
            let step = m * 10f64.powi(k);
            let n = (hi / step - 1e-9).ceil() - (lo / step + 1e-9).floor();
            if n <= 7.0 {
                break 'search (step, m);
            }
        }
        if k > 310 {
            return linear_ticks(0.0, 1.0);
        }
        k += 1;
    };
    let (i0, i1) = (
        (lo / step + 1e-9).floor() as i64,
        (hi / step - 1e-9).ceil() as i64,
    );
    let decimals = decimals_of(step);
    let values: Vec<f64> = (i0..=i1)
        .map(|i| {
            let v = i as f64 * step;
            // Drop the float noise of i·step (0.30000000000000004).
            let q = 10f64.powi(decimals as i32 + 3);
            (v * q).round() / q
        })
        .collect();
    let sub = if mantissa == 2.0 { 4 } else { 5 };
    let minor = (i0 * sub..i1 * sub)
        .filter(|j| j % sub != 0)
        .map(|j| j as f64 * step / sub as f64)
        .collect();
    let (a, b) = (values[0], values[values.len() - 1]);
    let pad = AXIS_PAD * (b - a);
    AxisTicks {
        range: (a - pad, b + pad),
        labelled: tick_labels(&values, decimals),
        minor,
        log: false,
    }
}

/// Ticks of a logarithmic axis holding the positive data range `[lo, hi]`.
///
/// Two decades or more: the decades bracketing the data, labelled (every other one beyond
/// eight). Less: the 1-2-5 values bracketing the data, labelled; below a factor of 4, every
/// `m·10ᵏ` (`m` = 1…9); below a factor of 2, linear 1-2-5 steps. Grid lines at every
/// `m·10ᵏ`. A non-positive or non-finite bound falls back to `[1, 10]`.
pub fn log_ticks(lo: f64, hi: f64) -> AxisTicks {
    let (lo, hi) = if lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi {
        (lo, hi)
    } else {
        (1.0, 10.0)
    };
    if hi / lo < 2.0 {
        let mut t = linear_ticks(lo, hi);
        if t.labelled[0].0 > 0.0 {
            t.log = true;
            let (a, b) = (t.labelled[0].0, t.labelled[t.labelled.len() - 1].0);
            let pad = (b / a).powf(AXIS_PAD);
            t.range = (a / pad, b * pad);
            return t;
        }
    }
    let (e0, e1) = (
        (lo.log10() + 1e-9).floor() as i32,
        (hi.log10() - 1e-9).ceil() as i32,
    );
    let decades = (hi / lo).log10();
    let tick = |m: f64, e: i32| {
        // m·10ᵉ computed as a division for negative e: exact for 0.1, 0.2, 0.5.
        if e < 0 {
            m / 10f64.powi(-e)
        } else {
            m * 10f64.powi(e)
        }
    };
    let all: Vec<(f64, f64, i32)> = (e0 - 1..=e1)
        .flat_map(|e| (1..10).map(move |m| (m as f64, e)))
        .map(|(m, e)| (tick(m, e), m, e))
        .collect();
    let labelled_mantissa = |m: f64| -> bool {
        if decades >= 2.0 {
            m == 1.0
        } else if decades >= 4f64.log10() {
            [1.0, 2.0, 5.0].contains(&m)
        } else {
            true
        }
    };
    let candidates: Vec<f64> = all
        .iter()
        .filter(|(_, m, _)| labelled_mantissa(*m))
        .map(|(v, _, _)| *v)
        .chain(std::iter::once(tick(1.0, e1)))
        .collect();
    let a = candidates
        .iter()
        .copied()
        .filter(|v| *v <= lo * (1.0 + 1e-9))
        .fold(f64::MIN, f64::max);
    let b = candidates
        .iter()
        .copied()
        .filter(|v| *v >= hi * (1.0 - 1e-9))
        .fold(f64::MAX, f64::min);
    let mut values: Vec<f64> = candidates
        .iter()
        .copied()
        .filter(|v| *v >= a * (1.0 - 1e-9) && *v <= b * (1.0 + 1e-9))
        .collect();
    values.dedup_by(|x, y| (*x - *y).abs() <= 1e-9 * x.abs());
    if decades >= 2.0 && values.len() > 9 {
        // Every other decade, keeping both ends.
        let last = values.len() - 1;
        values = values
            .iter()
            .enumerate()
            .filter(|(i, _)| (last - i).is_multiple_of(2) || *i == 0)
            .map(|(_, v)| *v)
            .collect();
    }
    let minor = all
        .iter()
        .map(|(v, _, _)| *v)
        .filter(|v| *v > a && *v < b && !values.iter().any(|t| (t - v).abs() <= 1e-9 * v))
        .collect();
    let decimals = values.iter().map(|v| decimals_of(*v)).max().unwrap_or(0);
    let pad = (b / a).powf(AXIS_PAD);
    AxisTicks {
        range: (a / pad, b * pad),
        labelled: tick_labels(&values, decimals),
        minor,
        log: true,
    }
}

/// Ticks of a data range on a linear or logarithmic axis ([`linear_ticks`], [`log_ticks`]).
pub fn axis_ticks(lo: f64, hi: f64, log: bool) -> AxisTicks {
    if log {
        log_ticks(lo, hi)
    } else {
        linear_ticks(lo, hi)
    }
}

/// Ticks of a categorical axis: category `i` at `x = i`, labelled by its name.
pub fn category_ticks(names: &[String]) -> AxisTicks {
    AxisTicks {
        range: (-0.4, names.len().max(1) as f64 - 0.6),
        labelled: names
            .iter()
            .enumerate()
            .map(|(i, n)| (i as f64, n.clone()))
            .collect(),
        minor: vec![],
        log: false,
    }
}

/// The scale of a [`TickedAxis`].
enum Scale {
    Linear(RangedCoordf64),
    Log(LogCoord<f64>),
}

/// A plotters coordinate drawn with the ticks of an [`AxisTicks`]: its labelled ticks as the
/// bold key points, its grid lines as the light ones.
struct TickedAxis {
    scale: Scale,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl TickedAxis {
    fn new(t: &AxisTicks) -> Self {
        let r = t.range.0..t.range.1;
        Self {
            scale: if t.log {
                Scale::Log(r.log_scale().into())
            } else {
                Scale::Linear(r.into())
            },
            bold: t.values(),
            light: t.minor.clone(),
        }
    }
}

impl Ranged for TickedAxis {
    type ValueType = f64;
    type FormatOption = DefaultFormatting;

    fn range(&self) -> Range<f64> {
        match &self.scale {
            Scale::Linear(c) => c.range(),
            Scale::Log(c) => c.range(),
        }
    }

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        match &self.scale {
            Scale::Linear(c) => c.map(value, limit),
            Scale::Log(c) => c.map(value, limit),
        }
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }
}

/// One named polyline.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartSeries {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`; non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
}

/// A 2-D line chart.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineChart {
    /// Title.
    pub title: String,
    /// x-axis label (with its unit, e.g. `time t [s]`).
    pub x_label: String,
    /// y-axis label (with its unit).
    pub y_label: String,
    /// Logarithmic x axis (ignored on a categorical x axis).
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// ChartSeries.
    pub series: Vec<ChartSeries>,
    /// Vertical marker lines at these x values (e.g. payload events).
    pub markers: Vec<f64>,
    /// Categorical x axis: the series' x values are the indices `0, 1, …` of these
    /// categories, each labelled by its name (empty: a numeric x axis).
    pub x_categories: Vec<String>,
}

/// Axes of a chart: x and y ticks.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartAxes {
    /// x axis.
    pub x: AxisTicks,
    /// y axis.
    pub y: AxisTicks,
}

/// Largest span a log axis shows \[decades\]: exact values (an estimate equal to the prior)
/// would otherwise squash every curve against the top. Smaller values sit on the bottom edge.
const LOG_DECADES: f64 = 8.0;

/// Range `(min, max)` of the values `v` a chart draws (finite; positive on a log axis, at
/// most [`LOG_DECADES`] below the maximum); `None` if there are none.
fn data_range(values: impl Iterator<Item = f64>, log: bool) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return None;
    }
    Some(if log {
        (lo.max(hi * 10f64.powf(-LOG_DECADES)), hi)
    } else {
        (lo, hi)
    })
}

/// The axes `chart` is drawn with. Each range comes from the data through [`axis_ticks`]:
/// finite values, on a log axis positive ones at most 8 decades below the largest. A
/// categorical x axis comes from [`category_ticks`]. A linear y axis of non-negative data
/// starts at 0 when the data's minimum is at most half its maximum.
pub fn chart_axes(chart: &LineChart) -> ChartAxes {
    let points = || {
        chart
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    };
    let x =
        if chart.x_categories.is_empty() {
            let (lo, hi) = data_range(points().map(|p| p.0), chart.log_x)
                .unwrap_or(if chart.log_x { (1.0, 10.0) } else { (0.0, 1.0) });
            axis_ticks(lo, hi, chart.log_x)
        } else {
            category_ticks(&chart.x_categories)
        };
    let (mut lo, hi) = data_range(points().map(|p| p.1), chart.log_y).unwrap_or(if chart.log_y {
        (1.0, 10.0)
    } else {
        (0.0, 1.0)
    });
    if !chart.log_y && lo >= 0.0 && lo <= 0.5 * hi {
        lo = 0.0;
    }
    ChartAxes {
        x,
        y: axis_ticks(lo, hi, chart.log_y),
    }
}

/// Dash pattern `(dash, gap)` of series `i` in pixels at scale 1 (`None`: solid), so that
/// series that coincide stay apart.
fn dash(i: usize) -> Option<(u32, u32)> {
    [
        None,
        Some((9, 5)),
        Some((3, 4)),
        Some((14, 4)),
        Some((6, 3)),
        Some((2, 6)),
    ][i % 6]
}

/// Draws the marker of series `i` (circle, triangle, square, cross, filled circle) at a
/// pixel position on `area`, `r` pixels in size (the legend's; [`draw_styled`] draws the
/// same shapes in data coordinates).
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    i: usize,
    (x, y): (i32, i32),
    r: i32,
    c: RGBColor,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    let style = c.stroke_width(2);
    match i % 5 {
        0 => area.draw(&Circle::new((x, y), r, style)),
        1 => area.draw(&TriangleMarker::new((x, y), r + 1, style.filled())),
        2 => area.draw(&Rectangle::new([(x - r, y - r), (x + r, y + r)], style)),
        3 => area.draw(&Cross::new((x, y), r, style)),
        _ => area.draw(&Circle::new((x, y), r, style.filled())),
    }
    .map_err(perr)
}

/// A polyline in data coordinates with series `i`'s dash pattern, and its markers at about a
/// dozen points (staggered by series so that coinciding series show every marker) and at
/// its last point.
fn draw_styled<DB: DrawingBackend, CT>(
    ctx: &mut ChartContext<'_, DB, CT>,
    i: usize,
    pts: &[(f64, f64)],
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate<From = (f64, f64)>,
{
    let c = colour(i);
    let style = c.stroke_width(2 * scale);
    match dash(i) {
        None => {
            ctx.draw_series(LineSeries::new(pts.iter().copied(), style))
                .map_err(perr)?;
        }
        Some((d, g)) => {
            ctx.draw_series(DashedLineSeries::new(
                pts.iter().copied(),
                d * scale,
                g * scale,
                style,
            ))
            .map_err(perr)?;
        }
    }
    let every = (pts.len() / 12).max(1);
    let offset = (i * every / 5).min(pts.len().saturating_sub(1));
    let mut at: Vec<(f64, f64)> = pts.iter().copied().skip(offset).step_by(every).collect();
    // The last point always: a dash gap can hide a series' end (a CDF's last step to 1).
    if let Some(last) = pts.last()
        && at.last() != Some(last)
    {
        at.push(*last);
    }
    let r = 4 * scale as i32;
    let st = c.stroke_width(2 * scale);
    let e = |p: (f64, f64)| EmptyElement::at(p);
    match i % 5 {
        0 => ctx.draw_series(at.into_iter().map(|p| e(p) + Circle::new((0, 0), r, st))),
        1 => ctx.draw_series(
            at.into_iter()
                .map(|p| e(p) + TriangleMarker::new((0, 0), r + 1, st.filled())),
        ),
        2 => ctx.draw_series(
            at.into_iter()
                .map(|p| e(p) + Rectangle::new([(-r, -r), (r, r)], st)),
        ),
        3 => ctx.draw_series(at.into_iter().map(|p| e(p) + Cross::new((0, 0), r, st))),
        _ => ctx.draw_series(
            at.into_iter()
                .map(|p| e(p) + Circle::new((0, 0), r, st.filled())),
        ),
    }
    .map_err(perr)?;
    Ok(())
}

/// Legend font size \[px at scale 1\].
const LEGEND_FONT: u32 = 15;
/// Legend row height \[px at scale 1\].
const LEGEND_ROW: i32 = 22;
/// Width of a legend entry's line sample and the gap after it \[px at scale 1\].
const LEGEND_SAMPLE: i32 = 38;
/// Widest legend column kept right of the plot, as a share of the figure's width; a wider
/// legend goes below the plot.
const LEGEND_RIGHT_MAX: f64 = 0.3;

/// Width of `text` in the embedded font at `px` pixels (the width plotters draws it with).
fn text_width(text: &str, px: u32) -> i32 {
    register_embedded_font();
    ("sans-serif", px).into_font().box_size(text).map_or(
        (px as usize * 7 / 10 * text.chars().count()) as i32,
        |(w, _)| w as i32,
    )
}

/// Where a figure's legend goes, sized from its entries.
#[derive(Debug, Clone, PartialEq)]
struct Legend {
    /// A column right of the plot (`true`) or rows below it.
    right: bool,
    /// Width (right) or height (below) of the legend strip \[px\].
    size: u32,
    /// Top-left corner of each entry inside the strip \[px\].
    at: Vec<(i32, i32)>,
    /// The labels drawn (a label wider than the figure is cut with `…`).
    labels: Vec<String>,
}

/// Lays out the legend of `labels` for a figure `width` pixels wide at `scale`: one column
/// right of the plot if it fits in [`LEGEND_RIGHT_MAX`] of the width, else centred rows of
/// equal columns below it. Every entry lies inside the figure.
fn legend_layout(labels: &[&str], width: u32, scale: u32) -> Legend {
    let s = scale as i32;
    let px = LEGEND_FONT * scale;
    let entry = |l: &str| LEGEND_SAMPLE * s + text_width(l, px) + 14 * s;
    let widest = labels.iter().map(|l| entry(l)).max().unwrap_or(0);
    let margin = 14 * s;
    if labels.is_empty() || f64::from(widest + 2 * margin) <= LEGEND_RIGHT_MAX * f64::from(width) {
        return Legend {
            right: true,
            size: (widest + margin).max(0) as u32,
            at: (0..labels.len() as i32)
                .map(|i| (6 * s, 60 * s + i * LEGEND_ROW * s))
                .collect(),
            labels: labels.iter().map(|l| l.to_string()).collect(),
        };
    }
    let usable = width as i32 - 2 * margin;
    let col = widest.min(usable);
    let cols = (usable / col.max(1)).clamp(1, labels.len() as i32);
    let rows = (labels.len() as i32 + cols - 1) / cols;
    let x0 = margin + (usable - cols * col) / 2;
    let fit = |l: &str| {
        if entry(l) <= col {
            return l.to_string();
        }
        let mut t: Vec<char> = l.chars().collect();
        while !t.is_empty() && entry(&format!("{}…", t.iter().collect::<String>())) > col {
            t.pop();
        }
        format!("{}…", t.into_iter().collect::<String>())
    };
    Legend {
        right: false,
        size: (rows * LEGEND_ROW * s + 12 * s) as u32,
        at: (0..labels.len() as i32)
            .map(|i| (x0 + (i % cols) * col, 2 * s + (i / cols) * LEGEND_ROW * s))
            .collect(),
        labels: labels.iter().map(|l| fit(l)).collect(),
    }
}

/// Splits `root` into the plot area and the legend strip of `legend`.
fn split_for_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    legend: &Legend,
) -> (DrawingArea<DB, Shift>, DrawingArea<DB, Shift>) {
    let (w, h) = root.dim_in_pixel();
    if legend.right {
        root.split_horizontally(w.saturating_sub(legend.size))
    } else {
        root.split_vertically(h.saturating_sub(legend.size))
    }
}

/// Draws `legend` on its strip: each series' line with its dash pattern and marker, and its
/// label.
fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    legend: &Legend,
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    let s = scale as i32;
    for (i, (label, (x, top))) in legend.labels.iter().zip(&legend.at).enumerate() {
        let (x, yy) = (*x, top + 8 * s);
        let c = colour(i);
        let style = c.stroke_width(2 * scale);
        let line = vec![(x, yy), (x + 30 * s, yy)];
        match dash(i) {
            None => area.draw(&PathElement::new(line, style)).map_err(perr)?,
            Some((d, g)) => {
                let (d, g) = (d as i32 * s, g as i32 * s);
                let mut a = x;
                while a < x + 30 * s {
                    let b = (a + d).min(x + 30 * s);
                    area.draw(&PathElement::new(vec![(a, yy), (b, yy)], style))
                        .map_err(perr)?;
                    a = b + g;
                }
            }
        }
        draw_marker(area, i, (x + 15 * s, yy), 4 * s, c)?;
        area.draw(&Text::new(
            label.clone(),
            (x + LEGEND_SAMPLE * s, yy - 8 * s),
            ("sans-serif", LEGEND_FONT * scale).into_font(),
        ))
        .map_err(perr)?;
    }
    Ok(())
}

/// Draws `chart` on `root` at `scale`, its axes from [`chart_axes`].
fn draw_lines<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    chart: &LineChart,
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(perr)?;
    let axes = chart_axes(chart);
    let (y0, y1) = axes.y.range;
    let (x0, x1) = axes.x.range;
    let labels: Vec<&str> = chart.series.iter().map(|s| s.label.as_str()).collect();
    let legend = legend_layout(&labels, root.dim_in_pixel().0, scale);
    let (plot_area, legend_area) = split_for_legend(&root, &legend);
    let mut builder = ChartBuilder::on(&plot_area);
    builder
        .caption(&chart.title, ("sans-serif", 22 * scale))
        .margin(14 * scale)
        .x_label_area_size(50 * scale)
        .y_label_area_size(84 * scale);
    let x_formatter = |v: &f64| axes.x.label_of(*v);
    let y_formatter = |v: &f64| axes.y.label_of(*v);
    let log_x = axes.x.log;
    let mut ctx = builder
        .build_cartesian_2d(TickedAxis::new(&axes.x), TickedAxis::new(&axes.y))
        .map_err(perr)?;
    let mut mesh = ctx.configure_mesh();
    mesh.y_label_formatter(&y_formatter)
        .x_label_formatter(&x_formatter)
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .label_style(("sans-serif", 15 * scale))
        .axis_desc_style(("sans-serif", 16 * scale));
    if !chart.x_categories.is_empty() {
        mesh.disable_x_mesh();
    }
    mesh.draw().map_err(perr)?;
    for m in &chart.markers {
        ctx.draw_series(LineSeries::new(
            vec![(*m, y0), (*m, y1)],
            BLACK.mix(0.3).stroke_width(scale),
        ))
        .map_err(perr)?;
    }
    for (i, s) in chart.series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| {
                x.is_finite() && y.is_finite() && (!chart.log_y || *y > 0.0) && (!log_x || *x > 0.0)
            })
            .map(|(x, y)| (x.clamp(x0, x1), y.clamp(y0, y1)))
            .collect();
        draw_styled(&mut ctx, i, &pts, scale)?;
    }
    draw_legend(&legend_area, &legend, scale)?;
    root.present().map_err(perr)?;
    Ok(())
}

/// Figure size at scale 1 \[px\]: the SVG's size; the PNG is drawn at [`PNG_SCALE`] times it.
const SIZE: (u32, u32) = (900, 560);
/// Size of the 3-D figure at scale 1 \[px\].
const SIZE_3D: (u32, u32) = (900, 700);
/// The PNG's scale over the SVG: 1800 px wide, 300 dpi at 6 in, a page-wide figure.
pub const PNG_SCALE: u32 = 2;

/// An RGB image in memory: `width × height` pixels, 3 bytes each, row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    /// Width \[px\].
    pub width: u32,
    /// Height \[px\].
    pub height: u32,
    /// Pixels, `(r, g, b)` row-major from the top-left.
    pub rgb: Vec<u8>,
}

impl Raster {
    fn new((width, height): (u32, u32)) -> Self {
        Self {
            width,
            height,
            rgb: vec![255; width as usize * height as usize * 3],
        }
    }

    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: u32, y: u32) -> (u8, u8, u8) {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        (self.rgb[i], self.rgb[i + 1], self.rgb[i + 2])
    }
}

/// Draws `chart` to `<stem>.svg` (900×560 px) and `<stem>.png` (1800×1120 px: 300 dpi at
/// 6 in wide). The axes come from [`chart_axes`]. The legend sits right of the data, or
/// below it when its entries are too wide. Each series has its own dash pattern and marker,
/// so that coinciding series stay visible.
///
/// # Errors
/// [`SimError::Plot`] if drawing or writing fails.
pub fn line_chart(stem: &Path, chart: &LineChart) -> Result<(), SimError> {
    register_embedded_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_lines(
        BitMapBackend::new(&png, (SIZE.0 * PNG_SCALE, SIZE.1 * PNG_SCALE)).into_drawing_area(),
        chart,
        PNG_SCALE,
    )?;
    draw_lines(SVGBackend::new(&svg, SIZE).into_drawing_area(), chart, 1)?;
    Ok(())
}

/// Draws `chart` as [`line_chart`] does, at `scale` (the PNG's is [`PNG_SCALE`]), into memory.
///
/// # Errors
/// [`SimError::Plot`] if drawing fails.
pub fn render_line_chart(chart: &LineChart, scale: u32) -> Result<Raster, SimError> {
    register_embedded_font();
    let mut r = Raster::new((SIZE.0 * scale, SIZE.1 * scale));
    let size = (r.width, r.height);
    draw_lines(
        BitMapBackend::with_buffer(&mut r.rgb, size).into_drawing_area(),
        chart,
        scale,
    )?;
    Ok(r)
}

/// Empirical CDF points of `values` (non-finite values are dropped): `(x_i, i/n)` for the
/// sorted values, one point per value.
pub fn cdf(values: &[f64]) -> Vec<(f64, f64)> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    v.iter()
        .enumerate()
        .map(|(i, x)| (*x, (i + 1) as f64 / n))
        .collect()
}

/// The empirical CDF of `values` as a staircase to draw as a polyline: from `(x₁, 0)`, up
/// at each sorted value and flat between them, ending at `(x_n, 1)`. Non-finite values are
/// dropped; no values give no points.
pub fn cdf_steps(values: &[f64]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut below = 0.0;
    for (x, f) in cdf(values) {
        out.push((x, below));
        out.push((x, f));
        below = f;
    }
    out
}

/// One 3-D path for [`path_chart_3d`].
#[derive(Debug, Clone, PartialEq)]
pub struct Path3 {
    /// Legend label.
    pub label: String,
    /// Points `(x, y, z)` \[m\].
    pub points: Vec<(f64, f64, f64)>,
    /// Points to mark with a cross (aborts, payload events).
    pub marks: Vec<(f64, f64, f64)>,
}

/// Ticks of the world x, y and z axes of [`path_chart_3d`] \[m\]: [`linear_ticks`] of each
/// coordinate's range, widened to at least 0.1 m.
pub fn paths_3d_axes(paths: &[Path3]) -> [AxisTicks; 3] {
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for (x, y, z) in paths.iter().flat_map(|p| p.points.iter()) {
        for (i, v) in [*x, *y, *z].iter().enumerate() {
            if v.is_finite() {
                lo[i] = lo[i].min(*v);
                hi[i] = hi[i].max(*v);
            }
        }
    }
    std::array::from_fn(|i| {
        let (mut a, mut b) = (lo[i], hi[i]);
        if a > b {
            (a, b) = (0.0, 1.0);
        }
        if b - a < 0.1 {
            let c = 0.5 * (a + b);
            (a, b) = (c - 0.05, c + 0.05);
        }
        linear_ticks(a, b)
    })
}

fn draw_3d<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    paths: &[Path3],
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(perr)?;
    let axes = paths_3d_axes(paths);
    let lo: [f64; 3] = std::array::from_fn(|i| axes[i].range.0);
    let hi: [f64; 3] = std::array::from_fn(|i| axes[i].range.1);
    let labels: Vec<&str> = paths.iter().map(|p| p.label.as_str()).collect();
    let legend = legend_layout(&labels, root.dim_in_pixel().0, scale);
    let (plot_area, legend_area) = split_for_legend(&root, &legend);
    let key = |i: usize| TickedAxis::new(&axes[i]);
    let mut ctx = ChartBuilder::on(&plot_area)
        .caption(title, ("sans-serif", 22 * scale))
        .margin(14 * scale)
        .margin_left(60 * scale)
        .build_cartesian_3d(key(0), key(2), key(1))
        .map_err(perr)?;
    let (fx, fy, fz) = (
        |v: &f64| axes[0].label_of(*v),
        |v: &f64| axes[2].label_of(*v),
        |v: &f64| axes[1].label_of(*v),
    );
    ctx.configure_axes()
        .x_formatter(&fx)
        .y_formatter(&fy)
        .z_formatter(&fz)
        .label_style(("sans-serif", 13 * scale))
        .draw()
        .map_err(perr)?;
    // Axis names beside the axes (plotters' 3-D axes have no descriptions of their own).
    let font = ("sans-serif", 17 * scale).into_font();
    let mid = |i: usize| 0.5 * (lo[i] + hi[i]);
    let pad = |i: usize| 0.12 * (hi[i] - lo[i]);
    for (name, at) in [
        ("x [m]", (mid(0), lo[2], hi[1] + 2.5 * pad(1))),
        ("y [m]", (hi[0] + pad(0), lo[2], mid(1))),
        ("z [m]", (lo[0], hi[2] + 0.5 * pad(2), lo[1])),
    ] {
        ctx.draw_series(std::iter::once(Text::new(name, at, font.clone())))
            .map_err(perr)?;
    }
    for (i, p) in paths.iter().enumerate() {
        let c = colour(i);
        let pts: Vec<(f64, f64, f64)> = p.points.iter().map(|(x, y, z)| (*x, *z, *y)).collect();
        match dash(i) {
            None => {
                ctx.draw_series(LineSeries::new(pts, c.stroke_width(2 * scale)))
                    .map_err(perr)?;
            }
            Some((d, g)) => {
                ctx.draw_series(DashedLineSeries::new(
                    pts,
                    d * scale,
                    g * scale,
                    c.stroke_width(2 * scale),
                ))
                .map_err(perr)?;
            }
        }
        ctx.draw_series(p.marks.iter().map(|(x, y, z)| {
            Cross::new((*x, *z, *y), 6 * scale as i32, c.stroke_width(2 * scale))
        }))
        .map_err(perr)?;
    }
    draw_legend(&legend_area, &legend, scale)?;
    root.present().map_err(perr)?;
    Ok(())
}

/// Draws 3-D paths (x, y horizontal, z up; axes labelled in m, ticks from
/// [`paths_3d_axes`]) to `<stem>.svg` (900×700 px) and `<stem>.png` (1800×1400 px), the
/// legend right of the plot or below it.
///
/// # Errors
/// [`SimError::Plot`].
pub fn path_chart_3d(stem: &Path, title: &str, paths: &[Path3]) -> Result<(), SimError> {
    register_embedded_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_3d(
        BitMapBackend::new(&png, (SIZE_3D.0 * PNG_SCALE, SIZE_3D.1 * PNG_SCALE))
            .into_drawing_area(),
        title,
        paths,
        PNG_SCALE,
    )?;
    draw_3d(
        SVGBackend::new(&svg, SIZE_3D).into_drawing_area(),
        title,
        paths,
        1,
    )?;
    Ok(())
}

/// Draws 3-D paths as [`path_chart_3d`] does, at `scale`, into memory.
///
/// # Errors
/// [`SimError::Plot`] if drawing fails.
pub fn render_paths_3d(title: &str, paths: &[Path3], scale: u32) -> Result<Raster, SimError> {
    register_embedded_font();
    let mut r = Raster::new((SIZE_3D.0 * scale, SIZE_3D.1 * scale));
    let size = (r.width, r.height);
    draw_3d(
        BitMapBackend::with_buffer(&mut r.rgb, size).into_drawing_area(),
        title,
        paths,
        scale,
    )?;
    Ok(r)
}

/// Checks of drawn figures shared by the tests of this crate, independent of the tick code.
#[cfg(test)]
pub(crate) mod check {
    use super::{AxisTicks, Raster};

    /// The number a tick label shows (`0.05`, `−2`, `10⁻³`, `2.5×10⁻⁵`), parsed here
    /// without the formatting code.
    pub(crate) fn parse_label(label: &str) -> Option<f64> {
        let l = label.replace('−', "-");
        let sup = |s: &str| -> Option<i32> {
            let t: String = s
                .chars()
                .map(|c| match c {
                    '⁻' => Some('-'),
                    _ => "⁰¹²³⁴⁵⁶⁷⁸⁹"
                        .chars()
                        .position(|d| d == c)
                        .and_then(|d| char::from_digit(d as u32, 10)),
                })
                .collect::<Option<String>>()?;
            t.parse().ok()
        };
        if let Some((m, e)) = l.split_once("×10") {
            return Some(m.parse::<f64>().ok()? * 10f64.powi(sup(e)?));
        }
        if let Some(e) = l.strip_prefix("10")
            && !e.is_empty()
            && let Some(e) = sup(e)
        {
            return Some(10f64.powi(e));
        }
        l.parse().ok()
    }

    /// Whether `ticks` labels the data range `[lo, hi]` readably: 3 to 10 labelled ticks,
    /// increasing, inside the drawn range; the first ≤ `lo`, the last ≥ `hi`; distinct labels
    /// that read back as their values; on a log axis a labelled tick in every decade.
    pub(crate) fn covers(ticks: &AxisTicks, lo: f64, hi: f64) -> Result<(), String> {
        let v = ticks.values();
        if !(3..=10).contains(&v.len()) {
            return Err(format!("{} labelled ticks: {v:?}", v.len()));
        }
        if v.windows(2).any(|w| w[1] <= w[0]) {
            return Err(format!("ticks not increasing: {v:?}"));
        }
        let tol = 1e-12 * lo.abs().max(hi.abs());
        if v[0] > lo + tol || v[v.len() - 1] < hi - tol {
            return Err(format!(
                "data [{lo}, {hi}] outside the labelled ticks {v:?}"
            ));
        }
        let (a, b) = ticks.range;
        if v.iter().any(|t| *t < a || *t > b) {
            return Err(format!("ticks {v:?} outside the axis ({a}, {b})"));
        }
        for (t, label) in &ticks.labelled {
            let back = parse_label(label).ok_or(format!("label {label:?} is not a number"))?;
            if (back - t).abs() > 1e-9 * t.abs().max(1e-300) {
                return Err(format!("label {label:?} reads {back}, tick is {t}"));
            }
        }
        if ticks.log && v.windows(2).any(|w| w[1] / w[0] > 10.0 * (1.0 + 1e-9)) {
            return Err(format!("a decade without a labelled tick: {v:?}"));
        }
        Ok(())
    }

    /// Whether the outer `band` pixels on the right and at the bottom of `r` are white:
    /// nothing (a legend entry, a label) runs off the figure.
    pub(crate) fn edges_blank(r: &Raster, band: u32) -> bool {
        let right = (0..r.height)
            .all(|y| (r.width - band..r.width).all(|x| r.pixel(x, y) == (255, 255, 255)));
        let bottom = (r.height - band..r.height)
            .all(|y| (0..r.width).all(|x| r.pixel(x, y) == (255, 255, 255)));
        right && bottom
    }
}

#[cfg(test)]
mod tests {
    use super::check::{covers, edges_blank, parse_label};
    use super::*;

    /// Data ranges of the project's figures (the faults of issue #30 among them).
    const RANGES: [(f64, f64); 14] = [
        (2.0e-3, 7.0e-3), // parameter error of Table II
        (0.2, 0.9),       // TAG-K and oracle position errors [cm]
        (0.19, 22.7),     // position errors with a failing estimator [cm]
        (2.4, 55.0),      // update times [µs]
        (6.5e-9, 1.3e-2), // parameter error over time
        (2.8e-5, 4.0e-5), // burn-in sweep
        (0.95, 1.2),      // nominal position error [cm]
        (1.0, 1.0),       // a single value
        (0.0, 100.0),     // success [%]
        (0.0, 0.0),       // abort rate, none aborted [%]
        (-0.37, 1.02),    // 3-D path x [m]
        (1.26, 1.36),     // 3-D path z [m]
        (0.0, 19.99),     // time [s]
        (40.0, 120.0),    // parameter dimension
    ];

    #[test]
    fn labelled_ticks_hold_the_data_on_linear_and_log_axes() {
        for (lo, hi) in RANGES {
            covers(&linear_ticks(lo, hi), lo, hi)
                .unwrap_or_else(|e| panic!("linear [{lo}, {hi}]: {e}"));
            if lo > 0.0 {
                let t = log_ticks(lo, hi);
                covers(&t, lo, hi).unwrap_or_else(|e| panic!("log [{lo}, {hi}]: {e}"));
                assert!(t.log);
            }
        }
        // Less than two decades: 1-2-5 (or finer) labels, not decades alone.
        let t = log_ticks(0.19, 4.0);
        assert_eq!(t.values(), [0.1, 0.2, 0.5, 1.0, 2.0, 5.0]);
        assert_eq!(t.labelled[1].1, "0.2");
        // Two decades or more: decades; 8 and more, in the `10ⁿ` style throughout.
        assert_eq!(log_ticks(0.19, 22.7).values(), [0.1, 1.0, 10.0, 100.0]);
        let t = log_ticks(6.5e-9, 1.3e-2);
        assert_eq!(t.values().len(), 9);
        assert!(t.labelled.iter().all(|(_, l)| l.starts_with("10")));
        assert_eq!(
            linear_ticks(0.0, 1.0).values(),
            [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
        );
    }

    #[test]
    fn the_checks_reject_plotters_own_log_ticks() {
        // What the figures drew before: plotters' key points on the old ranges. Table II's
        // parameter error (2e-3..7e-3 on 1e-3..1e-2) got the single label 0.01; the update
        // times (2.4..55 µs on 1.6..82) none below 10.
        for ((a, b), (lo, hi)) in [((1e-3, 1e-2), (2e-3, 7e-3)), ((1.6, 82.5), (2.4, 55.0))] {
            let coord: LogCoord<f64> = (a..b).log_scale().into();
            let old: Vec<f64> = coord.key_points(10usize);
            let ticks = AxisTicks {
                range: (a, b),
                labelled: old.iter().map(|v| (*v, format!("{v}"))).collect(),
                minor: vec![],
                log: true,
            };
            assert!(covers(&ticks, lo, hi).is_err(), "{old:?}");
        }
    }

    #[test]
    fn labels_read_back_as_their_values() {
        assert_eq!(parse_label("10⁻³"), Some(1e-3));
        assert_eq!(parse_label("2.5×10⁻⁵"), Some(2.5e-5));
        assert_eq!(parse_label("−0.5"), Some(-0.5));
        assert_eq!(scientific(2.5e-5), "2.5×10⁻⁵");
        assert_eq!(plain(-0.0, 2), "0");
    }

    #[test]
    fn cdf_steps_is_the_staircase_of_the_sorted_values() {
        let s = cdf_steps(&[3.0, f64::NAN, 1.0, 2.0]);
        let third = 1.0 / 3.0;
        let expected = [
            (1.0, 0.0),
            (1.0, third),
            (2.0, third),
            (2.0, 2.0 * third),
            (3.0, 2.0 * third),
            (3.0, 1.0),
        ];
        assert_eq!(s.len(), expected.len());
        for (p, e) in s.iter().zip(expected) {
            assert!(
                (p.0 - e.0).abs() < 1e-15 && (p.1 - e.1).abs() < 1e-15,
                "{s:?}"
            );
        }
        assert!(cdf_steps(&[]).is_empty());
    }

    #[test]
    fn legends_stay_inside_the_figure() {
        let long = "TAG-K (scaled, tol 3σ, fz+τ rows, events 5σ)";
        for labels in [
            vec!["RLS", "KF"],
            vec!["RLS-low", long, "oracle", "nominal"],
        ] {
            let chart = LineChart {
                title: "legend".into(),
                x_label: "x [m]".into(),
                y_label: "y [m]".into(),
                series: labels
                    .iter()
                    .map(|l| ChartSeries {
                        label: l.to_string(),
                        points: vec![(0.0, 1.0), (1.0, 2.0)],
                    })
                    .collect(),
                ..LineChart::default()
            };
            for scale in [1, PNG_SCALE] {
                let legend = legend_layout(&labels, SIZE.0 * scale, scale);
                assert_eq!(legend.right, labels.len() == 2);
                let r = render_line_chart(&chart, scale).unwrap();
                assert!(edges_blank(&r, 2 * scale), "{labels:?} at scale {scale}");
            }
        }
    }
}
