//! Octopaint's CPU octree (the painter core): a root array of 2:1-balanced
//! octrees in pooled arrays, the brushes that paint it, topology cleaning,
//! undo, the g3 CPU port, tree dumps and documents of layers, over
//! octopaint-model's vocabulary and octopaint-trace's reader. No GPU
//! dependency. Everything follows docs/spec.md, whose sections the comments
//! cite as "spec N.M"; reference/octopaint_ref is the oracle it is checked
//! against, index for index.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`lattice`] | root array, lattice, canvas units, target depth | tree.py |
//! | [`pool`] | pools, allocator, cell writes with their undo journal and change log | tree.py, history.py (the journal) |
//! | [`balance`] | face neighbours, refinement rounds, coarsening test | tree.py |
//! | [`g3`] | g3, shader-shaped, plus brute force | g3.py |
//! | [`raycast`] | the ray caster's CPU port, shader-shaped | raycast.py |
//! | [`view`] | orbit cameras, the view framing the painting | camera.py (orbit_camera) |
//! | [`dirty`] | publications: dirty blocks, dirty cells, neighbour mask | tree.py |
//! | [`brush`] | primitives, reach, coverage, blend modes | brush.py |
//! | [`noise`] | hashed permutation, improved Perlin noise | noise.py |
//! | [`stroke`] | samples to capsules and stamps | stroke.py |
//! | [`paint`] | per-segment levels, per-stroke maximum | paint.py |
//! | [`clean`] | topology cleaning | clean.py |
//! | [`history`] | undo and redo | history.py |
//! | [`lanes`] | a unit's 8 children against capsules in vector registers | — |
//! | [`par`] | parallel passes, the same bytes on any pool; a radix sort of cell lists | — |
//! | [`layers`] | documents of layers, merge down, document dumps (the rules: octopaint-model) | layers.py |
//! | [`voxels`] | imports painted into a tree | paint.py (`import_voxels`), voxelset.py (`VoxelIndex`) |
//! | [`check`] | whether pools form a valid tree; a tree from pools | check.py |
//! | [`dump`] | `.npz` tree dumps | dump.py |
//! | [`trace`] | octopaint-model's events and octopaint-trace's reader, re-exported | trace.py |
//! | [`trace_write`] | octopaint-trace's writer, re-exported | — |
//! | [`replay`] | replaying a trace | replay.py |

pub mod balance;
pub mod brush;
pub mod check;
pub mod clean;
pub mod dirty;
pub mod dump;
pub mod fuzz_harness;
pub mod g3;
pub mod history;
pub mod lanes;
pub mod lattice;
pub mod layers;
pub mod noise;
pub mod pager;
pub mod paint;
pub mod par;
pub mod pool;
pub mod raycast;
pub mod replay;
pub mod slots;
pub mod stroke;
pub mod team;
pub mod trace;
pub mod trace_write;
pub mod view;
pub mod voxels;

pub use paint::Painting;
pub use pool::{FREE, NONE, Tree, UNIT};
pub use trace::{Trace, TraceError, read_trace};
