//! Shading vectors (spec 6.1): every live cell's `v = w·n`, the lighting's
//! weight times its normal, from the density gradient across the cell's
//! faces, quantised to 3 × 10 bits in one word stored beside g3. The CPU
//! port of the g3 pass's second half: shaders/g3.wgsl `normal_word`, kept
//! line for line (f32); reference: reference/octopaint_ref/shading.py
//! `vectors` (f64). The ray casters interpolate the words across a leaf
//! (shaders/raycast.wgsl `shade`, its CPU port in octopaint-tree).
//!
//! A cell's word reads only its own g3 row and the pools, so the GPU
//! computes it in the invocation that has just computed that row; which
//! cells a change makes stale is spec 3.4 rule 3 ([`crate::dirty`]).

use crate::pool::{FREE, NONE, Tree};

/// The relative gradient below which a cell is unlit, and above which it
/// is fully lit (spec 6.1).
pub const R_UNLIT: f32 = 0.004;
pub const R_LIT: f32 = 0.02;

/// The word of the zero vector: what unlit cells and free cells hold.
pub const ZERO: u32 = 512 | 512 << 10 | 512 << 20;

/// What the computation reads: the pools, g3 and the root array.
#[derive(Clone, Copy)]
pub struct NormalInput<'a> {
    pub first_child: &'a [u32],
    pub depth: &'a [u8],
    pub sigma: &'a [f32],
    pub g3: &'a [[u32; 3]],
    pub roots: [u32; 3],
}

impl<'a> NormalInput<'a> {
    pub fn of(tree: &'a Tree, g3: &'a [[u32; 3]]) -> Self {
        NormalInput { first_child: tree.first_child(), depth: tree.depth(), sigma: tree.sigma(), g3, roots: tree.lat.roots }
    }

    // Reads past the pools (NONE included) give a free cell, as on the GPU.
    fn sigma_of(&self, c: u32) -> f32 {
        self.sigma.get(c as usize).copied().unwrap_or(0.0)
    }
    fn depth_of(&self, c: u32) -> u32 {
        self.depth.get(c as usize).map_or(u32::from(FREE), |&d| u32::from(d))
    }
    fn first_child_of(&self, c: u32) -> u32 {
        self.first_child.get(c as usize).copied().unwrap_or(NONE)
    }
}

/// The cell across `c`'s face on side `side` (+1/-1) of axis `a`: root
/// array arithmetic for a root, the sibling across an inward face, g3
/// across an outward one; NONE outside the canvas. `row` is `c`'s g3 row.
pub fn across(roots: [u32; 3], c: u32, row: [u32; 3], a: usize, side: i32) -> u32 {
    let n_roots = roots[0] * roots[1] * roots[2];
    if c < n_roots {
        let mut r = [(c % roots[0]) as i32, ((c / roots[0]) % roots[1]) as i32, (c / (roots[0] * roots[1])) as i32];
        r[a] += side;
        if r[a] < 0 || r[a] as u32 >= roots[a] {
            return NONE;
        }
        return r[0] as u32 + roots[0] * (r[1] as u32 + roots[1] * r[2] as u32);
    }
    if ((c >> a) & 1 == 1) == (side > 0) { row[a] } else { c ^ (1 << a) }
}

/// What `c` (of depth `depth`) sees across a face (spec 6.1): the sigma
/// there and the distance between centres in edges of `c`.
fn face(inp: &NormalInput, c: u32, depth: u32, row: [u32; 3], a: usize, side: i32) -> [f32; 2] {
    let nb = across(inp.roots, c, row, a, side);
    if nb == NONE {
        return [0.0, 1.0];
    }
    let dn = inp.depth_of(nb);
    if dn == depth {
        let fc = inp.first_child_of(nb);
        if fc == NONE {
            return [inp.sigma_of(nb), 1.0];
        }
        // The children whose bit a is on the face, by increasing index.
        let want = if side > 0 { 0 } else { 1 };
        let kid = [0u32, 1, 2, 3].map(|j| {
            let lo = j & ((1 << a) - 1);
            let k = ((j >> a) << (a + 1)) | (want << a) | lo;
            inp.sigma_of(fc.wrapping_add(k))
        });
        return [((kid[0] + kid[1]) + (kid[2] + kid[3])) * 0.25, 0.75];
    }
    if dn + 1 == depth {
        return [inp.sigma_of(nb), 1.5];
    }
    [0.0, 1.0]
}

/// One component quantised: `floor(v·511 + 0.5)` clamped to ±511, offset
/// by 512 (spec 6.1).
fn quantise(v: f32) -> u32 {
    ((v * 511.0 + 0.5).floor().clamp(-511.0, 511.0) + 512.0) as u32
}

/// The stored word of cell `c` (spec 6.1): the shader's `normal_word`.
/// Free cells hold [`ZERO`].
pub fn normal_word(inp: &NormalInput, c: u32) -> u32 {
    let depth = inp.depth_of(c);
    if depth == u32::from(FREE) {
        return ZERO;
    }
    let row = inp.g3.get(c as usize).copied().unwrap_or([NONE; 3]);
    let mut delta = [0f32; 3];
    let mut top = inp.sigma_of(c);
    for a in 0..3 {
        let hi = face(inp, c, depth, row, a, 1);
        let lo = face(inp, c, depth, row, a, -1);
        delta[a] = (hi[0] - lo[0]) / (hi[1] + lo[1]);
        top = top.max(hi[0].max(lo[0]));
    }
    let g = (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt();
    let r = if top > 0.0 { g / top } else { 0.0 };
    let w = ((r - R_UNLIT) / (R_LIT - R_UNLIT)).clamp(0.0, 1.0);
    // n = -delta / g points out of the paint; v = w n.
    let scale = if g > 0.0 { -w / g } else { 0.0 };
    quantise(delta[0] * scale) | quantise(delta[1] * scale) << 10 | quantise(delta[2] * scale) << 20
}

/// A stored word decoded: `(field − 512) / 511` per component.
#[inline]
pub fn decode(word: u32) -> [f32; 3] {
    [0, 1, 2].map(|a| (((word >> (10 * a)) & 1023) as f32 - 512.0) / 511.0)
}

/// g3 and the word side by side, one 16-byte row per cell, for a tree
/// with its g3 table: the GPU's layout (docs/buffer-layouts.md) and what
/// the CPU ray caster reads.
pub fn rows(tree: &Tree, g3: &[[u32; 3]]) -> Vec<[u32; 4]> {
    let inp = NormalInput::of(tree, g3);
    g3.iter().enumerate().map(|(c, r)| [r[0], r[1], r[2], normal_word(&inp, c as u32)]).collect()
}

/// [`rows`] with the g3 table computed here.
pub fn table(tree: &Tree) -> Vec<[u32; 4]> {
    rows(tree, &crate::g3::g3_table(tree))
}

#[cfg(test)]
mod tests {
    use super::*;
    use octopaint_model::Canvas;

    #[test]
    fn components_round_half_up_and_clamp() {
        assert_eq!(quantise(0.0), 512);
        assert_eq!(quantise(0.5), 512 + 256);
        assert_eq!(quantise(-0.5), 512 - 255);
        assert_eq!(quantise(2.0), 1023);
        assert_eq!(quantise(-2.0), 1);
        assert_eq!(decode(ZERO), [0.0; 3]);
        assert_eq!(decode(1023 | 1 << 10 | 512 << 20), [1.0, -1.0, 0.0]);
    }

    #[test]
    fn even_paint_is_zero_and_an_edge_points_out() {
        // 3 x 1 x 1 roots: a step in sigma along x.
        let mut tree = Tree::new(&Canvas { roots: [3, 1, 1], max_depth: 3, root_size: 1.0, capacity: 1024 });
        for (c, s) in [(0, 1.0), (1, 1.0), (2, 1.0)] {
            tree.set_value(c, [9, 9, 9], s);
        }
        let t = table(&tree);
        // The middle sees equal paint both ways; the ends see nothing
        // beyond the canvas: fully lit, pointing out along x.
        assert_eq!(t[1][3], ZERO);
        assert_eq!(decode(t[0][3]), [-1.0, 0.0, 0.0]);
        assert_eq!(decode(t[2][3]), [1.0, 0.0, 0.0]);
        assert!(t[3..].iter().all(|r| r[3] == ZERO), "free cells");
    }
}
