//! Imports (spec 15.3). A voxel set (octopaint-model; its file is
//! octopaint-trace's) is painted into the tree by an `import` event as
//! one undo step, with the stroke machinery: a top-down traversal of the
//! cells that hold a voxel, a paint pass, refinement rounds on the leaves
//! that are not settled, cleaning. Reference twin:
//! reference/octopaint_ref/voxelset.py and `Painting.import_voxels` in
//! paint.py.

pub use octopaint_model::voxel_set::{MAX_VOXELS, VoxelSet};
pub use octopaint_trace::voxels::{parse_voxel_set, sha256_hex, voxel_set_bytes};

use octopaint_octree::pool::{NONE, Tree, UNIT};

/// Sort key of a coordinate: (z, y, x).
#[inline]
fn key(q: [u32; 3]) -> [u32; 3] {
    [q[2], q[1], q[0]]
}

/// A stored value as one integer: rgb bytes and the f32 bits of sigma.
#[inline]
fn packed(rgb: [u8; 3], sigma: f32) -> u64 {
    u64::from(rgb[0]) | u64::from(rgb[1]) << 8 | u64::from(rgb[2]) << 16 | u64::from(sigma.to_bits()) << 24
}

#[inline]
fn unpacked(v: u64) -> ([u8; 3], f32) {
    ([v as u8, (v >> 8) as u8, (v >> 16) as u8], f32::from_bits((v >> 24) as u32))
}

/// One cell position at some depth that holds voxels: how many, and the
/// smallest and largest packed value among them.
#[derive(Clone, Copy)]
struct Block {
    key: [u32; 3],
    count: u64,
    lo: u64,
    hi: u64,
}

/// Per depth `e <= d`, the blocks of the set, sorted by key (spec 15.3).
struct VoxelIndex {
    d: u32,
    max_depth: u32,
    levels: Vec<Vec<Block>>,
}

impl VoxelIndex {
    fn new(vs: &VoxelSet, max_depth: u32) -> Self {
        let d = vs.depth;
        let mut level: Vec<Block> = (0..vs.len())
            .map(|i| {
                let v = packed(vs.rgb[i], vs.sigma[i]);
                Block { key: key(vs.ijk[i]), count: 1, lo: v, hi: v }
            })
            .collect();
        level.sort_unstable_by_key(|b| b.key);
        let mut levels = vec![Vec::new(); d as usize + 1];
        for e in (0..d).rev() {
            let mut up: Vec<Block> = level.iter().map(|b| Block { key: b.key.map(|k| k >> 1), ..*b }).collect();
            up.sort_by_key(|b| b.key);
            let mut merged: Vec<Block> = Vec::with_capacity(up.len() / 4 + 1);
            for b in up {
                match merged.last_mut() {
                    Some(m) if m.key == b.key => {
                        m.count += b.count;
                        m.lo = m.lo.min(b.lo);
                        m.hi = m.hi.max(b.hi);
                    }
                    _ => merged.push(b),
                }
            }
            levels[e as usize + 1] = std::mem::replace(&mut level, merged);
        }
        levels[0] = level; // (the set itself when d = 0)
        VoxelIndex { d, max_depth, levels }
    }

    /// The block at depth `e` holding coordinate `q` (at that depth).
    #[inline]
    fn find(&self, e: u32, q: [u32; 3]) -> Option<&Block> {
        let lv = &self.levels[e as usize];
        lv.binary_search_by_key(&key(q), |b| b.key).ok().map(|i| &lv[i])
    }

    /// Does the cell of depth `e` and origin `o` hold a voxel?
    fn reached(&self, o: [u32; 3], e: u32) -> bool {
        let lv = e.min(self.d);
        self.find(lv, o.map(|v| v >> (self.max_depth - lv))).is_some()
    }

    /// The value of the voxel at the centre of the cell (spec 15.3), if the
    /// set has one there.
    fn centre_value(&self, o: [u32; 3], e: u32) -> Option<([u8; 3], f32)> {
        let half = if e < self.d { 1u32 << (self.max_depth - e - 1) } else { 0 };
        let q = o.map(|v| (v + half) >> (self.max_depth - self.d));
        self.find(self.d, q).map(|b| unpacked(b.lo))
    }

    /// A leaf of depth `e < d` whose block and before-value hold one stored
    /// value (spec 15.3).
    fn settled(&self, o: [u32; 3], e: u32, before: ([u8; 3], f32)) -> bool {
        let Some(b) = self.find(e, o.map(|v| v >> (self.max_depth - e))) else { return true };
        let span = 3 * (self.d - e);
        // 8^(d-e) voxels: more than a set can hold once 3(d-e) > 26.
        let whole = span <= 26 && b.count == 1u64 << span;
        b.lo == b.hi && (whole || b.lo == packed(before.0, before.1))
    }
}

/// What [`paint_voxels`] leaves for the caller: the touched cells (for
/// cleaning) and counts.
pub(crate) struct ImportWork {
    pub touched: Vec<u32>,
    pub created: u64,
    pub refusals: u64,
}

/// Spec 15.3 steps 1-4 on `tree`: traverse, paint, refine round by round.
/// Warnings (a refused round, once) go to `warnings`. The caller cleans
/// and commits the undo step.
pub(crate) fn paint_voxels(tree: &mut Tree, vs: &VoxelSet, line: usize, warnings: &mut Vec<String>) -> ImportWork {
    let mut work = ImportWork { touched: Vec::new(), created: 0, refusals: 0 };
    if vs.is_empty() {
        return work;
    }
    let max_depth = tree.lat.max_depth;
    let d = vs.depth;
    let index = VoxelIndex::new(vs, max_depth);
    // Before-values of the touched cells (spec 8.8).
    let mut before: std::collections::HashMap<u32, ([u8; 3], f32)> = std::collections::HashMap::new();
    // 1. Traverse from the roots that hold a voxel, ascending.
    let mut roots: Vec<u32> = index.levels[0].iter().map(|b| tree.lat.root_index([b.key[2], b.key[1], b.key[0]])).collect();
    roots.sort_unstable();
    roots.dedup();
    let mut frontier: Vec<(u32, [u32; 3])> = roots.iter().map(|&r| (r, tree.lat.root_origin(r))).collect();
    let mut paint: Vec<(u32, [u32; 3], u32)> = Vec::new();
    while !frontier.is_empty() {
        let mut next = Vec::new();
        for (c, o) in frontier {
            let e = u32::from(tree.depth()[c as usize]);
            if !index.reached(o, e) {
                continue;
            }
            let fc = tree.first_child()[c as usize];
            if fc == NONE {
                paint.push((c, o, e));
            } else {
                next.extend((0..UNIT).map(|k| (fc + k, tree.child_origin(o, e, k))));
            }
        }
        frontier = next;
    }
    // 2. Paint pass: touched, written their import value.
    let write = |tree: &mut Tree, c: u32, o: [u32; 3], e: u32, b: ([u8; 3], f32)| {
        let (rgb, sigma) = index.centre_value(o, e).unwrap_or(b);
        tree.set_value(c, rgb, sigma);
    };
    for &(c, o, e) in &paint {
        let b = (tree.rgb()[c as usize], tree.sigma()[c as usize]);
        before.insert(c, b);
        work.touched.push(c);
        write(tree, c, o, e, b);
    }
    // 3. Candidates: leaves above the set's depth that are not settled.
    let mut candidates: Vec<u32> = paint.iter().filter(|&&(c, o, e)| e < d && !index.settled(o, e, before[&c])).map(|&(c, _, _)| c).collect();
    let mut warned = false;
    // 4. Rounds.
    while !candidates.is_empty() {
        let (units, refusal) = tree.refine_round(&mut candidates);
        if let Some(r) = refusal {
            work.refusals += 1;
            if !warned {
                warned = true;
                warnings.push(r.warning(line, tree));
            }
        }
        if units.is_empty() {
            break;
        }
        work.created += units.len() as u64 * u64::from(UNIT);
        let mut next = Vec::new();
        for &(parent, unit) in &units {
            let po = tree.origin(parent);
            let pe = u32::from(tree.depth()[parent as usize]);
            let b = before.get(&parent).copied().unwrap_or((tree.rgb()[parent as usize], tree.sigma()[parent as usize]));
            for k in 0..UNIT {
                let (c, o, e) = (unit + k, tree.child_origin(po, pe, k), pe + 1);
                before.insert(c, b);
                work.touched.push(c);
                write(tree, c, o, e, b);
                if e < d && index.reached(o, e) && !index.settled(o, e, b) {
                    next.push(c);
                }
            }
        }
        if refusal.is_some() {
            break;
        }
        candidates = next;
    }
    work
}
