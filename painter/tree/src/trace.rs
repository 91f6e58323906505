//! The events of a trace and their reader, as the tree's modules and the
//! crates above name them: octopaint-model's vocabulary and limits and
//! octopaint-trace's reader, in one namespace. Neither knows the tree.

pub use octopaint_model::event::*;
pub use octopaint_model::limits::*;
pub use octopaint_trace::{
    ErrorKind, MAX_NESTING, Resolve, TraceError, folder_resolver, io_reason, is_valid_name, nesting_depth, parse_brush, parse_camera, parse_canvas,
    parse_layer, parse_light, parse_mirror, parse_sample, parse_trace, parse_trace_bytes, parse_trace_with, read_trace, segment_too_long,
};
