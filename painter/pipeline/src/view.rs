//! The view layer every front end shares (docs/architecture.md, "The
//! front ends"): what a frame casts (dynamic resolution, still frames that
//! present the last cast again), the frame log, the frame statistics, and
//! what the stroke thread is doing as the heavy-operation indicator shows
//! it. The window and the headset hold one [`View`] each; the bench's
//! render thread casts every frame at full size and keeps its own record
//! ([`crate::pipeline`]).

use std::io::Write as _;
use std::path::Path;
use std::time::Instant;

use octopaint_tree::view::follow_frame_time;

use crate::engine::Engine;

/// The frame time dynamic resolution aims at in the window (60 Hz).
pub const WINDOW_TARGET_MS: f64 = 16.7;
/// The time both eyes' casts aim at in the headset: one frame at 90 Hz.
pub const HEADSET_TARGET_MS: f64 = 11.1;

/// The frame log's columns, one line a frame (docs/desktop.md).
pub const FRAME_LOG_HEADER: &str = "t_ms,interval_ms,scale,width,height,still,mirror,cast,engine,prepare_ms";

/// How a front end tells dynamic resolution what a moving frame cost.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// The interval from one moving frame to the next (the window: its
    /// frames follow one another as fast as they are drawn).
    Interval,
    /// The time the front end measured for the frame's casts, told through
    /// [`View::took`] (the headset: its frames are paced by the runtime,
    /// so their interval says little about the cast).
    Measured,
}

/// What the stroke thread is doing as a frame begins, as the frame log
/// writes it (its `engine` column).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Doing {
    Nothing,
    /// A sample, a stroke's begin or end, an undo or a redo.
    Painting,
    Saving,
    /// Another job: an event of the document, an import, a question.
    Other,
}

impl Doing {
    pub fn of(engine: &Engine) -> Doing {
        match engine.busy().map(|b| b.what) {
            None => Doing::Nothing,
            Some("sample" | "stroke_begin" | "stroke_end" | "undo" | "redo") => Doing::Painting,
            Some("save") => Doing::Saving,
            Some(_) => Doing::Other,
        }
    }

    /// The frame log's code: 0 nothing, 1 painting, 2 saving, 3 other.
    pub fn code(self) -> u8 {
        match self {
            Doing::Nothing => 0,
            Doing::Painting => 1,
            Doing::Saving => 2,
            Doing::Other => 3,
        }
    }
}

/// The heavy-operation indicator (the paper's 8.3): what the stroke
/// thread is running and for how long, and the share of the queued work
/// done when work is queued.
#[derive(Debug, Clone, PartialEq)]
pub struct Indicator {
    pub text: String,
    pub progress: Option<f32>,
}

impl Indicator {
    /// The indicator when the stroke thread has run one job for at least
    /// `after_ms` or 8 jobs wait; None otherwise.
    pub fn of(engine: &Engine, after_ms: f64) -> Option<Indicator> {
        let busy = engine.busy()?;
        let ms = busy.since.elapsed().as_secs_f64() * 1e3;
        let queued = engine.queued();
        if ms < after_ms && queued < 8 {
            return None;
        }
        let what = match busy.what {
            "save" => "saving…",
            "import" => "importing…",
            "layer" => "changing layers…",
            _ => "painting…",
        };
        let (submitted, finished) = engine.progress();
        let progress = (queued > 0).then(|| finished as f32 / submitted.max(1) as f32);
        let waiting = if queued > 0 { format!(", {queued} queued") } else { String::new() };
        Some(Indicator { text: format!("{what} {ms:.0} ms{waiting}"), progress })
    }
}

/// The closing summary of a front end's session: how many jobs were
/// shown, their stroke-to-display latency p50 and p99 (nearest rank, to
/// the ledger's bins: within 1.2 %), and the heaviest sample's painting
/// time; None when no job was shown.
pub fn latency_summary(engine: &Engine) -> Option<String> {
    let shown = engine.shown();
    let (p50, p99) = (shown.latency_quantile_ms(0.5)?, shown.latency_quantile_ms(0.99)?);
    let heaviest = shown.heaviest_sample_seconds * 1e3;
    Some(format!("{} jobs shown, stroke-to-display latency p50 {p50:.1} ms, p99 {p99:.1} ms; the heaviest sample painted in {heaviest:.1} ms", shown.jobs))
}

/// What one frame casts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Planned {
    /// The share of the image's width and height cast.
    pub scale: f64,
    /// The cast size.
    pub size: [u32; 2],
    /// Nothing changed since the last frame: the view, the painting.
    pub still: bool,
    /// Cast new rays; when false the front end presents its last cast
    /// again (a still view already cast at full size).
    pub cast: bool,
}

/// A front end's frames so far: intervals, casts, scales.
#[derive(Debug, Clone, Default)]
pub struct FrameStats {
    pub frames: u64,
    pub still_frames: u64,
    /// Frames that cast new rays.
    pub cast_frames: u64,
    /// The interval before each frame but the first, ms.
    pub intervals_ms: Vec<f64>,
    scale_sum: f64,
    scale_min: f64,
    /// Frames per second over the last second or so.
    pub fps: f64,
    fps_window: Option<(Instant, u64)>,
}

impl FrameStats {
    /// Statistics of intervals measured elsewhere (the headset's waits
    /// for its frames).
    pub fn of_intervals(intervals_ms: Vec<f64>) -> FrameStats {
        FrameStats { intervals_ms, ..Default::default() }
    }

    /// The mean and smallest share of the image cast.
    pub fn scale(&self) -> (f64, f64) {
        if self.frames == 0 { (1.0, 1.0) } else { (self.scale_sum / self.frames as f64, self.scale_min) }
    }

    /// Interval mean and max, ms.
    pub fn interval_mean_max(&self) -> (f64, f64) {
        let n = self.intervals_ms.len().max(1) as f64;
        (self.intervals_ms.iter().sum::<f64>() / n, self.intervals_ms.iter().copied().fold(0.0, f64::max))
    }

    /// The interval at quantile `q` (0.5: the median), ms; nearest rank.
    pub fn interval_quantile(&self, q: f64) -> f64 {
        let mut v = self.intervals_ms.clone();
        if v.is_empty() {
            return 0.0;
        }
        v.sort_by(f64::total_cmp);
        v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1]
    }

    fn count(&mut self, now: Instant, interval_ms: Option<f64>, scale: f64, still: bool, cast: bool) {
        if self.frames == 0 {
            self.scale_min = scale;
        }
        self.frames += 1;
        self.still_frames += u64::from(still);
        self.cast_frames += u64::from(cast);
        self.intervals_ms.extend(interval_ms);
        self.scale_sum += scale;
        self.scale_min = self.scale_min.min(scale);
        let (t0, f0) = *self.fps_window.get_or_insert((now, self.frames));
        let s = (now - t0).as_secs_f64();
        if s >= 1.0 {
            self.fps = (self.frames - f0) as f64 / s;
            self.fps_window = Some((now, self.frames));
        }
    }
}

/// Dynamic resolution, still frames and the frame log of one front end.
///
/// While the view or the painting changes, rays are cast for `scale` of
/// the image's width and height, `scale` following the frame time towards
/// the target; once a frame changes nothing it is cast at full size (the
/// still picture is always exact), and the frames after it cast nothing
/// and present that cast again. `L` is what the front end's view is made
/// of (a camera and a window size; two eye poses and the canvas's place),
/// compared frame to frame.
pub struct View<L> {
    pub scale: f64,
    target_ms: f64,
    pace: Pace,
    fixed: bool,
    last_look: Option<L>,
    /// When the last frame began, and whether it was moving (its interval
    /// then tells how long a frame at `scale` takes).
    last_frame: Option<(Instant, bool)>,
    /// The last cast was of the view as it is, at full size.
    full_cast: bool,
    log: Option<(std::io::BufWriter<std::fs::File>, Instant)>,
    /// This frame's log line, finished by [`View::log`].
    line: Option<String>,
    pub stats: FrameStats,
}

impl<L: PartialEq> View<L> {
    /// A view starting at full size; `fixed`: always cast at full size;
    /// `log`: write the frame log there (its header first).
    pub fn new(target_ms: f64, pace: Pace, fixed: bool, log: Option<&Path>) -> Result<View<L>, String> {
        let log = match log {
            Some(p) => {
                let f = std::fs::File::create(p).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
                let mut w = std::io::BufWriter::new(f);
                writeln!(w, "{FRAME_LOG_HEADER}").map_err(|e| format!("cannot write {}: {e}", p.display()))?;
                Some((w, Instant::now()))
            }
            None => None,
        };
        Ok(View { scale: 1.0, target_ms, pace, fixed, last_look: None, last_frame: None, full_cast: false, log, line: None, stats: FrameStats::default() })
    }

    /// Plan this frame of a `full`-sized image showing `look`, given
    /// whether the painting changed since the last frame (`changed`:
    /// anything uploaded). `full_size`: cast at full size anyway (a
    /// screenshot; its interval then teaches nothing). `have_cast`: the
    /// front end holds a last cast to present again. `mirror` (bit a: axis
    /// a) goes to the frame log only.
    pub fn plan(&mut self, full: [u32; 2], look: L, changed: bool, full_size: bool, have_cast: bool, mirror: u8) -> Planned {
        let now = Instant::now();
        let still = !changed && self.last_look.as_ref() == Some(&look);
        self.last_look = Some(look);
        let interval = self.last_frame.map(|(t, moving)| ((now - t).as_secs_f64() * 1e3, moving));
        if self.pace == Pace::Interval
            && let Some((ms, true)) = interval
            && !self.fixed
        {
            self.scale = follow_frame_time(self.scale, ms, self.target_ms);
        }
        let scale = if still || self.fixed || full_size { 1.0 } else { self.scale };
        let size = full.map(|v| ((f64::from(v) * scale).round() as u32).clamp(1, v.max(1)));
        self.last_frame = Some((now, !still && !full_size));
        let cast = !(still && self.full_cast) || !have_cast;
        if cast {
            self.full_cast = size == full;
        }
        self.stats.count(now, interval.map(|(ms, _)| ms), scale, still, cast);
        if let Some((_, t0)) = self.log.as_ref() {
            let ms = interval.map_or(0.0, |(ms, _)| ms);
            self.line = Some(format!(
                "{:.1},{ms:.2},{scale:.4},{},{},{},{mirror},{}",
                (now - *t0).as_secs_f64() * 1e3,
                size[0],
                size[1],
                u8::from(still),
                u8::from(cast)
            ));
        }
        Planned { scale, size, still, cast }
    }

    /// [`Pace::Measured`]: the casts of a moving frame took `ms`.
    pub fn took(&mut self, planned: &Planned, ms: f64) {
        if self.pace == Pace::Measured && !self.fixed && planned.cast && !planned.still {
            self.scale = follow_frame_time(self.scale, ms, self.target_ms);
        }
    }

    /// The last cast is of the view as it is at full size: nothing more
    /// to refine, a still frame casts nothing.
    pub fn settled(&self) -> bool {
        self.full_cast
    }

    /// Write this frame's line of the frame log with what the stroke
    /// thread was doing as the frame began and how long its uploads and g3
    /// pass took (`prepare_ms`). Line by line, flushed: a script or a test
    /// watching the log sees each frame as it is drawn.
    pub fn log(&mut self, doing: Doing, prepare_ms: f64) {
        if let (Some((log, _)), Some(line)) = (self.log.as_mut(), self.line.take()) {
            let _ = writeln!(log, "{line},{},{prepare_ms:.2}", doing.code());
            let _ = log.flush();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_still_view_casts_once_at_full_size_then_presents_it() {
        let mut v: View<u32> = View::new(WINDOW_TARGET_MS, Pace::Measured, false, None).unwrap();
        v.scale = 0.5;
        let moving = v.plan([100, 80], 1, true, false, false, 0);
        assert_eq!((moving.size, moving.still, moving.cast), ([50, 40], false, true));
        assert!(!v.settled());
        let first_still = v.plan([100, 80], 1, false, false, true, 0);
        assert_eq!((first_still.size, first_still.still, first_still.cast), ([100, 80], true, true));
        assert!(v.settled());
        let again = v.plan([100, 80], 1, false, false, true, 0);
        assert_eq!((again.still, again.cast), (true, false));
        // Nothing to present: cast anyway.
        assert!(v.plan([100, 80], 1, false, false, false, 0).cast);
        // The look or the painting changes: cast at the moving scale.
        let moved = v.plan([100, 80], 2, false, false, true, 0);
        assert_eq!((moved.size, moved.still, moved.cast), ([50, 40], false, true));
        assert_eq!((v.stats.frames, v.stats.still_frames, v.stats.cast_frames), (5, 3, 4));
        assert_eq!(v.stats.scale(), ((0.5 + 1.0 + 1.0 + 1.0 + 0.5) / 5.0, 0.5));
    }

    #[test]
    fn a_measured_pace_learns_only_from_moving_casts() {
        let mut v: View<u32> = View::new(HEADSET_TARGET_MS, Pace::Measured, false, None).unwrap();
        let p = v.plan([100, 100], 1, true, false, false, 0);
        v.took(&p, 4.0 * HEADSET_TARGET_MS);
        let shrunk = v.scale;
        assert!(shrunk < 1.0, "{shrunk}");
        let still = v.plan([100, 100], 1, false, false, true, 0);
        v.took(&still, 100.0 * HEADSET_TARGET_MS);
        assert_eq!(v.scale, shrunk);
        let mut fixed: View<u32> = View::new(HEADSET_TARGET_MS, Pace::Measured, true, None).unwrap();
        let p = fixed.plan([100, 100], 1, true, false, false, 0);
        fixed.took(&p, 4.0 * HEADSET_TARGET_MS);
        assert_eq!((fixed.scale, p.size), (1.0, [100, 100]));
    }

    #[test]
    fn the_frame_log_has_a_line_a_frame() {
        let dir = std::env::temp_dir().join(format!("octopaint-view-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("frames.csv");
        let mut v: View<u32> = View::new(WINDOW_TARGET_MS, Pace::Interval, false, Some(&path)).unwrap();
        for k in 0..3 {
            v.plan([64, 48], k / 2, k == 0, false, k > 0, 5);
            v.log(Doing::Saving, 1.25);
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], FRAME_LOG_HEADER);
        assert_eq!(lines.len(), 4);
        for line in &lines[1..] {
            let cols: Vec<&str> = line.split(',').collect();
            assert_eq!(cols.len(), FRAME_LOG_HEADER.split(',').count(), "{line}");
            assert_eq!((cols[6], cols[8], cols[9]), ("5", "2", "1.25"));
        }
        // The second frame is still (the same look, nothing changed), the
        // third is not (the look changed).
        assert_eq!(lines[2].split(',').nth(5), Some("1"));
        assert_eq!(lines[3].split(',').nth(5), Some("0"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn interval_quantiles_by_nearest_rank() {
        let s = FrameStats::of_intervals((1..=100).map(f64::from).collect());
        assert_eq!((s.interval_quantile(0.5), s.interval_quantile(0.99), s.interval_quantile(1.0)), (50.0, 99.0, 100.0));
        assert_eq!(s.interval_mean_max(), (50.5, 100.0));
    }
}
