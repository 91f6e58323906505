//! Exports of a painting to other tools' formats (docs/export.md): OpenVDB
//! volumes for renderers and simulation tools, iso-surface meshes (glTF
//! binary, OBJ) for everything that only takes triangles.
//!
//! | module | what it holds |
//! | --- | --- |
//! | [`values`] | what a cell exports: extinction, colour, aggregates |
//! | [`voxels`] | the painting resampled at one export depth, in VDB's shape |
//! | [`vdb`] | the OpenVDB file writer (format 224) |
//! | [`dual`] | the iso-surface on the adaptive tree's dual grid |
//! | [`mesh`] | glTF binary and OBJ writers for that surface |
//! | [`usd`] | USD stages (`.usda`) over the VDB's grids and the surface |
//! | [`vdb_read`], [`mesh_read`], [`voxelise`], [`import`] | imports: VDB files and closed meshes read and turned into voxel sets (spec 15) |
//! | [`fuzz_harness`] | the import fuzz targets' bodies |
//!
//! Nothing here writes a file (but the mesh fuzz target, which hands its
//! bytes to the mesh reader through a temporary one): the writers take a
//! `Write`, and the command line (`octopaint export`) writes them
//! atomically.

pub mod dual;
pub mod fuzz_harness;
pub mod import;
pub mod mesh;
pub mod mesh_read;
pub mod usd;
pub mod values;
pub mod vdb;
pub mod vdb_read;
pub mod voxelise;
pub mod voxels;

pub use dual::{Mesh, SurfaceOptions, default_iso, surface};
pub use values::ColourSpace;
pub use voxels::VoxelGrid;

/// How canvas coordinates map to the file's: `file = turn(scale · (p −
/// origin))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// File units per canvas unit (metres per canvas unit for glTF).
    pub scale: f64,
    /// Rotate the canvas's +y-up frame to +z up: (x, y, z) → (x, −z, y).
    /// glTF is +y up by definition and ignores it.
    pub z_up: bool,
    /// The canvas point that becomes the file's origin. Readers hold
    /// positions in f32: a painting far from the origin of a 40 km canvas
    /// keeps its millimetres only when moved near the file's origin.
    pub origin: [f64; 3],
}

impl Default for Placement {
    fn default() -> Self {
        Placement { scale: 1.0, z_up: false, origin: [0.0; 3] }
    }
}

impl Placement {
    /// A canvas point in the file's frame (`allow_z_up` false: no turn).
    pub fn apply(&self, p: glam::DVec3, allow_z_up: bool) -> glam::DVec3 {
        self.turn((p - glam::DVec3::from_array(self.origin)) * self.scale, allow_z_up)
    }

    /// A vector (offsets, normals) in the file's frame: the turn alone.
    pub fn turn(&self, v: glam::DVec3, allow_z_up: bool) -> glam::DVec3 {
        if self.z_up && allow_z_up { glam::DVec3::new(v.x, -v.z, v.y) } else { v }
    }
}

/// A box of the canvas to export, in canvas units: `[lo, hi)` on each
/// axis. Voxels that overlap it are written; the mesh treats leaves whose
/// centre lies outside it as empty, so it is closed along the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crop {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Crop {
    /// Whether the cell with lattice origin `o` and depth `d` overlaps it.
    pub fn touches_cell(&self, tree: &octopaint_tree::Tree, o: [u32; 3], d: u32) -> bool {
        let s = tree.lat.size_canvas[d as usize];
        (0..3).all(|a| {
            let lo = f64::from(o[a]) * tree.lat.lattice_unit;
            lo < self.hi[a] && lo + s > self.lo[a]
        })
    }

    /// Whether the point is inside.
    pub fn contains(&self, p: glam::DVec3) -> bool {
        let p = p.to_array();
        (0..3).all(|a| p[a] >= self.lo[a] && p[a] < self.hi[a])
    }
}

/// Why an export was refused. Every refusal happens before anything is
/// written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("export depth {depth} is out of range: this canvas goes from depth 0 to {deepest}")]
    DepthOutOfRange { depth: u32, deepest: u32 },
    #[error(
        "a voxel grid at depth {depth} would take {} MiB, over the cap of {} MiB{}",
        mib(*bytes),
        mib(*cap_bytes),
        match fits {
            Some(d) => format!("; depth {d} fits (--depth {d}), or raise --max-mib"),
            None => "; no depth fits: raise --max-mib".to_string(),
        }
    )]
    TooLarge { depth: u32, bytes: u64, cap_bytes: u64, fits: Option<u32> },
    #[error("no export depth fits in {} MiB, not even depth 0: raise --max-mib", mib(*cap_bytes))]
    NothingFits { cap_bytes: u64 },
    #[error("the surface would have more than {max} triangles: pass a coarser --mesh-depth, a higher --iso, or a larger --max-triangles")]
    TooManyTriangles { max: usize },
    #[error("{what} would be {} MiB, over the format's limit of 4 GiB: pass a coarser --mesh-depth", mib(*bytes))]
    FormatLimit { what: &'static str, bytes: u64 },
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

fn mib(bytes: u64) -> String {
    let m = bytes as f64 / (1u64 << 20) as f64;
    if m < 10.0 { format!("{m:.1}") } else { format!("{m:.0}") }
}
