//! The durable storage of a sweep or a shard: its journal while it runs, its HDF5 file written
//! from the journal, and the checked reading of the values a file or a journal holds.
//!
//! **While it runs.** Every value that finishes (done or failed) is appended to
//! `DIR/<file>.journal` ([`super::journal`]) and forced to disk before it is counted; the
//! journal's header names the study text, the shard and the number of rows, so that a journal is
//! never taken for another computation's.
//!
//! **The file.** When the sweep ends or stops, `write_file` writes the HDF5 file from the
//! values kept: under `<file>.partial`, closed, read back and checked row by row against each
//! value's checksum, forced to disk and renamed over `<file>` ([`super::durable::replace`]).
//! Each row's checksum goes into `/sweep/checksum`, so that `--resume` and `merge` can check every
//! value a file holds (`read_values`). A complete file ends the journal (it is removed); an
//! incomplete one keeps it for `--resume`.
//!
//! **Resuming** (`resume`) keeps the values of the journal and those of the file that the
//! journal lacks (a merged file, say), each checked; a value that does not check is computed
//! again, and said so.

use std::path::{Path, PathBuf};

use ndarray::Array1;

use super::durable::{self, with_suffix};
use super::journal::{self, Journal};
use super::rows::{Cells, Kind, Outcome, Row, Section, Value, read_cells};
use crate::storage::analysis_file::{
    JobResult, Shard, SweepLayout, create_sweep_file, write_crossings,
};
use crate::storage::h5::{f64_attr_set, h5err, read_attr, read_str, str_attr, u8_attr_set};
use crate::{Error, Result};

/// The journal of the sweep file `path` (`x.h5` -> `x.journal`, `x.shard-0-of-4.h5` ->
/// `x.shard-0-of-4.journal`).
pub fn journal_path(path: &Path) -> PathBuf {
    path.with_extension("journal")
}

/// What a journal belongs to: the study text, the shard and the number of rows.
fn header(text: &str, shard: Option<Shard>, rows: usize) -> Vec<u8> {
    let shard = shard.map_or("none".to_string(), |s| s.to_string());
    format!("jointplay sweep journal 1\nshard {shard}\nrows {rows}\nstudy\n{text}").into_bytes()
}

/// The datasets under `/sweep` a value has a row in, their element type and their width (0 for
/// a dataset of one dimension), in the order of its row data.
pub(crate) fn row_names(l: &SweepLayout) -> Vec<(String, Kind, Option<usize>)> {
    const ONE: usize = usize::MAX;
    let mut v = vec![("strobe_time".to_string(), Kind::F64, l.kept)];
    for o in &l.observables {
        v.push((o.name.clone(), Kind::F64, l.kept));
    }
    if l.history > 0 {
        v.push(("history/time".into(), Kind::F64, l.history));
        for o in &l.observables {
            v.push((format!("history/{}", o.name), Kind::F64, l.history));
        }
    }
    v.push(("final_state".into(), Kind::F64, l.shape.dim));
    v.push(("final_time".into(), Kind::F64, ONE));
    v.push(("final_onset".into(), Kind::F64, l.shape.contacts));
    v.push(("final_warned".into(), Kind::U8, l.shape.clearances));
    v.push(("final_stepper".into(), Kind::F64, 5));
    v.push(("rhs_evals".into(), Kind::U64, ONE));
    v.push(("wall_time".into(), Kind::F64, ONE));
    if l.chaos.any() {
        v.push(("chaos/class".into(), Kind::U8, ONE));
        if let Some(ly) = &l.chaos.lyapunov {
            for name in ["exponents", "stderr", "map_exponents"] {
                v.push((format!("chaos/{name}"), Kind::F64, ly.exponents));
            }
            if ly.two_trajectory {
                v.push(("chaos/two_trajectory".into(), Kind::F64, 2));
            }
        }
        for asked in &l.chaos.indicators {
            let row = asked.indicator.row();
            v.push((format!("chaos/{}", row.name), Kind::F64, ONE));
        }
    }
    v.into_iter()
        .map(|(n, k, w)| (n, k, (w != ONE).then_some(w)))
        .collect()
}

/// `v` padded with `fill` (or cut) to `width` values (one for a dataset of one dimension).
fn fit<T: Clone>(v: &[T], width: Option<usize>, fill: T) -> Vec<T> {
    let w = width.unwrap_or(1);
    let mut out: Vec<T> = v.iter().take(w).cloned().collect();
    out.resize(w, fill);
    out
}

/// The row data of a finished job, as the file stores it (histories rounded to the layout's
/// bits, every row padded to its dataset's width as an unwritten row reads).
pub(crate) fn job_row(l: &SweepLayout, r: &JobResult) -> Row {
    let t = &r.trace;
    let s = &t.final_state;
    let obs = |name: &str| l.observables.iter().position(|o| o.name == name);
    let spectrum = r.chaos.as_ref().and_then(|c| c.spectrum.as_ref());
    let cells = row_names(l)
        .into_iter()
        .map(|(name, _, w)| {
            let nan = f64::NAN;
            let c = match name.as_str() {
                "strobe_time" => Cells::F64(fit(&t.strobe_time, w, nan)),
                "history/time" => Cells::F64(fit(&t.history_time, w, nan)),
                "final_state" => Cells::F64(fit(&s.y, w, nan)),
                "final_time" => Cells::F64(vec![s.t]),
                "final_onset" => Cells::F64(fit(&s.onset, w, nan)),
                "final_warned" => {
                    let v: Vec<u8> = s.warned.iter().map(|&x| u8::from(x)).collect();
                    Cells::U8(fit(&v, w, 0))
                }
                "final_stepper" => {
                    Cells::F64(crate::storage::hybrid::stepper_row(&s.stepper).to_vec())
                }
                "rhs_evals" => Cells::U64(vec![t.stats.rhs_evals]),
                "wall_time" => Cells::F64(vec![r.wall]),
                "chaos/class" => Cells::U8(vec![r.chaos.as_ref().map_or(0, |c| c.class as u8)]),
                "chaos/exponents" => {
                    Cells::F64(fit(spectrum.map_or(&[][..], |s| &s.exponents), w, nan))
                }
                "chaos/stderr" => Cells::F64(fit(spectrum.map_or(&[][..], |s| &s.stderr), w, nan)),
                "chaos/map_exponents" => Cells::F64(fit(
                    &spectrum.map(|s| s.map_exponents()).unwrap_or_default(),
                    w,
                    nan,
                )),
                "chaos/two_trajectory" => Cells::F64(fit(
                    &spectrum
                        .and_then(|s| s.two_trajectory.as_ref())
                        .map(|(v, e, _)| vec![*v, *e])
                        .unwrap_or_default(),
                    w,
                    nan,
                )),
                other if other.starts_with("chaos/") => {
                    // An indicator's number (the rows above are the spectrum's).
                    let row = &other["chaos/".len()..];
                    let key = l
                        .chaos
                        .indicators
                        .iter()
                        .find(|a| a.indicator.row().name == row);
                    Cells::F64(vec![
                        r.chaos
                            .iter()
                            .flat_map(|c| &c.readings)
                            .find(|x| key.is_some_and(|a| a.key() == x.key))
                            .map_or(nan, |x| x.value),
                    ])
                }
                other => match other.strip_prefix("history/") {
                    Some(o) => {
                        let v = obs(o).map_or(&[][..], |i| &t.history[i][..]);
                        Cells::F64(fit(&crate::storage::bitround::rounded(v, l.bits), w, nan))
                    }
                    None => {
                        let v = obs(other).map_or(&[][..], |i| &t.strobe[i][..]);
                        Cells::F64(fit(v, w, nan))
                    }
                },
            };
            (name, c)
        })
        .collect();
    let sections = l
        .sections
        .iter()
        .zip(&t.crossings)
        .map(|(name, c)| Section {
            name: name.clone(),
            time: c.time.clone(),
            values: c.values.clone(),
        })
        .collect();
    Row { cells, sections }
}

/// The final hybrid state a row holds (a continuation sweep's hand-over).
pub(crate) fn row_state(
    row: &Row,
) -> std::result::Result<jointplay_solver::state::HybridState, String> {
    let warned = match row.cell("final_warned") {
        Some(Cells::U8(v)) => v.iter().map(|&w| w != 0).collect(),
        _ => Vec::new(),
    };
    let t = row.f64s("final_time").first().copied().unwrap_or(f64::NAN);
    if t.is_nan() {
        return Err("the value has no final state".into());
    }
    Ok(jointplay_solver::state::HybridState {
        t,
        y: row.f64s("final_state").to_vec(),
        onset: row.f64s("final_onset").to_vec(),
        warned,
        stepper: crate::storage::hybrid::stepper_from(row.f64s("final_stepper"))
            .map_err(|e| e.to_string())?,
    })
}

/// Reads the row data of row `r` of the sweep file `file` (cells and sections).
fn read_row(
    file: &hdf5::File,
    l: &SweepLayout,
    names: &[(String, Kind)],
    r: usize,
) -> hdf5::Result<Row> {
    let g = file.group("sweep")?;
    let cells = read_cells(&g, r, names)?;
    let mut sections = Vec::new();
    if !l.sections.is_empty() {
        let gr = g.group(&format!("sections/{r}"))?;
        for name in &l.sections {
            let gp = gr.group(name)?;
            let time = gp.dataset("time")?.read_raw::<f64>()?;
            let values = l
                .observables
                .iter()
                .map(|o| gp.dataset(&o.name)?.read_raw::<f64>())
                .collect::<hdf5::Result<Vec<_>>>()?;
            sections.push(Section {
                name: name.clone(),
                time,
                values,
            });
        }
    }
    Ok(Row { cells, sections })
}

/// The values of a sweep file that check: each done row whose data has the checksum of
/// `/sweep/checksum`, each failed row with its message. A row that does not check is left out
/// and described in the second list. An error when the file cannot be read as a sweep file of
/// `n` rows with checksums.
pub(crate) fn read_values(
    path: &Path,
    file: &hdf5::File,
    l: &SweepLayout,
    n: usize,
) -> Result<(Vec<Value>, Vec<String>)> {
    let e = h5err(path);
    let g = file.group("sweep").map_err(&e)?;
    let done = g
        .dataset("done")
        .and_then(|d| d.read_raw::<u8>())
        .map_err(&e)?;
    if done.len() != n {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: format!("has {} values where this run has {n}", done.len()),
        });
    }
    let sums = g
        .dataset("checksum")
        .and_then(|d| d.read_raw::<u32>())
        .map_err(|_| Error::Io {
            file: path.to_path_buf(),
            message: "has no /sweep/checksum (written by an earlier jointplay, whose values \
                      cannot be checked): remove it, or run without --resume"
                .into(),
        })?;
    if sums.len() != n {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: format!("/sweep/checksum has {} rows for {n} values", sums.len()),
        });
    }
    let names: Vec<(String, Kind)> = row_names(l).into_iter().map(|(n, k, _)| (n, k)).collect();
    let errors = g.group("errors").map_err(&e)?;
    let mut values = Vec::new();
    let mut bad = Vec::new();
    for (r, d) in done.iter().enumerate() {
        match d {
            0 => {}
            1 => match read_row(file, l, &names, r) {
                Ok(row) if row.checksum() == sums[r] => values.push(Value {
                    row: r,
                    outcome: Outcome::Done(row),
                }),
                Ok(_) => bad.push(format!("row {r}: its data do not match its checksum")),
                Err(err) => bad.push(format!("row {r}: cannot be read: {err}")),
            },
            2 => match read_str(&errors, &r.to_string()) {
                Ok(m) => values.push(Value {
                    row: r,
                    outcome: Outcome::Failed(m),
                }),
                Err(err) => bad.push(format!(
                    "row {r}: failed, but its message cannot be read: {err}"
                )),
            },
            other => bad.push(format!("row {r}: status {other} (0, 1 or 2 expected)")),
        }
    }
    Ok((values, bad))
}

/// A sweep's journal open for appending, with the values it keeps by row.
pub(crate) struct Store {
    pub journal: Journal,
    pub values: Vec<Option<Value>>,
}

/// Opens the store of the sweep file `path` of `n` rows: with `resume`, the values of its journal
/// and of the file that check (warnings for what is left out go to `warn`); without, a new
/// journal. Refuses a journal or a file of another study text, shard or size, and a file that
/// cannot be read, naming it.
pub(crate) fn open(
    path: &Path,
    text: &str,
    shard: Option<Shard>,
    l: &SweepLayout,
    n: usize,
    resume: bool,
    warn: &mut dyn FnMut(String),
) -> Result<Store> {
    let jp = journal_path(path);
    let head = header(text, shard, n);
    let _ = std::fs::remove_file(with_suffix(&jp, ".tmp"));
    let mut values: Vec<Option<Value>> = vec![None; n];
    if !resume {
        // The journal of a run that did not finish holds finished values: never thrown away
        // unasked.
        if jp.exists() {
            let kept = journal::scan(&jp).map(|s| s.records.len()).unwrap_or(0);
            if kept > 0 {
                return Err(Error::Io {
                    file: jp.clone(),
                    message: format!(
                        "holds {kept} finished values of an earlier run of this output that did \
                         not finish: go on with --resume, or remove this file to start afresh \
                         (its values are then lost)"
                    ),
                });
            }
        }
        let journal = Journal::create(&jp, &head)?;
        return Ok(Store { journal, values });
    }
    let refuse = |file: &Path, m: String| Error::Io {
        file: file.to_path_buf(),
        message: format!("{m}: remove it, or run without --resume"),
    };
    let mut journal = None;
    if jp.exists() {
        let scan = journal::scan(&jp)?;
        if scan.header != head {
            return Err(refuse(
                &jp,
                "belongs to another computation (another study text, shard or number of \
                 values)"
                    .into(),
            ));
        }
        for (off, len, why) in &scan.skipped {
            warn(format!(
                "{}: {len} bytes at offset {off} skipped: {why}; the values there are computed again",
                jp.display()
            ));
        }
        for p in &scan.records {
            match Value::decode(p) {
                Ok(v) if v.row < n => {
                    let r = v.row;
                    values[r] = Some(v);
                }
                Ok(v) => warn(format!(
                    "{}: a value of row {} of {n} skipped",
                    jp.display(),
                    v.row
                )),
                Err(m) => warn(format!("{}: a record skipped: {m}", jp.display())),
            }
        }
        journal = Some(Journal::reopen(&jp, &scan)?);
    }
    let mut imported = Vec::new();
    if path.exists() {
        match read_file_values(path, text, shard, l, n) {
            Ok((vals, bad)) => {
                for b in bad {
                    warn(format!("{}: {b}; computed again", path.display()));
                }
                for v in vals {
                    let r = v.row;
                    if values[r].is_none() {
                        imported.push(v.encode());
                        values[r] = Some(v);
                    }
                }
            }
            // With a journal, the file is only a copy of (part of) it.
            Err(err) if journal.is_some() => {
                warn(format!("{err}; the values of its journal are kept"));
            }
            Err(err) => return Err(err),
        }
    }
    let journal = match journal {
        Some(mut j) => {
            for p in &imported {
                j.append(p)?;
            }
            j.commit()?;
            j
        }
        None => Journal::create_with(&jp, &head, &imported)?,
    };
    Ok(Store { journal, values })
}

/// The values that check in the sweep file `path`, after its study text, shard and size are
/// checked against this run's.
fn read_file_values(
    path: &Path,
    text: &str,
    shard: Option<Shard>,
    l: &SweepLayout,
    n: usize,
) -> Result<(Vec<Value>, Vec<String>)> {
    let e = h5err(path);
    let refuse = |m: &str| Error::Io {
        file: path.to_path_buf(),
        message: format!("{m}: remove it, or run without --resume"),
    };
    let file = hdf5::File::open(path).map_err(|err| Error::Io {
        file: path.to_path_buf(),
        message: format!("cannot be opened ({err}): remove it, or run without --resume"),
    })?;
    let old = read_str(&file, "study").map_err(&e)?;
    if old != text {
        return Err(refuse("written from another version of the study text"));
    }
    if Shard::of_file(&file).map_err(&e)? != shard {
        return Err(refuse(
            "holds other values of the sweep than this run computes (its shard attributes do not match)",
        ));
    }
    read_values(path, &file, l, n)
}

impl Store {
    /// Appends `v` to the journal (committed by [`Store::commit`]) and keeps it.
    pub fn add(&mut self, v: Value) -> Result<()> {
        self.journal.append(&v.encode())?;
        let r = v.row;
        self.values[r] = Some(v);
        Ok(())
    }

    /// Forces the values added so far to disk: from now on they count as finished.
    pub fn commit(&mut self) -> Result<()> {
        self.journal.commit()
    }
}

/// Writes the sweep file `path` of `layout` with `jobs` (parameter value and direction of each
/// row) and the `values` kept (see the module documentation): built in memory, each dataset
/// read back and compared with what was written, then written under no name, forced to disk
/// and moved into place. Returns whether every row is done or failed.
#[allow(clippy::too_many_arguments)]
pub(crate) fn write_file(
    path: &Path,
    layout: &SweepLayout,
    version: &str,
    jobs: &[(f64, i8)],
    shard: Option<(Shard, &[usize])>,
    values: &[Option<Value>],
    wall: f64,
) -> Result<bool> {
    let name = with_suffix(path, ".partial");
    let e = h5err(&name);
    let file = create_sweep_file(&name, layout, version, jobs, shard)?;
    let n = jobs.len();
    let mut done = vec![0u8; n];
    let mut sums = vec![0u32; n];
    let mut rows: Vec<Option<&Row>> = vec![None; n];
    (|| -> hdf5::Result<()> {
        let g = file.group("sweep")?;
        let errors = g.group("errors")?;
        for v in values.iter().flatten() {
            let r = v.row;
            match &v.outcome {
                Outcome::Done(row) => {
                    if !row.sections.is_empty() {
                        let gj = g.group("sections")?.create_group(&r.to_string())?;
                        for s in &row.sections {
                            write_crossings(
                                &gj,
                                &s.name,
                                &layout.observables,
                                &layout.units,
                                &s.time,
                                &s.values,
                            )?;
                        }
                    }
                    sums[r] = row.checksum();
                    done[r] = 1;
                    rows[r] = Some(row);
                }
                Outcome::Failed(m) => {
                    str_attr(&errors, &r.to_string(), m)?;
                    done[r] = 2;
                }
            }
        }
        // Dataset by dataset, every row at once: each chunk is compressed once.
        for (cell, kind, width) in row_names(layout) {
            write_checked(&g, &cell, kind, width, &rows)?;
        }
        write_checked_u8(&g, "done", &done)?;
        let ds = g.dataset("checksum")?;
        ds.write(&Array1::from(sums.clone()))?;
        if ds.read_raw::<u32>()? != sums {
            return Err("/sweep/checksum does not read back as written".into());
        }
        let complete = done.iter().all(|&d| d != 0);
        u8_attr_set(&file, "complete", u8::from(complete))?;
        f64_attr_set(&file, "wall_time", wall)?;
        Ok(())
    })()
    .map_err(&e)?;
    let complete: u8 = read_attr(&file, "complete").map_err(&e)?;
    let bytes = crate::storage::h5::image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    durable::write_new(path, &bytes)?;
    Ok(complete == 1)
}

/// Writes dataset `name` of `g` (a row per value, `width` columns or one value) from the cells
/// of `rows` (rows without a value: NaN, or 0 for integers, as an unwritten row reads), in one
/// write, and reads it back: an error when it does not read back bit for bit.
fn write_checked(
    g: &hdf5::Group,
    name: &str,
    kind: Kind,
    width: Option<usize>,
    rows: &[Option<&Row>],
) -> hdf5::Result<()> {
    let w = width.unwrap_or(1);
    if w == 0 {
        return Ok(());
    }
    let n = rows.len();
    let ds = g.dataset(name)?;
    let back = |same: bool| -> hdf5::Result<()> {
        if same {
            Ok(())
        } else {
            Err(format!("/sweep/{name} does not read back as written").into())
        }
    };
    macro_rules! column {
        ($t:ty, $fill:expr, $variant:ident) => {{
            let mut v: Vec<$t> = vec![$fill; n * w];
            for (r, row) in rows.iter().enumerate() {
                if let Some(Cells::$variant(c)) = row.and_then(|row| row.cell(name)) {
                    let k = c.len().min(w);
                    v[r * w..r * w + k].copy_from_slice(&c[..k]);
                }
            }
            match width {
                Some(w) => ds.write(
                    &ndarray::Array2::from_shape_vec((n, w), v.clone())
                        .map_err(|e| hdf5::Error::from(e.to_string()))?,
                )?,
                None => ds.write(&Array1::from(v.clone()))?,
            }
            v
        }};
    }
    match kind {
        Kind::F64 => {
            let v = column!(f64, f64::NAN, F64);
            let r = ds.read_raw::<f64>()?;
            back(r.len() == v.len() && r.iter().zip(&v).all(|(a, b)| a.to_bits() == b.to_bits()))
        }
        Kind::U8 => {
            let v = column!(u8, 0, U8);
            back(ds.read_raw::<u8>()? == v)
        }
        Kind::U64 => {
            let v = column!(u64, 0, U64);
            back(ds.read_raw::<u64>()? == v)
        }
    }
}

/// Writes the one-dimensional u8 dataset `name` and reads it back.
fn write_checked_u8(g: &hdf5::Group, name: &str, v: &[u8]) -> hdf5::Result<()> {
    let ds = g.dataset(name)?;
    ds.write(&Array1::from(v.to_vec()))?;
    if ds.read_raw::<u8>()? != v {
        return Err(format!("/sweep/{name} does not read back as written").into());
    }
    Ok(())
}
