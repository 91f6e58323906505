//! Between the stroke thread and the render thread (docs/architecture.md):
//! the pending set of dirty blocks, the pool of staging buffers, and the
//! stack of staged copies.
//!
//! Policies when full, so that neither side of the pipeline waits for the
//! other: the pending set is a *set* (a block dirtied again while pending
//! is merged into its entry, never queued twice), so the stroke thread
//! never waits on it; the staging thread waits for a free staging buffer
//! when the render thread is behind (it holds no lock meanwhile); the
//! render thread never waits: it takes what is staged. A newer copy of a
//! block replaces an older one still on the stack.

use std::collections::HashMap;
use std::sync::{Condvar, Mutex};
use std::time::Instant;

use octopaint_gpu::pools::GpuCell;
use octopaint_tree::dirty::NeighbourMask;

/// A layer's block or group as one number: the layer's id in the high
/// half (a document's layers are painted, staged and uploaded apart; a
/// one-tree painting is layer 0).
pub fn key(layer: u32, n: u32) -> u64 {
    u64::from(layer) << 32 | u64::from(n)
}

/// The layer and the block or group of a [`key`].
pub fn split(key: u64) -> (u32, u32) {
    ((key >> 32) as u32, key as u32)
}

/// One group of blocks waiting to be staged.
#[derive(Clone, Debug)]
struct PendingGroup {
    /// Newest publication that dirtied it.
    newest_pub: u64,
    /// The g3 regions of every publication that dirtied it since it was
    /// last staged: recomputed when the copy is uploaded.
    mask: NeighbourMask,
    /// The 65,536-cell blocks of those publications inside this group
    /// ([`key`]s).
    blocks: Vec<u64>,
    /// Position in the LIFO order (larger: dirtied more recently).
    stamp: u64,
}

#[derive(Default)]
struct PendingInner {
    /// By group [`key`].
    groups: HashMap<u64, PendingGroup>,
    /// LIFO order: (stamp, group key); entries whose stamp no longer
    /// matches their group's are stale and skipped.
    stack: Vec<(u64, u64)>,
    next_stamp: u64,
    closed: bool,
}

/// Dirty groups of blocks, newest first (the paper's LIFO queue).
#[derive(Default)]
pub struct PendingSet {
    inner: Mutex<PendingInner>,
    changed: Condvar,
}

/// A group taken from the pending set for staging.
pub struct Taken {
    pub layer: u32,
    pub group: u32,
    pub newest_pub: u64,
    pub mask: NeighbourMask,
    pub blocks: Vec<u64>,
}

impl Taken {
    fn new(k: u64, e: PendingGroup) -> Taken {
        let (layer, group) = split(k);
        Taken { layer, group, newest_pub: e.newest_pub, mask: e.mask, blocks: e.blocks }
    }
}

impl PendingSet {
    /// A publication dirtied `blocks` (65,536-cell blocks) of layer
    /// `layer`, in the groups `group_of` gives; `mask`: that layer's g3
    /// regions.
    pub fn merge(&self, pub_no: u64, layer: u32, group_of: impl Fn(u32) -> u32, blocks: &[u32], mask: &NeighbourMask) {
        if blocks.is_empty() {
            return;
        }
        let mut inner = self.inner.lock().expect("pending lock");
        for &b in blocks {
            let (g, b) = (key(layer, group_of(b)), key(layer, b));
            inner.next_stamp += 1;
            let stamp = inner.next_stamp;
            let e = inner.groups.entry(g).or_insert_with(|| PendingGroup { newest_pub: 0, mask: NeighbourMask::default(), blocks: Vec::new(), stamp });
            e.newest_pub = e.newest_pub.max(pub_no);
            e.mask.union(mask);
            if !e.blocks.contains(&b) {
                e.blocks.push(b);
            }
            e.stamp = stamp;
            inner.stack.push((stamp, g));
        }
        self.changed.notify_all();
    }

    /// The most recently dirtied group, waiting for one; None once closed
    /// and empty.
    pub fn take_newest(&self) -> Option<Taken> {
        let mut inner = self.inner.lock().expect("pending lock");
        loop {
            while let Some((stamp, g)) = inner.stack.pop() {
                if inner.groups.get(&g).is_some_and(|e| e.stamp == stamp) {
                    let e = inner.groups.remove(&g).expect("just checked");
                    return Some(Taken::new(g, e));
                }
            }
            if inner.closed {
                return None;
            }
            inner = self.changed.wait(inner).expect("pending lock");
        }
    }

    /// Wait until something is pending; false once closed and empty.
    pub fn wait_for_work(&self) -> bool {
        let mut inner = self.inner.lock().expect("pending lock");
        loop {
            if !inner.groups.is_empty() {
                return true;
            }
            if inner.closed {
                return false;
            }
            inner = self.changed.wait(inner).expect("pending lock");
        }
    }

    /// Every pending group at once, without waiting (grouped staging calls
    /// it holding the tree's lock, so that the batch is one consistent
    /// state: no publication can slip in between taking and copying).
    pub fn take_all_now(&self) -> Vec<Taken> {
        let mut inner = self.inner.lock().expect("pending lock");
        inner.stack.clear();
        let mut all: Vec<Taken> = inner.groups.drain().map(|(g, e)| Taken::new(g, e)).collect();
        all.sort_by_key(|t| (t.layer, t.group));
        all
    }

    pub fn close(&self) {
        self.inner.lock().expect("pending lock").closed = true;
        self.changed.notify_all();
    }

    pub fn len(&self) -> usize {
        self.inner.lock().expect("pending lock").groups.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A staged copy of one group, ready to upload.
pub struct StagedCopy {
    pub layer: u32,
    pub group: u32,
    /// First cell of the copy, in its layer's tree.
    pub first: u64,
    /// The cells its layer's tree used when it was staged (`n_used`): its
    /// range of the GPU's pages need hold no more ([`crate::layout`]).
    pub length: u64,
    pub cells: Vec<GpuCell>,
    /// Every publication up to this one is in the copy.
    pub covered_pub: u64,
    /// The g3 regions to recompute once it is uploaded.
    pub mask: NeighbourMask,
    /// The 65,536-cell blocks whose pending changes it carries ([`key`]s).
    pub blocks: Vec<u64>,
    /// Staging order of this group's copies (larger: newer).
    pub version: u64,
    pub staged_at: Instant,
}

impl StagedCopy {
    /// One past its last cell, in its layer's tree.
    pub fn end(&self) -> u64 {
        self.first + self.cells.len() as u64
    }
}

/// What the render thread takes in one go: a copy, or (grouped staging) a
/// consistent batch to upload in one frame.
#[expect(clippy::large_enum_variant, reason = "a copy is a buffer's handle and a few numbers, moved a few times a frame")]
pub enum StagedItem {
    One(StagedCopy),
    Batch(Vec<StagedCopy>),
}

struct StackInner {
    items: Vec<StagedItem>,
    free_buffers: Vec<Vec<GpuCell>>,
    /// Buffers not yet created (the pool is allocated lazily).
    unborn: usize,
    /// The most free buffers kept: the pool's size. Grouped staging takes
    /// more than that while a big publication is staged (a buffer a dirty
    /// group); those beyond it are freed when given back, so one big
    /// publication does not hold its memory for the session's life.
    keep: usize,
    closed: bool,
}

impl StackInner {
    fn keep_spare(&mut self, mut buf: Vec<GpuCell>) {
        if self.free_buffers.len() < self.keep {
            buf.clear();
            self.free_buffers.push(buf);
        }
    }
}

/// The staging buffers and the stack of staged copies.
pub struct StagedStack {
    inner: Mutex<StackInner>,
    buffer_freed: Condvar,
}

impl StagedStack {
    pub fn new(buffers: usize) -> StagedStack {
        StagedStack {
            inner: Mutex::new(StackInner { items: Vec::new(), free_buffers: Vec::new(), unborn: buffers.max(1), keep: buffers.max(1), closed: false }),
            buffer_freed: Condvar::new(),
        }
    }

    /// A free staging buffer, waiting while every one is staged and not
    /// yet uploaded (the render thread is behind).
    pub fn buffer(&self) -> Vec<GpuCell> {
        let mut inner = self.inner.lock().expect("staged lock");
        loop {
            if let Some(b) = inner.free_buffers.pop() {
                return b;
            }
            if inner.unborn > 0 {
                inner.unborn -= 1;
                return Vec::new();
            }
            inner = self.buffer_freed.wait(inner).expect("staged lock");
        }
    }

    /// A free buffer if there is one, else a new one: never waits (grouped
    /// staging takes its buffers while it holds the tree's lock).
    pub fn spare(&self) -> Vec<GpuCell> {
        self.inner.lock().expect("staged lock").free_buffers.pop().unwrap_or_default()
    }

    /// Give a buffer back to the pool.
    pub fn give_back(&self, buf: Vec<GpuCell>) {
        self.inner.lock().expect("staged lock").keep_spare(buf);
        self.buffer_freed.notify_all();
    }

    /// Buffers in the pool, free now.
    pub fn spares(&self) -> usize {
        self.inner.lock().expect("staged lock").free_buffers.len()
    }

    /// Push a staged item. An older copy of a group the item holds, still
    /// on the stack, is dropped (its buffer goes back to the pool) and its
    /// regions and blocks pass to the newer copy. A pushed batch also takes
    /// in the older batches' other copies: a group left out of the newer
    /// batch was not dirtied since, so its older copy is still current and
    /// the merged batch is the newer consistent state (the render thread
    /// uploads every staged batch together in any case). So at most one
    /// batch waits, and a slow frame holds one copy per dirty group, not one
    /// per staging round.
    pub fn push(&self, mut item: StagedItem) {
        let mut inner = self.inner.lock().expect("staged lock");
        let mut kept = Vec::with_capacity(inner.items.len());
        let mut freed = Vec::new();
        let mut adopted = Vec::new();
        for old in inner.items.drain(..) {
            let (olds, was_batch) = match old {
                StagedItem::One(c) => (vec![c], false),
                StagedItem::Batch(cs) if matches!(item, StagedItem::Batch(_)) => (cs, true),
                batch => {
                    kept.push(batch);
                    continue;
                }
            };
            for c in olds {
                let newer = match &mut item {
                    StagedItem::One(n) if (n.layer, n.group) == (c.layer, c.group) => Some(n),
                    StagedItem::Batch(ns) => ns.iter_mut().find(|n| (n.layer, n.group) == (c.layer, c.group)),
                    _ => None,
                };
                match newer {
                    // The newer copy holds the older one's cells as they
                    // are now; it takes over its regions and blocks.
                    Some(n) => {
                        n.mask.union(&c.mask);
                        for b in c.blocks {
                            if !n.blocks.contains(&b) {
                                n.blocks.push(b);
                            }
                        }
                        freed.push(c.cells);
                    }
                    None if was_batch => adopted.push(c),
                    None => kept.push(StagedItem::One(c)),
                }
            }
        }
        if let StagedItem::Batch(ns) = &mut item {
            ns.append(&mut adopted);
        }
        for buf in freed {
            inner.keep_spare(buf);
        }
        inner.items = kept;
        inner.items.push(item);
        self.buffer_freed.notify_all();
    }

    /// Up to `max` items, newest first.
    pub fn take(&self, max: usize) -> Vec<StagedItem> {
        let mut inner = self.inner.lock().expect("staged lock");
        let n = max.min(inner.items.len());
        let at = inner.items.len() - n;
        let mut out: Vec<StagedItem> = inner.items.drain(at..).collect();
        out.reverse();
        out
    }

    pub fn len(&self) -> usize {
        self.inner.lock().expect("staged lock").items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The staging thread is done: nothing more will be pushed.
    pub fn close(&self) {
        self.inner.lock().expect("staged lock").closed = true;
        self.buffer_freed.notify_all();
    }

    pub fn is_closed(&self) -> bool {
        self.inner.lock().expect("staged lock").closed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn copy(layer: u32, group: u32, version: u64, region: usize) -> StagedCopy {
        let mut mask = NeighbourMask::default();
        mask.set(region);
        StagedCopy {
            layer,
            group,
            first: u64::from(group) * 4,
            length: u64::from(group) * 4 + 4,
            cells: vec![GpuCell::FREE; 4],
            covered_pub: version,
            mask,
            blocks: vec![key(layer, group), key(layer, 100 + version as u32)],
            version,
            staged_at: Instant::now(),
        }
    }

    fn groups(item: &StagedItem) -> Vec<(u32, u32, u64)> {
        let StagedItem::Batch(cs) = item else { panic!("a batch") };
        let mut g: Vec<_> = cs.iter().map(|c| (c.layer, c.group, c.version)).collect();
        g.sort();
        g
    }

    #[test]
    fn batches_staged_while_the_render_thread_is_behind_merge_into_one() {
        let stack = StagedStack::new(2);
        // A thousand staging rounds of the same two groups, and one round
        // that also holds a third, before any frame takes them.
        stack.push(StagedItem::Batch(vec![copy(0, 7, 1, 3)]));
        for v in 2..1002 {
            stack.push(StagedItem::Batch(vec![copy(0, 1, v, v as usize % 64), copy(1, 1, v, 5)]));
        }
        assert_eq!(stack.len(), 1, "one batch waits");
        let items = stack.take(usize::MAX);
        // The newest copy of each group, and the third group's only copy.
        assert_eq!(groups(&items[0]), vec![(0, 1, 1001), (0, 7, 1), (1, 1, 1001)]);
        let StagedItem::Batch(cs) = &items[0] else { unreachable!() };
        let newest = cs.iter().find(|c| (c.layer, c.group) == (0, 1)).unwrap();
        // Every older copy's regions and blocks passed to it.
        assert!((2..1002).all(|v| newest.mask.get(v % 64)), "a region of an older copy was lost");
        assert_eq!(newest.blocks.len(), 1 + 1000, "the group's block and every round's own");
        // The dropped copies' buffers: the pool keeps its size, no more.
        assert_eq!(stack.spares(), 2);
    }

    #[test]
    fn a_single_copy_replaces_only_its_own_group() {
        let stack = StagedStack::new(4);
        stack.push(StagedItem::One(copy(0, 1, 1, 0)));
        stack.push(StagedItem::One(copy(0, 2, 2, 0)));
        stack.push(StagedItem::One(copy(0, 1, 3, 1)));
        let items = stack.take(usize::MAX);
        let got: Vec<_> = items
            .iter()
            .map(|i| match i {
                StagedItem::One(c) => (c.group, c.version, c.mask.get(0)),
                StagedItem::Batch(_) => panic!("no batch was pushed"),
            })
            .collect();
        assert_eq!(got, vec![(1, 3, true), (2, 2, true)], "newest first, the older copy of group 1 merged into the newer");
    }

    #[test]
    fn given_back_buffers_beyond_the_pool_are_freed() {
        let stack = StagedStack::new(3);
        let bufs: Vec<_> = (0..10).map(|_| stack.spare()).collect();
        for b in bufs {
            stack.give_back(b);
        }
        assert_eq!(stack.spares(), 3);
    }
}
