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
//! `significant_bits` asks for is rounded before, by [`crate::storage::bitround`], and marked with the
//! attribute `significant_bits`.) The chunks of a run's recording (streamed by [`RunWriter`](crate::storage::run_file::RunWriter) or
//! written whole by [`write_run`](crate::storage::run_file::write_run) and [`write_study`](crate::storage::run_file::write_study)), and those of a single analysis run's
//! histories, are shuffled and deflated by
//! `crate::storage::chunk`, with libdeflate and on several threads where nothing else runs, and written
//! as they are; every other dataset goes through HDF5's own filters (zlib). The chunks are in
//! the format of the declared filters either way, and decompress to the same values. Chunks hold about [`CHUNK_BYTES`] (a recording's datasets one
//! column at a time, `column_chunks`; other tables whole rows; a sweep's history rows chunked
//! by the block its jobs write them in; a streamed recording's chunks hold [`STREAM_ROWS`]
//! samples of a column), small enough
//! that reading one column of a long recording decompresses little beyond it, large enough that
//! the per-chunk index and deflate's start-up cost stay negligible. Datasets of strings are not
//! compressed (their values live on the file's heap, out of the filters' reach).
//!
//! **Streaming.** A run file can be written while the run goes ([`RunWriter`](crate::storage::run_file::RunWriter)): its datasets
//! are created empty and extendable, and every [`STREAM_ROWS`] samples are appended as one chunk
//! each (not flushed until the close: see `create_streamed`), so a run's memory does not grow
//! with its length; the attributes known only
//! at the end (statistics, `complete`, the final state) are written when it ends.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;
use ndarray::{Array1, Array2, s};

use crate::{Error, Result};

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
pub(crate) fn attr_set<T: hdf5::H5Type>(
    loc: &hdf5::Location,
    name: &str,
    v: T,
) -> hdf5::Result<()> {
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
pub const CHUNK_BYTES: usize = crate::measures::sections::HISTORY_BLOCK * 8;

/// Deflate level after the shuffle filter, of zlib (HDF5's filter) and of libdeflate
/// (`crate::storage::chunk`) alike. Level 4 is the middle of zlib's range. On a 6 s run of the mixed
/// 4-UPS/RPU (DOPRI5, 1 ms output) zlib's level 1 made the file 0.8 % larger and took the same
/// share of the run's time (about 16 %, by `perf`): recorded trajectories compress little either
/// way. On a 10 s run's chunks libdeflate's levels 1, 4 and 6 gave 1.357, 1.382 and 1.385 times
/// smaller in 179, 248 and 273 ms (zlib's level 4: 1.374 in 527 ms).
pub const DEFLATE: u8 = 4;

/// Samples a streamed run file appends at once: one chunk of each column of every dataset.
pub const STREAM_ROWS: usize = 2048;

/// Creates dataset `name` in `g` holding `arr`: chunked, shuffled and deflated when
/// [`chunk_shape`] finds it large enough, contiguous otherwise.
pub(crate) fn create_filtered<T: hdf5::H5Type, D: ndarray::Dimension>(
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
pub(crate) fn filter_size<T: hdf5::H5Type>() -> usize {
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
pub(crate) fn unique(label: &Path) -> PathBuf {
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
pub(crate) fn root_attrs(file: &hdf5::File, program_version: &str) -> hdf5::Result<()> {
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

/// The `significant_bits` attribute of a file's (or a run's) group and of its rounded datasets;
/// nothing for `None` (every bit kept).
pub(crate) fn mark_bits(loc: &hdf5::Location, bits: Option<u32>) -> hdf5::Result<()> {
    match bits {
        Some(b) => u64_attr(loc, "significant_bits", u64::from(b)),
        None => Ok(()),
    }
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
pub(crate) fn extendable<T: hdf5::H5Type>(
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
