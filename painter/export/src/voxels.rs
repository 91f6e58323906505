//! The painting resampled on a uniform voxel lattice at one *export depth*
//! E, held in OpenVDB's own shape (a root table of 4096³-voxel nodes, each
//! of 32³ children of 16³ children of 8³-voxel leaves) so that the writer in
//! `vdb.rs` only serialises it.
//!
//! A voxel is a cell of depth E. A leaf coarser than E is a cube of 2^(E−d)
//! voxels on a side, aligned to its size, so it splits exactly into the
//! biggest tiles VDB has at that size: root tiles (4096³), tiles of a
//! 4096³ node (128³ each), tiles of a 128³ node (8³ each), or single
//! voxels. A cell deeper than E is folded into its ancestor at depth E
//! (`values::cell_value`). Only cells with extinction > 0 are active;
//! everything else is background (0), as in a VDB fog volume.

use std::collections::{BTreeMap, HashSet};

use glam::DVec3;
use octopaint_tree::pool::{NONE, Tree};

use crate::values::{ColourSpace, Value, cell_value};
use crate::{Crop, ExportError, Placement};

/// log2 of the edge of each VDB node level, in voxels: leaf 8, internal
/// 128, internal 4096 (OpenVDB's standard 5-4-3 tree).
pub const LEAF_LOG2: u32 = 3;
pub const NODE4_LOG2: u32 = 7;
pub const NODE5_LOG2: u32 = 12;

/// One active voxel (or tile) value as written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Voxel {
    pub density: f32,
    pub colour: [f32; 3],
}

/// An 8³ leaf: active mask (bit `(x&7)<<6 | (y&7)<<3 | (z&7)`) and values.
pub struct Leaf {
    pub mask: [u64; 8],
    pub values: Box<[Voxel; 512]>,
}

/// A 128³ node: tiles of 8³ voxels and child leaves, by linear offset
/// `(x>>3 & 15)<<8 | (y>>3 & 15)<<4 | (z>>3 & 15)`.
#[derive(Default)]
pub struct Node4 {
    pub tiles: BTreeMap<u32, Voxel>,
    pub leaves: BTreeMap<u32, Leaf>,
}

/// A 4096³ node: tiles of 128³ voxels and child nodes, by linear offset
/// `(x>>7 & 31)<<10 | (y>>7 & 31)<<5 | (z>>7 & 31)`.
#[derive(Default)]
pub struct Node5 {
    pub tiles: BTreeMap<u32, Voxel>,
    pub children: BTreeMap<u32, Node4>,
}

/// The resampled painting. Coordinates are voxel indices: voxel `i`
/// covers canvas `[i, i+1)·voxel_size` on each axis.
pub struct VoxelGrid {
    pub depth: u32,
    pub voxel_size: f64,
    /// Root tiles (4096³ voxels each) by origin, and root children by
    /// origin; BTreeMap orders [i32; 3] as OpenVDB's root table does
    /// (x, then y, then z).
    pub root_tiles: BTreeMap<[i32; 3], Voxel>,
    pub nodes: BTreeMap<[i32; 3], Node5>,
    /// Added to `(i + 0.5)·voxel_size` to place voxel i in the file's frame
    /// (file units): what is left of `Placement::origin` once the voxel
    /// indices have been shifted by whole 4096-voxel nodes.
    pub translation: [f64; 3],
    /// Voxels (tiles count all theirs): up to 2^93 on a deep canvas.
    pub active_voxels: u128,
    /// Inclusive bounds of the active voxels.
    pub bbox: Option<([i32; 3], [i32; 3])>,
}

/// What a grid at one export depth would hold, counted before building it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    pub root_tiles: u64,
    pub nodes5: u64,
    pub nodes4: u64,
    pub leaves: u64,
    pub active_voxels: u128,
    /// Cells of the tree that become one cube of voxels each.
    pub regions: u64,
}

impl Estimate {
    /// Bytes of the uncompressed grids (density and colour together):
    /// each node's value table and masks, as OpenVDB holds them in memory
    /// and as the file holds them before compression.
    pub fn bytes(&self) -> u64 {
        let per_value = 4 + 12;
        self.leaves * (512 * per_value + 2 * 64)
            + self.nodes4 * (4096 * per_value + 2 * 512)
            + self.nodes5 * (32768 * per_value + 2 * 4096)
            // A root tile is written once per grid: origin, value, active.
            + self.root_tiles * (2 * (12 + 1) + per_value)
    }
}

/// The greatest export depth whose voxel indices fit OpenVDB's i32
/// coordinates: `R_a · 2^E ≤ 2^31` on every axis.
pub fn deepest_addressable(tree: &Tree) -> u32 {
    let r = *tree.lat.roots.iter().max().expect("three axes");
    let mut e = tree.lat.max_depth;
    while e > 0 && u64::from(r) << e > 1u64 << 31 {
        e -= 1;
    }
    e
}

/// The deepest depth of a non-empty leaf inside `crop` (0 for an empty
/// painting): no export needs to be finer.
pub fn deepest_painted(tree: &Tree, crop: Option<Crop>) -> u32 {
    let origins = crop.map(|_| octopaint_tree::dump::origins(tree));
    let mut d = 0;
    for c in 0..tree.n_used() as usize {
        if tree.depth()[c] != octopaint_tree::pool::FREE && tree.first_child()[c] == NONE && tree.sigma()[c] > 0.0 {
            let depth = u32::from(tree.depth()[c]);
            if let (Some(crop), Some(o)) = (crop, &origins)
                && !crop.touches_cell(tree, o[c], depth)
            {
                continue;
            }
            d = d.max(depth);
        }
    }
    d
}

/// Voxel-index bounds of a crop at depth `e`: the voxels that overlap it,
/// `[lo, hi)` on each axis.
fn crop_voxels(tree: &Tree, e: u32, crop: Crop) -> ([i64; 3], [i64; 3]) {
    let h = tree.lat.root_size * (2.0f64).powi(-(e as i32));
    let n = tree.lat.roots.map(|r| i64::from(r) << e);
    let lo = [0, 1, 2].map(|a| ((crop.lo[a] / h).floor() as i64).clamp(0, n[a]));
    let hi = [0, 1, 2].map(|a| ((crop.hi[a] / h).ceil() as i64).clamp(0, n[a]));
    (lo, hi)
}

/// Every active region of the export at depth `e`: (voxel origin, log2 of
/// its edge in voxels, value), in traversal order. `f` returns false to
/// stop early. With a crop, cells across its border are cut into the
/// biggest aligned cubes inside it.
fn for_each_region(tree: &Tree, e: u32, crop: Option<Crop>, mut f: impl FnMut([i32; 3], u32, Value) -> bool) {
    let dmax = tree.lat.max_depth;
    let bounds = crop.map(|c| crop_voxels(tree, e, c));
    // 0: outside, 1: across the border, 2: inside.
    let classify = |o: [i64; 3], k: u32| -> u8 {
        let Some((lo, hi)) = bounds else { return 2 };
        let s = 1i64 << k;
        if (0..3).any(|a| o[a] + s <= lo[a] || o[a] >= hi[a]) {
            0
        } else if (0..3).all(|a| o[a] >= lo[a] && o[a] + s <= hi[a]) {
            2
        } else {
            1
        }
    };
    let mut stack: Vec<(u32, [u32; 3])> = (0..tree.lat.n_roots).map(|r| (r, tree.lat.root_origin(r))).collect();
    stack.reverse();
    let mut pieces: Vec<([i64; 3], u32)> = Vec::new();
    while let Some((c, o)) = stack.pop() {
        let d = u32::from(tree.depth()[c as usize]);
        let fc = tree.first_child()[c as usize];
        // The cell's cube in voxels of depth e (a cell deeper than e is
        // never reached: its ancestor at e stops the descent).
        let ov = o.map(|x| i64::from(x >> (dmax - e)));
        let k = e - d.min(e);
        let class = classify(ov, k);
        if class == 0 {
            continue;
        }
        if fc != NONE && d < e {
            for k in (0..8).rev() {
                stack.push((fc + k, tree.child_origin(o, d, k)));
            }
            continue;
        }
        let v = cell_value(tree, c);
        if v.sigma as f32 <= 0.0 {
            continue;
        }
        if class == 2 {
            if !f(ov.map(|x| x as i32), k, v) {
                return;
            }
            continue;
        }
        // Across the border: split into octants until each is in or out.
        pieces.clear();
        pieces.push((ov, k));
        while let Some((p, k)) = pieces.pop() {
            match classify(p, k) {
                0 => {}
                2 => {
                    if !f(p.map(|x| x as i32), k, v) {
                        return;
                    }
                }
                _ => {
                    let s = 1i64 << (k - 1);
                    for q in (0..8).rev() {
                        pieces.push(([0, 1, 2].map(|a| p[a] + ((q >> a) & 1) * s), k - 1));
                    }
                }
            }
        }
    }
}

/// Count what the grid at depth `e` would hold, stopping once it is
/// past `cap_bytes` (the count is then a lower bound, already too big).
pub fn estimate(tree: &Tree, e: u32, crop: Option<Crop>, cap_bytes: u64) -> Estimate {
    let mut est = Estimate::default();
    let (mut n5, mut n4, mut lv): (HashSet<[i32; 3]>, HashSet<[i32; 3]>, HashSet<[i32; 3]>) = Default::default();
    for_each_region(tree, e, crop, |o, k, _| {
        est.active_voxels += 1u128 << (3 * k);
        est.regions += 1;
        let mask = |log2: u32| o.map(|v| v & !((1 << log2) - 1));
        if k >= NODE5_LOG2 {
            est.root_tiles += 1u64 << (3 * (k - NODE5_LOG2));
        } else {
            n5.insert(mask(NODE5_LOG2));
            if k < NODE4_LOG2 {
                n4.insert(mask(NODE4_LOG2));
                if k < LEAF_LOG2 {
                    lv.insert(mask(LEAF_LOG2));
                }
            }
        }
        est.nodes5 = n5.len() as u64;
        est.nodes4 = n4.len() as u64;
        est.leaves = lv.len() as u64;
        est.bytes() <= cap_bytes
    });
    est
}

fn offset5(v: [i32; 3]) -> u32 {
    let s = |a: i32| ((a as u32) >> NODE4_LOG2) & 31;
    (s(v[0]) << 10) | (s(v[1]) << 5) | s(v[2])
}

fn offset4(v: [i32; 3]) -> u32 {
    let s = |a: i32| ((a as u32) >> LEAF_LOG2) & 15;
    (s(v[0]) << 8) | (s(v[1]) << 4) | s(v[2])
}

fn offset_leaf(v: [i32; 3]) -> usize {
    let s = |a: i32| (a as u32 & 7) as usize;
    (s(v[0]) << 6) | (s(v[1]) << 3) | s(v[2])
}

/// Visit the origins of the `2^(k−step)`-per-side sub-cubes of edge
/// `2^step` in the cube of edge `2^k` at `o`.
fn sub_cubes(o: [i32; 3], k: u32, step: u32, mut f: impl FnMut([i32; 3])) {
    let n = 1i32 << (k - step);
    let s = 1i32 << step;
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                f([o[0] + x * s, o[1] + y * s, o[2] + z * s]);
            }
        }
    }
}

impl VoxelGrid {
    /// Resample `tree` as `plan` says (its depth and crop, checked
    /// against the canvas and the size cap when the plan was made).
    /// `placement` scales the voxel size; moves the indices by whole root
    /// nodes (4096 voxels, so every tile stays aligned) toward its origin,
    /// the rest going into `translation`; and, with `z_up`, turns the grid
    /// so that the canvas's +y points along the file's +z: voxel (i, j, k)
    /// becomes (i, −1−k, j).
    pub fn build(tree: &Tree, plan: &Plan, colour: ColourSpace, placement: Placement, progress: &mut dyn FnMut(u64)) -> VoxelGrid {
        let (e, crop) = (plan.depth, plan.crop);
        let h = tree.lat.root_size * (2.0f64).powi(-(e as i32));
        let node = 1i64 << NODE5_LOG2;
        let shift = placement.origin.map(|o| ((o / h / node as f64).floor() as i64).clamp(-(1 << 20), 1 << 20) * node);
        let rest = placement.turn(DVec3::from_array([0, 1, 2].map(|a| shift[a] as f64 * h - placement.origin[a])) * placement.scale, true);
        let mut g = VoxelGrid {
            depth: e,
            translation: rest.to_array(),
            voxel_size: h * placement.scale,
            root_tiles: BTreeMap::new(),
            nodes: BTreeMap::new(),
            active_voxels: 0,
            bbox: None,
        };
        let mut regions = 0u64;
        for_each_region(tree, e, crop, |o, k, v| {
            // Extinction is per canvas unit: per file unit it is divided by
            // the scale, so that optical depth is unchanged.
            let density = (v.sigma / placement.scale).min(f64::from(f32::MAX)) as f32;
            let vox = Voxel { density, colour: colour.encode(v.rgb) };
            // Shifted indices stay within ±2^31 (both the index and the
            // shift are); the tests turn absurd origins away before.
            let o = [0, 1, 2].map(|a| i64::from(o[a]) - shift[a]);
            let o = if placement.z_up { [o[0], -(o[2] + (1i64 << k)), o[1]] } else { o };
            let o = o.map(|v| v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32);
            g.fill(o, k, vox);
            regions += 1;
            if regions.is_multiple_of(4096) {
                progress(regions);
            }
            true
        });
        progress(regions);
        g
    }

    fn fill(&mut self, o: [i32; 3], k: u32, v: Voxel) {
        self.active_voxels += 1u128 << (3 * k);
        // o + 2^k ≤ 2^31: the last voxel fits in i32, the sum may not.
        let hi = o.map(|a| (i64::from(a) + (1i64 << k) - 1) as i32);
        self.bbox = Some(match self.bbox {
            None => (o, hi),
            Some((lo, h)) => ([lo[0].min(o[0]), lo[1].min(o[1]), lo[2].min(o[2])], [h[0].max(hi[0]), h[1].max(hi[1]), h[2].max(hi[2])]),
        });
        let align = |log2: u32, p: [i32; 3]| p.map(|a| a & !((1 << log2) - 1));
        if k >= NODE5_LOG2 {
            sub_cubes(o, k, NODE5_LOG2, |p| {
                self.root_tiles.insert(p, v);
            });
            return;
        }
        let n5 = self.nodes.entry(align(NODE5_LOG2, o)).or_default();
        if k >= NODE4_LOG2 {
            sub_cubes(o, k, NODE4_LOG2, |p| {
                n5.tiles.insert(offset5(p), v);
            });
            return;
        }
        let n4 = n5.children.entry(offset5(o)).or_default();
        if k >= LEAF_LOG2 {
            sub_cubes(o, k, LEAF_LOG2, |p| {
                n4.tiles.insert(offset4(p), v);
            });
            return;
        }
        let leaf = n4.leaves.entry(offset4(o)).or_insert_with(|| Leaf { mask: [0; 8], values: Box::new([Voxel { density: 0.0, colour: [0.0; 3] }; 512]) });
        sub_cubes(o, k, 0, |p| {
            let i = offset_leaf(p);
            leaf.mask[i / 64] |= 1 << (i % 64);
            leaf.values[i] = v;
        });
    }

    /// The value at voxel `p`, None where inactive (a lookup through the
    /// same levels a VDB accessor walks; tests compare it with OpenVDB's).
    pub fn get(&self, p: [i32; 3]) -> Option<Voxel> {
        let align = |log2: u32| p.map(|a| a & !((1 << log2) - 1));
        if let Some(v) = self.root_tiles.get(&align(NODE5_LOG2)) {
            return Some(*v);
        }
        let n5 = self.nodes.get(&align(NODE5_LOG2))?;
        if let Some(v) = n5.tiles.get(&offset5(p)) {
            return Some(*v);
        }
        let n4 = n5.children.get(&offset5(p))?;
        if let Some(v) = n4.tiles.get(&offset4(p)) {
            return Some(*v);
        }
        let leaf = n4.leaves.get(&offset4(p))?;
        let i = offset_leaf(p);
        (leaf.mask[i / 64] >> (i % 64) & 1 == 1).then(|| leaf.values[i])
    }
}

/// The deepest export depth below `from` that fits `cap_bytes`, if any.
pub fn deepest_fitting(tree: &Tree, from: u32, crop: Option<Crop>, cap_bytes: u64) -> Option<u32> {
    (0..from).rev().find(|&e| estimate(tree, e, crop, cap_bytes).bytes() <= cap_bytes)
}

/// A voxel depth checked against the canvas and the size cap, with what
/// its grid will hold: the only way to a `VoxelGrid`.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    depth: u32,
    crop: Option<Crop>,
    estimate: Estimate,
}

impl Plan {
    pub fn depth(&self) -> u32 {
        self.depth
    }

    pub fn estimate(&self) -> &Estimate {
        &self.estimate
    }
}

/// Plan an export at `depth`, or when None at the deepest depth that holds
/// every painted detail, failing that the deepest that fits `cap_bytes`.
/// Refused when the depth is off the canvas or the grid would take more
/// than `cap_bytes` (the message says which depth fits).
pub fn plan(tree: &Tree, depth: Option<u32>, crop: Option<Crop>, cap_bytes: u64) -> Result<Plan, ExportError> {
    let deepest = tree.lat.max_depth.min(deepest_addressable(tree));
    let at = |depth| Plan { depth, crop, estimate: estimate(tree, depth, crop, cap_bytes) };
    match depth {
        Some(e) if e > deepest => Err(ExportError::DepthOutOfRange { depth: e, deepest }),
        Some(e) => {
            let p = at(e);
            if p.estimate.bytes() > cap_bytes {
                let fits = deepest_fitting(tree, e, crop, cap_bytes);
                return Err(ExportError::TooLarge { depth: e, bytes: p.estimate.bytes(), cap_bytes, fits });
            }
            Ok(p)
        }
        None => {
            let want = deepest_painted(tree, crop).min(deepest);
            (0..=want).rev().map(at).find(|p| p.estimate.bytes() <= cap_bytes).ok_or(ExportError::NothingFits { cap_bytes })
        }
    }
}

/// The export depth to use when none is asked for (see [`plan`]).
pub fn choose_depth(tree: &Tree, crop: Option<Crop>, cap_bytes: u64) -> Result<u32, ExportError> {
    plan(tree, None, crop, cap_bytes).map(|p| p.depth)
}
