//! Octopaint's painting: the brushes (primitives, reach, coverage, blend
//! modes), strokes from samples to capsules and stamps, the paint pass
//! (serial and split across threads, with its vector lanes), refinement
//! levels, the stroke's slots, and imports of voxel sets. It writes the
//! tree only through octopaint-octree's writers (journalled, marking dirty
//! blocks); documents of layers are octopaint-tree's, over this crate.
//! Everything follows docs/spec.md ("spec N.M"); reference/octopaint_ref is
//! the oracle it is checked against.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`brush`] | primitives, reach, coverage, blend modes | brush.py |
//! | [`noise`] | hashed permutation, improved Perlin noise | noise.py |
//! | [`stroke`] | samples to capsules and stamps | stroke.py |
//! | [`paint`] | per-segment levels, per-stroke maximum | paint.py |
//! | [`lanes`] | a unit's 8 children against capsules in vector registers | — |
//! | [`slots`] | the stroke's map from cell to slot, in pages | — |
//! | [`voxels`] | imports painted into a tree | paint.py (`import_voxels`), voxelset.py (`VoxelIndex`) |

pub mod brush;
pub mod lanes;
pub mod noise;
pub mod paint;
pub mod slots;
pub mod stroke;
pub mod voxels;

pub use paint::Painting;
