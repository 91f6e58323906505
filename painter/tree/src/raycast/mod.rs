//! Ray casting in cell-local coordinates: the CPU port of
//! shaders/raycast.wgsl (f32 variant), kept line for line so the two can be
//! compared; painter/gpu tests render with both and compare the images.
//! Reference: reference/octopaint_ref/raycast.py (the f64 oracle, spec 6
//! and 7). The host-side camera set-up shared with the GPU is
//! [`RayParams::new`].

mod layers;
mod lod;
mod params;

pub use layers::{LayerInput, render_layers, trace_pixel_layers};
pub use params::{DEFAULT_LOD, MAX_LOD, RayParams, check_lod, parse_lods};

use crate::normals;
use crate::pool::{FREE, NONE};

/// Steps before a ray gives up (a broken tree caught mid-upload).
pub const MAX_STEPS: u32 = 1 << 16;
const T_MIN: f32 = 1.0 / 256.0;

/// Distance of v (in spacings) to the nearest whole number; `v -
/// floor(v)` is WGSL's `fract` (Rust's keeps the sign).
fn to_line(v: f32) -> f32 {
    0.5 - ((v - v.floor()) - 0.5).abs()
}

/// The shader's `ground`: the background, or the grid on the floor.
fn ground(pr: &RayParams, dir: [f32; 3]) -> [f32; 3] {
    let bg = pr.background;
    let g = pr.grid;
    if g[3] <= 0.0 {
        return bg;
    }
    let horizon = 0.06 * (1.0 - dir[1].abs() * 400.0).clamp(0.0, 1.0);
    if dir[1] >= 0.0 || g[1] <= 0.0 {
        return bg.map(|c| c + horizon);
    }
    let t = g[1] / -dir[1];
    let x = (g[0] + t * dir[0]) / g[3];
    let z = (g[2] + t * dir[2]) / g[3];
    let fade = (1.0 - t / (60.0 * g[3])).clamp(0.0, 1.0);
    let px = t * (pr.tan_fov[2] - pr.tan_fov[3]) / pr.height as f32 / (-dir[1]).max(0.001) / g[3];
    let w_minor = px.max(0.02);
    let w_major = (px * 0.1).max(0.004);
    let minor = (1.0 - to_line(x).min(to_line(z)) / w_minor).clamp(0.0, 1.0) * (0.02 / w_minor);
    let major = (1.0 - to_line(x * 0.1).min(to_line(z * 0.1)) / w_major).clamp(0.0, 1.0) * (0.004 / w_major);
    let tint = 0.03 * (-dir[1] * 20.0).clamp(0.0, 1.0);
    bg.map(|c| c + (horizon + tint + fade * (0.12 * minor).max(0.3 * major)))
}

/// What the shader reads: the pools, and g3 with the stored shading
/// vectors in rows of four words as the GPU holds them
/// ([`normals::table`]).
pub struct RayInput<'a> {
    pub parent: &'a [u32],
    pub first_child: &'a [u32],
    pub depth: &'a [u8],
    pub rgb: &'a [[u8; 3]],
    pub sigma: &'a [f32],
    pub rows: &'a [[u32; 4]],
}

impl<'a> RayInput<'a> {
    /// The pools of `tree` with its rows of g3 and shading vectors.
    pub fn of(tree: &'a crate::pool::Tree, rows: &'a [[u32; 4]]) -> Self {
        RayInput { parent: tree.parent(), first_child: tree.first_child(), depth: tree.depth(), rgb: tree.rgb(), sigma: tree.sigma(), rows }
    }
}

impl RayInput<'_> {
    // Reads past the pools (NONE included) give a free cell, as on the GPU
    // (shared/pools.wgsl `cell_at`).
    fn sigma_of(&self, c: u32) -> f32 {
        self.sigma.get(c as usize).copied().unwrap_or(0.0)
    }
    fn g3_of(&self, c: u32, a: usize) -> u32 {
        self.rows.get(c as usize).map_or(NONE, |row| row[a])
    }
    fn vector_of(&self, c: u32) -> [f32; 3] {
        normals::decode(self.rows.get(c as usize).map_or(normals::ZERO, |row| row[3]))
    }
    fn depth_of(&self, c: u32) -> u32 {
        self.depth.get(c as usize).map_or(u32::from(FREE), |&d| u32::from(d))
    }
    fn parent_of(&self, c: u32) -> u32 {
        self.parent.get(c as usize).copied().unwrap_or(NONE)
    }
    fn first_child_of(&self, c: u32) -> u32 {
        self.first_child.get(c as usize).copied().unwrap_or(NONE)
    }
}

fn consistent(inp: &RayInput, p: &RayParams, c: u32) -> bool {
    if c < p.n_roots || !p.skip_invalid {
        return true;
    }
    let par = inp.parent_of(c);
    par != NONE && inp.first_child_of(par) == (c & 0xFFFF_FFF8)
}

fn ldexp(x: f32, e: i32) -> f32 {
    x * 2f32.powi(e)
}

fn offset_lattice(base: u32, fl: f32, top: u32) -> u32 {
    if fl >= 0.0 {
        let m = fl as u32;
        if m <= top - base { base + m } else { top }
    } else {
        let m = (-fl) as u32;
        base.saturating_sub(m)
    }
}

/// The shader's `shade`: the factors of a lit cell's emitted colour, the
/// part that needs no light and the direct part (spec 6.1), with the
/// stored vectors interpolated at `mu`, the segment's midpoint in the
/// cell's frame; a cell whose own vector is zero is unlit, its neighbours
/// unread.
fn shade(inp: &RayInput, pr: &RayParams, cell: u32, depth: u32, mu: [f32; 3]) -> [f32; 2] {
    let row = inp.rows.get(cell as usize).copied().unwrap_or([NONE, NONE, NONE, normals::ZERO]);
    if row[3] == normals::ZERO {
        return [1.0, 0.0];
    }
    let own = normals::decode(row[3]);
    let mut v = own;
    for a in 0..3 {
        if mu[a] == 0.0 {
            continue;
        }
        let up = mu[a] > 0.0;
        let mut nb = normals::across(pr.roots, cell, [row[0], row[1], row[2]], a, if up { 1 } else { -1 });
        let mut h = 1.0;
        // Only g3 (an outward face of a non-root) may give a coarser cell.
        if nb != NONE && cell >= pr.n_roots && ((cell >> a) & 1 == 1) == up {
            let dn = inp.depth_of(nb);
            if dn + 1 == depth {
                h = 1.5;
            } else if dn != depth {
                nb = NONE;
            }
        }
        if nb == NONE {
            continue;
        }
        let om = mu[a].abs() / h;
        let vn = inp.vector_of(nb);
        for b in 0..3 {
            v[b] += om * (vn[b] - own[b]);
        }
    }
    let nu = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let l = pr.light;
    let v_dot_l = v[0] * l[0] + v[1] * l[1] + v[2] * l[2];
    [1.0 - nu.min(1.0) * (1.0 - pr.ambient), l[3] * v_dot_l.max(0.0) / nu.max(1.0)]
}

/// The shader's `Walk`: one walk through the cells, a pixel's ray or a
/// shadow ray.
#[derive(Clone, Copy)]
struct Walk {
    cell: u32,
    depth: u32,
    origin: [u32; 3],
    p: [f32; 3],
    visible: bool,
    colour: [f32; 3],
    direct: [f32; 3],
    trans: f32,
    running: bool,
    found: bool,
    s_cell: u32,
    s_depth: u32,
    s_origin: [u32; 3],
    s_p: [f32; 3],
}

fn start_walk(inp: &RayInput, pr: &RayParams, cell: u32, depth: u32, origin: [u32; 3], p: [f32; 3], running: bool) -> Walk {
    Walk {
        cell,
        depth,
        origin,
        p,
        visible: consistent(inp, pr, cell),
        colour: [0.0; 3],
        direct: [0.0; 3],
        trans: 1.0,
        running,
        found: false,
        s_cell: NONE,
        s_depth: 0,
        s_origin: [0; 3],
        s_p: [0.0; 3],
    }
}

/// Where a walk is: its cell, depth and origin, the point in the cell's
/// local frame, and whether the cell is composited (spec 7).
#[derive(Clone, Copy)]
struct Cursor {
    cell: u32,
    depth: u32,
    origin: [u32; 3],
    p: [f32; 3],
    visible: bool,
}

/// The octant bits (x, y, z) of a non-root cell: its index's low three
/// bits, siblings being stored in octant order (spec 2.1).
fn octant(cell: u32) -> [u32; 3] {
    [cell & 1, (cell >> 1) & 1, (cell >> 2) & 1]
}

/// The index of octant `bits` within its unit.
fn octant_index(bits: [u32; 3]) -> u32 {
    bits[0] | (bits[1] << 1) | (bits[2] << 2)
}

/// A point `p` of a cell in octant `bits` of edge `size` (lattice units)
/// at lattice `origin`, as a point of its parent's frame with the parent's
/// origin.
fn in_parent(p: [f32; 3], origin: [u32; 3], bits: [u32; 3], size: u32) -> ([f32; 3], [u32; 3]) {
    let p_par = [0, 1, 2].map(|a| p[a] * 0.5 + (bits[a] as f32 - 0.5) * 0.5);
    let o_par = [0, 1, 2].map(|a| origin[a].wrapping_sub(bits[a] * size));
    (p_par, o_par)
}

/// The child holding `p` of a cell whose first child is `fc` (ties to the
/// upper half), with `p` and the origin in the child's frame; `half` is
/// the child's edge in lattice units.
fn child_at(fc: u32, p: [f32; 3], origin: [u32; 3], half: u32) -> (u32, [f32; 3], [u32; 3]) {
    let cbits = p.map(|v| u32::from(v >= 0.0));
    let child = fc + octant_index(cbits);
    let p_child = [0, 1, 2].map(|a| p[a] * 2.0 + if cbits[a] == 1 { -0.5 } else { 0.5 });
    let o_child = [0, 1, 2].map(|a| origin[a].wrapping_add(cbits[a] * half));
    (child, p_child, o_child)
}

/// The exit distance from `p` along `d`, the exit axis and the bound per
/// axis (spec 7 "Step"; ties to the lowest axis).
fn exit(p: [f32; 3], d: [f32; 3]) -> (f32, usize, [f32; 3]) {
    let mut t_axes = [60000f32; 3];
    let mut bound = [-0.5f32; 3];
    for a in 0..3 {
        bound[a] = if d[a] > 0.0 { 0.5 } else { -0.5 };
        if d[a] != 0.0 {
            t_axes[a] = ((bound[a] - p[a]) / d[a]).max(0.0);
        }
    }
    let mut axis = 0usize;
    if t_axes[1] < t_axes[axis] {
        axis = 1;
    }
    if t_axes[2] < t_axes[axis] {
        axis = 2;
    }
    (t_axes[axis], axis, bound)
}

/// The cell after `c` for a ray leaving it after `t` through axis `axis`
/// (bound `bound`) along `d`, with the point in its frame (spec 7 "Next
/// cell", one descent at most; with a level of detail, the cell of the cut
/// there); None when the ray leaves the canvas or meets a cell of a depth
/// it cannot enter.
fn next_cell(inp: &RayInput, pr: &RayParams, c: &Cursor, t: f32, axis: usize, bound: f32, d: [f32; 3]) -> Option<Cursor> {
    let dd = pr.max_depth;
    let (rx, ry) = (pr.roots[0], pr.roots[1]);
    let (cell, depth, origin, p) = (c.cell, c.depth, c.origin, c.p);
    let mut p_exit = [0, 1, 2].map(|a| p[a] + t * d[a]);
    p_exit[axis] = bound;

    let sgn: i32 = if d[axis] > 0.0 { 1 } else { -1 };
    let bits = octant(cell);
    let size = 1u32 << (dd - depth);
    let mut nxt = NONE;
    if cell < pr.n_roots {
        let mut r = origin.map(|v| (v >> dd) as i32);
        r[axis] += sgn;
        if r.iter().all(|&v| v >= 0) && (0..3).all(|a| (r[a] as u32) < pr.roots[a]) {
            nxt = r[0] as u32 + rx * (r[1] as u32 + ry * r[2] as u32);
        }
    } else if (bits[axis] == 1) == (sgn > 0) {
        nxt = inp.g3_of(cell, axis);
    } else {
        nxt = cell ^ (1 << axis);
    }
    if nxt == NONE {
        return None;
    }
    let dn = inp.depth_of(nxt);
    let coarser = dn + 1 == depth;
    if dn != depth && !coarser {
        return None;
    }
    let entry = -0.5 * sgn as f32;
    let mut p_next = p_exit;
    let mut o_next = origin;
    if coarser {
        (p_next, o_next) = in_parent(p_exit, origin, bits, size);
        o_next[axis] = o_next[axis].wrapping_add((sgn as u32).wrapping_mul(2 * size));
    } else {
        o_next[axis] = o_next[axis].wrapping_add((sgn as u32).wrapping_mul(size));
    }
    p_next[axis] = entry;
    let mut out = Cursor { cell: nxt, depth: dn, origin: o_next, p: p_next, visible: consistent(inp, pr, nxt) };
    let fc = inp.first_child_of(nxt);
    if pr.lod > 0.0 {
        return Some(lod::settle(inp, pr, out, fc));
    }
    if out.visible && fc != NONE {
        let (child, p_child, o_child) = child_at(fc, p_next, o_next, 1u32 << (dd - dn - 1));
        if !pr.skip_invalid || inp.parent_of(child) == nxt {
            out = Cursor { cell: child, depth: dn + 1, origin: o_child, p: p_child, ..out };
        }
    }
    Some(out)
}

/// The shader's `walk`: along `d` from `w` until the ray stops,
/// compositing as it goes; `shadow`: only attenuate.
fn walk(inp: &RayInput, pr: &RayParams, mut w: Walk, d: [f32; 3], shadow: bool) -> Walk {
    let dd = pr.max_depth;
    let mut steps = 0u32;
    while w.running {
        let (cell, depth, origin, p) = (w.cell, w.depth, w.origin, w.p);
        let (t, axis, bound) = exit(p, d);

        if w.visible {
            let edge = ldexp(pr.lattice_unit, (dd - depth) as i32);
            let len_canvas = t * edge;
            let sigma = inp.sigma_of(cell);
            let ext = (-sigma * len_canvas).exp();
            if shadow {
                w.trans *= ext;
            } else {
                let rgb = inp.rgb.get(cell as usize).copied().unwrap_or([0; 3]).map(|c| c as f32 / 255.0);
                if pr.lit == 0 {
                    for i in 0..3 {
                        w.colour[i] += w.trans * (1.0 - ext) * rgb[i];
                    }
                } else {
                    let emitted = rgb.map(|c| w.trans * (1.0 - ext) * c);
                    if sigma > 0.0 {
                        let mu = [0, 1, 2].map(|a| (p[a] + (t * 0.5) * d[a]).clamp(-0.5, 0.5));
                        let f = shade(inp, pr, cell, depth, mu);
                        for i in 0..3 {
                            w.colour[i] += emitted[i] * f[0];
                            w.direct[i] += emitted[i] * f[1];
                        }
                    }
                    // Only a cast with shadows keeps the shadow ray's start.
                    if pr.lit == 2 && !w.found && w.trans >= 0.5 && w.trans * ext < 0.5 {
                        let per_unit = sigma * edge;
                        let t_half = ((2.0 * w.trans).ln() / if per_unit > 0.0 { per_unit } else { 1.0 }).min(t);
                        w.found = true;
                        w.s_cell = cell;
                        w.s_depth = depth;
                        w.s_origin = origin;
                        w.s_p = [0, 1, 2].map(|a| (p[a] + t_half * d[a]).clamp(-0.5, 0.5));
                    }
                }
                w.trans *= ext;
            }
        }

        steps += 1;
        w.running = false;
        if w.trans < T_MIN {
            break;
        }
        let here = Cursor { cell, depth, origin, p, visible: w.visible };
        let Some(next) = next_cell(inp, pr, &here, t, axis, bound[axis], d) else { break };
        if steps >= pr.max_steps {
            break;
        }
        w.running = true;
        w.cell = next.cell;
        w.depth = next.depth;
        w.origin = next.origin;
        w.p = next.p;
        w.visible = next.visible;
    }
    w
}

/// A pixel's ray where it starts in the canvas (spec 7 "Start", the
/// shader's `main` up to the descent): its direction, whether it meets the
/// canvas, the lattice point and fraction of its start, and its entry axis
/// (-1 when the eye is inside).
struct RayStart {
    dir: [f32; 3],
    running: bool,
    q_lat: [u32; 3],
    q_frac: [f32; 3],
    entry_axis: i32,
}

fn ray_start(pr: &RayParams, x: u32, y: u32) -> RayStart {
    let (w, h) = (pr.width, pr.height);
    let [tl, tr, tu, td] = pr.tan_fov;
    let tx = tl + (x as f32 + 0.5) / w as f32 * (tr - tl);
    let ty = tu - (y as f32 + 0.5) / h as f32 * (tu - td);
    let v = pr.rot.map(|row| row[0] * tx + row[1] * ty - row[2]);
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let dir = v.map(|c| c / n);

    let e = pr.eye_rel;
    let lo = pr.eye_cell.map(|c| -(c as f32));
    let hi = [0, 1, 2].map(|a| pr.extent[a] - pr.eye_cell[a] as f32);
    let mut t_in = -3.0e38f32;
    let mut t_out = 3.0e38f32;
    let mut entry_axis: i32 = -1;
    for a in 0..3 {
        let in_slab = e[a] >= lo[a] && e[a] < hi[a];
        let mut near = if in_slab { -3.0e38 } else { 3.0e38 };
        let mut far = if in_slab { 3.0e38 } else { -3.0e38 };
        if dir[a] != 0.0 {
            let t0 = (lo[a] - e[a]) / dir[a];
            let t1 = (hi[a] - e[a]) / dir[a];
            near = t0.min(t1);
            far = t0.max(t1);
        }
        if near > t_in {
            t_in = near;
            entry_axis = a as i32;
        }
        t_out = t_out.min(far);
    }
    let inside = pr.inside;
    let mut running = true;
    if !inside && !(t_in <= t_out && t_out > 0.0) {
        running = false;
    }
    let mut q_lat = pr.eye_cell;
    let mut q_frac = e;
    if !inside {
        for a in 0..3 {
            let q = e[a] + t_in * dir[a];
            let fl = q.floor();
            q_lat[a] = offset_lattice(pr.eye_cell[a], fl, pr.extent_max[a]);
            q_frac[a] = q - fl;
        }
    }
    if !inside && entry_axis >= 0 {
        let ax = entry_axis as usize;
        q_lat[ax] = if dir[ax] > 0.0 { 0 } else { pr.extent_max[ax] };
        q_frac[ax] = 0.0;
    }
    for a in 0..3 {
        q_lat[a] = q_lat[a].min(pr.extent_max[a]);
    }
    RayStart { dir, running, q_lat, q_frac, entry_axis: if inside { -1 } else { entry_axis } }
}

/// The leaf of `inp` (or the cell of the cut, spec 7 "Level of detail")
/// where the ray of `rs` starts, and the point in it.
fn start_cursor(inp: &RayInput, pr: &RayParams, rs: &RayStart) -> Cursor {
    let dd = pr.max_depth;
    let (q_lat, q_frac, dir) = (rs.q_lat, rs.q_frac, rs.dir);
    let (rx, ry) = (pr.roots[0], pr.roots[1]);
    let root = q_lat.map(|v| v >> dd);
    let mut cell = root[0] + rx * (root[1] + ry * root[2]);
    let mut depth = 0u32;
    let mut origin = root.map(|v| v << dd);
    for _ in 0..dd {
        let fc = inp.first_child_of(cell);
        if fc == NONE || (pr.lod > 0.0 && lod::small(pr, depth, origin)) {
            break;
        }
        let half = 1u32 << (dd - depth - 1);
        let bits = [0, 1, 2].map(|a| u32::from(q_lat[a] - origin[a] >= half));
        let child = fc + octant_index(bits);
        if pr.skip_invalid && inp.parent_of(child) != cell {
            break;
        }
        cell = child;
        depth += 1;
        origin = [0, 1, 2].map(|a| origin[a] + bits[a] * half);
    }
    let inv = ldexp(1.0, -((dd - depth) as i32));
    let mut p = [0, 1, 2].map(|a| {
        let rel = (q_lat[a] - origin[a]) as f32 * inv;
        let frac = q_frac[a] * inv;
        (rel + frac) - 0.5
    });
    if rs.entry_axis >= 0 {
        let ax = rs.entry_axis as usize;
        p[ax] = if dir[ax] > 0.0 { -0.5 } else { 0.5 };
    }
    p = p.map(|v| v.clamp(-0.5, 0.5));
    Cursor { cell, depth, origin, p, visible: consistent(inp, pr, cell) }
}

/// One pixel, as the shader's `main` computes it: 8-bit sRGB.
pub fn trace_pixel(inp: &RayInput, params: &RayParams, x: u32, y: u32) -> [u8; 3] {
    let pr = params;
    let rs = ray_start(pr, x, y);
    let d = rs.dir;
    let c = start_cursor(inp, pr, &rs);
    let ray = walk(inp, pr, start_walk(inp, pr, c.cell, c.depth, c.origin, c.p, rs.running), d, false);
    let mut colour = ray.colour;
    if pr.lit == 1 {
        for i in 0..3 {
            colour[i] += ray.direct[i];
        }
    } else if pr.lit == 2 {
        // One shadow ray towards the light from where the opacity passed
        // 1/2: the same walk in another direction (spec 6.1).
        let start = start_walk(inp, pr, ray.s_cell, ray.s_depth, ray.s_origin, ray.s_p, ray.found);
        let l = [pr.light[0], pr.light[1], pr.light[2]];
        let s = walk(inp, pr, start, l, true).trans;
        for i in 0..3 {
            colour[i] += s * ray.direct[i];
        }
    }
    let back = ground(pr, d);
    for i in 0..3 {
        colour[i] += ray.trans * back[i];
    }
    colour.map(|c| (c * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8)
}

/// A whole image, row 0 at the top: `width·height·3` bytes of sRGB.
pub fn render(inp: &RayInput, params: &RayParams) -> Vec<u8> {
    let mut out = Vec::with_capacity((params.width * params.height * 3) as usize);
    for y in 0..params.height {
        for x in 0..params.width {
            out.extend_from_slice(&trace_pixel(inp, params, x, y));
        }
    }
    out
}

#[cfg(test)]
mod tests;
