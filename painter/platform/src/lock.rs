//! One writer per document (docs/documents.md, "One writer at a time"): an
//! advisory lock, held for a session's life, on a file beside the
//! document, `<document>.lock`.
//!
//! The lock is the operating system's own, through the standard library
//! (`File::try_lock`, Rust 1.89): `flock(LOCK_EX | LOCK_NB)` on Linux and
//! macOS, `LockFileEx(LOCKFILE_EXCLUSIVE_LOCK | LOCKFILE_FAIL_IMMEDIATELY)`
//! on Windows. Both belong to the open file, so the system lets go of them
//! when the process ends, however it ends: a crash never leaves a document
//! locked. No crate is needed for two calls the standard library makes;
//! `fd-lock` and `fs4` wrap the same ones.
//!
//! Why a file of its own and not the document or its journal: a save
//! replaces both by a rename (`durable`), and a lock belongs to the file
//! it was taken on, not to the name, so it would stay on the replaced
//! file; and on Windows a locked file cannot be read by anyone else, while
//! readers (`octopaint info`, `dump`, `render`, `export`) must go on
//! reading the document and its journal during a session. The lock file
//! holds the writer's process id, for the message a second writer gets
//! (where the system lets it read it: not on Windows, whose lock keeps
//! others from reading). It is never deleted: taking a lock on a file
//! another process is about to delete would let two writers in.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// A document's writer lock, held until dropped.
#[derive(Debug)]
pub struct WriterLock {
    _file: File,
    pub path: PathBuf,
}

/// Why the lock was not taken.
#[derive(Debug)]
pub enum LockError {
    /// Another process (or another session of this one) holds it; its
    /// process id when the lock file could be read.
    Held { path: PathBuf, pid: Option<u32> },
    /// The lock file could not be made or locked.
    Io { path: PathBuf, error: std::io::Error },
}

/// `<document>.lock`.
pub fn lock_path(doc: &Path) -> PathBuf {
    let mut p = doc.as_os_str().to_owned();
    p.push(".lock");
    PathBuf::from(p)
}

/// Take the writer lock of document `doc`, or say at once who has it.
pub fn acquire(doc: &Path) -> Result<WriterLock, LockError> {
    let path = lock_path(doc);
    let io = |error| LockError::Io { path: path.clone(), error };
    let mut file = OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(io)?;
    match file.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            let mut text = String::new();
            let pid = file.read_to_string(&mut text).ok().and_then(|_| text.trim().parse().ok());
            return Err(LockError::Held { path, pid });
        }
        Err(TryLockError::Error(e)) => return Err(io(e)),
    }
    // The holder's process id, for a second writer's message. Not synced:
    // it only matters while this process lives.
    file.set_len(0).and_then(|()| file.seek(SeekFrom::Start(0))).and_then(|_| write!(file, "{}", std::process::id())).map_err(io)?;
    Ok(WriterLock { _file: file, path })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_until_the_first_is_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let doc = dir.path().join("a.octo");
        let first = acquire(&doc).unwrap();
        assert_eq!(first.path, dir.path().join("a.octo.lock"));
        match acquire(&doc) {
            Err(LockError::Held { path, pid }) => {
                assert_eq!(path, first.path);
                // Windows keeps others from reading a locked file.
                if cfg!(unix) {
                    assert_eq!(pid, Some(std::process::id()));
                }
            }
            other => panic!("a second writer was not refused: {other:?}"),
        }
        // Another document is not held.
        let other = acquire(&dir.path().join("b.octo")).unwrap();
        drop(first);
        let again = acquire(&doc).unwrap();
        drop((again, other));
        // The lock file stays (see the module's text).
        assert!(lock_path(&doc).exists());
    }

    #[test]
    fn a_folder_that_cannot_hold_the_lock_file_is_an_io_error() {
        let dir = tempfile::tempdir().unwrap();
        let doc = dir.path().join("missing").join("a.octo");
        assert!(matches!(acquire(&doc), Err(LockError::Io { .. })));
    }
}
