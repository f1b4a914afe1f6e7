//! Figures with plotters (PNG and SVG, no system libraries): the embedded DejaVu Sans font
//! (`assets/DejaVuSans.ttf`, licence in `assets/DejaVuSans-LICENSE.txt`) is registered with
//! plotters' ab_glyph backend as `"sans-serif"`.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
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

/// Tick label. On a log axis: plain numbers from 0.01 to 9999 (`0.05`, `20`), else
/// `2×10⁻⁵`; on a linear axis up to 4 significant digits (`0.01`, `5`, `15`).
fn axis_label(v: f64, log: bool) -> String {
    if log {
        if v <= 0.0 || !v.is_finite() {
            return String::new();
        }
        let exp = v.log10().floor() as i32;
        let mantissa = (v / 10f64.powi(exp) * 1000.0).round() / 1000.0;
        if (-2..4).contains(&exp) {
            let s = format!("{:.*}", (-exp).max(0) as usize + 2, v);
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else if (mantissa - 1.0).abs() < 1e-9 {
            power_of_ten(exp)
        } else {
            format!(
                "{}×{}",
                format!("{mantissa:.2}")
                    .trim_end_matches('0')
                    .trim_end_matches('.'),
                power_of_ten(exp)
            )
        }
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" {
            "0".into()
        } else {
            s.replace('-', "−")
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

fn bounds(series: &[ChartSeries], log_y: bool) -> (f64, f64, f64, f64) {
    let pts = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log_y || *y > 0.0));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in pts {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    if x0 > x1 {
        return (0.0, 1.0, if log_y { 1e-3 } else { 0.0 }, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if log_y {
        // At most six decades: exact values (an estimate equal to the prior) would
        // otherwise squash every curve against the top.
        let (lo, hi) = ((y0 / 1.5).max(y1 * 1e-6), y1 * 1.5);
        if hi / lo < 10.0 {
            // Less than a decade would show no labelled tick: widen to whole decades.
            (
                x0,
                x1,
                10f64.powf(lo.log10().floor()),
                10f64.powf(hi.log10().ceil()),
            )
        } else {
            (x0, x1, lo, hi)
        }
    } else {
        let pad = 0.05 * (y1 - y0).max(1e-12);
        (x0, x1, (y0 - pad).min(0.0_f64.max(y0 - pad)), y1 + pad)
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
/// dozen points (staggered by series so that coinciding series show every marker).
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
    let at: Vec<(f64, f64)> = pts.iter().copied().skip(offset).step_by(every).collect();
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

/// The legend outside the data, in the right-hand column of `root` starting at pixel
/// `(x, y)`: each series' line with its dash pattern and marker, and its label.
fn draw_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    labels: &[&str],
    (x, y): (i32, i32),
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    let s = scale as i32;
    for (i, label) in labels.iter().enumerate() {
        let yy = y + i as i32 * 22 * s;
        let c = colour(i);
        let style = c.stroke_width(2 * scale);
        let line = vec![(x, yy), (x + 30 * s, yy)];
        match dash(i) {
            None => root.draw(&PathElement::new(line, style)).map_err(perr)?,
            Some((d, g)) => {
                let (d, g) = (d as i32 * s, g as i32 * s);
                let mut a = x;
                while a < x + 30 * s {
                    let b = (a + d).min(x + 30 * s);
                    root.draw(&PathElement::new(vec![(a, yy), (b, yy)], style))
                        .map_err(perr)?;
                    a = b + g;
                }
            }
        }
        draw_marker(root, i, (x + 15 * s, yy), 4 * s, c)?;
        root.draw(&Text::new(
            label.to_string(),
            (x + 38 * s, yy - 8 * s),
            ("sans-serif", 15 * s).into_font(),
        ))
        .map_err(perr)?;
    }
    Ok(())
}

/// Width of the legend column for these labels \[px at scale 1\].
fn legend_width(labels: &[&str]) -> u32 {
    let longest = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0) as u32;
    (50 + 8 * longest).clamp(90, 300)
}

fn draw_lines<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    chart: &LineChart,
    scale: u32,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(perr)?;
    let (mut x0, mut x1, y0, y1) = bounds(&chart.series, chart.log_y);
    let categorical = !chart.x_categories.is_empty();
    if categorical {
        x0 = -0.4;
        x1 = chart.x_categories.len() as f64 - 0.6;
    }
    let labels: Vec<&str> = chart.series.iter().map(|s| s.label.as_str()).collect();
    let legend_w = legend_width(&labels) * scale;
    let (width, _) = root.dim_in_pixel();
    let (plot_area, legend_area) = root.split_horizontally(width - legend_w);
    let mut builder = ChartBuilder::on(&plot_area);
    builder
        .caption(&chart.title, ("sans-serif", 22 * scale))
        .margin(14 * scale)
        .x_label_area_size(50 * scale)
        .y_label_area_size(84 * scale);
    let categories = &chart.x_categories;
    let x_formatter = |v: &f64| {
        if categorical {
            let k = v.round();
            if (v - k).abs() < 1e-6 && k >= 0.0 {
                categories.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        } else {
            axis_label(*v, false)
        }
    };
    macro_rules! body {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            let y_formatter = |v: &f64| axis_label(*v, chart.log_y);
            let mut mesh = ctx.configure_mesh();
            mesh.y_label_formatter(&y_formatter)
                .x_label_formatter(&x_formatter)
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .label_style(("sans-serif", 15 * scale))
                .axis_desc_style(("sans-serif", 16 * scale));
            if categorical {
                mesh.x_labels(chart.x_categories.len() * 4 - 3)
                    .disable_x_mesh();
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
                    .filter(|(x, y)| x.is_finite() && y.is_finite() && (!chart.log_y || *y > 0.0))
                    .map(|(x, y)| (x, y.clamp(y0, y1)))
                    .collect();
                draw_styled(&mut ctx, i, &pts, scale)?;
            }
        }};
    }
    if chart.log_y {
        body!(
            builder
                .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                .map_err(perr)?
        );
    } else {
        body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(perr)?);
    }
    draw_legend(
        &legend_area,
        &labels,
        (6 * scale as i32, 60 * scale as i32),
        scale,
    )?;
    root.present().map_err(perr)?;
    Ok(())
}

/// Figure size at scale 1 \[px\]: the SVG's size; the PNG is drawn at [`PNG_SCALE`] times it.
const SIZE: (u32, u32) = (900, 560);
/// The PNG's scale over the SVG: 1800 px wide, 300 dpi at 6 in, a page-wide figure.
pub const PNG_SCALE: u32 = 2;

/// Draws `chart` to `<stem>.svg` (900×560 px) and `<stem>.png` (1800×1120 px: 300 dpi at
/// 6 in wide). The legend sits right of the data; each series has its own dash pattern and
/// marker, so that coinciding series stay visible.
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

/// Empirical CDF points of `values` (non-finite values are dropped).
pub fn cdf(values: &[f64]) -> Vec<(f64, f64)> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    v.iter()
        .enumerate()
        .map(|(i, x)| (*x, (i + 1) as f64 / n))
        .collect()
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
    let all = paths.iter().flat_map(|p| p.points.iter());
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for (x, y, z) in all {
        for (i, v) in [*x, *y, *z].iter().enumerate() {
            lo[i] = lo[i].min(*v);
            hi[i] = hi[i].max(*v);
        }
    }
    for i in 0..3 {
        if lo[i] > hi[i] {
            lo[i] = 0.0;
            hi[i] = 1.0;
        }
        if hi[i] - lo[i] < 0.1 {
            let c = 0.5 * (lo[i] + hi[i]);
            lo[i] = c - 0.05;
            hi[i] = c + 0.05;
        }
    }
    let labels: Vec<&str> = paths.iter().map(|p| p.label.as_str()).collect();
    let legend_w = legend_width(&labels) * scale;
    let (width, _) = root.dim_in_pixel();
    let (plot_area, legend_area) = root.split_horizontally(width - legend_w);
    let mut ctx = ChartBuilder::on(&plot_area)
        .caption(title, ("sans-serif", 22 * scale))
        .margin(14 * scale)
        .margin_left(60 * scale)
        .build_cartesian_3d(lo[0]..hi[0], lo[2]..hi[2], lo[1]..hi[1])
        .map_err(perr)?;
    let tick = |v: &f64| axis_label(*v, false);
    ctx.configure_axes()
        .x_formatter(&tick)
        .y_formatter(&tick)
        .z_formatter(&tick)
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
    draw_legend(
        &legend_area,
        &labels,
        (6 * scale as i32, 60 * scale as i32),
        scale,
    )?;
    root.present().map_err(perr)?;
    Ok(())
}

/// Draws 3-D paths (x, y horizontal, z up; axes labelled in m) to `<stem>.svg` (900×700 px)
/// and `<stem>.png` (1800×1400 px), the legend right of the plot.
///
/// # Errors
/// [`SimError::Plot`].
pub fn path_chart_3d(stem: &Path, title: &str, paths: &[Path3]) -> Result<(), SimError> {
    register_embedded_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_3d(
        BitMapBackend::new(&png, (900 * PNG_SCALE, 700 * PNG_SCALE)).into_drawing_area(),
        title,
        paths,
        PNG_SCALE,
    )?;
    draw_3d(
        SVGBackend::new(&svg, (900, 700)).into_drawing_area(),
        title,
        paths,
        1,
    )?;
    Ok(())
}
