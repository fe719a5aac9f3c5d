//! Figures as PNG and SVG (plotters), drawn with an embedded DejaVu Sans so that no system font or
//! fontconfig is needed (font licence: `crates/analysis/fonts/LICENSE-DejaVu.txt`).

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::prelude::*;

use crate::{Error, Result};

static FONT: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The embedded font is a valid TrueType file; failure would be a build defect.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One line of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
}

/// How one line of a panel is drawn: its colour (an index into the palette) and whether it is
/// dashed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LineStyle {
    pub color: usize,
    pub dashed: bool,
}

/// One chart: title, axis labels (with units) and lines.
#[derive(Debug, Clone)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Logarithmic y axis (non-positive values are left out).
    pub log_y: bool,
    /// Logarithmic x axis (non-positive values are left out).
    pub log_x: bool,
    /// Fixed axis ranges (default: fitted to the data).
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    /// Series drawn as dots (radius 1.5 px; section points, bifurcation diagrams) over the lines.
    pub points: Vec<Series>,
    /// A zoomed panel drawn in a quarter of this one ...
    pub inset: Option<Box<Panel>>,
    /// ... the (right, top) quarter when (true, true).
    pub inset_corner: (bool, bool),
    /// Line width and dot radius (px).
    pub line_width: u32,
    pub point_size: u32,
    /// Styles of the lines, by index (default: the palette in order, solid). A line with an
    /// empty label gets no legend entry.
    pub styles: Vec<LineStyle>,
    /// Dot radii of the point series, by index (default `point_size`).
    pub point_radii: Vec<u32>,
    /// Dot colours of the point series, by index into the dot palette (default in order).
    pub point_colors: Vec<usize>,
}

impl Default for Panel {
    /// Untitled, linear fitted axes, 2 px lines and dots, an inset at the upper right.
    fn default() -> Panel {
        Panel {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            series: Vec::new(),
            log_y: false,
            log_x: false,
            x_range: None,
            y_range: None,
            points: Vec::new(),
            inset: None,
            inset_corner: (true, true),
            line_width: 2,
            point_size: 2,
            styles: Vec::new(),
            point_radii: Vec::new(),
            point_colors: Vec::new(),
        }
    }
}

impl Panel {
    /// A panel with fitted linear axes.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
        series: Vec<Series>,
    ) -> Panel {
        Panel {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series,
            ..Panel::default()
        }
    }
}

/// Output formats of a figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    /// The formats named by `name`: `png`, `svg` or `both` (PNG then SVG); None for any other
    /// name.
    pub fn list(name: &str) -> Option<Vec<Format>> {
        match name {
            "png" => Some(vec![Format::Png]),
            "svg" => Some(vec![Format::Svg]),
            "both" => Some(vec![Format::Png, Format::Svg]),
            _ => None,
        }
    }
}

/// Dot colours: red first, so section points stand out over a blue trajectory; the last three
/// (grey, black, orange) are only chosen by [`Panel::point_colors`].
const POINT_COLORS: [RGBColor; 7] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(170, 170, 170),
    RGBColor(0, 0, 0),
    RGBColor(255, 127, 14),
];

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(23, 190, 207),
];

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1e-12)
    };
    (lo - pad, hi + pad)
}

/// Tick label with as many digits as the axis span needs; scientific notation for very small or
/// large magnitudes.
fn tick(v: f64, span: f64) -> String {
    let mag = v.abs().max(span.abs());
    if v == 0.0 || v.abs() < 1e-9 * span.abs() {
        "0".into()
    } else if !(1e-3..1e5).contains(&mag) {
        format!("{v:.2e}")
    } else {
        let digits = (-(span.abs().max(1e-300)).log10().floor() + 1.0).clamp(0.0, 8.0) as usize;
        format!("{v:.digits$}")
    }
}

/// Mesh, axis labels, lines and legend of one panel, for linear and logarithmic y axes alike.
/// Points with y outside `keep` are left out (non-positive values on a log axis).
fn fill_chart<'a, DB, X, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    panel: &Panel,
    x_fmt: &dyn Fn(&f64) -> String,
    y_fmt: &dyn Fn(&f64) -> String,
    keep: fn(f64) -> bool,
    small: bool,
) -> Result<(), String>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .x_label_formatter(x_fmt)
        .y_label_formatter(y_fmt)
        .x_labels(if small { 3 } else { 10 })
        .y_labels(if small { 4 } else { 10 })
        .label_style(("sans-serif", if small { 10 } else { 13 }))
        .axis_desc_style(("sans-serif", if small { 11 } else { 15 }))
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in panel.series.iter().enumerate() {
        let style = panel.styles.get(i).copied().unwrap_or(LineStyle {
            color: i,
            dashed: false,
        });
        let c = COLORS[style.color % COLORS.len()];
        let pts: Vec<(f64, f64)> =
            s.x.iter()
                .zip(&s.y)
                .filter(|(x, y)| keep(**y) && (!panel.log_x || **x > 0.0))
                .map(|(x, y)| (*x, *y))
                .collect();
        let stroke = c.stroke_width(panel.line_width);
        let anno = if style.dashed {
            chart
                .draw_series(DashedLineSeries::new(pts, 6, 4, stroke))
                .map_err(|e| e.to_string())?
        } else {
            chart
                .draw_series(LineSeries::new(pts, stroke))
                .map_err(|e| e.to_string())?
        };
        if !s.label.is_empty() {
            anno.label(&s.label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
            });
        }
    }
    for (i, s) in panel.points.iter().enumerate() {
        let c =
            POINT_COLORS[panel.point_colors.get(i).copied().unwrap_or(i % 4) % POINT_COLORS.len()];
        let r = if small {
            1
        } else {
            panel
                .point_radii
                .get(i)
                .copied()
                .unwrap_or(panel.point_size) as i32
        };
        let anno = chart
            .draw_series(
                s.x.iter()
                    .zip(&s.y)
                    .filter(|(x, y)| keep(**y) && (!panel.log_x || **x > 0.0))
                    .map(move |(x, y)| Circle::new((*x, *y), r, c.filled())),
            )
            .map_err(|e| e.to_string())?;
        if !s.label.is_empty() {
            anno.label(&s.label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled()));
        }
    }
    if panel.series.len() + panel.points.len() > 1 && !small {
        chart
            .configure_series_labels()
            // Log-log work-precision lines fall from upper left to lower right: the lower left
            // (fast and accurate) stays empty.
            .position(if panel.log_x {
                SeriesLabelPosition::LowerLeft
            } else {
                SeriesLabelPosition::MiddleRight
            })
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// A logarithmic axis range from `lo` to `hi` (positive data): widened to whole decades, at least
/// one, so that the ticks fall on round values and do not crowd a partial decade.
fn decades(lo: f64, hi: f64) -> (f64, f64) {
    if !(lo.is_finite() && hi.is_finite() && hi > 0.0) {
        // No positive data: an empty decade (an infinite range would never end its ticks).
        return (1.0, 10.0);
    }
    let lo = lo.max(1e-300);
    let hi = hi.max(lo);
    let a = lo.log10().floor();
    let b = hi.log10().ceil().max(a + 1.0);
    (10f64.powf(a), 10f64.powf(b))
}

/// One panel in `area`; `small` for an inset (smaller fonts, no legend).
fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    small: bool,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let all = || panel.series.iter().chain(&panel.points);
    let (x0, x1) = panel
        .x_range
        .unwrap_or_else(|| range(all().flat_map(|s| s.x.iter().copied())));
    let ys = || {
        all()
            .flat_map(|s| s.y.iter().copied())
            .filter(|v| !panel.log_y || *v > 0.0)
    };
    let (y0, y1) = panel.y_range.unwrap_or_else(|| range(ys()));
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&panel.title, ("sans-serif", if small { 12 } else { 20 }))
        .margin(if small { 4 } else { 10 })
        .x_label_area_size(if small { 22 } else { 40 })
        .y_label_area_size(if small { 55 } else { 80 });
    let xs = x1 - x0;
    let x_fmt = |v: &f64| tick(*v, xs);
    let log_fmt = |v: &f64| format!("{v:.0e}");
    let (lx0, lx1) = {
        let pos = || {
            all()
                .flat_map(|s| s.x.iter().copied())
                .filter(|v| *v > 0.0 && v.is_finite())
        };
        decades(
            pos().fold(f64::INFINITY, f64::min),
            pos().fold(0.0, f64::max),
        )
    };
    let y_lin = y0..y1;
    let yspan = y1 - y0;
    let y_fmt = |v: &f64| tick(*v, yspan);
    if panel.log_y {
        let (lo, hi) = decades(ys().fold(f64::INFINITY, f64::min), ys().fold(0.0, f64::max));
        let y_log = (lo..hi).log_scale();
        if panel.log_x {
            let mut chart = builder
                .build_cartesian_2d((lx0..lx1).log_scale(), y_log)
                .map_err(|e| e.to_string())?;
            fill_chart(&mut chart, panel, &log_fmt, &log_fmt, |y| y > 0.0, small)
        } else {
            let mut chart = builder
                .build_cartesian_2d(x0..x1, y_log)
                .map_err(|e| e.to_string())?;
            fill_chart(&mut chart, panel, &x_fmt, &log_fmt, |y| y > 0.0, small)
        }
    } else if panel.log_x {
        let mut chart = builder
            .build_cartesian_2d((lx0..lx1).log_scale(), y_lin)
            .map_err(|e| e.to_string())?;
        fill_chart(&mut chart, panel, &log_fmt, &y_fmt, |_| true, small)
    } else {
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y_lin)
            .map_err(|e| e.to_string())?;
        fill_chart(&mut chart, panel, &x_fmt, &y_fmt, |_| true, small)
    }
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Panel],
    cols: usize,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let rows = panels.len().div_ceil(cols);
    let areas = root.split_evenly((rows, cols));
    for (panel, area) in panels.iter().zip(areas) {
        draw_panel(&area, panel, false)?;
        if let Some(inset) = &panel.inset {
            // A quarter of the plotting area, on white with a frame.
            let (w, h) = area.dim_in_pixel();
            let (w, h) = (w as i32, h as i32);
            let (right, top) = panel.inset_corner;
            let x0 = if right { w * 52 / 100 } else { w * 17 / 100 };
            let y0 = if top { h * 10 / 100 } else { h * 42 / 100 };
            let sub = area.shrink((x0, y0), (w * 45 / 100, h * 42 / 100));
            sub.fill(&WHITE).map_err(|e| e.to_string())?;
            let (sw, sh) = sub.dim_in_pixel();
            sub.draw(&Rectangle::new(
                [(0, 0), (sw as i32 - 1, sh as i32 - 1)],
                BLACK.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
            draw_panel(&sub, inset, true)?;
        }
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// Draws `panels` in a grid of `cols` columns to `path` (extension added from `format`).
pub fn figure(
    path_stem: &Path,
    format: Format,
    panels: &[Panel],
    cols: usize,
) -> Result<std::path::PathBuf> {
    register_font();
    let cols = cols.max(1).min(panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let size = (560 * cols as u32, 380 * rows as u32);
    let path = path_stem.with_extension(match format {
        Format::Png => "png",
        Format::Svg => "svg",
    });
    let res = match format {
        Format::Png => draw(
            BitMapBackend::new(&path, size).into_drawing_area(),
            panels,
            cols,
        ),
        Format::Svg => draw(
            SVGBackend::new(&path, size).into_drawing_area(),
            panels,
            cols,
        ),
    };
    res.map_err(|message| Error::Plot {
        file: path.clone(),
        message,
    })?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_names_give_their_formats_in_order() {
        assert_eq!(Format::list("png"), Some(vec![Format::Png]));
        assert_eq!(Format::list("svg"), Some(vec![Format::Svg]));
        assert_eq!(Format::list("both"), Some(vec![Format::Png, Format::Svg]));
        assert_eq!(Format::list("pdf"), None);
        assert_eq!(Format::list("PNG"), None);
    }
}
