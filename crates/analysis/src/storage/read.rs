//! Any HDF5 file the program writes, read generically (what the Python package's `H5` shows):
//! every dataset by its path, every dataset's unit, the scalar attributes of the file, a group or
//! a dataset, and a dataset's values as numbers (float64, with its shape) or text.

use std::path::{Path, PathBuf};

use hdf5::types::{TypeDescriptor, VarLenUnicode};

use crate::Result;
use crate::storage::h5::h5err;

/// A scalar attribute's value (attributes of other types are not read).
#[derive(Debug, Clone, PartialEq)]
pub enum Attr {
    Text(String),
    Float(f64),
    Integer(i64),
}

/// A dataset's values.
#[derive(Debug, Clone, PartialEq)]
pub enum Data {
    /// Text, one string per element.
    Text(Vec<String>),
    /// Numbers as float64, in row-major order, with the dataset's shape.
    Numbers { shape: Vec<usize>, values: Vec<f64> },
}

/// An HDF5 file written by the program, opened again for every read.
#[derive(Debug, Clone)]
pub struct Reader {
    path: PathBuf,
}

impl Reader {
    /// The reader of `path`, which must open as an HDF5 file.
    pub fn open(path: &Path) -> Result<Reader> {
        let r = Reader::new(path);
        r.file()?;
        Ok(r)
    }

    /// The reader of `path`, opened at the first read (a file just written).
    pub fn new(path: &Path) -> Reader {
        Reader {
            path: path.to_path_buf(),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn file(&self) -> Result<hdf5::File> {
        hdf5::File::open(&self.path).map_err(h5err(&self.path))
    }

    /// Every dataset's path, a group's datasets before its groups
    /// (`cases/ideal/bodies/platform/position`).
    pub fn datasets(&self) -> Result<Vec<String>> {
        let f = self.file()?;
        let mut out = Vec::new();
        walk(&f, "", &mut out).map_err(h5err(&self.path))?;
        Ok(out.into_iter().map(|d| d.0).collect())
    }

    /// The scalar attributes of the root (`None`), or of the group or dataset at `path`; None
    /// when there is nothing at `path`.
    pub fn attributes(&self, path: Option<&str>) -> Result<Option<Vec<(String, Attr)>>> {
        let f = self.file()?;
        let e = h5err(&self.path);
        let Some(path) = path else {
            return attrs(&f).map(Some).map_err(e);
        };
        if let Ok(d) = f.dataset(path) {
            return attrs(&d).map(Some).map_err(e);
        }
        match f.group(path) {
            Ok(g) => attrs(&g).map(Some).map_err(e),
            Err(_) => Ok(None),
        }
    }

    /// The SI unit of every dataset that states one (its `unit` attribute).
    pub fn units(&self) -> Result<Vec<(String, String)>> {
        let f = self.file()?;
        let mut all = Vec::new();
        walk(&f, "", &mut all).map_err(h5err(&self.path))?;
        Ok(all
            .into_iter()
            .filter_map(|(p, ds)| {
                let u = ds.attr("unit").ok()?.read_scalar::<VarLenUnicode>().ok()?;
                Some((p, u.as_str().to_string()))
            })
            .collect())
    }

    /// Whether the file has a dataset at `path`.
    pub fn contains(&self, path: &str) -> Result<bool> {
        Ok(self.file()?.dataset(path).is_ok())
    }

    /// The dataset at `path`: text as strings, numbers as float64; None when there is none.
    pub fn dataset(&self, path: &str) -> Result<Option<Data>> {
        let f = self.file()?;
        let Ok(ds) = f.dataset(path) else {
            return Ok(None);
        };
        let bad = |e: hdf5::Error| crate::Error::Io {
            file: self.path.clone(),
            message: format!("{path}: {e}"),
        };
        Ok(Some(
            match ds.dtype().and_then(|t| t.to_descriptor()).map_err(bad)? {
                TypeDescriptor::VarLenUnicode => Data::Text(
                    ds.read_raw::<VarLenUnicode>()
                        .map_err(bad)?
                        .iter()
                        .map(|s| s.as_str().to_string())
                        .collect(),
                ),
                _ => Data::Numbers {
                    shape: ds.shape(),
                    values: ds.read_raw::<f64>().map_err(bad)?,
                },
            },
        ))
    }
}

fn attrs(loc: &hdf5::Location) -> hdf5::Result<Vec<(String, Attr)>> {
    let mut out = Vec::new();
    for n in loc.attr_names()? {
        let a = loc.attr(&n)?;
        if !a.is_scalar() {
            continue;
        }
        let v = match a.dtype()?.to_descriptor()? {
            TypeDescriptor::VarLenUnicode => {
                Attr::Text(a.read_scalar::<VarLenUnicode>()?.as_str().to_string())
            }
            TypeDescriptor::Float(_) => Attr::Float(a.read_scalar::<f64>()?),
            TypeDescriptor::Unsigned(_) | TypeDescriptor::Integer(_) => {
                Attr::Integer(a.read_scalar::<i64>()?)
            }
            _ => continue,
        };
        out.push((n, v));
    }
    Ok(out)
}

fn walk(g: &hdf5::Group, prefix: &str, out: &mut Vec<(String, hdf5::Dataset)>) -> hdf5::Result<()> {
    for ds in g.datasets()? {
        let name = ds.name();
        let short = name.rsplit('/').next().unwrap_or(&name).to_string();
        out.push((format!("{prefix}{short}"), ds));
    }
    for sub in g.groups()? {
        let name = sub.name();
        let short = name.rsplit('/').next().unwrap_or(&name).to_string();
        walk(&sub, &format!("{prefix}{short}/"), out)?;
    }
    Ok(())
}
