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
//!
//! A benchmark's or a test's ledger keeps every job's record for its
//! report; a live session's ([`Ledger::keeping`]: the window, the headset,
//! `bench soak`) keeps the newest shown ones only, with running figures
//! of all of them ([`Shown`]), so that hours of painting take no more of
//! it than minutes.

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
    /// Time the stroke thread spent painting it (inside `Painting::advance`,
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

/// Bins of [`Shown::latency`] a decade: a latency is known to within
/// 10^(1/200), about 1.2 %.
const BINS_A_DECADE: f64 = 200.0;
/// The histogram's range: 1 µs (bin 0 holds everything shorter) to 10^4 s
/// (the last bin, everything longer).
const FIRST_MS: f64 = 1e-3;
const BINS: usize = 7 * BINS_A_DECADE as usize + 1;

/// Running figures of every job shown so far, in constant memory: a live
/// session's closing summary, whatever the ledger still keeps.
#[derive(Clone)]
pub struct Shown {
    pub jobs: u64,
    /// Stroke-to-display latencies, counted in logarithmic bins.
    latency: Vec<u64>,
    /// The heaviest sample's painting time, seconds.
    pub heaviest_sample_seconds: f64,
    /// The newest shown job's latency, ms.
    pub last_latency_ms: Option<f64>,
}

impl Default for Shown {
    fn default() -> Shown {
        Shown { jobs: 0, latency: vec![0; BINS], heaviest_sample_seconds: 0.0, last_latency_ms: None }
    }
}

impl Shown {
    fn bin(ms: f64) -> usize {
        if !(ms > FIRST_MS) {
            return 0;
        }
        ((ms / FIRST_MS).log10() * BINS_A_DECADE).ceil().min((BINS - 1) as f64) as usize
    }

    fn add(&mut self, job: &JobRecord) {
        self.jobs += 1;
        if let Some(ms) = job.latency_ms() {
            self.latency[Shown::bin(ms)] += 1;
            self.last_latency_ms = Some(ms);
        }
        if job.kind == "sample" {
            self.heaviest_sample_seconds = self.heaviest_sample_seconds.max(job.paint_seconds);
        }
    }

    /// The latency at quantile `q` (0..=1) by nearest rank, ms: the upper
    /// edge of the bin the job of that rank fell in (within 1.2 % above
    /// its latency); None before any job was shown.
    pub fn latency_quantile_ms(&self, q: f64) -> Option<f64> {
        let n: u64 = self.latency.iter().sum();
        if n == 0 {
            return None;
        }
        let rank = ((n - 1) as f64 * q.clamp(0.0, 1.0)).round() as u64;
        let mut seen = 0;
        for (b, &c) in self.latency.iter().enumerate() {
            seen += c;
            if seen > rank {
                return Some(FIRST_MS * 10f64.powf(b as f64 / BINS_A_DECADE));
            }
        }
        unreachable!("the rank is below the count")
    }
}

#[derive(Default)]
pub struct Ledger {
    /// The jobs' records, oldest first: every job's, or (a ledger
    /// [`keeping`](Ledger::keeping) a number) the newest ones, from job
    /// `dropped + 1`.
    pub jobs: Vec<JobRecord>,
    /// Jobs whose records were let go (all of them shown).
    pub dropped: u64,
    /// Shown records kept at least, when records are let go at all.
    keep: Option<usize>,
    /// Every shown job, counted.
    pub shown: Shown,
    /// Publication number (from 1) of the last publication recorded.
    pub last_pub: u64,
    /// Per block: the publications that dirtied it and are not uploaded yet.
    uncovered: HashMap<u64, VecDeque<u64>>,
    /// The oldest uncovered publication of each block, counted.
    fronts: BTreeMap<u64, usize>,
    /// Jobs before this index of `jobs` are all shown.
    next_unshown: usize,
}

impl Ledger {
    /// A ledger that lets the records of shown jobs go once more than
    /// `2 keep` are shown, keeping the newest `keep` (a live session).
    pub fn keeping(keep: usize) -> Ledger {
        Ledger { keep: Some(keep.max(1)), ..Ledger::default() }
    }

    pub fn submitted(&mut self, seq: u64, kind: &'static str, at: Instant) {
        debug_assert_eq!(seq, self.dropped + self.jobs.len() as u64 + 1, "jobs are recorded in order");
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

    /// Job `seq`'s record: a job is let go only once shown, and nothing
    /// records anything of it after that.
    fn job(&mut self, seq: u64) -> &mut JobRecord {
        &mut self.jobs[(seq - self.dropped) as usize - 1]
    }

    pub fn started(&mut self, seq: u64) {
        self.job(seq).started = Some(Instant::now());
    }

    /// A publication of job `seq` dirtied `blocks`; returns its number.
    /// Job 0 is the opening: the painting as the pipeline found it.
    pub fn published(&mut self, seq: u64, blocks: &[u64]) -> u64 {
        self.last_pub += 1;
        let n = self.last_pub;
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
            self.shown.add(j);
            self.next_unshown += 1;
        }
        if let Some(keep) = self.keep
            && self.next_unshown > 2 * keep
        {
            let go = self.next_unshown - keep;
            self.jobs.drain(..go);
            self.dropped += go as u64;
            self.next_unshown -= go;
        }
        self.dropped + self.next_unshown as u64
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

    #[test]
    fn a_live_ledger_keeps_the_newest_records_and_counts_every_job() {
        let mut l = Ledger::keeping(3);
        let t = Instant::now();
        for seq in 1..=100u64 {
            l.submitted(seq, "sample", t);
            let p = l.published(seq, &[seq % 5]);
            l.painted(seq, seq as f64 * 1e-3);
            l.finished(seq);
            l.uploaded(seq % 5, p);
            assert_eq!(l.frame_ended(seq, t + std::time::Duration::from_micros(seq * 100)), seq);
            assert!(l.jobs.len() <= 7, "at most 2 keep shown and the one in hand");
        }
        assert_eq!(l.dropped + l.jobs.len() as u64, 100);
        assert_eq!(l.jobs.last().unwrap().seq, 100);
        assert_eq!(l.shown.jobs, 100);
        assert!((l.shown.heaviest_sample_seconds - 0.1).abs() < 1e-12);
        // Latencies 0.1 .. 10 ms: p50 is rank 50 of 0..=99 (round(49.5)),
        // job 51's 5.1 ms, to within a bin above.
        let p50 = l.shown.latency_quantile_ms(0.5).unwrap();
        assert!((5.1..5.1 * 1.012).contains(&p50), "{p50}");
        let max = l.shown.latency_quantile_ms(1.0).unwrap();
        assert!((10.0..10.0 * 1.012).contains(&max), "{max}");
        assert!((l.shown.last_latency_ms.unwrap() - 10.0).abs() < 1e-9);
    }
}
