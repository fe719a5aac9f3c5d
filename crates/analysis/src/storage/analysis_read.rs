//! An analysis file read back for what is drawn from it ([`open`], then [`Opened::read`]): the
//! study text, each done value's (or the single run's) strobe and section points and the tail of
//! its history, the chaos measures and the branches of periodic orbits, as plain data. The
//! figures layer parses the study text and passes the observables and sections it names back to
//! [`Opened::read`]; nothing here knows a study's spec.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::measures::indicator::Row;
use crate::measures::registry::INDICATORS;
use crate::storage::h5::{h5err, read_attr, read_rows, read_str, read_strings};
use crate::{Error, Result};

/// History samples read per run, at most: the last ones (what a figure draws).
pub const FIGURE_HISTORY: usize = 20_000;

/// The recorded data of one run (or one sweep value).
#[derive(Debug, Clone, Default)]
pub struct RecordedJob {
    /// The swept parameter's value (0 for a single run).
    pub parameter: f64,
    /// Swept upwards (or a single run); false on the way down.
    pub up: bool,
    /// The last [`FIGURE_HISTORY`] history times and, per observable, values.
    pub history_time: Vec<f64>,
    pub history: BTreeMap<String, Vec<f64>>,
    /// Section name ("strobe" or a hyperplane) to observable to points.
    pub sections: BTreeMap<String, BTreeMap<String, Vec<f64>>>,
    /// Hyperplane section name to its crossing times (s).
    pub crossing_times: BTreeMap<String, Vec<f64>>,
}

/// A sweep's parameter: its path, its unit and every value of the sweep (done or not).
#[derive(Debug, Clone)]
pub struct SweepAxis {
    pub path: String,
    pub unit: String,
    pub values: Vec<f64>,
}

/// A single run's Lyapunov estimates as they converged (`/chaos/lyapunov`).
#[derive(Debug, Clone, Default)]
pub struct Convergence {
    /// Times of the re-orthonormalisations (s).
    pub time: Vec<f64>,
    /// The running estimate of every exponent there, one row per time (1/s).
    pub history: Vec<Vec<f64>>,
    /// The running two-trajectory estimate of lambda_1 (1/s; empty when not computed).
    pub two: Vec<f64>,
    /// The final exponents and their batch-means standard errors (1/s).
    pub exponents: Vec<f64>,
    pub stderr: Vec<f64>,
    /// The time the estimates averaged over (s): the run began that long before the last time.
    pub averaging_time: f64,
}

/// One branch of periodic orbits as read back: its parameter, stability and, per observable, the
/// values at its strobe points (one row per point, one column per drive period).
#[derive(Debug, Clone)]
pub struct BranchData {
    pub parameter: Vec<f64>,
    pub stable: Vec<u8>,
    pub strobe: BTreeMap<String, Vec<Vec<f64>>>,
}

/// `/continuation`: the parameter's path and unit, the branches, and the special points (kind,
/// parameter, observables at the first strobe point).
#[derive(Debug, Clone)]
pub struct ContData {
    pub parameter: String,
    pub unit: String,
    pub branches: Vec<BranchData>,
    pub specials: Vec<(String, f64, BTreeMap<String, f64>)>,
}

/// What an analysis file recorded, as [`Opened::read`] reads it.
#[derive(Debug, Clone, Default)]
pub struct Recorded {
    /// Each observable's unit.
    pub units: BTreeMap<String, String>,
    /// The swept parameter; None for a single run.
    pub sweep: Option<SweepAxis>,
    /// A job per done sweep value, in the sweep's order, or the single run.
    pub jobs: Vec<RecordedJob>,
    /// Per done sweep value: parameter, lambda_1, its standard error and the two-trajectory
    /// estimate (NaN where not computed).
    pub chaos: Vec<[f64; 4]>,
    /// Each chaos indicator the sweep computed (crate::measures::registry), with its parameter
    /// and number per done value.
    pub numbers: Vec<(Row, Vec<[f64; 2]>)>,
    /// A single run's running Lyapunov estimates.
    pub convergence: Option<Convergence>,
    /// The branches of periodic orbits, when the study followed them.
    pub continuation: Option<ContData>,
    /// The integrator's relative and absolute tolerances (root attribute `integrator`); `None`
    /// for a fixed-step method.
    pub tolerances: Option<(f64, f64)>,
}

/// An analysis file, its kind checked: the study text it was written from and the study's name.
#[derive(Debug, Clone)]
pub struct Opened {
    pub path: PathBuf,
    pub study: String,
    pub name: String,
}

/// Opens the analysis file `path` (one whose root attribute `kind` is "analysis"), reading the
/// study text and name.
pub fn open(path: &Path) -> Result<Opened> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let kind = read_str(&file, "kind").unwrap_or_default();
    if kind != "analysis" {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: "not a nonlinear-analysis file (no kind = \"analysis\" attribute): `jointplay plot` redraws the figures of analysis studies; `jointplay run` draws those of scenes and comparison studies".into(),
        });
    }
    Ok(Opened {
        path: path.to_path_buf(),
        study: read_str(&file, "study").map_err(&e)?,
        name: read_str(&file, "study_name").map_err(&e)?,
    })
}

impl Opened {
    /// Reads the `observables` and `sections` (by name, as the study names them): a sweep's
    /// values or a single run, then the continuation when the study followed one.
    pub fn read(&self, observables: &[&str], sections: &[&str]) -> Result<Recorded> {
        let path = &self.path;
        let e = h5err(path);
        let file = hdf5::File::open(path).map_err(&e)?;
        let names = Names {
            observables,
            sections,
        };
        let mut d = Recorded::default();
        if let Ok(g) = file.group("sweep") {
            d.read_sweep(&g, path, &names)?;
        } else {
            d.read_single(&file, path, &names)?;
        }
        d.tolerances = read_str(&file, "integrator")
            .ok()
            .and_then(|s| jointplay_solver::ode::Method::tolerances_in(&s));
        d.continuation = match file.group("continuation") {
            Ok(g) => Some(read_continuation(&g, observables).map_err(&e)?),
            Err(_) => None,
        };
        Ok(d)
    }
}

/// The observables and sections read.
struct Names<'a> {
    observables: &'a [&'a str],
    sections: &'a [&'a str],
}

fn read_continuation(g: &hdf5::Group, observables: &[&str]) -> hdf5::Result<ContData> {
    let n: u64 = read_attr(g, "branches").unwrap_or(0);
    let mut branches = Vec::new();
    for i in 0..n {
        let b = g.group(&format!("branch_{i}"))?;
        let sg = b.group("strobe")?;
        let mut strobe = BTreeMap::new();
        for o in observables {
            strobe.insert(o.to_string(), read_rows(&sg, o)?);
        }
        branches.push(BranchData {
            parameter: b.dataset("parameter")?.read_raw()?,
            stable: b.dataset("stable")?.read_raw()?,
            strobe,
        });
    }
    let mut specials = Vec::new();
    if let Ok(sp) = g.group("special") {
        let kinds = read_strings(&sp, "kind")?;
        let params: Vec<f64> = sp.dataset("parameter")?.read_raw()?;
        let sg = sp.group("strobe")?;
        let mut vals = BTreeMap::new();
        for o in observables {
            vals.insert(o.to_string(), sg.dataset(o)?.read_raw::<f64>()?);
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

/// A hyperplane section group's crossing times (s).
fn read_times(g: &hdf5::Group) -> hdf5::Result<Vec<f64>> {
    g.dataset("time")?.read_raw::<f64>()
}

fn read_group(g: &hdf5::Group, observables: &[&str]) -> hdf5::Result<BTreeMap<String, Vec<f64>>> {
    let mut m = BTreeMap::new();
    for o in observables {
        m.insert(o.to_string(), g.dataset(o)?.read_raw::<f64>()?);
    }
    Ok(m)
}

impl Recorded {
    /// Reads the sweep group `g` of `path`: the observables' units, a job per done value (its
    /// strobe and section points and the tail of its history), the chaos measures, and the swept
    /// parameter's path, unit and values.
    fn read_sweep(&mut self, g: &hdf5::Group, path: &Path, names: &Names) -> Result<()> {
        let e = h5err(path);
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
        for o in names.observables {
            let ds = g.dataset(o).map_err(&e)?;
            self.units
                .insert(o.to_string(), read_str(&ds, "unit").unwrap_or_default());
            let r = read_rows(g, o).map_err(&e)?;
            rows(o, r.len())?;
            strobe.insert(o.to_string(), r);
        }
        let hg = g.group("history").ok();
        let htime = match &hg {
            Some(h) => {
                for o in names.observables {
                    let r = read_tail_rows(h, o, &done).map_err(&e)?;
                    rows(&format!("history/{o}"), r.len())?;
                    hist.insert(o.to_string(), r);
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
            let mut crossing_times = BTreeMap::new();
            if let Ok(sj) = g.group(&format!("sections/{j}")) {
                for s in names.sections {
                    let gs = sj.group(s).map_err(&e)?;
                    sections.insert(
                        s.to_string(),
                        read_group(&gs, names.observables).map_err(&e)?,
                    );
                    crossing_times.insert(s.to_string(), read_times(&gs).map_err(&e)?);
                }
            }
            self.jobs.push(RecordedJob {
                parameter: *p,
                up: dirs[j] >= 0,
                history_time: htime.get(j).cloned().unwrap_or_default(),
                history: hist
                    .iter()
                    .map(|(k, v)| (k.clone(), v[j].clone()))
                    .collect(),
                sections,
                crossing_times,
            });
        }
        if let Ok(c) = g.group("chaos") {
            self.read_chaos(&c, &params, &done);
        }
        self.sweep = Some(SweepAxis {
            path: pname,
            unit: punit,
            values: params,
        });
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
    fn read_single(&mut self, file: &hdf5::File, path: &Path, names: &Names) -> Result<()> {
        let e = h5err(path);
        if let Ok(l) = file.group("chaos/lyapunov") {
            let t = l.dataset("history_time").and_then(|d| d.read_raw::<f64>());
            let h = read_rows(&l, "history");
            if let (Ok(time), Ok(history)) = (t, h) {
                let raw = |name: &str| {
                    l.dataset(name)
                        .and_then(|d| d.read_raw::<f64>())
                        .unwrap_or_default()
                };
                self.convergence = Some(Convergence {
                    time,
                    history,
                    two: raw("two_trajectory_history"),
                    exponents: raw("exponents"),
                    stderr: raw("stderr"),
                    averaging_time: read_attr(&l, "averaging_time").unwrap_or(f64::NAN),
                });
            }
        }
        let mut job = RecordedJob {
            up: true,
            ..Default::default()
        };
        if let Ok(h) = file.group("history") {
            job.history_time = read_tail(&h, "time").map_err(&e)?;
            job.history = names
                .observables
                .iter()
                .map(|o| Ok((o.to_string(), read_tail(&h, o)?)))
                .collect::<hdf5::Result<_>>()
                .map_err(&e)?;
        }
        let sg = file.group("sections").map_err(&e)?;
        let strobe = sg.group("strobe").map_err(&e)?;
        for o in names.observables {
            let ds = strobe.dataset(o).map_err(&e)?;
            self.units
                .insert(o.to_string(), read_str(&ds, "unit").unwrap_or_default());
        }
        job.sections.insert(
            "strobe".into(),
            read_group(&strobe, names.observables).map_err(&e)?,
        );
        for s in names.sections {
            let g = sg.group(s).map_err(&e)?;
            job.sections.insert(
                s.to_string(),
                read_group(&g, names.observables).map_err(&e)?,
            );
            job.crossing_times
                .insert(s.to_string(), read_times(&g).map_err(&e)?);
        }
        self.jobs.push(job);
        Ok(())
    }
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
