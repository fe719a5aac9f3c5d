//! Durable file operations: a file forced to disk, a directory entry forced to disk, and the
//! atomic replacement of a file by a finished one.
//!
//! A rename is atomic on POSIX file systems (a reader sees the old file or the new one, never a
//! mix), but it is durable only once the renamed file's data and the directory entry are on
//! disk: [`replace`] forces the new file's data (`fsync`), renames it over the target and forces
//! the directory (`fsync` of the directory), the sequence of SQLite's atomic commit and of
//! every crash-safe store. Until the rename the target keeps its earlier contents, so the only
//! copy of finished work is never rewritten in place.

use std::fs::File;
use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// The directory that holds `path` (`.` for a bare file name).
pub fn parent(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// `path` with `suffix` appended to its file name (`a/b.h5` + `.lock` = `a/b.h5.lock`).
pub fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

fn io(file: &Path, what: &str, e: std::io::Error) -> Error {
    Error::Write {
        file: file.to_path_buf(),
        message: format!("{what}: {e}"),
    }
}

/// Forces the data of the file `path` to disk.
pub fn sync_file(path: &Path) -> Result<()> {
    File::open(path)
        .and_then(|f| f.sync_all())
        .map_err(|e| io(path, "cannot force the file to disk", e))
}

/// Forces the directory `dir`'s entries (a rename, a new or removed file) to disk.
pub fn sync_dir(dir: &Path) -> Result<()> {
    File::open(dir)
        .and_then(|f| f.sync_all())
        .map_err(|e| io(dir, "cannot force the directory to disk", e))
}

/// Replaces `to` by the finished file `from` (same directory) atomically and durably: `from`'s
/// data forced to disk, renamed over `to`, the directory forced to disk. A process killed at any
/// point leaves `to` as it was before or as `from` was, whole.
pub fn replace(from: &Path, to: &Path) -> Result<()> {
    sync_file(from)?;
    std::fs::rename(from, to).map_err(|e| io(to, "cannot move the finished file into place", e))?;
    sync_dir(parent(to))
}

/// Removes `path` if it exists and forces the directory to disk.
pub fn remove(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => sync_dir(parent(path)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io(path, "cannot remove", e)),
    }
}

/// Creates the directory `dir` (and its parents) when missing.
pub fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::Io {
        file: dir.to_path_buf(),
        message: format!("cannot create output directory: {e}"),
    })
}

/// A file being written that has no name until it is finished: created with `O_TMPFILE` in the
/// directory of its final name (Linux; ext4, XFS, Btrfs and tmpfs support it), written through
/// [`Unnamed::path`] (`/proc/self/fd/N`, which HDF5 opens as any path), and given its name by
/// [`Unnamed::persist`] only once it is complete. A process killed before leaves nothing under
/// any name: the kernel frees the file. Where the file system cannot make unnamed files, the
/// file is `<final>.partial` instead, removed on an error, and left behind by a kill (a later
/// writer of the same output removes it).
#[derive(Debug)]
pub struct Unnamed {
    /// The open unnamed file (None for a named `.partial`).
    fd: Option<File>,
    /// What the file is opened by.
    path: PathBuf,
    /// `<final>.partial`: the name errors give, and the file's name where it has one.
    partial: PathBuf,
}

impl Unnamed {
    /// A new empty file that will become `target`.
    pub fn create(target: &Path) -> Result<Unnamed> {
        use std::os::unix::fs::OpenOptionsExt;
        let partial = with_suffix(target, ".partial");
        let _ = std::fs::remove_file(&partial);
        let unnamed = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .mode(0o644)
            .custom_flags(libc::O_TMPFILE)
            .open(parent(target));
        match unnamed {
            Ok(fd) => {
                use std::os::fd::AsRawFd;
                let path = PathBuf::from(format!("/proc/self/fd/{}", fd.as_raw_fd()));
                Ok(Unnamed {
                    fd: Some(fd),
                    path,
                    partial,
                })
            }
            Err(_) => Ok(Unnamed {
                fd: None,
                path: partial.clone(),
                partial,
            }),
        }
    }

    /// A file that will become `target`, written under the name `<target>.partial` (for a
    /// writer that opens files by name only, as HDF5 does: it refuses the `/proc/self/fd` link
    /// of an unnamed file). Removed when dropped without [`Unnamed::persist`].
    pub fn named(target: &Path) -> Unnamed {
        let partial = with_suffix(target, ".partial");
        let _ = std::fs::remove_file(&partial);
        Unnamed {
            fd: None,
            path: partial.clone(),
            partial,
        }
    }

    /// The path to write the file through.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The name errors give the file: `<final>.partial`.
    pub fn name(&self) -> &Path {
        &self.partial
    }

    /// Gives the finished (closed) file the name `target`, atomically and durably: its data
    /// forced to disk, linked as `<final>.partial`, renamed over `target`, the directory forced
    /// to disk ([`replace`]).
    pub fn persist(mut self, target: &Path) -> Result<()> {
        if let Some(fd) = self.fd.take() {
            fd.sync_all()
                .map_err(|e| io(&self.partial, "cannot force the file to disk", e))?;
            let from = std::ffi::CString::new(self.path.as_os_str().as_encoded_bytes())
                .map_err(|e| io(&self.partial, "bad path", std::io::Error::other(e)))?;
            let to = std::ffi::CString::new(self.partial.as_os_str().as_encoded_bytes())
                .map_err(|e| io(&self.partial, "bad path", std::io::Error::other(e)))?;
            // SAFETY: both are valid NUL-terminated paths; linkat reads them only.
            let rc = unsafe {
                libc::linkat(
                    libc::AT_FDCWD,
                    from.as_ptr(),
                    libc::AT_FDCWD,
                    to.as_ptr(),
                    libc::AT_SYMLINK_FOLLOW,
                )
            };
            if rc != 0 {
                return Err(io(
                    &self.partial,
                    "cannot give the finished file a name",
                    std::io::Error::last_os_error(),
                ));
            }
            drop(fd);
        }
        let res = replace(&self.partial, target);
        if res.is_err() {
            let _ = std::fs::remove_file(&self.partial);
        }
        res
    }
}

/// Writes `bytes` as the file `target`, whole or not at all: into an [`Unnamed`] file, forced to
/// disk and given its name atomically ([`Unnamed::persist`]). A write error (a full disk) is an
/// error naming `<target>.partial`, and leaves `target` as it was.
pub fn write_new(target: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let tmp = Unnamed::create(target)?;
    let mut f = match &tmp.fd {
        Some(fd) => fd.try_clone(),
        None => File::create(&tmp.path),
    }
    .map_err(|e| io(&tmp.partial, "cannot create", e))?;
    f.write_all(bytes)
        .and_then(|()| f.flush())
        .map_err(|e| io(&tmp.partial, "cannot write", e))?;
    drop(f);
    tmp.persist(target)
}

impl Drop for Unnamed {
    /// A file never persisted is discarded (an unnamed one vanishes by itself).
    fn drop(&mut self) {
        if self.fd.is_none() && self.path == self.partial {
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replacement_leaves_the_new_contents_under_the_name_and_no_temporary() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("x.tmp"), d.path().join("x"));
        std::fs::write(&b, b"old").unwrap();
        std::fs::write(&a, b"new").unwrap();
        replace(&a, &b).unwrap();
        assert_eq!(std::fs::read(&b).unwrap(), b"new");
        assert!(!a.exists());
        assert_eq!(with_suffix(&b, ".lock"), d.path().join("x.lock"));
        assert_eq!(parent(Path::new("x.h5")), Path::new("."));
    }

    #[test]
    fn an_unnamed_file_has_no_name_until_persisted_and_none_if_dropped() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("f.h5");
        let names = || std::fs::read_dir(d.path()).unwrap().count();
        let u = Unnamed::create(&target).unwrap();
        std::fs::write(u.path(), b"data").unwrap();
        drop(u);
        assert_eq!(names(), 0);
        let u = Unnamed::create(&target).unwrap();
        std::fs::write(u.path(), b"data").unwrap();
        u.persist(&target).unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"data");
        assert_eq!(names(), 1);
    }
}
