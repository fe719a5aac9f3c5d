//! A run's recorded datasets exported for spreadsheets (CSV) and MATLAB (MAT, level 5).
//!
//! What is exported is a run: a run file, or one case of a comparison study's file
//! (`cases/<label>/`). Its sample times and every dataset with one row per sample (the final
//! state and the file's other records are not samples), or only the datasets asked for.
//!
//! * **CSV**: one table, a row per sample. The header names each column by its observable path
//!   with its SI unit, `bodies.crank.position.x [m]`, after `time [s]`; the values are written
//!   in the shortest decimal form that reads back to the same double, so nothing is rounded.
//! * **MAT**: MATLAB's level-5 format (MathWorks, *MAT-File Format*, R2024a, "Level 5 MAT-File
//!   Format"), written here: the subset needed (double and char matrices and one level of
//!   struct) is short, and the crates that write MAT files either bind the C library libmatio
//!   (`matio-rs`: a system library and a build step more) or are young (`matrw`); the Python
//!   tests read the files back with `scipy.io.loadmat`. One double matrix per dataset, named by its path with `/` as `_`
//!   (`bodies_crank_position`, n x 3), `time` (n x 1), and two structs with a field per
//!   variable: `units` (the SI unit) and `columns` (the observable path of each column, one row
//!   of a char matrix per column). `load` reads it in MATLAB and Octave, `scipy.io.loadmat` in
//!   Python. Level 5 holds variables below 2 GB each; a larger one is an error that says so.
//!
//! Column names come from the scene the run file holds (its `scene` attribute), compiled again
//! to declare its recording; a column the scene does not declare (a file of another version of
//! the program) is named `<dataset>[k]`.

use std::path::{Path, PathBuf};

use crate::Result;
use crate::storage::read::{Attr, Data, Reader};

/// The export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Csv,
    Mat,
}

impl Format {
    pub fn extension(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Mat => "mat",
        }
    }
}

/// One exported dataset: its path in the run, unit, column names and values (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    pub dataset: String,
    pub unit: String,
    pub names: Vec<String>,
    pub values: Vec<f64>,
}

/// A run's samples, ready to export.
#[derive(Debug, Clone, PartialEq)]
pub struct Samples {
    pub time: Vec<f64>,
    pub datasets: Vec<Column>,
}

fn invalid(path: &Path, message: String) -> crate::Error {
    crate::Error::Io {
        file: path.to_path_buf(),
        message,
    }
}

/// The samples of the run in `file` (or of its case `case`, for a comparison study's file),
/// limited to `only` when that names datasets (their paths in the run, `bodies/crank/position`).
pub fn read(file: &Path, case: Option<&str>, only: &[String]) -> Result<Samples> {
    let r = Reader::open(file)?;
    let all = r.datasets()?;
    let prefix = run_prefix(file, &all, case)?;
    let names = scene_model(&r, &prefix)
        .map(|m| declared(&m))
        .unwrap_or_default();
    samples(&r, &all, &prefix, only, true, &names)
}

/// The group of `file` that holds a run: "" for a run file, `cases/<case>/` for a case of a
/// comparison study; anything else is an error saying which file or option fits.
fn run_prefix(file: &Path, all: &[String], case: Option<&str>) -> Result<String> {
    let cases: Vec<&str> = all
        .iter()
        .filter_map(|d| d.strip_prefix("cases/")?.strip_suffix("/time"))
        .collect();
    Ok(
        match (case, all.iter().any(|d| d == "time"), cases.is_empty()) {
            (None, true, _) => String::new(),
            (Some(c), _, false) => {
                if !cases.contains(&c) {
                    return Err(invalid(
                        file,
                        format!("no case '{c}'; the study's cases: {}", cases.join(", ")),
                    ));
                }
                format!("cases/{c}/")
            }
            (None, _, false) => {
                return Err(invalid(
                    file,
                    format!(
                        "a comparison study's file: choose a case with --case ({})",
                        cases.join(", ")
                    ),
                ));
            }
            (Some(_), true, true) => {
                return Err(invalid(
                    file,
                    "a run's file has no cases: leave out --case".into(),
                ));
            }
            (_, false, true) => {
                return Err(invalid(
                    file,
                    "not a run's file (it has no samples, no /time): an analysis study's table is \
                 `jointplay report FILE`, its figures `jointplay plot FILE`, the motion of one \
                 of its sweep values `jointplay animate FILE --value V`, of a periodic orbit \
                 `jointplay animate FILE --orbit BRANCH:POINT`"
                        .into(),
                ));
            }
        },
    )
}

/// A run of a file, read for drawing: its compiled scene and the samples of the datasets
/// `wanted` that it holds (a dataset it lacks is left out, not an error).
pub struct Run {
    pub model: jointplay_solver::model::Model,
    pub samples: Samples,
}

/// The run in `file` (or its case `case`) with its scene compiled again, and those of the
/// datasets `wanted(model)` names that it holds. A file whose scene this program cannot compile
/// is an error that says so.
pub fn read_run(
    file: &Path,
    case: Option<&str>,
    wanted: impl FnOnce(&jointplay_solver::model::Model) -> Vec<String>,
) -> Result<Run> {
    let r = Reader::open(file)?;
    let all = r.datasets()?;
    let prefix = run_prefix(file, &all, case)?;
    let model = scene_model(&r, &prefix).map_err(|m| invalid(file, m))?;
    let only: Vec<String> = wanted(&model)
        .into_iter()
        .filter(|d| all.iter().any(|a| *a == format!("{prefix}{d}")))
        .collect();
    if only.is_empty() {
        return Err(invalid(
            file,
            "the run records none of the datasets needed".into(),
        ));
    }
    let samples = samples(&r, &all, &prefix, &only, false, &declared(&model))?;
    Ok(Run { model, samples })
}

/// The samples of the run under `prefix`: every dataset with a row per sample, or those of
/// `only`; with `strict`, one of `only` the run does not hold is an error. `names` are the
/// column names its scene declares ([`declared`]).
fn samples(
    r: &Reader,
    all: &[String],
    prefix: &str,
    only: &[String],
    strict: bool,
    names: &[(String, Vec<String>)],
) -> Result<Samples> {
    let file = r.path();
    let numbers = |path: &str| -> Result<(Vec<usize>, Vec<f64>)> {
        match r.dataset(path)? {
            Some(Data::Numbers { shape, values }) => Ok((shape, values)),
            _ => Err(invalid(file, format!("{path}: not a numeric dataset"))),
        }
    };
    let (_, time) = numbers(&format!("{prefix}time"))?;
    let n = time.len();
    let units: std::collections::HashMap<String, String> = r.units()?.into_iter().collect();
    let mut datasets = Vec::new();
    for full in all {
        let Some(d) = full.strip_prefix(prefix) else {
            continue;
        };
        if d == "time" || d.starts_with("final_") || d.starts_with("cases/") {
            continue;
        }
        if !only.is_empty() && !only.iter().any(|o| o == d) {
            continue;
        }
        let Ok((shape, values)) = numbers(full) else {
            continue;
        };
        if shape.first() != Some(&n) || shape.len() > 2 {
            continue;
        }
        let width = shape.get(1).copied().unwrap_or(1);
        let names = match names
            .iter()
            .find(|(ds, cols)| ds == d && cols.len() == width)
        {
            Some((_, cols)) => cols.clone(),
            None if shape.len() == 1 => vec![d.replace('/', ".")],
            None => (0..width).map(|k| format!("{d}[{k}]")).collect(),
        };
        datasets.push(Column {
            dataset: d.to_string(),
            unit: units.get(full).cloned().unwrap_or_default(),
            names,
            values,
        });
    }
    if let Some(missing) = only
        .iter()
        .find(|o| strict && !datasets.iter().any(|c| &c.dataset == *o))
    {
        return Err(invalid(
            file,
            format!(
                "no dataset '{missing}' with a row per sample in this run (datasets: {})",
                datasets_of(all, prefix)
            ),
        ));
    }
    Ok(Samples { time, datasets })
}

/// The run's sampled dataset paths, for an error message.
fn datasets_of(all: &[String], prefix: &str) -> String {
    all.iter()
        .filter_map(|d| d.strip_prefix(prefix))
        .filter(|d| *d != "time" && !d.starts_with("final_") && !d.starts_with("cases/"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The observable path of every column of every dataset `model` records (empty when its
/// recording cannot be declared).
fn declared(model: &jointplay_solver::model::Model) -> Vec<(String, Vec<String>)> {
    let Ok(rec) = crate::storage::run::Recording::of(model) else {
        return Vec::new();
    };
    rec.channels
        .iter()
        .map(|c| {
            (
                c.dataset.clone(),
                c.columns.iter().map(|o| o.path.clone()).collect(),
            )
        })
        .collect()
}

/// The scene of the run under `prefix` (its `scene` and `scene_file` attributes), compiled
/// again; why not, when it cannot be.
fn scene_model(
    r: &Reader,
    prefix: &str,
) -> std::result::Result<jointplay_solver::model::Model, String> {
    let group = prefix.strip_suffix('/');
    let attrs = match r.attributes(group) {
        Ok(Some(a)) => a,
        Ok(None) => return Err("the run's group has no attributes".into()),
        Err(e) => return Err(e.to_string()),
    };
    let text = |name: &str| {
        attrs.iter().find_map(|(n, v)| match v {
            Attr::Text(t) if n == name => Some(t.clone()),
            _ => None,
        })
    };
    let (Some(scene), Some(file)) = (text("scene"), text("scene_file")) else {
        return Err(
            "the run holds no scene (no `scene` attribute): not a file `jointplay run` wrote"
                .into(),
        );
    };
    let path = PathBuf::from(file);
    let spec = jointplay_solver::scene::SceneSpec::parse(&scene, &path)
        .map_err(|e| format!("its scene does not parse with this version of the program: {e}"))?;
    let scene = jointplay_solver::scene::SceneFile {
        path,
        spec,
        text: scene,
    };
    let (model, _) = jointplay_solver::model::Model::compile(&scene)
        .map_err(|e| format!("its scene does not compile with this version of the program: {e}"))?;
    Ok(model)
}

/// Writes `samples` as `target` in `format`, whole or not at all.
pub fn write(samples: &Samples, format: Format, target: &Path) -> Result<()> {
    let bytes = match format {
        Format::Csv => csv(samples).map_err(|m| invalid(target, m))?.into_bytes(),
        Format::Mat => mat(samples).map_err(|m| invalid(target, m))?,
    };
    crate::storage::durable::write_new(target, &bytes)
}

/// Whether every dataset has one row of its width per sample (what [`read`] gives).
fn consistent(samples: &Samples) -> bool {
    samples
        .datasets
        .iter()
        .all(|c| c.values.len() == samples.time.len() * c.names.len())
}

/// The CSV text of `samples`.
pub fn csv(samples: &Samples) -> Result<String, String> {
    if !consistent(samples) {
        return Err("a dataset's values do not fill its rows".into());
    }
    let quote = |s: String| {
        if s.contains([',', '"']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s
        }
    };
    let mut out = String::from("time [s]");
    for c in &samples.datasets {
        for name in &c.names {
            out.push(',');
            out.push_str(&quote(format!("{name} [{}]", c.unit)));
        }
    }
    out.push('\n');
    for (i, t) in samples.time.iter().enumerate() {
        out.push_str(&number(*t));
        for c in &samples.datasets {
            let w = c.names.len();
            for v in &c.values[i * w..(i + 1) * w] {
                out.push(',');
                out.push_str(&number(*v));
            }
        }
        out.push('\n');
    }
    Ok(out)
}

/// `v` in the shortest decimal form that reads back to the same double: plain between 1e-4 and
/// 1e15, with an exponent outside (Rust's float formatting is shortest round-trip in both).
fn number(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 || (1e-4..1e15).contains(&a) || !v.is_finite() {
        v.to_string()
    } else {
        format!("{v:e}")
    }
}

// The level-5 data types and array classes used (MAT-File Format, tables 1-2 and 1-3).
const MI_INT8: u32 = 1;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_DOUBLE: u32 = 9;
const MI_MATRIX: u32 = 14;
const MX_STRUCT: u8 = 2;
const MX_CHAR: u8 = 4;
const MX_DOUBLE: u8 = 6;

/// One data element: its tag (type, byte count) and data, padded to 8 bytes.
fn element(out: &mut Vec<u8>, kind: u32, data: &[u8]) {
    out.extend_from_slice(&kind.to_le_bytes());
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
    out.resize(out.len().next_multiple_of(8), 0);
}

/// A matrix element: flags, dimensions, name, then `body` (its data subelements).
fn matrix(class: u8, dims: [usize; 2], name: &str, body: &[u8]) -> Result<Vec<u8>, String> {
    let mut m = Vec::new();
    let mut flags = [0u8; 8];
    flags[0] = class;
    element(&mut m, MI_UINT32, &flags);
    let mut d = Vec::new();
    for x in dims {
        let x =
            i32::try_from(x).map_err(|_| format!("'{name}': {x} rows is beyond MAT level 5"))?;
        d.extend_from_slice(&x.to_le_bytes());
    }
    element(&mut m, MI_INT32, &d);
    element(&mut m, MI_INT8, name.as_bytes());
    m.extend_from_slice(body);
    let mut out = Vec::new();
    // MATLAB reads a variable's byte count as a signed 32-bit number: below 2 GB.
    let len = i32::try_from(m.len()).map_err(|_| {
        format!("'{name}' needs {} bytes; MAT level 5 holds less than 2 GB per variable: export fewer datasets (--dataset) or use the HDF5 file", m.len())
    })?;
    out.extend_from_slice(&MI_MATRIX.to_le_bytes());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(&m);
    Ok(out)
}

/// A double matrix of `rows` x `cols` from row-major `values` (MAT is column-major).
fn doubles(name: &str, rows: usize, cols: usize, values: &[f64]) -> Result<Vec<u8>, String> {
    let mut data = Vec::with_capacity(8 * values.len());
    for j in 0..cols {
        for i in 0..rows {
            data.extend_from_slice(&values[i * cols + j].to_le_bytes());
        }
    }
    let mut body = Vec::new();
    element(&mut body, MI_DOUBLE, &data);
    matrix(MX_DOUBLE, [rows, cols], name, &body)
}

/// A char matrix, one row per string, padded with spaces (MATLAB's `char` of several strings).
fn chars(name: &str, rows: &[String]) -> Result<Vec<u8>, String> {
    let rows: Vec<Vec<u16>> = rows.iter().map(|s| s.encode_utf16().collect()).collect();
    let width = rows.iter().map(Vec::len).max().unwrap_or(0);
    let mut data = Vec::new();
    for j in 0..width {
        for r in &rows {
            data.extend_from_slice(&r.get(j).copied().unwrap_or(u16::from(b' ')).to_le_bytes());
        }
    }
    let mut body = Vec::new();
    element(&mut body, MI_UINT16, &data);
    matrix(MX_CHAR, [rows.len(), width], name, &body)
}

/// A 1 x 1 struct of `fields` (name, value matrix without a name).
fn structure(name: &str, fields: &[(String, Vec<u8>)]) -> Result<Vec<u8>, String> {
    let width = fields.iter().map(|(n, _)| n.len() + 1).max().unwrap_or(1);
    let mut body = Vec::new();
    // The field-name length in the small data element form MATLAB writes: the byte count in
    // the tag's upper half and the 4 bytes of data in its second word.
    body.extend_from_slice(&((4u32 << 16) | MI_INT32).to_le_bytes());
    body.extend_from_slice(&(width as i32).to_le_bytes());
    let mut names = Vec::new();
    for (n, _) in fields {
        let mut b = n.as_bytes().to_vec();
        b.resize(width, 0);
        names.extend_from_slice(&b);
    }
    element(&mut body, MI_INT8, &names);
    for (_, v) in fields {
        body.extend_from_slice(v);
    }
    matrix(MX_STRUCT, [1, 1], name, &body)
}

/// A dataset's MATLAB variable name: its path with `/` as `_`, cut to MATLAB's 63 characters
/// (the path's end kept, which names the quantity) and starting with a letter.
pub fn variable(dataset: &str) -> String {
    let v: String = dataset
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let v = if v.len() > 63 {
        v[v.len() - 63..].to_string()
    } else {
        v
    };
    if v.starts_with(|c: char| c.is_ascii_alphabetic()) {
        v
    } else {
        format!("x{}", &v[..v.len().min(62)])
    }
}

/// The MAT (level 5) bytes of `samples`.
pub fn mat(samples: &Samples) -> Result<Vec<u8>, String> {
    if !consistent(samples) {
        return Err("a dataset's values do not fill its rows".into());
    }
    let mut out = Vec::new();
    let mut header = format!(
        "MATLAB 5.0 MAT-file, written by jointplay {}",
        env!("CARGO_PKG_VERSION")
    )
    .into_bytes();
    header.resize(116, b' ');
    out.extend_from_slice(&header);
    out.extend_from_slice(&[0u8; 8]);
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM");
    let n = samples.time.len();
    out.extend(doubles("time", n, 1, &samples.time)?);
    let mut units = vec![("time".to_string(), chars("", &["s".to_string()])?)];
    let mut columns = vec![("time".to_string(), chars("", &["time".to_string()])?)];
    let mut seen: std::collections::HashSet<String> =
        ["time", "units", "columns"].map(String::from).into();
    for c in &samples.datasets {
        let name = variable(&c.dataset);
        if !seen.insert(name.clone()) {
            return Err(format!(
                "dataset '{}' would become the variable '{name}', which another variable has",
                c.dataset
            ));
        }
        out.extend(doubles(&name, n, c.names.len(), &c.values)?);
        units.push((name.clone(), chars("", std::slice::from_ref(&c.unit))?));
        columns.push((name, chars("", &c.names)?));
    }
    out.extend(structure("units", &units)?);
    out.extend(structure("columns", &columns)?);
    Ok(out)
}

/// Exports `file` (its case `case`, its datasets `only` or all) as `<out>/<stem>.<ext>` and
/// returns that path.
pub fn export(
    file: &Path,
    case: Option<&str>,
    only: &[String],
    format: Format,
    out: &Path,
) -> Result<PathBuf> {
    let samples = read(file, case, only)?;
    crate::storage::durable::create_dir(out)?;
    let target = out.join(format!("{}.{}", stem(file, case), format.extension()));
    write(&samples, format, &target)?;
    Ok(target)
}

/// The name of what is written of the run in `file` (or of its case `case`): the file's stem,
/// `<stem>-<case>` for a case.
pub fn stem(file: &Path, case: Option<&str>) -> String {
    let stem = file
        .file_stem()
        .map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
    match case {
        Some(c) => format!("{stem}-{c}"),
        None => stem,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> Samples {
        Samples {
            time: vec![0.0, 0.1, 0.2],
            datasets: vec![Column {
                dataset: "bodies/b/position".into(),
                unit: "m".into(),
                names: vec!["bodies.b.position.x".into(), "bodies.b.position.y".into()],
                values: vec![1.0, 2.0, 3.0, 4.0, 0.1 + 0.2, -1e-300],
            }],
        }
    }

    #[test]
    fn the_csv_names_every_column_with_its_unit_and_keeps_every_digit() {
        let text = csv(&samples()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "time [s],bodies.b.position.x [m],bodies.b.position.y [m]"
        );
        assert_eq!(lines[3], "0.2,0.30000000000000004,-1e-300");
        let back: f64 = lines[3].split(',').nth(1).unwrap().parse().unwrap();
        assert_eq!(back, 0.1 + 0.2);
    }

    #[test]
    fn mat_elements_are_padded_to_eight_bytes_and_matrices_column_major() {
        let m = mat(&samples()).unwrap();
        assert_eq!(&m[126..128], b"IM");
        assert_eq!(m.len() % 8, 0);
        // The first variable, time: a miMATRIX whose double data follow flags (16 bytes),
        // dimensions (16), the name "time" (16) and the data tag (8).
        let t = 128 + 8 + 16 + 16 + 16 + 8;
        let read = |at: usize| f64::from_le_bytes(m[at..at + 8].try_into().unwrap());
        assert_eq!([read(t), read(t + 8), read(t + 16)], [0.0, 0.1, 0.2]);
        // The position: column x (1, 3, 0.3...) then column y.
        // Its name, "bodies_b_position", is 17 bytes: 24 with padding, after its tag.
        let p = t + 24 + 8 + 16 + 16 + 8 + 24 + 8;
        let got: Vec<f64> = (0..6).map(|k| read(p + 8 * k)).collect();
        assert_eq!(got, [1.0, 3.0, 0.1 + 0.2, 2.0, 4.0, -1e-300]);
    }

    #[test]
    fn variable_names_are_matlab_identifiers() {
        assert_eq!(
            variable("joints/pin/normal_force"),
            "joints_pin_normal_force"
        );
        let long = format!("joints/{}/radial_eccentricity_rate", "j".repeat(60));
        let v = variable(&long);
        assert!(
            v.len() == 63 && v.ends_with("radial_eccentricity_rate"),
            "{v}"
        );
        assert!(variable("1st/x").starts_with('x'));
    }
}
