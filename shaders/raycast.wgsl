// Ray casting in cell-local coordinates (docs/spec.md 6 and 7), one pixel
// per invocation, writing 8-bit sRGB pixels. CPU port:
// painter/tree/src/raycast/, kept line for line; reference:
// reference/octopaint_ref/raycast.py (the f64 oracle). Host side:
// painter/gpu/src/raycast.rs. Prepended with a precision prelude
// (`alias real = f32;`, or `enable f16; alias real = f16;` for the f16
// variant) and shared/pools.wgsl.
//
// Positions, exit distances and frame changes are `real`; compositing is
// f32. Every position is in the frame of the current cell: centre at 0,
// edge 1.

const LEFT: u32 = 1u;
const OPAQUE: u32 = 2u;
const LOST: u32 = 3u;
const OVERFLOW: u32 = 4u;
const RUNNING: u32 = 0u;
const T_MIN: f32 = 0.00390625; // 1/256 (spec 6)

// 0 unlit, 1 lit, 2 lit with a shadow ray (spec 6.1). A pipeline constant,
// not a uniform: each mode is its own pipeline, so the unlit one carries
// none of the lighting code (a CPU Vulkan such as lavapipe runs both sides
// of a branch its lanes disagree on, and cannot tell a uniform one apart).
override LIT: u32 = 0u;

// 1: walk the cut of a level of detail (spec 7 'Level of detail'; lod.xyz
// the view axis, lod.w lam = min(k alpha, 1) > 0); 0: every ray walks to
// the leaves, with none of the cut's code. A pipeline constant like LIT.
override LOD: u32 = 0u;

// Kept in sync with painter/gpu/src/raycast.rs (RayParams); a layout test
// compares the two through naga.
struct RayParams {
    // xyz: the eye's lattice point clamped into the canvas; w: image width
    eye_cell: vec4<u32>,
    // xyz: the eye minus eye_cell, lattice units (the fraction when inside);
    // w: canvas units per lattice unit
    eye_rel: vec4<f32>,
    // xyz: roots per axis; w: max depth D
    roots: vec4<u32>,
    // xyz: lattice units per axis (R_a * 2^D, exact in f32); w: unused
    extent: vec4<f32>,
    // xyz: the last lattice point per axis, R_a * 2^D - 1; w: cells the
    // pages hold (reads past it are free cells)
    extent_max: vec4<u32>,
    // tan(left), tan(right), tan(up), tan(down)
    tan_fov: vec4<f32>,
    // rows of the camera-to-canvas rotation M(q)
    rot0: vec4<f32>,
    rot1: vec4<f32>,
    rot2: vec4<f32>,
    // rgb background, w unused
    background: vec4<f32>,
    // x: image height, y: step limit, z: roots in all, w: 1 if the eye is
    // inside the canvas (then eye_rel is its fraction in [0, 1))
    misc: vec4<u32>,
    // x: 1 to skip cells whose links disagree (spec 7; 0 only in the
    // real-time benchmark's comparison of strategies); y: 1 to write a
    // probe record per ray instead of a pixel (docs/precision.md); zw:
    // unused
    flags: vec4<u32>,
    // The ground grid, a view aid behind everything (not part of the
    // painting; docs/desktop.md): x, z the eye's position modulo ten
    // spacings, y its height above the canvas floor (canvas units); w the
    // spacing, 0 for no grid.
    grid: vec4<f32>,
    // Lighting (spec 6.1), used when LIT is 1 or 2: xyz the unit direction
    // towards the light, w intensity.
    light: vec4<f32>,
    // x: the ambient term; yzw unused.
    shade: vec4<f32>,
    // The level of detail (spec 7), used when LOD is 1: xyz the camera's
    // view axis M(q) (0, 0, -1) in canvas space, w lam = min(k alpha, 1).
    lod: vec4<f32>,
}

@group(1) @binding(0) var<storage, read> g3_0: array<Row>;
@group(1) @binding(1) var<storage, read> g3_1: array<Row>;
@group(1) @binding(2) var<storage, read> g3_2: array<Row>;
@group(1) @binding(3) var<storage, read> g3_3: array<Row>;

@group(2) @binding(0) var<uniform> params: RayParams;
// One pixel per u32: r | g << 8 | b << 16 | 255 << 24, row 0 at the top.
// With flags.y set, PROBE_WORDS per pixel instead: the probe record.
@group(2) @binding(1) var<storage, read_write> pixels: array<u32>;

// The probe record of one ray (painter/gpu/src/raycast.rs `ProbeRecord`
// reads it): 0 status, 1 steps, 2 the last cell, 3 its depth, 4-6 its
// origin, 7-9 the last exit point in its frame, 10-12 the direction (f32),
// 13 the start cell's depth, 14-16 its origin, 17-19 the start point in
// its frame. Points are `real` widened to f32 (exact).
const PROBE_WORDS: u32 = 20u;

fn probe_put(base: u32, k: u32, v: u32) {
    pixels[base + k] = v;
}

fn probe_put3(base: u32, k: u32, v: vec3<u32>) {
    pixels[base + k] = v.x;
    pixels[base + k + 1u] = v.y;
    pixels[base + k + 2u] = v.z;
}

// The first cell of the tree being walked in the pages: 0 for one tree; a
// document's layers lie one after the other (spec 6.2, `main_layers`),
// each walked with its own cell indices.
var<private> layer_base: u32;

// Cell c of the tree being walked; at or past the cells the pages hold
// (NONE included) a free cell.
fn tcell(c: u32) -> Cell {
    if (c >= cells_held - min(layer_base, cells_held)) {
        return FREE_CELL;
    }
    return cell_at(layer_base + c);
}

// Cell c's row (g3 and the shading vector's word); past the pages, a free
// cell's.
fn row_at(c: u32) -> Row {
    if (c >= cells_held - min(layer_base, cells_held)) {
        return Row(vec3<u32>(NONE), ZERO_WORD);
    }
    let i = layer_base + c;
    let j = i & ((1u << PAGE_SHIFT) - 1u);
    switch (i >> PAGE_SHIFT) {
        case 0u: { return g3_0[j]; }
        case 1u: { return g3_1[j]; }
        case 2u: { return g3_2[j]; }
        default: { return g3_3[j]; }
    }
}

fn g3_at(c: u32, a: u32) -> u32 {
    return row_at(c).g3[a];
}

// Links agree: a root, or a child whose parent's first_child is its unit
// (spec 7, inconsistent links).
fn consistent(c: u32) -> bool {
    if (c < params.misc.z || params.flags.x == 0u) {
        return true;
    }
    let par = tcell(c).parent;
    return par != NONE && tcell(par).first_child == (c & 0xFFFFFFF8u);
}

// base + fl (an integral float) clamped to [0, top], without wrapping.
fn offset_lattice(base: u32, fl: f32, top: u32) -> u32 {
    if (fl >= 0.0) {
        let m = u32(fl);
        return select(top, base + m, m <= top - base);
    }
    let m = u32(-fl);
    return select(0u, base - m, m <= base);
}

// Distance of v (in spacings) to the nearest whole number, in [0, 0.5].
fn to_line(v: f32) -> f32 {
    return 0.5 - abs(fract(v) - 0.5);
}

// What a ray leaving everything sees: the background, or with the grid on
// and the ray going down, the floor plane y = 0 of the canvas: a faint
// tint, lines every spacing and brighter ones every ten, fading with
// distance; a thin horizon line where the ray is level. Kept line for line
// with painter/tree/src/raycast/ `ground`.
fn ground(dir: vec3<f32>) -> vec3<f32> {
    let bg = params.background.xyz;
    let g = params.grid;
    if (g.w <= 0.0) {
        return bg;
    }
    let horizon = 0.06 * clamp(1.0 - abs(dir.y) * 400.0, 0.0, 1.0);
    if (dir.y >= 0.0 || g.y <= 0.0) {
        return bg + vec3<f32>(horizon);
    }
    let t = g.y / -dir.y;
    let x = (g.x + t * dir.x) / g.w;
    let z = (g.z + t * dir.z) / g.w;
    let fade = clamp(1.0 - t / (60.0 * g.w), 0.0, 1.0);
    // A pixel's footprint on the floor, in spacings (stretched where the
    // ray grazes): a line narrower than that is widened to it and dimmed
    // in proportion, so that far lines fade instead of breaking up.
    let px = t * (params.tan_fov.z - params.tan_fov.w) / f32(params.misc.x) / max(-dir.y, 0.001) / g.w;
    let w_minor = max(0.02, px);
    let w_major = max(0.004, px * 0.1);
    let minor = clamp(1.0 - min(to_line(x), to_line(z)) / w_minor, 0.0, 1.0) * (0.02 / w_minor);
    let major = clamp(1.0 - min(to_line(x * 0.1), to_line(z * 0.1)) / w_major, 0.0, 1.0) * (0.004 / w_major);
    let tint = 0.03 * clamp(-dir.y * 20.0, 0.0, 1.0);
    return bg + vec3<f32>(horizon + tint + fade * max(0.12 * minor, 0.3 * major));
}

// 2^-(D - depth), exact.
fn inv_edge(depth: u32) -> f32 {
    return ldexp(1.0, -i32(params.roots.w - depth));
}

// A stored shading vector's word decoded (spec 6.1).
fn decode(word: u32) -> vec3<f32> {
    let q = vec3<u32>(word & 1023u, (word >> 10u) & 1023u, (word >> 20u) & 1023u);
    return (vec3<f32>(q) - 512.0) / 511.0;
}

// The factors of a lit cell's emitted colour (spec 6.1): x the part that
// needs no light, y the direct part (before the shadow ray), from the
// stored vectors interpolated at mu, the segment's midpoint in the cell's
// frame. A cell whose own vector is zero is unlit, without reading its
// neighbours. Across an inward face (the sibling) and from a root (root
// array arithmetic) the neighbour has the cell's depth; across an outward
// face g3 gives one of the same depth or coarser. Kept line for line with
// painter/tree/src/raycast/ `shade` and reference/octopaint_ref/shading.py
// `factors`.
fn shade(cell: u32, depth: u32, mu: vec3<f32>) -> vec2<f32> {
    let row = row_at(cell);
    if (row.shade == ZERO_WORD) {
        return vec2<f32>(1.0, 0.0);
    }
    let own = decode(row.shade);
    var v = own;
    for (var a = 0u; a < 3u; a = a + 1u) {
        if (mu[a] == 0.0) {
            continue;
        }
        let up = mu[a] > 0.0;
        var nb = NONE;
        var h = 1.0;
        if (cell < params.misc.z) {
            nb = root_across(cell, params.roots.xyz, a, select(-1, 1, up));
        } else if ((((cell >> a) & 1u) == 1u) == up) {
            nb = row.g3[a];
            if (nb != NONE) {
                let dn = depth_of(tcell(nb));
                if (dn + 1u == depth) {
                    h = 1.5;
                } else if (dn != depth) {
                    nb = NONE;
                }
            }
        } else {
            nb = cell ^ (1u << a);
        }
        if (nb == NONE) {
            continue;
        }
        let om = abs(mu[a]) / h;
        v = v + om * (decode(row_at(nb).shade) - own);
    }
    let nu = sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    let l = params.light.xyz;
    let v_dot_l = v.x * l.x + v.y * l.y + v.z * l.z;
    return vec2<f32>(1.0 - min(nu, 1.0) * (1.0 - params.shade.x), params.light.w * max(v_dot_l, 0.0) / max(nu, 1.0));
}

// One walk through the cells: a pixel's ray, or a shadow ray.
struct Walk {
    cell: u32,
    depth: u32,
    origin: vec3<u32>,
    p: vec3<real>,
    // composite this cell (false: skipped, spec 7)
    visible: bool,
    // unlit: the colour; lit: the part that needs no light (C0)
    colour: vec3<f32>,
    // lit: the directly lit part (C1), before the shadow ray
    direct: vec3<f32>,
    trans: f32,
    steps: u32,
    status: u32,
    last_exit: vec3<real>,
    // lit with shadows: where the opacity first passed 1/2
    found: bool,
    s_cell: u32,
    s_depth: u32,
    s_origin: vec3<u32>,
    s_p: vec3<real>,
}

fn start_walk(cell: u32, depth: u32, origin: vec3<u32>, p: vec3<real>, status: u32) -> Walk {
    return Walk(cell, depth, origin, p, consistent(cell), vec3<f32>(0.0), vec3<f32>(0.0), 1.0, 0u, status,
        vec3<real>(real(0.0)), false, NONE, 0u, vec3<u32>(0u), vec3<real>(real(0.0)));
}

// Where a walk is (spec 7): the cell, its depth and origin, the point in
// its local frame, whether it is composited, and RUNNING, or LEFT / LOST
// when a step found no cell to enter.
struct Cur {
    cell: u32,
    depth: u32,
    origin: vec3<u32>,
    p: vec3<real>,
    visible: bool,
    status: u32,
}

struct Exit {
    t: real,
    axis: u32,
    bound: real,
}

// Exit distances, clamped at 0; the smallest, ties to the lowest axis
// (spec 7 'Step').
fn exit_of(p: vec3<real>, d: vec3<real>) -> Exit {
    var t_axes = vec3<real>(real(60000.0));
    var bound = vec3<real>(real(-0.5));
    for (var a = 0; a < 3; a = a + 1) {
        bound[a] = select(real(-0.5), real(0.5), d[a] > real(0.0));
        if (d[a] != real(0.0)) {
            t_axes[a] = max((bound[a] - p[a]) / d[a], real(0.0));
        }
    }
    var axis = 0u;
    if (t_axes.y < t_axes[axis]) {
        axis = 1u;
    }
    if (t_axes.z < t_axes[axis]) {
        axis = 2u;
    }
    return Exit(t_axes[axis], axis, bound[axis]);
}

// a - b for lattice coordinates (each below 2^32), exact before its one
// rounding to f32.
fn lattice_diff(a: u32, b: u32) -> f32 {
    return select(-f32(b - a), f32(a - b), a >= b);
}

// Whether the cell of `depth` at lattice `origin` is small (spec 7 'Level of
// detail'): its edge S at most lam times its centre's view depth
// z = sum_a f_a ((o_a - Ec_a) + S/2 - eye_rel_a), lattice units, summed in
// axis order. CPU port: painter/tree/src/raycast/lod.rs.
fn small(depth: u32, origin: vec3<u32>) -> bool {
    let s = f32(1u << (params.roots.w - depth));
    let f = params.lod.xyz;
    var v = vec3<f32>(0.0);
    for (var a = 0u; a < 3u; a = a + 1u) {
        v[a] = (lattice_diff(origin[a], params.eye_cell[a]) + s * 0.5) - params.eye_rel[a];
    }
    let z = (v.x * f.x + v.y * f.y) + v.z * f.z;
    return s <= params.lod.w * z;
}

// The octant bits (x, y, z) of a non-root cell: its index's low three bits
// (spec 2.1); and the child octant holding a point p (ties to the upper half).
fn octant(cell: u32) -> vec3<u32> {
    return vec3<u32>(cell & 1u, (cell >> 1u) & 1u, (cell >> 2u) & 1u);
}

fn octant_at(p: vec3<real>) -> vec3<u32> {
    return vec3<u32>(select(vec3<u32>(0u), vec3<u32>(1u), p >= vec3<real>(0.0)));
}

fn octant_index(bits: vec3<u32>) -> u32 {
    return bits.x | (bits.y << 1u) | (bits.z << 2u);
}

// A point of a cell in octant `bits`, in its parent's frame; a point of a
// cell, in the frame of its child in octant `cbits` (spec 7). CPU port:
// in_parent and child_at in painter/tree/src/raycast/mod.rs.
fn to_parent(p: vec3<real>, bits: vec3<u32>) -> vec3<real> {
    return p * real(0.5) + (vec3<real>(bits) - real(0.5)) * real(0.5);
}

fn to_child(p: vec3<real>, cbits: vec3<u32>) -> vec3<real> {
    return p * real(2.0) + select(vec3<real>(0.5), vec3<real>(-0.5), cbits == vec3<u32>(1u));
}

// From the cell a step entered (same depth or one coarser; `fc0` its first
// child) to the cell of the cut there: up while the cell is not a root and
// its parent is small, then (when it did not go up: a small parent's
// children are small) down while it has a consistent child at the point and
// is not small. The parent's smallness comes from the cell's own index and
// origin, so a step reads the parent link only to go up; one level per
// round, so both loops end within D rounds.
fn settle(c0: Cur, fc0: u32) -> Cur {
    let D = params.roots.w;
    var c = c0;
    var fc = fc0;
    var ascended = false;
    loop {
        if (c.cell < params.misc.z || c.depth == 0u) {
            break;
        }
        let bits = octant(c.cell);
        let o_par = c.origin - bits * (1u << (D - c.depth));
        if (!small(c.depth - 1u, o_par)) {
            break;
        }
        let par = tcell(c.cell).parent;
        if (par == NONE) {
            break;
        }
        c.p = to_parent(c.p, bits);
        c.cell = par;
        c.depth = c.depth - 1u;
        c.origin = o_par;
        c.visible = consistent(par);
        ascended = true;
    }
    loop {
        if (ascended || !c.visible || c.depth >= D) {
            break;
        }
        if (fc == NONE || small(c.depth, c.origin)) {
            break;
        }
        let cbits = octant_at(c.p);
        let child = fc + octant_index(cbits);
        let kid = tcell(child);
        if (params.flags.x != 0u && kid.parent != c.cell) {
            break;
        }
        c.p = to_child(c.p, cbits);
        c.origin = c.origin + cbits * (1u << (D - c.depth - 1u));
        c.cell = child;
        c.depth = c.depth + 1u;
        fc = kid.first_child;
    }
    return c;
}

// The cell after `c` for a ray leaving it after `t` through `axis` (at
// `bound`) along d, with the point in its frame (spec 7 'Next cell', one
// descent at most; with LOD the cell of the cut there): a sibling across an inward face, g3 across an outward
// one, root-array arithmetic for roots. Status LEFT when the ray leaves the
// canvas, LOST at a cell of a depth it cannot enter (only mid-upload).
fn next_cell(c: Cur, t: real, axis: u32, bound: real, d: vec3<real>) -> Cur {
    let D = params.roots.w;
    let rx = params.roots.x;
    let ry = params.roots.y;
    let cell = c.cell;
    let depth = c.depth;
    let origin = c.origin;
    var p_exit = c.p + t * d;
    p_exit[axis] = bound;
    let sgn = select(-1, 1, d[axis] > real(0.0));
    let bits = octant(cell);
    let size = 1u << (D - depth);
    var nxt = NONE;
    if (cell < params.misc.z) {
        var r = vec3<i32>(origin >> vec3<u32>(D));
        r[axis] = r[axis] + sgn;
        if (all(r >= vec3<i32>(0)) && all(vec3<u32>(r) < params.roots.xyz)) {
            nxt = u32(r.x) + rx * (u32(r.y) + ry * u32(r.z));
        }
    } else if ((bits[axis] == 1u) == (sgn > 0)) {
        nxt = g3_at(cell, axis);
    } else {
        nxt = cell ^ (1u << axis);
    }
    var out = c;
    if (nxt == NONE) {
        out.status = LEFT;
        return out;
    }
    let next = tcell(nxt);
    let dn = depth_of(next);
    let coarser = dn + 1u == depth;
    if (dn != depth && !coarser) {
        out.status = LOST; // a freed or unbalanced cell: only mid-upload
        return out;
    }
    // Into the next frame: p' = p * scale + shift (spec 7).
    let entry = real(-0.5) * real(sgn);
    var p_next = p_exit;
    var o_next = origin;
    if (coarser) {
        p_next = to_parent(p_exit, bits);
        o_next = origin - bits * size;
        o_next[axis] = o_next[axis] + u32(sgn) * (2u * size);
    } else {
        o_next[axis] = o_next[axis] + u32(sgn) * size;
    }
    p_next[axis] = entry;
    out = Cur(nxt, dn, o_next, p_next, consistent(nxt), RUNNING);
    if (LOD != 0u) {
        return settle(out, next.first_child);
    }
    // At most one descent, into the child holding the entry point.
    if (out.visible && next.first_child != NONE) {
        let cbits = octant_at(p_next);
        let child = next.first_child + octant_index(cbits);
        if (params.flags.x == 0u || tcell(child).parent == nxt) {
            out.p = to_child(p_next, cbits);
            out.origin = o_next + cbits * (1u << (D - dn - 1u));
            out.cell = child;
            out.depth = dn + 1u;
        }
    }
    return out;
}

// Walk along d from w0 until the ray stops (spec 7 'Step', 'Next cell'),
// compositing as it goes (spec 6, 6.1). shadow: only attenuate.
fn walk(w0: Walk, d: vec3<real>, shadow: bool) -> Walk {
    var w = w0;
    let D = params.roots.w;
    loop {
        if (w.status != RUNNING) {
            break;
        }
        let cell = w.cell;
        let depth = w.depth;
        let origin = w.origin;
        let p = w.p;
        let here = tcell(cell);
        let ex = exit_of(p, d);
        let axis = ex.axis;
        let t = ex.t;

        // Emission-absorption over the segment (f32; spec 6).
        if (w.visible) {
            let edge = ldexp(params.eye_rel.w, i32(D - depth));
            let len_canvas = f32(t) * edge;
            let ext = exp(-here.sigma * len_canvas);
            if (shadow) {
                w.trans = w.trans * ext;
            } else {
                let rgb = vec3<f32>(f32(here.rgbd & 255u), f32((here.rgbd >> 8u) & 255u), f32((here.rgbd >> 16u) & 255u)) / 255.0;
                if (LIT == 0u) {
                    w.colour = w.colour + w.trans * (1.0 - ext) * rgb;
                } else {
                    let emitted = w.trans * (1.0 - ext) * rgb;
                    if (here.sigma > 0.0) {
                        let mu = vec3<f32>(clamp(p + (t * real(0.5)) * d, vec3<real>(real(-0.5)), vec3<real>(real(0.5))));
                        let f = shade(cell, depth, mu);
                        w.colour = w.colour + emitted * f.x;
                        w.direct = w.direct + emitted * f.y;
                    }
                    // The shadow ray starts where T = 1/2 (spec 6.1); only
                    // a pipeline with shadows casts one.
                    if (LIT == 2u && !w.found && w.trans >= 0.5 && w.trans * ext < 0.5) {
                        let per_unit = here.sigma * edge;
                        let t_half = min(log(2.0 * w.trans) / select(1.0, per_unit, per_unit > 0.0), f32(t));
                        w.found = true;
                        w.s_cell = cell;
                        w.s_depth = depth;
                        w.s_origin = origin;
                        w.s_p = clamp(p + real(t_half) * d, vec3<real>(real(-0.5)), vec3<real>(real(0.5)));
                    }
                }
                w.trans = w.trans * ext;
            }
        }

        var p_exit = p + t * d;
        p_exit[axis] = ex.bound;
        w.last_exit = p_exit;
        w.steps = w.steps + 1u;
        if (w.trans < T_MIN) {
            w.status = OPAQUE;
            break;
        }
        let next = next_cell(Cur(cell, depth, origin, p, w.visible, RUNNING), t, axis, ex.bound, d);
        if (next.status != RUNNING) {
            w.status = next.status;
            break;
        }
        if (w.steps >= params.misc.y) {
            w.status = OVERFLOW;
            break;
        }
        w.cell = next.cell;
        w.depth = next.depth;
        w.origin = next.origin;
        w.p = next.p;
        w.visible = next.visible;
    }
    return w;
}

// A pixel's ray where it starts in the canvas (spec 6, 7 'Start'): its
// direction, RUNNING or LEFT (it misses the canvas), the lattice point and
// fraction of its start, and its entry axis (-1 when the eye is inside).
struct RayStart {
    dir: vec3<f32>,
    status: u32,
    q_lat: vec3<u32>,
    q_frac: vec3<f32>,
    entry_axis: i32,
}

fn ray_start(gid: vec3<u32>) -> RayStart {
    let w = params.eye_cell.w;
    let h = params.misc.x;
    // The pixel's ray (spec 6).
    let tl = params.tan_fov.x;
    let tr = params.tan_fov.y;
    let tu = params.tan_fov.z;
    let td = params.tan_fov.w;
    let tx = tl + (f32(gid.x) + 0.5) / f32(w) * (tr - tl);
    let ty = tu - (f32(gid.y) + 0.5) / f32(h) * (tu - td);
    let v = vec3<f32>(
        params.rot0.x * tx + params.rot0.y * ty - params.rot0.z,
        params.rot1.x * tx + params.rot1.y * ty - params.rot1.z,
        params.rot2.x * tx + params.rot2.y * ty - params.rot2.z,
    );
    let dir = v / sqrt(v.x * v.x + v.y * v.y + v.z * v.z);

    // Clip to the canvas box (spec 7 'Start'), in lattice units relative
    // to eye_cell: exact bounds, the eye offset rounded once.
    let e = params.eye_rel.xyz;
    let lo = -vec3<f32>(params.eye_cell.xyz);
    let hi = params.extent.xyz - vec3<f32>(params.eye_cell.xyz);
    var t_in = -3.0e38;
    var t_out = 3.0e38;
    var entry_axis = -1;
    for (var a = 0; a < 3; a = a + 1) {
        let in_slab = e[a] >= lo[a] && e[a] < hi[a];
        var near = select(3.0e38, -3.0e38, in_slab);
        var far = select(-3.0e38, 3.0e38, in_slab);
        if (dir[a] != 0.0) {
            let t0 = (lo[a] - e[a]) / dir[a];
            let t1 = (hi[a] - e[a]) / dir[a];
            near = min(t0, t1);
            far = max(t0, t1);
        }
        if (near > t_in) {
            t_in = near;
            entry_axis = a;
        }
        t_out = min(t_out, far);
    }
    let inside = params.misc.w == 1u;
    var status = RUNNING;
    if (!inside && !(t_in <= t_out && t_out > 0.0)) {
        status = LEFT;
    }
    // The start point as a lattice point plus a fraction.
    var q_lat = params.eye_cell.xyz;
    var q_frac = e;
    if (!inside) {
        let q = e + t_in * dir;
        for (var a = 0; a < 3; a = a + 1) {
            let fl = floor(q[a]);
            q_lat[a] = offset_lattice(params.eye_cell[a], fl, params.extent_max[a]);
            q_frac[a] = q[a] - fl;
        }
    }
    if (!inside && entry_axis >= 0) {
        // On the entry axis the point is the bounding plane itself.
        let ax = u32(entry_axis);
        q_lat[ax] = select(params.extent_max[ax], 0u, dir[ax] > 0.0);
        q_frac[ax] = 0.0;
    }
    q_lat = min(q_lat, params.extent_max.xyz);
    return RayStart(dir, status, q_lat, q_frac, select(entry_axis, -1, inside));
}

// The leaf of the tree being walked where the ray of `rs` starts (spec
// 1.3: a descent refusing a child whose parent does not point back), and
// the local position ((E - o) + phi) / S - 1/2 in it, (E - o) exact.
fn start_cursor(rs: RayStart) -> Cur {
    let D = params.roots.w;
    let rx = params.roots.x;
    let ry = params.roots.y;
    let q_lat = rs.q_lat;
    let root = q_lat >> vec3<u32>(D);
    var cell = root.x + rx * (root.y + ry * root.z);
    var depth = 0u;
    var origin = root << vec3<u32>(D);
    for (var i = 0u; i < D; i = i + 1u) {
        let fc = tcell(cell).first_child;
        if (fc == NONE || (LOD != 0u && small(depth, origin))) {
            break;
        }
        let half = 1u << (D - depth - 1u);
        let bits = vec3<u32>(select(vec3<u32>(0u), vec3<u32>(1u), q_lat - origin >= vec3<u32>(half)));
        let child = fc + octant_index(bits);
        if (params.flags.x != 0u && tcell(child).parent != cell) {
            break;
        }
        cell = child;
        depth = depth + 1u;
        origin = origin + bits * half;
    }
    let inv = inv_edge(depth);
    let rel = vec3<real>(vec3<f32>(q_lat - origin) * inv);
    let frac = vec3<real>(vec3<real>(rs.q_frac) * real(inv));
    var p = (rel + frac) - real(0.5);
    if (rs.entry_axis >= 0) {
        let ax = u32(rs.entry_axis);
        p[ax] = select(real(0.5), real(-0.5), rs.dir[ax] > 0.0);
    }
    p = clamp(p, vec3<real>(-0.5), vec3<real>(0.5));
    return Cur(cell, depth, origin, p, consistent(cell), rs.status);
}

fn write_pixel(gid: vec3<u32>, colour: vec3<f32>) {
    let px = vec3<u32>(clamp(floor(colour * 255.0 + 0.5), vec3<f32>(0.0), vec3<f32>(255.0)));
    pixels[gid.y * params.eye_cell.w + gid.x] = px.x | (px.y << 8u) | (px.z << 16u) | (255u << 24u);
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    cells_held = params.extent_max.w;
    layer_base = 0u;
    let w = params.eye_cell.w;
    let h = params.misc.x;
    if (gid.x >= w || gid.y >= h) {
        return;
    }
    let rs = ray_start(gid);
    let dir = rs.dir;
    let d = vec3<real>(dir);
    let c = start_cursor(rs);
    let probe = params.flags.y != 0u;
    let record = (gid.y * w + gid.x) * PROBE_WORDS;
    if (probe) {
        probe_put3(record, 10u, bitcast<vec3<u32>>(dir));
        probe_put(record, 13u, c.depth);
        probe_put3(record, 14u, c.origin);
        probe_put3(record, 17u, bitcast<vec3<u32>>(vec3<f32>(c.p)));
    }

    let ray = walk(start_walk(c.cell, c.depth, c.origin, c.p, rs.status), d, false);
    if (probe) {
        probe_put(record, 0u, ray.status);
        probe_put(record, 1u, ray.steps);
        probe_put(record, 2u, ray.cell);
        probe_put(record, 3u, ray.depth);
        probe_put3(record, 4u, ray.origin);
        probe_put3(record, 7u, bitcast<vec3<u32>>(vec3<f32>(ray.last_exit)));
        return;
    }
    var colour = ray.colour;
    if (LIT == 1u) {
        colour = colour + ray.direct;
    } else if (LIT == 2u) {
        // One shadow ray towards the light from where the opacity passed
        // 1/2: the same walk in another direction (spec 6.1).
        let start = start_walk(ray.s_cell, ray.s_depth, ray.s_origin, ray.s_p, select(LEFT, RUNNING, ray.found));
        let shadow = walk(start, vec3<real>(params.light.xyz), true);
        colour = colour + shadow.trans * ray.direct;
    }
    write_pixel(gid, colour + ray.trans * ground(dir));
}

// ------------------------------------------------------------------ layers
// A document of several layers (spec 6.2): their pools lie one after the
// other in the pages; per layer k, `at[k].x` is its first cell and
// `at[k].y` its opacity (f32 bits); `count.x` the layers. Kept in sync with
// painter/gpu/src/raycast.rs (LayerTableGpu).
const MAX_LAYERS: u32 = 16u;

struct LayerTable {
    count: vec4<u32>,
    at: array<vec4<u32>, 16>,
}

@group(2) @binding(2) var<uniform> layer_table: LayerTable;

struct March {
    colour: vec3<f32>,
    direct: vec3<f32>,
    trans: f32,
    found: bool,
    s_cur: array<Cur, 16>,
}

// The march of spec 6.2 along d from the cursors `cur0` (status RUNNING:
// inside the canvas): every step composites the interval up to the
// nearest boundary of any layer. shadow: only attenuate. Kept line for line
// with painter/tree/src/raycast/layers.rs `march`.
fn march(cur0: array<Cur, 16>, d: vec3<real>, shadow: bool) -> March {
    let n = layer_table.count.x;
    var cur = cur0;
    let root_size = ldexp(params.eye_rel.w, i32(params.roots.w));
    var out: March;
    out.colour = vec3<f32>(0.0);
    out.direct = vec3<f32>(0.0);
    out.trans = 1.0;
    out.found = false;
    out.s_cur = cur0;
    for (var k = 0u; k < n; k = k + 1u) {
        out.s_cur[k].status = LEFT;
    }
    var ex: array<Exit, 16>;
    var u_k: array<f32, 16>;
    var sig_k: array<f32, 16>;
    var steps = 0u;
    loop {
        var running = false;
        var u = 3.0e38;
        var sig = 0.0;
        for (var k = 0u; k < n; k = k + 1u) {
            u_k[k] = 3.0e38;
            sig_k[k] = 0.0;
            if (cur[k].status == RUNNING) {
                running = true;
                layer_base = layer_table.at[k].x;
                ex[k] = exit_of(cur[k].p, d);
                u_k[k] = f32(ex[k].t) * ldexp(1.0, -i32(cur[k].depth));
                u = min(u, u_k[k]);
                if (cur[k].visible) {
                    sig_k[k] = bitcast<f32>(layer_table.at[k].y) * tcell(cur[k].cell).sigma;
                }
            }
            sig = sig + sig_k[k];
        }
        if (!running) {
            break;
        }
        let ext = exp(-sig * (u * root_size));
        if (!shadow && sig > 0.0) {
            let w = out.trans * (1.0 - ext);
            for (var k = 0u; k < n; k = k + 1u) {
                if (sig_k[k] == 0.0) {
                    continue;
                }
                layer_base = layer_table.at[k].x;
                let c = cur[k];
                let here = tcell(c.cell);
                let share = sig_k[k] / sig;
                let rgb = vec3<f32>(f32(here.rgbd & 255u), f32((here.rgbd >> 8u) & 255u), f32((here.rgbd >> 16u) & 255u)) / 255.0;
                if (LIT == 0u) {
                    out.colour = out.colour + w * share * rgb;
                } else {
                    // Shaded at the interval's midpoint in the cursor's frame.
                    let t_mid = real(u * ldexp(1.0, i32(c.depth)) * 0.5);
                    let mu = vec3<f32>(clamp(c.p + t_mid * d, vec3<real>(real(-0.5)), vec3<real>(real(0.5))));
                    let f = shade(c.cell, c.depth, mu);
                    out.colour = out.colour + w * share * f.x * rgb;
                    out.direct = out.direct + w * share * f.y * rgb;
                }
            }
            if (LIT == 2u && !out.found && out.trans >= 0.5 && out.trans * ext < 0.5) {
                let per_unit = sig * root_size;
                let t_half = min(log(2.0 * out.trans) / per_unit, u);
                out.found = true;
                for (var k = 0u; k < n; k = k + 1u) {
                    let c = cur[k];
                    let t = real(t_half * ldexp(1.0, i32(c.depth)));
                    out.s_cur[k] = c;
                    out.s_cur[k].p = clamp(c.p + t * d, vec3<real>(real(-0.5)), vec3<real>(real(0.5)));
                }
            }
        }
        out.trans = out.trans * ext;
        steps = steps + 1u;
        if (out.trans < T_MIN || steps >= params.misc.y) {
            break;
        }
        for (var k = 0u; k < n; k = k + 1u) {
            if (cur[k].status != RUNNING) {
                continue;
            }
            layer_base = layer_table.at[k].x;
            if (u_k[k] == u) {
                cur[k] = next_cell(cur[k], ex[k].t, ex[k].axis, ex[k].bound, d);
            } else {
                let t = real(u * ldexp(1.0, i32(cur[k].depth)));
                cur[k].p = clamp(cur[k].p + t * d, vec3<real>(real(-0.5)), vec3<real>(real(0.5)));
            }
        }
    }
    return out;
}

// One pixel of a document's contributing layers, bottom first (spec 6.2).
@compute @workgroup_size(8, 8)
fn main_layers(@builtin(global_invocation_id) gid: vec3<u32>) {
    cells_held = params.extent_max.w;
    if (gid.x >= params.eye_cell.w || gid.y >= params.misc.x) {
        return;
    }
    let rs = ray_start(gid);
    let d = vec3<real>(rs.dir);
    let n = layer_table.count.x;
    var cur: array<Cur, 16>;
    for (var k = 0u; k < n; k = k + 1u) {
        layer_base = layer_table.at[k].x;
        cur[k] = start_cursor(rs);
    }
    let ray = march(cur, d, false);
    var colour = ray.colour;
    if (LIT == 1u) {
        colour = colour + ray.direct;
    } else if (LIT == 2u) {
        var s = 1.0;
        if (ray.found) {
            s = march(ray.s_cur, vec3<real>(params.light.xyz), true).trans;
        }
        colour = colour + s * ray.direct;
    }
    write_pixel(gid, colour + ray.trans * ground(rs.dir));
}
