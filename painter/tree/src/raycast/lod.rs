//! Level of detail (spec 7 "Level of detail"): the walk stops at cells no
//! wider than k footprints of a pixel and composites their prefiltered
//! values (spec 4.4). Whether a cell is small depends on the cell and the
//! camera alone ([`RayParams::with_lod`] sets the camera's constants), so
//! every ray of an image walks the same cut. The shader's `small` and
//! `settle` (shaders/raycast.wgsl) follow these line for line; reference:
//! reference/octopaint_ref/lod.py.

use super::{Cursor, RayInput, RayParams, child_at, consistent, in_parent, octant};
use crate::pool::NONE;

/// `a - b` for lattice coordinates (each below 2^32), exact before its
/// one rounding to f32.
fn lattice_diff(a: u32, b: u32) -> f32 {
    if a >= b { (a - b) as f32 } else { -((b - a) as f32) }
}

/// Whether the cell of `depth` at lattice `origin` is small: its edge `S`
/// at most `lam` times its centre's view depth, `z = sum_a f_a ((o_a -
/// Ec_a) + S/2 - eye_rel_a)` in lattice units, summed in axis order.
pub(super) fn small(pr: &RayParams, depth: u32, origin: [u32; 3]) -> bool {
    let s = (1u64 << (pr.max_depth - depth)) as f32;
    let f = pr.forward;
    let v = [0, 1, 2].map(|a| (lattice_diff(origin[a], pr.eye_cell[a]) + s * 0.5) - pr.eye_rel[a]);
    let z = (v[0] * f[0] + v[1] * f[1]) + v[2] * f[2];
    s <= pr.lod * z
}

/// From the cell a step entered (same depth or one coarser; `fc` its
/// first child) to the cell of the cut there: up while the cell is not a
/// root and its parent is small, then (when it did not go up: a small
/// parent's children are small) down while it has a consistent child at
/// the point and is not small. The parent's smallness comes from the
/// cell's own index and origin, so a step reads the parent link only to go
/// up. Each round is one level, so both loops end within D rounds.
pub(super) fn settle(inp: &RayInput, pr: &RayParams, mut c: Cursor, mut fc: u32) -> Cursor {
    let dd = pr.max_depth;
    let mut ascended = false;
    while c.cell >= pr.n_roots && c.depth > 0 {
        let (p_par, o_par) = in_parent(c.p, c.origin, octant(c.cell), 1u32 << (dd - c.depth));
        if !small(pr, c.depth - 1, o_par) {
            break;
        }
        let par = inp.parent_of(c.cell);
        if par == NONE {
            break;
        }
        c.p = p_par;
        c.cell = par;
        c.depth -= 1;
        c.origin = o_par;
        c.visible = consistent(inp, pr, par);
        ascended = true;
    }
    while !ascended && c.visible && c.depth < dd {
        if fc == NONE || small(pr, c.depth, c.origin) {
            break;
        }
        let (child, p_child, o_child) = child_at(fc, c.p, c.origin, 1u32 << (dd - c.depth - 1));
        if pr.skip_invalid && inp.parent_of(child) != c.cell {
            break;
        }
        c.p = p_child;
        c.origin = o_child;
        c.cell = child;
        c.depth += 1;
        fc = inp.first_child_of(child);
    }
    c
}
