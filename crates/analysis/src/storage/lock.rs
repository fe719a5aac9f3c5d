//! One writer per output: an exclusive lock taken before anything under an output's name is
//! created, truncated or removed.
//!
//! The lock is `<output>.lock` beside the output (`out/study.h5.lock` for `out/study.h5`), held
//! with the operating system's advisory file lock (`flock` on Linux, through
//! [`std::fs::File::try_lock`]), which the kernel releases when its process ends, however it
//! ends: a killed writer never leaves a stale lock behind, only a stale lock file, which the next
//! writer takes over. The file holds the holder's process id, so that a refused writer can name
//! it. A holder removes the file when it lets go; a writer that opened the file just before it
//! was removed finds that its file is no longer the one under the name and tries again, so two
//! processes never both hold a lock on one name.
//!
//! Within one process the lock nests: a program that holds it around a whole study (its sweep,
//! then its continuation) lets the steps inside take it again.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::durable::{parent, with_suffix};
use crate::{Error, Result};

/// An output this process holds the lock of: its key, its holders, the locked file.
struct Held {
    key: PathBuf,
    holders: usize,
    lock_file: PathBuf,
    file: File,
}

/// The outputs this process holds locks on.
static HELD: Mutex<Vec<Held>> = Mutex::new(Vec::new());

/// An exclusive lock on an output (see the module documentation); released when its last holder
/// in the process is dropped.
#[derive(Debug)]
pub struct Lock {
    key: PathBuf,
}

/// The key of an output in [`HELD`]: its directory made absolute, and its name.
fn key(output: &Path) -> PathBuf {
    let dir = parent(output);
    let dir = dir.canonicalize().unwrap_or_else(|_| dir.to_path_buf());
    dir.join(output.file_name().unwrap_or_default())
}

impl Lock {
    /// Takes the lock of `output` (its directory must exist), or fails at once, naming the
    /// process that holds it, when another process does.
    pub fn acquire(output: &Path) -> Result<Lock> {
        let key = key(output);
        let lock_file = with_suffix(output, ".lock");
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(h) = held.iter_mut().find(|h| h.key == key) {
            h.holders += 1;
            return Ok(Lock { key });
        }
        // Taken while HELD is locked, so that two threads of this process do not both open the
        // file (flock conflicts between two opens of one process too).
        let file = take(output, &lock_file)?;
        held.push(Held {
            key: key.clone(),
            holders: 1,
            lock_file,
            file,
        });
        Ok(Lock { key })
    }
}

fn take(output: &Path, lock_file: &Path) -> Result<File> {
    let err = |e: std::io::Error| Error::Io {
        file: lock_file.to_path_buf(),
        message: format!("cannot take the lock of {}: {e}", output.display()),
    };
    for _ in 0..100 {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(lock_file)
            .map_err(err)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                let who = if holder.is_empty() {
                    "another process".to_string()
                } else {
                    format!("process {holder}")
                };
                return Err(Error::Io {
                    file: output.to_path_buf(),
                    message: format!(
                        "{who} is writing this output (it holds {}): wait for it to end or \
                         stop it, or write elsewhere with another --out; nothing was changed",
                        lock_file.display()
                    ),
                });
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(err(e)),
        }
        // The file under the name may have been removed (and another made) by a holder letting
        // go between our open and our lock: then ours is not the lock, try again.
        let same = match (std::fs::metadata(lock_file), file.metadata()) {
            (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
            _ => false,
        };
        if !same {
            continue;
        }
        file.set_len(0).map_err(err)?;
        writeln!(file, "{}", std::process::id()).map_err(err)?;
        return Ok(file);
    }
    Err(err(std::io::Error::other("the lock file kept changing")))
}

impl Drop for Lock {
    fn drop(&mut self) {
        let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = held.iter().position(|h| h.key == self.key) {
            held[i].holders -= 1;
            if held[i].holders == 0 {
                let h = held.swap_remove(i);
                // Removed while still locked (see the module documentation), then released.
                let _ = std::fs::remove_file(&h.lock_file);
                drop(h.file);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lock_nests_in_its_process_and_is_gone_when_released() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("s.h5");
        let a = Lock::acquire(&out).unwrap();
        let lf = d.path().join("s.h5.lock");
        assert_eq!(
            std::fs::read_to_string(&lf).unwrap().trim(),
            std::process::id().to_string()
        );
        let b = Lock::acquire(&out).unwrap();
        drop(a);
        assert!(lf.exists(), "the nested holder still holds it");
        drop(b);
        assert!(!lf.exists());
        // Taken again after release.
        drop(Lock::acquire(&out).unwrap());
    }

    #[test]
    fn a_lock_held_through_another_open_file_refuses_naming_the_holder() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("s.h5");
        let lf = d.path().join("s.h5.lock");
        // Another holder: a file description of its own with the lock, as another process has.
        let other = File::create(&lf).unwrap();
        other.try_lock().unwrap();
        std::fs::write(&lf, "4242\n").unwrap();
        let e = Lock::acquire(&out).unwrap_err().to_string();
        assert!(e.contains("process 4242 is writing this output"), "{e}");
        drop(other);
        drop(Lock::acquire(&out).unwrap());
    }
}
