// The g3 pass (docs/spec.md 3.3-3.5): recompute g3 for every cell of the
// regions the neighbour mask marks, from parent, first_child and depth
// alone. A document's layer lives in its own range of the pages (spec 6.2):
// its cells are read and its g3 written at `base` plus the tree's own
// index, and g3 holds the tree's own indices (one tree: base 0). CPU port: painter/octree/src/g3.rs (g3_cell, g3_row), kept line for
// line; reference: reference/octopaint_ref/g3.py. Host side:
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

@group(1) @binding(0) var<storage, read_write> g3_0: array<u32>;
@group(1) @binding(1) var<storage, read_write> g3_1: array<u32>;
@group(1) @binding(2) var<storage, read_write> g3_2: array<u32>;
@group(1) @binding(3) var<storage, read_write> g3_3: array<u32>;

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

fn store_g3(i: u32, a: u32, v: u32) {
    let c = params.base + i;
    let j = (c & ((1u << PAGE_SHIFT) - 1u)) * 3u + a;
    switch (c >> PAGE_SHIFT) {
        case 0u: { g3_0[j] = v; }
        case 1u: { g3_1[j] = v; }
        case 2u: { g3_2[j] = v; }
        default: { g3_3[j] = v; }
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
    let d = depth_of(layer_cell(c));
    if (d == 0u || d == FREE) {
        store_g3(c, 0u, NONE);
        store_g3(c, 1u, NONE);
        store_g3(c, 2u, NONE);
        return;
    }
    store_g3(c, 0u, g3_cell(c, 0u));
    store_g3(c, 1u, g3_cell(c, 1u));
    store_g3(c, 2u, g3_cell(c, 2u));
}
