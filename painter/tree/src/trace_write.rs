//! Writing traces: octopaint-trace's writer, under the name the crates
//! above use.

pub use octopaint_trace::write::*;
