//! Reading and writing the painter's inputs of outside bytes that need no
//! tree: traces (spec 12; ../../shared/TRACE-FORMAT.md) and voxel sets
//! (spec 15.1), plus the `.npz` writer tree dumps share. Over
//! octopaint-model's vocabulary, under the tree. A bad trace gives one
//! [`TraceError`]: its line and its [`ErrorKind`] are the contract both
//! readers keep; reference twin: reference/octopaint_ref/trace.py.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`error`] | the error kinds of spec 12.2 | trace.py (`TraceError`) |
//! | [`fields`] | the rules on the fields of one line | trace.py |
//! | [`read`] | a whole trace: order, names, layers, imports | trace.py |
//! | [`write`] | writing traces (recorded sessions) | — |
//! | [`voxels`] | voxel sets' files | voxelset.py |
//! | [`npz`] | `.npz` files of stored `.npy` entries | — (numpy's `savez`) |

pub mod error;
pub mod fields;
pub mod npz;
pub mod read;
pub mod voxels;
pub mod write;

pub use error::{ErrorKind, TraceError};
pub use fields::{is_valid_name, parse_brush, parse_camera, parse_canvas, parse_layer, parse_light, parse_mirror, parse_sample, segment_too_long};
pub use read::{MAX_NESTING, Resolve, folder_resolver, io_reason, nesting_depth, parse_trace, parse_trace_bytes, parse_trace_with, read_trace};
