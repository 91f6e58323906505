//! The painter core's parallel passes: work is decided in parallel, in
//! chunks whose results are joined in index order, and written serially
//! (or into disjoint cells), so the tree, its undo steps and its dirty
//! marks are the same bytes for any number of threads.
//!
//! The number of threads is rayon's: the current pool's (all cores, or
//! `RAYON_NUM_THREADS`, unless the caller installs its own pool, as
//! `octopaint bench tree --threads` and the thread-count tests do). The
//! passes themselves run on the calling thread and the helpers of
//! [`crate::team`], which stay awake between the many short passes of a
//! stroke. On one thread, and for batches smaller than the grain,
//! everything runs serially with no hand-off at all.
//!
//! [`Disjoint`] is the one way a pass writes in place from several threads:
//! the paint pass's runs write the pools' values through it
//! ([`crate::pool::InPlaceValues`]) and their stroke's slots.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crate::team;

/// A vector's elements, written by a parallel pass through a raw pointer:
/// each worker touches elements no other worker touches (the paint pass:
/// the cells of its run's own subtrees and their slots).
#[derive(Clone, Copy)]
pub struct Disjoint<T> {
    ptr: *mut T,
    len: usize,
}

// SAFETY: the pointer is only dereferenced at elements one worker owns
// (the contract of `Disjoint::at`).
unsafe impl<T: Send> Send for Disjoint<T> {}
unsafe impl<T: Send> Sync for Disjoint<T> {}

impl<T> Disjoint<T> {
    pub fn new(v: &mut [T]) -> Self {
        Disjoint { ptr: v.as_mut_ptr(), len: v.len() }
    }

    /// Element `i` (checked against the length: an index past it panics).
    ///
    /// # Safety
    /// No other thread accesses element `i` while the pointer is used, and
    /// the vector is neither resized nor otherwise borrowed meanwhile.
    #[inline]
    pub unsafe fn at(self, i: usize) -> *mut T {
        assert!(i < self.len, "element {i} out of range");
        unsafe { self.ptr.add(i) }
    }
}

/// Batches below this many items run serially: handing a batch to awake
/// helpers costs a microsecond or two, which a few hundred cells repay.
pub const DEFAULT_GRAIN: usize = 256;

static GRAIN: AtomicUsize = AtomicUsize::new(DEFAULT_GRAIN);

/// Set the grain (tests set 1 so that every batch is split, however small
/// the trace; the results must not change).
pub fn set_grain(items: usize) {
    GRAIN.store(items.max(1), Ordering::Relaxed);
}

pub fn grain() -> usize {
    GRAIN.load(Ordering::Relaxed)
}

static MEASURED_SPLIT: AtomicBool = AtomicBool::new(true);

/// Whether the capsule paint pass chooses by measurement to split its walk
/// (the default) or splits it whenever the grain says it is worth it (the
/// thread-count tests, so that every split they ask for is taken, and
/// `octopaint bench tree --always-split`). Either way the results are the
/// same bytes.
pub fn set_measured_split(on: bool) {
    MEASURED_SPLIT.store(on, Ordering::Relaxed);
}

pub fn measured_split() -> bool {
    MEASURED_SPLIT.load(Ordering::Relaxed)
}

/// Threads a pass may use.
#[inline]
pub fn threads() -> usize {
    rayon::current_num_threads()
}

/// Whether a batch of `len` items is split across threads.
#[inline]
pub fn worth(len: usize) -> bool {
    len >= grain() && threads() > 1
}

/// The chunk length that splits `len` items into 4 chunks a thread (a batch
/// is split only when it is worth it, so chunks are never tiny in use).
fn chunk_len(len: usize) -> usize {
    len.div_ceil(threads() * 4).max(1)
}

/// `f(0)`, ..., `f(n − 1)` on the team, the results in order.
pub fn tasks<U: Send>(n: usize, f: impl Fn(usize) -> U + Sync) -> Vec<U> {
    let slots: Vec<Mutex<Option<U>>> = (0..n).map(|_| Mutex::new(None)).collect();
    team::run(n, threads(), &|k| {
        let v = f(k);
        *slots[k].lock().unwrap_or_else(|e| e.into_inner()) = Some(v);
    });
    slots.into_iter().map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner()).expect("every task ran")).collect()
}

/// `f` over consecutive chunks of `items` of [`chunk_len`] items (each
/// chunk's first index and its slice) on the team, the results in order.
fn per_chunk<T: Sync, U: Send>(items: &[T], f: impl Fn(usize, &[T]) -> U + Sync) -> Vec<U> {
    let n = chunk_len(items.len());
    tasks(items.len().div_ceil(n), |k| f(k * n, &items[k * n..(k * n + n).min(items.len())]))
}

/// The chunks' results joined in order.
fn joined<U>(parts: Vec<Vec<U>>) -> Vec<U> {
    let mut out = Vec::with_capacity(parts.iter().map(Vec::len).sum());
    for p in parts {
        out.extend(p);
    }
    out
}

/// `items.iter().map(f).collect()`, in parallel when worth it; the results
/// are in the items' order.
pub fn map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
    map_weighted(items, 1, f)
}

/// [`map`] for items that each cost about `weight` cells' work (the grain
/// counts cells): a batch of fewer, heavier items is split too.
pub fn map_weighted<T: Sync, U: Send>(items: &[T], weight: usize, f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
    if !worth(items.len().saturating_mul(weight)) {
        return items.iter().map(f).collect();
    }
    joined(per_chunk(items, |_, c| c.iter().map(&f).collect()))
}

/// `f` over consecutive groups of `n` items (`items.len()` a multiple of
/// `n`: a unit's 8 children at a time) and the same groups of `out`, which
/// is as long as `items`: results written in place, in parallel when worth
/// it.
pub fn for_groups<T: Sync, U: Send>(items: &[T], out: &mut [U], n: usize, f: impl Fn(&[T], &mut [U]) + Sync + Send) {
    assert!(n > 0 && items.len().is_multiple_of(n) && out.len() == items.len(), "{} items, {} results, groups of {n}", items.len(), out.len());
    if !worth(items.len()) {
        items.chunks_exact(n).zip(out.chunks_exact_mut(n)).for_each(|(g, o)| f(g, o));
        return;
    }
    let per = chunk_len(items.len() / n) * n;
    let parts: Vec<Mutex<&mut [U]>> = out.chunks_mut(per).map(Mutex::new).collect();
    team::run(parts.len(), threads(), &|k| {
        let mut o = parts[k].lock().unwrap_or_else(|e| e.into_inner());
        items[k * per..].chunks_exact(n).zip(o.chunks_exact_mut(n)).for_each(|(g, o)| f(g, o));
    });
}

/// The items for which `keep` holds, in their order.
pub fn filter<T: Sync + Send + Copy>(items: &[T], keep: impl Fn(&T) -> bool + Sync + Send) -> Vec<T> {
    if !worth(items.len()) {
        return items.iter().copied().filter(|t| keep(t)).collect();
    }
    joined(per_chunk(items, |_, c| c.iter().copied().filter(|t| keep(t)).collect()))
}

/// `f` over consecutive chunks of `items` (each chunk's first index and its
/// slice), the chunks' results in order: for passes that build a
/// partial result per chunk and join them.
pub fn chunks<T: Sync, U: Send>(items: &[T], f: impl Fn(usize, &[T]) -> U + Sync + Send) -> Vec<U> {
    if !worth(items.len()) {
        return vec![f(0, items)];
    }
    per_chunk(items, f)
}

/// `f` over consecutive sub-ranges of `lo..hi`, the results in order.
pub fn ranges<U: Send>(lo: u32, hi: u32, f: impl Fn(std::ops::Range<u32>) -> U + Sync + Send) -> Vec<U> {
    let len = hi.saturating_sub(lo) as usize;
    if !worth(len) {
        return vec![f(lo..hi.max(lo))];
    }
    let n = chunk_len(len);
    tasks(len.div_ceil(n), |k| {
        let s = lo + (k * n) as u32;
        f(s..(s + n as u32).min(hi))
    })
}

/// Sort a list of cell indices ascending and drop repeats: the same list as
/// `sort_unstable` then `dedup`. Long lists go through a radix sort (11
/// bits a pass, as many passes as the largest index needs), which is
/// linear: refinement rounds and cleaning sort tens of thousands of cells
/// per stroke.
pub fn sort_dedup(v: &mut Vec<u32>) {
    const BITS: u32 = 11;
    const RADIX: usize = 1 << BITS;
    if v.len() < 512 {
        v.sort_unstable();
        v.dedup();
        return;
    }
    let max = v.iter().copied().max().unwrap_or(0);
    let bits = u32::BITS - max.leading_zeros();
    let mut src = std::mem::take(v);
    let mut dst = vec![0u32; src.len()];
    let mut shift = 0;
    while shift < bits {
        let mut at = [0usize; RADIX];
        for &x in &src {
            at[((x >> shift) as usize) & (RADIX - 1)] += 1;
        }
        let mut sum = 0;
        for a in at.iter_mut() {
            (*a, sum) = (sum, sum + *a);
        }
        for &x in &src {
            let b = ((x >> shift) as usize) & (RADIX - 1);
            dst[at[b]] = x;
            at[b] += 1;
        }
        std::mem::swap(&mut src, &mut dst);
        shift += BITS;
    }
    src.dedup();
    *v = src;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sort_dedup_is_sort_then_dedup() {
        let mut seed = 12345u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            seed
        };
        for (len, range) in [(0, 1), (1, 1), (511, 100), (512, 7), (600, 1 << 11), (3000, 1 << 12), (5000, 1 << 22), (70_000, 1 << 23), (20_000, u32::MAX)] {
            let mut v: Vec<u32> = (0..len).map(|_| if range == u32::MAX { next() } else { next() % range }).collect();
            if len > 100 {
                v[3] = u32::MAX; // the largest index, all 32 bits
                v[7] = 0;
            }
            let mut want = v.clone();
            want.sort_unstable();
            want.dedup();
            sort_dedup(&mut v);
            assert_eq!(v, want, "{len} {range}");
        }
    }

    #[test]
    fn results_keep_their_order_on_any_pool() {
        let items: Vec<u32> = (0..10_000).collect();
        for threads in [1, 2, 7] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (m, f, c, r) = pool.install(|| {
                (
                    (map(&items, |x| x * 3), {
                        let mut out = vec![0; items.len()];
                        for_groups(&items, &mut out, 8, |g, o| o.iter_mut().zip(g).for_each(|(o, x)| *o = x * 5 + g[0]));
                        out
                    }),
                    filter(&items, |x| x % 7 == 3),
                    chunks(&items, |at, c| (at, c.len())),
                    ranges(5, 9_999, |r| r.collect::<Vec<u32>>()),
                )
            });
            assert_eq!(r.concat(), (5..9_999).collect::<Vec<u32>>());
            // 100 items of weight 64 are split on a pool of several threads.
            assert_eq!(pool.install(|| map_weighted(&items[..100], 64, |x| x + 1)), (1..101).collect::<Vec<u32>>());
            assert_eq!(m.0, items.iter().map(|x| x * 3).collect::<Vec<_>>());
            assert_eq!(m.1, items.iter().map(|x| x * 5 + x / 8 * 8).collect::<Vec<_>>());
            assert_eq!(f, items.iter().copied().filter(|x| x % 7 == 3).collect::<Vec<_>>());
            let mut next = 0;
            for (at, len) in c {
                assert_eq!(at, next);
                next += len;
            }
            assert_eq!(next, items.len());
        }
    }
}
