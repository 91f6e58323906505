//! A parsed trace written canonically, one line per event, every number as
//! Python's repr writes it: the conformance driver compares this text with
//! the reference reader's (conformance/readers.py `canonical`).

use octopaint_tree::pyrepr::py_float_repr as f;
use octopaint_tree::trace::{EventKind, MODES, SHAPES, Trace, TraceError};
use octopaint_tree::trace_write::float_list;

pub fn canonical(result: &Result<Trace, TraceError>) -> Vec<String> {
    let t = match result {
        Ok(t) => t,
        Err(e) => return vec![format!("error: {e}")],
    };
    let c = &t.canvas;
    let mut out = vec![format!(
        "canvas [{}, {}, {}] {} {} {}",
        c.roots[0],
        c.roots[1],
        c.roots[2],
        c.max_depth,
        f(c.root_size),
        c.capacity
    )];
    out.extend(t.warnings.iter().map(|w| format!("warning: {w}")));
    for ev in &t.events {
        let head = |kind: &str| format!("{} {} {kind}", ev.line, f(ev.t));
        out.push(match &ev.kind {
            EventKind::Brush(b) => format!(
                "{} {} {} {} {} {} {} {} {} {} {} {} {} {} {}",
                head("brush"),
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
            ),
            EventKind::Sample(s) => format!("{} {} {} {}", head("sample"), float_list(&s.p), f(s.pressure), float_list(&s.q)),
            EventKind::Camera(c) => format!(
                "{} {} {} {} [{}, {}] {}",
                head("camera"),
                float_list(&c.eye),
                float_list(&c.q),
                float_list(&c.fov),
                c.size[0],
                c.size[1],
                float_list(&c.background)
            ),
            EventKind::Render(n) => format!("{} {n}", head("render")),
            EventKind::Snapshot(n) => format!("{} {n}", head("snapshot")),
            EventKind::StrokeBegin => head("stroke_begin"),
            EventKind::StrokeEnd => head("stroke_end"),
            EventKind::Undo => head("undo"),
            EventKind::Redo => head("redo"),
        });
    }
    out
}
