//! Figures of a nonlinear-analysis file, drawn from the HDF5 file alone (so `jointplay plot`
//! redraws exactly what `jointplay run` drew, without simulating again).
//!
//! Kinds (the `[[figures]]` of the study; see [`crate::study::analysis::spec::FigureKind`]): time histories,
//! phase portraits with the stroboscopic points, Poincare maps (section points over the faint
//! trajectory, with a zoomed inset when the points cluster within a tenth of the trajectory's
//! extent but spread over at least 100 integration tolerances, `ZOOM_TOLERANCES`), orbits inside a clearance circle, and bifurcation diagrams (section points against
//! the swept parameter; a continuation sweep draws the way up and the way down in two colours).
//! For a sweep, per-value figures draw one panel per selected value (`values`, default the
//! first six done). Without `[[figures]]`, every observable gets a time history and, in a sweep,
//! a bifurcation diagram.
//!
//! Time histories and phase portraits draw at most the last [`FIGURE_HISTORY`] history samples of
//! each run, read from the file as such: a long run's figures cost no more memory than a short
//! one's (the file keeps every sample).
//!
//! When the study computed the chaos measures ([`crate::measures::chaos`]), a bifurcation diagram gets
//! panels below it on the same parameter axis: lambda_1 with its 3-standard-error band (and the
//! two-trajectory estimate), and the 0-1 test's K; a single run gets a convergence figure of the
//! running exponent estimates (`<study>-lyapunov.png`).

use std::path::{Path, PathBuf};

use crate::figures::analysis_data::{Data, Job, read, short};
pub use crate::figures::analysis_data::{FIGURE_HISTORY, display_scale};
use crate::figures::plot::write;
use crate::figures::plot::{Format, Panel, Series};
use crate::study::analysis::spec::{FigureKind, FigureSpec};
use crate::{Error, Result};

fn default_figures(d: &Data) -> Vec<FigureSpec> {
    let mut v = Vec::new();
    let has_history = d.jobs.iter().any(|j| !j.history_time.is_empty());
    for o in &d.spec.observables {
        let base = FigureSpec {
            kind: FigureKind::Time,
            name: None,
            x: None,
            y: o.name.clone(),
            title: None,
            section: None,
            values: Vec::new(),
            circle: None,
            circle_from_parameter: false,
            scale: None,
            unit: None,
        };
        if has_history {
            v.push(base.clone());
        }
        if d.sweep.is_some() {
            v.push(FigureSpec {
                kind: FigureKind::Bifurcation,
                ..base
            });
        }
    }
    v
}

/// `title`, naming the done values a panel leaves out because their `what` is not a number (a
/// periodic window where the 0-1 test has no K, a value whose Lyapunov run failed): the count
/// and the parameter range, with `(parameter, value)` per done value.
fn left_out(title: String, values: impl Iterator<Item = (f64, f64)>, what: &str) -> String {
    let missing: Vec<f64> = values
        .filter(|(_, v)| !v.is_finite())
        .map(|(p, _)| p)
        .collect();
    match (missing.first(), missing.last()) {
        (Some(a), Some(b)) if missing.len() == 1 || a == b => {
            format!("{title} (no {what} at {})", crate::study::report::num(*a))
        }
        (Some(a), Some(b)) => format!(
            "{title} (no {what} at {} values, {} to {})",
            missing.len(),
            crate::study::report::num(*a),
            crate::study::report::num(*b)
        ),
        _ => title,
    }
}

/// The chaos panels under a bifurcation diagram: lambda_1 with its 3-standard-error band and the
/// two-trajectory estimate, and one panel per chaos indicator (K of the 0-1 test); none when the
/// sweep has no chaos measures.
fn chaos_panels(d: &Data, x_label: &str, px: f64) -> Vec<Panel> {
    let mut out = Vec::new();
    let rows: Vec<&[f64; 4]> = d.chaos.iter().filter(|r| r[1].is_finite()).collect();
    if !rows.is_empty() {
        let x: Vec<f64> = rows.iter().map(|r| r[0] * px).collect();
        let line = |label: &str, f: &dyn Fn(&[f64; 4]) -> f64| Series {
            label: label.into(),
            x: x.clone(),
            y: rows.iter().map(|r| f(r)).collect(),
        };
        let mut p = Panel::new(
            left_out(
                "Largest Lyapunov exponent".into(),
                d.chaos.iter().map(|r| (r[0] * px, r[1])),
                "lambda_1",
            ),
            x_label,
            "lambda_1 (1/s)",
            vec![Series {
                label: String::new(),
                x: vec![x[0], x[x.len() - 1]],
                y: vec![0.0, 0.0],
            }],
        );
        p.styles.push(crate::figures::plot::LineStyle {
            color: 5,
            dashed: true,
        });
        p.bands.push(crate::figures::plot::Band {
            label: "lambda_1 +- 3 s.e.".into(),
            x: x.clone(),
            lo: rows.iter().map(|r| r[1] - 3.0 * r[2]).collect(),
            hi: rows.iter().map(|r| r[1] + 3.0 * r[2]).collect(),
            color: 0,
        });
        p.line_width = 1;
        // The two estimates usually agree to the width of a dot: the two-trajectory one is
        // drawn first and larger, the tangent one over it, smaller, so that both show.
        if rows.iter().any(|r| r[3].is_finite()) {
            p.points
                .push(line("lambda_1 (two trajectories)", &|r| r[3]));
            p.point_radii = vec![4, 2];
            p.point_colors = vec![1, 0];
        }
        p.points.push(line("lambda_1 (tangent)", &|r| r[1]));
        out.push(p);
    }
    for (row, values) in &d.numbers {
        let finite: Vec<&[f64; 2]> = values.iter().filter(|r| r[1].is_finite()).collect();
        if finite.is_empty() {
            continue;
        }
        let mut p = Panel::new(
            left_out(
                row.title.into(),
                values.iter().map(|r| (r[0] * px, r[1])),
                row.column,
            ),
            x_label,
            row.column,
            Vec::new(),
        );
        p.y_range = row.range;
        p.points = vec![Series {
            label: row.column.into(),
            x: finite.iter().map(|r| r[0] * px).collect(),
            y: finite.iter().map(|r| r[1]).collect(),
        }];
        out.push(p);
    }
    out
}

/// The branches of periodic orbits (observable `y` at their strobe points against the parameter:
/// stable solid, unstable dashed, every strobe point of a period-k orbit a line of its own) with
/// their special points marked, over the brute-force bifurcation diagram (the sweep's strobe
/// points, grey) when the study has one.
fn branches_panel(d: &Data, f: &FigureSpec, y: &str, scale: f64, y_label: String) -> Panel {
    let mut p = Panel::new(
        f.title
            .clone()
            .unwrap_or(format!("Periodic orbits: {y} at the strobe points")),
        String::new(),
        y_label,
        Vec::new(),
    );
    let Some(c) = &d.continuation else {
        p.title = format!("{} (no continuation in the file)", p.title);
        return p;
    };
    // The parameter in millimetres when it is a small length (a clearance), as the sweep's
    // bifurcation diagrams draw it.
    let all = c
        .branches
        .iter()
        .flat_map(|b| b.parameter.iter().copied())
        .chain(c.specials.iter().map(|s| s.1))
        .chain(d.jobs.iter().map(|j| j.parameter));
    let (px, punit) = match display_scale(&c.unit, all) {
        Some((f, u)) => (f, u.to_string()),
        None => (1.0, c.unit.clone()),
    };
    p.x_label = if punit.is_empty() {
        short(&c.parameter).to_string()
    } else {
        format!("{} ({punit})", short(&c.parameter))
    };
    let (mut stable_seen, mut unstable_seen) = (false, false);
    for b in &c.branches {
        let rows = &b.strobe[y];
        let k = rows.first().map_or(0, Vec::len);
        for j in 0..k {
            // Runs of equal stability; consecutive runs share their end point.
            let mut start = 0;
            while start < b.parameter.len() {
                let st = b.stable[start];
                let mut end = start;
                while end + 1 < b.parameter.len() && b.stable[end + 1] == st {
                    end += 1;
                }
                let stop = (end + 1).min(b.parameter.len() - 1);
                let stable = st == 1;
                let label = match (stable, stable_seen, unstable_seen) {
                    (true, false, _) => "stable",
                    (false, _, false) => "unstable",
                    _ => "",
                };
                if stable {
                    stable_seen = true;
                } else {
                    unstable_seen = true;
                }
                p.series.push(Series {
                    label: label.into(),
                    x: b.parameter[start..=stop].iter().map(|v| v * px).collect(),
                    y: rows[start..=stop].iter().map(|r| r[j] * scale).collect(),
                });
                p.styles.push(crate::figures::plot::LineStyle {
                    color: if stable { 0 } else { 1 },
                    dashed: !stable,
                });
                start = end + 1;
            }
        }
    }
    if d.sweep.is_some() {
        let mut pts = Series {
            label: "strobe points (sweep)".into(),
            x: Vec::new(),
            y: Vec::new(),
        };
        for j in &d.jobs {
            let v = &j.sections["strobe"][y];
            pts.x.extend(std::iter::repeat_n(j.parameter * px, v.len()));
            pts.y.extend(v.iter().map(|a| a * scale));
        }
        p.points.push(pts);
        p.point_colors.push(4);
        p.point_radii.push(1);
    }
    for (kind, color) in [
        ("fold", 5),
        ("period-doubling", 0),
        ("neimark-sacker", 2),
        ("grazing", 6),
    ] {
        let sp: Vec<_> = c.specials.iter().filter(|s| s.0 == kind).collect();
        if sp.is_empty() {
            continue;
        }
        p.points.push(Series {
            label: kind.replace('-', " "),
            x: sp.iter().map(|s| s.1 * px).collect(),
            y: sp.iter().map(|s| s.2[y] * scale).collect(),
        });
        p.point_colors.push(color);
        p.point_radii.push(5);
    }
    p.line_width = 2;
    p
}

/// The convergence figure of a single run's Lyapunov exponents: the running estimates against
/// the time since the Lyapunov run began, on a logarithmic axis (the estimates settle as 1/t),
/// the two-trajectory estimate dashed over them (both show where they agree), and the final
/// lambda_1 with its 3-standard-error band.
fn convergence_panel(d: &Data) -> Option<Panel> {
    let c = d.convergence.as_ref()?;
    let k = c.history.first().map_or(0, Vec::len);
    // The run began `averaging_time` before its last re-orthonormalisation (files without the
    // attribute: at the first one's time less one interval).
    let last = c.time.last().copied().unwrap_or(0.0);
    let begun = if c.averaging_time.is_finite() {
        last - c.averaging_time
    } else {
        match c.time[..] {
            [a, b, ..] => a - (b - a),
            _ => 0.0,
        }
    };
    let since: Vec<f64> = c.time.iter().map(|t| t - begun).collect();
    let mut p = Panel::new(
        format!("{}: running Lyapunov exponents", d.name),
        "time since the Lyapunov run began (s)",
        "exponent (1/s)",
        Vec::new(),
    );
    p.log_x = since.iter().any(|t| *t > 0.0);
    for j in 0..k {
        p.series.push(Series {
            label: format!("lambda_{}", j + 1),
            x: since.clone(),
            y: c.history.iter().map(|r| r[j]).collect(),
        });
        p.styles.push(crate::figures::plot::LineStyle {
            color: if j == 0 { 0 } else { j + 1 },
            dashed: false,
        });
    }
    if !c.two.is_empty() {
        p.series.push(Series {
            label: "lambda_1, two trajectories".into(),
            x: since.clone(),
            y: c.two.clone(),
        });
        p.styles.push(crate::figures::plot::LineStyle {
            color: 1,
            dashed: true,
        });
    }
    if let (Some(l1), Some(e1), Some(t0), Some(t1)) = (
        c.exponents.first(),
        c.stderr.first(),
        since.iter().find(|t| **t > 0.0),
        since.last(),
    ) && l1.is_finite()
        && e1.is_finite()
    {
        p.bands.push(crate::figures::plot::Band {
            label: format!(
                "lambda_1 = {} +- {} (3 s.e.)",
                crate::study::report::num(*l1),
                crate::study::report::num(3.0 * e1)
            ),
            x: vec![*t0, *t1],
            lo: vec![l1 - 3.0 * e1; 2],
            hi: vec![l1 + 3.0 * e1; 2],
            color: 0,
        });
    }
    Some(p)
}

/// The unit an axis recorded in `recorded` is drawn in when a figure scales it by `scale` and
/// names the unit `figure` (`scale = 1000.0, unit = "mm"`): the figure's unit takes the place of
/// the SI unit it is a multiple of, so that a velocity recorded in m/s reads "mm/s", not "mm";
/// an axis in another unit keeps its own with the factor (`rad/s, x 1000`).
fn scaled_unit(recorded: &str, figure: &str, scale: f64) -> String {
    // Multiples of SI units a figure may name, and the SI unit of each.
    const BASES: [(&str, &str); 12] = [
        ("mm", "m"),
        ("um", "m"),
        ("µm", "m"),
        ("cm", "m"),
        ("km", "m"),
        ("mrad", "rad"),
        ("deg", "rad"),
        ("kN", "N"),
        ("mN", "N"),
        ("ms", "s"),
        ("kN m", "N m"),
        ("N mm", "N m"),
    ];
    let base = BASES.iter().find(|(f, _)| *f == figure).map(|(_, b)| *b);
    if base.is_none() && !figure.is_empty() {
        // A unit of the figure's own (`mm/s`): as written.
        return figure.to_string();
    }
    let rest = base.and_then(|b| {
        recorded
            .strip_prefix(b)
            .filter(|r| r.is_empty() || r.starts_with(['/', ' ', '^', '*']))
    });
    match rest {
        Some(r) => format!("{figure}{r}"),
        None if scale == 1.0 => recorded.to_string(),
        None if recorded.is_empty() || recorded == "1" => format!("x {scale}"),
        None => format!("{recorded}, x {scale}"),
    }
}

fn scaled(v: &[f64], s: f64) -> Vec<f64> {
    v.iter().map(|x| x * s).collect()
}

/// Bounding box (x0, x1, y0, y1) of points.
fn bbox(x: &[f64], y: &[f64]) -> Option<(f64, f64, f64, f64)> {
    let fin = |v: &[f64]| {
        let it = v.iter().copied().filter(|a| a.is_finite());
        let lo = it.clone().fold(f64::INFINITY, f64::min);
        let hi = it.fold(f64::NEG_INFINITY, f64::max);
        (lo.is_finite()).then_some((lo, hi))
    };
    let (x0, x1) = fin(x)?;
    let (y0, y1) = fin(y)?;
    Some((x0, x1, y0, y1))
}

/// Every recorded value of observable `n`: histories and section points of every job.
fn values_of<'a>(d: &'a Data, n: &'a str) -> impl Iterator<Item = f64> + 'a {
    d.jobs.iter().flat_map(move |j| {
        j.history
            .get(n)
            .into_iter()
            .flatten()
            .chain(j.sections.values().filter_map(move |m| m.get(n)).flatten())
            .copied()
    })
}

/// The panels of figure `f`: its branches, its bifurcation diagram (with the chaos panels under
/// it), or one panel per selected job.
fn panels_for(d: &Data, f: &FigureSpec) -> Result<Vec<Panel>> {
    let axes = Axes::new(d, f);
    let y = axes.y;
    if f.kind == FigureKind::Branches {
        return Ok(vec![branches_panel(d, f, y, axes.s, axes.label(y))]);
    }
    if f.kind == FigureKind::Bifurcation {
        return Ok(axes.bifurcation());
    }
    let jobs: Vec<&Job> = if f.values.is_empty() {
        d.jobs.iter().take(6).collect()
    } else {
        f.values
            .iter()
            .filter_map(|v| {
                d.jobs
                    .iter()
                    .find(|j| (j.parameter - v).abs() <= 1e-9 * v.abs().max(1e-300))
            })
            .collect()
    };
    let mut panels = Vec::new();
    for j in jobs {
        let mut p = axes.job_panel(j);
        // Thin lines: long trajectories drawn 2 px wide show stroke artifacts.
        p.line_width = 1;
        panels.push(p);
    }
    Ok(panels)
}

/// What the panels of one figure share: the figure, the observables on its axes with the scale
/// and unit each is drawn in, and the section whose points it draws.
/// The larger of the extents `bx` and `by` of points `x` and `y` (drawn values, the recorded
/// ones times `sx` and `sy`), each in integration tolerances of its axis: the step's error bound
/// atol + rtol |v| at the largest recorded |v|, in the drawn unit.
fn in_tolerances(
    (x, sx, bx): (&[f64], f64, f64),
    (y, sy, by): (&[f64], f64, f64),
    (rtol, atol): (f64, f64),
) -> f64 {
    let tol = |v: &[f64], s: f64| {
        let s = s.abs().max(f64::MIN_POSITIVE);
        let big = v.iter().fold(0.0f64, |m, x| m.max(x.abs())) / s;
        (atol + rtol * big) * s
    };
    (bx / tol(x, sx)).max(by / tol(y, sy))
}

/// The fewest integration tolerances (atol + rtol |v| on an axis) the points of a Poincare map
/// must spread over for a zoomed inset: closer together, they agree to the integrator's error,
/// and magnifying them would draw its noise as structure.
const ZOOM_TOLERANCES: f64 = 100.0;

struct Axes<'a> {
    d: &'a Data,
    f: &'a FigureSpec,
    /// The figure's own scale (1 when it gives none).
    s: f64,
    x: &'a str,
    y: &'a str,
    sx: f64,
    ux: Option<String>,
    sy: f64,
    uy: Option<String>,
    section: String,
    sec_label: String,
}

impl<'a> Axes<'a> {
    /// The axes of figure `f`: per axis the figure's own scale and unit when it gives them, else
    /// millimetres for small lengths ([`display_scale`]), else as recorded; an orbit keeps one
    /// scale for both axes and its circle.
    fn new(d: &'a Data, f: &'a FigureSpec) -> Axes<'a> {
        let s = f.scale.unwrap_or(1.0);
        // Per axis: the figure's own scale and unit when it gives them, else millimetres for small
        // lengths (display_scale), else as recorded.
        let auto = |n: &str| -> (f64, Option<String>) {
            if f.scale.is_some() || f.unit.is_some() {
                return (s, None);
            }
            let u = d.units.get(n).cloned().unwrap_or_default();
            match display_scale(&u, values_of(d, n)) {
                Some((k, mm)) => (k, Some(mm.to_string())),
                None => (1.0, None),
            }
        };
        let y = f.y.as_str();
        let x = f.x.as_deref().unwrap_or("");
        let (sx, ux) = auto(x);
        let (sy, uy) = auto(y);
        // An orbit keeps one scale for both axes and its circle.
        let (sx, ux, sy, uy) = if f.kind == FigureKind::Orbit && (sx != sy || ux != uy) {
            (s, None, s, None)
        } else {
            (sx, ux, sy, uy)
        };
        let section = f.section.clone().unwrap_or_else(|| "strobe".into());
        let sec_label = if section == "strobe" {
            "strobe points".to_string()
        } else {
            format!("section '{section}'")
        };
        Axes {
            d,
            f,
            s,
            x,
            y,
            sx,
            ux,
            sy,
            uy,
            section,
            sec_label,
        }
    }

    /// The axis label of observable `n`: its name and the unit it is drawn in.
    fn label(&self, n: &str) -> String {
        let shown = if n == self.x { &self.ux } else { &self.uy };
        let recorded = self.d.units.get(n).cloned().unwrap_or_default();
        let u = shown.clone().unwrap_or_else(|| match &self.f.unit {
            Some(fu) => scaled_unit(&recorded, fu, self.s),
            None if self.s != 1.0 => scaled_unit(&recorded, "", self.s),
            None => recorded,
        });
        if u.is_empty() || u == "1" {
            n.to_string()
        } else {
            format!("{n} ({u})")
        }
    }

    /// A panel's title: the figure's own or `what`, with the job's value.
    fn title(&self, what: String, job: &Job) -> String {
        let t = self.f.title.clone().unwrap_or(what);
        if job.label.is_empty() {
            t
        } else {
            format!("{t}, {}", job.label)
        }
    }

    /// The bifurcation diagram (section points against the swept parameter, the way up and the
    /// way down apart) and the chaos panels under it, on one parameter axis.
    fn bifurcation(&self) -> Vec<Panel> {
        let (d, f, y) = (self.d, self.f, self.y);
        let (pname, punit) = d.sweep.clone().unwrap_or_default();
        let mut up = Series {
            label: "way up".into(),
            x: Vec::new(),
            y: Vec::new(),
        };
        let mut down = Series {
            label: "way down".into(),
            x: Vec::new(),
            y: Vec::new(),
        };
        // A clearance swept in metres is drawn in millimetres.
        let (px, punit) = match display_scale(&punit, d.jobs.iter().map(|j| j.parameter)) {
            Some((k, u)) => (k, u.to_string()),
            None => (1.0, punit),
        };
        for j in &d.jobs {
            let pts = &j.sections[&self.section][y];
            let s_ = if j.up { &mut up } else { &mut down };
            s_.x.extend(std::iter::repeat_n(j.parameter * px, pts.len()));
            s_.y.extend(pts.iter().map(|v| v * self.sy));
        }
        let mut p = Panel::new(
            f.title
                .clone()
                .unwrap_or(format!("Bifurcation diagram of {y} ({})", self.sec_label)),
            if punit.is_empty() {
                short(&pname).to_string()
            } else {
                format!("{} ({punit})", short(&pname))
            },
            self.label(y),
            Vec::new(),
        );
        p.point_size = 1;
        if down.x.is_empty() {
            up.label = self.sec_label.clone();
            p.points = vec![up];
        } else {
            p.points = vec![up, down];
        }
        let mut panels = vec![p];
        panels.extend(chaos_panels(d, &panels[0].x_label, px));
        if panels.len() > 1 {
            // One parameter axis for the stacked panels.
            let (lo, hi) = d
                .jobs
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), j| {
                    (a.min(j.parameter * px), b.max(j.parameter * px))
                });
            let pad = 0.02 * (hi - lo).max(f64::MIN_POSITIVE);
            for p in &mut panels {
                p.x_range = Some((lo - pad, hi + pad));
            }
        }
        panels
    }

    /// Job `j`'s panel of the figure's kind: its time history, phase portrait, Poincare map or
    /// orbit.
    fn job_panel(&self, j: &Job) -> Panel {
        let (x, y, sx, sy) = (self.x, self.y, self.sx, self.sy);
        let hx = j.history.get(x).map(|v| scaled(v, sx)).unwrap_or_default();
        let hy = j.history.get(y).map(|v| scaled(v, sy)).unwrap_or_default();
        let pts = j.sections.get(&self.section);
        let px = pts
            .and_then(|m| m.get(x))
            .map(|v| scaled(v, sx))
            .unwrap_or_default();
        let py = pts
            .and_then(|m| m.get(y))
            .map(|v| scaled(v, sy))
            .unwrap_or_default();
        match self.f.kind {
            FigureKind::Time => self.time(j, hy),
            FigureKind::Phase => {
                let mut p = Panel::new(
                    self.title(format!("Phase portrait {y} against {x}"), j),
                    self.label(x),
                    self.label(y),
                    vec![Series {
                        label: "trajectory (kept periods)".into(),
                        x: hx,
                        y: hy,
                    }],
                );
                p.points = vec![Series {
                    label: self.sec_label.clone(),
                    x: px,
                    y: py,
                }];
                p
            }
            FigureKind::Poincare => self.poincare(j, hx, hy, px, py),
            FigureKind::Orbit => self.orbit(j, hx, hy),
            FigureKind::Bifurcation | FigureKind::Branches => unreachable!("handled above"),
        }
    }

    /// Job `j`'s time history `hy` of the figure's `y`; with a hyperplane `section`, its
    /// crossings inside the history's span marked on it. The history is sampled on a clock, so
    /// it cuts the corners of sharp turns (an impact, a stop) and its samples' extremes miss
    /// them; the crossings are located on the integrator's dense output (a section on the
    /// impact surface marks every impact where it happens).
    fn time(&self, j: &Job, hy: Vec<f64>) -> Panel {
        let y = self.y;
        let mut p = Panel::new(
            self.title(format!("{y} against time"), j),
            "time (s)",
            self.label(y),
            vec![Series {
                label: y.into(),
                x: j.history_time.clone(),
                y: hy,
            }],
        );
        let (Some(name), Some(&t0), Some(&t1)) = (
            self.f.section.as_ref(),
            j.history_time.first(),
            j.history_time.last(),
        ) else {
            return p;
        };
        if let (Some(times), Some(values)) = (
            j.crossing_times.get(name),
            j.sections.get(name).and_then(|m| m.get(y)),
        ) {
            let (x, v): (Vec<f64>, Vec<f64>) = times
                .iter()
                .zip(values)
                .filter(|(t, _)| (t0..=t1).contains(*t))
                .map(|(t, v)| (*t, v * self.sy))
                .unzip();
            p.points = vec![Series {
                label: format!("section '{name}' crossings"),
                x,
                y: v,
            }];
            p.point_size = 2;
        }
        p
    }

    /// Job `j`'s Poincare map: the section points `(px, py)` over the faint trajectory
    /// `(hx, hy)`, with a zoomed inset, away from the points, when they cluster within a tenth of
    /// the trajectory's extent and spread over at least [`ZOOM_TOLERANCES`] integration
    /// tolerances; the inset's title gives the spread in tolerances.
    fn poincare(&self, j: &Job, hx: Vec<f64>, hy: Vec<f64>, px: Vec<f64>, py: Vec<f64>) -> Panel {
        let (x, y) = (self.x, self.y);
        let traj = bbox(&hx, &hy);
        let mut p = Panel::new(
            self.title(format!("Poincare map {y} against {x}"), j),
            self.label(x),
            self.label(y),
            if hx.is_empty() {
                Vec::new()
            } else {
                vec![Series {
                    label: "trajectory".into(),
                    x: hx,
                    y: hy,
                }]
            },
        );
        let pts = Series {
            label: self.sec_label.clone(),
            x: px.clone(),
            y: py.clone(),
        };
        if let (Some(t), Some(b)) = (traj, bbox(&px, &py)) {
            let (tw, th) = (t.1 - t.0, t.3 - t.2);
            let (bw, bh) = (b.1 - b.0, b.3 - b.2);
            // The points' spread in integration tolerances: the step's error bound
            // atol + rtol |v| on each axis (in the drawn unit). A cluster a few tolerances wide
            // is the integrator's error, not structure of the map: it gets no zoom, and the
            // title says how wide it is.
            let spread = self
                .d
                .tolerances
                .map(|t| in_tolerances((&px, self.sx, bw), (&py, self.sy, bh), t));
            if let Some(n) = spread.filter(|n| *n < ZOOM_TOLERANCES) {
                p.title = format!(
                    "{} (points within {n:.1} integration tolerances: no zoom)",
                    p.title
                );
            } else if bw < 0.1 * tw && bh < 0.1 * th {
                let pad = |lo: f64, hi: f64, span: f64| {
                    let w = (hi - lo).max(1e-6 * span).max(f64::MIN_POSITIVE);
                    (lo - 0.25 * w, hi + 0.25 * w)
                };
                let title = match spread {
                    Some(n) => format!("zoom: {n:.1e} tolerances wide"),
                    None => "zoom".into(),
                };
                let mut inset = Panel::new(&title, "", "", Vec::new());
                inset.points = vec![pts.clone()];
                inset.x_range = Some(pad(b.0, b.1, tw));
                inset.y_range = Some(pad(b.2, b.3, th));
                p.inset = Some(Box::new(inset));
                // Put the inset in the quarter away from the points.
                let (cx, cy) = (0.5 * (b.0 + b.1), 0.5 * (b.2 + b.3));
                p.inset_corner = (cx < 0.5 * (t.0 + t.1), cy < 0.5 * (t.2 + t.3));
            }
        }
        p.points = vec![pts];
        p
    }

    /// Job `j`'s orbit `(hx, hy)` inside its clearance circle (the figure's, or the job's
    /// parameter), on equal axes about the centre.
    fn orbit(&self, j: &Job, hx: Vec<f64>, hy: Vec<f64>) -> Panel {
        let (f, x, y, sx) = (self.f, self.x, self.y, self.sx);
        let r = if f.circle_from_parameter {
            Some(j.parameter * sx)
        } else {
            f.circle.map(|c| c * sx)
        };
        let mut series = vec![Series {
            label: "centre".into(),
            x: hx.clone(),
            y: hy.clone(),
        }];
        let mut lim =
            hx.iter().chain(&hy).fold(
                0.0f64,
                |m, v| {
                    if v.is_finite() { m.max(v.abs()) } else { m }
                },
            );
        if let Some(r) = r {
            let a = (0..=360).map(|k| (k as f64).to_radians());
            series.push(Series {
                label: format!("clearance {}", crate::study::report::num(r)),
                x: a.clone().map(|t| r * t.cos()).collect(),
                y: a.map(|t| r * t.sin()).collect(),
            });
            lim = lim.max(r);
        }
        let lim = 1.1 * lim.max(f64::MIN_POSITIVE);
        let mut p = Panel::new(
            self.title(format!("Orbit {y} against {x}"), j),
            self.label(x),
            self.label(y),
            series,
        );
        p.x_range = Some((-lim, lim));
        p.y_range = Some((-lim, lim));
        p.equal_aspect = true;
        p
    }
}

fn stem(d: &Data, f: &FigureSpec) -> String {
    if let Some(n) = &f.name {
        return n.clone();
    }
    let kind = format!("{:?}", f.kind).to_lowercase();
    match &f.x {
        Some(x) if f.kind != FigureKind::Time && f.kind != FigureKind::Bifurcation => {
            format!("{}-{kind}-{x}-{}", d.name, f.y)
        }
        _ => format!("{}-{kind}-{}", d.name, f.y),
    }
}

/// The `[[figures]]` tables of the TOML file `from` (a study file edited, or a file of figures
/// alone; its other tables are not read), each checked against the study of the analysis file
/// `path` (`spec`), as the study's own are when it is run: errors name `from` and the field.
fn figures_from(
    from: &Path,
    path: &Path,
    spec: &crate::study::analysis::spec::AnalysisStudy,
) -> Result<Vec<FigureSpec>> {
    #[derive(serde::Deserialize)]
    struct Figures {
        #[serde(default)]
        figures: Vec<FigureSpec>,
    }
    let text = std::fs::read_to_string(from).map_err(|e| Error::Io {
        file: from.to_path_buf(),
        message: e.to_string(),
    })?;
    let figures = jointplay_solver::scene::parse_toml::<Figures>(&text, from)?.figures;
    if figures.is_empty() {
        return Err(crate::study::spec::invalid(
            from,
            "figures",
            "no [[figures]] table to draw",
        ));
    }
    let jobs = match spec.sweep {
        Some(_) => crate::study::analysis::spec::sweep_jobs(spec, path)?,
        None => Vec::new(),
    };
    for (i, f) in figures.iter().enumerate() {
        spec.check_figure(from, &jobs, i, f)?;
    }
    Ok(figures)
}

/// Draws every figure of the analysis file `path` into `out` in the given formats: the figures
/// of its study, or those of the TOML file `figures` when given (a title or a scale changed
/// without running the study again); returns the files written.
pub fn render(
    path: &Path,
    out: &Path,
    formats: &[Format],
    figures: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    let mut d = read(path)?;
    if let Some(from) = figures {
        d.spec.figures = figures_from(from, path, &d.spec)?;
    }
    std::fs::create_dir_all(out).map_err(|e| Error::Io {
        file: out.to_path_buf(),
        message: format!("cannot create output directory: {e}"),
    })?;
    let specs = if d.spec.figures.is_empty() {
        default_figures(&d)
    } else {
        d.spec.figures.clone()
    };
    let mut files = Vec::new();
    for f in &specs {
        let panels = panels_for(&d, f)?;
        let cols = if f.kind == FigureKind::Bifurcation {
            1
        } else if panels.len() >= 3 {
            3
        } else {
            panels.len()
        };
        files.extend(write(out, &stem(&d, f), &panels, cols, formats)?);
    }
    if let Some(p) = convergence_panel(&d) {
        files.extend(write(
            out,
            &format!("{}-lyapunov", d.name),
            &[p],
            1,
            formats,
        )?);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {

    /// A Poincare map's points are measured in integration tolerances: on a period-1 orbit at
    /// |x| near 1 and rtol 1e-9, atol 1e-11 (the Duffing studies), points 5e-9 apart span 5
    /// tolerances and get no zoom; drawn in mm (scale 1000) the count is the same.
    #[test]
    fn a_cluster_is_measured_in_integration_tolerances_in_any_drawn_unit() {
        let x = [1.0, 1.0 + 5e-9];
        let y = [0.5, 0.5 + 1e-9];
        let t = (1e-9, 1e-11);
        let n = in_tolerances((&x, 1.0, 5e-9), (&y, 1.0, 1e-9), t);
        assert!((n - 5e-9 / 1.01e-9).abs() < 1e-6 * n, "{n}");
        assert!(n < ZOOM_TOLERANCES);
        let mm = |v: &[f64]| v.iter().map(|a| a * 1e3).collect::<Vec<_>>();
        let m = in_tolerances((&mm(&x), 1e3, 5e-6), (&mm(&y), 1e3, 1e-6), t);
        assert!((m - n).abs() < 1e-9 * n, "{m} against {n}");
        // A cluster a thousand times wider is structure worth a zoom.
        assert!(in_tolerances((&x, 1.0, 5e-6), (&y, 1.0, 1e-9), t) > ZOOM_TOLERANCES);
    }

    use super::{ZOOM_TOLERANCES, display_scale, in_tolerances, left_out};

    #[test]
    fn a_scaled_axis_names_the_unit_it_is_drawn_in() {
        use super::scaled_unit;
        assert_eq!(scaled_unit("m", "mm", 1e3), "mm");
        assert_eq!(scaled_unit("m/s", "mm", 1e3), "mm/s");
        assert_eq!(scaled_unit("m/s^2", "mm", 1e3), "mm/s^2");
        assert_eq!(scaled_unit("rad/s", "deg", 57.3), "deg/s");
        // A unit the figure's does not scale keeps its own, with the factor.
        assert_eq!(scaled_unit("N", "mm", 1e3), "N, x 1000");
        assert_eq!(scaled_unit("1", "", 10.0), "x 10");
        // "m" is no prefix of "mol": only a whole unit is replaced.
        assert_eq!(scaled_unit("mol", "mm", 1e3), "mol, x 1000");
        assert_eq!(scaled_unit("m", "m", 1.0), "m");
        // A unit the table does not know is the figure's own, as written.
        assert_eq!(scaled_unit("m/s", "mm/s", 1e3), "mm/s");
    }

    #[test]
    fn a_panel_names_the_values_it_leaves_out() {
        let t = || "K".to_string();
        assert_eq!(
            left_out(t(), [(0.2, 1.0), (0.3, 0.0)].into_iter(), "K"),
            "K"
        );
        assert_eq!(
            left_out(t(), [(0.2, f64::NAN), (0.3, 0.0)].into_iter(), "K"),
            "K (no K at 0.2000)"
        );
        assert_eq!(
            left_out(
                t(),
                [(0.2, f64::NAN), (0.25, 1.0), (0.3, f64::NAN)].into_iter(),
                "K"
            ),
            "K (no K at 2 values, 0.2000 to 0.3000)"
        );
    }

    #[test]
    fn small_lengths_are_drawn_in_millimetres() {
        // A clearance sweep 0 to 0.8 mm and an eccentricity: mm.
        assert_eq!(display_scale("m", [0.0, 2e-4, 8e-4]), Some((1e3, "mm")));
        assert_eq!(
            display_scale("m", [-5.8e-5, f64::NAN, 4.2e-5]),
            Some((1e3, "mm"))
        );
        // The platform's height (1.2 m), a velocity, a friction coefficient: as recorded.
        assert_eq!(display_scale("m", [1.18, 1.24]), None);
        assert_eq!(display_scale("m/s", [1e-4]), None);
        assert_eq!(display_scale("", [0.05]), None);
        assert_eq!(display_scale("m", []), None);
    }
}
