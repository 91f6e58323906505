//! Octopaint's CPU octree: a root array of 2:1-balanced octrees in pooled
//! arrays, and what keeps them a tree: the one writer of their cells (with
//! its undo journal and change log), refinement and balance, topology
//! cleaning, undo and redo, the publications the GPU uploads, the g3 CPU
//! port, tree dumps. It knows no brush: painting is octopaint-paint's,
//! over this crate; documents of layers are octopaint-tree's, over that.
//! Everything follows docs/spec.md ("spec N.M"); reference/octopaint_ref is
//! the oracle it is checked against, index for index.
//!
//! | module | what it holds | reference twin |
//! | --- | --- | --- |
//! | [`lattice`] | root array, lattice, canvas units, target depth | tree.py |
//! | [`pool`] | pools, allocator, cell writes with their undo journal and change log | tree.py, history.py (the journal) |
//! | [`pager`] | the pools' pages made resident ahead of their first write | — |
//! | [`prefilter`] | interior values: each cell with children holds its children's prefilter | prefilter.py |
//! | [`balance`] | face neighbours, refinement rounds, coarsening test | tree.py |
//! | [`dirty`] | publications: dirty blocks, dirty cells, neighbour mask | tree.py |
//! | [`clean`] | topology cleaning | clean.py |
//! | [`history`] | undo and redo | history.py |
//! | [`g3`] | g3, shader-shaped, plus brute force | g3.py |
//! | [`check`] | whether pools form a valid tree; a tree from pools | check.py |
//! | [`dump`] | `.npz` tree dumps | dump.py |
//! | [`par`] | parallel passes, the same bytes on any pool; a radix sort of cell lists; disjoint writes | — |
//! | [`team`] | the few threads a parallel pass runs on | — |

pub mod balance;
pub mod check;
pub mod clean;
pub mod dirty;
pub mod dump;
pub mod g3;
pub mod history;
pub mod lattice;
pub mod normals;
pub mod pager;
pub mod par;
pub mod pool;
pub mod prefilter;
pub mod team;

pub use pool::{FREE, NONE, Tree, UNIT};
