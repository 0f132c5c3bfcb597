//! The instance lock: one opennav drives the chair. An advisory `flock` on
//! a file in the runtime directory, held for the life of the process (the
//! kernel drops it when the process ends, however it ends); the file
//! holds the owner's pid for the message.

use std::io::{Read, Seek, Write};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum LockError {
    #[error("another opennav drives the chair ({holder}; lock {path}): stop it first")]
    Held { path: PathBuf, holder: String },
    #[error("lock {path}: {reason}")]
    Io { path: PathBuf, reason: String },
}

/// Held while alive.
#[derive(Debug)]
pub struct InstanceLock {
    _file: std::fs::File,
    pub path: PathBuf,
}

impl InstanceLock {
    pub fn acquire(path: &Path) -> Result<InstanceLock, LockError> {
        let io = |e: std::io::Error| LockError::Io {
            path: path.to_path_buf(),
            reason: e.to_string(),
        };
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(io)?;
        // SAFETY: flock on a descriptor this function owns
        let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
        if rc != 0 {
            let e = std::io::Error::last_os_error();
            if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
                let mut holder = String::new();
                // the holder's pid, if it wrote one
                file.read_to_string(&mut holder).ok();
                let holder = match holder.trim() {
                    "" => "pid unknown".to_string(),
                    pid => format!("pid {pid}"),
                };
                return Err(LockError::Held {
                    path: path.to_path_buf(),
                    holder,
                });
            }
            return Err(io(e));
        }
        file.set_len(0).map_err(io)?;
        file.rewind().map_err(io)?;
        writeln!(file, "{}", std::process::id()).map_err(io)?;
        Ok(InstanceLock {
            _file: file,
            path: path.to_path_buf(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_until_the_first_lets_go() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("opennav.lock");
        let first = InstanceLock::acquire(&p).expect("first");
        let e = InstanceLock::acquire(&p).expect_err("second").to_string();
        assert!(e.contains("another opennav drives the chair"), "{e}");
        assert!(e.contains(&format!("pid {}", std::process::id())), "{e}");
        drop(first);
        InstanceLock::acquire(&p).expect("free again");
    }

    #[test]
    fn an_unwritable_place_is_an_error_naming_it() {
        let e = InstanceLock::acquire(Path::new("/nonexistent-dir/opennav.lock"))
            .expect_err("no dir")
            .to_string();
        assert!(e.contains("/nonexistent-dir/opennav.lock"), "{e}");
    }
}
