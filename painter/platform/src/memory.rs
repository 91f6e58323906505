//! The process's peak resident memory, for the benchmarks' figures.

/// Peak resident set size in KiB since the process started, where the
/// platform reports it: Linux (`VmHWM` in /proc/self/status) and Windows
/// (`PeakWorkingSetSize`); None elsewhere (macOS) or if the call fails.
pub fn peak_rss_kib() -> Option<u64> {
    imp::peak_rss_kib()
}

#[cfg(target_os = "linux")]
mod imp {
    pub fn peak_rss_kib() -> Option<u64> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
        line.split_whitespace().nth(1)?.parse().ok()
    }
}

#[cfg(windows)]
mod imp {
    use windows_sys::Win32::System::ProcessStatus::{GetProcessMemoryInfo, PROCESS_MEMORY_COUNTERS};
    use windows_sys::Win32::System::Threading::GetCurrentProcess;

    pub fn peak_rss_kib() -> Option<u64> {
        let size = std::mem::size_of::<PROCESS_MEMORY_COUNTERS>() as u32;
        // SAFETY: PROCESS_MEMORY_COUNTERS is plain data (all zeros is a
        // valid value); the call writes at most `size` bytes into it, and
        // GetCurrentProcess returns a pseudo-handle that needs no closing.
        let mut c: PROCESS_MEMORY_COUNTERS = unsafe { std::mem::zeroed() };
        c.cb = size;
        let ok = unsafe { GetProcessMemoryInfo(GetCurrentProcess(), &mut c, size) };
        (ok != 0).then(|| c.PeakWorkingSetSize as u64 / 1024)
    }
}

#[cfg(not(any(target_os = "linux", windows)))]
mod imp {
    pub fn peak_rss_kib() -> Option<u64> {
        None
    }
}

#[cfg(test)]
mod tests {
    #[cfg(any(target_os = "linux", windows))]
    #[test]
    fn peak_grows_with_a_touched_allocation() {
        let before = super::peak_rss_kib().unwrap();
        let v = vec![1u8; 64 << 20];
        std::hint::black_box(&v);
        let after = super::peak_rss_kib().unwrap();
        assert!(after >= before.max(64 * 1024), "{before} KiB then {after} KiB after touching 64 MiB");
    }
}
