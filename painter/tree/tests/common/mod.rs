//! What the thread-count tests (threads.rs, threads_grain.rs) share.

use octopaint_tree::paint::Painting;

/// A painting's undo and redo steps as bytes, record by record in their
/// order (a tag tells done from undone): equal bytes, equal histories.
pub fn history_bytes(p: &Painting) -> Vec<u8> {
    let mut out = Vec::new();
    for (tag, steps) in [(0u8, &p.history.done), (1, &p.history.undone)] {
        for step in steps {
            out.push(tag);
            out.extend(step.n_before.to_le_bytes());
            out.extend(step.n_after.to_le_bytes());
            for (c, b, a) in step.entries() {
                out.extend(c.to_le_bytes());
                for r in [b, a] {
                    out.extend(r.parent.to_le_bytes());
                    out.extend(r.first_child.to_le_bytes());
                    out.push(r.depth);
                    out.extend(r.rgb);
                    out.extend(r.sigma.to_bits().to_le_bytes());
                }
            }
        }
    }
    out
}
