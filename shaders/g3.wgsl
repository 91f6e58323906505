// The g3 pass (docs/spec.md 3.3-3.5, 6.1): recompute g3 and the stored
// shading vector of every cell of the regions the neighbour mask marks. g3
// comes from parent, first_child and depth alone; the vector from the
// cell's new g3 row and the pools (sigma included), so one invocation
// computes both. Rows are four words: g3 x, y, z and the vector's word
// (docs/buffer-layouts.md). A document's layer lives in its own range of the pages (spec 6.2):
// its cells are read and its g3 written at `base` plus the tree's own
// index, and g3 holds the tree's own indices (one tree: base 0). CPU port: painter/octree/src/g3.rs (g3_cell, g3_row), kept line for
// line, and painter/octree/src/normals.rs (normal_word); reference:
// reference/octopaint_ref/g3.py and shading.py (vectors). Host side:
// painter/gpu/src/g3.rs. Prepended with shared/pools.wgsl.

struct G3Params {
    roots: vec3<u32>,
    // cells per region, ceil(capacity / 2048) (spec 3.5)
    region_cells: u32,
    // entries of `regions` to process
    n_regions: u32,
    // workgroups per region: ceil(region_cells / 64)
    chunks: u32,
    // cells the pages hold: every cell below is valid to read
    n_cells: u32,
    // workgroups per row of the 2D dispatch
    row: u32,
    // the layer's first cell in the pages
    base: u32,
    // cells of the layer's range: its indices below are valid to read
    layer_cells: u32,
}

@group(1) @binding(0) var<storage, read_write> g3_0: array<Row>;
@group(1) @binding(1) var<storage, read_write> g3_1: array<Row>;
@group(1) @binding(2) var<storage, read_write> g3_2: array<Row>;
@group(1) @binding(3) var<storage, read_write> g3_3: array<Row>;

@group(2) @binding(0) var<uniform> params: G3Params;
// The dirty regions (indices < 2048), compacted from the mask on the host.
@group(2) @binding(1) var<storage, read> regions: array<u32>;

// Cell `i` of the layer (its own index); past its range, a free cell.
fn layer_cell(i: u32) -> Cell {
    if (i >= params.layer_cells) {
        return FREE_CELL;
    }
    return cell_at(params.base + i);
}

// Cell i's row (the layer's own index).
fn store_row(i: u32, row: Row) {
    let c = params.base + i;
    let j = c & ((1u << PAGE_SHIFT) - 1u);
    switch (c >> PAGE_SHIFT) {
        case 0u: { g3_0[j] = row; }
        case 1u: { g3_1[j] = row; }
        case 2u: { g3_2[j] = row; }
        default: { g3_3[j] = row; }
    }
}

// g3[c][a] for a live non-root cell: climb while the outward face stays
// outward, step to the sibling (or the neighbouring root), mirror the climb
// back down while children exist. NONE at the canvas boundary.
fn g3_cell(c: u32, a: u32) -> u32 {
    let side_bit = (c >> a) & 1u;
    var octants: array<u32, 28>;
    var n = 0u;
    var x = c;
    var y = NONE;
    loop {
        let cx = layer_cell(x);
        if (depth_of(cx) == 0u) {
            let rx = params.roots.x;
            let ry = params.roots.y;
            var xyz = vec3<u32>(x % rx, (x / rx) % ry, x / (rx * ry));
            if (side_bit == 1u) {
                if (xyz[a] + 1u >= params.roots[a]) {
                    return NONE;
                }
                xyz[a] = xyz[a] + 1u;
            } else {
                if (xyz[a] == 0u) {
                    return NONE;
                }
                xyz[a] = xyz[a] - 1u;
            }
            y = xyz.x + rx * (xyz.y + ry * xyz.z);
            break;
        }
        if (((x >> a) & 1u) != side_bit) {
            y = x ^ (1u << a);
            break;
        }
        if (n >= 28u) {
            return NONE; // deeper than any valid tree: a cell caught mid-upload
        }
        octants[n] = x & 7u;
        n = n + 1u;
        x = cx.parent;
    }
    loop {
        if (n == 0u) {
            break;
        }
        let fc = layer_cell(y).first_child;
        if (fc == NONE) {
            break;
        }
        n = n - 1u;
        y = fc + (octants[n] ^ (1u << a));
    }
    return y;
}

// Spec 6.1: the relative gradient below which a cell is unlit, and above
// which it is fully lit.
const R_UNLIT: f32 = 0.004;
const R_LIT: f32 = 0.02;

// The cell across c's face on side `side` of axis a: root array arithmetic
// for a root, the sibling across an inward face, g3 (c's row) across an
// outward one; NONE outside the canvas.
fn across(c: u32, row: vec3<u32>, a: u32, side: i32) -> u32 {
    if (c < params.roots.x * params.roots.y * params.roots.z) {
        return root_across(c, params.roots, a, side);
    }
    if ((((c >> a) & 1u) == 1u) == (side > 0)) {
        return row[a];
    }
    return c ^ (1u << a);
}

// What c (of depth `depth`) sees across a face (spec 6.1): x the sigma
// there, y the distance between centres in edges of c.
fn face(c: u32, depth: u32, row: vec3<u32>, a: u32, side: i32) -> vec2<f32> {
    let nb = across(c, row, a, side);
    if (nb == NONE) {
        return vec2<f32>(0.0, 1.0);
    }
    let n = layer_cell(nb);
    let dn = depth_of(n);
    if (dn == depth) {
        if (n.first_child == NONE) {
            return vec2<f32>(n.sigma, 1.0);
        }
        // The children whose bit a is on the face, by increasing index.
        let want = select(1u, 0u, side > 0);
        var kid = vec4<f32>(0.0);
        for (var j = 0u; j < 4u; j = j + 1u) {
            let lo = j & ((1u << a) - 1u);
            let k = ((j >> a) << (a + 1u)) | (want << a) | lo;
            kid[j] = layer_cell(n.first_child + k).sigma;
        }
        return vec2<f32>(((kid.x + kid.y) + (kid.z + kid.w)) * 0.25, 0.75);
    }
    if (dn + 1u == depth) {
        return vec2<f32>(n.sigma, 1.5);
    }
    return vec2<f32>(0.0, 1.0);
}

// One component quantised: floor(v 511 + 0.5) clamped to +-511, plus 512.
fn quantise(v: f32) -> u32 {
    return u32(clamp(floor(v * 511.0 + 0.5), -511.0, 511.0) + 512.0);
}

// The stored word of live cell c (spec 6.1): w n, quantised.
fn normal_word(c: u32, depth: u32, sigma: f32, row: vec3<u32>) -> u32 {
    var delta = vec3<f32>(0.0);
    var top = sigma;
    for (var a = 0u; a < 3u; a = a + 1u) {
        let hi = face(c, depth, row, a, 1);
        let lo = face(c, depth, row, a, -1);
        delta[a] = (hi.x - lo.x) / (hi.y + lo.y);
        top = max(top, max(hi.x, lo.x));
    }
    let g = sqrt(delta.x * delta.x + delta.y * delta.y + delta.z * delta.z);
    let r = select(0.0, g / top, top > 0.0);
    let w = clamp((r - R_UNLIT) / (R_LIT - R_UNLIT), 0.0, 1.0);
    // n = -delta / g points out of the paint; v = w n.
    let scale = select(0.0, -w / g, g > 0.0);
    return quantise(delta.x * scale) | (quantise(delta.y * scale) << 10u) | (quantise(delta.z * scale) << 20u);
}

@compute @workgroup_size(64)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    cells_held = params.n_cells;
    let w = wg.x + wg.y * params.row;
    let r = w / params.chunks;
    if (r >= params.n_regions) {
        return;
    }
    let region = regions[r];
    let offset = (w % params.chunks) * 64u + li;
    if (offset >= params.region_cells) {
        return;
    }
    let c = region * params.region_cells + offset;
    if (c >= params.layer_cells || params.base + c >= params.n_cells) {
        return;
    }
    let cell = layer_cell(c);
    let d = depth_of(cell);
    if (d == FREE) {
        store_row(c, Row(vec3<u32>(NONE), ZERO_WORD));
        return;
    }
    var row = vec3<u32>(NONE);
    if (d != 0u) {
        row = vec3<u32>(g3_cell(c, 0u), g3_cell(c, 1u), g3_cell(c, 2u));
    }
    store_row(c, Row(row, normal_word(c, d, cell.sigma, row)));
}
