// The pools on the GPU, shared by every stage (docs/spec.md 2.2; the byte
// layout is drawn in docs/buffer-layouts.md). Kept in sync with
// painter/gpu/src/pools.rs (GpuCell, PAGES) and painter/octree/src/pool.rs;
// a stride test in painter/gpu checks the Rust copy.
//
// One cell, 16 bytes:
//
//   byte 0          4          8                   12         16
//        +----------+----------+----+----+----+----+----------+
//        |  parent  |first_chld| r  | g  | b  |dpth|  sigma   |
//        |   u32    |   u32    |       rgbd u32    |   f32    |
//        +----------+----------+----+----+----+----+----------+
//
// Pools are split into PAGES pages of 2^PAGE_SHIFT cells, one binding each,
// so that capacity is not capped by one binding's size (128 MiB on
// lavapipe: 2^23 cells of 16 bytes).

const NONE: u32 = 0xFFFFFFFFu;
const FREE: u32 = 255u;
const PAGES: u32 = 4u;

struct Cell {
    parent: u32,
    first_child: u32,
    // r | g << 8 | b << 16 | depth << 24
    rgbd: u32,
    sigma: f32,
}

override PAGE_SHIFT: u32 = 23u;

@group(0) @binding(0) var<storage, read> cells0: array<Cell>;
@group(0) @binding(1) var<storage, read> cells1: array<Cell>;
@group(0) @binding(2) var<storage, read> cells2: array<Cell>;
@group(0) @binding(3) var<storage, read> cells3: array<Cell>;

// Cells the allocated pages hold; every stage sets it first thing in
// `main` from its parameters. A read at or past it (NONE included) gives a
// free cell, so a link broken mid-upload never reads another page's cell
// or an unallocated binding (the CPU ports read out-of-range cells the same
// way).
var<private> cells_held: u32;

const FREE_CELL: Cell = Cell(NONE, NONE, 0xFF000000u, 0.0);

// Beside every cell, in pages of the same size (bindings of group 1), its
// row, 16 bytes (painter/gpu/src/pools.rs `GpuRow`): g3 (spec 3.3, NONE
// for roots and free cells) and the stored shading vector's word (spec 6.1:
// three 10-bit components, q + 512 at bits 0, 10 and 20). The g3 pass
// (g3.wgsl) writes both; the ray cast (raycast.wgsl) reads them.
//
//   byte 0          4          8          12         16
//        +----------+----------+----------+----------+
//        |  g3[x]   |  g3[y]   |  g3[z]   |  shade   |
//        +----------+----------+----------+----------+
struct Row {
    g3: vec3<u32>,
    shade: u32,
}

// The word of the zero vector (spec 6.1): 512 | 512 << 10 | 512 << 20.
const ZERO_WORD: u32 = 537395712u;

// The root next to root c on side `side` (+1/-1) of axis a, by root array
// arithmetic (spec 1.1); NONE outside the canvas. painter/octree/src/
// normals.rs `across` is the CPU twin.
fn root_across(c: u32, roots: vec3<u32>, a: u32, side: i32) -> u32 {
    var r = vec3<i32>(vec3<u32>(c % roots.x, (c / roots.x) % roots.y, c / (roots.x * roots.y)));
    r[a] = r[a] + side;
    if (r[a] < 0 || u32(r[a]) >= roots[a]) {
        return NONE;
    }
    return u32(r.x) + roots.x * (u32(r.y) + roots.y * u32(r.z));
}

fn cell_at(i: u32) -> Cell {
    if (i >= cells_held) {
        return FREE_CELL;
    }
    let j = i & ((1u << PAGE_SHIFT) - 1u);
    switch (i >> PAGE_SHIFT) {
        case 0u: { return cells0[j]; }
        case 1u: { return cells1[j]; }
        case 2u: { return cells2[j]; }
        default: { return cells3[j]; }
    }
}

fn depth_of(c: Cell) -> u32 {
    return c.rgbd >> 24u;
}
