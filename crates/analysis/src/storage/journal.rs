//! An append-only journal of checksummed records: where a long computation keeps each value
//! the moment it is finished.
//!
//! **Format.** The file starts with the 8 bytes `JPJRNL1\n`; then records follow, each
//!
//! ```text
//! marker "JPR1" (4 bytes) | length n (u64, little-endian) | CRC-32 of length and payload (u32) | payload (n bytes)
//! ```
//!
//! The first record is the journal's header (what computation it belongs to); the others are
//! the computation's values. The CRC-32 (IEEE 802.3, the zlib polynomial, through `crc32fast`)
//! covers the length too, so a record whose length field is damaged fails its check.
//!
//! **Writing.** A journal is created whole with its header under a temporary name and moved into
//! place ([`super::durable::replace`]), so a journal under its name always has a header. Records
//! are only ever appended, never rewritten: [`Journal::append`] writes one with a single `write`,
//! and [`Journal::commit`] forces everything appended to disk (`fdatasync`). A value counts as
//! finished only once a commit after its record returned: a writer appends the records that
//! arrived together and commits once (group commit).
//!
//! **Reading.** [`scan`] reads every record whose marker, length and checksum agree. A process
//! killed during an append leaves a torn record at the end; a damaged disk may leave a damaged one
//! anywhere: either is skipped (after a damaged record the scan looks for the next marker), and
//! reported, never trusted. [`Journal::reopen`] goes on with a scanned journal: when anything was
//! skipped, the valid records are first copied into a new journal that replaces the old one
//! atomically, so that new records never follow damaged bytes.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use super::durable::{replace, with_suffix};
use crate::{Error, Result};

const MAGIC: &[u8; 8] = b"JPJRNL1\n";
const MARKER: &[u8; 4] = b"JPR1";
const HEAD: usize = 16;

/// A journal open for appending.
#[derive(Debug)]
pub struct Journal {
    file: File,
    path: PathBuf,
    buf: Vec<u8>,
}

/// What [`scan`] found in a journal.
#[derive(Debug, Clone, Default)]
pub struct Scan {
    /// The header's payload.
    pub header: Vec<u8>,
    /// The payloads of the valid records after the header, in order.
    pub records: Vec<Vec<u8>>,
    /// Byte ranges skipped: torn or damaged records (offset, length, why).
    pub skipped: Vec<(u64, u64, String)>,
}

fn wr(path: &Path, e: std::io::Error) -> Error {
    Error::Write {
        file: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn frame(buf: &mut Vec<u8>, payload: &[u8]) {
    let len = (payload.len() as u64).to_le_bytes();
    let mut h = crc32fast::Hasher::new();
    h.update(&len);
    h.update(payload);
    buf.extend_from_slice(MARKER);
    buf.extend_from_slice(&len);
    buf.extend_from_slice(&h.finalize().to_le_bytes());
    buf.extend_from_slice(payload);
}

/// The record at `pos` of `data`, if whole and valid: its payload range.
fn record_at(data: &[u8], pos: usize) -> Option<std::ops::Range<usize>> {
    let head = data.get(pos..pos + HEAD)?;
    if &head[..4] != MARKER {
        return None;
    }
    let len_bytes: [u8; 8] = head[4..12].try_into().ok()?;
    let crc = u32::from_le_bytes(head[12..16].try_into().ok()?);
    let len = usize::try_from(u64::from_le_bytes(len_bytes)).ok()?;
    let start = pos + HEAD;
    let end = start.checked_add(len)?;
    let payload = data.get(start..end)?;
    let mut h = crc32fast::Hasher::new();
    h.update(&len_bytes);
    h.update(payload);
    (h.finalize() == crc).then_some(start..end)
}

/// Reads the journal `path` (see the module documentation). An error when it cannot be read or
/// is not a journal (wrong magic, or no valid header).
pub fn scan(path: &Path) -> Result<Scan> {
    let data = std::fs::read(path).map_err(|e| Error::Read {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    scan_bytes(&data).map_err(|m| Error::Read {
        file: path.to_path_buf(),
        message: m,
    })
}

fn scan_bytes(data: &[u8]) -> std::result::Result<Scan, String> {
    if data.get(..8) != Some(MAGIC.as_slice()) {
        return Err("not a jointplay journal (its first bytes are not JPJRNL1)".into());
    }
    let mut out = Scan::default();
    let mut pos = 8;
    let mut first = true;
    while pos < data.len() {
        match record_at(data, pos) {
            Some(r) => {
                let payload = data[r.clone()].to_vec();
                if first {
                    out.header = payload;
                    first = false;
                } else {
                    out.records.push(payload);
                }
                pos = r.end;
            }
            None => {
                if first {
                    return Err("its header record is damaged".into());
                }
                // Skip to the next marker that starts a valid record.
                let next = (pos + 1..data.len())
                    .find(|&p| data[p..].starts_with(MARKER) && record_at(data, p).is_some())
                    .unwrap_or(data.len());
                let why = if next == data.len() {
                    "torn or damaged record at the end (a write that did not finish)"
                } else {
                    "damaged record (its checksum does not match)"
                };
                out.skipped
                    .push((pos as u64, (next - pos) as u64, why.to_string()));
                pos = next;
            }
        }
    }
    if first {
        return Err("it has no header record".into());
    }
    Ok(out)
}

impl Journal {
    /// Creates the journal `path` with `header` (replacing any journal of that name atomically)
    /// and opens it for appending.
    pub fn create(path: &Path, header: &[u8]) -> Result<Journal> {
        Journal::create_with(path, header, &[])
    }

    /// [`Journal::create`] with `records` after the header, all on disk when it returns.
    pub fn create_with(path: &Path, header: &[u8], records: &[Vec<u8>]) -> Result<Journal> {
        let tmp = with_suffix(path, ".tmp");
        let mut buf = MAGIC.to_vec();
        frame(&mut buf, header);
        for r in records {
            frame(&mut buf, r);
        }
        std::fs::write(&tmp, &buf).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            wr(&tmp, e)
        })?;
        if let Err(e) = replace(&tmp, path) {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
        Journal::open_append(path)
    }

    fn open_append(path: &Path) -> Result<Journal> {
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|e| wr(path, e))?;
        Ok(Journal {
            file,
            path: path.to_path_buf(),
            buf: Vec::new(),
        })
    }

    /// Goes on with the journal `path` that [`scan`] read as `scan`: appended to as it is when
    /// nothing was skipped, else replaced first by a copy of its valid records.
    pub fn reopen(path: &Path, scan: &Scan) -> Result<Journal> {
        if scan.skipped.is_empty() {
            Journal::open_append(path)
        } else {
            Journal::create_with(path, &scan.header, &scan.records)
        }
    }

    /// The journal's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends one record (not yet forced to disk: see [`Journal::commit`]).
    pub fn append(&mut self, payload: &[u8]) -> Result<()> {
        self.buf.clear();
        frame(&mut self.buf, payload);
        self.file
            .write_all(&self.buf)
            .map_err(|e| wr(&self.path, e))
    }

    /// Forces every record appended so far to disk.
    pub fn commit(&mut self) -> Result<()> {
        self.file.sync_data().map_err(|e| wr(&self.path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_come_back_in_order_and_a_torn_tail_is_skipped() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("j");
        let mut j = Journal::create(&p, b"head").unwrap();
        j.append(b"one").unwrap();
        j.append(&[7u8; 1000]).unwrap();
        j.commit().unwrap();
        drop(j);
        let s = scan(&p).unwrap();
        assert_eq!(s.header, b"head");
        assert_eq!(s.records, vec![b"one".to_vec(), vec![7u8; 1000]]);
        assert!(s.skipped.is_empty());
        // A write cut short at every length leaves the records before it.
        let full = std::fs::read(&p).unwrap();
        let cut_from = full.len() - 1000 - HEAD;
        for cut in cut_from..full.len() {
            let s = scan_bytes(&full[..cut]).unwrap();
            assert_eq!(s.records, vec![b"one".to_vec()], "cut at {cut}");
            assert_eq!(s.skipped.len(), usize::from(cut > cut_from));
        }
    }

    #[test]
    fn a_damaged_record_is_skipped_and_the_next_ones_kept_and_reopen_copies_the_valid_ones() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("j");
        let mut j = Journal::create(&p, b"h").unwrap();
        for r in [b"aaaa", b"bbbb", b"cccc"] {
            j.append(r).unwrap();
        }
        j.commit().unwrap();
        drop(j);
        let mut data = std::fs::read(&p).unwrap();
        // Flip one payload byte of the second value record.
        let second = 8 + (HEAD + 1) + (HEAD + 4) + HEAD + 2;
        data[second] ^= 0x40;
        std::fs::write(&p, &data).unwrap();
        let s = scan(&p).unwrap();
        assert_eq!(s.records, vec![b"aaaa".to_vec(), b"cccc".to_vec()]);
        assert_eq!(s.skipped.len(), 1);
        let mut j = Journal::reopen(&p, &s).unwrap();
        j.append(b"dddd").unwrap();
        j.commit().unwrap();
        let s = scan(&p).unwrap();
        assert!(s.skipped.is_empty());
        assert_eq!(s.records.len(), 3);
        assert!(scan_bytes(b"something else").is_err());
    }
}
