//! The limits a trace's values are read against (spec 12.2), shared by the
//! reader and the tree that must never see more, and the spec's constants
//! that the tree's lattice and the brushes both use.

/// The deepest `max_depth` a canvas may have (spec 12.2).
pub const MAX_DEPTH_LIMIT: i64 = 28;
/// The largest multiple of 8 below NONE.
pub const MAX_CAPACITY: i64 = 0xFFFF_FFF8;
/// The widest or tallest image a camera may ask for, in pixels.
pub const MAX_IMAGE_SIZE: i64 = 16384;
/// The most roots a canvas may have.
pub const MAX_ROOTS: u64 = 1 << 24;
/// The most stamps one segment of a stroke may take (spec 12.2).
pub const MAX_STAMPS_PER_SEGMENT: f64 = 65536.0;
/// The largest `intensity` of a `light` event (spec 6.1).
pub const LIGHT_INTENSITY_MAX: f64 = 16.0;
/// Smallest normal f64; smaller magnitudes read as +0 (spec 8.9).
pub const TINY: f64 = 2.2250738585072014e-308;
/// √3/2, half a unit cube's diagonal: the reach radius's factor (spec 8.1,
/// 8.7).
pub const HALF_DIAG: f64 = 0.8660254037844386;
/// Cells across a brush's radius at its target depth (spec 8.1, 8.7).
pub const CELLS_PER_RADIUS: f64 = 10.0;
