//! Documents (docs/documents.md): a painting saved as one `.octo` file
//! holding its tree, its undo history and the whole session that made it
//! (as a trace, so `octopaint record` gives it back to any replayer), a
//! journal beside it that every completed stroke reaches before the next
//! begins, and recovery from that journal after a crash.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`format`] | the file: header, checksummed compressed sections, trailer |
//! | [`session`] | events applied, journalled, saved; recovery |

pub mod format;
pub mod session;

pub use session::{Session, journal_path};

use std::path::PathBuf;

/// Why a document could not be opened, changed or saved. Nothing is
/// changed on disk when one is returned (but for `Io` during a journal
/// append, which leaves the journal as it was up to the last whole line).
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
}
