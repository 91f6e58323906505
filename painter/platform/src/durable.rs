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
//! A failure before the replacement removes the temporary file and leaves
//! the target as it was. A failure of the last step (the sync after the
//! replacement) is reported too: the new file is then in place, but
//! whether it would survive a power cut is unknown.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

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
pub fn write_with(path: &Path, f: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> std::io::Result<u64> {
    let (file, tmp) = temporary_in(folder_of(path))?.into_parts();
    let mut w = BufWriter::with_capacity(1 << 20, file);
    f(&mut w)?;
    let file = w.into_inner().map_err(|e| e.into_error())?;
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
