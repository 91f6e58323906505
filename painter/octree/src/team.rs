//! The helper threads of the painter core's parallel passes
//! ([`crate::par`]): a few threads that stay awake between passes.
//!
//! A stroke runs a parallel pass every few tens of microseconds (a sample's
//! paint pass, then each refinement round's new children and settled
//! tests), with serial work between them. A pool whose idle threads go to
//! sleep after a few yields pays a wake-up for every pass, and on a virtual
//! machine a wake-up costs about as much as a pass of a few thousand cells
//! (`examples/hand_off.rs`; docs/benchmarks.md, "How the core got here",
//! the 11th step): rayon's second thread made such strokes no faster. Here a helper that finishes a pass keeps
//! looking for the next one for [`STAY_AWAKE`], yielding its core to any
//! other runnable thread meanwhile, and only then parks; the thread that
//! posts a pass unparks the helpers that sleep.
//!
//! One pass at a time: a pass is `n` tasks, numbered `0..n`, that the
//! posting thread (the *lead*) and up to `threads − 1` helpers take one by
//! one; the lead returns when all have run. Which thread runs which task
//! does not matter: the callers write each task's result into its own place
//! (see `par`). A thread that finds the team busy (another lead, or a
//! pass inside a task) runs its tasks itself.

use std::cell::{Cell, UnsafeCell};
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Mutex, OnceLock};
use std::thread::Thread;
use std::time::{Duration, Instant};

/// How long a helper looks for the next pass before it parks.
pub const STAY_AWAKE: Duration = Duration::from_micros(500);

/// The most helpers the team has (a pass on more threads uses these).
const MAX_HELPERS: usize = 31;

type Task = &'static (dyn Fn(usize) + Sync);

struct Team {
    /// Held by the lead for the whole pass.
    lead: Mutex<()>,
    /// The helpers' handles, in order (their index is their place here).
    helpers: Mutex<Vec<Thread>>,
    /// Bumped when a pass is posted.
    epoch: AtomicU64,
    /// A pass is posted and not finished.
    live: AtomicBool,
    /// The pass's tasks; set before `live`, cleared once no helper is inside.
    task: UnsafeCell<Option<Task>>,
    /// Helpers with an index below this take part.
    seats: AtomicUsize,
    n: AtomicUsize,
    next: AtomicUsize,
    done: AtomicUsize,
    /// Helpers inside the pass (they may read `task`).
    inside: AtomicUsize,
    panicked: AtomicBool,
    sleeping: [AtomicBool; MAX_HELPERS],
}

// SAFETY: `task` is read only by a helper that saw `live` true after it
// raised `inside`; it is written only by the lead holding `lead` while
// `live` is false, after the previous lead, having stored `live = false`,
// saw `inside` at 0. With every access SeqCst, a helper that raises
// `inside` late either sees `live` false and leaves without reading, or
// sees a later pass's `live` true, which is ordered after that pass's
// write. (Acquire and release alone would not give this.)
unsafe impl Sync for Team {}

thread_local! {
    /// This thread runs a task of a pass (or is a helper): a pass it posts
    /// runs on it alone.
    static IN_PASS: Cell<bool> = const { Cell::new(false) };
}

fn team() -> &'static Team {
    static TEAM: OnceLock<Team> = OnceLock::new();
    TEAM.get_or_init(|| Team {
        lead: Mutex::new(()),
        helpers: Mutex::new(Vec::new()),
        epoch: AtomicU64::new(0),
        live: AtomicBool::new(false),
        task: UnsafeCell::new(None),
        seats: AtomicUsize::new(0),
        n: AtomicUsize::new(0),
        next: AtomicUsize::new(0),
        done: AtomicUsize::new(0),
        inside: AtomicUsize::new(0),
        panicked: AtomicBool::new(false),
        sleeping: [const { AtomicBool::new(false) }; MAX_HELPERS],
    })
}

impl Team {
    /// Take tasks until none is left; a panicking task is counted as done
    /// and reported.
    fn work(&self, task: &(dyn Fn(usize) + Sync)) {
        let n = self.n.load(SeqCst);
        loop {
            let k = self.next.fetch_add(1, SeqCst);
            if k >= n {
                return;
            }
            if let Err(payload) = catch_unwind(AssertUnwindSafe(|| task(k))) {
                // Not dropped: a payload whose drop panics would unwind
                // out of here (rust-lang/rust#86027).
                std::mem::forget(payload);
                self.panicked.store(true, SeqCst);
            }
            self.done.fetch_add(1, SeqCst);
        }
    }

    /// A helper's life: `seen` is the last pass it need not join.
    fn helper(&'static self, index: usize, mut seen: u64) {
        IN_PASS.set(true);
        loop {
            // Wait for the next pass that seats it: awake for a while
            // after its last one (passes without a seat for it do not
            // keep it awake), then parked.
            let since = Instant::now();
            loop {
                let e = self.epoch.load(SeqCst);
                if e != seen {
                    seen = e;
                    if index < self.seats.load(SeqCst) {
                        break;
                    }
                    continue;
                }
                if since.elapsed() < STAY_AWAKE {
                    std::thread::yield_now();
                    continue;
                }
                self.sleeping[index].store(true, SeqCst);
                if self.epoch.load(SeqCst) == seen {
                    std::thread::park();
                }
                self.sleeping[index].store(false, SeqCst);
            }
            self.inside.fetch_add(1, SeqCst);
            if self.live.load(SeqCst) {
                // SAFETY: inside a live pass, `task` is set and stays so
                // until this helper leaves (`inside`).
                if let Some(task) = unsafe { *self.task.get() } {
                    self.work(task);
                }
            }
            self.inside.fetch_sub(1, SeqCst);
        }
    }

    /// At least `count` helpers exist (spawning fails: fewer; the pass
    /// still runs). Called by the lead before it posts its pass, which new
    /// helpers then join.
    fn ensure_helpers(&'static self, count: usize) {
        let mut helpers = self.helpers.lock().unwrap_or_else(|e| e.into_inner());
        let seen = self.epoch.load(SeqCst);
        while helpers.len() < count {
            let index = helpers.len();
            match std::thread::Builder::new().name(format!("octopaint-helper-{index}")).spawn(move || self.helper(index, seen)) {
                Ok(h) => helpers.push(h.thread().clone()),
                Err(_) => break,
            }
        }
    }
}

/// Run `task(0)`, ..., `task(n − 1)`, on this thread and up to `threads −
/// 1` helpers; returns when all have run. A task that panics makes this
/// panic once all have run.
pub fn run(n: usize, threads: usize, task: &(dyn Fn(usize) + Sync)) {
    let serial = || (0..n).for_each(task);
    if n <= 1 || threads <= 1 || IN_PASS.get() {
        return serial();
    }
    let team = team();
    // (A pass whose task panicked poisons the lock; the team is fine.)
    let _lead = match team.lead.try_lock() {
        Ok(g) => g,
        Err(std::sync::TryLockError::Poisoned(p)) => p.into_inner(),
        Err(std::sync::TryLockError::WouldBlock) => return serial(),
    };
    let seats = (threads - 1).min(MAX_HELPERS).min(n - 1);
    team.ensure_helpers(seats);
    // SAFETY: no pass is live and no helper inside (the last lead waited
    // for both), so nothing reads `task`; the reference outlives the pass,
    // which ends before this function returns.
    unsafe { *team.task.get() = Some(std::mem::transmute::<&(dyn Fn(usize) + Sync), Task>(task)) };
    team.n.store(n, SeqCst);
    team.next.store(0, SeqCst);
    team.done.store(0, SeqCst);
    team.panicked.store(false, SeqCst);
    team.seats.store(seats, SeqCst);
    team.live.store(true, SeqCst);
    // Whatever happens from here, the pass ends before this frame (and the
    // closure it lent) goes away.
    let end = EndOfPass(team, n);
    team.epoch.fetch_add(1, SeqCst);
    {
        let helpers = team.helpers.lock().unwrap_or_else(|e| e.into_inner());
        for (i, h) in helpers.iter().enumerate().take(seats) {
            if team.sleeping[i].load(SeqCst) {
                h.unpark();
            }
        }
    }
    IN_PASS.set(true);
    team.work(task);
    drop(end);
    if team.panicked.load(SeqCst) {
        resume_unwind(Box::new("a task of a parallel pass panicked"));
    }
}

/// Ends the lead's pass when dropped: waits until every task has run and
/// no helper is inside, then takes the task back.
struct EndOfPass(&'static Team, usize);

impl Drop for EndOfPass {
    fn drop(&mut self) {
        let EndOfPass(team, n) = *self;
        // Tasks nobody took yet (only when this thread unwinds before it
        // worked) are run here, so that `done` reaches `n`.
        // SAFETY: the lead reads what it wrote itself.
        if let Some(task) = unsafe { *team.task.get() } {
            team.work(task);
        }
        IN_PASS.set(false);
        wait_until(|| team.done.load(SeqCst) >= n);
        team.live.store(false, SeqCst);
        wait_until(|| team.inside.load(SeqCst) == 0);
        // SAFETY: `live` is false and no helper is inside (see `Team`).
        unsafe { *team.task.get() = None };
    }
}

/// Spin until `ok`, yielding the core after a while (the thread awaited
/// may have been pushed off its core).
fn wait_until(ok: impl Fn() -> bool) {
    let mut spins = 0u32;
    while !ok() {
        if spins < 256 {
            spins += 1;
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_task_runs_once_on_any_number_of_threads() {
        for threads in [1, 2, 3, 8] {
            for n in [0, 1, 2, 5, 64, 1000] {
                let counts: Vec<AtomicUsize> = (0..n).map(|_| AtomicUsize::new(0)).collect();
                run(n, threads, &|k| {
                    counts[k].fetch_add(1, SeqCst);
                });
                assert!(counts.iter().all(|c| c.load(SeqCst) == 1), "{threads} threads, {n} tasks");
            }
        }
    }

    #[test]
    fn passes_from_several_threads_and_inside_tasks_all_finish() {
        let total = AtomicUsize::new(0);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    for _ in 0..200 {
                        run(8, 3, &|_| {
                            // A pass inside a task runs on its thread.
                            run(4, 3, &|_| {
                                total.fetch_add(1, SeqCst);
                            });
                        });
                    }
                });
            }
        });
        assert_eq!(total.load(SeqCst), 4 * 200 * 8 * 4);
    }

    #[test]
    fn a_panic_whose_payload_panics_when_dropped_stays_inside_the_pass() {
        struct Bomb;
        impl Drop for Bomb {
            fn drop(&mut self) {
                panic!("the payload's drop");
            }
        }
        let ran = AtomicUsize::new(0);
        let r = catch_unwind(AssertUnwindSafe(|| {
            run(8, 2, &|k| {
                ran.fetch_add(1, SeqCst);
                if k == 3 {
                    std::panic::panic_any(Bomb);
                }
            })
        }));
        // Serially (the team busy with another test) the payload reaches
        // the caller as it is; on the team the lead reports the pass.
        match r {
            Err(p) if p.is::<Bomb>() => std::mem::forget(p),
            r => assert!(r.is_err()),
        }
        assert!(ran.load(SeqCst) >= 4);
        let after = AtomicUsize::new(0);
        run(16, 2, &|_| {
            after.fetch_add(1, SeqCst);
        });
        assert_eq!(after.load(SeqCst), 16);
    }

    #[test]
    fn a_panicking_task_panics_the_lead_after_the_pass() {
        let ran = AtomicUsize::new(0);
        let r = catch_unwind(AssertUnwindSafe(|| {
            run(16, 2, &|k| {
                ran.fetch_add(1, SeqCst);
                assert!(k != 7, "task 7 fails");
            })
        }));
        assert!(r.is_err());
        // On the team every task runs before the lead panics; serially (the
        // team busy with another test's pass) the panic stops the loop.
        assert!(ran.load(SeqCst) >= 8, "tasks 0 to 7 ran");
        // The team works on.
        let after = AtomicUsize::new(0);
        run(16, 2, &|_| {
            after.fetch_add(1, SeqCst);
        });
        assert_eq!(after.load(SeqCst), 16);
    }
}
