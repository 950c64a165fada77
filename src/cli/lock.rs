//! The exclusive lock of an output folder: `batch` and `sequence` hold `OUT_DIR/.foldmatch.lock`
//! for as long as they run, so two runs never write into one folder (their outputs and
//! reports would mix).
//!
//! The lock is an advisory `flock` on the file, which holds the owner's process id as text.
//! The kernel releases it when the process ends in any way (exit, Ctrl-C, `kill -9`, a
//! crash), so a lock file left behind by a run that was killed is stale by construction: the
//! next run finds it unlocked, says so and takes it over. The file itself stays in the folder
//! (removing it would let a run that opened it just before lock a file no longer there).
//! On platforms without `flock` (not Unix) no lock is taken.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// The lock file's name in the output folder.
pub const LOCK_FILE: &str = ".foldmatch.lock";

/// A held lock (released when dropped, or when the process ends).
#[derive(Debug)]
pub struct OutputLock {
    _file: File,
    /// The lock file.
    pub path: PathBuf,
    /// What the lock file said when it was taken over from a run that is gone (its pid).
    pub stale: Option<String>,
}

impl OutputLock {
    /// Takes the lock of `dir` (which must exist), or explains who holds it.
    pub fn acquire(dir: &Path) -> Result<Self, String> {
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| format!("{}: cannot open the lock file: {e}", path.display()))?;
        let mut previous = String::new();
        // The holder's pid is a few bytes: read at most a few hundred.
        let _ = (&mut file).take(256).read_to_string(&mut previous);
        let previous = previous.trim().to_string();
        #[cfg(unix)]
        {
            use std::os::fd::AsRawFd;
            // SAFETY: `flock` only takes a file descriptor, which `file` owns and keeps open
            // for the duration of the call; it touches no memory of ours.
            let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
            if rc != 0 {
                let err = std::io::Error::last_os_error();
                if err.kind() == std::io::ErrorKind::WouldBlock {
                    let holder = if previous.is_empty() {
                        "another process".to_string()
                    } else {
                        previous.clone()
                    };
                    return Err(format!(
                        "{}: another foldmatch run ({holder}) is writing into this folder; \
                         wait for it to end or choose another -o (its lock, {}, is released \
                         when it exits)",
                        dir.display(),
                        path.display()
                    ));
                }
                return Err(format!("{}: cannot lock: {err}", path.display()));
            }
        }
        // Ours now. A non-empty file names a run that ended without a clean exit.
        let stale = (!previous.is_empty()).then_some(previous);
        let write = (|| -> std::io::Result<()> {
            file.set_len(0)?;
            file.seek(SeekFrom::Start(0))?;
            writeln!(file, "pid {}", std::process::id())?;
            file.flush()
        })();
        write.map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Self {
            _file: file,
            path,
            stale,
        })
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // A clean end empties the file: the next run sees no stale owner.
        let _ = self._file.set_len(0);
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_held_lock_is_refused_and_a_released_one_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let first = OutputLock::acquire(dir.path()).unwrap();
        assert_eq!(first.stale, None);
        let me = format!("pid {}", std::process::id());
        assert_eq!(
            std::fs::read_to_string(dir.path().join(LOCK_FILE))
                .unwrap()
                .trim(),
            me
        );
        // flock locks belong to the open file: a second open in this process conflicts too.
        let err = OutputLock::acquire(dir.path()).unwrap_err();
        assert!(err.contains("another foldmatch run (pid "), "{err}");
        drop(first);
        // A killed run leaves its pid in an unlocked file: stale, taken over.
        std::fs::write(dir.path().join(LOCK_FILE), "pid 999999999\n").unwrap();
        let again = OutputLock::acquire(dir.path()).unwrap();
        assert_eq!(again.stale.as_deref(), Some("pid 999999999"));
    }
}
