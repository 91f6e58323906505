//! The trace reader (spec 12; ../../shared/TRACE-FORMAT.md): parses and
//! validates a whole `.jsonl` trace before anything runs. A bad trace gives
//! one [`TraceError`] naming the line and the field, with exactly the text of
//! the reference reader (reference/octopaint_ref/trace.py), which
//! `traces/malformed/expected.json` and the conformance driver's reader
//! comparison hold both readers to.

use num_bigint::BigInt;
use num_traits::{FromPrimitive, ToPrimitive};

use crate::json::{self, Json, ParseFailure};
use crate::pyrepr::py_float_repr as repr;

pub const SHAPES: [&str; 5] = ["sphere", "cylinder", "box", "cone", "noise"];
pub const MODES: [&str; 5] = ["paint", "erase", "recolor", "mix", "pickup"];
pub const MAX_DEPTH_LIMIT: i64 = 28;
/// The largest multiple of 8 below NONE.
pub const MAX_CAPACITY: i64 = 0xFFFF_FFF8;
pub const MAX_IMAGE_SIZE: i64 = 16384;
pub const MAX_ROOTS: u64 = 1 << 24;
pub const MAX_STAMPS_PER_SEGMENT: f64 = 65536.0;
const SPACING_RANGE: (f64, f64) = (0.01, 100.0);
const ASPECT_RANGE: (f64, f64) = (1e-3, 1e3);
const NOISE_FREQUENCY_MAX: f64 = 1e6;
/// Smallest normal f64; smaller magnitudes read as +0 (spec 8.9).
pub const TINY: f64 = 2.2250738585072014e-308;

/// A trace that must not be replayed; the message names line and field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct TraceError(pub String);

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

#[derive(Clone, Debug, PartialEq)]
pub enum EventKind {
    Brush(Brush),
    StrokeBegin,
    Sample(Sample),
    StrokeEnd,
    Camera(Camera),
    Render(String),
    Snapshot(String),
    Undo,
    Redo,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// 1-based line of the event in the file.
    pub line: usize,
    pub t: f64,
    pub kind: EventKind,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    pub canvas: Canvas,
    pub meta: Json,
    pub events: Vec<Event>,
    pub warnings: Vec<String>,
}

type R<T> = Result<T, TraceError>;

fn fail(line: usize, field: &str, msg: impl AsRef<str>) -> TraceError {
    TraceError(format!("line {line}: {field}: {}", msg.as_ref()))
}

/// Python's float(int): correctly rounded, None where it would overflow.
fn int_to_f64(i: &BigInt) -> Option<f64> {
    let x: f64 = i.to_string().parse().ok()?;
    x.is_finite().then_some(x)
}

fn finite(line: usize, field: &str, v: &Json) -> R<f64> {
    let x = match v {
        Json::Int(i) => int_to_f64(i).ok_or_else(|| fail(line, field, "not a finite number"))?,
        Json::Float(x) => *x,
        other => return Err(fail(line, field, format!("expected a number, got {}", other.dumps()))),
    };
    if !x.is_finite() {
        return Err(fail(line, field, "not a finite number"));
    }
    Ok(if x.abs() < TINY { 0.0 } else { x })
}

fn int(line: usize, field: &str, v: &Json, lo: i64, hi: i64) -> R<i64> {
    let i = match v {
        Json::Int(i) => i.clone(),
        Json::Float(x) => {
            if !x.is_finite() || *x != x.floor() {
                return Err(fail(line, field, format!("expected an integer, got {}", repr(*x))));
            }
            BigInt::from_f64(*x).expect("a finite integral f64 is an integer")
        }
        other => return Err(fail(line, field, format!("expected an integer, got {}", other.dumps()))),
    };
    match i.to_i64() {
        Some(k) if lo <= k && k <= hi => Ok(k),
        _ => Err(fail(line, field, format!("{i} is outside [{lo}, {hi}]"))),
    }
}

fn ranged(line: usize, field: &str, v: &Json, lo: f64, hi: f64) -> R<f64> {
    let x = finite(line, field, v)?;
    if !(lo <= x && x <= hi) {
        return Err(fail(line, field, format!("{} is outside [{}, {}]", repr(x), repr(lo), repr(hi))));
    }
    Ok(x)
}

fn vec_of<'a>(line: usize, field: &str, v: &'a Json, n: usize) -> R<&'a [Json]> {
    match v {
        Json::Array(items) if items.len() == n => Ok(items),
        _ => Err(fail(line, field, format!("expected an array of {n} numbers"))),
    }
}

fn vec_finite<const N: usize>(line: usize, field: &str, v: &Json) -> R<[f64; N]> {
    let items = vec_of(line, field, v, N)?;
    let mut out = [0.0; N];
    for (i, x) in items.iter().enumerate() {
        out[i] = finite(line, &format!("{field}[{i}]"), x)?;
    }
    Ok(out)
}

fn vec_ranged<const N: usize>(line: usize, field: &str, v: &Json, lo: f64, hi: f64) -> R<[f64; N]> {
    let items = vec_of(line, field, v, N)?;
    let mut out = [0.0; N];
    for (i, x) in items.iter().enumerate() {
        out[i] = ranged(line, &format!("{field}[{i}]"), x, lo, hi)?;
    }
    Ok(out)
}

fn quat(line: usize, field: &str, v: &Json) -> R<[f64; 4]> {
    let q: [f64; 4] = vec_finite(line, field, v)?;
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if !n2.is_finite() || n2.sqrt() < 1e-12 {
        return Err(fail(line, field, "zero or non-finite quaternion"));
    }
    Ok(q)
}

fn require<'a>(line: usize, obj: &'a Json, key: &str, prefix: &str) -> R<&'a Json> {
    obj.get(key).ok_or_else(|| fail(line, &format!("{prefix}{key}"), "missing"))
}

/// `[A-Za-z0-9._-]+`, not `.` or `..`.
pub fn is_valid_name(s: &str) -> bool {
    !s.is_empty() && s != "." && s != ".." && s.chars().all(|c| c.is_ascii_alphanumeric() || "._-".contains(c))
}

fn name(line: usize, v: &Json) -> R<String> {
    if let Json::Str(s) = v {
        if let Some(text) = s.to_string_opt() {
            if is_valid_name(&text) {
                return Ok(text);
            }
        }
    }
    Err(fail(line, "name", format!("{} is not a name of [A-Za-z0-9._-]+ (no paths)", v.dumps())))
}

fn one_of<T: Copy>(line: usize, field: &str, v: &Json, names: &[&str], values: &[T]) -> R<T> {
    if let Json::Str(s) = v {
        if let Some(i) = names.iter().position(|n| s.is(n)) {
            return Ok(values[i]);
        }
    }
    Err(fail(line, field, format!("{} is not one of {}", v.dumps(), names.join(", "))))
}

pub fn parse_canvas(line: usize, obj: &Json) -> R<Canvas> {
    if !matches!(obj, Json::Object(_)) {
        return Err(fail(line, "canvas", "expected an object"));
    }
    let roots_v = vec_of(line, "canvas.roots", require(line, obj, "roots", "canvas.")?, 3)?;
    let mut roots = [0u32; 3];
    for (i, x) in roots_v.iter().enumerate() {
        roots[i] = int(line, &format!("canvas.roots[{i}]"), x, 1, 1 << 16)? as u32;
    }
    let max_depth = int(line, "canvas.max_depth", require(line, obj, "max_depth", "canvas.")?, 0, MAX_DEPTH_LIMIT)?;
    for (i, &r) in roots.iter().enumerate() {
        if (u64::from(r) << max_depth) > 1 << 32 {
            return Err(fail(
                line,
                &format!("canvas.roots[{i}]"),
                format!("{r} roots of depth {max_depth} exceed the u32 lattice"),
            ));
        }
    }
    let root_size = finite(line, "canvas.root_size", require(line, obj, "root_size", "canvas.")?)?;
    if !(1e-9..=1e12).contains(&root_size) {
        return Err(fail(line, "canvas.root_size", format!("{} is outside [1e-09, 1e+12]", repr(root_size))));
    }
    let n_roots = roots.iter().map(|&r| u64::from(r)).product::<u64>();
    if n_roots > MAX_ROOTS {
        return Err(fail(line, "canvas.roots", format!("{n_roots} roots are more than the {MAX_ROOTS} allowed")));
    }
    let padded = n_roots.div_ceil(8) * 8;
    let capacity = int(line, "canvas.capacity", require(line, obj, "capacity", "canvas.")?, 8, MAX_CAPACITY)?;
    if (capacity as u64) < padded {
        return Err(fail(line, "canvas.capacity", format!("{capacity} is below the {padded} cells the roots need")));
    }
    Ok(Canvas { roots, max_depth: max_depth as u32, root_size, capacity: capacity as u32 })
}

pub fn parse_brush(line: usize, obj: &Json) -> R<Brush> {
    use Mode::*;
    use Shape::*;
    let shape = one_of(line, "shape", require(line, obj, "shape", "")?, &SHAPES, &[Sphere, Cylinder, Box, Cone, Noise])?;
    let mode = one_of(line, "mode", require(line, obj, "mode", "")?, &MODES, &[Paint, Erase, Recolor, Mix, Pickup])?;
    let radius = finite(line, "radius", require(line, obj, "radius", "")?)?;
    if radius <= 0.0 {
        return Err(fail(line, "radius", format!("{} must be > 0", repr(radius))));
    }
    let color = vec_ranged::<3>(line, "color", require(line, obj, "color", "")?, 0.0, 1.0)?;
    let opacity = ranged(line, "opacity", require(line, obj, "opacity", "")?, 0.0, 1.0)?;
    let hardness = ranged(line, "hardness", require(line, obj, "hardness", "")?, 0.0, 1.0)?;
    let mut b = self::Brush::new(shape, mode, radius, color, opacity, hardness);
    if let Some(v) = obj.get("spacing") {
        b.spacing = ranged(line, "spacing", v, SPACING_RANGE.0, SPACING_RANGE.1)?;
    }
    if let Some(v) = obj.get("mix_ratio") {
        b.mix_ratio = ranged(line, "mix_ratio", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("pickup_rate") {
        b.pickup_rate = ranged(line, "pickup_rate", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("aspect") {
        b.aspect = vec_ranged::<3>(line, "aspect", v, ASPECT_RANGE.0, ASPECT_RANGE.1)?;
    }
    if let Some(n) = obj.get("noise") {
        if !matches!(n, Json::Object(_)) {
            return Err(fail(line, "noise", "expected an object"));
        }
        if let Some(v) = n.get("frequency") {
            let f = finite(line, "noise.frequency", v)?;
            if !(0.0 < f && f <= NOISE_FREQUENCY_MAX) {
                return Err(fail(line, "noise.frequency", format!("{} is outside (0, 1e+06]", repr(f))));
            }
            b.noise.frequency = f;
        }
        if let Some(v) = n.get("octaves") {
            b.noise.octaves = int(line, "noise.octaves", v, 1, 8)? as u32;
        }
        if let Some(v) = n.get("seed") {
            b.noise.seed = int(line, "noise.seed", v, 0, 0xFFFF_FFFF)? as u32;
        }
        if let Some(v) = n.get("gain") {
            b.noise.gain = ranged(line, "noise.gain", v, 0.0, 1.0)?;
        }
    }
    Ok(b)
}

pub fn parse_sample(line: usize, obj: &Json) -> R<Sample> {
    let mut s = Sample::at(vec_finite::<3>(line, "p", require(line, obj, "p", "")?)?);
    if let Some(v) = obj.get("pressure") {
        s.pressure = ranged(line, "pressure", v, 0.0, 1.0)?;
    }
    if let Some(v) = obj.get("q") {
        s.q = quat(line, "q", v)?;
    }
    Ok(s)
}

pub fn parse_camera(line: usize, obj: &Json) -> R<Camera> {
    let eye = vec_finite::<3>(line, "eye", require(line, obj, "eye", "")?)?;
    let q = quat(line, "q", require(line, obj, "q", "")?)?;
    let fov = vec_finite::<4>(line, "fov", require(line, obj, "fov", "")?)?;
    let half_pi = std::f64::consts::FRAC_PI_2;
    for (i, &a) in fov.iter().enumerate() {
        if !(-half_pi < a && a < half_pi) {
            return Err(fail(line, &format!("fov[{i}]"), format!("{} is outside (-pi/2, pi/2)", repr(a))));
        }
    }
    let [left, right, up, down] = fov;
    if !(left < right) {
        return Err(fail(line, "fov", "angles not ordered: left must be < right"));
    }
    if !(down < up) {
        return Err(fail(line, "fov", "angles not ordered: down must be < up"));
    }
    let size_v = vec_of(line, "size", require(line, obj, "size", "")?, 2)?;
    let mut size = [0u32; 2];
    for (i, x) in size_v.iter().enumerate() {
        size[i] = int(line, &format!("size[{i}]"), x, 1, MAX_IMAGE_SIZE)? as u32;
    }
    let mut background = [0.0; 3];
    if let Some(v) = obj.get("background") {
        background = vec_ranged::<3>(line, "background", v, 0.0, 1.0)?;
    }
    Ok(Camera { eye, q, fov, size, background })
}

/// Whether the segment between samples `a` and `b` would place more than
/// 65,536 stamps (spec 8.4): `floor(L / (spacing·r_min)) + 1` with
/// `r_min` the smaller pressure's radius; a zero-length segment places
/// none, and a quotient that overflows counts as too many.
pub fn segment_too_long(brush: &Brush, a: &Sample, b: &Sample) -> bool {
    if brush.shape == Shape::Sphere {
        return false;
    }
    let d = [b.p[0] - a.p[0], b.p[1] - a.p[1], b.p[2] - a.p[2]];
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if length == 0.0 {
        return false;
    }
    let r_min = brush.radius * (0.25 + 0.75 * a.pressure.min(b.pressure));
    let quotient = length / (brush.spacing * r_min);
    !quotient.is_finite() || quotient.floor() + 1.0 > MAX_STAMPS_PER_SEGMENT
}

/// Python's `str.isspace` (what `str.strip()` removes).
fn py_isspace(c: char) -> bool {
    matches!(c, '\t'..='\r' | '\x1c'..='\x1f' | ' ' | '\u{85}' | '\u{a0}' | '\u{1680}' | '\u{2000}'..='\u{200a}'
        | '\u{2028}' | '\u{2029}' | '\u{202f}' | '\u{205f}' | '\u{3000}')
}

/// Parse and validate a whole trace (already decoded text).
pub fn parse_trace(text: &str) -> R<Trace> {
    let mut header: Option<(Canvas, Json)> = None;
    let mut events: Vec<Event> = Vec::new();
    let mut brush: Option<Brush> = None;
    let mut in_stroke = false;
    let mut stroke_begin_line = 0;
    let mut last_sample: Option<Sample> = None;
    let mut last_t = 0.0f64;
    let mut done = 0usize; // strokes that can be undone
    let mut undone = 0usize;
    let mut seen_camera = false;
    let mut render_names = std::collections::HashSet::new();
    let mut snapshot_names = std::collections::HashSet::new();
    let mut n_lines = 0;
    for (i, raw) in text.split('\n').enumerate() {
        let lineno = i + 1;
        n_lines = lineno;
        if raw.chars().all(py_isspace) {
            continue;
        }
        let obj = match json::loads(raw) {
            Ok(v) => v,
            Err(ParseFailure::Syntax(e)) => {
                return Err(TraceError(format!("line {lineno}: not valid JSON: {} (column {})", e.msg, e.pos + 1)));
            }
            Err(ParseFailure::Limit(msg)) => return Err(TraceError(format!("line {lineno}: not valid JSON: {msg}"))),
        };
        if !matches!(obj, Json::Object(_)) {
            return Err(TraceError(format!("line {lineno}: expected a JSON object")));
        }
        if header.is_none() {
            if !matches!(obj.get("format"), Some(Json::Str(s)) if s.is("ddo-trace")) {
                return Err(fail(lineno, "format", "the first line must be a header with \"format\": \"ddo-trace\""));
            }
            let version = obj.get("version").ok_or_else(|| fail(lineno, "version", "missing"))?;
            let is_one = match version {
                Json::Int(i) => *i == BigInt::from(1),
                Json::Float(x) => *x == 1.0,
                _ => false,
            };
            if !is_one {
                return Err(fail(
                    lineno,
                    "version",
                    format!("{} is not supported (this reader knows version 1)", version.dumps()),
                ));
            }
            let canvas = parse_canvas(lineno, require(lineno, &obj, "canvas", "")?)?;
            let meta = obj.get("meta").cloned().unwrap_or(Json::Object(Vec::new()));
            if !matches!(meta, Json::Object(_)) {
                return Err(fail(lineno, "meta", "expected an object"));
            }
            header = Some((canvas, meta));
            continue;
        }
        let ev = require(lineno, &obj, "ev", "")?;
        let ev_name = match ev {
            Json::Str(s) => s.clone(),
            other => return Err(fail(lineno, "ev", format!("expected a string, got {}", other.dumps()))),
        };
        let t = finite(lineno, "t", require(lineno, &obj, "t", "")?)?;
        if t < 0.0 {
            return Err(fail(lineno, "t", format!("{} must be >= 0", repr(t))));
        }
        if t < last_t {
            return Err(fail(lineno, "t", format!("{} is earlier than the previous event's {}", repr(t), repr(last_t))));
        }
        last_t = t;
        let kind = match ev_name.to_string_opt().as_deref() {
            Some("brush") => {
                if in_stroke {
                    return Err(fail(lineno, "ev", "brush inside a stroke (brushes change between strokes)"));
                }
                let b = parse_brush(lineno, &obj)?;
                brush = Some(b);
                EventKind::Brush(b)
            }
            Some("stroke_begin") => {
                if in_stroke {
                    return Err(fail(lineno, "ev", format!("stroke_begin inside the stroke begun on line {stroke_begin_line}")));
                }
                if brush.is_none() {
                    return Err(fail(lineno, "ev", "stroke_begin before any brush event"));
                }
                in_stroke = true;
                stroke_begin_line = lineno;
                last_sample = None;
                EventKind::StrokeBegin
            }
            Some("sample") => {
                if !in_stroke {
                    return Err(fail(lineno, "ev", "sample outside a stroke"));
                }
                let s = parse_sample(lineno, &obj)?;
                let b = brush.as_ref().expect("a stroke always has a brush");
                if let Some(prev) = &last_sample {
                    if segment_too_long(b, prev, &s) {
                        return Err(fail(
                            lineno,
                            "p",
                            "this segment would place more than 65536 stamps (samples too far apart for the brush radius and spacing)",
                        ));
                    }
                }
                last_sample = Some(s);
                EventKind::Sample(s)
            }
            Some("stroke_end") => {
                if !in_stroke {
                    return Err(fail(lineno, "ev", "stroke_end outside a stroke"));
                }
                in_stroke = false;
                done += 1;
                undone = 0;
                EventKind::StrokeEnd
            }
            Some("camera") => {
                seen_camera = true;
                EventKind::Camera(parse_camera(lineno, &obj)?)
            }
            Some(kind @ ("render" | "snapshot")) => {
                let n = name(lineno, require(lineno, &obj, "name", "")?)?;
                let names = if kind == "render" { &mut render_names } else { &mut snapshot_names };
                if !names.insert(n.clone()) {
                    return Err(fail(lineno, "name", format!("\"{n}\" is already used by an earlier {kind}")));
                }
                if kind == "render" {
                    if !seen_camera {
                        return Err(fail(lineno, "ev", "render before any camera event"));
                    }
                    EventKind::Render(n)
                } else {
                    EventKind::Snapshot(n)
                }
            }
            Some(kind @ ("undo" | "redo")) => {
                if in_stroke {
                    return Err(fail(lineno, "ev", format!("{kind} inside a stroke")));
                }
                if kind == "undo" {
                    if done == 0 {
                        return Err(fail(lineno, "ev", "undo with no stroke to undo"));
                    }
                    done -= 1;
                    undone += 1;
                    EventKind::Undo
                } else {
                    if undone == 0 {
                        return Err(fail(lineno, "ev", "redo with nothing undone"));
                    }
                    undone -= 1;
                    done += 1;
                    EventKind::Redo
                }
            }
            _ => return Err(fail(lineno, "ev", format!("unknown event {}", ev.dumps()))),
        };
        events.push(Event { line: lineno, t, kind });
    }
    let Some((canvas, meta)) = header else {
        return Err(TraceError("line 1: format: empty trace (a header line is required)".into()));
    };
    let mut warnings = Vec::new();
    if in_stroke {
        warnings.push(format!("line {stroke_begin_line}: the trace ends inside this stroke; it is ended here"));
        events.push(Event { line: n_lines, t: last_t, kind: EventKind::StrokeEnd });
    }
    Ok(Trace { canvas, meta, events, warnings })
}

/// Decode bytes as UTF-8 (naming the line of the first bad byte) and parse.
pub fn parse_trace_bytes(data: &[u8]) -> R<Trace> {
    match std::str::from_utf8(data) {
        Ok(text) => parse_trace(text),
        Err(e) => {
            let line = data[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
            Err(TraceError(format!("line {line}: not valid UTF-8")))
        }
    }
}

/// Read and parse a trace file.
pub fn read_trace(path: &std::path::Path) -> R<Trace> {
    let data = std::fs::read(path).map_err(|e| TraceError(format!("cannot read {}: {}", path.display(), io_reason(&e))))?;
    parse_trace_bytes(&data)
}

/// An I/O error's reason without Rust's "(os error N)" suffix, as Python's
/// strerror reads.
pub fn io_reason(e: &std::io::Error) -> String {
    let s = e.to_string();
    match s.find(" (os error") {
        Some(i) => s[..i].to_string(),
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_malformed_trace_gives_its_expected_message() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces/malformed");
        let expected = std::fs::read_to_string(dir.join("expected.json")).unwrap();
        let Json::Object(pairs) = json::loads(&expected.replace('\n', " ")).unwrap() else { panic!() };
        assert!(pairs.len() >= 40);
        for (file, msg) in pairs {
            let file = file.to_string_opt().unwrap();
            let Json::Str(msg) = msg else { panic!() };
            let got = read_trace(&dir.join(&file)).expect_err(&file);
            assert_eq!(got.0, msg.to_string_opt().unwrap(), "{file}");
        }
    }

    #[test]
    fn every_checked_in_trace_reads() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "jsonl") {
                let t = read_trace(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!t.events.is_empty());
                n += 1;
            }
        }
        assert!(n >= 6);
    }

    #[test]
    fn numbers_follow_python() {
        let header = r#"{"format": "ddo-trace", "version": 1.0, "canvas": {"roots": [1, 1, 1], "max_depth": 4.0, "root_size": 1, "capacity": 64}}"#;
        let t = parse_trace(header).unwrap();
        assert_eq!(t.canvas.max_depth, 4);
        let bad = header.replace("\"max_depth\": 4.0", "\"max_depth\": 1e300");
        let e = parse_trace(&bad).unwrap_err().0;
        assert!(e.starts_with("line 1: canvas.max_depth: 1000000000000000052504760255204420248704468581108159154915854115511802457988908195786371375080447864043704443832883878176942523235360430575644792184786706982848387200926575803737830233794788090059368953234970799945081119038967640880074652742780142494579258788820056842838115669472196386865459400540160 is outside [0, 28]"), "{e}");
        let bad = header.replace("\"max_depth\": 4.0", "\"max_depth\": 4.5");
        assert_eq!(parse_trace(&bad).unwrap_err().0, "line 1: canvas.max_depth: expected an integer, got 4.5");
        let bad = header.replace("\"version\": 1.0", "\"version\": true");
        assert_eq!(parse_trace(&bad).unwrap_err().0, "line 1: version: true is not supported (this reader knows version 1)");
    }

    #[test]
    fn subnormal_numbers_read_as_zero() {
        let text = concat!(
            r#"{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 4, "root_size": 1, "capacity": 64}}"#,
            "\n",
            r#"{"ev": "camera", "t": -1e-310, "eye": [1e-320, -0.0, 0.5], "q": [0, 0, 0, 1], "fov": [-0.5, 0.5, 0.5, -0.5], "size": [4, 4]}"#
        );
        let t = parse_trace(text).unwrap();
        let EventKind::Camera(c) = &t.events[0].kind else { panic!() };
        assert_eq!(t.events[0].t.to_bits(), 0);
        assert_eq!(c.eye[0].to_bits(), 0);
        assert_eq!(c.eye[1].to_bits(), 0);
    }

    #[test]
    fn names_are_plain() {
        assert!(is_valid_name("a.b-c_9"));
        for bad in ["", ".", "..", "a/b", "a\n", "a b", "é"] {
            assert!(!is_valid_name(bad), "{bad:?}");
        }
    }

    #[test]
    fn overflowing_segments_are_refused_not_crashed() {
        let b = Brush::new(Shape::Box, Mode::Paint, 1e-300, [0.0; 3], 1.0, 0.5);
        assert!(segment_too_long(&b, &Sample::at([1e300, 0.0, 0.0]), &Sample::at([-1e300, 0.0, 0.0])));
        assert!(!segment_too_long(&b, &Sample::at([1.0, 0.0, 0.0]), &Sample::at([1.0, 0.0, 0.0])));
    }
}
