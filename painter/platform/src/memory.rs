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

/// What the C allocator holds, in bytes: `in_use` by live allocations,
/// `free` in its heaps but not given back to the system (resident until
/// reused or trimmed), `mapped` in blocks of their own (`mmap`). glibc
/// only (`mallinfo2`, summed over every arena); None elsewhere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Heap {
    pub in_use: u64,
    pub free: u64,
    pub mapped: u64,
}

/// [`Heap`] now, where the allocator reports it (glibc).
pub fn heap() -> Option<Heap> {
    heap_imp::heap()
}

/// Give the allocator's free memory back to the system (`malloc_trim(0)`:
/// the free pages inside every arena, not only its top), so that a
/// transient peak (a save's buffers, a big layer operation) does not stay
/// resident for the session's life. glibc only; elsewhere nothing is done.
/// Returns whether the call could release anything; it takes milliseconds
/// on a heap of gigabytes, so callers make it after rare, long work.
pub fn release_free_heap() -> bool {
    heap_imp::release()
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
mod heap_imp {
    /// glibc's `struct mallinfo2` (2.33 and later): ten `size_t`.
    #[repr(C)]
    #[allow(dead_code, reason = "the C struct's layout: only three of its fields are read")]
    struct MallInfo2 {
        arena: usize,
        ordblks: usize,
        smblks: usize,
        hblks: usize,
        hblkhd: usize,
        usmblks: usize,
        fsmblks: usize,
        uordblks: usize,
        fordblks: usize,
        keepcost: usize,
    }

    unsafe extern "C" {
        fn mallinfo2() -> MallInfo2;
        fn malloc_trim(pad: usize) -> i32;
    }

    pub fn heap() -> Option<super::Heap> {
        // SAFETY: mallinfo2 takes no argument and returns plain data.
        let m = unsafe { mallinfo2() };
        Some(super::Heap { in_use: m.uordblks as u64 + m.hblkhd as u64, free: m.fordblks as u64, mapped: m.hblkhd as u64 })
    }

    pub fn release() -> bool {
        // SAFETY: malloc_trim only gives free pages back; no allocation
        // changes.
        unsafe { malloc_trim(0) == 1 }
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
mod heap_imp {
    pub fn heap() -> Option<super::Heap> {
        None
    }

    pub fn release() -> bool {
        false
    }
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
    /// The tests measure the whole process's memory: one at a time.
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    #[cfg(any(target_os = "linux", windows))]
    #[test]
    fn peak_grows_with_a_touched_allocation() {
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
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
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
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
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn freed_heap_memory_is_counted_and_released() {
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        // Many small blocks (below the mmap threshold, so in an arena),
        // then every other one freed: free memory the heap keeps.
        let blocks: Vec<Vec<u8>> = (0..4096).map(|i| vec![i as u8; 16 << 10]).collect();
        let held = super::heap().unwrap();
        assert!(held.in_use >= 64 << 20, "{held:?} while 64 MiB are live");
        let kept: Vec<Vec<u8>> = blocks.into_iter().enumerate().filter(|(i, _)| i % 2 == 0).map(|(_, b)| b).collect();
        let freed = super::heap().unwrap();
        assert!(freed.free >= 24 << 20, "{freed:?} after freeing 32 MiB in holes");
        let rss_before = super::rss_kib().unwrap();
        super::release_free_heap();
        let rss_after = super::rss_kib().unwrap();
        // The holes' pages go back; the kept blocks keep their bytes.
        assert!(rss_after + 16 * 1024 <= rss_before, "resident {rss_before} KiB, then {rss_after} KiB after the trim");
        assert!(kept.iter().enumerate().all(|(i, b)| b.iter().all(|&x| x == (2 * i) as u8)));
    }
}
