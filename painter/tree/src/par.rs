//! The painter core's parallel passes: work is decided in parallel, in
//! chunks whose results are joined in index order, and written serially
//! (or into disjoint cells), so the tree, its undo steps and its dirty
//! marks are the same bytes for any number of threads.
//!
//! The passes run on rayon's current pool: the global one (all cores, or
//! `RAYON_NUM_THREADS`) unless the caller installs its own
//! (`rayon::ThreadPool::install`, as `octopaint bench tree --threads` and
//! the thread-count tests do). On one thread, and for batches smaller than
//! the grain, everything runs serially with no hand-off at all.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

/// Batches below this many items run serially: handing a batch to the pool
/// costs a few microseconds, which a batch of a few hundred cells does not
/// repay.
pub const DEFAULT_GRAIN: usize = 2048;

static GRAIN: AtomicUsize = AtomicUsize::new(DEFAULT_GRAIN);

/// Set the grain (tests set 1 so that every batch is split, however small
/// the trace; the results must not change).
pub fn set_grain(items: usize) {
    GRAIN.store(items.max(1), Ordering::Relaxed);
}

pub fn grain() -> usize {
    GRAIN.load(Ordering::Relaxed)
}

/// Whether a batch of `len` items is split across the pool.
#[inline]
pub fn worth(len: usize) -> bool {
    len >= grain() && rayon::current_num_threads() > 1
}

/// The chunk length that splits `len` items into 4 chunks a thread (a batch
/// is split only when it is worth it, so chunks are never tiny in use).
fn chunk_len(len: usize) -> usize {
    len.div_ceil(rayon::current_num_threads() * 4).max(1)
}

/// `items.iter().map(f).collect()`, in parallel when worth it; the results
/// are in the items' order.
pub fn map<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
    if !worth(items.len()) {
        return items.iter().map(f).collect();
    }
    items.par_iter().with_min_len(chunk_len(items.len())).map(f).collect()
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
    let groups = items.len() / n;
    items.par_chunks_exact(n).zip(out.par_chunks_exact_mut(n)).with_min_len(chunk_len(groups)).for_each(|(g, o)| f(g, o));
}

/// The items for which `keep` holds, in their order.
pub fn filter<T: Sync + Send + Copy>(items: &[T], keep: impl Fn(&T) -> bool + Sync + Send) -> Vec<T> {
    if !worth(items.len()) {
        return items.iter().copied().filter(|t| keep(t)).collect();
    }
    items.par_iter().with_min_len(chunk_len(items.len())).copied().filter(|t| keep(t)).collect()
}

/// `f` over consecutive chunks of `items` (each chunk's first index and its
/// slice), the chunks' results in order: for passes that build a
/// partial result per chunk and join them.
pub fn chunks<T: Sync, U: Send>(items: &[T], f: impl Fn(usize, &[T]) -> U + Sync + Send) -> Vec<U> {
    if !worth(items.len()) {
        return vec![f(0, items)];
    }
    let n = chunk_len(items.len());
    items.par_chunks(n).enumerate().map(|(i, c)| f(i * n, c)).collect()
}

/// `f` over consecutive sub-ranges of `lo..hi`, the results in order.
pub fn ranges<U: Send>(lo: u32, hi: u32, f: impl Fn(std::ops::Range<u32>) -> U + Sync + Send) -> Vec<U> {
    let len = hi.saturating_sub(lo) as usize;
    if !worth(len) {
        return vec![f(lo..hi.max(lo))];
    }
    let n = chunk_len(len) as u32;
    let starts: Vec<u32> = (lo..hi).step_by(n as usize).collect();
    starts.par_iter().map(|&s| f(s..(s + n).min(hi))).collect()
}

/// Run `f` on a worker thread of the current rayon pool, the caller
/// waiting: for long jobs that paint many samples (a replay, an export).
/// A parallel batch started outside the pool is injected into it and the
/// caller sleeps until the workers finish it, so every batch costs two
/// wake-ups; started on a worker, the batch is split between that worker
/// and the others, and only an idle helper has to wake. Nothing is
/// handed off on one thread, or when already on a worker.
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_num_threads() <= 1 || rayon::current_thread_index().is_some() {
        return f();
    }
    rayon::scope(|_| f())
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
    fn on_pool_runs_on_a_worker_of_a_pool_of_several_threads() {
        // The test thread belongs to no pool: on_pool takes the global one.
        assert_eq!(rayon::current_thread_index(), None);
        assert_eq!(on_pool(rayon::current_thread_index).is_some(), rayon::current_num_threads() > 1);
        // On a worker already, or on one thread: in place.
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (me, there) = pool.install(|| (rayon::current_thread_index(), on_pool(rayon::current_thread_index)));
            assert!(me.is_some());
            assert_eq!(there, me, "{threads} threads");
        }
    }

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
