//! Painting with the controllers (docs/vr.md, "Controllers"): the right
//! trigger paints at the right controller's tip with the trigger's value as
//! pressure; a grip grabs the canvas and moves it with the hand, two grips
//! scale and turn it about the vertical; the right thumbstick changes the
//! brush size; the right primary and secondary buttons undo and redo; the
//! left hand holds the palette, whose pages the left trigger steps through:
//! the brush (thumbstick left/right: colour, up/down: mode, primary
//! button: shape), the layers (up/down: select, left/right: opacity, X:
//! show or hide, Y: a new layer), the mirror planes (X, Y, stick up:
//! the x, y, z planes through the painting's centre; stick down: none) and
//! the brush presets (up/down: choose, X: take its brush).
//! Every change of the painting is a job for the engine's stroke thread,
//! which owns the document and journals each stroke and layer operation as
//! it happens (`octopaint_pipeline::OpenDocument`), so the session records
//! as a trace; what the palette shows of the document comes from the
//! status the stroke thread publishes.

use glam::{DQuat, DVec3};
use octopaint_doc::presets::Preset;
use octopaint_pipeline::{Engine, Job, Status};
use octopaint_tree::trace::{Brush, EventKind, LayerOp, LayerOpKind, Mirror, Mode, Sample, Shape};

use crate::input::{Hand, LEFT, RIGHT};
use crate::placement::Placement;

/// What the controllers act on: the engine that owns the document, and
/// what its stroke thread published last.
pub struct Live<'a> {
    pub engine: &'a Engine,
    pub status: &'a Status,
}

/// Colours of the palette (sRGB).
pub const PALETTE: [[f64; 3]; 8] =
    [[0.92, 0.45, 0.15], [0.85, 0.15, 0.15], [0.95, 0.85, 0.25], [0.25, 0.65, 0.3], [0.2, 0.45, 0.9], [0.55, 0.3, 0.75], [0.95, 0.95, 0.95], [0.08, 0.08, 0.1]];

/// What the controllers are doing to the painting and the canvas.
pub struct Gestures {
    /// Brush radius in the room, metres (the canvas radius follows the zoom).
    pub room_radius: f64,
    pub colour: usize,
    /// A preset's colour, in place of the palette's until the stick
    /// chooses one of those again.
    pub preset_colour: Option<[f64; 3]>,
    /// The brush fields the palette has no control for (spacing, mix
    /// ratio, pickup rate, aspect, noise), as the last preset taken set them.
    pub rest: Brush,
    /// The artist's brush presets (docs/vr.md; read when the session
    /// starts, kept by the window) and the one the presets page points at.
    pub presets: Vec<Preset>,
    pub preset: usize,
    pub shape: usize,
    pub mode: usize,
    pub opacity: f64,
    pub hardness: f64,
    prev: [Hand; 2],
    last_tip: Option<DVec3>,
    grab: Grab,
    /// Events refused by the document (shown, never fatal).
    pub last_error: Option<String>,
    pub strokes: u64,
    /// How the view is drawn: lit (docs/spec.md 6.1, the canvas's default
    /// light) and with the ground grid; Y (the left secondary button)
    /// steps through [`VIEWS`].
    pub view: usize,
    /// Set by X with the left grip held: put the painting back in front of
    /// the head (the session does it, knowing the head's pose).
    pub reframe: bool,
    /// The palette's page (the left trigger steps through [`PAGES`]).
    pub page: Page,
    /// The mirror planes of the next strokes (spec 8.11), as the last
    /// `mirror` event set them.
    pub mirror: Mirror,
    /// A stroke is open (the trigger began it and has not let go).
    pub in_stroke: bool,
}

/// The palette's pages, in the order the left trigger steps through them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Page {
    Brush,
    Layers,
    Mirror,
    Presets,
}

pub const PAGES: [Page; 4] = [Page::Brush, Page::Layers, Page::Mirror, Page::Presets];

impl Page {
    /// The page's name on the palette.
    pub fn name(self) -> &'static str {
        match self {
            Page::Brush => "brush",
            Page::Layers => "layers",
            Page::Mirror => "mirror",
            Page::Presets => "presets",
        }
    }
}

/// The brush's radius in the room, metres: what the right stick allows.
pub const ROOM_RADII: (f64, f64) = (0.001, 0.5);

/// The headset's views, in the order Y steps through them: (lit, grid).
pub const VIEWS: [(bool, bool); 4] = [(true, false), (true, true), (false, true), (false, false)];

#[derive(Clone, Copy)]
enum Grab {
    None,
    /// One hand: its pose and the placement when the grab began.
    One {
        hand: usize,
        p0: DVec3,
        q0: DQuat,
        start: Placement,
    },
    /// Both hands: their positions and the placement when it began.
    Two {
        a0: DVec3,
        b0: DVec3,
        start: Placement,
    },
}

impl Default for Gestures {
    fn default() -> Self {
        Gestures {
            room_radius: 0.01,
            colour: 0,
            preset_colour: None,
            rest: Brush::new(Shape::Sphere, Mode::Paint, 1.0, [0.0; 3], 1.0, 0.5),
            presets: Vec::new(),
            preset: 0,
            shape: 0,
            mode: 0,
            opacity: 0.8,
            hardness: 0.6,
            prev: [Hand::default(); 2],
            last_tip: None,
            grab: Grab::None,
            last_error: None,
            strokes: 0,
            view: 0,
            reframe: false,
            page: Page::Brush,
            mirror: Mirror { axes: [false; 3], centre: [0.0; 3] },
            in_stroke: false,
        }
    }
}

fn yaw(v: DVec3) -> f64 {
    v.x.atan2(-v.z)
}

impl Gestures {
    /// Whether the view is lit, and whether it shows the ground grid.
    pub fn lit_and_grid(&self) -> (bool, bool) {
        VIEWS[self.view]
    }

    /// The brush as the canvas sees it at `placement`'s zoom.
    pub fn brush(&self, placement: &Placement) -> Brush {
        Brush {
            shape: Shape::ALL[self.shape],
            mode: Mode::ALL[self.mode],
            radius: self.room_radius / placement.scale,
            color: self.preset_colour.unwrap_or(PALETTE[self.colour]),
            opacity: self.opacity,
            hardness: self.hardness,
            ..self.rest
        }
    }

    /// The presets page: stick up/down points at the preset above/below
    /// (round the list), X takes its whole brush for the next strokes, its
    /// radius kept in canvas units at `placement`'s zoom (within the room
    /// radii the stick allows). Nothing of the document changes.
    pub fn presets_page(&mut self, placement: &Placement, up: bool, down: bool, x: bool) {
        let n = self.presets.len();
        if n == 0 {
            return;
        }
        if up {
            self.preset = (self.preset + n - 1) % n;
        }
        if down {
            self.preset = (self.preset + 1) % n;
        }
        self.preset %= n;
        if x {
            let b = self.presets[self.preset].brush;
            self.shape = Shape::ALL.iter().position(|&s| s == b.shape).unwrap_or(0);
            self.mode = Mode::ALL.iter().position(|&m| m == b.mode).unwrap_or(0);
            self.room_radius = (b.radius * placement.scale).clamp(ROOM_RADII.0, ROOM_RADII.1);
            (self.opacity, self.hardness, self.preset_colour, self.rest) = (b.opacity, b.hardness, Some(b.color), b);
        }
    }

    fn apply(&mut self, doc: &Live, job: Job) {
        if let Err(e) = doc.engine.submit(job) {
            self.last_error = Some(e.to_string());
        }
    }

    /// One frame of input, `dt` seconds since the last.
    pub fn update(&mut self, hands: &[Hand; 2], placement: &mut Placement, doc: &Live, dt: f64) {
        let (l, r) = (&hands[LEFT], &hands[RIGHT]);
        let rose = |now: bool, before: bool| now && !before;
        // Grabbing: the canvas follows one hand, or two.
        let holding = |h: &Hand| h.grip > 0.5 && h.pose.is_some();
        self.grab = match (holding(l), holding(r), self.grab) {
            (true, true, Grab::Two { a0, b0, start }) => {
                let (a, b) = (l.pose.expect("held").0, r.pose.expect("held").0);
                let s = ((b - a).length() / (b0 - a0).length().max(1e-6)).clamp(1e-3, 1e3);
                let turn = DQuat::from_rotation_y(yaw(b - a) - yaw(b0 - a0));
                let (m0, m) = ((a0 + b0) / 2.0, (a + b) / 2.0);
                let pivot = start.to_canvas(m0);
                let rotation = turn * start.rotation;
                let scale = start.scale * s;
                *placement = Placement { centre: start.centre, scale, rotation, origin: m - scale * (rotation * (pivot - start.centre)) };
                self.grab
            }
            (true, true, _) => Grab::Two { a0: l.pose.expect("held").0, b0: r.pose.expect("held").0, start: *placement },
            (gl, gr, g) if gl || gr => {
                let hand = if gl { LEFT } else { RIGHT };
                let (p, q) = hands[hand].pose.expect("held");
                match g {
                    Grab::One { hand: h0, p0, q0, start } if h0 == hand => {
                        let d = q * q0.inverse();
                        *placement = Placement { rotation: d * start.rotation, origin: p + d * (start.origin - p0), ..start };
                        g
                    }
                    _ => Grab::One { hand, p0: p, q0: q, start: *placement },
                }
            }
            _ => Grab::None,
        };
        // Brush size on the right stick (doubling per second at full tilt).
        if r.stick[1].abs() > 0.2 && !self.in_stroke {
            self.room_radius = (self.room_radius * 2f64.powf(f64::from(r.stick[1]) * dt)).clamp(ROOM_RADII.0, ROOM_RADII.1);
        }
        // The palette on the left hand: the trigger turns its page, the
        // stick and buttons act on the page shown.
        let pl = self.prev[LEFT];
        let (right, left, up, down) = (
            l.stick[0] > 0.7 && pl.stick[0] <= 0.7,
            l.stick[0] < -0.7 && pl.stick[0] >= -0.7,
            l.stick[1] > 0.7 && pl.stick[1] <= 0.7,
            l.stick[1] < -0.7 && pl.stick[1] >= -0.7,
        );
        if l.trigger > 0.7 && pl.trigger <= 0.7 {
            let k = PAGES.iter().position(|&p| p == self.page).unwrap_or(0);
            self.page = PAGES[(k + 1) % PAGES.len()];
        }
        let (x, y) = (rose(l.primary, pl.primary), rose(l.secondary, pl.secondary));
        if x && l.grip > 0.5 {
            // X while holding the canvas, on any page: frame the painting.
            // The grab starts again from the new placement next frame.
            self.reframe = true;
            self.grab = Grab::None;
        } else {
            match self.page {
                Page::Brush => {
                    if right {
                        self.colour = (self.colour + 1) % PALETTE.len();
                        self.preset_colour = None;
                    }
                    if left {
                        self.colour = (self.colour + PALETTE.len() - 1) % PALETTE.len();
                        self.preset_colour = None;
                    }
                    if up {
                        self.mode = (self.mode + 1) % Mode::ALL.len();
                    }
                    if down {
                        self.mode = (self.mode + Mode::ALL.len() - 1) % Mode::ALL.len();
                    }
                    if x {
                        self.shape = (self.shape + 1) % Shape::ALL.len();
                    }
                    if y {
                        self.view = (self.view + 1) % VIEWS.len();
                    }
                }
                Page::Layers if !self.in_stroke => self.layers_page(doc, [right, left, up, down], x, y),
                Page::Mirror if !self.in_stroke => {
                    let mut axes = self.mirror.axes;
                    if x {
                        axes[0] = !axes[0];
                    }
                    if y {
                        axes[1] = !axes[1];
                    }
                    if up {
                        axes[2] = !axes[2];
                    }
                    if down {
                        axes = [false; 3];
                    }
                    if axes != self.mirror.axes {
                        // Planes through the painting's centre as placed; an
                        // active set keeps its centre while axes are added.
                        let centre = if self.mirror.axes.iter().any(|&a| a) { self.mirror.centre } else { placement.centre.to_array() };
                        let m = Mirror { axes, centre };
                        self.apply(doc, Job::Event(EventKind::Mirror(m)));
                        self.mirror = m.active().unwrap_or(Mirror { axes: [false; 3], centre });
                    }
                }
                Page::Presets if !self.in_stroke => self.presets_page(placement, up, down, x),
                Page::Layers | Page::Mirror | Page::Presets => {}
            }
        }
        // Undo and redo on the right hand, between strokes.
        if !self.in_stroke {
            if rose(r.primary, self.prev[RIGHT].primary) {
                self.apply(doc, Job::Undo);
            }
            if rose(r.secondary, self.prev[RIGHT].secondary) {
                self.apply(doc, Job::Redo);
            }
        }
        // Painting with the right trigger.
        let painting = r.trigger > 0.05 && r.pose.is_some() && !matches!(self.grab, Grab::One { hand: RIGHT, .. } | Grab::Two { .. });
        if painting {
            let tip = r.pose.expect("checked").0;
            if !self.in_stroke {
                // The brush and the mirror planes go with the stroke (the
                // stroke thread records them as events when they change).
                let brush = Brush { mirror: self.mirror.active(), ..self.brush(placement) };
                self.apply(doc, Job::BeginStroke(brush));
                self.in_stroke = true;
                self.last_tip = None;
            }
            // A sample when the tip has moved a quarter radius (or first).
            let moved = self.last_tip.is_none_or(|p| (tip - p).length() >= 0.25 * self.room_radius);
            if moved {
                let p = placement.to_canvas(tip);
                let sample = Sample { p: p.to_array(), pressure: f64::from(r.trigger).clamp(0.0, 1.0), q: [0.0, 0.0, 0.0, 1.0] };
                self.apply(doc, Job::Sample(sample));
                self.last_tip = Some(tip);
            }
        } else if self.in_stroke {
            self.apply(doc, Job::EndStroke);
            self.in_stroke = false;
            self.strokes += 1;
        }
        self.prev = *hands;
    }

    /// The layers page: stick up/down selects the layer above/below,
    /// left/right changes its opacity by a tenth, X shows or hides it, Y
    /// adds a layer above it (a one-tree document becomes a document of
    /// layers first, as the window's "Use layers" does). Each is a `layer`
    /// event; one the document refuses says why on the panel.
    fn layers_page(&mut self, doc: &Live, [right, left, up, down]: [bool; 4], x: bool, y: bool) {
        let s = doc.status;
        if y {
            if s.version != 2 {
                self.apply(doc, Job::UseLayers);
            }
            let taken: Vec<&str> = s.layers.iter().map(|l| l.name.as_str()).collect();
            let name = (s.layers.len() + 1..).map(|n| format!("Layer {n}")).find(|n| !taken.contains(&n.as_str())).expect("a free name");
            let mut op = LayerOp::new(LayerOpKind::Add);
            op.name = Some(name);
            self.apply(doc, Job::Event(EventKind::Layer(op)));
            return;
        }
        if s.version != 2 {
            return; // one tree: nothing to select or set until Y makes layers
        }
        let (k, n) = (s.selected, s.layers.len());
        let Some(current) = s.layers.get(k) else { return };
        let name = current.name.clone();
        let (visible, opacity) = (current.visible, current.opacity);
        let target = if up && k + 1 < n {
            Some(k + 1)
        } else if down && k > 0 {
            Some(k - 1)
        } else {
            None
        };
        if let Some(j) = target {
            let mut op = LayerOp::new(LayerOpKind::Select);
            op.layer = Some(s.layers[j].name.clone());
            self.apply(doc, Job::Event(EventKind::Layer(op)));
        }
        let step = if right {
            0.1
        } else if left {
            -0.1
        } else {
            0.0
        };
        if step != 0.0 {
            // In tenths, so that steps land on 0.1, 0.2, ... exactly as read.
            let tenths = ((f64::from(opacity) * 10.0).round() + step * 10.0).clamp(0.0, 10.0);
            let mut op = LayerOp::new(LayerOpKind::Set);
            op.layer = Some(name.clone());
            op.opacity = Some((tenths / 10.0) as f32);
            self.apply(doc, Job::Event(EventKind::Layer(op)));
        }
        if x {
            let mut op = LayerOp::new(LayerOpKind::Set);
            op.layer = Some(name);
            op.visible = Some(!visible);
            self.apply(doc, Job::Event(EventKind::Layer(op)));
        }
    }

    /// End a stroke left open (the session is ending).
    pub fn finish(&mut self, doc: &Live) {
        if self.in_stroke {
            self.apply(doc, Job::EndStroke);
            self.in_stroke = false;
            self.strokes += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_presets_page_chooses_round_the_list_and_takes_a_whole_brush() {
        let mut g = Gestures { presets: octopaint_doc::presets::starting_set(), ..Gestures::default() };
        let n = g.presets.len();
        let placement = Placement { centre: DVec3::ZERO, scale: 0.25, rotation: DQuat::IDENTITY, origin: DVec3::ZERO };
        let before = g.brush(&placement);
        g.presets_page(&placement, true, false, false);
        assert_eq!(g.preset, n - 1, "up from the first is the last");
        assert_eq!(g.brush(&placement), before, "pointing changes no brush");
        g.presets_page(&placement, false, true, false);
        g.presets_page(&placement, false, true, false);
        assert_eq!(g.preset, 1);
        g.presets_page(&placement, false, false, true);
        let want = g.presets[1].brush;
        let got = g.brush(&placement);
        assert!((got.radius - want.radius).abs() <= 1e-12 * want.radius, "{} against {}", got.radius, want.radius);
        assert_eq!(Brush { radius: want.radius, ..got }, want);
        // The palette's stick takes its own colours back.
        g.page = Page::Brush;
        g.preset_colour = None;
        assert_eq!(g.brush(&placement).color, PALETTE[g.colour]);
        // A radius the room cannot hold is kept within the stick's range.
        let mut huge = g.presets[0].clone();
        huge.brush.radius = 1e6;
        g.presets = vec![huge];
        g.preset = 0;
        g.presets_page(&placement, false, false, true);
        assert_eq!(g.room_radius, ROOM_RADII.1);
        // No presets: the page does nothing.
        g.presets.clear();
        g.presets_page(&placement, true, true, true);
    }
}
