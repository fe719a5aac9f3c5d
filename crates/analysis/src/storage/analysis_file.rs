//! The analysis file (layout in book/src/reference/hdf5.md): its root attributes (`Root`),
//! the layout of a sweep file and its creation with every row not done (`SweepLayout`,
//! `create_sweep_file`), the histories of a single run written while it goes
//! (`SingleHistory`), the section crossings, and what one job stores ([`JobResult`]). A
//! sweep's values reach the file through its journal ([`crate::storage::sweep`]); a shard file
//! records its [`Shard`]. The studies that make these files are [`crate::study::analysis`].

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use crate::Result;
use crate::flow::observe::ObservableSpec;
use crate::measures::sections::{HISTORY_BLOCK, Trace};
use crate::storage::h5::*;
use crate::storage::hybrid;

/// What one job produced, with the units of the observables.
#[derive(Debug, Clone)]
pub struct JobResult {
    pub trace: Trace,
    /// The scene's warnings and the step-size guard's.
    pub warnings: Vec<String>,
    pub units: Vec<String>,
    pub integrator: String,
    pub period: f64,
    pub start: f64,
    pub wall: f64,
    /// The chaos measures, when the study asks for them.
    pub chaos: Option<crate::measures::chaos::Chaos>,
}

/// The root attributes of an analysis file besides `program`, `program_version`, `units` and
/// `complete`: what a merge checks to be the same in every shard and writes once.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Root {
    pub study_name: String,
    pub study_file: String,
    pub study: String,
    pub description: String,
    pub flow: String,
    pub flow_text: String,
    pub integrator: String,
    pub start_time: f64,
    pub period: f64,
    pub phase: f64,
    pub periods: u64,
    pub transient: u64,
    pub samples_per_period: u64,
    pub history_periods: u64,
}

impl Root {
    /// Writes the attributes, with `kind` and `complete`.
    pub(crate) fn write(&self, file: &hdf5::File, complete: u8) -> hdf5::Result<()> {
        str_attr(file, "kind", "analysis")?;
        str_attr(file, "study_name", &self.study_name)?;
        str_attr(file, "study_file", &self.study_file)?;
        str_attr(file, "study", &self.study)?;
        str_attr(file, "description", &self.description)?;
        str_attr(file, "flow", &self.flow)?;
        str_attr(file, "flow_text", &self.flow_text)?;
        str_attr(file, "integrator", &self.integrator)?;
        f64_attr(file, "start_time", self.start_time)?;
        f64_attr(file, "period", self.period)?;
        f64_attr(file, "phase", self.phase)?;
        u64_attr(file, "periods", self.periods)?;
        u64_attr(file, "transient", self.transient)?;
        u64_attr(file, "samples_per_period", self.samples_per_period)?;
        u64_attr(file, "history_periods", self.history_periods)?;
        u8_attr_set(file, "complete", complete)
    }

    /// Reads what [`Root::write`] wrote.
    pub(crate) fn read(file: &hdf5::File) -> hdf5::Result<Root> {
        let s = |n: &str| read_str(file, n);
        let f = |n: &str| read_attr::<f64>(file, n);
        let u = |n: &str| read_attr::<u64>(file, n);
        Ok(Root {
            study_name: s("study_name")?,
            study_file: s("study_file")?,
            study: s("study")?,
            description: s("description")?,
            flow: s("flow")?,
            flow_text: s("flow_text")?,
            integrator: s("integrator")?,
            start_time: f("start_time")?,
            period: f("period")?,
            phase: f("phase")?,
            periods: u("periods")?,
            transient: u("transient")?,
            samples_per_period: u("samples_per_period")?,
            history_periods: u("history_periods")?,
        })
    }

    /// The names of the attributes whose values differ between `self` and `other`.
    pub(crate) fn differences(&self, other: &Root) -> Vec<&'static str> {
        let strings = [
            ("study_name", &self.study_name, &other.study_name),
            ("study_file", &self.study_file, &other.study_file),
            ("study", &self.study, &other.study),
            ("description", &self.description, &other.description),
            ("flow", &self.flow, &other.flow),
            ("flow_text", &self.flow_text, &other.flow_text),
            ("integrator", &self.integrator, &other.integrator),
        ];
        let floats = [
            ("start_time", self.start_time, other.start_time),
            ("period", self.period, other.period),
            ("phase", self.phase, other.phase),
        ];
        let counts = [
            ("periods", self.periods, other.periods),
            ("transient", self.transient, other.transient),
            (
                "samples_per_period",
                self.samples_per_period,
                other.samples_per_period,
            ),
            (
                "history_periods",
                self.history_periods,
                other.history_periods,
            ),
        ];
        strings
            .iter()
            .filter(|(_, a, b)| a != b)
            .map(|(n, ..)| *n)
            .chain(
                floats
                    .iter()
                    .filter(|(_, a, b)| a.to_bits() != b.to_bits())
                    .map(|(n, ..)| *n),
            )
            .chain(counts.iter().filter(|(_, a, b)| a != b).map(|(n, ..)| *n))
            .collect()
    }
}

/// Everything that fixes the datasets of a sweep file apart from its jobs: its root attributes,
/// the observables with their units, the sections and the sizes of the rows. Taken from the
/// study for a run, read back from a shard for a merge, so both write the same file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SweepLayout {
    pub root: Root,
    /// Observable names and paths, and their units.
    pub observables: Vec<ObservableSpec>,
    pub units: Vec<String>,
    /// Names of the hyperplane sections.
    pub sections: Vec<String>,
    /// The swept parameter's path and unit, and whether the sweep is a continuation.
    pub parameter: String,
    pub unit: String,
    pub continuation: bool,
    /// Strobe points and history samples per job.
    pub kept: usize,
    pub history: usize,
    pub shape: hybrid::StateShape,
    /// The chaos measures each value stores.
    pub chaos: crate::measures::chaos::ChaosSpec,
    /// [`AnalysisSpec::history_bits`].
    pub bits: Option<u32>,
}

/// What a study declares of its sweep file's layout (the rest, [`SweepLayout`]'s sizes and
/// units, comes from the flow or from a file written before).
#[derive(Debug, Clone)]
pub(crate) struct Declared {
    pub observables: Vec<ObservableSpec>,
    pub sections: Vec<String>,
    pub parameter: String,
    pub unit: String,
    pub continuation: bool,
    pub chaos: crate::measures::chaos::ChaosSpec,
    pub bits: Option<u32>,
}

impl SweepLayout {
    /// The layout of the sweep file `file` whose study declares `d`: its root attributes, and
    /// the observables' units and the rows' sizes as written.
    pub(crate) fn read(file: &hdf5::File, d: Declared) -> hdf5::Result<SweepLayout> {
        let root = Root::read(file)?;
        let g = file.group("sweep")?;
        let cols = |g: &hdf5::Group, name: &str| -> hdf5::Result<usize> {
            Ok(g.dataset(name)?.shape().get(1).copied().unwrap_or(0))
        };
        let units = d
            .observables
            .iter()
            .map(|o| {
                let ds = g.dataset(&o.name)?;
                read_str(&ds, "unit")
            })
            .collect::<hdf5::Result<Vec<_>>>()?;
        let history = match g.group("history") {
            Ok(h) => cols(&h, "time")?,
            Err(_) => 0,
        };
        Ok(SweepLayout {
            root,
            observables: d.observables,
            units,
            sections: d.sections,
            parameter: d.parameter,
            unit: d.unit,
            continuation: d.continuation,
            kept: cols(&g, "strobe_time")?,
            history,
            shape: hybrid::StateShape {
                dim: cols(&g, "final_state")?,
                contacts: cols(&g, "final_onset")?,
                clearances: cols(&g, "final_warned")?,
            },
            chaos: d.chaos,
            bits: d.bits,
        })
    }
}

pub(crate) fn obs_datasets(
    g: &hdf5::Group,
    observables: &[ObservableSpec],
    units: &[String],
    values: &[Vec<f64>],
    what: &str,
) -> hdf5::Result<()> {
    for ((o, u), v) in observables.iter().zip(units).zip(values) {
        write1(g, &o.name, v, u, &format!("{} {what}", o.path))?;
        {
            let ds = g.dataset(&o.name)?;
            str_attr(&ds, "path", &o.path)?;
        }
    }
    Ok(())
}

/// Writes one hyperplane section's crossings (times and observables) into a new group `name`.
pub(crate) fn write_crossings(
    g: &hdf5::Group,
    name: &str,
    observables: &[ObservableSpec],
    units: &[String],
    time: &[f64],
    values: &[Vec<f64>],
) -> hdf5::Result<()> {
    let gp = g.create_group(name)?;
    write1(&gp, "time", time, "s", "crossing times")?;
    obs_datasets(&gp, observables, units, values, "at the crossings")
}

/// The time histories of a single run's file, `/history/time` and `/history/<observable>`:
/// extendable, appended block by block while the run goes, described by [`write_single`] once it
/// is over (the units are the flow's).
pub(crate) struct SingleHistory {
    time: hdf5::Dataset,
    values: Vec<hdf5::Dataset>,
    /// [`AnalysisSpec::history_bits`].
    bits: Option<u32>,
}

impl SingleHistory {
    /// Creates the empty histories in `file` (in memory: see h5::create_streamed); they are
    /// written through [`SingleHistory::open`] once the file is on disk.
    pub(crate) fn create(file: &hdf5::File, observables: &[ObservableSpec]) -> hdf5::Result<()> {
        let g = file.create_group("history")?;
        // One chunk per block, written whole.
        let create = |name: &str| create_extendable::<f64>(&g, name, 1, true, HISTORY_BLOCK);
        create("time")?;
        for o in observables {
            create(&o.name)?;
        }
        Ok(())
    }

    /// The histories [`SingleHistory::create`] made in `file`, opened again (after the file was
    /// moved from memory to disk).
    pub(crate) fn open(
        file: &hdf5::File,
        observables: &[ObservableSpec],
        bits: Option<u32>,
    ) -> hdf5::Result<SingleHistory> {
        let g = file.group("history")?;
        Ok(SingleHistory {
            time: g.dataset("time")?,
            values: observables
                .iter()
                .map(|o| g.dataset(&o.name))
                .collect::<hdf5::Result<_>>()?,
            bits,
        })
    }

    /// Appends the samples `from..` of a block. A block that starts a chunk (every block but
    /// after a short one) has its chunks compressed by [`crate::storage::chunk`], by the threads of
    /// rayon's pool: the run waits for its block to be written, so the other core is free.
    pub(crate) fn append(
        &self,
        from: usize,
        time: &[f64],
        values: &[Vec<f64>],
    ) -> hdf5::Result<()> {
        let n = time.len();
        if from.is_multiple_of(HISTORY_BLOCK) {
            use crate::storage::chunk::{Rows, Store};
            let row = |ds, values, store| Rows {
                ds,
                values,
                width: 1,
                chunk_rows: HISTORY_BLOCK,
                store,
            };
            let rows: Vec<_> = std::iter::once(row(&self.time, time, Store::F64(None)))
                .chain(
                    self.values
                        .iter()
                        .zip(values)
                        .map(|(ds, v)| row(ds, &v[..], Store::F64(self.bits))),
                )
                .collect();
            crate::storage::chunk::append_all(&rows, from, true)?;
        } else {
            append(&self.time, from, n, 1, true, time.to_vec())?;
            for (ds, v) in self.values.iter().zip(values) {
                let v = crate::storage::bitround::rounded(v, self.bits).into_owned();
                append(ds, from, n, 1, true, v)?;
            }
        }
        // Not flushed: see h5::create_streamed.
        Ok(())
    }
}

/// Creates the sweep file `path` of `layout`, in memory ([`crate::storage::h5::create_in_memory`]), with one row per job of `jobs` (parameter value
/// and direction), every row not done. A shard file also records its shard (root attributes
/// `shard` and `shards`) and the index of each row's job in the whole sweep (`/sweep/job`).
pub(crate) fn create_sweep_file(
    path: &Path,
    layout: &SweepLayout,
    version: &str,
    jobs: &[(f64, i8)],
    shard: Option<(Shard, &[usize])>,
) -> Result<hdf5::File> {
    let e = h5err(path);
    let l = layout;
    let n = jobs.len();
    let (kept, hl) = (l.kept, l.history);
    let file = crate::storage::h5::create_in_memory(path).map_err(&e)?;
    (|| -> hdf5::Result<()> {
        str_attr(&file, "program", "jointplay")?;
        str_attr(&file, "program_version", version)?;
        str_attr(&file, "units", "SI: m, kg, s, rad, N, N m, J")?;
        l.root.write(&file, 0)?;
        if hl > 0 {
            mark_bits(&file, l.bits)?;
        }
        let g = file.create_group("sweep")?;
        let params: Vec<f64> = jobs.iter().map(|j| j.0).collect();
        write1(
            &g,
            "parameter",
            &params,
            &l.unit,
            "swept parameter value of each job",
        )?;
        {
            let ds = g.dataset("parameter")?;
            str_attr(&ds, "path", &l.parameter)?;
        }
        let dirs: Vec<i8> = jobs.iter().map(|j| j.1).collect();
        write_column(
            &g,
            "direction",
            &dirs,
            None,
            "+1: up the list, -1: back down (continuation)",
        )?;
        write_column(
            &g,
            "done",
            &vec![0u8; n],
            None,
            "0 not run, 1 done, 2 failed (message in /sweep/errors)",
        )?;
        g.create_group("errors")?;
        let d = g.new_dataset::<u32>().shape(n).create("checksum")?;
        str_attr(
            &d,
            "description",
            "CRC-32 of each done value's row data (its rows of every dataset here and its section crossings), by which resume and merge check it; 0 for a value not done",
        )?;
        str_attr(&d, "unit", "1")?;
        u8_attr_set(&g, "continuation", u8::from(l.continuation))?;
        create_nan(&g, "strobe_time", &[n, kept], "s", "strobe times of each job")?;
        for (o, u) in l.observables.iter().zip(&l.units) {
            create_nan(
                &g,
                &o.name,
                &[n, kept],
                u,
                &format!("{} at the strobe times, per job", o.path),
            )?;
            {
                let ds = g.dataset(&o.name)?;
                str_attr(&ds, "path", &o.path)?;
            }
        }
        if hl > 0 {
            let h = g.create_group("history")?;
            // Chunks of one block of a row: each job writes its histories block by block.
            create_nan_chunked(
                &h,
                "time",
                &[n, hl],
                HISTORY_BLOCK,
                "s",
                "sample times over the kept window, per job",
            )?;
            for (o, u) in l.observables.iter().zip(&l.units) {
                create_nan_chunked(
                    &h,
                    &o.name,
                    &[n, hl],
                    HISTORY_BLOCK,
                    u,
                    &format!("{} over the kept window, per job", o.path),
                )?;
                let ds = h.dataset(&o.name)?;
                mark_bits(&ds, l.bits)?;
            }
        }
        hybrid::create_rows(&g, n, l.shape)?;
        let d = g.new_dataset::<u64>().shape(n).create("rhs_evals")?;
        str_attr(
            &d,
            "description",
            "right-hand-side evaluations of each job's analysis run (a Lyapunov run's are counted in its chaos attributes)",
        )?;
        str_attr(&d, "unit", "1")?;
        create_nan(
            &g,
            "wall_time",
            &[n],
            "s",
            "wall-clock time of each job (machine-dependent, the only dataset that is not reproducible)",
        )?;
        if !l.sections.is_empty() {
            g.create_group("sections")?;
        }
        if l.chaos.any() {
            crate::storage::chaos::create_rows(&g, n, &l.chaos)?;
        }
        if let Some((sh, rows)) = shard {
            u64_attr(&file, "shard", sh.index as u64)?;
            u64_attr(&file, "shards", sh.count as u64)?;
            let rows: Vec<u64> = rows.iter().map(|&j| j as u64).collect();
            write_column(
                &g,
                "job",
                &rows,
                Some("1"),
                "index of each row's job in the whole sweep (shard files only)",
            )?;
        }
        Ok(())
    })()
    .map_err(&e)?;
    file.flush().map_err(&e)?;
    Ok(file)
}

/// One shard of a sweep: `index` of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// Parses `I/N`.
    fn from_str(s: &str) -> std::result::Result<Shard, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("'{s}': give the shard as I/N, e.g. 0/8"))?;
        let num = |v: &str, what: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| format!("'{s}': {what} '{v}' is not a whole number"))
        };
        Shard::new(num(i, "shard index")?, num(n, "number of shards")?)
    }
}

impl Shard {
    /// Shard `index` of `count`; an error unless `count >= 1` and `index < count`.
    pub fn new(index: usize, count: usize) -> std::result::Result<Shard, String> {
        if count == 0 {
            return Err(format!(
                "{index}/{count}: the number of shards must be at least 1"
            ));
        }
        if index >= count {
            return Err(format!(
                "{index}/{count}: the shard index must be less than the number of shards \
                 (0 to {})",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }

    /// The shard of a Slurm array task, from `SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_COUNT` and
    /// `SLURM_ARRAY_TASK_MIN` (the offset; 0 when unset) as `var` returns them; `None` outside
    /// an array job. An array that is not one contiguous range of ids (a step or a list) has no
    /// such mapping and is refused.
    pub fn from_slurm(
        var: impl Fn(&str) -> Option<String>,
    ) -> std::result::Result<Option<Shard>, String> {
        let Some(id) = var("SLURM_ARRAY_TASK_ID") else {
            return Ok(None);
        };
        let num = |name: &str, v: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| format!("{name}='{v}' is not a whole number"))
        };
        let id = num("SLURM_ARRAY_TASK_ID", &id)?;
        let count = var("SLURM_ARRAY_TASK_COUNT").ok_or(
            "SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not: give --shard I/N",
        )?;
        let count = num("SLURM_ARRAY_TASK_COUNT", &count)?;
        let min = match var("SLURM_ARRAY_TASK_MIN") {
            Some(v) => num("SLURM_ARRAY_TASK_MIN", &v)?,
            None => 0,
        };
        if let Some(max) = var("SLURM_ARRAY_TASK_MAX") {
            let max = num("SLURM_ARRAY_TASK_MAX", &max)?;
            if max < min || max - min + 1 != count {
                return Err(format!(
                    "the job array ({min} to {max}, {count} tasks) is not one contiguous range of \
                     task ids, so its tasks are not shards 0 to N-1: give --shard I/N"
                ));
            }
        }
        if id < min {
            return Err(format!(
                "SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}"
            ));
        }
        Shard::new(id - min, count)
            .map(Some)
            .map_err(|m| format!("from SLURM_ARRAY_TASK_ID, _COUNT and _MIN: {m}"))
    }

    /// The jobs of a sweep of `jobs` jobs that this shard computes: `index`, `index + count`, ...
    pub fn jobs(self, jobs: usize) -> Vec<usize> {
        (self.index..jobs).step_by(self.count).collect()
    }

    /// The shard file's name for the study `study`: `<study>.shard-I-of-N.h5`.
    pub fn file_name(self, study: &str) -> String {
        format!("{study}.shard-{}-of-{}.h5", self.index, self.count)
    }

    /// The shard a file holds (root attributes `shard` and `shards`), `None` for a file of the
    /// whole sweep.
    pub(crate) fn of_file(file: &hdf5::File) -> hdf5::Result<Option<Shard>> {
        if file.attr("shard").is_err() {
            return Ok(None);
        }
        let (i, n) = (
            read_attr::<u64>(file, "shard")?,
            read_attr::<u64>(file, "shards")?,
        );
        Shard::new(i as usize, n as usize)
            .map(Some)
            .map_err(hdf5::Error::from)
    }
}

/// Writes a single run's result `r` into its `file`: the `root` attributes (complete unless
/// `failure`, whose message it keeps, with the time it stopped at), its warnings and counts, the
/// attributes of the history written while it ran (when `history` gives its rounding:
/// [`crate::storage::bitround`]), its strobe points and the crossings of the sections named
/// `planes`, its chaos measures and its final state.
pub(crate) fn write_single(
    file: &hdf5::File,
    root: &Root,
    obs: &[ObservableSpec],
    planes: &[&str],
    history: Option<Option<u32>>,
    r: &JobResult,
    failure: Option<&crate::Error>,
) -> hdf5::Result<()> {
    root.write(file, u8::from(failure.is_none()))?;
    if let Some(bits) = history {
        mark_bits(file, bits)?;
    }
    if !r.warnings.is_empty() {
        str_attr(file, "warnings", &r.warnings.join("\n"))?;
    }
    if let Some(e) = failure {
        str_attr(file, "error", &e.to_string())?;
        if let crate::Error::Solver(jointplay_solver::Error::Diverged { time, .. })
        | crate::Error::Interrupted {
            time: Some(time), ..
        } = e
        {
            f64_attr(file, "stopped_at", *time)?;
        }
    }
    let t = &r.trace;
    u64_attr(file, "rhs_evals", t.stats.rhs_evals)?;
    u64_attr(file, "accepted_steps", t.stats.accepted)?;
    f64_attr(file, "wall_time", r.wall)?;
    if let Some(bits) = history {
        // Written while the run went (SingleHistory).
        let g = file.group("history")?;
        describe(
            &g.dataset("time")?,
            Some("s"),
            "sample times over the kept window",
        )?;
        for (o, u) in obs.iter().zip(&r.units) {
            let ds = g.dataset(&o.name)?;
            describe(&ds, Some(u), &format!("{} over the kept window", o.path))?;
            str_attr(&ds, "path", &o.path)?;
            mark_bits(&ds, bits)?;
        }
    }
    let g = file.create_group("sections")?;
    let s0 = g.create_group("strobe")?;
    write1(
        &s0,
        "time",
        &t.strobe_time,
        "s",
        "t0 + phase + k T, one per kept period",
    )?;
    obs_datasets(&s0, obs, &r.units, &t.strobe, "at the strobe times")?;
    for (p, c) in planes.iter().zip(&t.crossings) {
        write_crossings(&g, p, obs, &r.units, &c.time, &c.values)?;
    }
    if let Some(c) = &r.chaos {
        crate::storage::chaos::write_single(file, c)?;
    }
    hybrid::write_state(file, &t.final_state)
}
