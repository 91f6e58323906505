//! A parsed trace written canonically: one JSON array per line, numbers as
//! serde_json writes them (shortest round trip). The conformance driver
//! compares these values, not their text, with the reference reader's
//! (conformance/readers.py `canonical`): a refusal is `["error", LINE,
//! KIND]`, so the two readers agree on where and what, each in its own
//! words.

use octopaint_tree::trace::{EventKind, MODES, SHAPES, Trace, TraceError};
use serde_json::{Value, json};

pub fn canonical(result: &Result<Trace, TraceError>) -> Vec<String> {
    let t = match result {
        Ok(t) => t,
        Err(e) => return vec![json!(["error", e.line, e.kind.code()]).to_string()],
    };
    let c = &t.canvas;
    let mut out = vec![json!(["canvas", c.roots, c.max_depth, c.root_size, c.capacity, t.version]).to_string()];
    out.extend(t.warnings.iter().map(|w| json!(["warning", w]).to_string()));
    for ev in &t.events {
        let mut row = vec![json!(ev.line), json!(ev.t), json!(ev.kind.ev())];
        let fields: Vec<Value> = match &ev.kind {
            EventKind::Brush(b) => vec![
                json!(SHAPES[b.shape as usize]),
                json!(MODES[b.mode as usize]),
                json!(b.radius),
                json!(b.color),
                json!(b.opacity),
                json!(b.hardness),
                json!(b.spacing),
                json!(b.mix_ratio),
                json!(b.pickup_rate),
                json!(b.aspect),
                json!(b.noise.frequency),
                json!(b.noise.octaves),
                json!(b.noise.seed),
                json!(b.noise.gain),
            ],
            EventKind::Mirror(m) => vec![json!(m.axes), json!(m.centre)],
            EventKind::Sample(s) => vec![json!(s.p), json!(s.pressure), json!(s.q)],
            EventKind::Camera(c) => vec![json!(c.eye), json!(c.q), json!(c.fov), json!(c.size), json!(c.background)],
            EventKind::Light(l) if l.on => vec![json!(true), json!(l.dir), json!(l.intensity), json!(l.ambient), json!(l.shadows)],
            EventKind::Light(_) => vec![json!(false)],
            EventKind::Render(n) | EventKind::Snapshot(n) => vec![json!(n)],
            EventKind::StrokeBegin | EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo => vec![],
            EventKind::Layer(op) => {
                vec![json!(op.op.code()), json!(op.layer), json!(op.name), json!(op.to), json!(op.visible), json!(op.opacity.map(f64::from)), json!(op.locked)]
            }
            EventKind::Import(imp) => vec![json!(imp.file), json!(imp.sha256), json!(imp.name), json!(imp.voxels.depth), json!(imp.voxels.len())],
        };
        row.extend(fields);
        out.push(Value::Array(row).to_string());
    }
    out
}
