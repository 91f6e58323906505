//! Replaying a trace (spec 12.3): events in order, a tree dump at every
//! `snapshot`. The trace has been validated whole before the first event
//! runs. Reference twin: reference/octopaint_ref/replay.py.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::dump::write_dump;
use crate::layers::Document;
use crate::paint::Painting;
use crate::pool::{FREE, Tree};
use crate::trace::{Brush, Camera, Event, EventKind, Light, Mirror, Trace};
use octopaint_platform::durable;

#[derive(Debug, Default)]
pub struct ReplayStats {
    pub samples: u64,
    pub strokes: u64,
    pub seconds: f64,
    pub cells: u32,
    pub deepest: u32,
    pub written: Vec<PathBuf>,
    pub warnings: Vec<String>,
    /// `render` events the observer did not draw.
    pub renders: Vec<String>,
}

/// What a replay reports as it goes.
pub trait ReplayObserver {
    /// A warning, as soon as it happens.
    fn warning(&mut self, _msg: &str) {}
    /// After every event, with the selected layer's painting as that event
    /// left it.
    fn after_event(&mut self, _ev: &Event, _painting: &Painting) {}
    /// A `render` event: draw the document as `camera` sees it, lit by
    /// `light` (None: unlit, spec 6.1; several layers: spec 6.2), and write
    /// `<name>.png` into `out_dir` (nothing when it is None), and more
    /// images where the observer draws several levels of detail (spec 7;
    /// `octopaint replay --lod`). Returns the paths written, none when this
    /// observer does not render.
    fn render(&mut self, _name: &str, _camera: &Camera, _light: Option<&Light>, _doc: &mut Document, _out_dir: Option<&Path>) -> std::io::Result<Vec<PathBuf>> {
        Ok(Vec::new())
    }
    /// The g3 table a snapshot of a version 1 trace dumps; None: the CPU
    /// port's (g3.rs). The GPU replay returns the table it read back from
    /// the GPU. (A document's dump, spec 14.5, takes the CPU port's.)
    fn dump_g3(&mut self, _painting: &mut Painting) -> std::io::Result<Option<Vec<[u32; 3]>>> {
        Ok(None)
    }
}

impl ReplayObserver for () {}

/// Replay `trace`, writing `<name>.npz` into `out_dir` at snapshots (nothing
/// when it is None). Returns the painting of the selected layer as the trace
/// left it (the only one of a version 1 trace).
pub fn replay(trace: &Trace, out_dir: Option<&Path>, obs: &mut dyn ReplayObserver) -> std::io::Result<(ReplayStats, Painting)> {
    let (stats, doc) = replay_document(trace, out_dir, obs)?;
    Ok((stats, doc.into_current_painting()))
}

/// [`replay`], returning the whole document (spec 14).
pub fn replay_document(trace: &Trace, out_dir: Option<&Path>, obs: &mut dyn ReplayObserver) -> std::io::Result<(ReplayStats, Document)> {
    replay_document_within(trace, out_dir, obs, None)
}

/// [`replay_document`] keeping at most `undo_bytes` of undo history, as a
/// document session does (its oldest steps forgotten after every stroke,
/// `Document::trim_to`); None keeps it all. A recorded session replays to
/// the same document either way (an undo the session recorded took a step
/// it still held), in bounded memory this way (`bench soak`).
pub fn replay_document_within(
    trace: &Trace,
    out_dir: Option<&Path>,
    obs: &mut dyn ReplayObserver,
    undo_bytes: Option<usize>,
) -> std::io::Result<(ReplayStats, Document)> {
    let mut stats = ReplayStats::default();
    for w in &trace.warnings {
        obs.warning(w);
        stats.warnings.push(w.clone());
    }
    if let Some(d) = out_dir {
        std::fs::create_dir_all(d)?;
    }
    let mut doc = Document::new(&trace.canvas);
    let mut brush = None;
    let mut camera: Option<Camera> = None;
    let mut light: Option<Light> = None;
    let mut mirror: Option<Mirror> = None;
    let mut writer = DumpWriter::default();
    let t0 = Instant::now();
    for (k, ev) in trace.events.iter().enumerate() {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::StrokeBegin => {
                let b = brush.as_ref().expect("validated: a brush precedes every stroke");
                doc.begin_stroke(&Brush { mirror, ..*b }, ev.line);
                stats.strokes += 1;
            }
            EventKind::Sample(s) => {
                doc.add_sample(s, ev.line);
                stats.samples += 1;
            }
            EventKind::StrokeEnd => {
                doc.end_stroke();
                if let Some(bound) = undo_bytes {
                    doc.trim_to(bound);
                }
            }
            EventKind::Undo => {
                doc.undo();
            }
            EventKind::Redo => {
                doc.redo();
            }
            EventKind::Layer(op) => {
                doc.apply(op, ev.line);
            }
            EventKind::Import(imp) => {
                doc.import_voxels(&imp.voxels, ev.line);
            }
            EventKind::Snapshot(name) => {
                if let Some(d) = out_dir {
                    // Inside a stroke its writes have not reached their
                    // ancestors yet (spec 4.4); only the selected layer is
                    // painted.
                    doc.current_mut().painting.update_prefilter();
                    let path = d.join(format!("{name}.npz"));
                    if trace.version == 2 {
                        writer.write(path.clone(), doc.dump_bytes())?;
                    } else {
                        let painting = &mut doc.current_mut().painting;
                        let g3 = obs.dump_g3(painting)?;
                        writer.write_tree(path.clone(), &painting.tree, g3, k + 1 == trace.events.len())?;
                    }
                    stats.written.push(path);
                }
            }
            EventKind::Render(name) => {
                let cam = camera.as_ref().expect("validated: a camera precedes every render");
                let paths = obs.render(name, cam, light.as_ref(), &mut doc, out_dir)?;
                if paths.is_empty() {
                    stats.renders.push(name.clone());
                }
                stats.written.extend(paths);
            }
            EventKind::Camera(c) => camera = Some(*c),
            EventKind::Light(l) => light = Some(*l),
            EventKind::Mirror(m) => mirror = m.active(),
        }
        for w in doc.take_warnings() {
            obs.warning(&w);
            stats.warnings.push(w);
        }
        obs.after_event(ev, &doc.current().painting);
    }
    writer.finish()?;
    stats.seconds = t0.elapsed().as_secs_f64();
    stats.cells = doc.used().min(u64::from(u32::MAX)) as u32;
    stats.deepest = doc.layers().flat_map(|l| l.tree().depth().iter()).filter(|&&d| d != FREE).map(|&d| u32::from(d)).max().unwrap_or(0);
    Ok((stats, doc))
}

/// Writes dumps on a thread of its own, one at a time: a dump's durable
/// write (most of it is the file's sync), and for a tree given by its
/// pools the dump itself, go on while the events after its snapshot run. The next snapshot, the end of the replay, or dropping the
/// writer (an error elsewhere) waits for the one in flight, so a failed
/// write is reported before anything else is written, and no temporary
/// file is left behind by a thread cut short.
#[derive(Default)]
struct DumpWriter {
    pending: Option<std::thread::JoinHandle<std::io::Result<()>>>,
}

impl DumpWriter {
    /// Wait for the dump in flight, then start writing `bytes` to `path`.
    fn write(&mut self, path: PathBuf, bytes: Vec<u8>) -> std::io::Result<()> {
        self.start(move || durable::write(&path, &bytes))
    }

    /// Wait for the dump in flight, then write the dump of `tree` with the
    /// g3 table `g3` (None: the CPU port's) to `path`, streamed into the
    /// file. The writer thread works on a copy of the tree's records (16
    /// bytes a cell, a few ms) while the events after the snapshot run;
    /// after the trace's `last` event nothing is left to overlap, so the
    /// dump is made here, from the pools themselves.
    fn write_tree(&mut self, path: PathBuf, tree: &Tree, g3: Option<Vec<[u32; 3]>>, last: bool) -> std::io::Result<()> {
        let dump = |path: &Path, tree: &Tree, g3: Option<&[[u32; 3]]>| durable::write_with(path, |w| write_dump(w, tree, g3).map(drop)).map(drop);
        if last {
            self.finish()?;
            return dump(&path, tree, g3.as_deref());
        }
        let tree = tree.records_copy();
        self.start(move || dump(&path, &tree, g3.as_deref()))
    }

    /// Wait for the dump in flight, then run `job` on the writer's thread.
    fn start(&mut self, job: impl FnOnce() -> std::io::Result<()> + Send + 'static) -> std::io::Result<()> {
        self.finish()?;
        self.pending = Some(std::thread::Builder::new().name("dump writer".into()).spawn(job)?);
        Ok(())
    }

    /// Wait for the dump in flight; its error, if it failed.
    fn finish(&mut self) -> std::io::Result<()> {
        match self.pending.take() {
            Some(h) => h.join().map_err(|_| std::io::Error::other("the dump writer panicked"))?,
            None => Ok(()),
        }
    }
}

impl Drop for DumpWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A snapshot's dump, computed on the writer thread from a copy of the
    /// pools and streamed into its file (the first), or from the pools
    /// themselves when it is the trace's last event (the second), has the
    /// bytes of the tree's dump made in memory on the painting thread, at
    /// the snapshot and at the end; a stroke painted after the first
    /// snapshot does not reach it.
    #[test]
    fn snapshots_written_from_the_pools_are_the_trees_dumps() {
        let trace = concat!(
            r#"{"format": "ddo-trace", "version": 1, "canvas": {"roots": [2, 1, 1], "max_depth": 7, "root_size": 1.0, "capacity": 65536}}"#,
            "\n",
            r#"{"ev": "brush", "t": 0.1, "shape": "sphere", "mode": "paint", "radius": 0.2, "color": [0.9, 0.3, 0.1], "opacity": 0.9, "hardness": 0.6}"#,
            "\n",
            r#"{"ev": "stroke_begin", "t": 0.2}"#,
            "\n",
            r#"{"ev": "sample", "t": 0.2, "p": [0.5, 0.5, 0.5]}"#,
            "\n",
            r#"{"ev": "sample", "t": 0.3, "p": [1.2, 0.4, 0.5]}"#,
            "\n",
            r#"{"ev": "stroke_end", "t": 0.4}"#,
            "\n",
            r#"{"ev": "snapshot", "t": 0.5, "name": "first"}"#,
            "\n",
            r#"{"ev": "brush", "t": 0.6, "shape": "box", "mode": "recolor", "radius": 0.15, "color": [0.1, 0.8, 0.2], "opacity": 0.7, "hardness": 0.5}"#,
            "\n",
            r#"{"ev": "stroke_begin", "t": 0.7}"#,
            "\n",
            r#"{"ev": "sample", "t": 0.7, "p": [0.6, 0.5, 0.5]}"#,
            "\n",
            r#"{"ev": "sample", "t": 0.8, "p": [1.0, 0.6, 0.4]}"#,
            "\n",
            r#"{"ev": "stroke_end", "t": 0.9}"#,
            "\n",
            r#"{"ev": "snapshot", "t": 1.0, "name": "last"}"#,
            "\n",
        );
        let trace = crate::trace::parse_trace_bytes(trace.as_bytes()).unwrap();
        let first: Vec<_> = trace.events.iter().take_while(|e| !matches!(e.kind, EventKind::Snapshot(_))).cloned().collect();
        let (_, before) = replay(&crate::trace::Trace { events: first, ..trace.clone() }, None, &mut ()).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let (stats, after) = replay(&trace, Some(dir.path()), &mut ()).unwrap();
        assert_eq!(stats.written, [dir.path().join("first.npz"), dir.path().join("last.npz")]);
        let (a, b) = (std::fs::read(&stats.written[0]).unwrap(), std::fs::read(&stats.written[1]).unwrap());
        assert_eq!(a, crate::dump::dump_bytes(&before.tree));
        assert_eq!(b, crate::dump::dump_bytes(&after.tree));
        assert_ne!(a, b, "the second stroke changed the tree");
    }

    /// A dump that cannot be written is reported when the next snapshot
    /// (or the end) comes, before that one is started; a writer dropped
    /// with a dump in flight lets it finish.
    #[test]
    fn a_failed_dump_write_is_reported_before_the_next_starts() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = DumpWriter::default();
        w.write(dir.path().join("missing").join("a.npz"), vec![1, 2, 3]).unwrap();
        let err = w.write(dir.path().join("b.npz"), vec![4]).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::NotFound);
        assert!(!dir.path().join("b.npz").exists());
        w.write(dir.path().join("c.npz"), vec![5; 1 << 20]).unwrap();
        drop(w);
        assert_eq!(std::fs::read(dir.path().join("c.npz")).unwrap(), vec![5; 1 << 20]);
        // Nothing else in the folder: no temporary file left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["c.npz"]);
    }
}
