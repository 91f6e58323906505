//! g3, the one stored neighbour per axis of every non-root cell (spec 3.3):
//! the CPU port of the GPU pass. One stage, one name: shaders/g3.wgsl is the
//! GPU twin and reference/octopaint_ref/g3.py the reference.
//!
//! The port ([`g3_cell`], [`g3_row`]) stays shader-shaped so the two can be
//! read side by side: a pure function of the pools (`parent`,
//! `first_child`, `depth`) and the root array, one cell and axis per
//! invocation, fixed-size loops, no recursion, no allocation. Whole tables
//! for dumps and CPU renders come from [`g3_table`], which computes the
//! same rows top down, each child's from its parent's; the tests hold it
//! to the port cell by cell.

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

/// g3 of every cell of the tree, cell by cell with [`g3_row`]: the
/// shader's pass on the CPU (tests hold [`g3_table`] to it).
pub fn g3_table_per_cell(tree: &Tree) -> Vec<[u32; 3]> {
    let inp = G3Input::of(tree);
    (0..tree.n_used()).map(|c| g3_row(&inp, c)).collect()
}

/// g3 of every cell of the tree (tree dumps, renders on the CPU), top
/// down from the roots: a child's row follows from its parent's in a few
/// operations, where [`g3_row`] climbs from each cell towards the root and
/// back (about a tenth of the instructions on the scene trace's trees).
///
/// Child `c` of `p` in octant `k`, axis `a`, outward side `s = k>>a & 1`:
/// the `p`-sized region beyond `p`'s face on side `s` is covered by
/// `g3[p][a]` when `s` is `p`'s own outward side, else by `p`'s sibling
/// across its inward face (roots: the neighbouring root, or none at the
/// canvas boundary). That cell, `y`, is a leaf or of `p`'s depth; in the
/// second case its child facing `c` (octant `k ^ 1<<a`) covers the
/// `c`-sized region, and it exists when `y` has children. This is the
/// climb of [`g3_cell`] taken one level at a time. A cell gets a row only
/// when it is reached through its parent's `first_child` and points back
/// (a consistent tree, which dumps and renders hold); free cells, roots and
/// anything unreachable keep NONE.
pub fn g3_table(tree: &Tree) -> Vec<[u32; 3]> {
    let n = tree.n_used() as usize;
    let mut g3 = vec![[NONE; 3]; n];
    let lat = &tree.lat;
    let mut stack: Vec<u32> = Vec::new();
    for r in 0..lat.n_roots {
        if tree.first_child[r as usize] != NONE {
            stack.push(r);
        }
    }
    while let Some(p) = stack.pop() {
        let pi = p as usize;
        let fc = tree.first_child[pi];
        if fc == NONE || fc as usize + 8 > n {
            continue;
        }
        let d = tree.depth[pi];
        let row = g3[pi];
        // The cell beyond p's face on side s of axis a.
        let beyond = |a: usize, s: u32| -> u32 {
            if d == 0 {
                lat.root_neighbour(p, 2 * a + s as usize).unwrap_or(NONE)
            } else if s == (p >> a) & 1 {
                row[a]
            } else {
                p ^ (1 << a)
            }
        };
        let ys = [[beyond(0, 0), beyond(0, 1)], [beyond(1, 0), beyond(1, 1)], [beyond(2, 0), beyond(2, 1)]];
        let fcs = ys.map(|pair| pair.map(|y| tree.first_child.get(y as usize).copied().unwrap_or(NONE)));
        for k in 0..8u32 {
            let c = fc + k;
            if tree.parent[c as usize] != p || u32::from(tree.depth[c as usize]) != u32::from(d) + 1 {
                continue; // not a consistent tree: left NONE
            }
            g3[c as usize] = std::array::from_fn(|a| {
                let s = ((k >> a) & 1) as usize;
                let (y, fy) = (ys[a][s], fcs[a][s]);
                if y == NONE {
                    NONE
                } else if fy == NONE {
                    y
                } else {
                    fy + (k ^ (1 << a))
                }
            });
            if tree.first_child[c as usize] != NONE {
                stack.push(c);
            }
        }
    }
    g3
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
