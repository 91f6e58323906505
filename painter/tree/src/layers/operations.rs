//! A document's history and its layer operations (spec 14.2-14.4): undo and
//! redo over strokes and layer operations, each operation applied under the
//! rules of octopaint-model's `layer_rules`, and merge down.

use super::{Document, DocumentStep, Layer, LayerList, LayerRow, check_op, placed};
use crate::clean::clean;
use crate::paint::Painting;
use crate::pool::{FREE, NONE, Tree};
use crate::trace::{LayerOp, LayerOpKind};

impl Document {
    /// The list of layers and the selection, as an undo step keeps them.
    fn settings(&self) -> LayerList {
        let rows = self
            .order
            .iter()
            .map(|&id| {
                let l = &self.arena[&id];
                LayerRow { id, name: l.name.clone(), visible: l.visible, opacity: l.opacity, locked: l.locked }
            })
            .collect();
        LayerList { rows, selected: self.selected }
    }

    /// Put back a list of layers and the selection an undo step kept.
    fn restore(&mut self, s: &LayerList) {
        self.order = s.rows.iter().map(|r| r.id).collect();
        for r in &s.rows {
            let l = self.arena.get_mut(&r.id).expect("a step's layers stay in the arena");
            l.name.clone_from(&r.name);
            l.visible = r.visible;
            l.opacity = r.opacity;
            l.locked = r.locked;
        }
        self.selected = s.selected;
    }

    /// Undo the last step (spec 14.3); false when there is none.
    pub fn undo(&mut self) -> bool {
        let Some(step) = self.done.pop() else { return false };
        match &step {
            DocumentStep::Stroke(id) => {
                self.arena.get_mut(id).expect("listed").painting.undo();
            }
            DocumentStep::Layers(b) => self.restore(&b.0),
        }
        self.undone.push(step);
        true
    }

    /// Redo the last undone step; false when there is none.
    pub fn redo(&mut self) -> bool {
        let Some(step) = self.undone.pop() else { return false };
        match &step {
            DocumentStep::Stroke(id) => {
                self.arena.get_mut(id).expect("listed").painting.redo();
            }
            DocumentStep::Layers(b) => self.restore(&b.1),
        }
        self.done.push(step);
        true
    }

    // --------------------------------------------------------- operations

    /// Run one `layer` event; false (with a warning) when the document
    /// cannot take it now (spec 14.2: refused by the budget, or out of step
    /// with the reader's model after such a refusal).
    pub fn apply(&mut self, op: &LayerOp, line: usize) -> bool {
        let names: Vec<&str> = self.layers().map(|l| l.name.as_str()).collect();
        let locked: Vec<bool> = self.layers().map(|l| l.locked).collect();
        if let Some(why) = check_op(&names, &locked, op) {
            self.warnings.push(format!("line {line}: {why}; it is skipped"));
            return false;
        }
        let i = op.layer.as_ref().map(|l| names.iter().position(|n| n == l).expect("checked"));
        drop(names);
        if op.op == LayerOpKind::Select {
            self.selected = i.expect("select names a layer");
            return true;
        }
        let capacity = u64::from(self.canvas.capacity);
        let made: Option<Layer> = match op.op {
            LayerOpKind::Add => {
                let l = Layer::new(op.name.as_deref().expect("add has a name"), Painting::new(&self.canvas));
                (u64::from(l.tree().n_used()) <= capacity - self.used()).then_some(l)
            }
            LayerOpKind::Duplicate => {
                let src = self.layer(i.expect("names a layer"));
                let mut tree = src.tree().clone();
                tree.capacity = self.canvas.capacity;
                let mut l = Layer::new(op.name.as_deref().expect("duplicate has a name"), Painting::from_parts(tree, Default::default()));
                l.visible = src.visible;
                l.opacity = src.opacity;
                (u64::from(l.tree().n_used()) <= capacity - self.used()).then_some(l)
            }
            LayerOpKind::MergeDown => {
                let i = i.expect("names a layer");
                let (lo, up) = (self.order[i - 1], self.order[i]);
                let limit = capacity - self.used_but(&[lo, up]);
                let (lower, upper) = (&self.arena[&lo], &self.arena[&up]);
                merge_trees(lower, upper, limit).map(|mut tree| {
                    tree.capacity = self.canvas.capacity;
                    Layer::new(&lower.name, Painting::from_parts(tree, Default::default()))
                })
            }
            _ => None,
        };
        let makes = matches!(op.op, LayerOpKind::Add | LayerOpKind::Duplicate | LayerOpKind::MergeDown);
        if makes && made.is_none() {
            self.warnings.push(format!("line {line}: the cell budget cannot hold this layer operation; it is skipped"));
            return false;
        }
        self.drop_redo();
        let before = self.settings();
        let (order, sel) = placed(self.order.len(), self.selected, op, i);
        let new_id = made.map(|l| self.insert(l));
        let old = std::mem::take(&mut self.order);
        self.order = order.iter().map(|j| j.map_or_else(|| new_id.expect("a new layer"), |j| old[j])).collect();
        match op.op {
            LayerOpKind::MergeDown => {
                let i = i.expect("names a layer");
                self.order[i - 1] = new_id.expect("merged");
            }
            LayerOpKind::Rename => {
                let l = self.arena.get_mut(&old[i.expect("names a layer")]).expect("listed");
                l.name = op.name.clone().expect("rename has a name");
            }
            LayerOpKind::Set => {
                let l = self.arena.get_mut(&old[i.expect("names a layer")]).expect("listed");
                if let Some(v) = op.visible {
                    l.visible = v;
                }
                if let Some(o) = op.opacity {
                    l.opacity = o;
                }
                if let Some(k) = op.locked {
                    l.locked = k;
                }
            }
            _ => {}
        }
        self.selected = sel;
        let after = self.settings();
        self.done.push(DocumentStep::Layers(Box::new((before, after))));
        true
    }
}

/// The tree of `upper` merged down into `lower` (spec 14.4), or None when it
/// would need more than `limit` cells.
pub fn merge_trees(lower: &Layer, upper: &Layer, limit: u64) -> Option<Tree> {
    let (a, b) = (lower.tree(), upper.tree());
    let mut m = a.clone();
    m.capacity = limit.min(u64::from(u32::MAX)) as u32;
    if u64::from(m.n_used()) > limit {
        return None;
    }
    for d in 0..m.lat.max_depth {
        let n = m.n_used() as usize;
        let origins = crate::dump::origins(&m);
        let mut cand: Vec<u32> = (0..n)
            .filter(|&c| u32::from(m.depth()[c]) == d && m.first_child()[c] == NONE)
            .filter(|&c| {
                let bc = b.cell_at(origins[c], d) as usize;
                u32::from(b.depth()[bc]) == d && b.first_child()[bc] != NONE
            })
            .map(|c| c as u32)
            .collect();
        if cand.is_empty() {
            continue;
        }
        if cand.len() as u64 > m.available_units() {
            return None;
        }
        let (_, refusal) = m.refine_round(&mut cand);
        if refusal.is_some() {
            return None;
        }
    }
    let n = m.n_used() as usize;
    let origins = crate::dump::origins(&m);
    let o_a = if lower.visible { f64::from(lower.opacity) } else { 0.0 };
    let o_b = if upper.visible { f64::from(upper.opacity) } else { 0.0 };
    let mut leaves = Vec::new();
    for c in 0..n {
        if m.depth()[c] == FREE || m.first_child()[c] != NONE {
            continue;
        }
        let bc = b.cell_at(origins[c], u32::from(m.depth()[c])) as usize;
        let w_a = o_a * f64::from(m.sigma()[c]);
        let w_b = o_b * f64::from(b.sigma()[bc]);
        let w = w_a + w_b;
        let mut rgb = m.rgb()[c];
        if w > 0.0 {
            for ch in 0..3 {
                let v = ((w_a * f64::from(m.rgb()[c][ch]) + w_b * f64::from(b.rgb()[bc][ch])) / w + 0.5).floor();
                rgb[ch] = v.clamp(0.0, 255.0) as u8;
            }
        }
        m.set_value(c as u32, rgb, crate::brush::quantize_sigma(w));
        if m.depth()[c] > 0 {
            leaves.push(c as u32);
        }
    }
    m.update_prefilter();
    clean(&mut m, leaves);
    Some(m)
}
