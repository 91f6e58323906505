//! The layer rules (spec 14.1, 14.2): what a layer name may be, whether a
//! document can take a layer operation, where its layers go. The trace
//! reader follows a document through [`Model`] with them and the tree's
//! documents of layers apply them, so the rules are written once.
//! Reference twin: reference/octopaint_ref/layer_rules.py.

use crate::event::{LayerOp, LayerOpKind};

pub const MAX_LAYERS: usize = 16;
pub const MAX_NAME_CHARS: usize = 64;
/// A name's UTF-8 bytes in a dump (64 code points need at most 256).
pub const NAME_BYTES: usize = 256;
pub const FIRST_NAME: &str = "Layer 1";

/// Why `name` is not a layer name (spec 14.1), or None.
pub fn name_problem(name: &str) -> Option<String> {
    let n = name.chars().count();
    if !(1..=MAX_NAME_CHARS).contains(&n) {
        return Some(format!("a layer name has 1 to {MAX_NAME_CHARS} characters, this one {n}"));
    }
    name.chars().find(|&c| c <= '\u{1f}' || ('\u{7f}'..='\u{9f}').contains(&c)).map(|c| format!("a layer name has no control characters (U+{:04X})", c as u32))
}

/// Why a document with these layer `names` and `locked` flags (bottom
/// first) cannot take `op`, or None: the rules of spec 14.2 after the
/// fields were read, in the order written there.
pub fn check_op(names: &[&str], locked: &[bool], op: &LayerOp) -> Option<String> {
    let i = match &op.layer {
        Some(l) => match names.iter().position(|n| n == l) {
            Some(i) => Some(i),
            None => return Some(format!("layer: there is no layer named \"{l}\"")),
        },
        None => None,
    };
    if let Some(name) = &op.name
        && names.contains(&name.as_str())
        && !(op.op == LayerOpKind::Rename && i.is_some_and(|i| names[i] == name))
    {
        return Some(format!("name: a layer named \"{name}\" exists already"));
    }
    match op.op {
        LayerOpKind::Add | LayerOpKind::Duplicate if names.len() >= MAX_LAYERS => Some(format!("op: a document holds at most {MAX_LAYERS} layers")),
        LayerOpKind::Delete if names.len() == 1 => Some("op: the only layer cannot be deleted".into()),
        LayerOpKind::Move if op.to.unwrap_or(0) >= names.len() => {
            Some(format!("to: {} is not a layer position (0 to {})", op.to.unwrap_or(0), names.len() - 1))
        }
        LayerOpKind::MergeDown => {
            let i = i.expect("merge_down names a layer");
            if i == 0 {
                Some(format!("op: \"{}\" is the bottom layer: there is nothing below it to merge into", names[i]))
            } else if locked[i] || locked[i - 1] {
                Some(format!("op: \"{}\" or the layer below it is locked", names[i]))
            } else {
                None
            }
        }
        _ => None,
    }
}

/// Where the layers go for `op` (accepted by [`check_op`]) on a document of
/// `n` layers with `sel` selected and `i` the layer it names: the new order
/// as old indices (None: a new layer) and the new selection.
pub fn placed(n: usize, sel: usize, op: &LayerOp, i: Option<usize>) -> (Vec<Option<usize>>, usize) {
    let mut order: Vec<Option<usize>> = (0..n).map(Some).collect();
    let i_or = |what: &str| i.unwrap_or_else(|| panic!("{what} names a layer"));
    match op.op {
        LayerOpKind::Add => {
            order.insert(sel + 1, None);
            (order, sel + 1)
        }
        LayerOpKind::Delete => {
            let i = i_or("delete");
            order.remove(i);
            let sel = if sel == i {
                i.saturating_sub(1)
            } else if sel > i {
                sel - 1
            } else {
                sel
            };
            (order, sel)
        }
        LayerOpKind::Select => (order, i_or("select")),
        LayerOpKind::Move => {
            let i = i_or("move");
            let moved = order.remove(i);
            order.insert(op.to.expect("move has `to`"), moved);
            let sel = order.iter().position(|&j| j == Some(sel)).expect("the selected layer stays");
            (order, sel)
        }
        LayerOpKind::Duplicate => {
            let i = i_or("duplicate");
            order.insert(i + 1, None);
            (order, i + 1)
        }
        LayerOpKind::MergeDown => {
            let i = i_or("merge_down");
            order.remove(i); // the merged layer takes the place of i - 1
            (order, i - 1)
        }
        LayerOpKind::Rename | LayerOpKind::Set => (order, sel),
    }
}

/// The trace reader's model of a document (spec 12.2, 14.2): the layers'
/// names and locks, bottom first, and the selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    pub names: Vec<String>,
    pub locked: Vec<bool>,
    pub selected: usize,
}

impl Default for Model {
    fn default() -> Self {
        Model { names: vec![FIRST_NAME.to_string()], locked: vec![false], selected: 0 }
    }
}

impl Model {
    /// Why the document cannot take `op` now, or None.
    pub fn check(&self, op: &LayerOp) -> Option<String> {
        let names: Vec<&str> = self.names.iter().map(String::as_str).collect();
        check_op(&names, &self.locked, op)
    }

    /// The model after `op`, which [`Model::check`] accepted.
    pub fn apply(&self, op: &LayerOp) -> Model {
        let i = op.layer.as_ref().map(|l| self.names.iter().position(|n| n == l).expect("checked"));
        let (order, selected) = placed(self.names.len(), self.selected, op, i);
        let mut names = Vec::with_capacity(order.len());
        let mut locked = Vec::with_capacity(order.len());
        for j in &order {
            match j {
                None => {
                    names.push(op.name.clone().expect("add and duplicate name the new layer"));
                    locked.push(false);
                }
                Some(j) => {
                    names.push(self.names[*j].clone());
                    locked.push(self.locked[*j]);
                }
            }
        }
        let i = i.unwrap_or(0);
        match op.op {
            LayerOpKind::Rename => names[i] = op.name.clone().expect("rename has a name"),
            LayerOpKind::Set => {
                if let Some(l) = op.locked {
                    locked[i] = l;
                }
            }
            LayerOpKind::MergeDown => locked[i - 1] = false,
            _ => {}
        }
        Model { names, locked, selected }
    }

    /// Whether the selected layer is locked (a stroke may not begin).
    pub fn selected_locked(&self) -> bool {
        self.locked[self.selected]
    }
}
