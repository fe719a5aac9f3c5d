//! The finished value of a sweep as a record: the cells of its row in every dataset of
//! `/sweep`, and its section crossings, encoded for a [`super::journal::Journal`], written into a
//! sweep file by [`super::sweep`] or read back from a row of one, and checksummed the same way in
//! both.
//!
//! **Encoding** (all integers little-endian; a string is its byte length as u32, then its
//! UTF-8 bytes):
//!
//! ```text
//! value record: row (u64) | status (u8: 1 done, 2 failed) | done: row data | failed: message (string)
//! row data:     cells (u32) | per cell: dataset path under /sweep (string), kind (u8: 0 f64,
//!               1 u8, 2 u64), count (u64), the values' bytes
//!               | sections (u32) | per section: name (string), crossings (u64), times (f64),
//!               observables (u32), per observable: count (u64), values (f64)
//! ```
//!
//! The checksum of a row ([`Row::checksum`], CRC-32) is that of its row data without its wall
//! time: the same whether the row was just computed, read from a journal, or read back from any
//! file that holds it (a shard file, a merged file), since it covers neither the row's index nor
//! where it is stored; and, as the wall time is left out, the same for every run of the same
//! inputs, so that two files of one study can be compared by their checksums alone. The wall
//! time (a measurement of the machine, not a result) is the one value it does not check.
//! Doubles are stored and compared bit for bit (NaN payloads and signed zeros included).

use ndarray::s;

/// The cell a row's checksum leaves out: the value's wall time, the one measurement of the
/// machine rather than of the inputs.
pub const WALL_TIME: &str = "wall_time";

/// The values of one cell of a row.
#[derive(Debug, Clone, PartialEq)]
pub enum Cells {
    F64(Vec<f64>),
    U8(Vec<u8>),
    U64(Vec<u64>),
}

/// The element type of a cell, for reading one back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    F64,
    U8,
    U64,
}

/// One hyperplane section's crossings of a value.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    pub name: String,
    pub time: Vec<f64>,
    /// Per observable, one value per crossing.
    pub values: Vec<Vec<f64>>,
}

/// The row data of a finished value.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Row {
    /// Dataset path under `/sweep` and the row's values in it (one value for a dataset of one
    /// dimension, the whole row for one of two).
    pub cells: Vec<(String, Cells)>,
    pub sections: Vec<Section>,
}

/// What a value came to.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    Done(Row),
    /// The value's run failed: its message.
    Failed(String),
}

/// A value of a sweep file: its row and its outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct Value {
    pub row: usize,
    pub outcome: Outcome,
}

fn put_str(b: &mut Vec<u8>, s: &str) {
    b.extend_from_slice(&(s.len() as u32).to_le_bytes());
    b.extend_from_slice(s.as_bytes());
}

fn put_f64s(b: &mut Vec<u8>, v: &[f64]) {
    b.extend_from_slice(&(v.len() as u64).to_le_bytes());
    for x in v {
        b.extend_from_slice(&x.to_bits().to_le_bytes());
    }
}

/// A cursor over an encoded record.
struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.0.len() < n {
            return Err("record ends early".into());
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or_default(),
        ))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or_default(),
        ))
    }
    fn count(&mut self, size: usize) -> Result<usize, String> {
        let n = self.u64()?;
        match usize::try_from(n).ok().and_then(|n| n.checked_mul(size)) {
            Some(b) if b <= self.0.len() => Ok(n as usize),
            _ => Err(format!("a count of {n} beyond the record's end")),
        }
    }
    fn str(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|e| e.to_string())
    }
    fn f64s(&mut self) -> Result<Vec<f64>, String> {
        let n = self.count(8)?;
        let b = self.take(8 * n)?;
        Ok(b.chunks_exact(8)
            .map(|c| f64::from_bits(u64::from_le_bytes(c.try_into().unwrap_or_default())))
            .collect())
    }
}

impl Row {
    /// Appends the row data's encoding to `b`.
    pub fn encode_into(&self, b: &mut Vec<u8>) {
        self.encode_cells(b, |_| true);
    }

    /// [`Row::encode_into`] with only the cells whose name `keep` takes.
    fn encode_cells(&self, b: &mut Vec<u8>, keep: impl Fn(&str) -> bool) {
        let cells: Vec<&(String, Cells)> = self.cells.iter().filter(|c| keep(&c.0)).collect();
        b.extend_from_slice(&(cells.len() as u32).to_le_bytes());
        for (name, c) in cells {
            put_str(b, name);
            match c {
                Cells::F64(v) => {
                    b.push(0);
                    put_f64s(b, v);
                }
                Cells::U8(v) => {
                    b.push(1);
                    b.extend_from_slice(&(v.len() as u64).to_le_bytes());
                    b.extend_from_slice(v);
                }
                Cells::U64(v) => {
                    b.push(2);
                    b.extend_from_slice(&(v.len() as u64).to_le_bytes());
                    for x in v {
                        b.extend_from_slice(&x.to_le_bytes());
                    }
                }
            }
        }
        b.extend_from_slice(&(self.sections.len() as u32).to_le_bytes());
        for s in &self.sections {
            put_str(b, &s.name);
            put_f64s(b, &s.time);
            b.extend_from_slice(&(s.values.len() as u32).to_le_bytes());
            for v in &s.values {
                put_f64s(b, v);
            }
        }
    }

    fn decode(r: &mut Reader) -> Result<Row, String> {
        let n = r.u32()?;
        let mut cells = Vec::new();
        for _ in 0..n {
            let name = r.str()?;
            let c = match r.u8()? {
                0 => Cells::F64(r.f64s()?),
                1 => {
                    let n = r.count(1)?;
                    Cells::U8(r.take(n)?.to_vec())
                }
                2 => {
                    let n = r.count(8)?;
                    Cells::U64(
                        r.take(8 * n)?
                            .chunks_exact(8)
                            .map(|c| u64::from_le_bytes(c.try_into().unwrap_or_default()))
                            .collect(),
                    )
                }
                k => return Err(format!("cell {name}: unknown kind {k}")),
            };
            cells.push((name, c));
        }
        let n = r.u32()?;
        let mut sections = Vec::new();
        for _ in 0..n {
            let name = r.str()?;
            let time = r.f64s()?;
            let m = r.u32()?;
            let values = (0..m).map(|_| r.f64s()).collect::<Result<Vec<_>, _>>()?;
            sections.push(Section { name, time, values });
        }
        Ok(Row { cells, sections })
    }

    /// The CRC-32 of the row data but its wall time (see the module documentation).
    pub fn checksum(&self) -> u32 {
        let mut b = Vec::new();
        self.encode_cells(&mut b, |name| name != WALL_TIME);
        crc32fast::hash(&b)
    }

    /// The cell of dataset `name`.
    pub fn cell(&self, name: &str) -> Option<&Cells> {
        self.cells.iter().find(|c| c.0 == name).map(|c| &c.1)
    }

    /// The doubles of cell `name` (empty when it has none).
    pub fn f64s(&self, name: &str) -> &[f64] {
        match self.cell(name) {
            Some(Cells::F64(v)) => v,
            _ => &[],
        }
    }
}

impl Value {
    /// The value's record payload.
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&(self.row as u64).to_le_bytes());
        match &self.outcome {
            Outcome::Done(row) => {
                b.push(1);
                row.encode_into(&mut b);
            }
            Outcome::Failed(m) => {
                b.push(2);
                put_str(&mut b, m);
            }
        }
        b
    }

    /// The value a record payload holds.
    pub fn decode(payload: &[u8]) -> Result<Value, String> {
        let mut r = Reader(payload);
        let row = usize::try_from(r.u64()?).map_err(|e| e.to_string())?;
        let outcome = match r.u8()? {
            1 => Outcome::Done(Row::decode(&mut r)?),
            2 => Outcome::Failed(r.str()?),
            s => return Err(format!("unknown status {s}")),
        };
        if !r.0.is_empty() {
            return Err(format!("{} bytes after the value", r.0.len()));
        }
        Ok(Value { row, outcome })
    }
}

/// Reads row `index` of the datasets `names` of `g` (whole rows of two-dimensional ones).
pub fn read_cells(
    g: &hdf5::Group,
    index: usize,
    names: &[(String, Kind)],
) -> hdf5::Result<Vec<(String, Cells)>> {
    names
        .iter()
        .map(|(name, kind)| {
            let ds = g.dataset(name)?;
            macro_rules! get {
                ($t:ty) => {{
                    let v: Vec<$t> = if ds.ndim() == 2 && ds.shape()[1] == 0 {
                        Vec::new()
                    } else if ds.ndim() == 2 {
                        ds.read_slice_1d::<$t, _>(s![index, ..])?.to_vec()
                    } else {
                        ds.read_slice_1d::<$t, _>(s![index..index + 1])?.to_vec()
                    };
                    v
                }};
            }
            let c = match kind {
                Kind::F64 => Cells::F64(get!(f64)),
                Kind::U8 => Cells::U8(get!(u8)),
                Kind::U64 => Cells::U64(get!(u64)),
            };
            Ok((name.clone(), c))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Row {
        Row {
            cells: vec![
                ("a".into(), Cells::F64(vec![1.5, f64::NAN, -0.0])),
                ("b".into(), Cells::U8(vec![1, 0])),
                ("c".into(), Cells::U64(vec![u64::MAX])),
            ],
            sections: vec![Section {
                name: "p".into(),
                time: vec![0.1, 0.2],
                values: vec![vec![3.0, 4.0], vec![]],
            }],
        }
    }

    #[test]
    fn a_value_decodes_to_itself_bit_for_bit() {
        let v = Value {
            row: 7,
            outcome: Outcome::Done(sample()),
        };
        let back = Value::decode(&v.encode()).unwrap();
        let (Outcome::Done(a), Outcome::Done(b)) = (&v.outcome, &back.outcome) else {
            panic!("not done")
        };
        assert_eq!(a.checksum(), b.checksum());
        assert_eq!(a.f64s("a")[1].to_bits(), b.f64s("a")[1].to_bits());
        let f = Value {
            row: 1,
            outcome: Outcome::Failed("diverged at t = 1 s".into()),
        };
        assert_eq!(Value::decode(&f.encode()).unwrap(), f);
        // Every truncation is refused, never a panic.
        let e = v.encode();
        for n in 0..e.len() {
            assert!(Value::decode(&e[..n]).is_err());
        }
    }

    #[test]
    fn a_row_read_back_from_a_file_has_its_checksum() {
        let d = tempfile::tempdir().unwrap();
        let f = hdf5::File::create(d.path().join("r.h5")).unwrap();
        let g = f.create_group("sweep").unwrap();
        g.new_dataset::<f64>().shape((3, 3)).create("a").unwrap();
        g.new_dataset::<u8>().shape((3, 2)).create("b").unwrap();
        g.new_dataset::<u64>().shape(3).create("c").unwrap();
        let row = sample();
        let ds = |n: &str| g.dataset(n).unwrap();
        ds("a")
            .write_slice(&[1.5, f64::NAN, -0.0], ndarray::s![2, ..])
            .unwrap();
        ds("b").write_slice(&[1u8, 0], ndarray::s![2, ..]).unwrap();
        ds("c").write_slice(&[u64::MAX], ndarray::s![2..3]).unwrap();
        let names = vec![
            ("a".to_string(), Kind::F64),
            ("b".to_string(), Kind::U8),
            ("c".to_string(), Kind::U64),
        ];
        let back = Row {
            cells: read_cells(&g, 2, &names).unwrap(),
            sections: row.sections.clone(),
        };
        assert_eq!(back.checksum(), row.checksum());
    }
}
