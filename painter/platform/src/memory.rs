//! The process's resident memory, now and at its peak, for the benchmarks'
//! figures, and pages mapped in ahead of their first write.

/// Peak resident set size in KiB since the process started, where the
/// platform reports it: Linux (`VmHWM` in /proc/self/status) and Windows
/// (`PeakWorkingSetSize`); None elsewhere (macOS) or if the call fails.
pub fn peak_rss_kib() -> Option<u64> {
    imp::peak_rss_kib()
}

/// Resident set size in KiB now, where the platform reports it: Linux
/// (`VmRSS`) and Windows (`WorkingSetSize`); None elsewhere or if the call
/// fails (`bench soak` samples it).
pub fn rss_kib() -> Option<u64> {
    imp::rss_kib()
}

/// Whether [`populate_for_write`] can do anything here (Linux); elsewhere
/// callers need not prepare a call.
pub const POPULATES: bool = cfg!(target_os = "linux");

/// Map in the pages of the `len` bytes at `addr` (the whole pages inside
/// them) as their first write would, without writing: afterwards a write
/// there takes no page fault. The memory's content is unchanged, so
/// another thread may write the range meanwhile, and a range that is no
/// longer mapped only makes the call fail. Linux 5.14 and later
/// (`madvise(MADV_POPULATE_WRITE)`); elsewhere nothing is done. Returns
/// whether the pages were mapped in.
pub fn populate_for_write(addr: usize, len: usize) -> bool {
    imp::populate_for_write(addr, len)
}

#[cfg(target_os = "linux")]
mod imp {
    fn status_kib(field: &str) -> Option<u64> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = status.lines().find(|l| l.starts_with(field))?;
        line.split_whitespace().nth(1)?.parse().ok()
    }

    pub fn peak_rss_kib() -> Option<u64> {
        status_kib("VmHWM:")
    }

    pub fn rss_kib() -> Option<u64> {
        status_kib("VmRSS:")
    }

    unsafe extern "C" {
        fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
        fn sysconf(name: i32) -> i64;
    }
    const MADV_POPULATE_WRITE: i32 = 23;
    const SC_PAGESIZE: i32 = 30;

    pub fn populate_for_write(addr: usize, len: usize) -> bool {
        // SAFETY: sysconf only reads a constant of the system.
        let page = match unsafe { sysconf(SC_PAGESIZE) } {
            p if p > 0 && (p as u64).is_power_of_two() => p as usize,
            _ => return false,
        };
        let start = addr.next_multiple_of(page);
        let end = addr.saturating_add(len) & !(page - 1);
        if end <= start {
            return true; // no whole page inside
        }
        // SAFETY: MADV_POPULATE_WRITE changes no byte of any mapping: it
        // maps in pages that are not yet present (private anonymous ones
        // as zeros, which a first write would have done), and fails on a
        // range that is not mapped.
        unsafe { madvise(start as *mut std::ffi::c_void, end - start, MADV_POPULATE_WRITE) == 0 }
    }
}

#[cfg(windows)]
mod imp {
    use windows_sys::Win32::System::ProcessStatus::{GetProcessMemoryInfo, PROCESS_MEMORY_COUNTERS};
    use windows_sys::Win32::System::Threading::GetCurrentProcess;

    fn counters() -> Option<PROCESS_MEMORY_COUNTERS> {
        let size = std::mem::size_of::<PROCESS_MEMORY_COUNTERS>() as u32;
        // SAFETY: PROCESS_MEMORY_COUNTERS is plain data (all zeros is a
        // valid value); the call writes at most `size` bytes into it, and
        // GetCurrentProcess returns a pseudo-handle that needs no closing.
        let mut c: PROCESS_MEMORY_COUNTERS = unsafe { std::mem::zeroed() };
        c.cb = size;
        let ok = unsafe { GetProcessMemoryInfo(GetCurrentProcess(), &mut c, size) };
        (ok != 0).then_some(c)
    }

    pub fn peak_rss_kib() -> Option<u64> {
        counters().map(|c| c.PeakWorkingSetSize as u64 / 1024)
    }

    pub fn rss_kib() -> Option<u64> {
        counters().map(|c| c.WorkingSetSize as u64 / 1024)
    }

    /// No Windows call maps in committed, never-touched pages without
    /// writing them: the first write still takes the fault.
    pub fn populate_for_write(_addr: usize, _len: usize) -> bool {
        false
    }
}

#[cfg(not(any(target_os = "linux", windows)))]
mod imp {
    pub fn peak_rss_kib() -> Option<u64> {
        None
    }

    pub fn rss_kib() -> Option<u64> {
        None
    }

    pub fn populate_for_write(_addr: usize, _len: usize) -> bool {
        false
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
        // Resident first, then the peak: the peak is never below what was
        // resident at any earlier moment, whereas the other order races
        // with the test threads beside this one, which allocate meanwhile.
        let now = super::rss_kib().unwrap();
        let after = super::peak_rss_kib().unwrap();
        assert!(after >= before.max(64 * 1024), "{before} KiB then {after} KiB after touching 64 MiB");
        assert!((64 * 1024..=after).contains(&now), "{now} KiB resident holding 64 MiB, peak {after} KiB");
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn populated_pages_are_resident_and_keep_their_bytes() {
        unsafe extern "C" {
            fn mincore(addr: *mut std::ffi::c_void, len: usize, vec: *mut u8) -> i32;
        }
        const PAGE: usize = 4096;
        // The resident pages among the whole pages of `v`'s capacity.
        let resident = |v: &Vec<u8>| {
            let start = (v.as_ptr() as usize).next_multiple_of(PAGE);
            let end = (v.as_ptr() as usize + v.capacity()) & !(PAGE - 1);
            let mut map = vec![0u8; (end - start) / PAGE];
            // SAFETY: the range lies inside `v`'s allocation; mincore writes
            // one byte a page into `map`.
            assert_eq!(unsafe { mincore(start as *mut std::ffi::c_void, end - start, map.as_mut_ptr()) }, 0);
            (map.iter().filter(|&&b| b & 1 == 1).count(), map.len())
        };
        // Written bytes, then 32 MiB of reserved and never touched capacity.
        let mut v: Vec<u8> = (0..10_000u32).map(|i| (i * 7) as u8).collect();
        v.reserve_exact(32 << 20);
        let (before, pages) = resident(&v);
        assert!(before < pages / 2, "{before} of {pages} pages resident before");
        assert!(super::populate_for_write(v.as_ptr() as usize, v.capacity()), "madvise(MADV_POPULATE_WRITE) failed");
        assert_eq!(resident(&v), (pages, pages), "every page resident after");
        assert!(v.iter().enumerate().all(|(i, &b)| b == (i as u32 * 7) as u8), "a populated page changed");
        // A range with no whole page inside; a range not mapped at all.
        assert!(super::populate_for_write(v.as_ptr() as usize + 1, 100));
        assert!(!super::populate_for_write(8 * PAGE, PAGE), "an unmapped page");
    }
}
