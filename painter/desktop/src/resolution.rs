//! Dynamic resolution and the frame log (docs/desktop.md).

use std::io::Write as _;
use std::time::Instant;

use octopaint_tree::trace::Light;
use octopaint_tree::view::{OrbitCamera, follow_frame_time};

/// The frame time the dynamic resolution aims at on the desktop (60 Hz).
pub const TARGET_FRAME_MS: f64 = 16.7;

/// What the view shows besides the camera: the grid, the light.
pub(crate) type Look = (bool, Option<Light>);

/// Dynamic resolution (docs/desktop.md): while the view changes (camera,
/// painting, size, grid, light), rays are cast for `scale` of the window's width
/// and height, `scale` following the frame time towards
/// [`TARGET_FRAME_MS`]; once a frame changes nothing, it is cast at full
/// size (progressive refinement: the still picture is always exact).
pub(crate) struct Resolution {
    pub scale: f64,
    /// What the last frame showed, to tell a still frame.
    last_view: Option<(OrbitCamera, [u32; 2], Look)>,
    /// When the last frame began, and whether the view was moving then
    /// (its interval then tells how long a frame at `scale` takes).
    last_frame: Option<(Instant, bool)>,
    pub fixed: bool,
    pub log: Option<(std::io::BufWriter<std::fs::File>, Instant)>,
    /// This frame's log line, written once the frame knows whether it
    /// cast new rays ([`Resolution::log`]).
    line: Option<String>,
}

impl Resolution {
    /// The cast size of this frame of a `window`-sized view, given whether
    /// the tree changed since the last one, and whether the view is still;
    /// learns from the last frame's interval when that frame was moving.
    /// `full`: cast this frame at full size anyway (a screenshot); its
    /// interval then teaches nothing.
    /// `mirror`: the mirror planes the brush has now (bit a: axis a), for
    /// the frame log only.
    pub fn next(&mut self, window: [u32; 2], camera: &OrbitCamera, look: Look, tree_changed: bool, full: bool, mirror: u8) -> ([u32; 2], bool) {
        let now = Instant::now();
        let view = (*camera, window, look);
        let still = !tree_changed && self.last_view == Some(view);
        self.last_view = Some(view);
        let interval = self.last_frame.map(|(t, moving)| ((now - t).as_secs_f64() * 1e3, moving));
        if let Some((ms, true)) = interval
            && !self.fixed
        {
            self.scale = follow_frame_time(self.scale, ms, TARGET_FRAME_MS);
        }
        let scale = if still || self.fixed || full { 1.0 } else { self.scale };
        let size = window.map(|v| ((f64::from(v) * scale).round() as u32).clamp(1, v.max(1)));
        self.last_frame = Some((now, !still && !full));
        if let Some((_, t0)) = self.log.as_ref() {
            let ms = interval.map_or(0.0, |(ms, _)| ms);
            self.line = Some(format!("{:.1},{ms:.2},{scale:.4},{},{},{},{mirror}", (now - *t0).as_secs_f64() * 1e3, size[0], size[1], u8::from(still)));
        }
        (size, still)
    }

    /// Write this frame's line of the frame log, with whether it cast new
    /// rays (a still frame presents the last cast again) and what the
    /// stroke thread was doing as the frame began (`engine`: 0 nothing,
    /// 1 painting a stroke, undo or redo, 2 saving, 3 another job), and
    /// how long its uploads and g3 pass took (`prepare_ms`).
    pub fn log(&mut self, cast: bool, engine: u8, prepare_ms: f64) {
        if let (Some((log, _)), Some(line)) = (self.log.as_mut(), self.line.take()) {
            let _ = writeln!(log, "{line},{},{engine},{prepare_ms:.2}", u8::from(cast));
            // Line by line: a script (or a test) watching the log sees each
            // frame as it is drawn. One small write a frame.
            let _ = log.flush();
        }
    }

    /// A resolution starting at full size, logging to `log` when given
    /// (its header written).
    pub fn new(fixed: bool, log: Option<&std::path::Path>) -> Result<Resolution, String> {
        let log = match log {
            Some(p) => {
                let f = std::fs::File::create(p).map_err(|e| format!("cannot write {}: {e}", p.display()))?;
                let mut w = std::io::BufWriter::new(f);
                let _ = writeln!(w, "t_ms,interval_ms,scale,width,height,still,mirror,cast,engine,prepare_ms");
                Some((w, Instant::now()))
            }
            None => None,
        };
        Ok(Resolution { scale: 1.0, last_view: None, last_frame: None, fixed, log, line: None })
    }
}

