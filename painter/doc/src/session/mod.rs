//! A painting session on a document: events applied as they come, every
//! completed stroke journalled to disk before the next one starts, saves
//! that replace the document atomically, and recovery of the journal after
//! a crash (docs/documents.md).
//!
//! The journal `<document>.journal` is a header line naming the document it
//! extends (the CRC of its file and its number of events), then event lines
//! of the trace format. Lines are appended and synced when a stroke ends
//! and at every undo and redo, so a crash loses at most the stroke in
//! progress. Opening a document with a journal replays the journal's
//! complete strokes onto it; saving writes the document (journal included)
//! and starts an empty journal.
//!
//! One session writes a document at a time: [`Session::open`] and the
//! creators take the document's writer lock (`octopaint_platform::lock`)
//! before they read anything, and hold it while the session lives. A
//! session opened with [`Session::open_read`] takes no lock and writes
//! nothing: it reads the saved document and the journal's complete
//! strokes while a writer may be painting.

use std::fs::File;
use std::path::{Path, PathBuf};

use octopaint_platform::{durable, lock};
use octopaint_tree::layers::Document as Layers;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{
    Brush, Canvas, Event, EventKind, Meta, Mirror, Sample, Trace, parse_brush, parse_camera, parse_light, parse_mirror, parse_sample, parse_trace,
    parse_trace_with, segment_too_long,
};
use octopaint_tree::trace_write::{event_line, header_line};

use crate::{DocError, io};

mod import;
use crate::format::{self, Content, Document, Imports};
use crate::journal::{self, journal_path};
use crate::trace_log::TraceLog;

/// Undo history kept by default (the history beyond it is forgotten,
/// oldest strokes first).
pub const DEFAULT_UNDO_BYTES: usize = 1 << 30;

pub struct Session {
    pub path: PathBuf,
    /// What the session paints: one layer for a one-tree document (a
    /// version 1 session), the layers of a version 2 one (spec 14).
    pub doc: Layers,
    /// The session's trace version: 1 one tree, 2 layers.
    pub version: u32,
    /// The session's trace: header and the events committed so far (the
    /// saved ones deflated once sealed).
    trace: TraceLog,
    /// The voxel sets its `import` events name (spec 15), by file.
    imports: Imports,
    events: usize,
    /// Lines of events since the last journal flush.
    pending: Vec<String>,
    journal: Option<File>,
    /// An append failed: what it wrote of its lines may be in the file,
    /// so the next flush writes the journal whole ([`journal::rewrite`]).
    journal_torn: bool,
    base_crc: u32,
    base_events: usize,
    brush: Option<Brush>,
    last_sample: Option<Sample>,
    has_camera: bool,
    /// The last `mirror` event's planes (spec 8.11), for the next strokes.
    mirror: Option<Mirror>,
    /// The names of the session's renders and snapshots: each is used
    /// once per kind (the trace reader's rule), or the saved session
    /// would not read back.
    render_names: std::collections::HashSet<String>,
    snapshot_names: std::collections::HashSet<String>,
    in_stroke: bool,
    last_t: f64,
    /// History bound in bytes.
    pub undo_bytes: usize,
    /// Complete strokes (and undos, redos) the journal gave back at open.
    pub recovered: usize,
    /// Undo steps forgotten to stay within `undo_bytes`.
    pub forgotten: usize,
    /// The document's writer lock; None for a session opened to read.
    lock: Option<lock::WriterLock>,
}

/// Take `doc`'s writer lock, or say who holds it.
fn writer_lock(doc: &Path) -> Result<lock::WriterLock, DocError> {
    lock::acquire(doc).map_err(|e| match e {
        lock::LockError::Held { pid, .. } => DocError::Locked { doc: doc.to_path_buf(), pid },
        lock::LockError::Io { path, error } => io(&path)(error),
    })
}

impl Session {
    /// A new, empty document at `path` (refused if a file is there).
    pub fn create(path: &Path, canvas: &Canvas, meta: &Meta) -> Result<Session, DocError> {
        if path.exists() {
            return Err(DocError::Exists(path.to_path_buf()));
        }
        let trace_text = header_line(canvas, meta);
        let trace = parse_trace(&trace_text).map_err(|e| DocError::BadEvent(e.to_string()))?;
        let lock = writer_lock(path)?;
        // Another writer may have made it while this one waited for nothing.
        if path.exists() {
            return Err(DocError::Exists(path.to_path_buf()));
        }
        let doc = Layers::new(&trace.canvas);
        let mut s = Session::from_parts(path, doc, trace.version, trace_text, 0, 0);
        s.lock = Some(lock);
        s.save()?;
        Ok(s)
    }

    /// A new, empty document of layers at `path` (a version 2 session,
    /// spec 14), refused if a file is there.
    pub fn create_layered(path: &Path, canvas: &Canvas, meta: &Meta) -> Result<Session, DocError> {
        if path.exists() {
            return Err(DocError::Exists(path.to_path_buf()));
        }
        let trace_text = octopaint_tree::trace_write::header_line_version(canvas, meta, 2);
        let trace = parse_trace(&trace_text).map_err(|e| DocError::BadEvent(e.to_string()))?;
        let lock = writer_lock(path)?;
        if path.exists() {
            return Err(DocError::Exists(path.to_path_buf()));
        }
        let mut s = Session::from_parts(path, Layers::new(&trace.canvas), 2, trace_text, 0, 0);
        s.lock = Some(lock);
        s.save()?;
        Ok(s)
    }

    /// Make a one-tree document a document of layers (spec 14): its session
    /// becomes a version 2 trace (every version 1 event reads the same in
    /// version 2, and replays to the same one layer, `Layer 1`), and it is
    /// saved at once in format version 2, so that its journal only ever
    /// extends a document that takes layer events. Nothing happens to a
    /// document of layers; refused inside a stroke.
    pub fn upgrade_to_layers(&mut self) -> Result<(), DocError> {
        if self.version == 2 {
            return Ok(());
        }
        self.check_writable()?;
        if self.in_stroke {
            return Err(DocError::BadEvent("cannot make layers inside a stroke: end it first".into()));
        }
        let whole = self.trace.text().map_err(io(&self.path))?;
        let (head, rest) = whole.split_once('\n').map_or((whole.as_str(), ""), |(h, r)| (h, r));
        let trace = parse_trace(head).map_err(|e| DocError::BadEvent(e.to_string()))?;
        let mut text = octopaint_tree::trace_write::header_line_version(&trace.canvas, &trace.meta, 2);
        if !rest.is_empty() {
            text.push('\n');
            text.push_str(rest);
        }
        let old = std::mem::replace(&mut self.trace, TraceLog::new(text));
        self.version = 2;
        if let Err(e) = self.save() {
            self.trace = old;
            self.version = 1;
            return Err(e);
        }
        Ok(())
    }

    /// The selected layer's painting (the only one of a one-tree document).
    pub fn painting(&self) -> &Painting {
        &self.doc.current().painting
    }

    pub fn painting_mut(&mut self) -> &mut Painting {
        &mut self.doc.current_mut().painting
    }

    fn from_parts(path: &Path, doc: Layers, version: u32, trace_text: String, events: usize, crc: u32) -> Session {
        Session {
            path: path.to_path_buf(),
            doc,
            version,
            trace: TraceLog::new(trace_text),
            imports: Imports::new(),
            events,
            pending: Vec::new(),
            journal: None,
            journal_torn: false,
            base_crc: crc,
            base_events: events,
            brush: None,
            last_sample: None,
            has_camera: false,
            mirror: None,
            render_names: Default::default(),
            snapshot_names: Default::default(),
            in_stroke: false,
            last_t: 0.0,
            undo_bytes: DEFAULT_UNDO_BYTES,
            recovered: 0,
            forgotten: 0,
            lock: None,
        }
    }

    /// Open a document to paint it, replaying the complete strokes of its
    /// journal (a crash's leftovers) onto it. The journal is kept until the
    /// next save. Refused at once, before anything is read, while another
    /// session has the document open ([`DocError::Locked`]).
    pub fn open(path: &Path) -> Result<Session, DocError> {
        let lock = writer_lock(path)?;
        let data = std::fs::read(path).map_err(io(path))?;
        let jp = journal_path(path);
        let journal = journal::read(&jp)?;
        let mut s = Session::from_bytes(path, &data, journal.as_deref())?;
        s.lock = Some(lock);
        Ok(s)
    }

    /// Open a document to read it, as [`Session::open`] would find it,
    /// without its writer lock: the saved document and its journal's
    /// complete strokes, while a writer may be painting. A session so
    /// opened writes nothing ([`DocError::ReadOnly`]). A save that replaces
    /// the document between the two reads is seen (the document's size or
    /// time changed) and both are read again.
    pub fn open_read(path: &Path) -> Result<Session, DocError> {
        let jp = journal_path(path);
        let stamp = |p: &Path| std::fs::metadata(p).map(|m| (m.len(), m.modified().ok())).map_err(io(p));
        let mut tries = 0;
        loop {
            let before = stamp(path)?;
            let data = std::fs::read(path).map_err(io(path))?;
            let journal = journal::read(&jp)?;
            tries += 1;
            if stamp(path)? == before || tries == 5 {
                return Session::from_bytes(path, &data, journal.as_deref());
            }
        }
    }

    /// A session of the document `data` read from `path`, with the
    /// journal's bytes when there is one; it writes nothing (as
    /// [`Session::open_read`]).
    pub fn from_bytes(path: &Path, data: &[u8], journal: Option<&[u8]>) -> Result<Session, DocError> {
        let loaded = format::read(data)?;
        let Document { trace_text, content, imports, .. } = loaded.doc;
        let trace = loaded.trace;
        let doc = match content {
            Content::Tree { tree, history } => Layers::from_painting(&trace.canvas, Painting::from_parts(tree, history)),
            Content::Layers(doc) => doc,
        };
        let mut s = Session::from_parts(path, doc, trace.version, trace_text, trace.events.len(), loaded.crc);
        s.imports = imports;
        s.resume_state(&trace);
        if let Some(bytes) = journal {
            s.recover(&journal_path(path), bytes)?;
        }
        Ok(s)
    }

    /// Whether this session may write its document (it holds the lock).
    pub fn writable(&self) -> bool {
        self.lock.is_some()
    }

    fn check_writable(&self) -> Result<(), DocError> {
        if self.lock.is_some() { Ok(()) } else { Err(DocError::ReadOnly(self.path.clone())) }
    }

    /// The brush, camera and clock the session's events leave.
    fn resume_state(&mut self, trace: &Trace) {
        for ev in &trace.events {
            self.remember(ev);
        }
    }

    /// What an event leaves for the events after it: the brush, a camera
    /// seen, the mirror planes, the names of renders and snapshots, the
    /// clock (the same for an event painted and one read at open).
    fn remember(&mut self, ev: &Event) {
        match &ev.kind {
            EventKind::Brush(b) => self.brush = Some(*b),
            EventKind::Camera(_) => self.has_camera = true,
            EventKind::Mirror(m) => self.mirror = m.active(),
            EventKind::Render(n) => {
                self.render_names.insert(n.clone());
            }
            EventKind::Snapshot(n) => {
                self.snapshot_names.insert(n.clone());
            }
            _ => {}
        }
        self.last_t = ev.t;
    }

    fn recover(&mut self, jp: &Path, bytes: &[u8]) -> Result<(), DocError> {
        let text = String::from_utf8_lossy(bytes);
        let Some(journal::Read { crc, base, body }) = journal::parse(jp, &text)? else {
            return Ok(()); // created, nothing written yet
        };
        let body = &body[..];
        if crc != self.base_crc || base != self.events {
            // Saved already (the crash came between the save and the new
            // journal)? Then the document holds these events.
            let text = self.trace.text().map_err(io(jp))?;
            let saved: Vec<&str> = text.lines().skip(1).collect();
            if base + body.len() <= saved.len() && saved[base..base + body.len()] == *body {
                return Ok(());
            }
            return Err(DocError::Journal {
                path: jp.to_path_buf(),
                why: "it extends another version of this document; move it away to open the document as saved".into(),
            });
        }
        if body.is_empty() {
            return Ok(());
        }
        let mut all = self.trace.text().map_err(io(jp))?;
        for l in body {
            all.push('\n');
            all.push_str(l);
        }
        let trace = {
            let resolve = format::resolver(&self.imports);
            parse_trace_with(&all, Some(&resolve)).map_err(|e| DocError::Journal { path: jp.to_path_buf(), why: format!("its events do not read: {e}") })?
        };
        for ev in &trace.events[self.events..] {
            self.apply_parsed(ev);
            if matches!(ev.kind, EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo | EventKind::Layer(_)) {
                self.recovered += 1;
            }
        }
        for l in body {
            self.trace.push(l);
        }
        self.events = trace.events.len();
        // The journal stays as it is: it still extends the saved document.
        self.pending.clear();
        Ok(())
    }

    fn apply_parsed(&mut self, ev: &Event) {
        self.remember(ev);
        match &ev.kind {
            // Remembered above; nothing to paint.
            EventKind::Brush(_) | EventKind::Camera(_) | EventKind::Mirror(_) | EventKind::Render(_) | EventKind::Snapshot(_) | EventKind::Light(_) => {}
            EventKind::StrokeBegin => {
                let b = self.brush.as_ref().expect("validated");
                self.doc.begin_stroke(&Brush { mirror: self.mirror, ..*b }, ev.line);
                self.in_stroke = true;
                self.last_sample = None;
            }
            EventKind::Sample(s) => {
                self.doc.add_sample(s, 0);
                self.last_sample = Some(*s);
            }
            EventKind::StrokeEnd => {
                self.doc.end_stroke();
                self.in_stroke = false;
                self.forgotten += self.doc.trim_to(self.undo_bytes);
            }
            EventKind::Undo => {
                self.doc.undo();
            }
            EventKind::Redo => {
                self.doc.redo();
            }
            // The reader took it (a version 2 session): applied to the
            // layers; one the budget refuses is skipped with a warning
            // (spec 14.2), as in a replay.
            EventKind::Layer(op) => {
                self.doc.apply(op, ev.line);
            }
            // Imports are saved as they happen, never journalled (see
            // Session::import); one in a journal is a damaged journal.
            EventKind::Import(imp) => {
                self.doc.import_voxels(&imp.voxels, ev.line);
            }
        }
    }

    /// The time of the last event (the next must not be earlier).
    pub fn last_time(&self) -> f64 {
        self.last_t
    }

    pub fn in_stroke(&self) -> bool {
        self.in_stroke
    }

    pub fn brush(&self) -> Option<&Brush> {
        self.brush.as_ref()
    }

    /// The mirror planes the next stroke paints with (spec 8.11).
    pub fn mirror(&self) -> Option<Mirror> {
        self.mirror
    }

    /// Bytes the session's trace takes in memory (`bench soak`'s figure).
    pub fn trace_bytes(&self) -> usize {
        self.trace.bytes() + self.pending.iter().map(String::len).sum::<usize>()
    }

    /// Events in the session, saved or not.
    pub fn event_count(&self) -> usize {
        self.events + self.pending.len()
    }

    /// Apply one event as the painter produces it, with the trace reader's
    /// rules on its values and its place (a sample inside a stroke, a
    /// brush before a stroke, time not going back). A refused event changes
    /// nothing. Undo and redo with nothing to undo or redo are not events.
    pub fn apply(&mut self, ev: &Event) -> Result<(), DocError> {
        self.check_writable()?;
        let bad = |m: String| Err(DocError::BadEvent(m));
        if !(ev.t.is_finite() && ev.t >= self.last_t) {
            return bad(format!("time {} goes back (last {})", ev.t, self.last_t));
        }
        let line = event_line(ev);
        let obj: serde_json::Value = serde_json::from_str(&line).map_err(|_| DocError::BadEvent("unwritable event".into()))?;
        let check = |r: Result<(), octopaint_tree::TraceError>| r.map_err(|e| DocError::BadEvent(e.to_string()));
        match &ev.kind {
            EventKind::Brush(_) if self.in_stroke => return bad("brush inside a stroke (brushes change between strokes)".into()),
            EventKind::Brush(_) => check(parse_brush(0, &obj).map(drop))?,
            EventKind::StrokeBegin if self.in_stroke => return bad("stroke_begin inside a stroke".into()),
            EventKind::StrokeBegin if self.brush.is_none() => return bad("stroke_begin before any brush event".into()),
            EventKind::Sample(s) => self.check_sample(s, &obj)?,
            EventKind::StrokeEnd if !self.in_stroke => return bad("stroke_end outside a stroke".into()),
            EventKind::Undo | EventKind::Redo if self.in_stroke => return bad("undo or redo inside a stroke".into()),
            EventKind::Camera(_) => check(parse_camera(0, &obj).map(drop))?,
            EventKind::Light(_) => check(parse_light(0, &obj).map(drop))?,
            EventKind::Mirror(_) if self.in_stroke => return bad("mirror inside a stroke (mirror planes change between strokes)".into()),
            EventKind::Mirror(_) => check(parse_mirror(0, &obj).map(drop))?,
            EventKind::Render(n) | EventKind::Snapshot(n) if !octopaint_tree::trace::is_valid_name(n) => return bad(format!("name {n:?}")),
            EventKind::Render(n) if self.render_names.contains(n) => return bad(format!("name \"{n}\" is already used by an earlier render")),
            EventKind::Snapshot(n) if self.snapshot_names.contains(n) => return bad(format!("name \"{n}\" is already used by an earlier snapshot")),
            EventKind::Render(_) if !self.has_camera => return bad("render before any camera event".into()),
            EventKind::Layer(_) if self.version != 2 => {
                return bad("layer events need a document of layers (octopaint new --layers, or a version 2 trace imported)".into());
            }
            EventKind::Layer(_) if self.in_stroke => return bad("layer inside a stroke (layers change between strokes)".into()),
            EventKind::Layer(_) => check(octopaint_tree::trace::parse_layer(0, &obj).map(drop))?,
            EventKind::Import(_) if self.in_stroke => return bad("import inside a stroke (imports come between strokes)".into()),
            EventKind::Import(_) if self.doc.current().locked => {
                return bad(format!("the selected layer \"{}\" is locked", self.doc.current().name));
            }
            // As a replay paints it (spec 15.3: a budget refusal paints at the
            // resolution reached, with a warning), and saved at once.
            EventKind::Import(imp) => return self.commit_import(&imp.voxels, imp.name.as_deref(), ev.t, false),
            EventKind::StrokeBegin if self.doc.current().locked => {
                return bad(format!("the selected layer \"{}\" is locked", self.doc.current().name));
            }
            _ => {}
        }
        let acted = match &ev.kind {
            EventKind::Undo => self.doc.undo(),
            EventKind::Redo => self.doc.redo(),
            EventKind::Layer(op) => {
                if !self.doc.apply(op, 0) {
                    let why = self.doc.take_warnings().join("; ");
                    return bad(why.trim_start_matches("line 0: ").to_string());
                }
                true
            }
            _ => true,
        };
        if !acted {
            return Ok(());
        }
        if !matches!(ev.kind, EventKind::Undo | EventKind::Redo | EventKind::Layer(_)) {
            self.apply_parsed(ev);
        } else {
            self.last_t = ev.t;
        }
        self.pending.push(line);
        if matches!(ev.kind, EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo | EventKind::Layer(_)) {
            self.flush()?;
        }
        Ok(())
    }

    /// A `sample` event's rules: inside a stroke, its values, its distance
    /// from the previous sample.
    fn check_sample(&self, s: &Sample, obj: &serde_json::Value) -> Result<(), DocError> {
        let bad = |m: &str| Err(DocError::BadEvent(m.to_string()));
        if !self.in_stroke {
            return bad("sample outside a stroke");
        }
        parse_sample(0, obj).map_err(|e| DocError::BadEvent(e.to_string()))?;
        let brush = self.brush.as_ref().expect("a stroke has a brush");
        if let Some(prev) = &self.last_sample
            && segment_too_long(brush, prev, s)
        {
            return bad("this sample is too far from the previous one for the brush (more than 65,536 stamps)");
        }
        Ok(())
    }

    /// [`Session::apply`] for a `sample` event whose levels the caller runs
    /// (`Painting::advance` on `doc.stroke_painting()`, the real-time pipeline
    /// publishing between them): checked and recorded as `apply` records
    /// it, then begun. Ok(false): the stroke paints nothing (its layer
    /// was locked), so no level follows. The caller runs every level
    /// before the next event: the stroke's end journals it.
    pub fn begin_sample(&mut self, ev: &Event) -> Result<bool, DocError> {
        self.check_writable()?;
        let EventKind::Sample(s) = &ev.kind else { return Err(DocError::BadEvent("not a sample".into())) };
        if !(ev.t.is_finite() && ev.t >= self.last_t) {
            return Err(DocError::BadEvent(format!("time {} goes back (last {})", ev.t, self.last_t)));
        }
        let line = event_line(ev);
        let obj: serde_json::Value = serde_json::from_str(&line).map_err(|_| DocError::BadEvent("unwritable event".into()))?;
        self.check_sample(s, &obj)?;
        let began = self.doc.begin_sample(s, 0);
        self.last_sample = Some(*s);
        self.last_t = ev.t;
        self.pending.push(line);
        Ok(began)
    }

    /// Append the pending events to the journal and sync it.
    fn flush(&mut self) -> Result<(), DocError> {
        let jp = journal_path(&self.path);
        let base = (self.base_crc, self.base_events);
        let written = if self.journal_torn {
            // Every event since the document, then the pending ones: the
            // journal replaced whole, as a save replaces the document.
            let since = self.trace.since_lines();
            journal::rewrite(&jp, base, since.chain(self.pending.iter().map(String::as_str)))
        } else {
            journal::append(&mut self.journal, &jp, base, &self.pending)
        };
        if let Err(e) = written {
            // The events stay pending (and applied): the next flush, or a
            // save, writes them again.
            self.journal = None;
            self.journal_torn = true;
            return Err(e);
        }
        self.journal_torn = false;
        for l in self.pending.drain(..) {
            self.trace.push(&l);
            self.events += 1;
        }
        Ok(())
    }

    /// Save the document (the session up to the last completed stroke;
    /// a stroke in progress is saved once it ends) and start a new journal.
    pub fn save(&mut self) -> Result<(), DocError> {
        self.check_writable()?;
        if self.in_stroke {
            return Err(DocError::BadEvent("cannot save inside a stroke: end it first".into()));
        }
        // Brush and camera events since the last stroke go with the save.
        for l in self.pending.drain(..) {
            self.trace.push(&l);
            self.events += 1;
        }
        let meta = format!(
            "{{\"app\": \"octopaint {}\", \"events\": {}, \"cells\": {}, \"layers\": {}, \"undo_steps\": {}}}",
            env!("CARGO_PKG_VERSION"),
            self.events,
            self.doc.used(),
            self.doc.len(),
            self.doc.steps().0
        );
        // The trace deflates only what is new since the last save.
        let folder = match self.path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let trace = self.trace.seal(folder).map_err(io(&self.path))?;
        let written = if self.version == 2 {
            format::write_layers(trace, &self.doc, &meta, &self.imports)
        } else {
            let p = &self.doc.current().painting;
            format::write_with(trace, &p.tree, &p.history, &meta, &self.imports)
        };
        let (bytes, crc) = written.map_err(io(&self.path))?;
        durable::write(&self.path, &bytes).map_err(io(&self.path))?;
        drop(bytes);
        // The document's bytes were a transient peak as large as the
        // document: give the allocator's free pages back (bench soak).
        octopaint_platform::memory::release_free_heap();
        self.trace.saved();
        // The new journal extends the new document; until it exists, the
        // old one's events are all in the document (recover() sees that).
        self.journal = None;
        self.journal_torn = false;
        self.base_crc = crc;
        self.base_events = self.events;
        let jp = journal_path(&self.path);
        if let Err(e) = durable::write(&jp, format!("{}\n", journal::header(crc, self.events)).as_bytes()) {
            // The document is saved, but the journal on disk may still
            // extend the one before it: the next flush writes it whole,
            // naming this one, rather than append to the old one.
            self.journal_torn = true;
            return Err(io(&jp)(e));
        }
        Ok(())
    }

    /// The whole session as a trace: replaying it gives this tree. Its
    /// saved part is read back from the session's spill file (an I/O
    /// error there is the only failure).
    pub fn trace_text(&self) -> Result<String, DocError> {
        let mut t = self.trace.text().map_err(io(&self.path))?;
        for l in &self.pending {
            t.push('\n');
            t.push_str(l);
        }
        t.push('\n');
        Ok(t)
    }
}
