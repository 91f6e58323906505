//! Where an artist's documents go when they name none (the system's
//! Documents folder, with an Octopaint folder in it), and where the
//! painter keeps the artist's settings (the platform's config folder).

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

/// The folder the painter keeps an artist's settings in (brush presets):
/// `OCTOPAINT_CONFIG` if set, else the roaming AppData known folder +
/// `Octopaint` on Windows, `$HOME/Library/Application Support/Octopaint` on
/// macOS, and `$XDG_CONFIG_HOME/octopaint` (`$HOME/.config/octopaint`
/// without it) elsewhere. None when none of these is known.
pub fn config_folder() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("OCTOPAINT_CONFIG").filter(|p| !p.is_empty()) {
        return Some(PathBuf::from(p));
    }
    imp::config()
}

#[cfg(windows)]
mod imp {
    use std::os::windows::ffi::OsStringExt;
    use std::path::PathBuf;
    use windows_sys::Win32::System::Com::CoTaskMemFree;
    use windows_sys::Win32::UI::Shell::{FOLDERID_Documents, FOLDERID_RoamingAppData, KF_FLAG_DEFAULT, SHGetKnownFolderPath};

    pub fn documents() -> Option<PathBuf> {
        known(&FOLDERID_Documents)
    }

    pub fn config() -> Option<PathBuf> {
        Some(known(&FOLDERID_RoamingAppData)?.join("Octopaint"))
    }

    fn known(id: &windows_sys::core::GUID) -> Option<PathBuf> {
        let mut p: *mut u16 = std::ptr::null_mut();
        // SAFETY: SHGetKnownFolderPath writes a CoTaskMemAlloc'd,
        // NUL-terminated UTF-16 string to `p` (or leaves it null on
        // failure); it is read up to its NUL and freed exactly once.
        unsafe {
            let hr = SHGetKnownFolderPath(id, KF_FLAG_DEFAULT as u32, std::ptr::null_mut(), &mut p);
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

    fn home() -> Option<PathBuf> {
        Some(PathBuf::from(std::env::var_os("HOME").filter(|h| !h.is_empty())?))
    }

    pub fn documents() -> Option<PathBuf> {
        let home = home()?;
        let docs = home.join("Documents");
        Some(if docs.is_dir() { docs } else { home })
    }

    #[cfg(target_os = "macos")]
    pub fn config() -> Option<PathBuf> {
        Some(home()?.join("Library/Application Support/Octopaint"))
    }

    #[cfg(not(target_os = "macos"))]
    pub fn config() -> Option<PathBuf> {
        match std::env::var_os("XDG_CONFIG_HOME").filter(|p| !p.is_empty()) {
            Some(x) => Some(PathBuf::from(x).join("octopaint")),
            None => Some(home()?.join(".config/octopaint")),
        }
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
