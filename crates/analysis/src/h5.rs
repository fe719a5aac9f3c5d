//! HDF5 export of a run (layout documented in book/src/reference/hdf5.md), and the small set of
//! helpers every file kind is written and read with (attributes, datasets of one or two
//! dimensions, rows of a sweep, strings).
//!
//! A file written whole (a study, a sweep, a run recorded in memory) is built in memory and
//! written under no name, forced to disk and renamed into place (`write_atomically`,
//! [`crate::storage`]); a file streamed while its run goes is written under the temporary name
//! `<name>.h5.partial`, in the 1.8 format and unflushed until its end (`create_streamed`), and
//! renamed once complete. So
//! a crash or an error never leaves a file that looks finished. Every dataset carries a `unit`
//! attribute (SI) and a `description`.
//!
//! **Compression.** Every numeric dataset of more than [`SMALL`] values, and every dataset
//! written while its run goes (extendable, so chunked whatever its final size), is chunked and
//! compressed with the shuffle filter followed by deflate ([`DEFLATE`]): the shuffle regroups
//! the bytes of the values by significance (all sign-and-exponent bytes, then the high mantissa
//! bytes, ...), and since neighbouring samples of a smooth signal share their exponent and high
//! mantissa bytes, deflate finds long repeats in the first planes. The compression is lossless:
//! only the file's bytes change. (What a scene's `output.significant_bits` or an analysis's
//! `significant_bits` asks for is rounded before, by [`crate::bitround`], and marked with the
//! attribute `significant_bits`.) The chunks of a run's recording (streamed by [`RunWriter`] or
//! written whole by [`write_run`] and [`write_study`]), and those of a single analysis run's
//! histories, are shuffled and deflated by
//! `crate::chunk`, with libdeflate and on several threads where nothing else runs, and written
//! as they are; every other dataset goes through HDF5's own filters (zlib). The chunks are in
//! the format of the declared filters either way, and decompress to the same values. Chunks hold about [`CHUNK_BYTES`] (a recording's datasets one
//! column at a time, `column_chunks`; other tables whole rows; a sweep's history rows chunked
//! by the block its jobs write them in; a streamed recording's chunks hold [`STREAM_ROWS`]
//! samples of a column), small enough
//! that reading one column of a long recording decompresses little beyond it, large enough that
//! the per-chunk index and deflate's start-up cost stay negligible. Datasets of strings are not
//! compressed (their values live on the file's heap, out of the filters' reach).
//!
//! **Streaming.** A run file can be written while the run goes ([`RunWriter`]): its datasets
//! are created empty and extendable, and every [`STREAM_ROWS`] samples are appended as one chunk
//! each (not flushed until the close: see `create_streamed`), so a run's memory does not grow
//! with its length; the attributes known only
//! at the end (statistics, `complete`, the final state) are written when it ends.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;
use jointplay_solver::model::Model;
use ndarray::{Array1, Array2, s};

use crate::run::{Attr, Channel, Recording, RunResult};
use crate::{Error, Result};

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

pub(crate) fn h5err(file: &Path) -> impl Fn(hdf5::Error) -> Error + '_ {
    move |e| {
        let mut message = e.to_string();
        // HDF5 locks a file while it is open; say what that means for the user.
        if message.contains("unable to lock file") {
            message.push_str(
                " (another program has this file open: close it there, \
                 or set HDF5_USE_FILE_LOCKING=FALSE when no two programs write it at once)",
            );
        }
        Error::Hdf5 {
            file: file.to_path_buf(),
            message,
        }
    }
}

pub(crate) fn str_attr(loc: &hdf5::Location, name: &str, value: &str) -> hdf5::Result<()> {
    // Strings with interior NUL bytes cannot be stored; replace them (never expected in practice).
    let v: VarLenUnicode = value
        .replace('\0', " ")
        .parse()
        .map_err(|e| hdf5::Error::from(format!("{e:?}")))?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&v)
}

pub(crate) fn f64_attr(loc: &hdf5::Location, name: &str, value: f64) -> hdf5::Result<()> {
    loc.new_attr::<f64>().create(name)?.write_scalar(&value)
}

/// Writes a scalar attribute, creating it or overwriting its value.
fn attr_set<T: hdf5::H5Type>(loc: &hdf5::Location, name: &str, v: T) -> hdf5::Result<()> {
    match loc.attr(name) {
        Ok(a) => a.write_scalar(&v),
        Err(_) => loc.new_attr::<T>().create(name)?.write_scalar(&v),
    }
}

/// Writes a u8 attribute, creating it or overwriting its value.
pub(crate) fn u8_attr_set(loc: &hdf5::Location, name: &str, v: u8) -> hdf5::Result<()> {
    attr_set(loc, name, v)
}

/// Writes an f64 attribute, creating it or overwriting its value.
pub(crate) fn f64_attr_set(loc: &hdf5::Location, name: &str, v: f64) -> hdf5::Result<()> {
    attr_set(loc, name, v)
}

pub(crate) fn u64_attr(loc: &hdf5::Location, name: &str, value: u64) -> hdf5::Result<()> {
    loc.new_attr::<u64>().create(name)?.write_scalar(&value)
}

/// Writes a one-dimensional f64 dataset with its unit and description.
pub(crate) fn write1(
    g: &hdf5::Group,
    name: &str,
    data: &[f64],
    unit: &str,
    desc: &str,
) -> hdf5::Result<()> {
    write_column(g, name, data, Some(unit), desc)
}

/// Datasets of at most this many values are stored contiguous and uncompressed (a chunk index
/// and a filter pipeline would cost more than they save).
pub const SMALL: usize = 256;

/// Bytes per chunk of a compressed dataset (rounded to whole rows).
pub const CHUNK_BYTES: usize = 64 * 1024;

/// Deflate level after the shuffle filter, of zlib (HDF5's filter) and of libdeflate
/// (`crate::chunk`) alike. Level 4 is the middle of zlib's range. On a 6 s run of the mixed
/// 4-UPS/RPU (DOPRI5, 1 ms output) zlib's level 1 made the file 0.8 % larger and took the same
/// share of the run's time (about 16 %, by `perf`): recorded trajectories compress little either
/// way. On a 10 s run's chunks libdeflate's levels 1, 4 and 6 gave 1.357, 1.382 and 1.385 times
/// smaller in 179, 248 and 273 ms (zlib's level 4: 1.374 in 527 ms).
pub const DEFLATE: u8 = 4;

/// Samples a streamed run file appends at once: one chunk of each column of every dataset.
pub const STREAM_ROWS: usize = 2048;

/// Creates dataset `name` in `g` holding `arr`: chunked, shuffled and deflated when
/// [`chunk_shape`] finds it large enough, contiguous otherwise.
fn create_filtered<T: hdf5::H5Type, D: ndarray::Dimension>(
    g: &hdf5::Group,
    name: &str,
    arr: &ndarray::Array<T, D>,
) -> hdf5::Result<hdf5::Dataset> {
    match chunk_shape(arr.shape(), filter_size::<T>()) {
        Some(c) => g
            .new_dataset_builder()
            .with_data(arr)
            .chunk(c)
            .shuffle()
            .deflate(DEFLATE)
            .create(name),
        None => g.new_dataset_builder().with_data(arr).create(name),
    }
}

/// The chunk shape of a compressed dataset of `shape` with elements of `size` bytes: whole rows
/// (every dimension but the first kept whole), about [`CHUNK_BYTES`] of them; `None` for a
/// dataset of at most [`SMALL`] values, or of strings (`size` 0), stored as it is.
pub(crate) fn chunk_shape(shape: &[usize], size: usize) -> Option<Vec<usize>> {
    let n: usize = shape.iter().product();
    if n <= SMALL || size == 0 || shape.is_empty() {
        return None;
    }
    let row: usize = shape[1..].iter().product::<usize>().max(1) * size;
    let rows = (CHUNK_BYTES / row).clamp(1, shape[0].max(1));
    Some(
        std::iter::once(rows)
            .chain(shape[1..].iter().copied())
            .collect(),
    )
}

/// The chunk shape of a recording's dataset of `shape` ((samples) or (samples, columns)) with
/// elements of `size` bytes: one column of about [`CHUNK_BYTES`] samples, so that the shuffle
/// regroups the bytes of one quantity's component (measured on a 4-case study rounded by
/// quantity: 7 % smaller than chunks of whole rows, the same values); `None` as in
/// [`chunk_shape`].
pub(crate) fn column_chunks(shape: &[usize], size: usize) -> Option<Vec<usize>> {
    let mut c = chunk_shape(shape, size)?;
    if let [rows, w] = c.as_mut_slice() {
        *rows = (CHUNK_BYTES / size).clamp(1, shape[0].max(1));
        *w = 1;
    }
    Some(c)
}

/// The element size of `T` for [`chunk_shape`], 0 for a type the filters do not apply to
/// (variable-length strings).
fn filter_size<T: hdf5::H5Type>() -> usize {
    use hdf5::types::TypeDescriptor as TD;
    match T::type_descriptor() {
        d @ (TD::Integer(_) | TD::Unsigned(_) | TD::Float(_) | TD::Boolean) => d.size(),
        _ => 0,
    }
}

/// Writes a one-dimensional dataset with its unit (unless `None`) and description.
pub(crate) fn write_column<T: hdf5::H5Type + Clone>(
    g: &hdf5::Group,
    name: &str,
    data: &[T],
    unit: Option<&str>,
    desc: &str,
) -> hdf5::Result<()> {
    let arr = Array1::from(data.to_vec());
    let ds = create_filtered(g, name, &arr)?;
    describe(&ds, unit, desc)
}

/// Writes a one-dimensional dataset of strings with its description.
pub(crate) fn write_strings(
    g: &hdf5::Group,
    name: &str,
    data: &[String],
    desc: &str,
) -> hdf5::Result<()> {
    let data = data
        .iter()
        .map(|s| s.replace('\0', " ").parse::<VarLenUnicode>())
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| hdf5::Error::from(format!("{e:?}")))?;
    write_column(g, name, &data, None, desc)
}

/// Creates an f64 dataset of `shape` filled with NaN (values not computed yet), with its unit and
/// description.
pub(crate) fn create_nan(
    g: &hdf5::Group,
    name: &str,
    shape: &[usize],
    unit: &str,
    desc: &str,
) -> hdf5::Result<()> {
    create_nan_chunked(g, name, shape, usize::MAX, unit, desc)
}

/// [`create_nan`] whose chunks hold at most `cols` columns of a row: a row written block by block
/// while its job runs (its time histories) is written in whole chunks.
pub(crate) fn create_nan_chunked(
    g: &hdf5::Group,
    name: &str,
    shape: &[usize],
    cols: usize,
    unit: &str,
    desc: &str,
) -> hdf5::Result<()> {
    let b = g.new_dataset::<f64>().shape(shape).fill_value(f64::NAN);
    let ds = match chunk_shape(shape, 8) {
        // One row (one job) per chunk: a job's results are written, and compressed, at once;
        // time histories, written block by block while the job runs, in chunks of a block.
        Some(mut c) => {
            c[0] = 1;
            if let Some(w) = c.get_mut(1) {
                *w = (*w).min(cols);
            }
            b.chunk(c).shuffle().deflate(DEFLATE).create(name)?
        }
        None => b.create(name)?,
    };
    describe(&ds, Some(unit), desc)
}

/// Reads a string attribute.
pub(crate) fn read_str(loc: &hdf5::Location, name: &str) -> hdf5::Result<String> {
    Ok(loc.attr(name)?.read_scalar::<VarLenUnicode>()?.to_string())
}

/// Reads a scalar attribute of a number type.
pub(crate) fn read_attr<T: hdf5::H5Type>(loc: &hdf5::Location, name: &str) -> hdf5::Result<T> {
    loc.attr(name)?.read_scalar::<T>()
}

/// Reads a one-dimensional dataset of strings.
pub(crate) fn read_strings(g: &hdf5::Group, name: &str) -> hdf5::Result<Vec<String>> {
    Ok(g.dataset(name)?
        .read_1d::<VarLenUnicode>()?
        .iter()
        .map(|v| v.as_str().to_string())
        .collect())
}

/// Reads a dataset of f64 row by row (a one-dimensional dataset is one value per row).
pub(crate) fn read_rows(g: &hdf5::Group, name: &str) -> hdf5::Result<Vec<Vec<f64>>> {
    let ds = g.dataset(name)?;
    let cols = ds.shape().get(1).copied().unwrap_or(1).max(1);
    let raw = ds.read_raw::<f64>()?;
    Ok(raw.chunks(cols).map(<[f64]>::to_vec).collect())
}

/// Writes the attributes `unit` (unless `None`) and `description` of a dataset.
pub(crate) fn describe(ds: &hdf5::Dataset, unit: Option<&str>, desc: &str) -> hdf5::Result<()> {
    if let Some(u) = unit {
        str_attr(ds, "unit", u)?;
    }
    str_attr(ds, "description", desc)
}

/// Writes a two-dimensional dataset of `cols` columns from its values row by row.
pub(crate) fn write_table<T: hdf5::H5Type + Clone>(
    g: &hdf5::Group,
    name: &str,
    data: &[T],
    cols: usize,
    unit: &str,
    desc: &str,
) -> hdf5::Result<()> {
    let rows = data.len().checked_div(cols).unwrap_or(0);
    let arr = Array2::from_shape_vec((rows, cols), data.to_vec())
        .map_err(|e| hdf5::Error::from(e.to_string()))?;
    let ds = create_filtered(g, name, &arr)?;
    describe(&ds, Some(unit), desc)
}

/// A file written under the temporary name `<name>.h5.partial` and moved to `<name>.h5` only once
/// it is complete and closed.
pub(crate) struct PartialFile {
    pub file: hdf5::File,
    /// The file while it is written, `<name>.h5.partial` ([`crate::storage::durable::Unnamed::named`]).
    tmp: crate::storage::durable::Unnamed,
    path: PathBuf,
    /// One writer per output (crate::storage::lock), held until the file is in place.
    _lock: crate::storage::lock::Lock,
    /// Still in memory ([`create_streamed`]), not yet on disk.
    in_memory: bool,
}

/// The oldest HDF5 library the files written must open in (`jointplay --hdf5-format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// The oldest format: readable by HDF5 1.8 (and, for these files, 1.6).
    V18,
    /// The 1.10 format (the default): a dataset of one chunk stores it without an index, a fixed
    /// or growing one indexes its chunks with a fixed or extensible array instead of a B-tree, and
    /// object headers are smaller. About 0.5 KiB of metadata per dataset instead of 3.2 KiB
    /// (a study of 4 cases of the 4-UPS/RPU has 553 datasets).
    V110,
}

impl std::str::FromStr for Format {
    type Err = String;

    /// "1.10" or "1.8", as `--hdf5-format` and Python's `set_hdf5_format` take it.
    fn from_str(s: &str) -> std::result::Result<Format, String> {
        match s {
            "1.10" => Ok(Format::V110),
            "1.8" => Ok(Format::V18),
            other => Err(format!(
                "hdf5 format '{other}': one of \"1.10\" (the default) or \"1.8\""
            )),
        }
    }
}

/// [`Format`] of the files [`create_in_memory`] makes: 0 for 1.10, 1 for 1.8.
static FORMAT: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Sets the [`Format`] of every file written from now on, in this process.
pub fn set_format(format: Format) {
    let v = match format {
        Format::V110 => 0,
        Format::V18 => 1,
    };
    FORMAT.store(v, std::sync::atomic::Ordering::Relaxed);
}

/// The [`Format`] files are written in.
pub fn format() -> Format {
    match FORMAT.load(std::sync::atomic::Ordering::Relaxed) {
        0 => Format::V110,
        _ => Format::V18,
    }
}

/// Creates, in memory, the HDF5 file that a run streams its samples into, named `path` in
/// messages; [`PartialFile::materialize`] writes it to disk, whole, once its groups and empty
/// datasets are laid out, so that a run killed while HDF5 lays out a new file leaves none.
///
/// It is in the 1.8 format whatever the [`format`] set: its superblock (version 0) has no "open
/// for writing" flag, which the 1.10 format's keeps set while a writer holds the file and which a
/// process killed leaves set, so that HDF5 1.10 and later refuse the file.
///
/// While the run goes, its blocks of samples are appended as chunks written beyond the file's
/// recorded end, and the file is not flushed: HDF5 updates its metadata (chunk indexes, dataset
/// extents, the superblock's end of file) in place and in no particular order, so that a process
/// killed while a flush writes them leaves a file that does not open (seen in the crash tests
/// when the file was flushed after every block). Unflushed, the file on disk keeps the layout
/// written whole at its start, and a run killed by SIGKILL leaves a `.partial` that opens, with
/// the samples that HDF5 happened to write out (often none). The one flush is the close at the
/// run's end, or at a stop on SIGINT or SIGTERM, which writes a complete file (`complete` = 0
/// for a stop). The cost of the 1.8 format, its larger object headers and B-tree chunk indexes,
/// is measured in book/src/explanation/durability.md.
pub(crate) fn create_streamed(path: &Path) -> Result<hdf5::File> {
    hdf5::File::with_options()
        .with_fapl(|p| p.libver_earliest().core_options(1 << 20, false))
        .create(unique(path))
        .map_err(h5err(path))
}

/// A file of the [`format`] set held in memory (HDF5's core driver, nothing written to disk),
/// named `label` (its name in HDF5's messages); its bytes come out with [`image`]. The small and
/// middle-sized files that must be whole or absent are built so and written by
/// [`crate::storage::durable::write_new`].
pub(crate) fn create_in_memory(label: &Path) -> hdf5::Result<hdf5::File> {
    hdf5::File::with_options()
        .with_fapl(|p| {
            match format() {
                Format::V110 => p.libver_v110(),
                Format::V18 => p.libver_earliest(),
            };
            p.core_options(1 << 20, false)
        })
        .create(unique(label))
}

/// The file `path` read into memory to be changed there ([`create_in_memory`]).
pub(crate) fn open_in_memory(path: &Path) -> hdf5::Result<hdf5::File> {
    hdf5::File::with_options()
        .with_fapl(|p| p.core_options(1 << 20, false))
        .open_rw(path)
}

/// `label` made unique among the files this process has open in memory.
fn unique(label: &Path) -> PathBuf {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    crate::storage::durable::with_suffix(label, &format!(".in-memory-{n}"))
}

/// The bytes of the file `file` as they would be on disk (flushed first).
pub(crate) fn image(file: &hdf5::File) -> hdf5::Result<Vec<u8>> {
    use hdf5_sys::h5f::H5Fget_file_image;
    file.flush()?;
    let id = file.id();
    // Under the crate's lock, as every HDF5 call of the `hdf5` crate: the library is not safe to
    // call from two threads at once.
    hdf5::sync::sync(|| {
        // SAFETY: a null buffer asks for the size only; the second call writes at most `len`
        // bytes into a buffer of that length.
        let len = unsafe { H5Fget_file_image(id, std::ptr::null_mut(), 0) };
        if len < 0 {
            return Err("cannot take the file's image".into());
        }
        let mut buf = vec![0u8; len as usize];
        let got = unsafe { H5Fget_file_image(id, buf.as_mut_ptr().cast(), buf.len()) };
        if got != len {
            return Err("cannot take the file's image".into());
        }
        Ok(buf)
    })
}

/// The root attributes of every file the program writes: `program`, `program_version`, `units`.
fn root_attrs(file: &hdf5::File, program_version: &str) -> hdf5::Result<()> {
    str_attr(file, "program", "jointplay")?;
    str_attr(file, "program_version", program_version)?;
    str_attr(file, "units", "SI: m, kg, s, rad, N, N m, J")
}

impl PartialFile {
    /// Creates `dir/<name>.h5.partial` ([`create_streamed`]) with the program's root attributes.
    pub fn create(dir: &Path, name: &str, program_version: &str) -> Result<PartialFile> {
        crate::storage::durable::create_dir(dir)?;
        let path = dir.join(format!("{name}.h5"));
        let lock = crate::storage::lock::Lock::acquire(&path)?;
        let tmp = crate::storage::durable::Unnamed::named(&path);
        let file = create_streamed(tmp.path())?;
        let out = PartialFile {
            file,
            tmp,
            path,
            _lock: lock,
            in_memory: true,
        };
        match root_attrs(&out.file, program_version) {
            Ok(()) => Ok(out),
            Err(err) => Err(out.fail(err)),
        }
    }

    /// The temporary name, for errors.
    pub fn partial(&self) -> &Path {
        self.tmp.name()
    }

    /// Writes the file, built in memory so far, to disk under its temporary name, whole, and
    /// goes on with it there (handles into the file must be opened again). Nothing when it is
    /// on disk already.
    pub fn materialize(&mut self) -> Result<()> {
        if !self.in_memory {
            return Ok(());
        }
        let e = h5err(self.tmp.name());
        let bytes = image(&self.file).map_err(&e)?;
        crate::storage::durable::write_new(self.tmp.path(), &bytes)?;
        let on_disk = hdf5::File::open_rw(self.tmp.path()).map_err(&e)?;
        let in_memory = std::mem::replace(&mut self.file, on_disk);
        self.in_memory = false;
        in_memory.close().map_err(&e)
    }

    /// Closes the file and gives it its name, durably; on an error it is discarded.
    pub fn finish(mut self) -> Result<PathBuf> {
        self.materialize()?;
        let PartialFile {
            file,
            tmp,
            path,
            _lock,
            ..
        } = self;
        if let Err(err) = file.close() {
            return Err(h5err(tmp.name())(err));
        }
        tmp.persist(&path)?;
        Ok(path)
    }

    /// Closes and discards the file.
    pub fn discard(self) {
        let _ = self.file.close();
    }

    /// [`PartialFile::discard`] after `err`, which it returns naming the file.
    pub fn fail(self, err: hdf5::Error) -> Error {
        let err = h5err(self.partial())(err);
        self.discard();
        err
    }
}

/// Writes `dir/<name>.h5`, whole or not at all: the program's root attributes and then `body`
/// into a file held in memory ([`create_in_memory`]), whose bytes are then written under no name,
/// forced to disk and renamed into place ([`crate::storage::durable::write_new`]). A kill at any
/// moment leaves the earlier file of the name, or the new one, and nothing else.
pub(crate) fn write_atomically(
    dir: &Path,
    name: &str,
    program_version: &str,
    body: impl FnOnce(&hdf5::File) -> hdf5::Result<()>,
) -> Result<PathBuf> {
    crate::storage::durable::create_dir(dir)?;
    let path = dir.join(format!("{name}.h5"));
    let _lock = crate::storage::lock::Lock::acquire(&path)?;
    let label = crate::storage::durable::with_suffix(&path, ".partial");
    let e = h5err(&label);
    let file = create_in_memory(&label).map_err(&e)?;
    root_attrs(&file, program_version)
        .and_then(|()| body(&file))
        .map_err(&e)?;
    let bytes = image(&file).map_err(&e)?;
    file.close().map_err(&e)?;
    crate::storage::durable::write_new(&path, &bytes)?;
    Ok(path)
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
    crate::hybrid::write_state(file, &run.final_state)
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
/// The chunks of the compressed datasets are compressed by [`crate::chunk`], by the threads of
/// rayon's pool (a recording is written whole once its run is over).
fn write_recording(g: &hdf5::Group, rec: &Recording) -> hdf5::Result<()> {
    use crate::chunk::Store;
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
fn store(c: &Channel) -> crate::chunk::Store {
    match c.flag {
        true => crate::chunk::Store::Flag,
        false => crate::chunk::Store::F64(c.bits),
    }
}

/// A dataset for [`write_sets`]: its values (whole rows of `width`; one-dimensional when
/// `scalar`), how it stores them, its unit and description.
struct NewSet<'a> {
    name: &'a str,
    values: &'a [f64],
    width: usize,
    scalar: bool,
    store: crate::chunk::Store,
    unit: &'a str,
    desc: &'a str,
}

/// Creates and writes the datasets `sets` in `g`, described: those [`column_chunks`] chunks with
/// their chunks compressed by [`crate::chunk`] (by the threads of rayon's pool) and written as
/// they are, the others (of at most [`SMALL`] values) stored as they are.
fn write_sets(g: &hdf5::Group, sets: &[NewSet<'_>]) -> hdf5::Result<()> {
    use crate::chunk::{Rows, Store, append_all};
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
                let v = crate::bitround::rounded(s.values, bits).into_owned();
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

/// The `significant_bits` attribute of a file's (or a run's) group and of its rounded datasets;
/// nothing for `None` (every bit kept).
pub(crate) fn mark_bits(loc: &hdf5::Location, bits: Option<u32>) -> hdf5::Result<()> {
    match bits {
        Some(b) => u64_attr(loc, "significant_bits", u64::from(b)),
        None => Ok(()),
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

/// Creates an empty extendable dataset of `width` columns (one-dimensional when `scalar`),
/// compressed in chunks of `rows` samples of one column ([`column_chunks`]), each appended whole.
pub(crate) fn create_extendable<T: hdf5::H5Type>(
    g: &hdf5::Group,
    name: &str,
    width: usize,
    scalar: bool,
    rows: usize,
) -> hdf5::Result<hdf5::Dataset> {
    // No chunk cache: every append writes whole chunks, straight to the file. (HDF5 gives every
    // open dataset a cache of 1 MiB by default; with the hundreds of datasets of a mechanism's
    // run held open, the caches alone would hold a few hundred MB.)
    let b = g.new_dataset::<T>().chunk_cache(0, 0, 1.0);
    if scalar {
        b.shape(0..)
            .chunk(rows)
            .shuffle()
            .deflate(DEFLATE)
            .create(name)
    } else {
        b.shape((0.., width))
            .chunk((rows, 1))
            .shuffle()
            .deflate(DEFLATE)
            .create(name)
    }
}

/// [`create_extendable`] in chunks of [`STREAM_ROWS`] samples, described.
fn extendable<T: hdf5::H5Type>(
    g: &hdf5::Group,
    name: &str,
    width: usize,
    scalar: bool,
    unit: &str,
    desc: &str,
) -> hdf5::Result<hdf5::Dataset> {
    let ds = create_extendable::<T>(g, name, width, scalar, STREAM_ROWS)?;
    describe(&ds, Some(unit), desc)?;
    Ok(ds)
}

/// Appends `rows` samples of `values` (`width` per sample) to `ds` after its first `from` rows.
pub(crate) fn append<T: hdf5::H5Type>(
    ds: &hdf5::Dataset,
    from: usize,
    rows: usize,
    width: usize,
    scalar: bool,
    values: Vec<T>,
) -> hdf5::Result<()> {
    if scalar {
        ds.resize(from + rows)?;
        ds.write_slice(&Array1::from(values), s![from..from + rows])
    } else {
        ds.resize((from + rows, width))?;
        let arr = Array2::from_shape_vec((rows, width), values)
            .map_err(|e| hdf5::Error::from(e.to_string()))?;
        ds.write_slice(&arr, s![from..from + rows, ..])
    }
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
    /// flushes the file. The chunks are compressed by `crate::chunk` (by the threads of
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
                        let v = crate::bitround::rounded(&c.values, c.bits).into_owned();
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
    /// every dataset extended, its chunks compressed by [`crate::chunk`] and written as they are.
    fn append_packed(&self, rec: &Recording, from: usize, parallel: bool) -> hdf5::Result<()> {
        use crate::chunk::{Rows, Store, append_all};
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

/// One component of a recorded dataset with its time axis, for comparing runs.
#[derive(Debug, Clone)]
pub struct SeriesData {
    pub time: Vec<f64>,
    pub values: Vec<f64>,
    pub unit: String,
    pub scene_name: String,
}

/// Reads column `component` of `dataset` (1-D datasets ignore it) and `/time` from a run file.
pub fn read_series(path: &Path, dataset: &str, component: usize) -> Result<SeriesData> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let time = file
        .dataset("time")
        .map_err(&e)?
        .read_raw::<f64>()
        .map_err(&e)?;
    let ds = file.dataset(dataset).map_err(|err| Error::Hdf5 {
        file: path.to_path_buf(),
        message: format!("no dataset '{dataset}': {err}"),
    })?;
    let shape = ds.shape();
    let raw = ds.read_raw::<f64>().map_err(&e)?;
    let values = match shape.as_slice() {
        [_] => raw,
        [n, m] => {
            if component >= *m {
                return Err(Error::Hdf5 {
                    file: path.to_path_buf(),
                    message: format!(
                        "'{dataset}' has {m} components; component {component} does not exist"
                    ),
                });
            }
            (0..*n).map(|i| raw[i * m + component]).collect()
        }
        _ => {
            return Err(Error::Hdf5 {
                file: path.to_path_buf(),
                message: format!("'{dataset}' has shape {shape:?}; expected one or two dimensions"),
            });
        }
    };
    Ok(SeriesData {
        unit: read_str(&ds, "unit").unwrap_or_default(),
        scene_name: read_str(&file, "scene_name").unwrap_or_default(),
        time,
        values,
    })
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
