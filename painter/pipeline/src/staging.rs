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
            let e = inner.groups.entry(g).or_insert_with(|| PendingGroup {
                newest_pub: 0,
                mask: NeighbourMask::default(),
                blocks: Vec::new(),
                stamp,
            });
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

/// What the render thread takes in one go: a copy, or (grouped staging) a
/// consistent batch to upload in one frame.
pub enum StagedItem {
    One(StagedCopy),
    Batch(Vec<StagedCopy>),
}

struct StackInner {
    items: Vec<StagedItem>,
    free_buffers: Vec<Vec<GpuCell>>,
    /// Buffers not yet created (the pool is allocated lazily).
    unborn: usize,
    closed: bool,
}

/// The staging buffers and the stack of staged copies.
pub struct StagedStack {
    inner: Mutex<StackInner>,
    buffer_freed: Condvar,
}

impl StagedStack {
    pub fn new(buffers: usize) -> StagedStack {
        StagedStack {
            inner: Mutex::new(StackInner { items: Vec::new(), free_buffers: Vec::new(), unborn: buffers.max(1), closed: false }),
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
    pub fn give_back(&self, mut buf: Vec<GpuCell>) {
        buf.clear();
        self.inner.lock().expect("staged lock").free_buffers.push(buf);
        self.buffer_freed.notify_all();
    }

    /// Push a staged item; older copies of the same groups still on the
    /// stack are dropped (their buffers go back to the pool).
    pub fn push(&self, mut item: StagedItem) {
        let mut inner = self.inner.lock().expect("staged lock");
        let mut kept = Vec::with_capacity(inner.items.len());
        let mut freed = Vec::new();
        for old in inner.items.drain(..) {
            match old {
                StagedItem::One(c) => {
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
                        None => kept.push(StagedItem::One(c)),
                    }
                }
                batch => kept.push(batch),
            }
        }
        for mut buf in freed {
            buf.clear();
            inner.free_buffers.push(buf);
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
