//! Traces (spec 12; ../../shared/TRACE-FORMAT.md): the event model here,
//! the field rules in [`fields`], reading a whole trace in [`read`]. A bad
//! trace gives one [`TraceError`]: its line and its [`ErrorKind`] are the
//! contract both readers keep (the reference's is
//! reference/octopaint_ref/trace.py; `traces/malformed/expected.json` and
//! the conformance driver hold them to it); the message is this reader's
//! own.

mod fields;
mod read;

pub use fields::{is_valid_name, parse_brush, parse_camera, parse_canvas, parse_layer, parse_light, parse_mirror, parse_sample, segment_too_long};
pub use read::{MAX_NESTING, Resolve, folder_resolver, io_reason, nesting_depth, parse_trace, parse_trace_bytes, parse_trace_with, read_trace};

pub const SHAPES: [&str; 5] = ["sphere", "cylinder", "box", "cone", "noise"];
pub const MODES: [&str; 5] = ["paint", "erase", "recolor", "mix", "pickup"];
pub const MAX_DEPTH_LIMIT: i64 = 28;
/// The largest multiple of 8 below NONE.
pub const MAX_CAPACITY: i64 = 0xFFFF_FFF8;
pub const MAX_IMAGE_SIZE: i64 = 16384;
pub const MAX_ROOTS: u64 = 1 << 24;
pub const MAX_STAMPS_PER_SEGMENT: f64 = 65536.0;
/// Smallest normal f64; smaller magnitudes read as +0 (spec 8.9).
/// The largest `intensity` of a `light` event (spec 6.1).
pub const LIGHT_INTENSITY_MAX: f64 = 16.0;
pub const TINY: f64 = 2.2250738585072014e-308;

/// What is wrong with a refused trace, as the short stable code of spec
/// 12.2 that both readers must agree on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The file cannot be read (line 0).
    Io,
    /// Bytes that are not UTF-8.
    Utf8,
    /// A line that is not JSON under the rules of spec 12.2.
    Json,
    /// No `ddo-trace` header first, or a version this reader does not know.
    Header,
    /// A line or field of the wrong JSON type.
    Type,
    /// A required field is absent.
    Missing,
    /// A value outside what its field allows.
    Range,
    /// More work or memory than the limits allow (stamps per segment,
    /// roots, the cell budget against the roots).
    Budget,
    /// An unknown `ev`.
    Event,
    /// An event out of place (time going back, a sample outside a stroke,
    /// undo with nothing to undo, ...).
    EventOrder,
    /// A render or snapshot name that is no plain name or is used twice.
    Name,
    /// A `layer` event or a stroke the document cannot take (spec 14.2).
    Layer,
    /// An `import` event's file: unreadable, another digest, or not a voxel
    /// set for this canvas (spec 15.2).
    Import,
}

impl ErrorKind {
    pub const ALL: [ErrorKind; 13] = [
        ErrorKind::Io,
        ErrorKind::Utf8,
        ErrorKind::Json,
        ErrorKind::Header,
        ErrorKind::Type,
        ErrorKind::Missing,
        ErrorKind::Range,
        ErrorKind::Budget,
        ErrorKind::Event,
        ErrorKind::EventOrder,
        ErrorKind::Name,
        ErrorKind::Layer,
        ErrorKind::Import,
    ];

    /// The code as the spec writes it.
    pub fn code(self) -> &'static str {
        match self {
            ErrorKind::Io => "io",
            ErrorKind::Utf8 => "utf8",
            ErrorKind::Json => "json",
            ErrorKind::Header => "header",
            ErrorKind::Type => "type",
            ErrorKind::Missing => "missing",
            ErrorKind::Range => "range",
            ErrorKind::Budget => "budget",
            ErrorKind::Event => "event",
            ErrorKind::EventOrder => "event-order",
            ErrorKind::Name => "name",
            ErrorKind::Layer => "layer",
            ErrorKind::Import => "import",
        }
    }

    pub fn from_code(code: &str) -> Option<ErrorKind> {
        ErrorKind::ALL.into_iter().find(|k| k.code() == code)
    }
}

/// A trace that must not be replayed: where (1-based line, 0 when the file
/// cannot be read), what kind of error, and a message naming the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}", self.text())]
pub struct TraceError {
    pub line: usize,
    pub kind: ErrorKind,
    pub message: String,
}

impl TraceError {
    pub fn new(line: usize, kind: ErrorKind, message: impl Into<String>) -> Self {
        TraceError { line, kind, message: message.into() }
    }

    /// `line N: MESSAGE` (the message alone at line 0).
    pub fn text(&self) -> String {
        if self.line == 0 { self.message.clone() } else { format!("line {}: {}", self.line, self.message) }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Canvas {
    pub roots: [u32; 3],
    pub max_depth: u32,
    pub root_size: f64,
    pub capacity: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    Sphere,
    Cylinder,
    Box,
    Cone,
    Noise,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    Paint,
    Erase,
    Recolor,
    Mix,
    Pickup,
}

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
    pub voxels: std::sync::Arc<crate::voxels::VoxelSet>,
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
