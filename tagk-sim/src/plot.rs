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

/// Tick label: `1e-3` style on a log axis, up to 4 significant digits otherwise.
fn axis_label(v: f64, log: bool) -> String {
    if log {
        format!("{v:.0e}")
    } else {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" { "0".into() } else { s.to_string() }
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
#[derive(Debug, Clone, PartialEq)]
pub struct LineChart {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// ChartSeries.
    pub series: Vec<ChartSeries>,
    /// Vertical marker lines at these x values (e.g. payload events).
    pub markers: Vec<f64>,
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
        (x0, x1, (y0 / 1.5).max(y1 * 1e-6), y1 * 1.5)
    } else {
        let pad = 0.05 * (y1 - y0).max(1e-12);
        (x0, x1, (y0 - pad).min(0.0_f64.max(y0 - pad)), y1 + pad)
    }
}

fn draw_lines<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    chart: &LineChart,
) -> Result<(), SimError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(perr)?;
    let (x0, x1, y0, y1) = bounds(&chart.series, chart.log_y);
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&chart.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    macro_rules! body {
        ($ctx:expr) => {{
            let mut ctx = $ctx;
            ctx.configure_mesh()
                .y_label_formatter(&|v: &f64| axis_label(*v, chart.log_y))
                .x_desc(chart.x_label.as_str())
                .y_desc(chart.y_label.as_str())
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(perr)?;
            for m in &chart.markers {
                ctx.draw_series(LineSeries::new(
                    vec![(*m, y0), (*m, y1)],
                    BLACK.mix(0.3).stroke_width(1),
                ))
                .map_err(perr)?;
            }
            for (i, s) in chart.series.iter().enumerate() {
                let c = colour(i);
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite() && (!chart.log_y || *y > 0.0))
                    .map(|(x, y)| (x, y.clamp(y0, y1)))
                    .collect();
                ctx.draw_series(LineSeries::new(pts, c.stroke_width(2)))
                    .map_err(perr)?
                    .label(s.label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
            }
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(perr)?;
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
    root.present().map_err(perr)?;
    Ok(())
}

/// Draws `chart` to `<stem>.png` and `<stem>.svg` (900×560 px).
///
/// # Errors
/// [`SimError::Plot`] if drawing or writing fails.
pub fn line_chart(stem: &Path, chart: &LineChart) -> Result<(), SimError> {
    register_embedded_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_lines(
        BitMapBackend::new(&png, (900, 560)).into_drawing_area(),
        chart,
    )?;
    draw_lines(SVGBackend::new(&svg, (900, 560)).into_drawing_area(), chart)?;
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
    let mut ctx = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(10)
        .build_cartesian_3d(lo[0]..hi[0], lo[2]..hi[2], lo[1]..hi[1])
        .map_err(perr)?;
    ctx.configure_axes()
        .label_style(("sans-serif", 12))
        .draw()
        .map_err(perr)?;
    for (i, p) in paths.iter().enumerate() {
        let c = colour(i);
        ctx.draw_series(LineSeries::new(
            p.points.iter().map(|(x, y, z)| (*x, *z, *y)),
            c.stroke_width(2),
        ))
        .map_err(perr)?
        .label(p.label.as_str())
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
        ctx.draw_series(
            p.marks
                .iter()
                .map(|(x, y, z)| Cross::new((*x, *z, *y), 6, c.stroke_width(2))),
        )
        .map_err(perr)?;
    }
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(perr)?;
    root.present().map_err(perr)?;
    Ok(())
}

/// Draws 3-D paths (x, y horizontal, z up) to `<stem>.png` and `<stem>.svg`.
///
/// # Errors
/// [`SimError::Plot`].
pub fn path_chart_3d(stem: &Path, title: &str, paths: &[Path3]) -> Result<(), SimError> {
    register_embedded_font();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    draw_3d(
        BitMapBackend::new(&png, (900, 700)).into_drawing_area(),
        title,
        paths,
    )?;
    draw_3d(
        SVGBackend::new(&svg, (900, 700)).into_drawing_area(),
        title,
        paths,
    )?;
    Ok(())
}
