//! Documents and the interior values of spec 4.4: a document saved before
//! the rule (its interior cells, and the interior records of its undo
//! steps, holding whatever the painter of then left there) opens to a tree
//! that keeps it, undoes and redoes every step keeping it, and ends as the
//! replay of its session; one saved under the rule opens unchanged.

use std::path::PathBuf;

use octopaint_doc::Session;
use octopaint_doc::format::{self, Content};
use octopaint_tree::check::check_tree;
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::history::{History, UndoStep};
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::{CellRecord, NONE, Tree};
use octopaint_tree::replay::{ReplayObserver, replay};

struct Silent;
impl ReplayObserver for Silent {}

fn trace_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"))
}

/// A value no prefilter gives (it depends on the cell alone).
fn stale(c: u32) -> ([u8; 3], f32) {
    ([(c % 251) as u8, 3, 5], (c % 7) as f32 * 0.25 + 0.125)
}

/// `r` with the stale value of `c` when it is a cell with children.
fn staled(c: u32, r: CellRecord) -> CellRecord {
    if r.first_child == NONE || r.depth == octopaint_tree::pool::FREE {
        return r;
    }
    let (rgb, sigma) = stale(c);
    CellRecord { rgb, sigma, ..r }
}

/// The saved document of `name`'s session, as bytes, and its tree.
fn saved(name: &str) -> (Vec<u8>, Tree) {
    let t = octopaint_tree::read_trace(&trace_path(name)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    for ev in &t.events {
        s.apply(ev).unwrap();
    }
    s.save().unwrap();
    drop(s);
    (std::fs::read(&path).unwrap(), replay(&t, None, &mut Silent).unwrap().1.tree)
}

#[test]
fn a_document_saved_before_the_rule_opens_to_it_and_undoes_and_redoes_within_it() {
    let (data, replayed) = saved("undo_redo");
    let loaded = format::read(&data).unwrap().doc;
    let Content::Tree { tree, history } = &loaded.content else { panic!("a one-tree document") };
    assert!(check_tree(tree).is_empty(), "a document saved under the rule opens as it was");
    assert_eq!(dump_bytes(tree), dump_bytes(&replayed));
    // With its last stroke undone (a step to redo), as the painter before
    // spec 4.4 would have left it.
    let mut base = Painting::from_parts(tree.clone(), history.clone());
    assert!(base.undo());
    let (tree, history, replayed) = (&base.tree, &base.history, base.tree.clone());
    let mut old_tree = tree.clone();
    let inner: Vec<u32> = (0..old_tree.n_used()).filter(|&c| old_tree.is_live(c) && !old_tree.is_leaf(c)).collect();
    assert!(inner.len() > 8, "the session refines");
    for &c in &inner {
        let (rgb, sigma) = stale(c);
        old_tree.set_value(c, rgb, sigma);
    }
    assert!(!old_tree.stale_interior_cells().is_empty());
    let steps: Vec<UndoStep> = history
        .full_steps(tree)
        .iter()
        .map(|s| {
            let mut o = UndoStep::new(s.n_before, s.n_after);
            for (c, b, a) in s.entries() {
                o.push(c, staled(c, b), staled(c, a));
            }
            o.shrink();
            o
        })
        .collect();
    let mut done = steps;
    let undone = done.split_off(history.done.len());
    assert!(!done.is_empty() && !undone.is_empty(), "the session leaves steps to undo and to redo");
    let old_history = History { done, undone };
    let (old, _) = format::write(&loaded.trace_text, &old_tree, &old_history, &loaded.meta).unwrap();
    // Opened: the rule holds, and the tree is the replay's.
    let reopened = format::read(&old).unwrap().doc;
    let Content::Tree { tree: t, history: h } = reopened.content else { panic!("a one-tree document") };
    assert!(check_tree(&t).is_empty(), "{:?}", check_tree(&t));
    assert_eq!(dump_bytes(&t), dump_bytes(&replayed));
    // Every undo and every redo keeps it, and all the way back the tree is
    // the one all the way forward again.
    let mut p = Painting::from_parts(t, h);
    let mut undos = 0;
    while p.undo() {
        undos += 1;
        assert!(check_tree(&p.tree).is_empty(), "after undo {undos}: {:?}", check_tree(&p.tree));
    }
    let mut redos = 0;
    while p.redo() {
        redos += 1;
        assert!(check_tree(&p.tree).is_empty(), "after redo {redos}: {:?}", check_tree(&p.tree));
    }
    assert!(undos >= 1 && redos == undos + 1, "{undos} undos, {redos} redos");
    for _ in 0..old_history.undone.len() {
        assert!(p.undo());
    }
    assert_eq!(dump_bytes(&p.tree), dump_bytes(&replayed), "back where the session ended");
}
