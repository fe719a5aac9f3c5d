//! The table of a sweep: one row per swept value, read from the sweep's HDF5 file and written
//! beside it as `<stem>.md` (for people) and `<stem>.csv` (for spreadsheets and MATLAB's
//! `readtable`), so that a sweep says what it found without a script.
//!
//! Each row has the value (in the parameter's unit), its status (`done`, `failed`, `not run`),
//! the period of its strobe series (the least `p <= 64` of [`crate::measures::chaos::strobe_period`] on
//! the first observable, the rule the classification uses; empty when there is none), and, when
//! the study computed them, the class, `lambda_1` with its standard error (1/s) and the 0-1
//! test's `K`; then for every observable the smallest and largest strobe point of the kept
//! periods, in the observable's SI unit. The CSV holds the numbers at full precision (shortest
//! round-trip form) with the units in the header; the Markdown rounds them for reading.

use std::path::{Path, PathBuf};

use crate::measures::chaos::{CLASS_NAMES, strobe_period};
use crate::measures::indicator::Row;
use crate::measures::registry::INDICATORS;
use crate::storage::h5::{h5err, read_str};
use crate::{Error, Result};

/// A sweep's table in both forms.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    pub markdown: String,
    pub csv: String,
}

/// The columns of one observable: its name, unit and strobe points per row.
struct Column {
    name: String,
    unit: String,
    rows: Vec<Vec<f64>>,
}

/// A dataset's SI unit; "1" for a dimensionless one (an empty or missing `unit`).
fn unit_of(d: &hdf5::Dataset) -> String {
    read_str(d, "unit")
        .ok()
        .filter(|u| !u.is_empty())
        .unwrap_or_else(|| "1".into())
}

/// The table of the sweep file `path`; None when the file holds no sweep (a single run).
pub fn of_file(path: &Path) -> Result<Option<Table>> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let Ok(sweep) = file.group("sweep") else {
        return Ok(None);
    };
    let s = Sweep::read(path, &file, &sweep)?;
    let (name, parameter_path, p_unit) = (&s.name, &s.parameter_path, &s.p_unit);
    let n = s.parameter.len();
    let head = s.head();
    let mut csv = head
        .iter()
        .map(|h| csv_cell(h))
        .collect::<Vec<_>>()
        .join(",");
    csv.push('\n');
    let mut md = format!(
        "# Sweep: {name}\n\n{n} values of `{parameter_path}` ({p_unit}). Period: the least p <= 64 \
         with the first observable's strobe points repeating after p periods; class, lambda_1 and \
         {} where the study computed them; min and max: the strobe points of the kept periods.\n\n\
         | {} |\n|{}\n",
        INDICATORS
            .iter()
            .map(|i| i.row().column)
            .collect::<Vec<_>>()
            .join(", "),
        head.join(" | "),
        "---|".repeat(head.len())
    );
    for i in 0..n {
        let cells = s.cells(i);
        md.push_str(&format!(
            "| {} |\n",
            cells
                .iter()
                .map(|c| c.0.as_str())
                .collect::<Vec<_>>()
                .join(" | ")
        ));
        csv.push_str(
            &cells
                .iter()
                .map(|c| csv_cell(&c.1))
                .collect::<Vec<_>>()
                .join(","),
        );
        csv.push('\n');
    }
    Ok(Some(Table { markdown: md, csv }))
}

/// What a sweep's table shows, read from its file.
struct Sweep {
    /// The study's name.
    name: String,
    /// The swept parameter's path.
    parameter_path: String,
    parameter: Vec<f64>,
    p_unit: String,
    done: Vec<u8>,
    columns: Vec<Column>,
    class: Option<Vec<u8>>,
    /// lambda_1 and its standard error per row.
    lambda: Option<(Vec<f64>, Vec<f64>)>,
    /// The chaos indicators' numbers, each in the order of the registry.
    numbers: Vec<(Row, Vec<f64>)>,
}

impl Sweep {
    /// Reads the sweep group `sweep` of `file` (at `path`): the study's name, parameter and
    /// observables, each value's status and strobe points, and the chaos measures computed.
    fn read(path: &Path, file: &hdf5::File, sweep: &hdf5::Group) -> Result<Sweep> {
        let e = h5err(path);
        let name = read_str(file, "study_name").map_err(&e)?;
        let text = read_str(file, "study").map_err(&e)?;
        let study: toml::Table = text.parse().map_err(|err| Error::Io {
            file: path.to_path_buf(),
            message: format!("the stored study text does not parse: {err}"),
        })?;
        let parameter_path = study
            .get("sweep")
            .and_then(|s| s.get("parameter"))
            .and_then(|p| p.as_str())
            .unwrap_or("parameter")
            .to_string();
        let observables: Vec<String> = study
            .get("observables")
            .and_then(|o| o.as_array())
            .map(|a| {
                a.iter()
                    .filter_map(|o| o.get("name").and_then(|n| n.as_str()).map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        let p = sweep.dataset("parameter").map_err(&e)?;
        let parameter: Vec<f64> = p.read_raw().map_err(&e)?;
        let p_unit = unit_of(&p);
        let done: Vec<u8> = sweep
            .dataset("done")
            .and_then(|d| d.read_raw())
            .map_err(&e)?;
        let mut columns = Vec::new();
        for o in &observables {
            let Ok(d) = sweep.dataset(o) else { continue };
            let a = d.read_2d::<f64>().map_err(&e)?;
            columns.push(Column {
                name: o.clone(),
                unit: unit_of(&d),
                rows: a.outer_iter().map(|r| r.to_vec()).collect(),
            });
        }
        let chaos = sweep.group("chaos").ok();
        let read1 = |g: &hdf5::Group, name: &str| -> Option<Vec<f64>> {
            g.dataset(name).and_then(|d| d.read_raw::<f64>()).ok()
        };
        let class: Option<Vec<u8>> = chaos
            .as_ref()
            .and_then(|c| c.dataset("class").and_then(|d| d.read_raw()).ok());
        let lambda: Option<(Vec<f64>, Vec<f64>)> = chaos.as_ref().and_then(|c| {
            let ex = c
                .dataset("exponents")
                .and_then(|d| d.read_2d::<f64>())
                .ok()?;
            let se = c.dataset("stderr").and_then(|d| d.read_2d::<f64>()).ok()?;
            Some((ex.column(0).to_vec(), se.column(0).to_vec()))
        });
        // The chaos indicators' numbers, each in the order of the registry.
        let numbers: Vec<(Row, Vec<f64>)> = INDICATORS
            .iter()
            .filter_map(|i| {
                let row = i.row();
                chaos
                    .as_ref()
                    .and_then(|c| read1(c, row.name))
                    .map(|v| (row, v))
            })
            .collect();
        Ok(Sweep {
            name,
            parameter_path,
            parameter,
            p_unit,
            done,
            columns,
            class,
            lambda,
            numbers,
        })
    }

    /// The column heads: value, status, period, the chaos measures computed, and each
    /// observable's smallest and largest strobe point.
    fn head(&self) -> Vec<String> {
        let mut head: Vec<String> = vec![
            format!("value ({})", self.p_unit),
            "status".into(),
            "period".into(),
        ];
        if self.class.is_some() {
            head.push("class".into());
        }
        if self.lambda.is_some() {
            head.push("lambda_1 (1/s)".into());
            head.push("lambda_1 stderr (1/s)".into());
        }
        for (row, _) in &self.numbers {
            head.push(row.column.into());
        }
        for c in &self.columns {
            head.push(format!("{} min ({})", c.name, c.unit));
            head.push(format!("{} max ({})", c.name, c.unit));
        }
        head
    }

    /// The cells of row `i`, each as (markdown, csv).
    fn cells(&self, i: usize) -> Vec<(String, String)> {
        let status = match self.done.get(i) {
            Some(1) => "done",
            Some(2) => "failed",
            _ => "not run",
        };
        let ok = status == "done";
        let period = self
            .columns
            .first()
            .filter(|_| ok)
            .and_then(|c| strobe_period(&c.rows[i]));
        // (markdown, csv) of each cell.
        let mut cells: Vec<(String, String)> = vec![
            (short(self.parameter[i]), self.parameter[i].to_string()),
            (status.into(), status.into()),
            (
                period.map_or(String::new(), |p| p.to_string()),
                period.map_or(String::new(), |p| p.to_string()),
            ),
        ];
        if let Some(c) = &self.class {
            let name = if ok {
                CLASS_NAMES
                    .get(c[i] as usize)
                    .copied()
                    .unwrap_or("undetermined")
            } else {
                ""
            };
            cells.push((name.into(), name.into()));
        }
        if let Some((ex, se)) = &self.lambda {
            cells.push(number(ok, ex[i], 4));
            cells.push(number(ok, se[i], 4));
        }
        for (row, v) in &self.numbers {
            cells.push(number(ok, v[i], row.digits));
        }
        for c in &self.columns {
            let finite = c.rows[i].iter().copied().filter(|v| v.is_finite());
            let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let ok = ok && lo <= hi;
            cells.push(exp(ok, lo));
            cells.push(exp(ok, hi));
        }
        cells
    }
}

/// A number rounded to `digits` decimals for the Markdown and whole for the CSV; empty cells
/// for a row not done or a value that is not finite.
fn number(ok: bool, v: f64, digits: usize) -> (String, String) {
    if ok && v.is_finite() {
        (format!("{v:.digits$}"), v.to_string())
    } else {
        (String::new(), String::new())
    }
}

/// [`number`] in exponent form (observables span many scales).
fn exp(ok: bool, v: f64) -> (String, String) {
    if ok && v.is_finite() {
        (format!("{v:.4e}"), v.to_string())
    } else {
        (String::new(), String::new())
    }
}

/// `v` to 10 significant digits in its shortest form: a swept 1e-4 that came out of `from + i
/// step` as 0.00009999999999999999 reads as 0.0001.
fn short(v: f64) -> String {
    format!("{v:.9e}")
        .parse::<f64>()
        .map_or_else(|_| v.to_string(), |r| r.to_string())
}

/// A CSV cell, quoted when it holds a comma or a quote (RFC 4180).
fn csv_cell(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes the table of the sweep file `path` beside it as `<stem>.md` and `<stem>.csv`, each
/// whole or not at all ([`crate::storage::durable::write_new`]); the files written, none for a
/// file without a sweep.
pub fn write_beside(path: &Path) -> Result<Vec<PathBuf>> {
    let Some(t) = of_file(path)? else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for (ext, text) in [("md", &t.markdown), ("csv", &t.csv)] {
        let target = path.with_extension(ext);
        crate::storage::durable::write_new(&target, text.as_bytes())?;
        out.push(target);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_cells_are_quoted_when_they_must_be() {
        assert_eq!(csv_cell("ex min (m)"), "ex min (m)");
        assert_eq!(csv_cell("a,b"), "\"a,b\"");
        assert_eq!(csv_cell("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(number(true, 0.12345, 3).0, "0.123");
        assert_eq!(number(false, 0.12345, 3), (String::new(), String::new()));
        assert_eq!(exp(true, f64::NAN), (String::new(), String::new()));
        assert_eq!(short(0.00009999999999999999), "0.0001");
        assert_eq!(short(0.00030000000000000003), "0.0003");
    }
}
