//! Where an artist's documents go when they name none: the system's
//! Documents folder, with an Octopaint folder in it.

use std::path::PathBuf;

/// The folder `octopaint` with no arguments keeps its document in:
/// `OCTOPAINT_HOME` if set, else `<Documents>/Octopaint`, where Documents is
/// the user's known folder on Windows (`SHGetKnownFolderPath`, so a moved
/// or OneDrive-backed Documents is followed) and `$HOME/Documents` (or
/// `$HOME` without one) elsewhere. None when none of these is known.
pub fn octopaint_home() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("OCTOPAINT_HOME").filter(|p| !p.is_empty()) {
        return Some(PathBuf::from(p));
    }
    Some(imp::documents()?.join("Octopaint"))
}

#[cfg(windows)]
mod imp {
    use std::os::windows::ffi::OsStringExt;
    use std::path::PathBuf;
    use windows_sys::Win32::System::Com::CoTaskMemFree;
    use windows_sys::Win32::UI::Shell::{FOLDERID_Documents, KF_FLAG_DEFAULT, SHGetKnownFolderPath};

    pub fn documents() -> Option<PathBuf> {
        let mut p: *mut u16 = std::ptr::null_mut();
        // SAFETY: SHGetKnownFolderPath writes a CoTaskMemAlloc'd,
        // NUL-terminated UTF-16 string to `p` (or leaves it null on
        // failure); it is read up to its NUL and freed exactly once.
        unsafe {
            let hr = SHGetKnownFolderPath(&FOLDERID_Documents, KF_FLAG_DEFAULT as u32, std::ptr::null_mut(), &mut p);
            let path = (hr >= 0 && !p.is_null()).then(|| {
                let len = (0..).take_while(|&i| *p.add(i) != 0).count();
                PathBuf::from(std::ffi::OsString::from_wide(std::slice::from_raw_parts(p, len)))
            });
            CoTaskMemFree(p as *const core::ffi::c_void);
            path
        }
    }
}

#[cfg(not(windows))]
mod imp {
    use std::path::PathBuf;

    pub fn documents() -> Option<PathBuf> {
        let home = PathBuf::from(std::env::var_os("HOME").filter(|h| !h.is_empty())?);
        let docs = home.join("Documents");
        Some(if docs.is_dir() { docs } else { home })
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn there_is_a_home_for_documents() {
        let home = super::octopaint_home().expect("a Documents folder");
        assert!(home.ends_with("Octopaint") || std::env::var_os("OCTOPAINT_HOME").is_some(), "{}", home.display());
    }
}
