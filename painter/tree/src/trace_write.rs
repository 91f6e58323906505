//! Writing traces: a header and events as the JSON lines of spec 12, every
//! number in Python's shortest round-trip form, so that what the painter
//! records reads back (here and in the reference) as exactly the events
//! that were painted. The tests parse every line back.

use crate::json::Json;
use crate::pyrepr::py_float_repr as f;
use crate::trace::{Brush, Canvas, Event, EventKind, MODES, SHAPES};

/// A list of numbers as Python writes it: `[1.0, 0.5]`.
pub fn float_list(xs: &[f64]) -> String {
    format!("[{}]", xs.iter().map(|x| f(*x)).collect::<Vec<_>>().join(", "))
}

/// The first line of a trace.
pub fn header_line(canvas: &Canvas, meta: &Json) -> String {
    format!(
        "{{\"format\": \"ddo-trace\", \"version\": 1, \"canvas\": {{\"roots\": [{}, {}, {}], \"max_depth\": {}, \"root_size\": {}, \"capacity\": {}}}, \"meta\": {}}}",
        canvas.roots[0],
        canvas.roots[1],
        canvas.roots[2],
        canvas.max_depth,
        f(canvas.root_size),
        canvas.capacity,
        meta.dumps()
    )
}

fn brush_fields(b: &Brush) -> String {
    format!(
        "\"shape\": \"{}\", \"mode\": \"{}\", \"radius\": {}, \"color\": {}, \"opacity\": {}, \"hardness\": {}, \"spacing\": {}, \"mix_ratio\": {}, \"pickup_rate\": {}, \"aspect\": {}, \"noise\": {{\"frequency\": {}, \"octaves\": {}, \"seed\": {}, \"gain\": {}}}",
        SHAPES[b.shape as usize],
        MODES[b.mode as usize],
        f(b.radius),
        float_list(&b.color),
        f(b.opacity),
        f(b.hardness),
        f(b.spacing),
        f(b.mix_ratio),
        f(b.pickup_rate),
        float_list(&b.aspect),
        f(b.noise.frequency),
        b.noise.octaves,
        b.noise.seed,
        f(b.noise.gain)
    )
}

/// One event as a trace line (no newline). Names are valid by construction
/// (the reader checked them, or the painter made them).
pub fn event_line(ev: &Event) -> String {
    let t = f(ev.t);
    match &ev.kind {
        EventKind::Brush(b) => format!("{{\"ev\": \"brush\", \"t\": {t}, {}}}", brush_fields(b)),
        EventKind::StrokeBegin => format!("{{\"ev\": \"stroke_begin\", \"t\": {t}}}"),
        EventKind::Sample(s) => format!(
            "{{\"ev\": \"sample\", \"t\": {t}, \"p\": {}, \"pressure\": {}, \"q\": {}}}",
            float_list(&s.p),
            f(s.pressure),
            float_list(&s.q)
        ),
        EventKind::StrokeEnd => format!("{{\"ev\": \"stroke_end\", \"t\": {t}}}"),
        EventKind::Camera(c) => format!(
            "{{\"ev\": \"camera\", \"t\": {t}, \"eye\": {}, \"q\": {}, \"fov\": {}, \"size\": [{}, {}], \"background\": {}}}",
            float_list(&c.eye),
            float_list(&c.q),
            float_list(&c.fov),
            c.size[0],
            c.size[1],
            float_list(&c.background)
        ),
        EventKind::Render(name) => format!("{{\"ev\": \"render\", \"t\": {t}, \"name\": \"{name}\"}}"),
        EventKind::Snapshot(name) => format!("{{\"ev\": \"snapshot\", \"t\": {t}, \"name\": \"{name}\"}}"),
        EventKind::Undo => format!("{{\"ev\": \"undo\", \"t\": {t}}}"),
        EventKind::Redo => format!("{{\"ev\": \"redo\", \"t\": {t}}}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::parse_trace;

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
            let mut text = header_line(&trace.canvas, &trace.meta);
            for ev in &trace.events {
                text.push('\n');
                text.push_str(&event_line(ev));
            }
            let again = parse_trace(&text).unwrap_or_else(|e| panic!("{}: {e}\n", path.display()));
            assert_eq!(again.canvas, trace.canvas);
            assert_eq!(again.meta.dumps(), trace.meta.dumps());
            assert_eq!(again.events.len(), trace.events.len());
            for (a, b) in again.events.iter().zip(&trace.events) {
                assert_eq!(a.kind, b.kind, "{}", path.display());
                assert_eq!(a.t.to_bits(), b.t.to_bits());
            }
            seen += trace.events.len();
        }
        assert!(seen > 5000);
    }
}
