//! Layers (spec 14): a document of up to 16 trees under one cell budget, one
//! history for strokes and layer operations, merge down, and the dump of a
//! document. The rules a layer operation obeys (names, locks, where the
//! layers go) are octopaint-model's `layer_rules`, which the trace reader
//! follows too. Reference twin: reference/octopaint_ref/layers.py.

mod operations;

pub use operations::merge_trees;

use std::collections::BTreeMap;
use std::io::Cursor;

use crate::dump::{NpyArray, TREE_ARRAYS, Values, layer_arrays, write_npz};
use crate::g3::g3_table;
use crate::paint::Painting;
use crate::pool::Tree;
use crate::trace::{Brush, Canvas, Sample};

pub use octopaint_model::layer_rules::{FIRST_NAME, MAX_LAYERS, MAX_NAME_CHARS, Model, NAME_BYTES, check_op, name_problem, placed};

/// One layer: its settings and its tree with its own undo steps.
#[derive(Clone)]
pub struct Layer {
    pub name: String,
    pub visible: bool,
    /// In [0, 1], the f32 every implementation uses (spec 14.1).
    pub opacity: f32,
    pub locked: bool,
    pub painting: Painting,
}

impl Layer {
    pub fn new(name: &str, painting: Painting) -> Layer {
        Layer { name: name.to_string(), visible: true, opacity: 1.0, locked: false, painting }
    }

    pub fn tree(&self) -> &Tree {
        &self.painting.tree
    }

    /// Rendering counts it (spec 6.2): visible with an opacity above 0.
    pub fn contributes(&self) -> bool {
        self.visible && self.opacity > 0.0
    }
}

/// A layer's settings as a layer operation's undo step restores them.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerRow {
    pub id: u32,
    pub name: String,
    pub visible: bool,
    pub opacity: f32,
    pub locked: bool,
}

/// The list of layers (bottom first) and the selection, as a layer
/// operation's undo step restores them.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerList {
    pub rows: Vec<LayerRow>,
    pub selected: usize,
}

/// One step of a document's history (spec 14.3).
#[derive(Clone)]
pub enum DocumentStep {
    /// A stroke on the layer of this id (its own undo step is the newest
    /// of that layer's history).
    Stroke(u32),
    /// A layer operation: the settings before and after it.
    Layers(Box<(LayerList, LayerList)>),
}

impl DocumentStep {
    /// The layer ids the step refers to.
    pub fn ids(&self) -> Vec<u32> {
        match self {
            DocumentStep::Stroke(id) => vec![*id],
            DocumentStep::Layers(b) => b.0.rows.iter().chain(b.1.rows.iter()).map(|r| r.id).collect(),
        }
    }
}

/// The layers of a version 2 trace and their one history (spec 14). Layers
/// live in an arena by id so that undo steps can hold on to layers that are
/// no longer in the list (deleted or merged).
#[derive(Clone)]
pub struct Document {
    canvas: Canvas,
    arena: BTreeMap<u32, Layer>,
    order: Vec<u32>,
    selected: usize,
    next_id: u32,
    done: Vec<DocumentStep>,
    undone: Vec<DocumentStep>,
    painting_on: Option<u32>,
    /// Warnings in the order they happened (the replay prints them).
    pub warnings: Vec<String>,
}

impl Document {
    pub fn new(canvas: &Canvas) -> Document {
        let mut d = Document {
            canvas: *canvas,
            arena: BTreeMap::new(),
            order: Vec::new(),
            selected: 0,
            next_id: 0,
            done: Vec::new(),
            undone: Vec::new(),
            painting_on: None,
            warnings: Vec::new(),
        };
        let id = d.insert(Layer::new(FIRST_NAME, Painting::new(canvas)));
        d.order.push(id);
        d
    }

    /// A document of one layer holding `painting` (a one-tree document,
    /// or a version 1 trace), its strokes the document's history.
    pub fn from_painting(canvas: &Canvas, painting: Painting) -> Document {
        let done = (0..painting.history.done.len()).map(|_| DocumentStep::Stroke(0)).collect();
        let undone = (0..painting.history.undone.len()).map(|_| DocumentStep::Stroke(0)).collect();
        let mut arena = BTreeMap::new();
        arena.insert(0, Layer::new(FIRST_NAME, painting));
        Document { canvas: *canvas, arena, order: vec![0], selected: 0, next_id: 1, done, undone, painting_on: None, warnings: Vec::new() }
    }

    /// Steps that can be undone and redone.
    pub fn steps(&self) -> (usize, usize) {
        (self.done.len(), self.undone.len())
    }

    fn insert(&mut self, layer: Layer) -> u32 {
        let id = self.next_id;
        self.next_id += 1;
        self.arena.insert(id, layer);
        id
    }

    pub fn canvas(&self) -> &Canvas {
        &self.canvas
    }

    pub fn len(&self) -> usize {
        self.order.len()
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The layer of id `id`, listed or kept for the history (deleted,
    /// merged); None once the history that held it is forgotten.
    pub fn layer_by_id(&self, id: u32) -> Option<&Layer> {
        self.arena.get(&id)
    }

    /// The listed layers' ids, bottom first.
    pub fn listed_ids(&self) -> &[u32] {
        &self.order
    }

    /// Layer `k` from the bottom.
    pub fn layer(&self, k: usize) -> &Layer {
        &self.arena[&self.order[k]]
    }

    pub fn layer_mut(&mut self, k: usize) -> &mut Layer {
        self.arena.get_mut(&self.order[k]).expect("listed layers live in the arena")
    }

    /// The layers, bottom first.
    pub fn layers(&self) -> impl Iterator<Item = &Layer> + '_ {
        self.order.iter().map(|id| &self.arena[id])
    }

    pub fn selected(&self) -> usize {
        self.selected
    }

    pub fn current(&self) -> &Layer {
        self.layer(self.selected)
    }

    pub fn current_mut(&mut self) -> &mut Layer {
        let k = self.selected;
        self.layer_mut(k)
    }

    /// Cells in use over all layers (the one budget of spec 14.1).
    pub fn used(&self) -> u64 {
        self.layers().map(|l| u64::from(l.tree().n_used())).sum()
    }

    fn used_but(&self, but: &[u32]) -> u64 {
        self.order.iter().filter(|id| !but.contains(id)).map(|id| u64::from(self.arena[id].tree().n_used())).sum()
    }

    /// The painting of the selected layer, taken out of the document.
    pub fn into_current_painting(mut self) -> Painting {
        let id = self.order[self.selected];
        self.arena.remove(&id).expect("listed").painting
    }

    /// Every warning of the document and its layers' paintings so far.
    pub fn take_warnings(&mut self) -> Vec<String> {
        let mut out = std::mem::take(&mut self.warnings);
        for l in self.arena.values_mut() {
            out.append(&mut l.painting.warnings);
        }
        out
    }

    // ------------------------------------------------------------ strokes

    /// Begin a stroke on the selected layer; false (with a warning) when it
    /// is locked: the stroke is skipped (spec 14.2).
    pub fn begin_stroke(&mut self, brush: &Brush, line: usize) -> bool {
        let Some(id) = self.ready_to_paint(line, "stroke") else { return false };
        self.arena.get_mut(&id).expect("listed").painting.begin_stroke(brush);
        self.painting_on = Some(id);
        true
    }

    /// The selected layer made ready for a stroke or an import (`what`, for
    /// the warning): None, with the warning `line N: layer "NAME" is locked;
    /// this WHAT is skipped`, when it is locked (spec 14.2); else the redo
    /// history dropped and the layer's budget set to its share; its id.
    fn ready_to_paint(&mut self, line: usize, what: &str) -> Option<u32> {
        if self.current().locked {
            let msg = format!("line {line}: layer \"{}\" is locked; this {what} is skipped", self.current().name);
            self.warnings.push(msg);
            return None;
        }
        self.drop_redo();
        let id = self.order[self.selected];
        let share = self.share_of(id);
        self.arena.get_mut(&id).expect("listed").painting.tree.capacity = share;
        Some(id)
    }

    /// What layer `id` may grow to: the budget less the other layers' used
    /// lengths (spec 14.1).
    fn share_of(&self, id: u32) -> u32 {
        (u64::from(self.canvas.capacity) - self.used_but(&[id])) as u32
    }

    pub fn add_sample(&mut self, sample: &Sample, line: usize) {
        if let Some(id) = self.painting_on {
            self.arena.get_mut(&id).expect("listed").painting.add_sample(sample, line);
        }
    }

    /// Start a sample of the open stroke, its levels to follow with
    /// `Painting::advance` on [`Document::stroke_painting`] (the real-time
    /// pipeline publishes between them); false when no stroke is open or
    /// it was skipped (nothing to step).
    pub fn begin_sample(&mut self, sample: &Sample, line: usize) -> bool {
        let Some(id) = self.painting_on else { return false };
        self.arena.get_mut(&id).expect("listed").painting.begin_sample(sample, line);
        true
    }

    /// The painting of the open stroke, if one is open and not skipped.
    pub fn stroke_painting(&mut self) -> Option<&mut Painting> {
        let id = self.painting_on?;
        Some(&mut self.arena.get_mut(&id).expect("listed").painting)
    }

    pub fn end_stroke(&mut self) {
        if let Some(id) = self.painting_on.take() {
            self.arena.get_mut(&id).expect("listed").painting.end_stroke();
            self.done.push(DocumentStep::Stroke(id));
        }
    }

    /// An `import` event (spec 15.3) on the selected layer: one step of
    /// the history. Skipped with a warning when the layer is locked (the
    /// reader's model was put out of step by a skipped layer operation).
    pub fn import_voxels(&mut self, vs: &crate::voxels::VoxelSet, line: usize) -> bool {
        let Some(id) = self.ready_to_paint(line, "import") else { return false };
        self.arena.get_mut(&id).expect("listed").painting.import_voxels(vs, line);
        self.done.push(DocumentStep::Stroke(id));
        true
    }

    /// An import the document must take whole or not at all (the painter's
    /// import commands, spec 15): tried on a copy of the selected layer
    /// first, and refused, changing nothing (redo history included), when
    /// the layer is locked or the cell budget refuses a refinement. On
    /// success it is one step of the history, as [`Document::import_voxels`].
    pub fn try_import(&mut self, vs: &crate::voxels::VoxelSet) -> Result<(), String> {
        if self.current().locked {
            return Err(format!("layer \"{}\" is locked", self.current().name));
        }
        let id = self.order[self.selected];
        let mut trial = self.arena.get(&id).expect("listed").painting.clone();
        trial.tree.capacity = self.share_of(id);
        let (refusals, warned) = (trial.counters.refusals, trial.warnings.len());
        trial.import_voxels(vs, 0);
        if trial.counters.refusals > refusals {
            return Err(format!(
                "the cell budget ({} cells, {} in use by the other layers) cannot hold this import at depth {}: \
                 import at a coarser depth, a smaller part, or into a document with a larger --capacity",
                self.canvas.capacity,
                self.used_but(&[id]),
                vs.depth
            ));
        }
        trial.warnings.truncate(warned);
        self.drop_redo();
        self.arena.get_mut(&id).expect("listed").painting = trial;
        self.done.push(DocumentStep::Stroke(id));
        Ok(())
    }

    fn drop_redo(&mut self) {
        self.undone.clear();
        for l in self.arena.values_mut() {
            l.painting.history.undone.clear();
        }
        self.forget_unreferenced();
    }

    /// Drop the layers that no step and no list position refer to.
    fn forget_unreferenced(&mut self) {
        let mut keep: Vec<u32> = self.order.clone();
        for s in self.done.iter().chain(&self.undone) {
            keep.extend(s.ids());
        }
        self.arena.retain(|id, _| keep.contains(id));
    }

    /// Bytes the history holds: every layer's undo steps, and the whole of
    /// every layer only the history still holds (deleted, merged, or added
    /// by an undone step: its pools as allocated). A layer operation's own
    /// step is a few rows; the trees it keeps are not.
    pub fn history_bytes(&self) -> usize {
        let steps: usize = self.arena.values().map(|l| l.painting.history.bytes()).sum();
        let unlisted: usize = self.arena.iter().filter(|(id, _)| !self.order.contains(id)).map(|(_, l)| l.tree().pool_bytes_allocated()).sum();
        steps + unlisted
    }

    /// Forget the oldest steps until the history takes at most `max_bytes`
    /// (the newest step and every redo step are kept). A forgotten stroke
    /// takes its layer's oldest undo step with it; a forgotten layer
    /// operation drops at once the layers only it still held (deleted,
    /// merged), whose bytes the history counted. Returns how many steps
    /// were forgotten.
    pub fn trim_to(&mut self, max_bytes: usize) -> usize {
        let mut dropped = 0;
        while self.history_bytes() > max_bytes && self.done.len() > 1 {
            match self.done.remove(0) {
                DocumentStep::Stroke(id) => {
                    if let Some(l) = self.arena.get_mut(&id)
                        && !l.painting.history.done.is_empty()
                    {
                        l.painting.history.done.remove(0);
                    }
                }
                DocumentStep::Layers(_) => self.forget_unreferenced(),
            }
            dropped += 1;
        }
        if dropped > 0 {
            self.forget_unreferenced();
        }
        dropped
    }

    // ------------------------------------------------------ saving, opening

    /// The parts a saved document keeps: every layer by id (those undo
    /// still needs included), the list, the selection, the next id and the
    /// history.
    pub fn parts(&self) -> (impl Iterator<Item = (u32, &Layer)> + '_, &[u32], usize, u32, &[DocumentStep], &[DocumentStep]) {
        (self.arena.iter().map(|(id, l)| (*id, l)), &self.order, self.selected, self.next_id, &self.done, &self.undone)
    }

    /// A document from saved parts, refused with the first problem unless
    /// they fit together: at most 16 listed layers, each id once, a
    /// selection in the list, steps naming layers that exist with valid
    /// names and opacities, each stroke step matching a step of its
    /// layer's history, and all layers within the cell budget.
    #[allow(clippy::too_many_arguments)]
    pub fn from_parts(
        canvas: &Canvas,
        layers: Vec<(u32, Layer)>,
        order: Vec<u32>,
        selected: usize,
        next_id: u32,
        done: Vec<DocumentStep>,
        undone: Vec<DocumentStep>,
    ) -> Result<Document, String> {
        let mut arena = BTreeMap::new();
        for (id, l) in layers {
            if id >= next_id {
                return Err(format!("layer id {id} is not below the next id {next_id}"));
            }
            if let Some(why) = name_problem(&l.name) {
                return Err(format!("layer {id}: {why}"));
            }
            if !(0.0..=1.0).contains(&l.opacity) {
                return Err(format!("layer {id}: opacity {} is not in [0, 1]", l.opacity));
            }
            if arena.insert(id, l).is_some() {
                return Err(format!("layer id {id} is there twice"));
            }
        }
        if order.is_empty() || order.len() > MAX_LAYERS {
            return Err(format!("{} layers in the list (1 to {MAX_LAYERS})", order.len()));
        }
        if selected >= order.len() {
            return Err(format!("the selection {selected} is past the {} layers", order.len()));
        }
        let check_rows = |s: &LayerList| -> Result<(), String> {
            if s.rows.is_empty() || s.rows.len() > MAX_LAYERS || s.selected >= s.rows.len() {
                return Err("a layer step has an impossible list".into());
            }
            for (k, r) in s.rows.iter().enumerate() {
                if !arena.contains_key(&r.id) || s.rows[..k].iter().any(|o| o.id == r.id || o.name == r.name) {
                    return Err(format!("a layer step names layer {} that is missing or twice", r.id));
                }
                if name_problem(&r.name).is_some() || !(0.0..=1.0).contains(&r.opacity) {
                    return Err(format!("a layer step holds impossible settings for layer {}", r.id));
                }
            }
            Ok(())
        };
        let mut strokes: BTreeMap<u32, (usize, usize)> = BTreeMap::new();
        for (k, s) in done.iter().chain(&undone).enumerate() {
            match s {
                DocumentStep::Stroke(id) => {
                    if !arena.contains_key(id) {
                        return Err(format!("step {k} paints layer {id}, which is missing"));
                    }
                    let e = strokes.entry(*id).or_default();
                    if k < done.len() { e.0 += 1 } else { e.1 += 1 }
                }
                DocumentStep::Layers(b) => {
                    check_rows(&b.0)?;
                    check_rows(&b.1)?;
                }
            }
        }
        for (id, l) in &arena {
            let (d, u) = strokes.get(id).copied().unwrap_or_default();
            let h = &l.painting.history;
            if h.done.len() != d || h.undone.len() != u {
                return Err(format!("layer {id}'s own history does not match the document's steps"));
            }
        }
        let mut seen = Vec::new();
        for id in &order {
            if !arena.contains_key(id) || seen.contains(id) {
                return Err(format!("the list names layer {id}, which is missing or twice"));
            }
            seen.push(*id);
        }
        let mut names: Vec<&str> = order.iter().map(|id| arena[id].name.as_str()).collect();
        names.sort_unstable();
        if names.windows(2).any(|w| w[0] == w[1]) {
            return Err("two listed layers have one name".into());
        }
        let used: u64 = order.iter().map(|id| u64::from(arena[id].tree().n_used())).sum();
        if used > u64::from(canvas.capacity) {
            return Err(format!("the layers use {used} cells, over the budget of {}", canvas.capacity));
        }
        Ok(Document { canvas: *canvas, arena, order, selected, next_id, done, undone, painting_on: None, warnings: Vec::new() })
    }

    /// The dump of the document (spec 14.5), with the CPU port's g3 tables.
    pub fn dump_bytes(&self) -> Vec<u8> {
        let n = self.len();
        let t0 = self.layer(0).tree();
        let count = n as u32;
        let selected = self.selected as u32;
        let mut names = vec![0u8; n * NAME_BYTES];
        for (k, l) in self.layers().enumerate() {
            let b = l.name.as_bytes();
            names[k * NAME_BYTES..k * NAME_BYTES + b.len()].copy_from_slice(b);
        }
        let visible: Vec<u8> = self.layers().map(|l| u8::from(l.visible)).collect();
        let locked: Vec<u8> = self.layers().map(|l| u8::from(l.locked)).collect();
        let opacity: Vec<f32> = self.layers().map(|l| l.opacity).collect();
        let g3: Vec<Vec<[u32; 3]>> = self.layers().map(|l| g3_table(l.tree())).collect();
        let origins: Vec<Vec<[u32; 3]>> = self.layers().map(|l| crate::dump::origins(l.tree())).collect();
        let names_k: Vec<Vec<String>> = (0..n).map(|k| TREE_ARRAYS.iter().map(|a| format!("{k}/{a}")).collect()).collect();
        let mut arrays = vec![
            NpyArray { name: "roots", shape: vec![3], values: Values::U32(&t0.lat.roots[..]) },
            NpyArray { name: "max_depth", shape: vec![], values: Values::U32(std::slice::from_ref(&t0.lat.max_depth)) },
            NpyArray { name: "root_size", shape: vec![], values: Values::F64(std::slice::from_ref(&t0.lat.root_size)) },
            NpyArray { name: "layer_count", shape: vec![], values: Values::U32(std::slice::from_ref(&count)) },
            NpyArray { name: "selected", shape: vec![], values: Values::U32(std::slice::from_ref(&selected)) },
            NpyArray { name: "layer_names", shape: vec![n, NAME_BYTES], values: Values::U8(&names) },
            NpyArray { name: "layer_visible", shape: vec![n], values: Values::U8(&visible) },
            NpyArray { name: "layer_locked", shape: vec![n], values: Values::U8(&locked) },
            NpyArray { name: "layer_opacity", shape: vec![n], values: Values::F32(&opacity) },
        ];
        for (k, l) in self.layers().enumerate() {
            arrays.extend(layer_arrays(l.tree(), &g3[k], &origins[k], &names_k[k]));
        }
        write_npz(Cursor::new(Vec::new()), &arrays).expect("writing to memory cannot fail").into_inner()
    }
}
