//! Writing traces: a header and events as the JSON lines of spec 12,
//! written by serde_json (every number as the shortest text that reads back
//! to the same f64: serde_json formats floats with `zmij`, the successor of
//! `ryu`), so that what the painter records reads back,
//! here and in the reference, as exactly the events that were painted. The
//! tests parse every line back.

use serde_json::{Value, json};

use octopaint_model::{Brush, Canvas, Event, EventKind, Meta};

fn line(v: Value) -> String {
    serde_json::to_string(&v).expect("trace values are finite numbers, strings and arrays")
}

/// The first line of a trace (version 1: one tree).
pub fn header_line(canvas: &Canvas, meta: &Meta) -> String {
    header_line_version(canvas, meta, 1)
}

/// The first line of a trace of `version` (2: a document of layers, spec 14).
pub fn header_line_version(canvas: &Canvas, meta: &Meta, version: u32) -> String {
    line(json!({
        "format": "ddo-trace",
        "version": version,
        "canvas": {
            "roots": canvas.roots,
            "max_depth": canvas.max_depth,
            "root_size": canvas.root_size,
            "capacity": canvas.capacity,
        },
        "meta": meta,
    }))
}

/// A brush event's fields (spec 12) as a JSON object: what `parse_brush` reads back.
pub fn brush_fields(b: &Brush) -> Value {
    json!({
        "shape": b.shape.name(),
        "mode": b.mode.name(),
        "radius": b.radius,
        "color": b.color,
        "opacity": b.opacity,
        "hardness": b.hardness,
        "spacing": b.spacing,
        "mix_ratio": b.mix_ratio,
        "pickup_rate": b.pickup_rate,
        "aspect": b.aspect,
        "noise": {"frequency": b.noise.frequency, "octaves": b.noise.octaves, "seed": b.noise.seed, "gain": b.noise.gain},
    })
}

/// One event as a trace line (no newline). Names are valid by construction
/// (the reader checked them, or the painter made them).
pub fn event_line(ev: &Event) -> String {
    let mut obj = json!({"ev": ev.kind.ev(), "t": ev.t});
    let fields = match &ev.kind {
        EventKind::Brush(b) => brush_fields(b),
        EventKind::Sample(s) => json!({"p": s.p, "pressure": s.pressure, "q": s.q}),
        EventKind::Camera(c) => json!({"eye": c.eye, "q": c.q, "fov": c.fov, "size": c.size, "background": c.background}),
        EventKind::Light(l) if l.on => json!({"on": true, "dir": l.dir, "intensity": l.intensity, "ambient": l.ambient, "shadows": l.shadows}),
        EventKind::Light(_) => json!({"on": false}),
        EventKind::Mirror(m) => json!({"axes": m.axes, "centre": m.centre}),
        EventKind::Render(name) | EventKind::Snapshot(name) => json!({"name": name}),
        EventKind::StrokeBegin | EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo => json!({}),
        EventKind::Layer(op) => {
            let mut m = serde_json::Map::new();
            m.insert("op".into(), json!(op.op.code()));
            if let Some(l) = &op.layer {
                m.insert("layer".into(), json!(l));
            }
            if let Some(n) = &op.name {
                m.insert("name".into(), json!(n));
            }
            if let Some(to) = op.to {
                m.insert("to".into(), json!(to));
            }
            if let Some(v) = op.visible {
                m.insert("visible".into(), json!(v));
            }
            if let Some(o) = op.opacity {
                m.insert("opacity".into(), json!(f64::from(o)));
            }
            if let Some(k) = op.locked {
                m.insert("locked".into(), json!(k));
            }
            Value::Object(m)
        }
        EventKind::Import(imp) => match &imp.name {
            Some(n) => json!({"file": imp.file, "sha256": imp.sha256, "name": n}),
            None => json!({"file": imp.file, "sha256": imp.sha256}),
        },
    };
    let (Value::Object(head), Value::Object(rest)) = (&mut obj, fields) else { unreachable!("objects") };
    head.extend(rest);
    line(obj)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse_trace;

    #[test]
    fn every_event_of_every_trace_reads_back_the_same() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces");
        let mut seen = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_none_or(|e| e != "jsonl") {
                continue;
            }
            let trace = crate::read_trace(&path).unwrap();
            let mut text = header_line_version(&trace.canvas, &trace.meta, trace.version);
            for ev in &trace.events {
                text.push('\n');
                text.push_str(&event_line(ev));
            }
            let resolve = crate::folder_resolver(&dir);
            let again = crate::parse_trace_with(&text, Some(&resolve)).unwrap_or_else(|e| panic!("{}: {e}\n", path.display()));
            assert_eq!(again.canvas, trace.canvas);
            assert_eq!(again.version, trace.version);
            assert_eq!(again.meta, trace.meta);
            assert_eq!(again.events.len(), trace.events.len());
            for (a, b) in again.events.iter().zip(&trace.events) {
                assert_eq!(a.kind, b.kind, "{}", path.display());
                assert_eq!(a.t.to_bits(), b.t.to_bits());
            }
            seen += trace.events.len();
        }
        assert!(seen > 5000);
    }

    #[test]
    fn extreme_numbers_read_back_bit_for_bit() {
        let canvas = Canvas { roots: [1, 1, 1], max_depth: 4, root_size: 1.0, capacity: 64 };
        let xs = [f64::MAX, f64::MIN_POSITIVE, 0.1, 1e16, 1e-9, 123_456_789.123_456_79, -2.5e-300];
        let s = octopaint_model::Sample { p: [xs[0], xs[1], xs[2]], pressure: 0.3, q: [xs[3], xs[4], xs[5], xs[6]] };
        let b = Brush::new(octopaint_model::Shape::Sphere, octopaint_model::Mode::Paint, 0.1, [1.0, 0.0, 0.0], 1.0, 0.5);
        let events = [
            Event { line: 0, t: 0.0, kind: EventKind::Brush(b) },
            Event { line: 0, t: 0.0, kind: EventKind::StrokeBegin },
            Event { line: 0, t: 7.5e-5, kind: EventKind::Sample(s) },
        ];
        let mut text = header_line(&canvas, &Meta::new());
        for ev in &events {
            text.push('\n');
            text.push_str(&event_line(ev));
        }
        let t = parse_trace(&text).unwrap();
        assert_eq!(t.events[2].kind, EventKind::Sample(s));
        assert_eq!(t.events[2].t, 7.5e-5);
    }
}
