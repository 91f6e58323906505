//! Replaying a trace (spec 12.3): events in order, a tree dump at every
//! `snapshot`. The trace has been validated whole before the first event
//! runs. Reference twin: reference/octopaint_ref/replay.py.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::dump::dump_bytes_with;
use octopaint_platform::durable;
use crate::g3::g3_table;
use crate::paint::Painting;
use crate::pool::FREE;
use crate::trace::{Brush, Camera, Event, EventKind, Light, Mirror, Trace};

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
    /// After every event, with the painting as that event left it.
    fn after_event(&mut self, _ev: &Event, _painting: &Painting) {}
    /// A `render` event: draw the tree as `camera` sees it, lit by `light`
    /// (None: unlit, spec 6.1), and write `<name>.png` into `out_dir`
    /// (nothing when it is None). Returns the path written, or None when
    /// this observer does not render.
    fn render(&mut self, _name: &str, _camera: &Camera, _light: Option<&Light>, _painting: &mut Painting, _out_dir: Option<&Path>) -> std::io::Result<Option<PathBuf>> {
        Ok(None)
    }
    /// The g3 table a snapshot dumps; None: the CPU port's (g3.rs). The GPU
    /// replay returns the table it read back from the GPU.
    fn dump_g3(&mut self, _painting: &mut Painting) -> std::io::Result<Option<Vec<[u32; 3]>>> {
        Ok(None)
    }
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
    let mut camera: Option<Camera> = None;
    let mut light: Option<Light> = None;
    let mut mirror: Option<Mirror> = None;
    let t0 = Instant::now();
    for ev in &trace.events {
        match &ev.kind {
            EventKind::Brush(b) => brush = Some(*b),
            EventKind::StrokeBegin => {
                let b = brush.as_ref().expect("validated: a brush precedes every stroke");
                painting.begin_stroke(&Brush { mirror, ..*b });
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
                    let g3 = match obs.dump_g3(&mut painting)? {
                        Some(g3) => g3,
                        None => g3_table(&painting.tree),
                    };
                    let path = d.join(format!("{name}.npz"));
                    durable::write(&path, &dump_bytes_with(&painting.tree, &g3))?;
                    stats.written.push(path);
                }
            }
            EventKind::Render(name) => {
                let cam = camera.as_ref().expect("validated: a camera precedes every render");
                match obs.render(name, cam, light.as_ref(), &mut painting, out_dir)? {
                    Some(path) => stats.written.push(path),
                    None => stats.renders.push(name.clone()),
                }
            }
            EventKind::Camera(c) => camera = Some(*c),
            EventKind::Light(l) => light = Some(*l),
            EventKind::Mirror(m) => mirror = m.active(),
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
