//! Octopaint's vocabulary: the values a trace carries and the rules that
//! need no tree. The bottom of the painter's crates: it depends on none of
//! them, and every crate that reads, paints or shows a painting speaks it.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`event`] | canvas, brush, shape and mode, sample, camera, light, mirror, layer operation, import, the events of a trace | trace.py (its dataclasses) |
//! | [`limits`] | the limits a trace's values are read against | trace.py (its constants) |
//! | [`layer_rules`] | layer names, whether an operation is allowed, where the layers go, the reader's model of a document | layer_rules.py |
//! | [`voxel_set`] | a voxel set as an import carries it | voxelset.py (`VoxelSet`) |

pub mod event;
pub mod layer_rules;
pub mod limits;
pub mod voxel_set;

pub use event::*;
pub use limits::*;
pub use voxel_set::{MAX_VOXELS, VoxelSet};
