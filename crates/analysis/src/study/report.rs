//! Quantities of a study computed from its HDF5 file, and the markdown table of them.
//!
//! Everything here reads the study file written by `jointplay run STUDY`, never the simulation in
//! memory, so a table can always be regenerated from the file (`jointplay report FILE.h5`).
//!
//! The settled window is the last drive period of a run, `[t_end - T, t_end]` (the last quarter of
//! the span when the drives have no common period). With `Δ` the difference from the case's
//! reference (sampled at the same times), the quantities per case are, for each axis `a` of the
//! report body:
//!
//! | name | unit | definition |
//! |---|---|---|
//! | `offset_max_a` | m | `max_t |Δr_a|`, the largest displacement deviation |
//! | `offset_settled_a` | m | mean of `Δr_a` over the settled window |
//! | `velocity_fluctuation_a` | m/s | `max_t |Δv_a|` |
//! | `acceleration_jump_a` | m/s^2 | `Δa_a` where `|Δa_a|` is largest (signed) |
//! | `acceleration_ripple_a` | m/s^2 | half the peak-to-peak range of `Δa_a` over the settled window |
//! | `acceleration_settling_time_a` | s | the first time after which `Δa_a` stays inside its settled range widened on both sides by `tol` times `A`, the reference's acceleration amplitude along `a` (half its peak-to-peak range over the settled window); none ("-") when the settled range of `Δa_a` is wider than `2 A`: the clearance still shakes the body by more than the drive moves it |
//!
//! and for each report joint `J`, with `F(t)` the magnitude of the resultant contact force on the
//! journal (clearance joints) or of the reaction force (ideal joints):
//!
//! | name | unit | definition |
//! |---|---|---|
//! | `J.peak_force`, `J.peak_time` | N, s | largest `F` over the run and when |
//! | `J.startup_peak_force`, `J.startup_peak_time` | N, s | largest `F` in the start-up window, the first tenth of a drive period (of the span without a period), and when |
//! | `J.settled_force` | N | mean of `F` over the settled window |
//! | `J.settled_min`, `J.settled_max` | N | range of `F` over the settled window |
//! | `J.ripple` | N | half of that range: the amplitude of the settled fluctuation |
//! | `J.settling_time` | s | the first time after which `F` stays inside the settled range widened by `tol` times the settled mean on both sides (`report.settle_tolerance`, default 0.1); none ("-") when the settled range is wider than twice the settled mean: the force still rattles or leaves contact in the settled window, so nothing has settled |

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::storage::study_read::{Asked, Case, CaseData, read_cases};
use crate::study::spec::{CaseSpec, Published, StudySpec};
use crate::{Error, Result};

/// One quantity's value per case (NaN where it does not apply).
#[derive(Debug, Clone)]
pub struct Quantity {
    pub name: String,
    pub unit: &'static str,
    pub values: Vec<f64>,
}

/// The computed report of a study file.
#[derive(Debug, Clone)]
pub struct Report {
    pub study_name: String,
    pub description: String,
    pub file: PathBuf,
    pub cases: Vec<String>,
    /// Each case's edits of the base scene (or its failure) and reference case.
    pub case_notes: Vec<(String, Option<String>)>,
    pub body: Option<String>,
    /// The study's base scene as written in the study file.
    pub base_scene: String,
    pub motion: Vec<Quantity>,
    pub forces: Vec<Quantity>,
    pub published: Vec<Published>,
    pub wall_times: Vec<f64>,
}

impl Report {
    /// The value of `quantity` for `case`, if computed.
    pub fn value(&self, case: &str, quantity: &str) -> Option<f64> {
        let k = self.cases.iter().position(|c| c == case)?;
        self.motion
            .iter()
            .chain(&self.forces)
            .find(|q| q.name == quantity)
            .map(|q| q.values[k])
            .filter(|v| !v.is_nan())
    }
}

/// Index and value of the largest element (the first one on ties).
fn argmax(v: &[f64]) -> (usize, f64) {
    v.iter().enumerate().fold(
        (0, f64::NEG_INFINITY),
        |m, (i, &x)| if x > m.1 { (i, x) } else { m },
    )
}

/// The first time after which `x` stays inside its range over the settled window (from index
/// `s` on) widened on both sides by `tol * scale`; NaN when that range is wider than
/// `2 * scale` (nothing has settled), the first time when `x` never leaves the band.
fn settling(x: &[f64], time: &[f64], s: usize, scale: f64, tol: f64) -> f64 {
    let (lo, hi) = range(&x[s..]);
    if hi - lo > 2.0 * scale {
        return f64::NAN;
    }
    let (blo, bhi) = (lo - tol * scale, hi + tol * scale);
    match x[..s].iter().rposition(|&v| v < blo || v > bhi) {
        Some(i) => time[i + 1],
        None => time[0],
    }
}

/// A fraction as a percentage with at most three decimals and no trailing zeros (0.04: "4").
fn percent(b: f64) -> String {
    format!("{}", (1e5 * b).round() / 1e3)
}

/// Whether `ours` lies within `value * (1 ± band)` (the band taken about the magnitude, so that
/// a negative published value has the same band).
fn within(ours: f64, value: f64, band: f64) -> bool {
    (ours - value).abs() <= band * value.abs()
}

/// Smallest and largest element.
fn range(v: &[f64]) -> (f64, f64) {
    v.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &x| {
            (lo.min(x), hi.max(x))
        })
}

/// Start index of the settled window.
fn settled_start(c: &CaseData) -> usize {
    let (t0, t1) = (c.time[0], *c.time.last().unwrap_or(&c.time[0]));
    let from = match c.period {
        Some(p) if p < t1 - t0 => t1 - p,
        _ => t1 - 0.25 * (t1 - t0),
    };
    c.time
        .partition_point(|&t| t < from - 1e-9 * (1.0 + t1.abs()))
}

/// Reads a study file and computes its report.
pub fn compute(path: &Path) -> Result<Report> {
    let text = crate::storage::study_read::open(path)?;
    let spec: StudySpec = toml::from_str(&text).map_err(|err| Error::Hdf5 {
        file: path.to_path_buf(),
        message: format!("the stored study text does not parse: {err}"),
    })?;
    let tol = spec.report.settle_tolerance.unwrap_or(0.1);
    let cases = Cases::read(path, &spec)?;
    let motion = cases.motion(path, &spec, tol)?;
    let forces = cases.forces(&spec, tol);
    Ok(Report {
        study_name: spec.study.name.clone(),
        description: spec.study.description.clone(),
        file: path.to_path_buf(),
        cases: cases.labels,
        case_notes: cases.notes,
        body: spec.report.body.clone(),
        base_scene: spec.study.scene.display().to_string(),
        motion,
        forces,
        published: spec.report.published.clone(),
        wall_times: cases.walls,
    })
}

/// The cases of a study file, in the study's order: label, recorded data (None for a failed
/// case), note (its edits or its failure, and its reference case) and wall time.
struct Cases {
    labels: Vec<String>,
    data: Vec<Option<CaseData>>,
    notes: Vec<(String, Option<String>)>,
    walls: Vec<f64>,
}

impl Cases {
    /// Reads every case of the study `spec` from its file `path`.
    fn read(path: &Path, spec: &StudySpec) -> Result<Cases> {
        let cases: Vec<&str> = spec.cases.iter().map(|c| c.label.as_str()).collect();
        let joints: Vec<&str> = spec.report.joints.iter().map(String::as_str).collect();
        let asked = Asked {
            cases: &cases,
            body: spec.report.body.as_deref(),
            joints: &joints,
        };
        let mut labels = Vec::new();
        let mut data = Vec::new();
        let mut notes = Vec::new();
        let mut walls = Vec::new();
        for (c, case) in spec.cases.iter().zip(read_cases(path, &asked)?) {
            labels.push(c.label.clone());
            match case {
                Case::Failed(err) => {
                    notes.push((format!("failed: {err}"), None));
                    walls.push(f64::NAN);
                    data.push(None);
                }
                Case::Recorded { data: d, wall } => {
                    notes.push(case_note(spec, c));
                    walls.push(wall);
                    data.push(Some(d));
                }
            }
        }
        Ok(Cases {
            labels,
            data,
            notes,
            walls,
        })
    }

    /// The motion quantities of the report body along each report axis, per case against its
    /// reference (none without a body; a quantity no case has is left out).
    fn motion(&self, path: &Path, spec: &StudySpec, tol: f64) -> Result<Vec<Quantity>> {
        let n = self.labels.len();
        let mut motion: Vec<Quantity> = Vec::new();
        if spec.report.body.is_some() {
            let kinds: [(&str, &'static str); 6] = [
                ("offset_max", "m"),
                ("offset_settled", "m"),
                ("velocity_fluctuation", "m/s"),
                ("acceleration_jump", "m/s^2"),
                ("acceleration_ripple", "m/s^2"),
                ("acceleration_settling_time", "s"),
            ];
            for (a, ax) in spec.report.axis_list() {
                for (kind, unit) in kinds {
                    let mut values = vec![f64::NAN; n];
                    for (k, c) in self.data.iter().enumerate() {
                        let Some(c) = c else { continue };
                        let Some(r) = self.notes[k]
                            .1
                            .as_ref()
                            .and_then(|r| self.labels.iter().position(|l| l == r))
                        else {
                            continue;
                        };
                        let Some(rd) = self.data[r].as_ref() else {
                            continue;
                        };
                        let (Some(b), Some(rb)) = (&c.body, &rd.body) else {
                            continue;
                        };
                        if rd.time.len() != c.time.len()
                            || rd
                                .time
                                .iter()
                                .zip(&c.time)
                                .any(|(x, y)| (x - y).abs() > 1e-9 * (1.0 + y.abs()))
                        {
                            return Err(Error::Hdf5 {
                                file: path.to_path_buf(),
                                message: format!(
                                    "case '{}' and its reference '{}' are not sampled at the same times",
                                    self.labels[k], self.labels[r]
                                ),
                            });
                        }
                        values[k] = motion_value(kind, a, c, b, rb, tol);
                    }
                    if values.iter().any(|v| !v.is_nan()) {
                        motion.push(Quantity {
                            name: format!("{kind}_{ax}"),
                            unit,
                            values,
                        });
                    }
                }
            }
        }
        Ok(motion)
    }

    /// The force quantities of each report joint, per case.
    fn forces(&self, spec: &StudySpec, tol: f64) -> Vec<Quantity> {
        let n = self.labels.len();
        let mut forces = Vec::new();
        for j in &spec.report.joints {
            let kinds: [(&str, &'static str); 9] = [
                ("peak_force", "N"),
                ("peak_time", "s"),
                ("startup_peak_force", "N"),
                ("startup_peak_time", "s"),
                ("settled_force", "N"),
                ("settled_min", "N"),
                ("settled_max", "N"),
                ("ripple", "N"),
                ("settling_time", "s"),
            ];
            let mut rows: Vec<Vec<f64>> = vec![vec![f64::NAN; n]; kinds.len()];
            for (k, c) in self.data.iter().enumerate() {
                let Some(c) = c else { continue };
                let f = &c.forces[j];
                let s = settled_start(c);
                let (ip, peak) = argmax(f);
                let win = &f[s..];
                let mean = win.iter().sum::<f64>() / win.len() as f64;
                let (lo, hi) = range(win);
                let settle = settling(f, &c.time, s, mean, tol);
                let (t0, t1) = (c.time[0], c.time[c.time.len() - 1]);
                let su_end = t0 + 0.1 * c.period.unwrap_or(t1 - t0);
                let n_su = c.time.partition_point(|&t| t <= su_end).max(1);
                let (isu, su_peak) = argmax(&f[..n_su]);
                for (row, v) in rows.iter_mut().zip([
                    peak,
                    c.time[ip],
                    su_peak,
                    c.time[isu],
                    mean,
                    lo,
                    hi,
                    0.5 * (hi - lo),
                    settle,
                ]) {
                    row[k] = v;
                }
            }
            for ((kind, unit), values) in kinds.iter().zip(rows) {
                forces.push(Quantity {
                    name: format!("{j}.{kind}"),
                    unit,
                    values,
                });
            }
        }
        forces
    }
}

/// The motion quantity `kind` along axis `a` of case `c` whose body's position, velocity and
/// acceleration are `b`, against its reference's `rb` (sampled at the same times).
fn motion_value(
    kind: &str,
    a: usize,
    c: &CaseData,
    b: &[Vec<[f64; 3]>; 3],
    rb: &[Vec<[f64; 3]>; 3],
    tol: f64,
) -> f64 {
    let which = match kind {
        "offset_max" | "offset_settled" => 0,
        "velocity_fluctuation" => 1,
        _ => 2,
    };
    let d: Vec<f64> = b[which]
        .iter()
        .zip(&rb[which])
        .map(|(x, y)| x[a] - y[a])
        .collect();
    let s = settled_start(c);
    match kind {
        "offset_max" | "velocity_fluctuation" => d.iter().fold(0.0f64, |m, x| m.max(x.abs())),
        "offset_settled" => d[s..].iter().sum::<f64>() / (d.len() - s) as f64,
        "acceleration_jump" => d
            .iter()
            .copied()
            .fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m }),
        "acceleration_settling_time" => {
            let reference: Vec<f64> = rb[2][s..].iter().map(|x| x[a]).collect();
            let (rlo, rhi) = range(&reference);
            settling(&d, &c.time, s, 0.5 * (rhi - rlo), tol)
        }
        _ => {
            let (lo, hi) = range(&d[s..]);
            0.5 * (hi - lo)
        }
    }
}

/// A case's note: its edits of the base scene ("base scene" without any), and its reference case.
fn case_note(spec: &StudySpec, c: &CaseSpec) -> (String, Option<String>) {
    let reference = spec.reference_of(c);
    let mut edits: Vec<String> = Vec::new();
    if let Some(sc) = &c.scene {
        edits.push(format!("scene {}", sc.display()));
    }
    edits.extend(c.set.iter().map(|(k, v)| format!("{k} = {v}")));
    edits.extend(c.remove.iter().map(|k| format!("remove {k}")));
    (
        if edits.is_empty() {
            "base scene".to_string()
        } else {
            edits.join("; ")
        },
        reference,
    )
}

/// Four significant digits, plain or scientific as fits.
pub fn num(v: f64) -> String {
    if v.is_nan() {
        return "-".into();
    }
    let a = v.abs();
    if a != 0.0 && !(1e-2..1e5).contains(&a) {
        format!("{v:.3e}")
    } else {
        let digits = if a == 0.0 {
            3
        } else {
            (3 - a.log10().floor() as i32).clamp(0, 6) as usize
        };
        format!("{v:.digits$}")
    }
}

fn table(out: &mut String, cases: &[String], qs: &[Quantity]) {
    let _ = writeln!(out, "| quantity | unit | {} |", cases.join(" | "));
    let _ = writeln!(out, "|---|---|{}", "---|".repeat(cases.len()));
    for q in qs {
        let vals: Vec<String> = q.values.iter().map(|&v| num(v)).collect();
        let _ = writeln!(out, "| `{}` | {} | {} |", q.name, q.unit, vals.join(" | "));
    }
}

/// The report as markdown (headed by the study name; definitions in this module's docs and the
/// book, book/src/reference/study.md).
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "### Study `{}`", r.study_name);
    let _ = writeln!(s);
    if !r.description.is_empty() {
        let _ = writeln!(s, "{}", r.description);
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "Generated by `jointplay report {}`.", r.file.display());
    let _ = writeln!(s);
    let _ = writeln!(s, "Base scene: `{}`.", r.base_scene);
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| case | edits of the base scene | compared with | wall time (s) |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    for (k, c) in r.cases.iter().enumerate() {
        let (d, rf) = &r.case_notes[k];
        let _ = writeln!(
            s,
            "| {c} | {d} | {} | {} |",
            rf.as_deref().unwrap_or("-"),
            num(r.wall_times[k])
        );
    }
    let _ = writeln!(s);
    if !r.published.is_empty() {
        let _ = writeln!(s, "Published values beside ours:");
        let _ = writeln!(s);
        // A column of verdicts only when some published value carries its band of agreement.
        let banded = r.published.iter().any(|p| p.band.is_some());
        let _ = writeln!(
            s,
            "| case | quantity | published | jointplay | ratio | {}source |",
            if banded { "within the band | " } else { "" }
        );
        let _ = writeln!(
            s,
            "|---|---|---|---|---|{}---|",
            if banded { "---|" } else { "" }
        );
        for p in &r.published {
            let ours = r.value(&p.case, &p.quantity);
            let unit = r
                .motion
                .iter()
                .chain(&r.forces)
                .find(|q| q.name == p.quantity)
                .map(|q| q.unit)
                .unwrap_or("");
            let verdict = match (banded, p.band, ours) {
                (false, _, _) => String::new(),
                (true, None, _) => " |".into(),
                (true, Some(b), None) => format!(" - (±{} %) |", percent(b)),
                (true, Some(b), Some(o)) => format!(
                    " {} (±{} %) |",
                    if within(o, p.value, b) { "yes" } else { "no" },
                    percent(b)
                ),
            };
            let _ = writeln!(
                s,
                "| {} | `{}` ({unit}) | {} | {} | {} |{verdict} {} |",
                p.case,
                p.quantity,
                num(p.value),
                ours.map(num).unwrap_or_else(|| "not computed".into()),
                ours.map(|o| num(o / p.value)).unwrap_or_else(|| "-".into()),
                p.source
            );
        }
        let _ = writeln!(s);
    }
    if !r.motion.is_empty() {
        let _ = writeln!(
            s,
            "Motion of `{}` against each case's reference:",
            r.body.as_deref().unwrap_or("?")
        );
        let _ = writeln!(s);
        table(&mut s, &r.cases, &r.motion);
        let _ = writeln!(s);
    }
    if !r.forces.is_empty() {
        let _ = writeln!(
            s,
            "Joint forces (contact force with clearance, reaction force when ideal):"
        );
        let _ = writeln!(s);
        table(&mut s, &r.cases, &r.forces);
        let _ = writeln!(s);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::{num, settling, within};

    #[test]
    fn numbers_keep_four_significant_digits() {
        assert_eq!(num(230.456), "230.5");
        assert_eq!(num(0.5921), "0.5921");
        assert_eq!(num(3.4e-3), "3.400e-3");
        assert_eq!(num(12345.0), "12345");
        assert_eq!(num(f64::NAN), "-");
    }

    #[test]
    fn settling_is_the_first_time_after_the_last_excursion_from_the_widened_band() {
        let time: Vec<f64> = (0..8).map(|i| 0.5 * i as f64).collect();
        // Settled window from index 4: range 1.0-1.1, widened by 0.1 * scale = 0.1 on each side.
        let x = [10.0, 0.0, 10.0, 1.15, 1.1, 1.05, 1.0, 1.1];
        assert_eq!(settling(&x, &time, 4, 1.0, 0.1), time[3]);
        // Never outside the band: settled from the start.
        let calm = [1.0, 1.05, 0.95, 1.15, 1.1, 1.05, 1.0, 1.1];
        assert_eq!(settling(&calm, &time, 4, 1.0, 0.1), time[0]);
        // A settled range wider than twice the scale: nothing has settled.
        let shaking = [0.0, 0.0, 0.0, 0.0, -1.5, 1.5, -1.5, 1.5];
        assert!(settling(&shaking, &time, 4, 1.0, 0.1).is_nan());
    }

    #[test]
    fn a_value_is_within_its_band_about_the_published_magnitude() {
        assert!(within(0.62 * 1.039, 0.62, 0.04));
        assert!(!within(0.62 * 1.041, 0.62, 0.04));
        assert!(within(-120.0, -122.7, 0.04));
        assert!(!within(53.7, -122.7, 0.35));
        assert_eq!(super::percent(0.04), "4");
        assert_eq!(super::percent(0.025), "2.5");
    }
}
