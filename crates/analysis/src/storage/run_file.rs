//! The run file (layout in book/src/reference/hdf5.md): a run written whole ([`write_run`]), the
//! runs of a comparison study in one file ([`write_study`]), and a run written while it goes
//! ([`RunWriter`]: its datasets created empty and extendable, every
//! [`STREAM_ROWS`] samples appended as one chunk per column,
//! compressed by `crate::storage::chunk`; the attributes known only at the end written when it
//! ends). What a run records is [`crate::storage::run`]; the helpers every file kind uses are
//! [`crate::storage::h5`].

use std::path::{Path, PathBuf};

use jointplay_solver::model::Model;
use ndarray::{Array1, Array2};

use crate::Result;
use crate::storage::h5::*;
use crate::storage::run::{Attr, Channel, Recording, RunResult};

/// Run metadata written as root attributes.
#[derive(Debug, Clone)]
pub struct Meta<'a> {
    pub scene_name: &'a str,
    pub scene_file: &'a Path,
    pub scene_text: &'a str,
    pub program_version: &'a str,
    /// Human-readable integrator settings, e.g. "rk4, step 1e-4 s".
    pub integrator: String,
    pub baumgarte_alpha: f64,
    pub baumgarte_beta: f64,
    /// The drives' common period (s), when they have one.
    pub drive_period: Option<f64>,
    /// Warnings found while compiling the scene.
    pub scene_warnings: &'a [String],
}

impl<'a> Meta<'a> {
    /// The metadata of a run of `model`, compiled from the scene file `file` whose text is
    /// `text`; `program_version` is the version of the program writing the file.
    pub fn of(
        model: &'a Model,
        file: &'a Path,
        text: &'a str,
        program_version: &'a str,
    ) -> Meta<'a> {
        Meta {
            scene_name: &model.name,
            scene_file: file,
            scene_text: text,
            program_version,
            integrator: model.settings.method.describe(),
            baumgarte_alpha: model.settings.alpha,
            baumgarte_beta: model.settings.beta,
            drive_period: model.settings.period,
            scene_warnings: &model.warnings,
        }
    }
}

/// Writes `run` to `dir/<scene_name>.h5` and returns the path.
pub fn write_run(dir: &Path, meta: &Meta, run: &RunResult) -> Result<PathBuf> {
    write_atomically(dir, meta.scene_name, meta.program_version, |file| {
        write_group(file, meta, run)
    })
}

/// Study metadata written as root attributes of a study file.
#[derive(Debug, Clone)]
pub struct StudyMeta<'a> {
    pub study_name: &'a str,
    pub study_file: &'a Path,
    pub study_text: &'a str,
    pub program_version: &'a str,
}

/// Writes the runs of a study to `dir/<study_name>.h5`, one group `/cases/<label>` per run with
/// the layout of a run file, and one group with an `error` attribute per failed case, and returns
/// the path.
pub fn write_study(
    dir: &Path,
    meta: &StudyMeta,
    runs: &[(String, Meta, &RunResult)],
    failed: &[(String, String)],
) -> Result<PathBuf> {
    write_atomically(dir, meta.study_name, meta.program_version, |file| {
        str_attr(file, "study_name", meta.study_name)?;
        str_attr(file, "study_file", &meta.study_file.display().to_string())?;
        str_attr(file, "study", meta.study_text)?;
        let labels: Vec<&str> = runs.iter().map(|r| r.0.as_str()).collect();
        str_attr(file, "cases", &labels.join(","))?;
        let cases = file.create_group("cases")?;
        for (label, m, run) in runs {
            let g = cases.create_group(label)?;
            write_group(&g, m, run)?;
        }
        // A case that failed keeps its group, empty but for the error, so the file says what
        // is missing and why.
        for (label, err) in failed {
            let g = cases.create_group(label)?;
            str_attr(&g, "error", err)?;
        }
        Ok(())
    })
}

/// Writes one run (its attributes and datasets, the layout of a run file's root) into `file`.
fn write_group(file: &hdf5::Group, meta: &Meta, run: &RunResult) -> hdf5::Result<()> {
    write_meta(file, meta)?;
    write_recording(file, &run.recording)?;
    write_outcome(file, meta, run)
}

/// The attributes of a run known before it starts: the scene and the integrator.
fn write_meta(file: &hdf5::Group, meta: &Meta) -> hdf5::Result<()> {
    str_attr(file, "scene_name", meta.scene_name)?;
    str_attr(file, "scene_file", &meta.scene_file.display().to_string())?;
    str_attr(file, "scene", meta.scene_text)?;
    str_attr(file, "integrator", &meta.integrator)?;
    f64_attr(file, "baumgarte_alpha", meta.baumgarte_alpha)?;
    f64_attr(file, "baumgarte_beta", meta.baumgarte_beta)?;
    if let Some(p) = meta.drive_period {
        f64_attr(file, "drive_period", p)?;
    }
    Ok(())
}

/// What a run's end decides: its statistics, whether it is complete (and if not, where and why
/// it stopped), its warnings and its final hybrid state.
fn write_outcome(file: &hdf5::Group, meta: &Meta, run: &RunResult) -> hdf5::Result<()> {
    u64_attr(file, "steps_accepted", run.stats.accepted)?;
    u64_attr(file, "steps_rejected", run.stats.rejected)?;
    u64_attr(file, "rhs_evaluations", run.stats.rhs_evals)?;
    u64_attr(file, "step_events", run.stats.events)?;
    f64_attr(file, "wall_time_s", run.stats.wall.as_secs_f64())?;
    f64_attr(file, "assembly_residual", run.assembly.final_residual)?;
    // A run that stopped keeps its samples up to the failure and says so.
    u8_attr_set(file, "complete", u8::from(run.stopped.is_none()))?;
    if let Some(s) = &run.stopped {
        str_attr(file, "error", &s.to_string())?;
        f64_attr(file, "stopped_at", s.time)?;
        if run.interrupted() {
            // Stopped on request, not by a failure: `run --from` continues from it.
            u8_attr_set(file, "interrupted", 1)?;
        }
    }
    let warnings: Vec<String> = meta
        .scene_warnings
        .iter()
        .cloned()
        .chain(run.warnings.iter().map(|w| w.message.clone()))
        .collect();
    if !warnings.is_empty() {
        str_attr(file, "warnings", &warnings.join("\n"))?;
    }
    // The hybrid state at the end: a later run can continue from it (`run --from`).
    crate::storage::hybrid::write_state(file, &run.final_state)
}

/// Writes the groups of a recording with their attributes.
fn write_groups(g: &hdf5::Group, rec: &Recording) -> hdf5::Result<()> {
    for group in &rec.groups {
        let h = g.create_group(&group.path)?;
        for (name, value) in &group.attrs {
            match value {
                Attr::Str(v) => str_attr(&h, name, v)?,
                Attr::F64(v) => f64_attr(&h, name, *v)?,
            }
        }
    }
    Ok(())
}

/// Writes a recording: the sample times, its groups with their attributes and one dataset per
/// channel (as u8 for a flag, one-dimensional for a scalar), the values of the others rounded to
/// their [`Channel::bits`] when set (marked on each rounded dataset, and the fewest on `g`).
///
/// The chunks of the compressed datasets are compressed by [`crate::storage::chunk`], by the threads of
/// rayon's pool (a recording is written whole once its run is over).
fn write_recording(g: &hdf5::Group, rec: &Recording) -> hdf5::Result<()> {
    use crate::storage::chunk::Store;
    write_groups(g, rec)?;
    mark_bits(g, rec.significant_bits())?;
    let time = NewSet {
        name: "time",
        values: &rec.time,
        width: 1,
        scalar: true,
        store: Store::F64(None),
        unit: "s",
        desc: "sample times",
    };
    let sets: Vec<_> = std::iter::once(time)
        .chain(rec.channels.iter().map(|c| NewSet {
            name: &c.dataset,
            values: &c.values,
            width: c.width(),
            // A flag is a table, whatever its width.
            scalar: c.scalar && !c.flag,
            store: store(c),
            unit: &c.unit,
            desc: &c.description,
        }))
        .collect();
    write_sets(g, &sets)?;
    for c in rec.channels.iter().filter(|c| c.bits.is_some()) {
        let ds = g.dataset(&c.dataset)?;
        mark_bits(&ds, c.bits)?;
    }
    Ok(())
}

/// How channel `c` is stored: a flag as a byte, any other value as a double rounded to its bits.
fn store(c: &Channel) -> crate::storage::chunk::Store {
    match c.flag {
        true => crate::storage::chunk::Store::Flag,
        false => crate::storage::chunk::Store::F64(c.bits),
    }
}

/// A dataset for [`write_sets`]: its values (whole rows of `width`; one-dimensional when
/// `scalar`), how it stores them, its unit and description.
struct NewSet<'a> {
    name: &'a str,
    values: &'a [f64],
    width: usize,
    scalar: bool,
    store: crate::storage::chunk::Store,
    unit: &'a str,
    desc: &'a str,
}

/// Creates and writes the datasets `sets` in `g`, described: those [`column_chunks`] chunks with
/// their chunks compressed by [`crate::storage::chunk`] (by the threads of rayon's pool) and written as
/// they are, the others (of at most [`SMALL`] values) stored as they are.
fn write_sets(g: &hdf5::Group, sets: &[NewSet<'_>]) -> hdf5::Result<()> {
    use crate::storage::chunk::{Rows, Store, append_all};
    let mut rows = Vec::new();
    for s in sets {
        let n = s.values.len().checked_div(s.width).unwrap_or(0);
        let shape = if s.scalar { vec![n] } else { vec![n, s.width] };
        let ds = match (column_chunks(&shape, s.store.size()), s.store) {
            (Some(c), store) => {
                let b = match store {
                    Store::Flag => g.new_dataset::<u8>(),
                    Store::F64(_) => g.new_dataset::<f64>(),
                };
                let ds = b.chunk(c.clone()).shuffle().deflate(DEFLATE);
                let ds = ds.shape(shape).create(s.name)?;
                rows.push((ds.clone(), c[0], s));
                ds
            }
            (None, Store::Flag) => {
                let v: Vec<u8> = s.values.iter().map(|&x| x as u8).collect();
                small(g, s.name, v, &shape)?
            }
            (None, Store::F64(bits)) => {
                let v = crate::storage::bitround::rounded(s.values, bits).into_owned();
                small(g, s.name, v, &shape)?
            }
        };
        describe(&ds, Some(s.unit), s.desc)?;
    }
    let rows: Vec<_> = rows
        .iter()
        .map(|(ds, chunk_rows, s)| Rows {
            ds,
            values: s.values,
            width: s.width,
            chunk_rows: *chunk_rows,
            store: s.store,
        })
        .collect();
    append_all(&rows, 0, true)
}

/// A dataset of at most [`SMALL`] values of `shape` (one or two dimensions), stored as it is.
fn small<T: hdf5::H5Type>(
    g: &hdf5::Group,
    name: &str,
    values: Vec<T>,
    shape: &[usize],
) -> hdf5::Result<hdf5::Dataset> {
    match *shape {
        [_] => create_filtered(g, name, &Array1::from(values)),
        [n, w] => {
            let arr = Array2::from_shape_vec((n, w), values)
                .map_err(|e| hdf5::Error::from(e.to_string()))?;
            create_filtered(g, name, &arr)
        }
        _ => Err(hdf5::Error::from(format!("'{name}': shape {shape:?}"))),
    }
}

/// A run file written while the run goes (see the module documentation): the layout of
/// [`write_run`], the same dataset names, shapes, types and values, with every dataset chunked
/// by [`STREAM_ROWS`] samples and compressed whatever its length. Until [`RunWriter::finish`]
/// the file lies under its temporary name with `complete = 0`, readable up to the last
/// appended samples.
pub struct RunWriter {
    out: PartialFile,
    time: hdf5::Dataset,
    /// One per channel of the recording, in its order.
    sets: Vec<hdf5::Dataset>,
    /// Samples written.
    rows: usize,
}

/// A run file opened by [`RunWriter::open`]: its metadata written, marked incomplete, its
/// datasets not yet created ([`OpenedRun::declare`]).
pub struct OpenedRun {
    out: PartialFile,
}

impl OpenedRun {
    /// The file's temporary name while it is written.
    pub fn partial(&self) -> &Path {
        self.out.partial()
    }

    /// Creates the groups and the empty datasets of `rec` (a recording declared by
    /// [`Recording::of`]); on an error the partial file is removed. This is most of the cost of
    /// creating a run file (on the mixed 4-UPS/RPU, its few hundred datasets about 22 ms of
    /// 23), so a streamed run does it on its writer thread, beside the integration's start.
    pub fn declare(self, rec: &Recording) -> Result<RunWriter> {
        let OpenedRun { out } = self;
        let file = &out.file;
        let made = (|| -> hdf5::Result<(hdf5::Dataset, Vec<hdf5::Dataset>)> {
            let time = extendable::<f64>(file, "time", 1, true, "s", "sample times")?;
            write_groups(file, rec)?;
            mark_bits(file, rec.significant_bits())?;
            let sets = rec
                .channels
                .iter()
                .map(|c: &Channel| {
                    let (name, unit, desc) = (&c.dataset, &c.unit, &c.description);
                    if c.flag {
                        extendable::<u8>(file, name, c.width(), false, unit, desc)
                    } else {
                        let ds = extendable::<f64>(file, name, c.width(), c.scalar, unit, desc)?;
                        mark_bits(&ds, c.bits)?;
                        Ok(ds)
                    }
                })
                .collect::<hdf5::Result<Vec<_>>>()?;
            Ok((time, sets))
        })();
        let mut out = out;
        match made {
            Ok((time, sets)) => {
                drop((time, sets));
                // On disk whole, then its datasets opened there.
                if let Err(err) = out.materialize() {
                    out.discard();
                    return Err(err);
                }
                let file = &out.file;
                let opened = (|| -> hdf5::Result<(hdf5::Dataset, Vec<hdf5::Dataset>)> {
                    let sets = rec
                        .channels
                        .iter()
                        .map(|c| file.dataset(&c.dataset))
                        .collect::<hdf5::Result<Vec<_>>>()?;
                    Ok((file.dataset("time")?, sets))
                })();
                match opened {
                    Ok((time, sets)) => Ok(RunWriter {
                        out,
                        time,
                        sets,
                        rows: 0,
                    }),
                    Err(err) => Err(out.fail(err)),
                }
            }
            Err(err) => Err(out.fail(err)),
        }
    }
}

impl RunWriter {
    /// Creates `dir/<scene_name>.h5.partial` with the run's metadata, marked incomplete, without
    /// its datasets yet ([`OpenedRun::declare`]).
    pub fn open(dir: &Path, meta: &Meta) -> Result<OpenedRun> {
        let out = PartialFile::create(dir, meta.scene_name, meta.program_version)?;
        let made = write_meta(&out.file, meta).and_then(|()| u8_attr_set(&out.file, "complete", 0));
        match made {
            Ok(()) => Ok(OpenedRun { out }),
            Err(err) => Err(out.fail(err)),
        }
    }

    /// Creates `dir/<scene_name>.h5.partial` with the run's metadata, the groups and the empty
    /// datasets of `rec` (a recording declared by [`Recording::of`]), marked incomplete.
    pub fn create(dir: &Path, meta: &Meta, rec: &Recording) -> Result<RunWriter> {
        Self::open(dir, meta)?.declare(rec)
    }

    /// Closes and removes the partial file (a run that could not be recorded).
    pub fn discard(self) {
        let RunWriter {
            out, time, sets, ..
        } = self;
        drop((time, sets));
        out.discard();
    }

    /// The file's temporary name while it is written.
    pub fn partial(&self) -> &Path {
        self.out.partial()
    }

    /// Samples written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Appends the samples `rec` holds (all its channels, the same number of samples each) and
    /// flushes the file. The chunks are compressed by `crate::storage::chunk` (by the threads of
    /// rayon's pool when `parallel`: the last block of a run, which nothing else waits beside)
    /// when the samples start a chunk, as every block of a streamed run does; otherwise they go
    /// through HDF5's own filters.
    pub fn append(&mut self, rec: &Recording, parallel: bool) -> Result<()> {
        let e = h5err(self.out.partial());
        let n = rec.time.len();
        if n == 0 {
            return Ok(());
        }
        let from = self.rows;
        (|| -> hdf5::Result<()> {
            if from.is_multiple_of(STREAM_ROWS) {
                self.append_packed(rec, from, parallel)?;
            } else {
                append(&self.time, from, n, 1, true, rec.time.clone())?;
                for (c, ds) in rec.channels.iter().zip(&self.sets) {
                    if c.flag {
                        let v: Vec<u8> = c.values.iter().map(|&x| x as u8).collect();
                        append(ds, from, n, c.width(), false, v)?;
                    } else {
                        let v = crate::storage::bitround::rounded(&c.values, c.bits).into_owned();
                        append(ds, from, n, c.width(), c.scalar, v)?;
                    }
                }
            }
            // Not flushed: see create_streamed.
            Ok(())
        })()
        .map_err(&e)?;
        self.rows += n;
        Ok(())
    }

    /// [`RunWriter::append`] of samples starting at row `from`, a multiple of [`STREAM_ROWS`]:
    /// every dataset extended, its chunks compressed by [`crate::storage::chunk`] and written as they are.
    fn append_packed(&self, rec: &Recording, from: usize, parallel: bool) -> hdf5::Result<()> {
        use crate::storage::chunk::{Rows, Store, append_all};
        let row = |ds, values, width, store| Rows {
            ds,
            values,
            width,
            chunk_rows: STREAM_ROWS,
            store,
        };
        let sets: Vec<_> = std::iter::once(row(&self.time, &rec.time[..], 1, Store::F64(None)))
            .chain(
                rec.channels
                    .iter()
                    .zip(&self.sets)
                    .map(|(c, ds)| row(ds, &c.values[..], c.width(), store(c))),
            )
            .collect();
        append_all(&sets, from, parallel)
    }

    /// Writes what the run's end decides (statistics, `complete`, the error of a run that
    /// stopped, warnings, the final state; `run.recording` is not written again), closes the
    /// file and moves it into place; on an error the partial file is removed.
    pub fn finish(self, meta: &Meta, run: &RunResult) -> Result<PathBuf> {
        let RunWriter {
            out, time, sets, ..
        } = self;
        drop((time, sets));
        if let Err(err) = write_outcome(&out.file, meta, run) {
            return Err(out.fail(err));
        }
        out.finish()
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use jointplay_solver::scene::SceneSpec;

    use super::*;

    #[test]
    fn the_metadata_of_a_run_comes_from_the_compiled_model() {
        let path =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes/4ups-rpu.toml");
        let scene = SceneSpec::load(&path).unwrap();
        let (model, _) = Model::compile(&scene).unwrap();
        let m = Meta::of(&model, &path, &scene.text, "9.9.9");
        assert_eq!(m.scene_name, "4ups-rpu");
        assert_eq!(m.scene_file, path);
        assert_eq!(m.scene_text, scene.text);
        assert_eq!(m.program_version, "9.9.9");
        assert_eq!(m.integrator, "rk4, fixed step 1e-4 s");
        assert_eq!((m.baumgarte_alpha, m.baumgarte_beta), (5.0, 5.0));
        // The drives move at omega = 3.14 rad/s: period 2 pi / 3.14 s.
        let period = m.drive_period.unwrap();
        assert!((period - 2.001014).abs() < 1e-6, "{period}");
        assert_eq!(m.scene_warnings, model.warnings.as_slice());
    }
}
