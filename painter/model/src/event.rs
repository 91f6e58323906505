//! The events of a trace (spec 12; ../../shared/TRACE-FORMAT.md) and the
//! values they carry: the canvas, brushes with their shapes and modes,
//! samples, cameras, lights, mirror planes, layer operations and imports.
//! Plain data: octopaint-trace reads and writes them, the tree paints them.
//! Reference twin: the dataclasses of reference/octopaint_ref/trace.py.

/// A canvas (spec 1): the root array, the deepest level, a root's edge
/// in metres and the cell budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Canvas {
    pub roots: [u32; 3],
    pub max_depth: u32,
    pub root_size: f64,
    pub capacity: u32,
}

/// A stamp shape (spec 8.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    Sphere,
    Cylinder,
    Box,
    Cone,
    Noise,
}

impl Shape {
    /// Every shape, in the order of spec 8.2 (a shape's index is its
    /// position here: `Shape::ALL[s as usize] == s`).
    pub const ALL: [Shape; 5] = [Shape::Sphere, Shape::Cylinder, Shape::Box, Shape::Cone, Shape::Noise];

    /// The `shape` string of a `brush` event.
    pub const fn name(self) -> &'static str {
        match self {
            Shape::Sphere => "sphere",
            Shape::Cylinder => "cylinder",
            Shape::Box => "box",
            Shape::Cone => "cone",
            Shape::Noise => "noise",
        }
    }

    pub fn from_name(name: &str) -> Option<Shape> {
        Shape::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// A blend mode (spec 8.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    Paint,
    Erase,
    Recolor,
    Mix,
    Pickup,
}

impl Mode {
    /// Every mode, in the order of spec 8.5 (`Mode::ALL[m as usize] == m`).
    pub const ALL: [Mode; 5] = [Mode::Paint, Mode::Erase, Mode::Recolor, Mode::Mix, Mode::Pickup];

    /// The `mode` string of a `brush` event.
    pub const fn name(self) -> &'static str {
        match self {
            Mode::Paint => "paint",
            Mode::Erase => "erase",
            Mode::Recolor => "recolor",
            Mode::Mix => "mix",
            Mode::Pickup => "pickup",
        }
    }

    pub fn from_name(name: &str) -> Option<Mode> {
        Mode::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// The shapes' names, indexed as [`Shape::ALL`].
pub const SHAPES: [&str; 5] = {
    let mut names = [""; 5];
    let mut i = 0;
    while i < names.len() {
        names[i] = Shape::ALL[i].name();
        i += 1;
    }
    names
};

/// The modes' names, indexed as [`Mode::ALL`].
pub const MODES: [&str; 5] = {
    let mut names = [""; 5];
    let mut i = 0;
    while i < names.len() {
        names[i] = Mode::ALL[i].name();
        i += 1;
    }
    names
};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Noise {
    pub frequency: f64,
    pub octaves: u32,
    pub seed: u32,
    pub gain: f64,
}

impl Default for Noise {
    fn default() -> Self {
        Noise { frequency: 1.0, octaves: 4, seed: 0, gain: 0.5 }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Brush {
    pub shape: Shape,
    pub mode: Mode,
    pub radius: f64,
    pub color: [f64; 3],
    pub opacity: f64,
    pub hardness: f64,
    pub spacing: f64,
    pub mix_ratio: f64,
    pub pickup_rate: f64,
    pub aspect: [f64; 3],
    pub noise: Noise,
    /// Mirror painting (spec 8.11): None paints the stroke alone. Not a
    /// brush field of the trace: the last `mirror` event's planes, set on
    /// the brush when a stroke begins.
    pub mirror: Option<Mirror>,
}

/// Mirror painting (spec 8.11): the planes through `centre` (canvas units)
/// normal to the axes set in `axes` (x, y, z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    pub axes: [bool; 3],
    pub centre: [f64; 3],
}

impl Mirror {
    /// The planes a stroke paints with: None when no axis is set.
    pub fn active(self) -> Option<Mirror> {
        self.axes.iter().any(|&a| a).then_some(self)
    }

    /// The mirrored copies as axis masks (bit a: axis a mirrored), in
    /// increasing order: every non-empty combination of the set axes.
    pub fn copies(&self) -> impl Iterator<Item = u8> + '_ {
        let on = (0..3).filter(|&a| self.axes[a]).fold(0u8, |m, a| m | 1 << a);
        (1..8u8).filter(move |m| m & !on == 0)
    }
}

impl Brush {
    /// A brush with the defaults of spec 8.1 for the optional parameters.
    pub fn new(shape: Shape, mode: Mode, radius: f64, color: [f64; 3], opacity: f64, hardness: f64) -> Self {
        Brush {
            shape,
            mode,
            radius,
            color,
            opacity,
            hardness,
            spacing: 0.25,
            mix_ratio: 1.0,
            pickup_rate: 0.25,
            aspect: [1.0; 3],
            noise: Noise::default(),
            mirror: None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub p: [f64; 3],
    pub pressure: f64,
    pub q: [f64; 4],
}

impl Sample {
    pub fn at(p: [f64; 3]) -> Self {
        Sample { p, pressure: 1.0, q: [0.0, 0.0, 0.0, 1.0] }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    pub q: [f64; 4],
    pub fov: [f64; 4],
    pub size: [u32; 2],
    pub background: [f64; 3],
}

/// The `light` event (spec 6.1): lighting on or off; when on, the direction
/// towards the light in canvas space (as given; normalised when rendering),
/// its intensity, the ambient term and whether a shadow ray is cast.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub on: bool,
    pub dir: [f64; 3],
    pub intensity: f64,
    pub ambient: f64,
    pub shadows: bool,
}

impl Light {
    /// Lighting off: the unlit images of spec 6.
    pub const OFF: Light = Light { on: false, dir: [0.0; 3], intensity: 0.8, ambient: 0.3, shadows: false };
}

impl Default for Light {
    /// On, with the trace format's defaults and no direction yet.
    fn default() -> Self {
        Light { on: true, ..Light::OFF }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum EventKind {
    Brush(Brush),
    StrokeBegin,
    Sample(Sample),
    StrokeEnd,
    Camera(Camera),
    Light(Light),
    Mirror(Mirror),
    Render(String),
    Snapshot(String),
    Undo,
    Redo,
    Layer(LayerOp),
    Import(Box<Import>),
}

/// One `import` event (spec 15.2): the file as the trace names it, its
/// digest, the optional label, and the voxel set read from it (shared: a
/// document keeps it once).
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    pub file: String,
    pub sha256: String,
    pub name: Option<String>,
    pub voxels: std::sync::Arc<crate::voxel_set::VoxelSet>,
}

/// One `layer` event (spec 14.2), as read: the fields its `op` uses.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerOp {
    pub op: LayerOpKind,
    pub layer: Option<String>,
    pub name: Option<String>,
    pub to: Option<usize>,
    pub visible: Option<bool>,
    /// Rounded to f32 when read (spec 14.1).
    pub opacity: Option<f32>,
    pub locked: Option<bool>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerOpKind {
    Add,
    Delete,
    Select,
    Rename,
    Move,
    Set,
    Duplicate,
    MergeDown,
}

impl LayerOpKind {
    pub const ALL: [LayerOpKind; 8] = [
        LayerOpKind::Add,
        LayerOpKind::Delete,
        LayerOpKind::Select,
        LayerOpKind::Rename,
        LayerOpKind::Move,
        LayerOpKind::Set,
        LayerOpKind::Duplicate,
        LayerOpKind::MergeDown,
    ];

    /// The `op` string.
    pub fn code(self) -> &'static str {
        match self {
            LayerOpKind::Add => "add",
            LayerOpKind::Delete => "delete",
            LayerOpKind::Select => "select",
            LayerOpKind::Rename => "rename",
            LayerOpKind::Move => "move",
            LayerOpKind::Set => "set",
            LayerOpKind::Duplicate => "duplicate",
            LayerOpKind::MergeDown => "merge_down",
        }
    }
}

impl LayerOp {
    pub fn new(op: LayerOpKind) -> Self {
        LayerOp { op, layer: None, name: None, to: None, visible: None, opacity: None, locked: None }
    }
}

impl EventKind {
    /// The `ev` string of the event.
    pub fn ev(&self) -> &'static str {
        match self {
            EventKind::Brush(_) => "brush",
            EventKind::StrokeBegin => "stroke_begin",
            EventKind::Sample(_) => "sample",
            EventKind::StrokeEnd => "stroke_end",
            EventKind::Camera(_) => "camera",
            EventKind::Light(_) => "light",
            EventKind::Mirror(_) => "mirror",
            EventKind::Render(_) => "render",
            EventKind::Snapshot(_) => "snapshot",
            EventKind::Undo => "undo",
            EventKind::Redo => "redo",
            EventKind::Layer(_) => "layer",
            EventKind::Import(_) => "import",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// 1-based line of the event in the file.
    pub line: usize,
    pub t: f64,
    pub kind: EventKind,
}

/// The free-form `meta` object of a header (written back with its keys
/// sorted: a JSON object has no order).
pub type Meta = serde_json::Map<String, serde_json::Value>;

#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    pub canvas: Canvas,
    pub meta: Meta,
    pub events: Vec<Event>,
    pub warnings: Vec<String>,
    /// 1, or 2 for a document of layers (spec 14).
    pub version: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shape_or_mode_is_its_index_and_its_name_reads_back() {
        for (i, s) in Shape::ALL.into_iter().enumerate() {
            assert_eq!(s as usize, i);
            assert_eq!(SHAPES[i], s.name());
            assert_eq!(Shape::from_name(s.name()), Some(s));
        }
        for (i, m) in Mode::ALL.into_iter().enumerate() {
            assert_eq!(m as usize, i);
            assert_eq!(MODES[i], m.name());
            assert_eq!(Mode::from_name(m.name()), Some(m));
        }
        assert_eq!(Shape::from_name("Sphere"), None);
        assert_eq!(Mode::from_name(""), None);
    }

    #[test]
    fn mirror_copies_are_every_combination_of_the_set_axes() {
        let m = Mirror { axes: [true, false, true], centre: [0.0; 3] };
        assert_eq!(m.copies().collect::<Vec<_>>(), vec![1, 4, 5]);
        assert_eq!(Mirror { axes: [false; 3], centre: [0.0; 3] }.active(), None);
    }
}
