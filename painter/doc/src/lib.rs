//! Documents (docs/documents.md): a painting saved as one `.octo` file
//! holding its tree, its undo history and the whole session that made it
//! (as a trace, so `octopaint record` gives it back to any replayer), a
//! journal beside it that every completed stroke reaches before the next
//! begins, and recovery from that journal after a crash.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`format`] | the file: header, checksummed compressed sections, trailer |
//! | [`session`] | events applied, journalled, saved; recovery; one writer at a time |
//! | [`journal`] | the journal's lines: header, appends, what a crash leaves |
//! | [`trace_log`] | a writing session's trace: saved events deflated, the rest as text |
//! | [`fuzz_harness`] | the document and journal fuzz targets' bodies |
//! | [`presets`] | the artist's brush presets file (beside documents: a user's settings, not a document's) |

pub mod format;
pub mod fuzz_harness;
pub mod journal;
pub mod presets;
pub mod session;
pub mod trace_log;

pub use journal::journal_path;
pub use session::Session;

use std::path::{Path, PathBuf};

/// An I/O error on `path` as a [`DocError`].
pub(crate) fn io(path: &Path) -> impl Fn(std::io::Error) -> DocError + '_ {
    move |e| DocError::Io { path: path.to_path_buf(), reason: octopaint_tree::trace::io_reason(&e) }
}

/// Why a document could not be opened, changed or saved. Nothing is
/// changed on disk when one is returned (but for `Io` during a journal
/// append, which leaves the journal as it was up to the last whole line;
/// and a refused writer leaves the empty `<document>.lock` it may have
/// made).
#[derive(Debug, thiserror::Error)]
pub enum DocError {
    #[error("not an octopaint document (no OCTOPAINTDOC header)")]
    NotADocument,
    #[error("the document is damaged: {0}")]
    Corrupt(String),
    #[error("the document was written by a newer octopaint (format {version}; this one reads up to {reads}): update octopaint to open it")]
    TooNew { version: u32, reads: u32 },
    #[error("{}: a file is already there", .0.display())]
    Exists(PathBuf),
    #[error("the journal {} cannot be used: {why}", path.display())]
    Journal { path: PathBuf, why: String },
    #[error("event refused: {0}")]
    BadEvent(String),
    #[error("{}: {reason}", path.display())]
    Io { path: PathBuf, reason: String },
    /// Another session holds the document's writer lock
    /// (`octopaint_platform::lock`): nothing was read or written.
    #[error(
        "{}: another Octopaint has this document open{}; close it there first (info, dump, record, render and export can still read it)",
        doc.display(),
        pid.map(|p| format!(" (process {p})")).unwrap_or_default()
    )]
    Locked { doc: PathBuf, pid: Option<u32> },
    /// A session opened to read (`Session::open_read`) was asked to write.
    #[error("{}: opened to read only", .0.display())]
    ReadOnly(PathBuf),
}
