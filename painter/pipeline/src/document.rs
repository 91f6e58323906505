//! An open document on the stroke thread: the window's and the headset's
//! canvas. Every job becomes the document events the session checks,
//! journals and applies (`octopaint_doc::Session`, docs/documents.md), so a
//! session through the real-time pipeline records the same trace, and
//! keeps every completed stroke through a crash, as one applied on the
//! frame's thread did; saves run here too, at a stroke boundary, while the
//! front end goes on presenting frames.

use std::time::Instant;

use octopaint_doc::Session;
use octopaint_tree::layers::Document;
use octopaint_tree::trace::{Brush, Event, EventKind, Mirror};

use crate::canvas::{Canvas, Ran, aimed};
use crate::jobs::Job;

pub struct OpenDocument {
    pub session: Session,
    /// The session's clock: event times are seconds since `opened`, after
    /// the document's last event (the trace format's clock never goes
    /// back).
    opened: Instant,
    t_open: f64,
}

impl OpenDocument {
    pub fn new(session: Session) -> OpenDocument {
        let t_open = session.last_time();
        OpenDocument { session, opened: Instant::now(), t_open }
    }

    /// The event time of a job submitted at `submitted`.
    fn time(&self, submitted: Instant) -> f64 {
        self.session.last_time().max(self.t_open + submitted.saturating_duration_since(self.opened).as_secs_f64())
    }

    fn apply(&mut self, kind: EventKind, submitted: Instant) -> Result<(), String> {
        let t = self.time(submitted);
        self.session.apply(&Event { line: 0, t, kind }).map_err(|e| e.to_string())
    }

    fn sample(&mut self, s: octopaint_tree::trace::Sample, submitted: Instant) -> Result<Ran, String> {
        let t = self.time(submitted);
        match self.session.begin_sample(&Event { line: 0, t, kind: EventKind::Sample(s) }) {
            Ok(true) => Ok(Ran::Sample),
            Ok(false) => Ok(Ran::Done),
            Err(e) => Err(e.to_string()),
        }
    }
}

impl Canvas for OpenDocument {
    fn document(&self) -> &Document {
        &self.session.doc
    }

    fn document_mut(&mut self) -> &mut Document {
        &mut self.session.doc
    }

    fn run(&mut self, job: &Job, submitted: Instant) -> Result<Ran, String> {
        match job {
            Job::BeginStroke(b) => {
                // The mirror planes and the brush as events, when they
                // differ from the session's (brushes and mirrors change
                // between strokes), then the stroke.
                if self.session.in_stroke() {
                    return Err("a stroke is already open".into());
                }
                if self.session.mirror() != b.mirror {
                    let canvas = self.session.doc.canvas();
                    let middle = canvas.roots.map(|r| f64::from(r) * canvas.root_size / 2.0);
                    let off = Mirror { axes: [false; 3], centre: self.session.mirror().map_or(middle, |m| m.centre) };
                    self.apply(EventKind::Mirror(b.mirror.unwrap_or(off)), submitted)?;
                }
                let brush = Brush { mirror: None, ..*b };
                if self.session.brush() != Some(&brush) {
                    self.apply(EventKind::Brush(brush), submitted)?;
                }
                self.apply(EventKind::StrokeBegin, submitted)?;
                Ok(Ran::Done)
            }
            // A stroke the session refused to begin (a locked layer, said
            // then) paints nothing: its samples are not refused one by one.
            Job::Sample(_) | Job::Event(EventKind::Sample(_)) if !self.session.in_stroke() => Ok(Ran::Done),
            Job::Sample(s) | Job::Event(EventKind::Sample(s)) => self.sample(*s, submitted),
            Job::Aim(a) => {
                if !self.session.in_stroke() {
                    // The stroke was refused (a locked layer): said then.
                    return Ok(Ran::Done);
                }
                let s = aimed(&self.session.doc, a);
                self.sample(s, submitted)
            }
            // A stroke the session refused to begin has nothing to end.
            Job::EndStroke | Job::Event(EventKind::StrokeEnd) if !self.session.in_stroke() => Ok(Ran::Done),
            Job::EndStroke => self.apply(EventKind::StrokeEnd, submitted).map(|()| Ran::Done),
            Job::Undo => self.apply(EventKind::Undo, submitted).map(|()| Ran::Done),
            Job::Redo => self.apply(EventKind::Redo, submitted).map(|()| Ran::Done),
            Job::Event(kind) => self.apply(kind.clone(), submitted).map(|()| Ran::Done),
            Job::Save => {
                let t0 = Instant::now();
                self.session.save().map_err(|e| format!("save failed: {e}"))?;
                Ok(Ran::Said(format!("saved {} ({:.0} ms)", self.session.path.display(), t0.elapsed().as_secs_f64() * 1e3)))
            }
            Job::UseLayers => {
                self.session.upgrade_to_layers().map_err(|e| format!("cannot make layers: {e}"))?;
                Ok(Ran::Said("this document now has layers (saved)".into()))
            }
        }
    }

    fn in_stroke(&self) -> bool {
        self.session.in_stroke()
    }

    fn version(&self) -> u32 {
        self.session.version
    }

    fn forgotten(&self) -> usize {
        self.session.forgotten
    }

    fn session(&self) -> Option<&Session> {
        Some(&self.session)
    }
}
