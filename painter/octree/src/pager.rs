//! The pools' new pages, mapped in on another thread.
//!
//! A pool that grows gets capacity the process has never written: its first
//! write to each page takes a page fault, and the kernel zeroes the page
//! before the write goes on. On a large stroke those faults were a good part
//! of the painting thread's time on this project's virtual machines
//! (docs/benchmarks.md, "How the core got here", the 18th step). When a
//! pass may use more than one thread, a pool growth hands its new capacity
//! to a pager thread, which maps the pages in ahead of the painting
//! ([`octopaint_platform::memory::populate_for_write`]: no byte changes, so
//! the painting thread may write there meanwhile). On one thread, or where
//! the platform cannot do it, nothing changes: the first writes fault as
//! before.
//!
//! A job names addresses inside the pools' allocations, so it must end
//! before those allocations move or are freed: the tree waits for it
//! before any reallocation of its pools ([`Pager::wait`]), and a pager
//! waits when it is dropped (the tree's first field, dropped before the
//! pools). A range that was freed anyway only makes the call fail.

use std::thread::JoinHandle;

#[derive(Default)]
pub struct Pager {
    job: Option<JoinHandle<()>>,
}

impl Pager {
    /// Map in the pages of `ranges` (address, length) on a pager thread,
    /// after the job before it ends. Runs nothing when the thread cannot
    /// be started.
    pub fn populate(&mut self, ranges: Vec<(usize, usize)>) {
        self.wait();
        let job = std::thread::Builder::new().name("octopaint-pager".into()).spawn(move || {
            for (addr, len) in ranges {
                octopaint_platform::memory::populate_for_write(addr, len);
            }
        });
        self.job = job.ok();
    }

    /// Wait for the job under way, if any.
    pub fn wait(&mut self) {
        if let Some(job) = self.job.take() {
            // A job that panicked mapped in fewer pages: nothing to undo.
            let _ = job.join();
        }
    }
}

/// A copy of a tree has its own allocations: no job of the original's.
impl Clone for Pager {
    fn clone(&self) -> Self {
        Pager::default()
    }
}

impl Drop for Pager {
    fn drop(&mut self) {
        self.wait();
    }
}

/// The whole spare capacity of `v` (past its length), as a pager range.
pub fn spare<T>(v: &Vec<T>) -> (usize, usize) {
    let size = std::mem::size_of::<T>();
    (v.as_ptr() as usize + v.len() * size, (v.capacity() - v.len()) * size)
}

#[cfg(test)]
mod tests {
    use crate::pool::{Tree, UNIT};
    use octopaint_model::Canvas;

    /// `f` on a new tree of one root and `capacity` cells, in a pool of
    /// `threads` threads (which decides whether growths start jobs).
    fn on_threads(threads: usize, capacity: u32, f: impl FnOnce(&mut Tree) + Send) {
        let canvas = Canvas { roots: [1, 1, 1], max_depth: 12, root_size: 1.0, capacity };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| f(&mut Tree::new(&canvas)));
    }

    /// The pools grow past several pager jobs on two threads while every
    /// new unit is written at once: the pages mapped in behind the writes
    /// keep every byte, through the reallocations that wait for the jobs.
    #[test]
    fn pools_grown_with_the_pager_keep_every_cell() {
        on_threads(2, 1 << 23, |t| {
            let first = t.n_used();
            let mut jobs = 0;
            let mut capacity = t.parent.capacity();
            let units = 3_000_000 / UNIT;
            for i in 0..units {
                let u = t.allocate_unit().unwrap() as usize;
                if t.parent.capacity() != capacity {
                    capacity = t.parent.capacity();
                    jobs += usize::from(t.pager.job.is_some());
                }
                for k in 0..UNIT as usize {
                    let v = i.wrapping_mul(2_654_435_761).wrapping_add(k as u32);
                    t.parent[u + k] = v;
                    t.first_child[u + k] = !v;
                    t.depth[u + k] = v as u8;
                    t.rgb[u + k] = [(v >> 8) as u8, (v >> 16) as u8, (v >> 24) as u8];
                    t.sigma[u + k] = v as f32;
                }
            }
            if octopaint_platform::memory::POPULATES {
                assert!(jobs >= 3, "{jobs} pager jobs");
            } else {
                assert_eq!(jobs, 0, "a pager job where pages cannot be mapped in ahead");
            }
            t.pager.wait();
            for i in 0..units {
                let u = (first + i * UNIT) as usize;
                for k in 0..UNIT as usize {
                    let v = i.wrapping_mul(2_654_435_761).wrapping_add(k as u32);
                    let cell = (t.parent[u + k], t.first_child[u + k], t.depth[u + k], t.rgb[u + k], t.sigma[u + k].to_bits());
                    assert_eq!(cell, (v, !v, v as u8, [(v >> 8) as u8, (v >> 16) as u8, (v >> 24) as u8], (v as f32).to_bits()), "cell {}", u + k);
                }
            }
        });
    }

    /// On one thread the pools grow with no pager job (nor anywhere the
    /// platform cannot map pages in ahead).
    #[test]
    fn one_thread_starts_no_pager_job() {
        on_threads(1, 1 << 22, |t| {
            for _ in 0..(2_000_000 / UNIT) {
                t.allocate_unit().unwrap();
                assert!(t.pager.job.is_none());
            }
        });
    }
}
