//! The stroke job queue (docs/architecture.md): what the input side hands
//! to the stroke thread. Bounded; when it is full, `submit` waits for room
//! (back-pressure on the input) and `try_submit` gives the job back: a job
//! is never dropped or merged, because every sample changes the painting.
//!
//! Beside the jobs, *questions* ([`Ask`]): closures the stroke thread runs
//! on the painting between two steps of its work (the surface under the
//! cursor, the view that frames the painting). They are served before the
//! next job and between the levels of a sample, so a front end never reads
//! the live pools itself and never waits for a heavy stroke to end.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};
use std::time::Instant;

use octopaint_tree::trace::{Brush, EventKind, Sample};

/// A sample placed by a ray from the eye: on the surface of the selected
/// layer's paint under the ray when `on_surface` finds one (optical depth
/// 0.7, `octopaint_tree::view::pick`), else `plane_t` along it. Resolved on
/// the stroke thread against the painting as that sample finds it, and
/// recorded as the `sample` event it becomes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aim {
    pub eye: [f64; 3],
    pub dir: [f64; 3],
    pub plane_t: f64,
    pub on_surface: bool,
}

/// One unit of work for the stroke thread.
#[derive(Clone, Debug)]
pub enum Job {
    /// A stroke with this brush (its `mirror` the planes it paints with):
    /// the brush and mirror events it needs, then `stroke_begin`.
    BeginStroke(Brush),
    Sample(Sample),
    /// A sample at the point a ray finds (the window's cursor).
    Aim(Aim),
    EndStroke,
    Undo,
    Redo,
    /// Any other event of the trace format: a layer operation, an import,
    /// a mirror, a brush (cameras, lights, renders and snapshots are
    /// recorded by documents and ignored by bare paintings).
    Event(EventKind),
    /// Save the document (a document's session; refused by a bare
    /// painting). At a stroke boundary: inside a stroke it is refused.
    Save,
    /// Make a one-tree document a document of layers (saved at once).
    UseLayers,
}

impl Job {
    pub fn name(&self) -> &'static str {
        match self {
            Job::BeginStroke(_) => "stroke_begin",
            Job::Sample(_) | Job::Aim(_) => "sample",
            Job::EndStroke => "stroke_end",
            Job::Undo => "undo",
            Job::Redo => "redo",
            Job::Event(k) => k.ev(),
            Job::Save => "save",
            Job::UseLayers => "use_layers",
        }
    }
}

/// A job with its sequence number (from 1, in submission order) and the
/// moment it was submitted (latency starts there).
#[derive(Clone, Debug)]
pub struct Ticket {
    pub seq: u64,
    pub submitted: Instant,
    pub job: Job,
}

#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum SubmitError {
    #[error("the job queue is full ({0} jobs)")]
    Full(usize),
    #[error("the pipeline is shutting down")]
    Closed,
}

/// What the stroke thread takes next: a job, or a question `A` (the
/// engine's: `crate::engine::Ask`).
pub enum Work<A> {
    Job(Ticket),
    Ask(A),
}

struct Inner<A> {
    queue: VecDeque<Ticket>,
    asks: VecDeque<A>,
    next_seq: u64,
    closed: bool,
}

/// The jobs, bounded, and the questions `A` beside them.
pub struct JobQueue<A> {
    capacity: usize,
    inner: Mutex<Inner<A>>,
    changed: Condvar,
}

impl<A> JobQueue<A> {
    pub fn new(capacity: usize) -> JobQueue<A> {
        JobQueue {
            capacity: capacity.max(1),
            inner: Mutex::new(Inner { queue: VecDeque::new(), asks: VecDeque::new(), next_seq: 1, closed: false }),
            changed: Condvar::new(),
        }
    }

    fn push(&self, inner: &mut Inner<A>, job: Job) -> Ticket {
        let t = Ticket { seq: inner.next_seq, submitted: Instant::now(), job };
        inner.next_seq += 1;
        inner.queue.push_back(t.clone());
        self.changed.notify_all();
        t
    }

    /// Queue a job, waiting while the queue is full. Returns its ticket.
    pub fn submit(&self, job: Job) -> Result<Ticket, SubmitError> {
        let mut inner = self.inner.lock().expect("job queue lock");
        while inner.queue.len() >= self.capacity && !inner.closed {
            inner = self.changed.wait(inner).expect("job queue lock");
        }
        if inner.closed {
            return Err(SubmitError::Closed);
        }
        Ok(self.push(&mut inner, job))
    }

    /// Queue a job if there is room; otherwise say so (the job is the
    /// caller's to keep).
    #[expect(clippy::result_large_err, reason = "a refused job is handed back whole, for the caller to keep")]
    pub fn try_submit(&self, job: Job) -> Result<Ticket, (SubmitError, Job)> {
        let mut inner = self.inner.lock().expect("job queue lock");
        if inner.closed {
            return Err((SubmitError::Closed, job));
        }
        if inner.queue.len() >= self.capacity {
            return Err((SubmitError::Full(self.capacity), job));
        }
        Ok(self.push(&mut inner, job))
    }

    /// Queue a question (never waits: questions are few and small). Refused
    /// once closed.
    pub fn ask(&self, ask: A) -> Result<(), SubmitError> {
        let mut inner = self.inner.lock().expect("job queue lock");
        if inner.closed {
            return Err(SubmitError::Closed);
        }
        inner.asks.push_back(ask);
        self.changed.notify_all();
        Ok(())
    }

    /// The questions asked so far, without waiting.
    pub fn take_asks(&self) -> Vec<A> {
        self.inner.lock().expect("job queue lock").asks.drain(..).collect()
    }

    /// The next question or job (questions first), waiting for one; None
    /// once closed with no job left.
    pub fn pop(&self) -> Option<Work<A>> {
        let mut inner = self.inner.lock().expect("job queue lock");
        loop {
            if let Some(a) = inner.asks.pop_front() {
                return Some(Work::Ask(a));
            }
            if let Some(t) = inner.queue.pop_front() {
                self.changed.notify_all();
                return Some(Work::Job(t));
            }
            if inner.closed {
                return None;
            }
            inner = self.changed.wait(inner).expect("job queue lock");
        }
    }

    /// No more jobs: the queued ones are still handed out.
    pub fn close(&self) {
        self.inner.lock().expect("job queue lock").closed = true;
        self.changed.notify_all();
    }

    pub fn len(&self) -> usize {
        self.inner.lock().expect("job queue lock").queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Jobs submitted so far.
    pub fn submitted(&self) -> u64 {
        self.inner.lock().expect("job queue lock").next_seq - 1
    }
}

/// The jobs of a trace's events, with their recorded times (seconds):
/// brushes and mirrors go with the next stroke's `BeginStroke` (its brush
/// carries the mirror planes); layer operations and imports (version 2,
/// spec 14 and 15) are jobs of their own; cameras, lights, renders and
/// snapshots are not jobs.
pub fn from_trace(trace: &octopaint_tree::trace::Trace) -> Vec<(f64, Job)> {
    let mut brush = None;
    let mut mirror = None;
    let mut out = Vec::new();
    for ev in &trace.events {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::Mirror(m) => mirror = m.active(),
            EventKind::StrokeBegin => {
                let b = brush.expect("validated: a brush precedes every stroke");
                out.push((ev.t, Job::BeginStroke(Brush { mirror, ..b })))
            }
            EventKind::Sample(s) => out.push((ev.t, Job::Sample(*s))),
            EventKind::StrokeEnd => out.push((ev.t, Job::EndStroke)),
            EventKind::Undo => out.push((ev.t, Job::Undo)),
            EventKind::Redo => out.push((ev.t, Job::Redo)),
            EventKind::Layer(_) | EventKind::Import(_) => out.push((ev.t, Job::Event(ev.kind.clone()))),
            EventKind::Camera(_) | EventKind::Light(_) | EventKind::Render(_) | EventKind::Snapshot(_) => {}
        }
    }
    out
}
