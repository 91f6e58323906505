//! What differs between the operating systems the painter runs on (Linux,
//! Windows, and macOS for the desktop window), one module per concern, so
//! the rest of the painter has no `cfg(unix)` or `cfg(windows)` of its own:
//!
//! | module | concern | Linux and macOS | Windows |
//! | --- | --- | --- | --- |
//! | [`durable`] | replacing a file atomically and durably | temporary file, `fsync`, `rename`, `fsync` of the folder; mode 0644 | temporary file, `FlushFileBuffers`, `MoveFileExW(REPLACE_EXISTING \| WRITE_THROUGH)`, `FlushFileBuffers`; the folder's ACL |
//! | [`memory`] | the process's peak resident memory; pages mapped in ahead of their first write | `VmHWM` in /proc, `madvise(MADV_POPULATE_WRITE)` (Linux; neither on macOS) | `GetProcessMemoryInfo` (`PeakWorkingSetSize`); no mapping ahead |
//! | [`folders`] | where documents go by default; where settings go | `$HOME/Documents/Octopaint` (`$HOME/Octopaint` without a Documents folder); `$XDG_CONFIG_HOME/octopaint` (`~/.config/octopaint`; macOS `~/Library/Application Support/Octopaint`) | the Documents known folder + `Octopaint`; roaming AppData + `Octopaint` |
//! | [`lock`] | one writer per document | `flock(LOCK_EX \| LOCK_NB)` on `<document>.lock` | `LockFileEx(EXCLUSIVE \| FAIL_IMMEDIATELY)` on `<document>.lock` |
//! | [`stdio`] | a reader that closes standard output early | the default SIGPIPE: the process ends quietly | a panic message (no such signal) |
//!
//! docs/documents.md says what each platform guarantees a save.

pub mod durable;
pub mod folders;
pub mod lock;
pub mod memory;
pub mod stdio;
