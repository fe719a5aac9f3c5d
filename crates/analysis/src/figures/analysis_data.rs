//! An analysis file read back for its figures ([`read`]): the study, each done value's (or the
//! single run's) strobe and section points and the tail of its history, the chaos measures and
//! the branches of periodic orbits.

use std::collections::BTreeMap;
use std::path::Path;

use crate::measures::indicator::Row;
use crate::measures::registry::INDICATORS;
use crate::storage::h5::{h5err, read_rows, read_str};
use crate::study::analysis::spec::AnalysisStudy;
use crate::{Error, Result};

/// The recorded data of one run (or one sweep job).
#[derive(Debug, Clone, Default)]
pub(super) struct Job {
    /// Panel title suffix, e.g. "gamma = 0.28".
    pub(super) label: String,
    pub(super) parameter: f64,
    pub(super) up: bool,
    pub(super) history_time: Vec<f64>,
    pub(super) history: BTreeMap<String, Vec<f64>>,
    /// Section name ("strobe" or a hyperplane) to observable to points.
    pub(super) sections: BTreeMap<String, BTreeMap<String, Vec<f64>>>,
}

pub(super) struct Data {
    pub(super) spec: AnalysisStudy,
    pub(super) name: String,
    pub(super) units: BTreeMap<String, String>,
    pub(super) sweep: Option<(String, String)>,
    pub(super) jobs: Vec<Job>,
    /// Per done sweep value: parameter, lambda_1, its standard error and the two-trajectory
    /// estimate (NaN where not computed).
    pub(super) chaos: Vec<[f64; 4]>,
    /// Each chaos indicator the sweep computed (crate::measures::registry), with its parameter
    /// and number per done value.
    pub(super) numbers: Vec<(Row, Vec<[f64; 2]>)>,
    /// A single run's running Lyapunov estimates: times, one row per time, and the
    /// two-trajectory estimate.
    pub(super) convergence: Option<Convergence>,
    /// The branches of periodic orbits, when the study followed them.
    pub(super) continuation: Option<ContData>,
}

/// One branch of periodic orbits as read back: its parameter, stability and, per observable, the
/// values at its strobe points (one row per point, one column per drive period).
pub(super) struct BranchData {
    pub(super) parameter: Vec<f64>,
    pub(super) stable: Vec<u8>,
    pub(super) strobe: BTreeMap<String, Vec<Vec<f64>>>,
}

/// `/continuation`: the parameter's path and unit, the branches, and the special points (kind,
/// parameter, observables at the first strobe point).
pub(super) struct ContData {
    pub(super) parameter: String,
    pub(super) unit: String,
    pub(super) branches: Vec<BranchData>,
    pub(super) specials: Vec<(String, f64, BTreeMap<String, f64>)>,
}

fn read_continuation(g: &hdf5::Group, spec: &AnalysisStudy) -> hdf5::Result<ContData> {
    let n: u64 = crate::storage::h5::read_attr(g, "branches").unwrap_or(0);
    let mut branches = Vec::new();
    for i in 0..n {
        let b = g.group(&format!("branch_{i}"))?;
        let sg = b.group("strobe")?;
        let mut strobe = BTreeMap::new();
        for o in &spec.observables {
            strobe.insert(o.name.clone(), read_rows(&sg, &o.name)?);
        }
        branches.push(BranchData {
            parameter: b.dataset("parameter")?.read_raw()?,
            stable: b.dataset("stable")?.read_raw()?,
            strobe,
        });
    }
    let mut specials = Vec::new();
    if let Ok(sp) = g.group("special") {
        let kinds = crate::storage::h5::read_strings(&sp, "kind")?;
        let params: Vec<f64> = sp.dataset("parameter")?.read_raw()?;
        let sg = sp.group("strobe")?;
        let mut vals = BTreeMap::new();
        for o in &spec.observables {
            vals.insert(o.name.clone(), sg.dataset(&o.name)?.read_raw::<f64>()?);
        }
        for (i, (k, p)) in kinds.into_iter().zip(params).enumerate() {
            let at = vals.iter().map(|(n, v)| (n.clone(), v[i])).collect();
            specials.push((k, p, at));
        }
    }
    Ok(ContData {
        parameter: read_str(g, "parameter")?,
        unit: read_str(g, "parameter_unit").unwrap_or_default(),
        branches,
        specials,
    })
}

/// Times of the re-orthonormalisations, the running estimates there (one row per time) and the
/// two-trajectory estimate.
pub(super) type Convergence = (Vec<f64>, Vec<Vec<f64>>, Vec<f64>);

/// History samples a figure draws per run, at most: the last ones.
pub const FIGURE_HISTORY: usize = 20_000;

/// The last [`FIGURE_HISTORY`] values of the one-dimensional dataset `name`.
fn read_tail(g: &hdf5::Group, name: &str) -> hdf5::Result<Vec<f64>> {
    let ds = g.dataset(name)?;
    let n = ds.shape().first().copied().unwrap_or(0);
    let v = ds.read_slice_1d::<f64, _>(ndarray::s![n.saturating_sub(FIGURE_HISTORY)..n])?;
    Ok(v.to_vec())
}

/// The last [`FIGURE_HISTORY`] values of each row of the two-dimensional dataset `name` whose
/// job is done (`done` 1); an empty row for the others.
fn read_tail_rows(g: &hdf5::Group, name: &str, done: &[u8]) -> hdf5::Result<Vec<Vec<f64>>> {
    let ds = g.dataset(name)?;
    let shape = ds.shape();
    let cols = shape.get(1).copied().unwrap_or(0);
    (0..shape.first().copied().unwrap_or(0))
        .map(|r| {
            if done.get(r) != Some(&1) {
                return Ok(Vec::new());
            }
            let range = cols.saturating_sub(FIGURE_HISTORY)..cols;
            Ok(ds.read_slice_1d::<f64, _>(ndarray::s![r, range])?.to_vec())
        })
        .collect()
}

fn read_group(g: &hdf5::Group, spec: &AnalysisStudy) -> hdf5::Result<BTreeMap<String, Vec<f64>>> {
    let mut m = BTreeMap::new();
    for o in &spec.observables {
        m.insert(o.name.clone(), g.dataset(&o.name)?.read_raw::<f64>()?);
    }
    Ok(m)
}

/// Reads the analysis file `path` for its figures: the study, then a sweep's values or a single
/// run, then the continuation when the study followed one.
pub(super) fn read(path: &Path) -> Result<Data> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let kind = read_str(&file, "kind").unwrap_or_default();
    if kind != "analysis" {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: "not a nonlinear-analysis file (no kind = \"analysis\" attribute): `jointplay plot` redraws the figures of analysis studies; `jointplay run` draws those of scenes and comparison studies".into(),
        });
    }
    let text = read_str(&file, "study").map_err(&e)?;
    let spec = AnalysisStudy::parse_spec(&text, path)?;
    let name = read_str(&file, "study_name").map_err(&e)?;
    let mut d = Data {
        spec,
        name,
        units: BTreeMap::new(),
        sweep: None,
        jobs: Vec::new(),
        chaos: Vec::new(),
        numbers: Vec::new(),
        convergence: None,
        continuation: None,
    };
    if let Ok(g) = file.group("sweep") {
        d.read_sweep(&g, path)?;
    } else {
        d.read_single(&file, path)?;
    }
    d.continuation = match file.group("continuation") {
        Ok(g) => Some(read_continuation(&g, &d.spec).map_err(&e)?),
        Err(_) => None,
    };
    Ok(d)
}

impl Data {
    /// Reads the sweep group `g` of `path`: the observables' units, a job per done value (its
    /// strobe and section points and the tail of its history), the chaos measures, and the swept
    /// parameter's path and unit.
    fn read_sweep(&mut self, g: &hdf5::Group, path: &Path) -> Result<()> {
        let e = h5err(path);
        let spec = &self.spec;
        let pds = g.dataset("parameter").map_err(&e)?;
        let params = pds.read_raw::<f64>().map_err(&e)?;
        let pname = read_str(&pds, "path").map_err(&e)?;
        let punit = read_str(&pds, "unit").unwrap_or_default();
        let dirs = g
            .dataset("direction")
            .and_then(|d| d.read_raw::<i8>())
            .map_err(&e)?;
        let done = g
            .dataset("done")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(&e)?;
        // Every per-value dataset has a row per value of /sweep/parameter: a damaged or edited
        // file is refused, naming the dataset, rather than indexed out of its bounds.
        let rows = |name: &str, n: usize| {
            if n == params.len() {
                Ok(())
            } else {
                Err(Error::Io {
                    file: path.to_path_buf(),
                    message: format!(
                        "/sweep/{name} has {n} rows but /sweep/parameter has {}: not a sweep file \
                         jointplay wrote (damaged or edited)",
                        params.len()
                    ),
                })
            }
        };
        rows("direction", dirs.len())?;
        rows("done", done.len())?;
        let mut strobe = BTreeMap::new();
        let mut hist = BTreeMap::new();
        for o in &spec.observables {
            let ds = g.dataset(&o.name).map_err(&e)?;
            self.units
                .insert(o.name.clone(), read_str(&ds, "unit").unwrap_or_default());
            let r = read_rows(g, &o.name).map_err(&e)?;
            rows(&o.name, r.len())?;
            strobe.insert(o.name.clone(), r);
        }
        let hg = g.group("history").ok();
        let htime = match &hg {
            Some(h) => {
                for o in &spec.observables {
                    let r = read_tail_rows(h, &o.name, &done).map_err(&e)?;
                    rows(&format!("history/{}", o.name), r.len())?;
                    hist.insert(o.name.clone(), r);
                }
                let t = read_tail_rows(h, "time", &done).map_err(&e)?;
                rows("history/time", t.len())?;
                t
            }
            None => Vec::new(),
        };
        for (j, p) in params.iter().enumerate() {
            if done[j] != 1 {
                continue;
            }
            let mut sections = BTreeMap::new();
            sections.insert(
                "strobe".to_string(),
                strobe
                    .iter()
                    .map(|(k, v)| (k.clone(), v[j].clone()))
                    .collect(),
            );
            if let Ok(sj) = g.group(&format!("sections/{j}")) {
                for s in &spec.sections {
                    let gs = sj.group(&s.name).map_err(&e)?;
                    sections.insert(s.name.clone(), read_group(&gs, spec).map_err(&e)?);
                }
            }
            self.jobs.push(Job {
                label: value_label(&pname, &punit, &params, *p, dirs[j]),
                parameter: *p,
                up: dirs[j] >= 0,
                history_time: htime.get(j).cloned().unwrap_or_default(),
                history: hist
                    .iter()
                    .map(|(k, v)| (k.clone(), v[j].clone()))
                    .collect(),
                sections,
            });
        }
        if let Ok(c) = g.group("chaos") {
            self.read_chaos(&c, &params, &done);
        }
        self.sweep = Some((pname, punit));
        Ok(())
    }

    /// Reads the sweep's chaos group `c`: lambda_1, its standard error and the two-trajectory
    /// estimate, and each chaos indicator computed, per done value (NaN where not computed).
    fn read_chaos(&mut self, c: &hdf5::Group, params: &[f64], done: &[u8]) {
        let col = |name: &str, k: usize| -> Vec<f64> {
            c.dataset(name)
                .and_then(|d| {
                    let cols = d.shape().get(1).copied().unwrap_or(1);
                    d.read_raw::<f64>()
                        .map(|v| v.iter().skip(k).step_by(cols).copied().collect())
                })
                .unwrap_or_else(|_| vec![f64::NAN; params.len()])
        };
        let (l1, e1, two) = (
            col("exponents", 0),
            col("stderr", 0),
            col("two_trajectory", 0),
        );
        let at = |v: &[f64], j: usize| v.get(j).copied().unwrap_or(f64::NAN);
        let done_values = || params.iter().enumerate().filter(|(j, _)| done[*j] == 1);
        for (j, p) in done_values() {
            self.chaos.push([*p, at(&l1, j), at(&e1, j), at(&two, j)]);
        }
        for i in INDICATORS {
            let row = i.row();
            if c.dataset(row.name).is_ok() {
                let v = col(row.name, 0);
                self.numbers
                    .push((row, done_values().map(|(j, p)| [*p, at(&v, j)]).collect()));
            }
        }
    }

    /// Reads a single run's `file`: the running Lyapunov estimates, the tail of its history, the
    /// observables' units and its strobe and section points.
    fn read_single(&mut self, file: &hdf5::File, path: &Path) -> Result<()> {
        let e = h5err(path);
        let spec = &self.spec;
        if let Ok(l) = file.group("chaos/lyapunov") {
            let t = l.dataset("history_time").and_then(|d| d.read_raw::<f64>());
            let h = read_rows(&l, "history");
            if let (Ok(t), Ok(h)) = (t, h) {
                let two = l
                    .dataset("two_trajectory_history")
                    .and_then(|d| d.read_raw::<f64>())
                    .unwrap_or_default();
                self.convergence = Some((t, h, two));
            }
        }
        let mut job = Job {
            up: true,
            ..Default::default()
        };
        if let Ok(h) = file.group("history") {
            job.history_time = read_tail(&h, "time").map_err(&e)?;
            job.history = spec
                .observables
                .iter()
                .map(|o| Ok((o.name.clone(), read_tail(&h, &o.name)?)))
                .collect::<hdf5::Result<_>>()
                .map_err(&e)?;
        }
        let sg = file.group("sections").map_err(&e)?;
        let strobe = sg.group("strobe").map_err(&e)?;
        for o in &spec.observables {
            let ds = strobe.dataset(&o.name).map_err(&e)?;
            self.units
                .insert(o.name.clone(), read_str(&ds, "unit").unwrap_or_default());
        }
        job.sections
            .insert("strobe".into(), read_group(&strobe, spec).map_err(&e)?);
        for s in &spec.sections {
            let g = sg.group(&s.name).map_err(&e)?;
            job.sections
                .insert(s.name.clone(), read_group(&g, spec).map_err(&e)?);
        }
        self.jobs.push(job);
        Ok(())
    }
}

/// A sweep value's panel title suffix, e.g. "gamma = 0.28": the parameter `p` of the sweep
/// `params` in the unit its axis is drawn in, marked on the way down (`dir` < 0).
fn value_label(pname: &str, punit: &str, params: &[f64], p: f64, dir: i8) -> String {
    format!(
        "{} = {}{}",
        short(pname),
        // In the unit the parameter axis is drawn in (mm for a clearance).
        match display_scale(punit, params.iter().copied()) {
            Some((k, u)) => format!("{} {u}", crate::study::report::num(p * k)),
            None if punit.is_empty() => crate::study::report::num(p),
            None => format!("{} {punit}", crate::study::report::num(p)),
        },
        if dir < 0 { " (down)" } else { "" }
    )
}

/// Last segment of a parameter path that is not a wildcard or a number.
pub(super) fn short(path: &str) -> &str {
    path.rsplit('.').next().unwrap_or(path)
}

/// Lengths recorded in metres that all stay below 0.1 m (clearances, eccentricities, offsets)
/// are drawn in millimetres, as the literature's figures draw them: the factor and the unit, or
/// None to draw the values as recorded.
pub fn display_scale(
    unit: &str,
    vals: impl IntoIterator<Item = f64>,
) -> Option<(f64, &'static str)> {
    if unit != "m" {
        return None;
    }
    let mut any = false;
    for v in vals.into_iter().filter(|v| v.is_finite()) {
        if v.abs() >= 0.1 {
            return None;
        }
        any = true;
    }
    any.then_some((1e3, "mm"))
}

#[cfg(test)]
mod tests {
    use super::{FIGURE_HISTORY, read_tail, read_tail_rows};

    #[test]
    fn figures_read_the_last_history_samples_of_the_runs_that_are_done() {
        let dir = tempfile::tempdir().unwrap();
        let file = hdf5::File::create(dir.path().join("h.h5")).unwrap();
        let n = FIGURE_HISTORY + 5_000;
        let rows: Vec<f64> = (0..2 * n).map(|i| i as f64).collect();
        let arr = ndarray::Array2::from_shape_vec((2, n), rows).unwrap();
        file.new_dataset_builder()
            .with_data(&arr)
            .create("x")
            .unwrap();
        let got = read_tail_rows(&file, "x", &[1, 0]).unwrap();
        let want: Vec<f64> = (5_000..n).map(|i| i as f64).collect();
        assert_eq!(got, vec![want, Vec::new()]);
        // A short run: every sample.
        let short = ndarray::Array1::from(vec![1.0, 2.0, 3.0]);
        file.new_dataset_builder()
            .with_data(&short)
            .create("t")
            .unwrap();
        assert_eq!(read_tail(&file, "t").unwrap(), vec![1.0, 2.0, 3.0]);
    }
}
