//! A trace played into a front end as live input at the trace's pace
//! (`octopaint window --play`, `octopaint vr --play`; docs/desktop.md,
//! "Playback"): a timelapse of a painting session for artists, and the way
//! tests and benchmarks drive the real window and headset. And a test's
//! hold on the stroke thread (`--hold-painting FILE`: while FILE exists the
//! stroke thread waits before each level; the front end must keep
//! presenting frames meanwhile).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use octopaint_doc::Session;
use octopaint_tree::trace::read_trace;

use crate::engine::{Gate, Submitter};
use crate::jobs::{Job, from_trace};

/// The jobs of the trace at `path` with their times, refused unless the
/// trace fits the document: the same canvas, and layers only in a document
/// of layers.
pub fn read(path: &Path, session: &Session) -> Result<Vec<(f64, Job)>, String> {
    let trace = read_trace(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if trace.canvas != *session.doc.canvas() {
        return Err(format!(
            "{}: its canvas differs from the document's (make a document for it with octopaint new DOC --like {})",
            path.display(),
            path.display()
        ));
    }
    if trace.version == 2 && session.version != 2 {
        return Err(format!("{}: a trace of layers needs a document of layers (octopaint new DOC --like TRACE --layers)", path.display()));
    }
    // Times from the trace's first event (a camera, say), so that a trace
    // whose first stroke comes later starts with that pause.
    let first = trace.events.first().map_or(0.0, |e| e.t);
    Ok(from_trace(&trace).into_iter().map(|(t, j)| (t - first, j)).collect())
}

/// Feed `jobs` to an engine from a thread of their own, each at its time
/// (seconds from now); the flag turns true once every job is queued (or the
/// engine stopped taking them).
pub fn start(submitter: Submitter, jobs: Vec<(f64, Job)>) -> Arc<AtomicBool> {
    let done = Arc::new(AtomicBool::new(false));
    let flag = done.clone();
    std::thread::Builder::new()
        .name("play".into())
        .spawn(move || {
            let t0 = Instant::now();
            for (t, job) in jobs {
                let due = t0 + Duration::from_secs_f64(t.max(0.0));
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
                if submitter.submit(job).is_err() {
                    break; // the front end closed
                }
            }
            flag.store(true, Ordering::Release);
        })
        .expect("spawn");
    done
}

/// Close `gate` while `path` exists, open it otherwise, until the returned
/// flag is set (then open for good).
pub fn hold_while(path: PathBuf, gate: Arc<Gate>) -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    std::thread::Builder::new()
        .name("hold".into())
        .spawn(move || {
            while !flag.load(Ordering::Acquire) {
                if path.exists() {
                    gate.close()
                } else {
                    gate.open()
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            gate.open();
        })
        .expect("spawn");
    stop
}
