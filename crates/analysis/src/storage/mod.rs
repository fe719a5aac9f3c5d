//! Storage that keeps finished work: what is counted finished is on disk and verified, and no
//! only copy of finished work is ever rewritten in place.
//!
//! * [`durable`]: files and directory entries forced to disk, and the atomic replacement of a
//!   file by a finished one (write a temporary, force it to disk, rename it over the target,
//!   force the directory).
//! * [`lock`]: one writer per output, a lock taken before anything under its name is touched.
//! * [`journal`]: an append-only file of checksummed records, where a sweep or a shard keeps each
//!   value the moment it finishes; a value counts as finished once its record is forced to disk.
//! * [`rows`]: a sweep value as a record (its row of every dataset, its section crossings), with
//!   one checksum whether it sits in a journal or in the row of an HDF5 file.
//!
//! How the file kinds use them (the guarantee and its limits, for users, are in the book's
//! chapter on durable results):
//!
//! * A **sweep or shard** keeps its values in `<file>.journal` while it runs, and writes its HDF5
//!   file from the journal when it ends or stops, under a temporary name, read back and checked
//!   against each value's checksum, then moved into place ([`durable::replace`]). Each row of
//!   the file carries its checksum (`/sweep/checksum`), so that `--resume` and `merge` check every
//!   value they keep, and recompute or refuse what does not check.
//! * A **continuation** writes its state after every point into a file of its own
//!   (`<study>.continuation.h5`), replaced atomically, and the study file once at the end.
//! * A **single run** is written under `<name>.h5.partial` and moved into place once complete.
//!
//! Any file written is read back generically (datasets by path, units, attributes) by
//! [`read::Reader`], what the Python package shows of a file; an analysis file's strobe and section
//! points, history tails, chaos measures and branches, as plain data for its figures, by
//! [`analysis_read`].

pub mod analysis_file;
pub mod analysis_read;
pub mod bitround;
pub mod branches;
pub mod chaos;
pub(crate) mod chunk;
pub mod continuation_file;
pub mod durable;
pub mod export;
pub mod h5;
pub mod hybrid;
pub mod inputs;
pub mod journal;
pub mod kept_states;
pub mod lock;
pub mod precision_file;
pub mod read;
pub mod rows;
pub mod run;
pub mod run_file;
pub(crate) mod shard_file;
pub mod study_read;
pub mod sweep;
pub mod table;
