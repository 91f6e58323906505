//! Octopaint's documents of layers, over the painting core: a document of
//! up to 16 layers under one cell budget and one history, merge down,
//! document dumps, replaying a trace, the ray caster's CPU port and orbit
//! cameras. The core is two crates below it, which Cargo keeps from
//! importing upward: octopaint-octree (the pools, their one journalled
//! writer, balance, cleaning, undo, g3, tree dumps) and octopaint-paint
//! (brushes, strokes, the paint pass, imports, over the octree). This crate
//! re-exports their modules, so `octopaint_tree::pool`, `::paint` and the
//! rest name the same items for every crate above (docs/architecture.md,
//! "The crates"). No GPU dependency. Everything follows docs/spec.md
//! ("spec N.M"); reference/octopaint_ref is the oracle it is checked
//! against.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`layers`] | documents of layers, merge down, document dumps (the rules: octopaint-model) | layers.py |
//! | [`replay`] | replaying a trace | replay.py |
//! | [`raycast`] | the ray caster's CPU port, shader-shaped | raycast.py |
//! | [`view`] | orbit cameras, the view framing the painting | camera.py (orbit_camera) |
//! | [`fuzz_harness`] | the fuzz targets' bodies for traces and replays; a deterministic mutator | — |
//! | [`trace`] | octopaint-model's events and octopaint-trace's reader, re-exported | trace.py |
//! | [`trace_write`] | octopaint-trace's writer, re-exported | — |
//! | octopaint-octree's | [`lattice`], [`pool`], [`pager`], [`balance`], [`dirty`], [`clean`], [`history`], [`g3`], [`check`], [`dump`], [`par`], [`team`] | tree.py, history.py, clean.py, g3.py, check.py, dump.py |
//! | octopaint-paint's | [`brush`], [`noise`], [`stroke`], [`paint`], [`lanes`], [`slots`], [`voxels`] | brush.py, noise.py, stroke.py, paint.py, voxelset.py |

pub mod fuzz_harness;
pub mod layers;
pub mod raycast;
pub mod replay;
pub mod trace;
pub mod trace_write;
pub mod view;

pub use octopaint_octree::{balance, check, clean, dirty, dump, g3, history, lattice, normals, pager, par, pool, team};
pub use octopaint_paint::{brush, lanes, noise, paint, slots, stroke, voxels};

pub use octopaint_octree::pool::{FREE, NONE, Tree, UNIT};
pub use octopaint_paint::Painting;
pub use trace::{Trace, TraceError, read_trace};
