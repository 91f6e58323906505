//! Replacing a file atomically and durably: a reader (or the next start
//! after a crash or a power cut) finds the old file or the whole new one,
//! never a mix, and once the call returns the new one is on the disk.
//!
//! The steps are the same everywhere: write a temporary file in the same
//! folder (so the last step is a rename within one file system), flush it
//! to the disk, then rename it over the target in one step the file system
//! makes durable. Only the calls differ:
//!
//! | step | Linux, macOS | Windows |
//! | --- | --- | --- |
//! | temporary file | `.tmp-XXXXXX` beside the target, mode 0644 | `.tmp-XXXXXX` beside the target, the folder's ACL |
//! | flush the data | `fsync` (`F_FULLFSYNC` on macOS) | `FlushFileBuffers` |
//! | replace | `rename` | `MoveFileExW(MOVEFILE_REPLACE_EXISTING \| MOVEFILE_WRITE_THROUGH)` on `\\?\` paths (no 260-character limit) |
//! | make the rename durable | `fsync` of the folder | `FlushFileBuffers` of the replaced file (see below) |
//!
//! On Windows there is no folder to sync. Microsoft documents
//! `MOVEFILE_WRITE_THROUGH`'s flush only for moves that copy across
//! volumes; within a volume the rename is one NTFS metadata transaction,
//! and flushing the file afterwards commits NTFS's log up to it, which is
//! the nearest Windows offers to a folder sync without administrator
//! rights.
//!
//! On Linux the data also starts on its way to the disk while it is being
//! written: every [`WRITEBACK_CHUNK`] bytes, `sync_file_range` asks the
//! kernel to begin writing them out without waiting for it, so the disk
//! works while the rest is produced and the final `fsync` finds little left
//! to do (docs/benchmarks.md, "Durable writes"). It changes no step
//! above: the `fsync` still comes before the rename and waits for every
//! byte. Elsewhere the data waits for the flush, as before.
//!
//! A failure before the replacement removes the temporary file and leaves
//! the target as it was. A failure of the last step (the sync after the
//! replacement) is reported too: the new file is then in place, but
//! whether it would survive a power cut is unknown.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::Path;

/// What [`write_with`]'s callers write into: the temporary file behind a
/// 1 MiB buffer (seekable, for zip archives that patch their headers).
pub type Out = BufWriter<Writeback>;

/// Bytes written between two requests to start writeback (Linux).
pub const WRITEBACK_CHUNK: u64 = 4 << 20;

/// The temporary file of a durable write, which on Linux starts writing
/// its data to the disk every [`WRITEBACK_CHUNK`] bytes (see the module's
/// text). Writes are cut at those boundaries, so a large `write_all`
/// (a whole array of a dump) is handed over a chunk at a time.
pub struct Writeback {
    file: File,
    /// The file's position.
    pos: u64,
    /// Where the bytes not yet sent to the disk begin.
    sent: u64,
}

impl Writeback {
    fn new(file: File) -> Writeback {
        Writeback { file, pos: 0, sent: 0 }
    }

    /// Ask for the writeback of `[sent, pos)` once it is a chunk long.
    fn send(&mut self) {
        if self.pos >= self.sent + WRITEBACK_CHUNK {
            start_writeback(&self.file, self.sent, self.pos - self.sent);
            self.sent = self.pos;
        }
    }
}

impl Write for Writeback {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        // A seek may have moved a chunk or more past the bytes sent.
        self.send();
        // Up to the next chunk's end, when the position is past the bytes
        // sent; anywhere else (a zip header patched in place) as it is.
        let room = if self.pos >= self.sent { (self.sent + WRITEBACK_CHUNK - self.pos) as usize } else { buf.len() };
        let n = self.file.write(&buf[..buf.len().min(room)])?;
        self.pos += n as u64;
        self.send();
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

impl Seek for Writeback {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.pos = self.file.seek(to)?;
        Ok(self.pos)
    }
}

/// Start writing `len` bytes of `file` from `offset` to the disk, without
/// waiting (Linux's `sync_file_range` with `SYNC_FILE_RANGE_WRITE`). Only a
/// hint: a file system that refuses it (an error) loses nothing, since the
/// `fsync` that follows writes everything anyway.
#[cfg(target_os = "linux")]
fn start_writeback(file: &File, offset: u64, len: u64) {
    use std::os::fd::AsRawFd;
    const SYNC_FILE_RANGE_WRITE: u32 = 2;
    unsafe extern "C" {
        fn sync_file_range(fd: i32, offset: i64, nbytes: i64, flags: u32) -> i32;
    }
    let (Ok(offset), Ok(len)) = (i64::try_from(offset), i64::try_from(len)) else { return };
    // SAFETY: the descriptor is open for as long as `file` is borrowed, and
    // the call reads no memory of ours.
    let _ = unsafe { sync_file_range(file.as_raw_fd(), offset, len, SYNC_FILE_RANGE_WRITE) };
}

/// Other systems have no call that starts writeback of a range without
/// waiting: the data goes to the disk at the flush.
#[cfg(not(target_os = "linux"))]
fn start_writeback(_file: &File, _offset: u64, _len: u64) {}

/// The folder `path` is in ("." for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// Replace `path` with `data` (see the module's steps).
pub fn write(path: &Path, data: &[u8]) -> std::io::Result<()> {
    write_with(path, |w| w.write_all(data)).map(drop)
}

/// Replace `path` with what `f` writes (through a 1 MiB buffer, for large
/// exports). Returns the size written.
pub fn write_with(path: &Path, f: impl FnOnce(&mut Out) -> std::io::Result<()>) -> std::io::Result<u64> {
    let (file, tmp) = temporary_in(folder_of(path))?.into_parts();
    let mut w = BufWriter::with_capacity(1 << 20, Writeback::new(file));
    f(&mut w)?;
    let file = w.into_inner().map_err(|e| e.into_error())?.file;
    file.sync_all()?;
    let size = file.metadata()?.len();
    // Windows cannot rename a file that is still open here.
    drop(file);
    replace(tmp, path)?;
    Ok(size)
}

#[cfg(unix)]
fn temporary_in(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    use std::os::unix::fs::PermissionsExt;
    tempfile::Builder::new().prefix(".tmp-").permissions(std::fs::Permissions::from_mode(0o644)).tempfile_in(dir)
}

#[cfg(windows)]
fn temporary_in(dir: &Path) -> std::io::Result<tempfile::NamedTempFile> {
    tempfile::Builder::new().prefix(".tmp-").tempfile_in(dir)
}

/// Make a file just created in `path`'s folder (not replaced through this
/// module) survive a power cut: its folder's entry for it is synced.
#[cfg(unix)]
pub fn sync_new_entry(path: &Path) -> std::io::Result<()> {
    File::open(folder_of(path))?.sync_all()
}

/// Windows: flushing the file commits NTFS's log with its new entry (the
/// caller has synced the file; a folder cannot be opened for flushing).
#[cfg(windows)]
pub fn sync_new_entry(path: &Path) -> std::io::Result<()> {
    std::fs::OpenOptions::new().write(true).open(path)?.sync_all()
}

#[cfg(unix)]
fn replace(tmp: tempfile::TempPath, path: &Path) -> std::io::Result<()> {
    tmp.persist(path).map_err(|e| e.error)?;
    sync_new_entry(path)
}

#[cfg(windows)]
fn replace(tmp: tempfile::TempPath, path: &Path) -> std::io::Result<()> {
    use windows_sys::Win32::Storage::FileSystem::{MOVEFILE_REPLACE_EXISTING, MOVEFILE_WRITE_THROUGH, MoveFileExW};
    let to_w = verbatim(path)?;
    // keep() clears the temporary attribute and stops the drop from
    // deleting the file; from here a failure removes it by hand.
    let from = tmp.keep().map_err(|e| e.error)?;
    let from_w = match verbatim(&from) {
        Ok(f) => f,
        Err(e) => {
            let _ = std::fs::remove_file(&from);
            return Err(e);
        }
    };
    // SAFETY: both arguments are NUL-terminated UTF-16 strings that live
    // until the call returns; MoveFileExW keeps no pointer to them.
    let ok = unsafe { MoveFileExW(from_w.as_ptr(), to_w.as_ptr(), MOVEFILE_REPLACE_EXISTING | MOVEFILE_WRITE_THROUGH) };
    if ok == 0 {
        let e = std::io::Error::last_os_error();
        let _ = std::fs::remove_file(&from);
        return Err(e);
    }
    sync_new_entry(path)
}

/// `path` as a NUL-terminated verbatim (`\\?\`) absolute path, as the
/// standard library passes paths to Windows, so paths over 260 characters
/// work without the system's long-path setting. `std::path::absolute`
/// (GetFullPathNameW) rather than canonicalize: the target may not exist,
/// and Wine 8 cannot canonicalize long paths.
#[cfg(windows)]
fn verbatim(path: &Path) -> std::io::Result<Vec<u16>> {
    use std::os::windows::ffi::OsStrExt;
    let abs: Vec<u16> = std::path::absolute(path)?.as_os_str().encode_wide().collect();
    let w = |s: &str| s.encode_utf16().collect::<Vec<u16>>();
    let mut out = if abs.starts_with(&w(r"\\?\")) || abs.starts_with(&w(r"\\.\")) {
        abs
    } else if abs.starts_with(&w(r"\\")) {
        [w(r"\\?\UNC\"), abs[2..].to_vec()].concat()
    } else {
        [w(r"\\?\"), abs].concat()
    };
    out.push(0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_whole_files_and_leaves_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        write(&p, b"first").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"first");
        let n = write_with(&p, |w| w.write_all(&[7u8; 3_000_000])).unwrap();
        assert_eq!(n, 3_000_000);
        assert_eq!(std::fs::read(&p).unwrap(), vec![7u8; 3_000_000]);
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.bin")]);
    }

    /// Large writes cut at the writeback chunks, seeks back to patch bytes
    /// in place (as zip archives patch their headers) and a seek past the
    /// end: the file holds exactly what an in-memory cursor holds.
    #[test]
    fn writes_across_writeback_chunks_and_seeks_land_where_they_should() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.npz");
        let chunk = WRITEBACK_CHUNK as usize;
        let pattern: Vec<u8> = (0..chunk * 2 + 12_345).map(|i| (i * 7 + i / 251) as u8).collect();
        let script = |w: &mut dyn WriteSeek| -> std::io::Result<()> {
            w.write_all(b"header")?;
            w.write_all(&pattern)?;
            w.seek(SeekFrom::Start(3))?;
            w.write_all(b"PATCH")?;
            w.seek(SeekFrom::Start(chunk as u64 + 17))?;
            w.write_all(b"middle")?;
            w.seek(SeekFrom::End(0))?;
            w.write_all(&pattern[..1000])?;
            w.seek(SeekFrom::Current(chunk as u64 as i64 + 3))?;
            w.write_all(b"after a hole")
        };
        let mut expected = std::io::Cursor::new(Vec::new());
        script(&mut expected).unwrap();
        let n = write_with(&p, |w| script(w)).unwrap();
        let got = std::fs::read(&p).unwrap();
        assert_eq!(n as usize, expected.get_ref().len());
        assert!(got == *expected.get_ref(), "the file differs from the cursor's bytes");
    }

    trait WriteSeek: Write + Seek {}
    impl<T: Write + Seek> WriteSeek for T {}

    #[test]
    fn a_failed_write_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("doc.octo");
        write(&p, b"old").unwrap();
        let err = write_with(&p, |w| {
            w.write_all(b"half of the new")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert_eq!(err.to_string(), "disk full");
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn paths_longer_than_260_characters_are_replaced_too() {
        let dir = tempfile::tempdir().unwrap();
        let mut deep = dir.path().to_path_buf();
        for i in 0..6 {
            deep.push(format!("{i}-{}", "f".repeat(48)));
        }
        std::fs::create_dir_all(&deep).unwrap();
        let p = deep.join("painting.octo");
        assert!(p.as_os_str().len() > 300);
        write(&p, b"old").unwrap();
        write(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(&deep).unwrap().count(), 1);
    }

    #[test]
    fn a_missing_folder_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(write(&dir.path().join("no/such/folder/x"), b"x").is_err());
    }

    #[cfg(unix)]
    #[test]
    fn files_are_readable_by_all() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a");
        write(&p, b"x").unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o644);
    }
}
