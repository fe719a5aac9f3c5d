//! A shard file read for a merge ([`ShardFile`]): its split, program version, root attributes
//! and layout, and every value it holds checked against its checksum. The merge itself, which
//! checks the shards against each other and the study, is [`crate::study::shards`].

use std::path::{Path, PathBuf};

use crate::storage::analysis_file::{Declared, Root, Shard, SweepLayout};
use crate::storage::h5::{h5err, read_attr, read_str};
use crate::storage::rows::Outcome as Kept;
use crate::{Error, Result};

/// One shard file, read for the merge.
pub(crate) struct ShardFile {
    pub path: PathBuf,
    pub shard: Shard,
    pub version: String,
    pub root: Root,
    pub layout: SweepLayout,
    pub done: Vec<u8>,
    /// Messages of failed rows.
    pub errors: Vec<(usize, String)>,
    /// The done values that check, by row of the shard file.
    pub values: Vec<crate::storage::rows::Value>,
    /// Rows that do not check: why.
    pub bad: Vec<String>,
    /// Per row of the file, the job (index in the whole sweep) and the parameter value.
    pub jobs: Vec<u64>,
    pub parameters: Vec<f64>,
    /// The root `wall_time` (s): what the shard's last run took (NaN when not recorded).
    pub wall: f64,
}

fn io(file: &Path, message: impl Into<String>) -> Error {
    Error::Io {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

impl ShardFile {
    /// Reads the shard file `path`, its every value checked against its checksum; `declare`
    /// gives the layout its study (the root's `study` text) declares.
    pub(crate) fn open(
        path: &Path,
        declare: &dyn Fn(&Root, &Path) -> Result<Declared>,
    ) -> Result<ShardFile> {
        let e = h5err(path);
        let file = hdf5::File::open(path).map_err(&e)?;
        let shard = Shard::of_file(&file).map_err(&e)?.ok_or_else(|| {
            io(
                path,
                "not a shard file (no 'shard' attribute): merge takes the files written by \
                 `jointplay run STUDY --shard I/N`",
            )
        })?;
        let version = read_str(&file, "program_version").map_err(&e)?;
        let root = Root::read(&file).map_err(&e)?;
        let layout = SweepLayout::read(&file, declare(&root, path)?).map_err(&e)?;
        let g = file.group("sweep").map_err(&e)?;
        let read = |name: &str| g.dataset(name).map_err(&e);
        let done = read("done")?.read_raw::<u8>().map_err(&e)?;
        let jobs = read("job")?.read_raw::<u64>().map_err(&e)?;
        let parameters = read("parameter")?.read_raw::<f64>().map_err(&e)?;
        // Every value is checked against its checksum; one that does not check counts as not
        // run (the shard's `--resume` computes it again).
        let (values, bad) = crate::storage::sweep::read_values(path, &file, &layout, done.len())?;
        let mut done = vec![0u8; done.len()];
        let mut errors = Vec::new();
        let mut kept = Vec::new();
        for v in values {
            match v.outcome {
                Kept::Done(_) => {
                    done[v.row] = 1;
                    kept.push(v);
                }
                Kept::Failed(m) => {
                    done[v.row] = 2;
                    errors.push((v.row, m));
                }
            }
        }
        Ok(ShardFile {
            path: path.to_path_buf(),
            wall: read_attr::<f64>(&file, "wall_time").unwrap_or(f64::NAN),
            shard,
            version,
            root,
            layout,
            done,
            errors,
            values: kept,
            bad,
            jobs,
            parameters,
        })
    }
}
