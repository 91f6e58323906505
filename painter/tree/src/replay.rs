//! Replaying a trace (spec 12.3): events in order, a tree dump at every
//! `snapshot`. The trace has been validated whole before the first event
//! runs. Reference twin: reference/octopaint_ref/replay.py.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::dump::{dump_bytes, write_atomic};
use crate::paint::Painting;
use crate::pool::FREE;
use crate::trace::{Event, EventKind, Trace};

#[derive(Debug, Default)]
pub struct ReplayStats {
    pub samples: u64,
    pub strokes: u64,
    pub seconds: f64,
    pub cells: u32,
    pub deepest: u32,
    pub written: Vec<PathBuf>,
    pub warnings: Vec<String>,
    /// `render` events: the painter core draws nothing (the GPU pipeline does).
    pub renders: Vec<String>,
}

/// What a replay reports as it goes.
pub trait ReplayObserver {
    /// A warning, as soon as it happens.
    fn warning(&mut self, _msg: &str) {}
    /// After every event, with the painting as that event left it.
    fn after_event(&mut self, _ev: &Event, _painting: &Painting) {}
}

impl ReplayObserver for () {}

/// Replay `trace`, writing `<name>.npz` into `out_dir` at snapshots (nothing
/// when it is None). Returns the painting as the trace left it.
pub fn replay(
    trace: &Trace,
    out_dir: Option<&Path>,
    obs: &mut dyn ReplayObserver,
) -> std::io::Result<(ReplayStats, Painting)> {
    let mut stats = ReplayStats::default();
    for w in &trace.warnings {
        obs.warning(w);
        stats.warnings.push(w.clone());
    }
    if let Some(d) = out_dir {
        std::fs::create_dir_all(d)?;
    }
    let mut painting = Painting::new(&trace.canvas);
    let mut brush = None;
    let t0 = Instant::now();
    for ev in &trace.events {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::StrokeBegin => {
                painting.begin_stroke(brush.as_ref().expect("validated: a brush precedes every stroke"));
                stats.strokes += 1;
            }
            EventKind::Sample(s) => {
                painting.add_sample(s, ev.line);
                stats.samples += 1;
            }
            EventKind::StrokeEnd => painting.end_stroke(),
            EventKind::Undo => {
                painting.undo();
            }
            EventKind::Redo => {
                painting.redo();
            }
            EventKind::Snapshot(name) => {
                if let Some(d) = out_dir {
                    let path = d.join(format!("{name}.npz"));
                    write_atomic(&path, &dump_bytes(&painting.tree))?;
                    stats.written.push(path);
                }
            }
            EventKind::Render(name) => stats.renders.push(name.clone()),
            EventKind::Camera(_) => {}
        }
        for w in painting.warnings.drain(..) {
            obs.warning(&w);
            stats.warnings.push(w);
        }
        obs.after_event(ev, &painting);
    }
    stats.seconds = t0.elapsed().as_secs_f64();
    let t = &painting.tree;
    stats.cells = t.n_used();
    stats.deepest = t.depth.iter().filter(|&&d| d != FREE).map(|&d| u32::from(d)).max().unwrap_or(0);
    Ok((stats, painting))
}
