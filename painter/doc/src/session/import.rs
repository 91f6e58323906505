//! Imports into a session (spec 15): a voxel set painted into the selected
//! layer as one undoable step, saved at once so that the journal never
//! names a voxel set the document does not hold (docs/documents.md,
//! "Imports").

use octopaint_tree::trace::{Event, EventKind, Import};
use octopaint_tree::trace_write::event_line;
use octopaint_tree::voxels::{VoxelSet, sha256_hex, voxel_set_bytes};

use super::Session;
use crate::DocError;
use crate::format::Imports;

impl Session {
    /// Paint a voxel set into the selected layer (an `import` event, spec
    /// 15) as one undoable step, and save at once: the document then holds
    /// the voxel set with the event, so the journal never names a voxel set
    /// it does not hold. All or nothing: refused, changing nothing, inside
    /// a stroke, on a locked layer, or when the cell budget cannot hold the
    /// whole import (the layer is tried on a copy first). `name` labels the
    /// event (where the voxels came from).
    pub fn import(&mut self, vs: &VoxelSet, name: Option<&str>) -> Result<(), DocError> {
        self.commit_import(vs, name, self.last_t, true)
    }

    /// An import, all or nothing ([`Session::import`]) or as a replay
    /// paints it (an `import` event applied from a trace), then saved.
    pub(super) fn commit_import(&mut self, vs: &VoxelSet, name: Option<&str>, t: f64, whole: bool) -> Result<(), DocError> {
        self.check_writable()?;
        let bad = |m: String| Err(DocError::BadEvent(m));
        if self.in_stroke {
            return bad("cannot import inside a stroke: end it first".into());
        }
        let canvas = *self.doc.canvas();
        if vs.depth > canvas.max_depth {
            return bad(format!("depth {} is deeper than the canvas's max depth {}", vs.depth, canvas.max_depth));
        }
        let bytes = voxel_set_bytes(vs);
        // The voxel set as the reader will see it: its checks, once.
        let checked = octopaint_tree::voxels::parse_voxel_set(&bytes, &canvas).map_err(DocError::BadEvent)?;
        if let Some(n) = name
            && let Some(why) = octopaint_tree::layers::name_problem(n)
        {
            return bad(format!("import name: {why}"));
        }
        let sha256 = sha256_hex(&bytes);
        let file = format!("imports/{sha256}.npz");
        let ev = Event {
            line: 0,
            t,
            kind: EventKind::Import(Box::new(Import { file: file.clone(), sha256, name: name.map(str::to_string), voxels: std::sync::Arc::new(checked) })),
        };
        let line = event_line(&ev);
        if whole {
            self.doc.try_import(vs).map_err(DocError::BadEvent)?;
        } else if !self.doc.import_voxels(vs, 0) {
            return bad(self.doc.take_warnings().join("; "));
        }
        self.last_t = t;
        self.imports.insert(file, bytes);
        self.pending.push(line);
        self.save()
    }

    /// The voxel sets the session's imports name, by file.
    pub fn imports(&self) -> &Imports {
        &self.imports
    }
}
