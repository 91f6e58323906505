//! g3, the one stored neighbour per axis of every non-root cell (spec 3.3):
//! the CPU port of the GPU pass. One stage, one name: shaders/g3.wgsl is the
//! GPU twin and reference/octopaint_ref/g3.py the reference.
//!
//! The port stays shader-shaped so the two can be read side by side: a pure
//! function of the pools (`parent`, `first_child`, `depth`) and the root
//! array, one cell and axis per invocation, fixed-size loops, no recursion,
//! no allocation.

use crate::lattice::Lattice;
use crate::pool::{FREE, NONE, Tree};

/// The longest climb: a cell of depth 28 has 28 ancestors below its root.
pub const G3_MAX_CLIMB: usize = 28;

/// Read-only view of what the g3 pass reads (the GPU binds the same three
/// pools plus these root-array constants).
#[derive(Clone, Copy)]
pub struct G3Input<'a> {
    pub parent: &'a [u32],
    pub first_child: &'a [u32],
    pub depth: &'a [u8],
    pub roots: [u32; 3],
}

impl<'a> G3Input<'a> {
    pub fn of(tree: &'a Tree) -> Self {
        G3Input { parent: &tree.parent, first_child: &tree.first_child, depth: &tree.depth, roots: tree.lat.roots }
    }

    // Reads past the pools (NONE included) give a free cell, as on the GPU
    // (shared/pools.wgsl `cell_at`): only a tree caught mid-upload has such
    // links.
    fn depth(&self, c: u32) -> u32 {
        self.depth.get(c as usize).map_or(u32::from(FREE), |&d| u32::from(d))
    }
    fn parent(&self, c: u32) -> u32 {
        self.parent.get(c as usize).copied().unwrap_or(NONE)
    }
    fn first_child(&self, c: u32) -> u32 {
        self.first_child.get(c as usize).copied().unwrap_or(NONE)
    }
}

/// g3[c][a] for one live non-root cell `c` and axis `a`: climb while the
/// face on the outward side is outward for the ancestor too, step to the
/// sibling (or the neighbouring root), mirror the climb back down while
/// children exist. NONE at the canvas boundary.
pub fn g3_cell(inp: &G3Input, c: u32, a: u32) -> u32 {
    let side_bit = (c >> a) & 1; // 1: the +a face is outward
    let mut octants = [0u32; G3_MAX_CLIMB];
    let mut n: usize = 0;
    let mut x = c;
    let mut y: u32;
    loop {
        if inp.depth(x) == 0 {
            // Root-array arithmetic (spec 1.1).
            let rx = inp.roots[0];
            let ry = inp.roots[1];
            let mut xyz = [x % rx, (x / rx) % ry, x / (rx * ry)];
            if side_bit == 1 {
                if xyz[a as usize] + 1 >= inp.roots[a as usize] {
                    return NONE;
                }
                xyz[a as usize] += 1;
            } else {
                if xyz[a as usize] == 0 {
                    return NONE;
                }
                xyz[a as usize] -= 1;
            }
            y = xyz[0] + rx * (xyz[1] + ry * xyz[2]);
            break;
        }
        if (x >> a) & 1 != side_bit {
            y = x ^ (1 << a); // the face is inward here: the sibling
            break;
        }
        if n >= G3_MAX_CLIMB {
            return NONE; // deeper than any valid tree: a cell caught mid-upload
        }
        octants[n] = x & 7;
        n += 1;
        x = inp.parent(x);
    }
    while n > 0 {
        let fc = inp.first_child(y);
        if fc == NONE {
            break;
        }
        n -= 1;
        y = fc + (octants[n] ^ (1 << a));
    }
    y
}

/// g3 of one cell: NONE for roots and free cells.
pub fn g3_row(inp: &G3Input, c: u32) -> [u32; 3] {
    let d = inp.depth(c);
    if d == 0 || d == u32::from(FREE) {
        return [NONE; 3];
    }
    [g3_cell(inp, c, 0), g3_cell(inp, c, 1), g3_cell(inp, c, 2)]
}

/// g3 of every cell of the tree (tree dumps, tests).
pub fn g3_table(tree: &Tree) -> Vec<[u32; 3]> {
    let inp = G3Input::of(tree);
    (0..tree.n_used()).map(|c| g3_row(&inp, c)).collect()
}

/// g3 from lattice geometry (tests): for each outward face, descend from
/// the root containing the point just across it, down to the cell's depth.
pub fn g3_brute_force(tree: &Tree) -> Vec<[u32; 3]> {
    let lat: &Lattice = &tree.lat;
    (0..tree.n_used())
        .map(|c| {
            let d = tree.depth[c as usize];
            if d == 0 || d == FREE {
                return [NONE; 3];
            }
            let o = tree.origin(c);
            let edge = i64::from(lat.edge_lattice(u32::from(d)));
            let mut row = [NONE; 3];
            for (a, slot) in row.iter_mut().enumerate() {
                let mut q = o.map(i64::from);
                q[a] += if (c >> a) & 1 == 1 { edge } else { -edge };
                if q[a] < 0 || q[a] >= lat.extent[a] as i64 {
                    continue;
                }
                *slot = tree.cell_at(q.map(|v| v as u32), u32::from(d));
            }
            row
        })
        .collect()
}
