//! The ledger: what every job changed and what every frame shows.
//!
//! The stroke thread records each publication (one level of a job, or part
//! of one in aggressive staging) with the 65,536-cell blocks it dirtied
//! (keyed by layer and block: [`crate::staging::key`]);
//! the render thread records each upload with the newest publication the
//! staged copy contains. From these the ledger knows, after every frame,
//! the *consistent cut*: the newest publication P such that every change of
//! every publication up to P is on the GPU. A job is shown by the first
//! frame whose cut reaches its last publication (after the job finished):
//! its stroke-to-display latency ends with that frame.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::time::Instant;

/// One job's life.
#[derive(Clone, Debug)]
pub struct JobRecord {
    pub seq: u64,
    pub kind: &'static str,
    pub submitted: Instant,
    pub started: Option<Instant>,
    pub finished: Option<Instant>,
    /// Time the stroke thread spent painting it (inside `Painting::step`,
    /// with the tree's lock held; waits for the lock excluded), seconds.
    pub paint_seconds: f64,
    /// Its first and last publications (None: it changed nothing).
    pub first_pub: Option<u64>,
    pub last_pub: Option<u64>,
    /// The end of the first frame that showed all of it, and that frame.
    pub shown: Option<Instant>,
    pub shown_frame: Option<u64>,
}

impl JobRecord {
    /// Submission to display, in milliseconds.
    pub fn latency_ms(&self) -> Option<f64> {
        self.shown.map(|s| (s - self.submitted).as_secs_f64() * 1e3)
    }
}

#[derive(Default)]
pub struct Ledger {
    pub jobs: Vec<JobRecord>,
    /// Publication number (from 1) of the last publication recorded.
    pub last_pub: u64,
    /// The job of every publication (index: number − 1).
    pub pub_jobs: Vec<u64>,
    /// Per block: the publications that dirtied it and are not uploaded yet.
    uncovered: HashMap<u64, VecDeque<u64>>,
    /// The oldest uncovered publication of each block, counted.
    fronts: BTreeMap<u64, usize>,
    /// Jobs before this index are all shown.
    next_unshown: usize,
}

impl Ledger {
    pub fn submitted(&mut self, seq: u64, kind: &'static str, at: Instant) {
        debug_assert_eq!(seq as usize, self.jobs.len() + 1, "jobs are recorded in order");
        self.jobs.push(JobRecord {
            seq,
            kind,
            submitted: at,
            started: None,
            paint_seconds: 0.0,
            finished: None,
            first_pub: None,
            last_pub: None,
            shown: None,
            shown_frame: None,
        });
    }

    fn job(&mut self, seq: u64) -> &mut JobRecord {
        &mut self.jobs[seq as usize - 1]
    }

    pub fn started(&mut self, seq: u64) {
        self.job(seq).started = Some(Instant::now());
    }

    /// A publication of job `seq` dirtied `blocks`; returns its number.
    /// Job 0 is the opening: the painting as the pipeline found it.
    pub fn published(&mut self, seq: u64, blocks: &[u64]) -> u64 {
        self.last_pub += 1;
        let n = self.last_pub;
        self.pub_jobs.push(seq);
        if seq > 0 {
            let job = self.job(seq);
            job.first_pub.get_or_insert(n);
            job.last_pub = Some(n);
        }
        for &b in blocks {
            let q = self.uncovered.entry(b).or_default();
            if q.is_empty() {
                *self.fronts.entry(n).or_default() += 1;
            }
            q.push_back(n);
        }
        n
    }

    /// Job `seq` took `seconds` of painting.
    pub fn painted(&mut self, seq: u64, seconds: f64) {
        self.job(seq).paint_seconds += seconds;
    }

    pub fn finished(&mut self, seq: u64) {
        self.job(seq).finished = Some(Instant::now());
    }

    /// Block `b` is on the GPU as it was after publication `covered`.
    pub fn uploaded(&mut self, b: u64, covered: u64) {
        let Some(q) = self.uncovered.get_mut(&b) else { return };
        let Some(&front) = q.front() else { return };
        if front > covered {
            return;
        }
        while q.front().is_some_and(|&p| p <= covered) {
            q.pop_front();
        }
        let next = q.front().copied();
        if next.is_none() {
            self.uncovered.remove(&b);
        }
        let count = self.fronts.get_mut(&front).expect("every uncovered block has a front");
        *count -= 1;
        if *count == 0 {
            self.fronts.remove(&front);
        }
        if let Some(n) = next {
            *self.fronts.entry(n).or_default() += 1;
        }
    }

    /// The newest publication whose changes, and all earlier ones, are on
    /// the GPU.
    pub fn cut(&self) -> u64 {
        match self.fronts.keys().next() {
            Some(&oldest) => oldest - 1,
            None => self.last_pub,
        }
    }

    /// Whether a block still has changes the GPU has not seen.
    pub fn block_pending(&self, b: u64) -> bool {
        self.uncovered.contains_key(&b)
    }

    /// After frame `frame` ended at `at`: every finished job whose changes
    /// are all within the cut is shown (in order: a job is never shown
    /// before an earlier one). Returns the newest job shown so far (0: none).
    pub fn frame_ended(&mut self, frame: u64, at: Instant) -> u64 {
        let cut = self.cut();
        while self.next_unshown < self.jobs.len() {
            let j = &mut self.jobs[self.next_unshown];
            let done = j.finished.is_some() && j.last_pub.is_none_or(|p| p <= cut);
            if !done {
                break;
            }
            j.shown = Some(at);
            j.shown_frame = Some(frame);
            self.next_unshown += 1;
        }
        self.next_unshown as u64
    }

    /// Jobs not shown yet.
    pub fn unshown(&self) -> usize {
        self.jobs.len() - self.next_unshown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cut_waits_for_every_block_of_a_publication() {
        let mut l = Ledger::default();
        let t = Instant::now();
        l.submitted(1, "sample", t);
        l.submitted(2, "sample", t);
        let p1 = l.published(1, &[3, 4]);
        l.finished(1);
        let p2 = l.published(2, &[4, 5]);
        l.finished(2);
        assert_eq!(l.cut(), 0);
        l.uploaded(4, p2); // block 4 as of p2 covers p1 and p2 for block 4
        assert_eq!(l.cut(), 0, "block 3 of p1 is still missing");
        l.uploaded(3, p1);
        assert_eq!(l.cut(), p1, "p2's block 5 is still missing");
        assert_eq!(l.frame_ended(1, t), 1);
        l.uploaded(5, p1); // a copy older than p2's change: not enough
        assert_eq!(l.cut(), p1);
        l.uploaded(5, p2);
        assert_eq!(l.cut(), p2);
        assert_eq!(l.frame_ended(2, t), 2);
        assert_eq!(l.jobs[1].shown_frame, Some(2));
    }

    #[test]
    fn a_job_is_not_shown_before_it_finishes_or_before_earlier_jobs() {
        let mut l = Ledger::default();
        let t = Instant::now();
        l.submitted(1, "sample", t);
        l.submitted(2, "undo", t);
        let p = l.published(1, &[0]);
        l.finished(2); // job 2 changed nothing, but job 1 is not done
        assert_eq!(l.frame_ended(1, t), 0);
        l.finished(1);
        assert_eq!(l.frame_ended(2, t), 0, "block 0 is not uploaded");
        l.uploaded(0, p);
        assert_eq!(l.frame_ended(3, t), 2);
        assert_eq!(l.unshown(), 0);
    }
}
