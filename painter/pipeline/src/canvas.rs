//! What the stroke thread paints (docs/architecture.md): a [`Canvas`] is a
//! document of layers with the rules that take jobs into it. Two kinds run
//! on the same threads: an open document (`crate::document::OpenDocument`:
//! the window's and the headset's, every stroke journalled, saves) and a
//! bare one ([`Replay`]: the benchmarks' and tests', a trace's events
//! applied as a replay applies them, nothing on disk).

use std::time::Instant;

use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::trace::{Brush, Canvas as CanvasSize, EventKind, Mirror, Sample};
use octopaint_tree::view::pick;

use glam::DVec3;

use crate::jobs::{Aim, Job};

/// What running a job did.
#[derive(Debug, PartialEq)]
pub enum Ran {
    /// Done: its changes are in the pools (or it changed nothing).
    Done,
    /// A sample began: its levels follow (`Painting::advance` on
    /// `document_mut().stroke_painting()`), each published on its own.
    Sample,
    /// Done, with a line for the artist (a save, a layer made).
    Said(String),
}

/// A document the stroke thread owns and paints.
pub trait Canvas: Send + 'static {
    /// The layers (a one-tree painting is a document of one layer).
    fn document(&self) -> &Document;
    fn document_mut(&mut self) -> &mut Document;
    /// Run `job`, submitted at `submitted`; Err: refused, nothing changed,
    /// with the reason.
    fn run(&mut self, job: &Job, submitted: Instant) -> Result<Ran, String>;
    fn in_stroke(&self) -> bool;
    /// The trace version the document's events are read with: 1 one tree,
    /// 2 layers (spec 14).
    fn version(&self) -> u32;
    /// Steps of undo history forgotten to stay within its bound.
    fn forgotten(&self) -> usize {
        0
    }
    /// The document's session when this canvas is an open document (its
    /// journal, its trace: `bench soak` reads its figures).
    fn session(&self) -> Option<&octopaint_doc::Session> {
        None
    }
}

/// Where a ray from the eye places a sample ([`Aim`]): the surface of the
/// selected layer's paint under it, or the plane distance.
pub fn aimed(doc: &Document, a: &Aim) -> Sample {
    let (eye, dir) = (DVec3::from_array(a.eye), DVec3::from_array(a.dir));
    let t = if a.on_surface { pick(doc.current().tree(), eye, dir).unwrap_or(a.plane_t) } else { a.plane_t };
    Sample::at((eye + dir * t).to_array())
}

/// A bare document: a trace's events applied as `octopaint replay` applies
/// them (a locked layer's stroke and a layer operation the budget refuses
/// are skipped with a warning, spec 14.2), nothing journalled or saved.
#[derive(Clone)]
pub struct Replay {
    pub doc: Document,
    version: u32,
    brush: Option<Brush>,
    mirror: Option<Mirror>,
    in_stroke: bool,
}

impl Replay {
    /// A one-tree painting (version 1).
    pub fn new(painting: Painting) -> Replay {
        let (lat, capacity) = (&painting.tree.lat, painting.tree.capacity);
        let canvas = CanvasSize { roots: lat.roots, max_depth: lat.max_depth, root_size: lat.root_size, capacity };
        Replay::of(Document::from_painting(&canvas, painting), 1)
    }

    /// A document of layers, read with trace version `version`.
    pub fn of(doc: Document, version: u32) -> Replay {
        Replay { doc, version, brush: None, mirror: None, in_stroke: false }
    }

    /// The selected layer's painting (a one-tree document's only one).
    pub fn painting(&self) -> &Painting {
        &self.doc.current().painting
    }

    pub fn painting_mut(&mut self) -> &mut Painting {
        &mut self.doc.current_mut().painting
    }

    /// Apply `job` whole, on the calling thread (a pre-painted scene).
    pub fn apply(&mut self, job: &Job) {
        if let Ok(Ran::Sample) = self.run(job, Instant::now())
            && let Some(p) = self.doc.stroke_painting()
        {
            while !p.advance(None) {}
        }
    }
}

impl Canvas for Replay {
    fn document(&self) -> &Document {
        &self.doc
    }

    fn document_mut(&mut self) -> &mut Document {
        &mut self.doc
    }

    fn run(&mut self, job: &Job, _submitted: Instant) -> Result<Ran, String> {
        let sample = |r: &mut Replay, s: &Sample| {
            if !r.in_stroke {
                return Err("sample outside a stroke".to_string());
            }
            Ok(if r.doc.begin_sample(s, 0) { Ran::Sample } else { Ran::Done })
        };
        match job {
            Job::BeginStroke(b) => {
                if self.in_stroke {
                    return Err("stroke_begin inside a stroke".into());
                }
                self.brush = Some(Brush { mirror: None, ..*b });
                self.mirror = b.mirror;
                self.doc.begin_stroke(b, 0);
                self.in_stroke = true;
                Ok(Ran::Done)
            }
            Job::Sample(s) => sample(self, s),
            Job::Aim(a) => {
                let s = aimed(&self.doc, a);
                sample(self, &s)
            }
            Job::EndStroke | Job::Event(EventKind::StrokeEnd) => {
                if self.in_stroke {
                    self.doc.end_stroke();
                    self.in_stroke = false;
                }
                Ok(Ran::Done)
            }
            Job::Undo | Job::Event(EventKind::Undo) if !self.in_stroke => {
                self.doc.undo();
                Ok(Ran::Done)
            }
            Job::Redo | Job::Event(EventKind::Redo) if !self.in_stroke => {
                self.doc.redo();
                Ok(Ran::Done)
            }
            Job::Undo | Job::Redo | Job::Event(EventKind::Undo | EventKind::Redo) => Err("undo or redo inside a stroke".into()),
            Job::Event(EventKind::Brush(b)) => {
                self.brush = Some(*b);
                Ok(Ran::Done)
            }
            Job::Event(EventKind::Mirror(m)) => {
                self.mirror = m.active();
                Ok(Ran::Done)
            }
            Job::Event(EventKind::StrokeBegin) => match self.brush {
                Some(b) => self.run(&Job::BeginStroke(Brush { mirror: self.mirror, ..b }), _submitted),
                None => Err("stroke_begin before any brush event".into()),
            },
            Job::Event(EventKind::Sample(s)) => sample(self, s),
            Job::Event(EventKind::Layer(op)) if !self.in_stroke && self.version == 2 => {
                self.doc.apply(op, 0);
                Ok(Ran::Done)
            }
            Job::Event(EventKind::Import(imp)) if !self.in_stroke => {
                self.doc.import_voxels(&imp.voxels, 0);
                Ok(Ran::Done)
            }
            Job::Event(EventKind::Layer(_) | EventKind::Import(_)) => Err("layer operations and imports come between strokes, in a document of layers".into()),
            Job::Event(EventKind::Camera(_) | EventKind::Light(_) | EventKind::Render(_) | EventKind::Snapshot(_)) => Ok(Ran::Done),
            Job::Save | Job::UseLayers => Err("a bare painting has no document to save".into()),
        }
    }

    fn in_stroke(&self) -> bool {
        self.in_stroke
    }

    fn version(&self) -> u32 {
        self.version
    }
}

/// One row of the layer list as the front end shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerRow {
    /// The layer's id in the document (stable across moves).
    pub id: u32,
    pub name: String,
    pub visible: bool,
    pub opacity: f32,
    pub locked: bool,
    /// Cells in use in the layer's pools, and the bytes the pools hold.
    pub cells: u32,
    pub bytes: usize,
}

/// What a front end shows of the painting besides the image, published by
/// the stroke thread after every job (docs/architecture.md): never read
/// from the live pools.
#[derive(Clone, Debug, Default)]
pub struct Status {
    pub version: u32,
    pub layers: Vec<LayerRow>,
    pub selected: usize,
    pub undo: usize,
    pub redo: usize,
    /// Cells in use over all layers, and the budget.
    pub used: u64,
    pub capacity: u32,
    /// Bytes of the CPU pools and the undo history.
    pub bytes: usize,
    pub in_stroke: bool,
}

impl Status {
    pub fn of(c: &dyn Canvas) -> Status {
        let doc = c.document();
        let (undo, redo) = doc.steps();
        Status {
            version: c.version(),
            layers: doc
                .listed_ids()
                .iter()
                .zip(doc.layers())
                .map(|(&id, l)| LayerRow {
                    id,
                    name: l.name.clone(),
                    visible: l.visible,
                    opacity: l.opacity,
                    locked: l.locked,
                    cells: l.tree().n_used(),
                    bytes: l.tree().pool_bytes_allocated(),
                })
                .collect(),
            selected: doc.selected(),
            undo,
            redo,
            used: doc.used(),
            capacity: doc.canvas().capacity,
            bytes: doc.layers().map(|l| l.tree().pool_bytes_allocated()).sum::<usize>() + doc.history_bytes(),
            in_stroke: c.in_stroke(),
        }
    }
}
