//! Topology cleaning at stroke end (spec 9). Reference twin:
//! reference/octopaint_ref/clean.py.
//!
//! Collapse every cell whose 8 children are leaves that are all empty or all
//! identical, when 2:1 balance allows, to the (unique) fixpoint. The tree is
//! at that fixpoint before every stroke, and a stroke only refines and
//! writes touched cells, so a collapse can start only at the parent of a
//! touched cell; collapsing P can only enable P's parent and that parent's
//! same-depth face neighbours. Each batch is decided before any of it is
//! collapsed; collapses in one batch never invalidate each other.

use crate::lattice::FACES;
use crate::par;
use crate::pool::{FREE, NONE, Tree, UNIT};

/// Collapse to the fixpoint, starting from the parents of `touched`.
/// Returns the number of collapses.
pub fn clean(tree: &mut Tree, touched: impl IntoIterator<Item = u32>) -> usize {
    // Siblings are touched together (a new unit's 8 children one after
    // another): a cell of the unit just seen has its parent (units are
    // allocated, freed and parented whole), so only the first of a run is
    // looked up, which leaves far less to read and to sort.
    let mut work = Vec::new();
    let mut last_unit = u32::MAX;
    for c in touched {
        if c / UNIT == last_unit {
            continue;
        }
        last_unit = c / UNIT;
        if (c as usize) < tree.depth.len() && tree.depth[c as usize] != FREE {
            let p = tree.parent[c as usize];
            if p != NONE {
                work.push(p);
            }
        }
    }
    let mut collapses = 0;
    loop {
        work.dedup();
        par::sort_dedup(&mut work);
        // Decided in parallel (reads only), collapsed in order.
        let view = &*tree;
        let done: Vec<u32> = par::filter(&work, |&p| view.depth[p as usize] != FREE && view.first_child[p as usize] != NONE && view.collapsible(p));
        if done.is_empty() {
            return collapses;
        }
        for &p in &done {
            tree.coarsen(p);
        }
        collapses += done.len();
        let mut parents: Vec<u32> = done.iter().map(|&p| tree.parent[p as usize]).filter(|&p| p != NONE).collect();
        par::sort_dedup(&mut parents);
        work.clear();
        for &p in &parents {
            work.push(p);
            for f in 0..FACES.len() {
                let m = tree.internal_same_depth_neighbour(p, f);
                if m != NONE {
                    work.push(m);
                }
            }
        }
    }
}

/// Every cell that could still collapse (tests: none at a fixpoint).
pub fn collapsible_anywhere(tree: &Tree) -> Vec<u32> {
    (0..tree.n_used()).filter(|&c| tree.is_live(c) && !tree.is_leaf(c) && tree.collapsible(c)).collect()
}
