//! The stroke job queue (docs/architecture.md): what the input side hands
//! to the stroke thread. Bounded; when it is full, `submit` waits for room
//! (back-pressure on the input) and `try_submit` gives the job back: a job
//! is never dropped or merged, because every sample changes the painting.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};
use std::time::Instant;

use octopaint_tree::trace::{Brush, Sample};

/// One unit of work for the stroke thread.
#[derive(Clone, Debug)]
pub enum Job {
    BeginStroke(Brush),
    Sample(Sample),
    EndStroke,
    Undo,
    Redo,
}

impl Job {
    pub fn name(&self) -> &'static str {
        match self {
            Job::BeginStroke(_) => "stroke_begin",
            Job::Sample(_) => "sample",
            Job::EndStroke => "stroke_end",
            Job::Undo => "undo",
            Job::Redo => "redo",
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

struct Inner {
    queue: VecDeque<Ticket>,
    next_seq: u64,
    closed: bool,
}

pub struct JobQueue {
    capacity: usize,
    inner: Mutex<Inner>,
    changed: Condvar,
}

impl JobQueue {
    pub fn new(capacity: usize) -> JobQueue {
        JobQueue {
            capacity: capacity.max(1),
            inner: Mutex::new(Inner { queue: VecDeque::new(), next_seq: 1, closed: false }),
            changed: Condvar::new(),
        }
    }

    fn push(&self, inner: &mut Inner, job: Job) -> Ticket {
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

    /// The next job, waiting for one; None once closed and empty.
    pub fn pop(&self) -> Option<Ticket> {
        let mut inner = self.inner.lock().expect("job queue lock");
        loop {
            if let Some(t) = inner.queue.pop_front() {
                self.changed.notify_all();
                return Some(t);
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
}

/// The jobs of a trace's events, with their recorded times (seconds):
/// brushes become the next stroke's `BeginStroke`; cameras, renders and
/// snapshots are not jobs. The pipeline paints one tree from brushes: a
/// version 2 trace's layer events (spec 14) and imports (spec 15) are not
/// jobs either, so callers refuse such traces first.
pub fn from_trace(trace: &octopaint_tree::trace::Trace) -> Vec<(f64, Job)> {
    use octopaint_tree::trace::EventKind;
    let mut brush = None;
    let mut mirror = None;
    let mut out = Vec::new();
    for ev in &trace.events {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::Mirror(m) => mirror = m.active(),
            EventKind::StrokeBegin => {
                let b = brush.expect("validated: a brush precedes every stroke");
                out.push((ev.t, Job::BeginStroke(octopaint_tree::trace::Brush { mirror, ..b })))
            }
            EventKind::Sample(s) => out.push((ev.t, Job::Sample(*s))),
            EventKind::StrokeEnd => out.push((ev.t, Job::EndStroke)),
            EventKind::Undo => out.push((ev.t, Job::Undo)),
            EventKind::Redo => out.push((ev.t, Job::Redo)),
            EventKind::Camera(_) | EventKind::Light(_) | EventKind::Render(_) | EventKind::Snapshot(_) | EventKind::Layer(_) | EventKind::Import(_) => {}
        }
    }
    out
}
