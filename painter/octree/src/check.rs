//! Structural validation of a tree (tests, fuzzing): the checks of
//! `octopaint-ref check` (spec 11.2) on the live pools instead of a dump.
//! Reference twin: reference/octopaint_ref/check.py.

use crate::g3::{g3_brute_force, g3_table, g3_table_per_cell};
use crate::lattice::FACES;
use crate::pool::{FREE, NONE, Tree, UNIT, origins};
use octopaint_model::Canvas;

/// Every problem found, in the order of spec 11.2; empty for a valid tree.
/// The interior values (check 8, spec 4.4) are checked once the structure
/// is valid.
pub fn check_tree(t: &Tree) -> Vec<String> {
    let mut p = check_structure(t);
    if p.is_empty() {
        let stale = t.stale_interior_cells();
        if let Some(&c) = stale.first() {
            p.push(format!("{} cells with children do not hold their children's prefilter (spec 4.4), the first {c}", stale.len()));
        }
    }
    p
}

/// The checks of spec 11.2 but the interior values: what a tree read from
/// a file must pass before its interior values are computed afresh.
pub fn check_structure(t: &Tree) -> Vec<String> {
    let mut p = Vec::new();
    let n = t.n_used();
    let lat = &t.lat;
    if !n.is_multiple_of(UNIT) || n < lat.padded {
        p.push(format!("used length {n} is not a multiple of 8 at least {}", lat.padded));
        return p;
    }
    for r in 0..lat.n_roots {
        if t.depth[r as usize] != 0 || t.parent[r as usize] != NONE {
            p.push(format!("root {r} has depth {} and parent {}", t.depth[r as usize], t.parent[r as usize]));
        }
    }
    for c in lat.n_roots..lat.padded {
        if t.depth[c as usize] != FREE {
            p.push(format!("padding cell {c} is not free"));
        }
    }
    for c in 0..n {
        let i = c as usize;
        if t.depth[i] == FREE {
            if t.parent[i] != NONE || t.first_child[i] != NONE || t.rgb[i] != [0; 3] || t.sigma[i].to_bits() != 0 {
                p.push(format!("free cell {c} holds data"));
            }
            continue;
        }
        if u32::from(t.depth[i]) > lat.max_depth {
            p.push(format!("cell {c} has depth {} > {}", t.depth[i], lat.max_depth));
        }
        if !(t.sigma[i].is_finite() && t.sigma[i] >= 0.0) {
            p.push(format!("cell {c} has sigma {}", t.sigma[i]));
        }
        if c >= lat.padded {
            let par = t.parent[i];
            if par == NONE || par >= n || t.depth[par as usize] == FREE {
                p.push(format!("cell {c} has no live parent ({par})"));
            } else if t.first_child[par as usize] != c & !7 || t.depth[par as usize] + 1 != t.depth[i] {
                p.push(format!("cell {c} and its parent {par} disagree"));
            }
        }
        let fc = t.first_child[i];
        if fc != NONE {
            if !fc.is_multiple_of(UNIT) || fc < lat.padded || fc + UNIT > n {
                p.push(format!("cell {c} has first_child {fc} outside the pools"));
            } else if (fc..fc + UNIT).any(|k| t.parent[k as usize] != c) {
                p.push(format!("children of {c} do not point back"));
            }
        }
    }
    if !p.is_empty() {
        return p;
    }
    p.extend(t.check_allocator());
    // 2:1 face balance: every same-depth-or-coarser neighbour of a leaf is
    // at most one level coarser.
    for c in 0..n {
        if t.depth[c as usize] == FREE || !t.is_leaf(c) {
            continue;
        }
        for f in 0..FACES.len() {
            let nb = t.neighbour(c, f);
            if nb != NONE && t.depth[nb as usize] + 1 < t.depth[c as usize] {
                p.push(format!("leaf {c} (depth {}) touches {nb} (depth {})", t.depth[c as usize], t.depth[nb as usize]));
            }
        }
    }
    let o = origins(t);
    if o.iter().enumerate().any(|(c, o)| (t.depth[c] == FREE) != (o[0] == NONE)) {
        p.push("some live cell is not reachable from a root".into());
    }
    let per_cell = g3_table_per_cell(t);
    if per_cell != g3_brute_force(t) {
        p.push("g3 from links differs from the lattice g3".into());
    }
    if g3_table(t) != per_cell {
        p.push("g3 top down differs from g3 cell by cell".into());
    }
    p
}

impl Tree {
    /// A tree from its pools (a saved document), refused unless it is a
    /// valid tree for `canvas` (every check of [`check_structure`] and the
    /// allocator's). The error names the first problem. Its interior values
    /// are as stored: a reader that keeps the tree calls
    /// [`Tree::prefilter_all`] (a document saved before spec 4.4).
    pub fn from_pools(canvas: &Canvas, parent: Vec<u32>, first_child: Vec<u32>, depth: Vec<u8>, rgb: Vec<[u8; 3]>, sigma: Vec<f32>) -> Result<Tree, String> {
        let mut t = Tree::new(canvas);
        let n = parent.len();
        if [first_child.len(), depth.len(), rgb.len(), sigma.len()].iter().any(|&l| l != n) {
            return Err("the pools have different lengths".into());
        }
        if n < t.lat.padded as usize || !n.is_multiple_of(UNIT as usize) || n as u64 > u64::from(canvas.capacity) {
            return Err(format!("{n} cells: not a multiple of 8 between {} and the capacity {}", t.lat.padded, canvas.capacity));
        }
        t.parent = parent;
        t.first_child = first_child;
        t.depth = depth;
        t.rgb = rgb;
        t.sigma = sigma;
        t.rebuild_free_units();
        let mut problems = check_structure(&t);
        problems.extend(t.check_allocator());
        match problems.first() {
            None => Ok(t),
            Some(p) if problems.len() == 1 => Err(p.clone()),
            Some(p) => Err(format!("{p} (and {} more problems)", problems.len() - 1)),
        }
    }
}
