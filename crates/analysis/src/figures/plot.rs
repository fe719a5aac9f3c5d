//! Figures as PNG and SVG (plotters), drawn with an embedded DejaVu Sans so that no system font or
//! fontconfig is needed (font licence: `crates/analysis/fonts/LICENSE-DejaVu.txt`).

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::coord::cartesian::Cartesian2d;
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::prelude::*;

use crate::{Error, Result};

static FONT: &[u8] = include_bytes!("../../fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

fn register_font() {
    REGISTER.call_once(|| {
        // The embedded font is a valid TrueType file; failure would be a build defect.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// How large figures are drawn: the size of one panel (px at scale 1), a resolution factor that
/// multiplies every pixel dimension (sizes, lines, points, fonts, margins: `scale = 2` draws the
/// same figure at twice the resolution, for print), and a factor on the fonts alone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Width and height of one panel (px at scale 1); default 560 x 380.
    pub panel: (u32, u32),
    /// Resolution factor, 0.25 to 8; default 1.
    pub scale: f64,
    /// Font size factor, 0.5 to 4; default 1 (tick labels 13 px, axis labels 15 px, titles 20 px
    /// at scale 1).
    pub font: f64,
}

/// The style of figures unless told otherwise.
const DEFAULT_STYLE: Style = Style {
    panel: (560, 380),
    scale: 1.0,
    font: 1.0,
};

impl Default for Style {
    fn default() -> Self {
        DEFAULT_STYLE
    }
}

impl Style {
    /// A style checked for sizes a figure can be drawn at, naming the option at fault.
    pub fn new(panel: (u32, u32), scale: f64, font: f64) -> std::result::Result<Style, String> {
        if !(120..=4000).contains(&panel.0) || !(100..=4000).contains(&panel.1) {
            return Err(format!(
                "figure size: {} x {} px per panel is outside 120-4000 x 100-4000",
                panel.0, panel.1
            ));
        }
        if !(scale.is_finite() && (0.25..=8.0).contains(&scale)) {
            return Err(format!("figure scale: {scale} is outside 0.25 to 8"));
        }
        if !(font.is_finite() && (0.5..=4.0).contains(&font)) {
            return Err(format!("font scale: {font} is outside 0.5 to 4"));
        }
        Ok(Style { panel, scale, font })
    }

    /// `v` px at scale 1, in pixels of the drawing (at least 1).
    fn px(&self, v: f64) -> u32 {
        ((v * self.scale).round() as u32).max(1)
    }

    /// A font of `v` px at scale 1 and font factor 1.
    fn font_px(&self, v: f64) -> f64 {
        (v * self.scale * self.font).round().max(1.0)
    }
}

/// The panel size "W x H" of `--figure-size` ("800x500").
pub fn parse_panel_size(s: &str) -> std::result::Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': give the panel size as WIDTHxHEIGHT in px, e.g. 800x500"))?;
    let n = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': '{v}' is not a whole number of px"))
    };
    Ok((n(w)?, n(h)?))
}

static STYLE: std::sync::RwLock<Style> = std::sync::RwLock::new(DEFAULT_STYLE);

/// Sets the [`Style`] of every figure drawn from now on, in this process.
pub fn set_style(style: Style) {
    // A poisoned lock holds a valid style still (it is replaced whole).
    *STYLE.write().unwrap_or_else(|e| e.into_inner()) = style;
}

/// The [`Style`] figures are drawn in.
pub fn style() -> Style {
    *STYLE.read().unwrap_or_else(|e| e.into_inner())
}

/// One line of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
}

/// A shaded band between `lo` and `hi` over `x` (an error band), drawn translucent under the
/// lines and dots, in colour `color` of the line palette.
#[derive(Debug, Clone, Default)]
pub struct Band {
    pub label: String,
    pub x: Vec<f64>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
    pub color: usize,
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
    /// One unit of x as long on the page as one unit of y (orbits: a circle stays a circle).
    /// The plotting area is narrowed or shortened, centred in the panel's area, to fit.
    pub equal_aspect: bool,
    /// Styles of the lines, by index (default: the palette in order, solid). A line with an
    /// empty label gets no legend entry.
    pub styles: Vec<LineStyle>,
    /// Dot radii of the point series, by index (default `point_size`).
    pub point_radii: Vec<u32>,
    /// Dot colours of the point series, by index into the dot palette (default in order).
    pub point_colors: Vec<usize>,
    /// Shaded bands under the lines ([`Band`]).
    pub bands: Vec<Band>,
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
            equal_aspect: false,
            styles: Vec::new(),
            point_radii: Vec::new(),
            point_colors: Vec::new(),
            bands: Vec::new(),
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
        // Enough mantissa digits that ticks a span apart differ (a zoomed inset).
        let digits = ((mag / span.abs().max(1e-300)).log10().ceil() + 1.0).clamp(2.0, 8.0) as usize;
        format!("{v:.digits$e}")
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
    legend: &Legend,
) -> Result<Drawn, String>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let st = style();
    chart
        .configure_mesh()
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .x_label_formatter(x_fmt)
        .y_label_formatter(y_fmt)
        .x_labels(if small { 3 } else { 10 })
        .y_labels(if small { 4 } else { 10 })
        .label_style(("sans-serif", st.font_px(if small { 10.0 } else { 13.0 })))
        .axis_desc_style(("sans-serif", st.font_px(if small { 11.0 } else { 15.0 })))
        .draw()
        .map_err(|e| e.to_string())?;
    let (xr, yr) = (chart.x_range(), chart.y_range());
    let frame = (xr.start, xr.end, yr.start, yr.end);
    let mut entries = Vec::new();
    for b in &panel.bands {
        let c = COLORS[b.color % COLORS.len()];
        // Clamped to the frame (a polygon is not clipped as a line is); points with an edge
        // outside `keep` (a log axis) are left out.
        let clamp = |v: f64, a: f64, z: f64| v.clamp(a.min(z), a.max(z));
        let at = |x: f64, y: f64| (clamp(x, frame.0, frame.1), clamp(y, frame.2, frame.3));
        let pts: Vec<(usize, f64)> =
            b.x.iter()
                .enumerate()
                .filter(|(i, x)| {
                    x.is_finite()
                        && (!panel.log_x || **x > 0.0)
                        && [b.lo[*i], b.hi[*i]]
                            .iter()
                            .all(|y| y.is_finite() && keep(*y))
                })
                .map(|(i, x)| (i, *x))
                .collect();
        let outline: Vec<(f64, f64)> = pts
            .iter()
            .map(|&(i, x)| at(x, b.lo[i]))
            .chain(pts.iter().rev().map(|&(i, x)| at(x, b.hi[i])))
            .collect();
        if outline.len() < 3 {
            continue;
        }
        let fill = c.mix(0.25).filled();
        let drawn = chart
            .draw_series(std::iter::once(Polygon::new(outline, fill)))
            .map_err(|e| e.to_string())?;
        if !b.label.is_empty() {
            drawn
                .label(&b.label)
                .legend(move |at| mark(Mark::Band(c), at, st));
            entries.push((b.label.clone(), Mark::Band(c)));
        }
    }
    for (i, s) in panel.series.iter().enumerate() {
        let style = panel.styles.get(i).copied().unwrap_or(LineStyle {
            color: i,
            dashed: false,
        });
        let c = COLORS[style.color % COLORS.len()];
        let kept: Vec<(f64, f64)> =
            s.x.iter()
                .zip(&s.y)
                .filter(|(x, y)| keep(**y) && (!panel.log_x || **x > 0.0))
                .map(|(x, y)| (*x, *y))
                .collect();
        // Lines end at the frame: each piece inside it is drawn on its own.
        let pieces: Vec<Vec<(f64, f64)>> = clip_polyline(&kept, frame, panel.log_x, panel.log_y)
            .into_iter()
            .flat_map(|p| split_sharp(p, |q| chart.backend_coord(q)))
            .collect();
        let stroke = c.stroke_width(st.px(panel.line_width as f64));
        let mut legend_done = s.label.is_empty();
        for piece in pieces {
            let drawn = if style.dashed {
                chart
                    .draw_series(DashedLineSeries::new(piece, st.px(6.0), st.px(4.0), stroke))
                    .map_err(|e| e.to_string())?
            } else {
                chart
                    .draw_series(LineSeries::new(piece, stroke))
                    .map_err(|e| e.to_string())?
            };
            if !legend_done {
                drawn
                    .label(&s.label)
                    .legend(move |at| mark(Mark::Line(c), at, st));
                entries.push((s.label.clone(), Mark::Line(c)));
                legend_done = true;
            }
        }
    }
    for (i, s) in panel.points.iter().enumerate() {
        let c =
            POINT_COLORS[panel.point_colors.get(i).copied().unwrap_or(i % 4) % POINT_COLORS.len()];
        let r = st.px(if small {
            1.0
        } else {
            panel
                .point_radii
                .get(i)
                .copied()
                .unwrap_or(panel.point_size) as f64
        }) as i32;
        let anno = chart
            .draw_series(
                s.x.iter()
                    .zip(&s.y)
                    .filter(|(x, y)| keep(**y) && (!panel.log_x || **x > 0.0))
                    .filter(|(x, y)| inside(**x, **y, frame))
                    .map(move |(x, y)| Circle::new((*x, *y), r, c.filled())),
            )
            .map_err(|e| e.to_string())?;
        if !s.label.is_empty() {
            anno.label(&s.label)
                .legend(move |at| mark(Mark::Point(c), at, st));
            entries.push((s.label.clone(), Mark::Point(c)));
        }
    }
    if let Legend::Inside(position) = legend {
        chart
            .configure_series_labels()
            .position(position.clone())
            .margin(st.px(10.0))
            .legend_area_size(st.px(30.0))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", st.font_px(13.0)))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    let (w, h) = chart.plotting_area().dim_in_pixel();
    Ok(Drawn {
        x: (frame.0, frame.1),
        y: (frame.2, frame.3),
        pixels: (w, h),
        origin: chart.plotting_area().get_base_pixel(),
        entries,
    })
}

/// Whether (x, y) lies in the frame (x0, x1, y0, y1) (either bound order).
fn inside(x: f64, y: f64, (x0, x1, y0, y1): (f64, f64, f64, f64)) -> bool {
    let within = |v: f64, a: f64, b: f64| v >= a.min(b) && v <= a.max(b);
    within(x, x0, x1) && within(y, y0, y1)
}

/// The pieces of the polyline `pts` inside the frame (x0, x1, y0, y1): a segment that leaves the
/// frame ends on its edge, one that comes back starts a new piece there (Liang-Barsky clipping,
/// in the axes' own scale: logarithmic axes clip in log coordinates). Non-finite points break
/// the line.
pub fn clip_polyline(
    pts: &[(f64, f64)],
    frame: (f64, f64, f64, f64),
    log_x: bool,
    log_y: bool,
) -> Vec<Vec<(f64, f64)>> {
    let fx = |v: f64| if log_x { v.ln() } else { v };
    let fy = |v: f64| if log_y { v.ln() } else { v };
    let gx = |v: f64| if log_x { v.exp() } else { v };
    let gy = |v: f64| if log_y { v.exp() } else { v };
    let (x0, x1) = (fx(frame.0.min(frame.1)), fx(frame.0.max(frame.1)));
    let (y0, y1) = (fy(frame.2.min(frame.3)), fy(frame.2.max(frame.3)));
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let flush = |cur: &mut Vec<(f64, f64)>, out: &mut Vec<Vec<(f64, f64)>>| {
        if !cur.is_empty() {
            out.push(std::mem::take(cur));
        }
    };
    let tx = |p: (f64, f64)| (fx(p.0), fy(p.1));
    for (k, &p) in pts.iter().enumerate() {
        let (ax, ay) = tx(p);
        if !(ax.is_finite() && ay.is_finite()) {
            flush(&mut cur, &mut out);
            continue;
        }
        let prev = if k > 0 { Some(tx(pts[k - 1])) } else { None };
        let Some((bx, by)) = prev.filter(|(a, b)| a.is_finite() && b.is_finite()) else {
            // First point of a line: kept when inside.
            if ax >= x0 && ax <= x1 && ay >= y0 && ay <= y1 {
                cur.push(p);
            }
            continue;
        };
        // Segment from (bx, by) to (ax, ay), clipped: t in [t0, t1].
        let (dx, dy) = (ax - bx, ay - by);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        let mut visible = true;
        for (q, r) in [(-dx, bx - x0), (dx, x1 - bx), (-dy, by - y0), (dy, y1 - by)] {
            if q == 0.0 {
                if r < 0.0 {
                    visible = false;
                }
            } else {
                let t = r / q;
                if q < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        if !visible || t0 >= t1 {
            flush(&mut cur, &mut out);
            continue;
        }
        let at = |t: f64| (gx(bx + t * dx), gy(by + t * dy));
        if t0 > 0.0 {
            // Entering the frame: a new piece starts on its edge.
            flush(&mut cur, &mut out);
            cur.push(at(t0));
        } else if cur.is_empty() {
            cur.push(pts[k - 1]);
        }
        if t1 < 1.0 {
            cur.push(at(t1));
            flush(&mut cur, &mut out);
        } else {
            cur.push(p);
        }
    }
    flush(&mut cur, &mut out);
    out
}

/// A piece of a line as drawn: points that fall on the pixel of the point before are dropped,
/// and the piece is cut where it turns back on itself on the page (the two segments at a point
/// closer than 30 degrees). plotters draws a line wider than one pixel as a polygon whose corner
/// at such a turn lies far outside the turn (its mitre is not capped on the inner side), so a
/// force spike one pixel wide drew a stroke through the frame's bottom and out of the panel; cut
/// there, each part ends with a square end instead.
pub fn split_sharp(
    piece: Vec<(f64, f64)>,
    px: impl Fn(&(f64, f64)) -> (i32, i32),
) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let mut cur_px: Vec<(i32, i32)> = Vec::new();
    for p in piece {
        let q = px(&p);
        if cur_px.last() == Some(&q) {
            continue;
        }
        if let [.., a, b] = cur_px[..] {
            let u = ((a.0 - b.0) as f64, (a.1 - b.1) as f64);
            let v = ((q.0 - b.0) as f64, (q.1 - b.1) as f64);
            let cos = (u.0 * v.0 + u.1 * v.1) / (u.0.hypot(u.1) * v.0.hypot(v.1));
            if cos > 30f64.to_radians().cos() {
                let last = *cur.last().expect("two points");
                out.push(std::mem::take(&mut cur));
                cur.push(last);
                cur_px = vec![b];
            }
        }
        cur.push(p);
        cur_px.push(q);
    }
    if cur.len() > 1 || (out.is_empty() && !cur.is_empty()) {
        out.push(cur);
    }
    out
}

/// Where a panel's legend goes: inside the plotting area at a spot it covers no data in, or,
/// when every spot would cover data, outside it, to the right of the frame (the plotting area
/// is narrowed to make room).
#[derive(Debug, Clone)]
enum Legend {
    None,
    Inside(SeriesLabelPosition),
    /// Right of the frame, `width` px wide.
    Outside {
        width: u32,
    },
}

/// The spot of the plotting area for a legend box of `box_frac` (width and height as
/// fractions of the plotting area) that covers the fewest data points (a line's points and the
/// midpoints between them), with that count: each corner and the right middle are tried (ties:
/// upper right, upper left, lower right, lower left, middle right). Fractions are taken in the
/// axes' own scale.
fn legend_spot(
    panel: &Panel,
    frame: (f64, f64, f64, f64),
    box_frac: (f64, f64),
) -> (SeriesLabelPosition, usize) {
    let (w, h) = (box_frac.0.min(0.9), box_frac.1.min(0.9));
    let frac = |v: f64, a: f64, b: f64, log: bool| {
        if log {
            if v <= 0.0 || a <= 0.0 || b <= 0.0 {
                return f64::NAN;
            }
            (v.ln() - a.ln()) / (b.ln() - a.ln())
        } else {
            (v - a) / (b - a)
        }
    };
    let (x0, x1, y0, y1) = frame;
    let mut counts = [0usize; 5];
    let boxes = [
        (1.0 - w, 1.0, 1.0 - h, 1.0),
        (0.0, w, 1.0 - h, 1.0),
        (1.0 - w, 1.0, 0.0, h),
        (0.0, w, 0.0, h),
        (1.0 - w, 1.0, 0.5 - h / 2.0, 0.5 + h / 2.0),
    ];
    let edges = panel
        .bands
        .iter()
        .flat_map(|b| [(&b.x, &b.lo), (&b.x, &b.hi)]);
    let lines = panel
        .series
        .iter()
        .chain(&panel.points)
        .map(|s| (&s.x, &s.y))
        .chain(edges);
    for (xs, ys) in lines {
        // A line between two points crosses the box too: its midpoints count as well.
        for (k, (x, y)) in xs.iter().zip(ys).enumerate() {
            let mut probe = |x: f64, y: f64| {
                let (u, v) = (frac(x, x0, x1, panel.log_x), frac(y, y0, y1, panel.log_y));
                for (k, b) in boxes.iter().enumerate() {
                    if u >= b.0 && u <= b.1 && v >= b.2 && v <= b.3 {
                        counts[k] += 1;
                    }
                }
            };
            probe(*x, *y);
            if k > 0 {
                probe(0.5 * (x + xs[k - 1]), 0.5 * (y + ys[k - 1]));
            }
        }
    }
    let fewest = (0..5).min_by_key(|k| (counts[*k], *k)).unwrap_or(0);
    (
        [
            SeriesLabelPosition::UpperRight,
            SeriesLabelPosition::UpperLeft,
            SeriesLabelPosition::LowerRight,
            SeriesLabelPosition::LowerLeft,
            SeriesLabelPosition::MiddleRight,
        ][fewest]
            .clone(),
        counts[fewest],
    )
}

/// The labels of a panel's legend entries, in drawing order.
fn legend_labels(panel: &Panel) -> Vec<&str> {
    panel
        .series
        .iter()
        .chain(&panel.points)
        .map(|s| s.label.as_str())
        .chain(panel.bands.iter().map(|b| b.label.as_str()))
        .collect()
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

/// Widens the x or the y range, about its middle, so that one unit takes as many pixels along
/// x as along y in a plotting area of `pixels` (width, height).
pub fn equal_aspect_ranges(
    x: (f64, f64),
    y: (f64, f64),
    pixels: (u32, u32),
) -> ((f64, f64), (f64, f64)) {
    let (pw, ph) = (pixels.0.max(1) as f64, pixels.1.max(1) as f64);
    let (ux, uy) = ((x.1 - x.0) / pw, (y.1 - y.0) / ph);
    let widen = |r: (f64, f64), span: f64| {
        let m = 0.5 * (r.0 + r.1);
        (m - 0.5 * span, m + 0.5 * span)
    };
    if ux > uy {
        (x, widen(y, ux * ph))
    } else {
        (widen(x, uy * pw), y)
    }
}

/// What a drawn panel shows: its axis ranges and the plotting area in pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Drawn {
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub pixels: (u32, u32),
    /// The plotting area's top left corner (px, in the drawing's coordinates).
    pub origin: (i32, i32),
    /// The legend's entries: each label and its mark, in drawing order.
    entries: Vec<(String, Mark)>,
}

/// The mark of a legend entry: a band's shade, a line, a point.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mark {
    Band(RGBColor),
    Line(RGBColor),
    Point(RGBColor),
}

/// The legend mark `m` with its left end at `(x, y)` (px), in style `st`: what plotters draws
/// in a legend inside the frame, and what [`legend_outside`] draws beside it.
fn mark<DB: DrawingBackend>(
    m: Mark,
    (x, y): (i32, i32),
    st: Style,
) -> DynElement<'static, DB, (i32, i32)> {
    let (d, w) = (st.px(5.0) as i32, st.px(20.0) as i32);
    match m {
        Mark::Band(c) => {
            Rectangle::new([(x, y - d), (x + w, y + d)], c.mix(0.25).filled()).into_dyn()
        }
        Mark::Line(c) => {
            PathElement::new(vec![(x, y), (x + w, y)], c.stroke_width(st.px(2.0))).into_dyn()
        }
        Mark::Point(c) => Circle::new((x + w / 2, y), st.px(3.0), c.filled()).into_dyn(),
    }
}

/// A legend of `entries` drawn on `area` with its top left corner at `at` (px in `area`) and
/// `width` px wide: a white box with a black border, each entry's mark and label on a line.
fn legend_outside<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, Mark)],
    at: (i32, i32),
    width: u32,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let st = style();
    let (margin, line) = (st.px(10.0) as i32, (st.font_px(13.0) * 1.25) as i32);
    let height = 2 * margin + line * entries.len() as i32;
    let corners = [at, (at.0 + width as i32, at.1 + height)];
    let err = |e: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    area.draw(&Rectangle::new(corners, WHITE.filled()))
        .map_err(err)?;
    area.draw(&Rectangle::new(corners, BLACK)).map_err(err)?;
    let font: TextStyle = ("sans-serif", st.font_px(13.0)).into_font().into();
    let font = font.pos(plotters::style::text_anchor::Pos::new(
        plotters::style::text_anchor::HPos::Left,
        plotters::style::text_anchor::VPos::Center,
    ));
    for (k, (label, m)) in entries.iter().enumerate() {
        let y = at.1 + margin + line * k as i32 + line / 2;
        area.draw(&mark::<DB>(*m, (at.0 + margin, y), st))
            .map_err(err)?;
        let x = at.0 + margin + st.px(30.0) as i32;
        area.draw(&Text::new(label.clone(), (x, y), font.clone()))
            .map_err(err)?;
    }
    Ok(())
}

/// The title's font size (px): 20 (12 in an inset) at scale 1 and font factor 1, made smaller,
/// down to 60 % of that, until the title fits the panel's width.
fn title_px<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    small: bool,
) -> Result<f64, String> {
    let full = style().font_px(if small { 12.0 } else { 20.0 });
    let room = f64::from(area.dim_in_pixel().0) * 0.96;
    let mut px = full;
    while px > 0.6 * full {
        let font: TextStyle = ("sans-serif", px).into_font().into();
        let (w, _) = area
            .estimate_text_size(title, &font)
            .map_err(|e| e.to_string())?;
        if f64::from(w) <= room {
            break;
        }
        px = (px * 0.95).floor();
    }
    Ok(px)
}

/// Pixels between the frame and a legend drawn outside it, at scale 1.
const LEGEND_GAP: f64 = 8.0;

/// The legend of `panel` drawn in `area` with the given margin and label areas (px) over the
/// frame (x0, x1, y0, y1) before log axes widen it to decades: none for an inset or a single
/// entry; else inside the plotting area where it covers no data, else outside on the right.
fn legend_for<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    small: bool,
    (margin, x_lab, y_lab): (u32, u32, u32),
    (x0, x1, y0, y1): (f64, f64, f64, f64),
) -> Result<Legend, String> {
    let labels = legend_labels(panel);
    if labels.len() < 2 || small {
        return Ok(Legend::None);
    }
    let st = style();
    let font: TextStyle = ("sans-serif", st.font_px(13.0)).into_font().into();
    let mut text_w = 0;
    for l in &labels {
        let (w, _) = area
            .estimate_text_size(l, &font)
            .map_err(|e| e.to_string())?;
        text_w = text_w.max(w);
    }
    // The box plotters draws: the entries' text, the legend marks' area and a margin around.
    let width = text_w + st.px(30.0) + 2 * st.px(10.0);
    let height = (labels.len() as f64 * st.font_px(13.0) * 1.25) as u32 + 2 * st.px(10.0);
    let (aw, ah) = area.dim_in_pixel();
    let plot = (
        aw.saturating_sub(2 * margin + y_lab).max(1),
        ah.saturating_sub(2 * margin + x_lab).max(1),
    );
    let frame = (
        if panel.log_x {
            x0.max(f64::MIN_POSITIVE)
        } else {
            x0
        },
        x1,
        if panel.log_y {
            y0.max(f64::MIN_POSITIVE)
        } else {
            y0
        },
        y1,
    );
    let fracs = (
        f64::from(width) / f64::from(plot.0),
        f64::from(height) / f64::from(plot.1),
    );
    Ok(match legend_spot(panel, frame, fracs) {
        (p, 0) => Legend::Inside(p),
        // Outside while the data keep at least 55 % of the plotting width; a legend wider than
        // that stays inside, where it covers the fewest points.
        _ if f64::from(width + st.px(LEGEND_GAP)) < 0.45 * f64::from(plot.0) => {
            Legend::Outside { width }
        }
        (p, _) => Legend::Inside(p),
    })
}

/// One panel in `area`; `small` for an inset (smaller fonts, no legend).
pub fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    small: bool,
) -> Result<Drawn, String>
where
    DB::ErrorType: 'static,
{
    register_font();
    let st = style();
    // A band's edges count as lines for the axes' ranges.
    let edges: Vec<Series> = panel
        .bands
        .iter()
        .flat_map(|b| {
            [&b.lo, &b.hi].map(|y| Series {
                label: String::new(),
                x: b.x.clone(),
                y: y.clone(),
            })
        })
        .collect();
    let all = || panel.series.iter().chain(&panel.points).chain(&edges);
    let (mut x0, mut x1) = panel
        .x_range
        .unwrap_or_else(|| range(all().flat_map(|s| s.x.iter().copied())));
    let ys = || {
        all()
            .flat_map(|s| s.y.iter().copied())
            .filter(|v| !panel.log_y || *v > 0.0)
    };
    let (mut y0, mut y1) = panel.y_range.unwrap_or_else(|| range(ys()));
    // The caption is drawn first, so that the plotting area's size is known before the axes are
    // chosen (an equal-aspect panel needs it).
    let area = if panel.title.is_empty() {
        area.clone()
    } else {
        let px = title_px(area, &panel.title, small)?;
        // The glyphs rise above the height plotters reserves for the title by about a fifth
        // of the font size at large sizes: that much room above it.
        let top = if st.scale * st.font > 1.0 {
            (0.2 * px) as u32
        } else {
            0
        };
        area.margin(top, 0, 0, 0)
            .titled(&panel.title, ("sans-serif", px))
            .map_err(|e| e.to_string())?
    };
    // Label areas grow with the fonts they hold.
    let (margin, x_lab, y_lab) = if small {
        (4.0, 22.0, 55.0)
    } else {
        (10.0, 40.0, 80.0)
    };
    let (margin, x_lab, y_lab) = (
        st.px(margin),
        st.px(x_lab * st.font),
        st.px(y_lab * st.font),
    );
    let legend = legend_for(
        &area,
        panel,
        small,
        (margin, x_lab, y_lab),
        (x0, x1, y0, y1),
    )?;
    let right = match legend {
        Legend::Outside { width } => width + st.px(LEGEND_GAP),
        _ => 0,
    };
    if panel.equal_aspect && !panel.log_x && !panel.log_y {
        let (w, h) = area.dim_in_pixel();
        let pixels = (
            w.saturating_sub(2 * margin + y_lab + right),
            h.saturating_sub(2 * margin + x_lab),
        );
        ((x0, x1), (y0, y1)) = equal_aspect_ranges((x0, x1), (y0, y1), pixels);
    }
    let mut builder = ChartBuilder::on(&area);
    builder
        .margin(margin)
        .margin_right(margin + right)
        .x_label_area_size(x_lab)
        .y_label_area_size(y_lab);
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
    let err = |e: plotters::drawing::DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let drawn = if panel.log_y {
        let (lo, hi) = decades(ys().fold(f64::INFINITY, f64::min), ys().fold(0.0, f64::max));
        let y_log = (lo..hi).log_scale();
        if panel.log_x {
            let mut chart = builder
                .build_cartesian_2d((lx0..lx1).log_scale(), y_log)
                .map_err(err)?;
            fill_chart(
                &mut chart,
                panel,
                &log_fmt,
                &log_fmt,
                |y| y > 0.0,
                small,
                &legend,
            )
        } else {
            let mut chart = builder.build_cartesian_2d(x0..x1, y_log).map_err(err)?;
            fill_chart(
                &mut chart,
                panel,
                &x_fmt,
                &log_fmt,
                |y| y > 0.0,
                small,
                &legend,
            )
        }
    } else if panel.log_x {
        let mut chart = builder
            .build_cartesian_2d((lx0..lx1).log_scale(), y_lin)
            .map_err(err)?;
        fill_chart(
            &mut chart,
            panel,
            &log_fmt,
            &y_fmt,
            |_| true,
            small,
            &legend,
        )
    } else {
        let mut chart = builder.build_cartesian_2d(x0..x1, y_lin).map_err(err)?;
        fill_chart(&mut chart, panel, &x_fmt, &y_fmt, |_| true, small, &legend)
    }?;
    if let Legend::Outside { width } = legend {
        let base = area.get_base_pixel();
        let at = (
            drawn.origin.0 - base.0 + drawn.pixels.0 as i32 + st.px(LEGEND_GAP) as i32,
            drawn.origin.1 - base.1,
        );
        legend_outside(&area, &drawn.entries, at, width)?;
    }
    Ok(drawn)
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
        let drawn = draw_panel(&area, panel, false)?;
        if let Some(inset) = &panel.inset {
            // About a quarter of the plotting area, inside its frame (clear of a legend beside
            // it), on white with a frame, in the corner the panel asks for.
            let (w, h) = area.dim_in_pixel();
            let base = area.get_base_pixel();
            let (ox, oy) = (drawn.origin.0 - base.0, drawn.origin.1 - base.1);
            let (pw, ph) = (drawn.pixels.0 as i32, drawn.pixels.1 as i32);
            let (iw, ih) = (pw * 48 / 100, ph * 46 / 100);
            let (right, top) = panel.inset_corner;
            let x0 = if right {
                ox + pw - iw - pw / 50
            } else {
                ox + pw / 50
            };
            let y0 = if top {
                oy + ph / 30
            } else {
                oy + ph - ih - ph / 30
            };
            let sub = area.shrink(
                (x0.max(0), y0.max(0)),
                (iw.min(w as i32) as u32, ih.min(h as i32) as u32),
            );
            sub.fill(&WHITE).map_err(|e| e.to_string())?;
            let (sw, sh) = sub.dim_in_pixel();
            sub.draw(&Rectangle::new(
                [(0, 0), (sw as i32 - 1, sh as i32 - 1)],
                BLACK.stroke_width(style().px(1.0)),
            ))
            .map_err(|e| e.to_string())?;
            draw_panel(&sub, inset, true)?;
        }
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// The file of a figure: the extension of `format` appended to `stem`. A stem may hold a dot of
/// its own (a study named "section3-ensemble-0.3"), which `with_extension` would take for an
/// extension; a stem that already ends in .png or .svg has it replaced.
fn file_of(stem: &Path, format: Format) -> std::path::PathBuf {
    let ext = match format {
        Format::Png => "png",
        Format::Svg => "svg",
    };
    match stem.extension().and_then(|e| e.to_str()) {
        Some("png" | "svg") => stem.with_extension(ext),
        _ => {
            let mut name = stem.as_os_str().to_owned();
            name.push(".");
            name.push(ext);
            std::path::PathBuf::from(name)
        }
    }
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
    let st = style();
    let size = (
        st.px(f64::from(st.panel.0)) * cols as u32,
        st.px(f64::from(st.panel.1)) * rows as u32,
    );
    let path = file_of(path_stem, format);
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

/// The formats of the figures `run` draws.
pub(crate) const PNG_AND_SVG: [Format; 2] = [Format::Png, Format::Svg];

/// Metres to millimetres.
pub(crate) fn mm(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| x * 1e3).collect()
}

/// The clearance circle of radius `r_mm` (mm), for orbit panels drawn in mm.
pub fn circle(r_mm: f64) -> Series {
    let angles = (0..=360).map(|k| (k as f64).to_radians());
    Series {
        label: format!("clearance {r_mm:.3} mm"),
        x: angles.clone().map(|a| r_mm * a.cos()).collect(),
        y: angles.map(|a| r_mm * a.sin()).collect(),
    }
}

/// Draws `panels` in `cols` columns as `out/<stem>.<format>` in each format; nothing when there
/// is no panel. Returns the files written.
pub(crate) fn write(
    out: &Path,
    stem: &str,
    panels: &[Panel],
    cols: usize,
    formats: &[Format],
) -> Result<Vec<std::path::PathBuf>> {
    let mut files = Vec::new();
    if panels.is_empty() {
        return Ok(files);
    }
    for fmt in formats {
        files.push(figure(&out.join(stem), *fmt, panels, cols)?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dot_in_a_figure_name_is_kept() {
        let f = |s: &str, fmt| file_of(Path::new(s), fmt);
        assert_eq!(
            f("out/ens-0.3-bifurcation-S2_vy", Format::Png),
            Path::new("out/ens-0.3-bifurcation-S2_vy.png")
        );
        assert_eq!(f("out/cmp.png", Format::Svg), Path::new("out/cmp.svg"));
        assert_eq!(f("out/cmp", Format::Svg), Path::new("out/cmp.svg"));
    }

    #[test]
    fn format_names_give_their_formats_in_order() {
        assert_eq!(Format::list("png"), Some(vec![Format::Png]));
        assert_eq!(Format::list("svg"), Some(vec![Format::Svg]));
        assert_eq!(Format::list("both"), Some(vec![Format::Png, Format::Svg]));
        assert_eq!(Format::list("pdf"), None);
        assert_eq!(Format::list("PNG"), None);
    }

    #[test]
    fn lines_are_cut_at_the_frame() {
        let frame = (0.0, 1.0, 0.0, 1.0);
        // Inside, out through the right edge, back in through the top: two pieces, each ending
        // on the edge it crosses.
        let pts = [(0.5, 0.5), (1.5, 0.5), (0.5, 1.8), (0.5, 0.8)];
        let pieces = clip_polyline(&pts, frame, false, false);
        assert_eq!(pieces.len(), 2, "{pieces:?}");
        assert_eq!(pieces[0], vec![(0.5, 0.5), (1.0, 0.5)]);
        assert_eq!(pieces[1], vec![(0.5, 1.0), (0.5, 0.8)]);
        // A segment that only passes through the frame is drawn between its two crossings.
        let through = clip_polyline(&[(-1.0, 0.5), (2.0, 0.5)], frame, false, false);
        assert_eq!(through, vec![vec![(0.0, 0.5), (1.0, 0.5)]]);
        // Every kept point lies in the frame; a segment outside it leaves nothing.
        assert!(clip_polyline(&[(2.0, 2.0), (3.0, 2.0)], frame, false, false).is_empty());
        let wave: Vec<(f64, f64)> = (0..200)
            .map(|k| (k as f64 / 199.0, 1.5 * (k as f64 * 0.2).sin()))
            .collect();
        let pieces = clip_polyline(&wave, frame, false, false);
        assert!(pieces.len() > 1);
        for p in pieces.iter().flatten() {
            assert!(inside(p.0, p.1, frame), "{p:?}");
        }
        // A non-finite point breaks the line.
        let broken = clip_polyline(
            &[(0.1, 0.1), (f64::NAN, 0.2), (0.3, 0.3), (0.4, 0.4)],
            frame,
            false,
            false,
        );
        assert_eq!(broken, vec![vec![(0.1, 0.1)], vec![(0.3, 0.3), (0.4, 0.4)]]);
        // A logarithmic axis clips in log coordinates: the crossing of y = 10 on the way from
        // 1 to 100 is halfway in x.
        let log = clip_polyline(
            &[(0.0, 1.0), (1.0, 100.0)],
            (0.0, 1.0, 1.0, 10.0),
            false,
            true,
        );
        assert!(
            (log[0][1].0 - 0.5).abs() < 1e-12 && (log[0][1].1 - 10.0).abs() < 1e-9,
            "{log:?}"
        );
    }

    #[test]
    fn a_band_is_shaded_inside_the_axes_it_widens() {
        // A line at 0 and a band from 1 to 3 over it: the fitted y range takes in the band, and
        // the band's pixels are the palette colour mixed with the white background.
        let line = Series {
            label: "line".into(),
            x: vec![0.0, 1.0],
            y: vec![0.0, 0.0],
        };
        let mut panel = Panel::new("band", "x", "y", vec![line]);
        panel.bands.push(Band {
            label: "band".into(),
            x: vec![0.0, 1.0],
            lo: vec![1.0, 1.0],
            hi: vec![3.0, 3.0],
            color: 0,
        });
        let (w, h) = (560u32, 380u32);
        let mut buf = vec![0u8; (w * h * 3) as usize];
        let drawn = {
            let area = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            area.fill(&WHITE).unwrap();
            draw_panel(&area, &panel, false).unwrap()
        };
        assert!(drawn.y.0 <= 0.0 && drawn.y.1 >= 3.0, "{drawn:?}");
        // 25 % of the first palette colour over white, the shade of every band pixel.
        let c = COLORS[0];
        let mix = |v: u8| (0.25 * v as f64 + 0.75 * 255.0).round() as i32;
        let shade = [mix(c.0), mix(c.1), mix(c.2)];
        let shaded = buf
            .chunks_exact(3)
            .filter(|p| {
                p.iter()
                    .zip(shade)
                    .all(|(a, b)| (i32::from(*a) - b).abs() <= 2)
            })
            .count();
        // The band covers about a third of the plotting area's height, over its whole width.
        let area = (drawn.pixels.0 * drawn.pixels.1) as usize;
        assert!(shaded > area / 5, "{shaded} of {area}");
    }

    /// `panel` drawn alone in a 560 x 380 px RGB buffer: what was drawn, and the pixels.
    fn draw_in_memory(panel: &Panel) -> (Drawn, Vec<u8>) {
        let mut buf = vec![0u8; 560 * 380 * 3];
        let area = BitMapBackend::with_buffer(&mut buf, (560, 380)).into_drawing_area();
        let drawn = draw_panel(&area, panel, false).unwrap();
        drop(area);
        (drawn, buf)
    }

    #[test]
    fn an_equal_aspect_panel_draws_a_circle_round() {
        // A unit circle on +-1.25 in a panel of the usual 560 x 380 px: the drawn ranges give
        // one unit the same number of pixels along x as along y.
        let n = 361;
        let circle = Series {
            label: "circle".into(),
            x: (0..n).map(|k| (k as f64).to_radians().cos()).collect(),
            y: (0..n).map(|k| (k as f64).to_radians().sin()).collect(),
        };
        let mut panel = Panel::new("orbit", "x (mm)", "y (mm)", vec![circle]);
        panel.x_range = Some((-1.25, 1.25));
        panel.y_range = Some((-1.25, 1.25));
        let draw = |panel: &Panel| draw_in_memory(panel).0;
        let per_px = |d: &Drawn| {
            (
                (d.x.1 - d.x.0) / d.pixels.0 as f64,
                (d.y.1 - d.y.0) / d.pixels.1 as f64,
            )
        };
        let plain = draw(&panel);
        let (ux, uy) = per_px(&plain);
        assert!(
            ux < 0.8 * uy,
            "without it the panel is wider than tall: {ux} {uy}"
        );
        panel.equal_aspect = true;
        let round = draw(&panel);
        let (ux, uy) = per_px(&round);
        assert!((ux / uy - 1.0).abs() < 0.01, "{ux} {uy} ({round:?})");
        // The requested range stays in view: only the other axis was widened.
        assert!(round.x.0 <= -1.25 && round.x.1 >= 1.25 && round.y.0 <= -1.25 && round.y.1 >= 1.25);
        assert_eq!(round.y, (-1.25, 1.25));
    }

    #[test]
    fn the_legend_goes_where_the_data_are_not() {
        // A line along the top of the frame: the legend moves to the bottom.
        let top = Series {
            label: "top".into(),
            x: (0..100).map(|k| k as f64 / 99.0).collect(),
            y: vec![0.95; 100],
        };
        let rising = Series {
            label: "second".into(),
            x: vec![0.0, 0.1],
            y: vec![0.5, 0.5],
        };
        let panel = Panel::new("", "", "", vec![top.clone(), rising.clone()]);
        let frame = (0.0, 1.0, 0.0, 1.0);
        let pos = legend_spot(&panel, frame, (0.2, 0.2));
        assert!(
            matches!(pos, (SeriesLabelPosition::LowerRight, 0)),
            "{pos:?}"
        );
        // Data in the lower right and the upper right: the upper left is free.
        let corner = Series {
            label: "c".into(),
            x: vec![0.95, 0.9, 0.95, 0.9],
            y: vec![0.05, 0.1, 0.95, 0.9],
        };
        let panel = Panel::new("", "", "", vec![corner, rising.clone()]);
        let pos = legend_spot(&panel, frame, (0.2, 0.2));
        assert!(
            matches!(pos, (SeriesLabelPosition::UpperLeft, 0)),
            "{pos:?}"
        );
        // A line through every spot (a zigzag over the whole frame): no spot is free, and the
        // legend is drawn right of the frame, which narrows to make room.
        let zigzag = Series {
            label: "zigzag".into(),
            x: (0..=40).map(|k| k as f64 / 40.0).collect(),
            y: (0..=40).map(|k| (k % 2) as f64).collect(),
        };
        let full = Panel::new("", "", "", vec![zigzag, rising]);
        assert!(matches!(legend_spot(&full, frame, (0.2, 0.2)), (_, n) if n > 0));
        let (outside, buf) = draw_in_memory(&full);
        let (inside, _) = draw_in_memory(&Panel::new("", "", "", vec![top.clone(), top]));
        assert!(
            outside.pixels.0 + 60 < inside.pixels.0,
            "{outside:?} against {inside:?}"
        );
        // The legend's black border stands right of the frame's right edge (the frame ends at
        // margin + y label area + plotting width = 10 + 80 + width px).
        let frame_right = 10 + 80 + outside.pixels.0 as usize;
        let dark_right = (0..380).any(|y| {
            (frame_right + 4..560).any(|x| {
                let p = &buf[3 * (560 * y + x)..3 * (560 * y + x) + 3];
                p.iter().all(|c| *c < 60)
            })
        });
        assert!(dark_right, "nothing drawn right of the frame");
    }

    #[test]
    fn scientific_ticks_of_a_narrow_axis_differ() {
        // An inset 1e-9 wide about -2.56e-5: five ticks, five different labels.
        let span = 1e-9;
        let labels: Vec<String> = (0..5)
            .map(|k| tick(-2.56e-5 + k as f64 * 0.25 * span, span))
            .collect();
        let mut unique = labels.clone();
        unique.dedup();
        assert_eq!(unique.len(), 5, "{labels:?}");
        // A wide axis keeps two decimals.
        assert_eq!(tick(2.0e-5, 4.0e-5), "2.00e-5");
    }

    #[test]
    fn equal_aspect_ranges_widen_the_shorter_unit() {
        // 400 x 200 px for a 1 x 1 range: x is widened to 2.
        let (x, y) = equal_aspect_ranges((0.0, 1.0), (0.0, 1.0), (400, 200));
        assert_eq!((x, y), ((-0.5, 1.5), (0.0, 1.0)));
        let (x, y) = equal_aspect_ranges((0.0, 1.0), (0.0, 1.0), (200, 400));
        assert_eq!((x, y), ((0.0, 1.0), (-0.5, 1.5)));
    }

    #[test]
    fn a_line_is_cut_where_it_turns_back_on_the_page() {
        let px = |p: &(f64, f64)| (p.0.round() as i32, p.1.round() as i32);
        // A spike one pixel wide: up 300 px and straight back down.
        let spike = vec![
            (0.0, 0.0),
            (10.0, 0.0),
            (11.0, -300.0),
            (12.0, 0.0),
            (20.0, 0.0),
        ];
        let parts = split_sharp(spike, px);
        assert_eq!(
            parts,
            [
                vec![(0.0, 0.0), (10.0, 0.0), (11.0, -300.0)],
                vec![(11.0, -300.0), (12.0, 0.0), (20.0, 0.0)]
            ]
        );
        // Points on the pixel of the one before are dropped; a right angle is kept whole.
        let corner = vec![(0.0, 0.0), (0.2, 0.1), (5.0, 0.0), (5.0, 5.0)];
        assert_eq!(
            split_sharp(corner, px),
            [vec![(0.0, 0.0), (5.0, 0.0), (5.0, 5.0)]]
        );
        // A single point stays a piece (drawn as nothing, as before).
        assert_eq!(split_sharp(vec![(1.0, 1.0)], px), [vec![(1.0, 1.0)]]);
    }
}
