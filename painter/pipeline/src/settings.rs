//! The pipeline's settings: the experiments of the paper's section 5 are
//! reruns with different values of these.

use octopaint_gpu::{Backend, Precision};
use octopaint_tree::trace::Camera;

/// How many cells one staged copy holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockSize {
    /// A group of 65,536-cell blocks: `cells` must be a power of two at
    /// least 65,536 (the unit the tree marks dirty).
    Cells(u32),
    /// The whole used pool, copied at once (the paper's "no block").
    WholePool,
}

/// The neighbour mask's resolution (spec 3.5 fixes 64×32 for the tree;
/// coarser ones widen every dirty region to its coarse cell).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaskSize {
    /// Columns × rows, dividing 64 × 32.
    Grid(u32, u32),
    /// No mask: g3 over every region whenever anything is uploaded.
    None,
}

/// How the stages hand work on (the paper's Fig. 9 strategies).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Strategy {
    /// The ray caster skips cells whose links disagree (spec 7).
    pub skip_invalid: bool,
    /// Publish after every `n` units of a refinement round instead of
    /// after whole levels: staging starts sooner.
    pub aggressive_units: Option<usize>,
    /// Stage every pending block in one batch, under one hold of the tree's
    /// lock, and upload every staged batch in the next frame, whatever K
    /// (dependencies respected: no frame shows a half-uploaded level).
    pub grouped: bool,
}

impl Default for Strategy {
    fn default() -> Self {
        // Grouped staging: in docs/benchmarks.md (Fig. 9) it is the only
        // strategy with no corrupted frame, and the shortest latency tail.
        Strategy { skip_invalid: true, aggressive_units: None, grouped: true }
    }
}

#[derive(Clone, Debug)]
pub struct Settings {
    pub block: BlockSize,
    /// Staged items uploaded per frame at most (K).
    pub blocks_per_frame: usize,
    pub mask: MaskSize,
    /// Staging buffers in the pool.
    pub staging_buffers: usize,
    /// Jobs the input may queue ahead of the stroke thread.
    pub job_queue: usize,
    pub strategy: Strategy,
    pub camera: Camera,
    pub precision: Precision,
    pub backend: Backend,
    /// Pace frames at this rate (a headset's refresh); None: as fast as the
    /// renderer goes.
    pub target_hz: Option<f64>,
    /// Take every frame's image digest (corruption analysis): a GPU pass
    /// over the pixels and at most 32 KiB read back a frame.
    pub capture: bool,
    /// Threads the stroke thread's painter core may use (its parallel
    /// passes give the same bytes for any count). Default: the cores less
    /// two, kept for the render and staging threads, at least 1.
    pub core_threads: usize,
    /// Records kept of jobs, frames and staged copies: None every one, for
    /// the run's report (benchmarks, tests); `Some(n)` the newest `n` to
    /// `2 n` of each, with running figures of all (a live session: the
    /// window, the headset, `bench soak`, whose memory must not grow with
    /// the hours painted).
    pub keep_records: Option<usize>,
}

/// [`Settings::keep_records`] of a live session: a few seconds of jobs.
pub const LIVE_RECORDS: usize = 4096;

/// Let the oldest of `records` go as [`Settings::keep_records`] says:
/// once there are more than `2 keep`, the newest `keep` stay.
pub(crate) fn trim_records<T>(records: &mut Vec<T>, keep: Option<usize>) {
    if let Some(keep) = keep
        && records.len() > 2 * keep.max(1)
    {
        records.drain(..records.len() - keep.max(1));
    }
}

/// The default of [`Settings::core_threads`].
pub fn default_core_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get()).saturating_sub(2).max(1)
}

impl Settings {
    pub fn new(camera: Camera) -> Settings {
        Settings {
            block: BlockSize::Cells(65536),
            blocks_per_frame: 4,
            mask: MaskSize::Grid(64, 32),
            staging_buffers: 16,
            job_queue: 4096,
            strategy: Strategy::default(),
            camera,
            precision: Precision::F32,
            backend: Backend::Auto,
            target_hz: None,
            capture: false,
            core_threads: default_core_threads(),
            keep_records: None,
        }
    }
}
