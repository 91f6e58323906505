//! Reading a whole trace (spec 12.2): bytes to lines, each line to JSON by
//! serde_json under the spec's rules, the header, and the order of the
//! events. Nothing runs until the whole trace has passed.

use std::collections::HashSet;

use serde_json::Value;

use octopaint_model::layer_rules::Model;
use octopaint_model::{Brush, Canvas, Event, EventKind, Import, LayerOpKind, Meta, Sample, Trace, VoxelSet};

use crate::error::{ErrorKind, TraceError};
use crate::fields::{
    fail, finite, name, parse_brush, parse_camera, parse_canvas, parse_import_fields, parse_layer, parse_light, parse_mirror, parse_sample, require,
    segment_too_long, shown,
};

/// Deepest bracket nesting a trace line may have; below serde_json's own
/// limit (128), so the two readers refuse deep lines by the same rule.
pub const MAX_NESTING: usize = 64;

type R<T> = Result<T, TraceError>;

/// How a reader finds the files of `import` events (spec 15.2): given the
/// trace's `file`, its bytes.
pub type Resolve<'a> = &'a dyn Fn(&str) -> std::io::Result<Vec<u8>>;

/// Imports resolved against a folder (the trace's own).
pub fn folder_resolver(folder: &std::path::Path) -> impl Fn(&str) -> std::io::Result<Vec<u8>> + use<> {
    let folder = folder.to_path_buf();
    move |file: &str| std::fs::read(file.split('/').fold(folder.clone(), |p, part| p.join(part)))
}

/// The deepest `[`/`{` nesting of a line, counted outside strings (a `"`
/// opens or closes a string unless an odd run of backslashes precedes it
/// inside one). Unbalanced closers may drive the count below zero. On a
/// line that parses, this is the JSON nesting; on one that does not, no
/// parser can have gone deeper before stopping.
pub fn nesting_depth(line: &str) -> usize {
    // Bytes, not characters: the marks are ASCII, and no byte of a UTF-8
    // multi-byte character is. (An escape's backslash skips one byte where
    // it would skip one character; what it skips matters only when it is
    // `"` or `\\`, both ASCII.)
    let mut depth: i64 = 0;
    let mut deepest: i64 = 0;
    let mut in_string = false;
    let mut escaped = false;
    for &c in line.as_bytes() {
        if in_string {
            if escaped {
                escaped = false;
            } else if c == b'\\' {
                escaped = true;
            } else if c == b'"' {
                in_string = false;
            }
            continue;
        }
        match c {
            b'"' => in_string = true,
            b'[' | b'{' => {
                depth += 1;
                deepest = deepest.max(depth);
            }
            b']' | b'}' => depth -= 1,
            _ => {}
        }
    }
    deepest.max(0) as usize
}

/// One line as JSON (spec 12.2): RFC 8259 (no `NaN`/`Infinity`, no
/// unpaired surrogate escapes, no byte-order mark), a number literal beyond
/// f64's range refused, a repeated key keeping its last value.
fn json_line(lineno: usize, raw: &str) -> R<Value> {
    if nesting_depth(raw) > MAX_NESTING {
        return Err(TraceError::new(lineno, ErrorKind::Json, format!("not valid JSON: brackets nested deeper than {MAX_NESTING} levels")));
    }
    serde_json::from_str(raw).map_err(|e| TraceError::new(lineno, ErrorKind::Json, format!("not valid JSON: {e}")))
}

/// Python's `str.isspace`: a line holding only these is blank (spec 12.2).
fn is_blank_char(c: char) -> bool {
    matches!(c, '\t'..='\r' | '\x1c'..='\x1f' | ' ' | '\u{85}' | '\u{a0}' | '\u{1680}' | '\u{2000}'..='\u{200a}'
        | '\u{2028}' | '\u{2029}' | '\u{202f}' | '\u{205f}' | '\u{3000}')
}

/// The header line: format, version, canvas, meta.
fn header(lineno: usize, obj: &Value) -> R<(Canvas, Meta, u32)> {
    if obj.get("format").and_then(Value::as_str) != Some("ddo-trace") {
        return Err(fail(lineno, "format", ErrorKind::Header, "the first line must be a header with \"format\": \"ddo-trace\""));
    }
    let v = require(lineno, obj, "version", "")?;
    let version = match v.as_f64() {
        Some(1.0) => 1,
        Some(2.0) => 2,
        _ => {
            let msg = format!("{} is not supported (this reader knows versions 1 and 2)", shown(v));
            return Err(fail(lineno, "version", ErrorKind::Header, msg));
        }
    };
    let canvas = parse_canvas(lineno, require(lineno, obj, "canvas", "")?)?;
    let meta = match obj.get("meta") {
        None => Meta::new(),
        Some(Value::Object(m)) => m.clone(),
        Some(_) => return Err(fail(lineno, "meta", ErrorKind::Type, "expected an object")),
    };
    Ok((canvas, meta, version))
}

/// What the order rules need to know of the events so far.
#[derive(Default)]
struct Order<'a> {
    canvas: Option<Canvas>,
    resolve: Option<Resolve<'a>>,
    brush: Option<Brush>,
    in_stroke: bool,
    stroke_begin_line: usize,
    last_sample: Option<Sample>,
    last_t: f64,
    /// The undo stack as a model (spec 12.2, 14.2): a step is None (a
    /// stroke) or the layers before and after a layer event.
    done: Vec<Option<Box<(Model, Model)>>>,
    undone: Vec<Option<Box<(Model, Model)>>>,
    layers: Model,
    version: u32,
    seen_camera: bool,
    render_names: HashSet<String>,
    snapshot_names: HashSet<String>,
}

impl Order<'_> {
    /// One event line (after the header): `ev`, `t`, then the kind's fields
    /// and its place among the events.
    fn event(&mut self, lineno: usize, obj: &Value) -> R<Event> {
        let order = |msg: &str| fail(lineno, "ev", ErrorKind::EventOrder, msg);
        let ev = require(lineno, obj, "ev", "")?;
        let Value::String(ev_name) = ev else {
            return Err(fail(lineno, "ev", ErrorKind::Type, format!("expected a string, got {}", shown(ev))));
        };
        let t = finite(lineno, "t", require(lineno, obj, "t", "")?)?;
        if t < 0.0 {
            return Err(fail(lineno, "t", ErrorKind::Range, format!("{t:?} must be >= 0")));
        }
        if t < self.last_t {
            let msg = format!("{t:?} is earlier than the previous event's {:?}", self.last_t);
            return Err(fail(lineno, "t", ErrorKind::EventOrder, msg));
        }
        self.last_t = t;
        let kind = match ev_name.as_str() {
            "brush" => {
                if self.in_stroke {
                    return Err(order("brush inside a stroke (brushes change between strokes)"));
                }
                let b = parse_brush(lineno, obj)?;
                self.brush = Some(b);
                EventKind::Brush(b)
            }
            "stroke_begin" => {
                if self.in_stroke {
                    return Err(order(&format!("stroke_begin inside the stroke begun on line {}", self.stroke_begin_line)));
                }
                if self.brush.is_none() {
                    return Err(order("stroke_begin before any brush event"));
                }
                if self.layers.selected_locked() {
                    let msg = format!("the selected layer {:?} is locked", self.layers.names[self.layers.selected]);
                    return Err(fail(lineno, "ev", ErrorKind::Layer, msg));
                }
                self.in_stroke = true;
                self.stroke_begin_line = lineno;
                self.last_sample = None;
                EventKind::StrokeBegin
            }
            "sample" => {
                if !self.in_stroke {
                    return Err(order("sample outside a stroke"));
                }
                let s = parse_sample(lineno, obj)?;
                let b = self.brush.as_ref().expect("a stroke always has a brush");
                if let Some(prev) = &self.last_sample
                    && segment_too_long(b, prev, &s)
                {
                    return Err(fail(
                        lineno,
                        "p",
                        ErrorKind::Budget,
                        "this segment would place more than 65536 stamps (samples too far apart for the brush radius and spacing)",
                    ));
                }
                self.last_sample = Some(s);
                EventKind::Sample(s)
            }
            "stroke_end" => {
                if !self.in_stroke {
                    return Err(order("stroke_end outside a stroke"));
                }
                self.in_stroke = false;
                self.done.push(None);
                self.undone.clear();
                EventKind::StrokeEnd
            }
            "camera" => {
                self.seen_camera = true;
                EventKind::Camera(parse_camera(lineno, obj)?)
            }
            "light" => EventKind::Light(parse_light(lineno, obj)?),
            "mirror" => {
                if self.in_stroke {
                    return Err(order("mirror inside a stroke (mirror planes change between strokes)"));
                }
                EventKind::Mirror(parse_mirror(lineno, obj)?)
            }
            kind @ ("render" | "snapshot") => {
                let n = name(lineno, require(lineno, obj, "name", "")?)?;
                let names = if kind == "render" { &mut self.render_names } else { &mut self.snapshot_names };
                if !names.insert(n.clone()) {
                    return Err(fail(lineno, "name", ErrorKind::Name, format!("\"{n}\" is already used by an earlier {kind}")));
                }
                if kind == "render" {
                    if !self.seen_camera {
                        return Err(order("render before any camera event"));
                    }
                    EventKind::Render(n)
                } else {
                    EventKind::Snapshot(n)
                }
            }
            kind @ ("undo" | "redo") => {
                if self.in_stroke {
                    return Err(order(&format!("{kind} inside a stroke")));
                }
                if kind == "undo" {
                    let Some(step) = self.done.pop() else {
                        return Err(order("undo with no stroke to undo"));
                    };
                    if let Some(b) = &step {
                        self.layers = b.0.clone();
                    }
                    self.undone.push(step);
                    EventKind::Undo
                } else {
                    let Some(step) = self.undone.pop() else {
                        return Err(order("redo with nothing undone"));
                    };
                    if let Some(b) = &step {
                        self.layers = b.1.clone();
                    }
                    self.done.push(step);
                    EventKind::Redo
                }
            }
            "import" => {
                if self.in_stroke {
                    return Err(order("import inside a stroke (imports come between strokes)"));
                }
                let (file, sha256, label) = parse_import_fields(lineno, obj)?;
                if self.layers.selected_locked() {
                    let msg = format!("the selected layer {:?} is locked", self.layers.names[self.layers.selected]);
                    return Err(fail(lineno, "ev", ErrorKind::Layer, msg));
                }
                let voxels = self.read_import(lineno, &file, &sha256)?;
                self.done.push(None);
                self.undone.clear();
                EventKind::Import(Box::new(Import { file, sha256, name: label, voxels: std::sync::Arc::new(voxels) }))
            }
            "layer" if self.version == 2 => {
                if self.in_stroke {
                    return Err(order("layer inside a stroke (layers change between strokes)"));
                }
                let op = parse_layer(lineno, obj)?;
                if let Some(why) = self.layers.check(&op) {
                    return Err(TraceError::new(lineno, ErrorKind::Layer, why));
                }
                let after = self.layers.apply(&op);
                if op.op != LayerOpKind::Select {
                    self.done.push(Some(Box::new((self.layers.clone(), after.clone()))));
                    self.undone.clear();
                }
                self.layers = after;
                EventKind::Layer(op)
            }
            _ => return Err(fail(lineno, "ev", ErrorKind::Event, format!("unknown event {}", shown(ev)))),
        };
        Ok(Event { line: lineno, t, kind })
    }
}

impl Order<'_> {
    /// The voxel set of an `import` event (spec 15.2): read through the
    /// resolver, its digest checked, then its content for this canvas.
    fn read_import(&self, lineno: usize, file: &str, sha256: &str) -> R<VoxelSet> {
        let import = |field: &str, msg: String| fail(lineno, field, ErrorKind::Import, msg);
        let Some(resolve) = self.resolve else {
            return Err(import("file", "this trace was not read from a folder, so its imports cannot be found".into()));
        };
        // The reason in words of our own for the common cases, so that the
        // message is the same on every system (Windows says "File not found.").
        let reason = |e: &std::io::Error| match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            std::io::ErrorKind::PermissionDenied => "permission denied".to_string(),
            _ => io_reason(e),
        };
        let data = resolve(file).map_err(|e| import("file", format!("cannot read {file}: {}", reason(&e))))?;
        let got = crate::voxels::sha256_hex(&data);
        if got != sha256 {
            return Err(import("sha256", format!("{file} has SHA-256 {got}, not the {sha256} the trace names (the file changed)")));
        }
        let canvas = self.canvas.as_ref().expect("events come after the header");
        crate::voxels::parse_voxel_set(&data, canvas).map_err(|e| import("file", format!("{file} is not a voxel set for this canvas: {e}")))
    }
}

/// Parse and validate a whole trace (already decoded text). A trace with
/// `import` events needs [`parse_trace_with`] and a resolver.
pub fn parse_trace(text: &str) -> R<Trace> {
    parse_trace_with(text, None)
}

/// Parse and validate a whole trace, reading the files of its `import`
/// events through `resolve` (spec 15.2).
pub fn parse_trace_with(text: &str, resolve: Option<Resolve<'_>>) -> R<Trace> {
    let mut head = None;
    let mut events = Vec::new();
    let mut order = Order { resolve, ..Order::default() };
    let mut n_lines = 0;
    for (i, raw) in text.split('\n').enumerate() {
        let lineno = i + 1;
        n_lines = lineno;
        if raw.chars().all(is_blank_char) {
            continue;
        }
        let obj = json_line(lineno, raw)?;
        if !obj.is_object() {
            return Err(TraceError::new(lineno, ErrorKind::Type, "expected a JSON object"));
        }
        if head.is_none() {
            let h = header(lineno, &obj)?;
            order.version = h.2;
            order.canvas = Some(h.0);
            head = Some(h);
        } else {
            events.push(order.event(lineno, &obj)?);
        }
    }
    let Some((canvas, meta, version)) = head else {
        return Err(TraceError::new(1, ErrorKind::Header, "format: empty trace (a header line is required)"));
    };
    let mut warnings = Vec::new();
    if order.in_stroke {
        warnings.push(format!("line {}: the trace ends inside this stroke; it is ended here", order.stroke_begin_line));
        events.push(Event { line: n_lines, t: order.last_t, kind: EventKind::StrokeEnd });
    }
    Ok(Trace { canvas, meta, events, warnings, version })
}

/// Decode bytes as UTF-8 (naming the line of the first bad byte) and parse.
pub fn parse_trace_bytes(data: &[u8]) -> R<Trace> {
    parse_bytes_with(data, None)
}

fn parse_bytes_with(data: &[u8], resolve: Option<Resolve<'_>>) -> R<Trace> {
    match std::str::from_utf8(data) {
        Ok(text) => parse_trace_with(text, resolve),
        Err(e) => {
            let line = data[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
            Err(TraceError::new(line, ErrorKind::Utf8, "not valid UTF-8"))
        }
    }
}

/// Read and parse a trace file.
pub fn read_trace(path: &std::path::Path) -> R<Trace> {
    let data = std::fs::read(path).map_err(|e| TraceError::new(0, ErrorKind::Io, format!("cannot read {}: {}", path.display(), io_reason(&e))))?;
    let folder = path.parent().map(std::path::Path::to_path_buf).unwrap_or_default();
    let resolve = folder_resolver(if folder.as_os_str().is_empty() { std::path::Path::new(".") } else { &folder });
    parse_bytes_with(&data, Some(&resolve))
}

/// An I/O error's reason without Rust's "(os error N)" suffix.
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

    fn repo(rel: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(rel)
    }

    #[test]
    fn every_malformed_trace_is_refused_on_its_line_with_its_kind() {
        let dir = repo("traces/malformed");
        let expected: serde_json::Map<String, Value> = serde_json::from_slice(&std::fs::read(dir.join("expected.json")).unwrap()).unwrap();
        assert!(expected.len() >= 50);
        for (file, want) in expected {
            let got = read_trace(&dir.join(&file)).expect_err(&file);
            let kind = ErrorKind::from_code(want["kind"].as_str().unwrap()).unwrap();
            assert_eq!((got.line, got.kind), (want["line"].as_u64().unwrap() as usize, kind), "{file}: {got}");
            assert!(got.to_string().starts_with(&format!("line {}: ", got.line)), "{got}");
        }
    }

    #[test]
    fn every_checked_in_trace_reads() {
        let mut n = 0;
        for entry in std::fs::read_dir(repo("traces")).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "jsonl") {
                let t = read_trace(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert!(!t.events.is_empty());
                n += 1;
            }
        }
        assert!(n >= 6);
    }

    const HEADER: &str = r#"{"format": "ddo-trace", "version": 1.0, "canvas": {"roots": [1, 1, 1], "max_depth": 4.0, "root_size": 1, "capacity": 64}}"#;

    #[test]
    fn the_json_rules_of_the_spec() {
        let kind = |line: &str| parse_trace(&format!("{HEADER}\n{line}")).map(drop).map_err(|e| (e.line, e.kind));
        let json = Err((2, ErrorKind::Json));
        assert_eq!(kind(r#"{"ev": "undo", "t": NaN}"#), json);
        assert_eq!(kind(r#"{"ev": "undo", "t": -Infinity}"#), json);
        assert_eq!(kind(r#"{"ev": "undo", "t": 1.8e308}"#), json);
        assert_eq!(kind(&format!(r#"{{"ev": "undo", "t": 2{}}}"#, "0".repeat(308))), json);
        assert_eq!(kind(&format!(r#"{{"ev": "undo", "t": 1{}e99}}"#, "0".repeat(250))), json);
        assert_eq!(kind(r#"{"ev": "undo", "t": 1e0309}"#), json);
        assert_eq!(kind(r#"{"ev": "undo", "t": 0, "x": "\ud800"}"#), json);
        assert_eq!(kind(r#"{"ev": "undo", "t": 0, "\udfff": 0}"#), json);
        let deep = |n: usize| format!(r#"{{"ev": "undo", "t": 0, "x": {}{}}}"#, "[".repeat(n), "]".repeat(n));
        assert_eq!(kind(&deep(MAX_NESTING)), json);
        // One level less is JSON; the event is then refused for its order.
        assert_eq!(kind(&deep(MAX_NESTING - 1)), Err((2, ErrorKind::EventOrder)));
        // A paired surrogate escape, a repeated key (the last wins), a
        // number literal at f64's edge and one that underflows are fine.
        let cam = r#"{"ev": "camera", "t": 5, "t": 1e-400, "eye": [1.7976931348623157e308, 0, "\ud83d\ude00"], "q": [0, 0, 0, 1], "fov": [-0.5, 0.5, 0.5, -0.5], "size": [4, 4]}"#;
        assert_eq!(kind(cam), Err((2, ErrorKind::Type)), "eye[2] is a string");
        let cam = cam.replace(r#""\ud83d\ude00""#, "0");
        let t = parse_trace(&format!("{HEADER}\n{cam}")).unwrap();
        let EventKind::Camera(c) = &t.events[0].kind else { panic!() };
        assert_eq!((t.events[0].t, c.eye[0]), (0.0, f64::MAX));
    }

    #[test]
    fn numbers_read_as_the_spec_says() {
        let t = parse_trace(HEADER).unwrap();
        assert_eq!(t.canvas.max_depth, 4);
        let bad = |from: &str, to: &str| parse_trace(&HEADER.replace(from, to)).map(drop).map_err(|e| e.kind);
        assert_eq!(bad("\"max_depth\": 4.0", "\"max_depth\": 1e300"), Err(ErrorKind::Range));
        assert_eq!(bad("\"max_depth\": 4.0", "\"max_depth\": 4.5"), Err(ErrorKind::Type));
        assert_eq!(bad("\"version\": 1.0", "\"version\": true"), Err(ErrorKind::Header));
        assert_eq!(bad("\"version\": 1.0", "\"version\": 1.0000000000000001"), Ok(()));
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
    fn a_repeated_meta_key_keeps_its_last_value() {
        let h = HEADER.replace("}}", r#"}, "meta": {"b": 1, "a": 2, "b": 3}}"#);
        let t = parse_trace(&h).unwrap();
        assert_eq!(serde_json::to_string(&t.meta).unwrap(), r#"{"a":2,"b":3}"#);
    }
}
