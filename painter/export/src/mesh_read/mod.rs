//! Triangle meshes read from other tools' files, for `octopaint
//! import-mesh` (the solid voxeliser is in [`crate::voxelise`]).
//!
//! | format | how |
//! | --- | --- |
//! | glTF 2.0, `.glb` or `.gltf` (external or `data:` buffers) | the `gltf` crate's document model; accessors decoded in gltf_read.rs |
//! | Wavefront `.obj` (+ `.mtl`) | the `tobj` crate, after a pre-scan of our own (obj_read.rs) |
//!
//! What comes out is one [`TriMesh`] in the file's own units and frame:
//! every triangle of the scene, node transforms applied, with a linear RGB
//! colour per vertex. Nothing is welded or repaired here; see
//! [`crate::voxelise::check_closed`].
//!
//! Every refusal is an `Err` with a message meant for the artist; a
//! malformed file never panics. The triangle limit is checked from the
//! counts the file declares, before anything is allocated for them.

mod gltf_read;
mod obj_read;

use std::path::{Path, PathBuf};

use gltf_read::read_gltf;
use obj_read::read_obj;

/// A triangle soup with shared vertices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// In the file's units, node transforms applied.
    pub positions: Vec<[f64; 3]>,
    /// Linear RGB per vertex, in [0, 1] as the file gives it (glTF's
    /// factors may take it past 1; nothing clamps here).
    pub colours: Vec<[f32; 3]>,
    /// Indices into `positions`; the winding is the file's (mirroring node
    /// transforms already undone), but need not be consistent.
    pub triangles: Vec<[u32; 3]>,
}

/// What a reader may take.
#[derive(Clone, Copy, Debug)]
pub struct MeshLimits {
    /// Refuse files with more triangles than this (counted over every
    /// instance of every mesh in the scene).
    pub max_triangles: u64,
}

/// Why a mesh was refused. Messages are meant for the artist.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("cannot read {}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{} is not a mesh this command reads: give a .glb, .gltf or .obj file", path.display())]
    UnknownFormat { path: PathBuf },
    #[error("not a valid glTF file: {0}")]
    Gltf(String),
    #[error("not a valid OBJ file: {0}")]
    Obj(String),
    #[error("the file is malformed: {0}")]
    Malformed(String),
    #[error("{0}")]
    Unsupported(String),
    #[error("the mesh has more than {max} triangles (counted {count} so far): simplify it (decimate) or raise the triangle limit")]
    TooManyTriangles { count: u64, max: u64 },
    #[error("vertex {vertex} of {what} has a position that is not a finite number ({position:?})")]
    NonFinite { what: String, vertex: u64, position: [f64; 3] },
    #[error("the file holds no triangles (meshes with only points or lines, or an empty scene)")]
    NoTriangles,
    #[error("the mesh is not closed, so it has no inside to fill: {0}")]
    NotClosed(Box<EdgeDefects>),
    #[error("the solid would have more than {max} voxels: use a coarser voxel size or a smaller scale, or raise the voxel limit")]
    TooManyVoxels { max: u64 },
    #[error("the voxel grid is invalid: {0}")]
    BadGrid(String),
    #[error("the mesh is not closed along the row of voxel centres at y = {y}, z = {z} (an odd number of surface crossings): run the closedness check first")]
    OddCrossings { y: f64, z: f64 },
}

/// What keeps a mesh from being closed ([`crate::voxelise::check_closed`]):
/// edge counts after welding, and one edge of each kind by its two end
/// points, for the artist to find.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeDefects {
    /// Edges used by one triangle: the rims of holes.
    pub boundary: u64,
    /// Edges shared by more than two triangles.
    pub non_manifold: u64,
    /// Edges shared by two triangles that run them the same way: one of
    /// the two is flipped.
    pub inconsistent: u64,
    pub boundary_at: Option<[[f64; 3]; 2]>,
    pub non_manifold_at: Option<[[f64; 3]; 2]>,
    pub inconsistent_at: Option<[[f64; 3]; 2]>,
}

impl std::fmt::Display for EdgeDefects {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} boundary edge(s) (holes){}, {} non-manifold edge(s) (shared by more than two triangles){}, {} inconsistently oriented edge(s) (flipped triangles){}",
            self.boundary,
            at(&self.boundary_at),
            self.non_manifold,
            at(&self.non_manifold_at),
            self.inconsistent,
            at(&self.inconsistent_at)
        )
    }
}

/// " e.g. from (x, y, z) to (x, y, z)" for an example edge.
fn at(edge: &Option<[[f64; 3]; 2]>) -> String {
    match edge {
        Some([a, b]) => format!(" e.g. from ({}, {}, {}) to ({}, {}, {})", a[0], a[1], a[2], b[0], b[1], b[2]),
        None => String::new(),
    }
}

/// Reads the mesh in `path`, by its extension (`.glb`, `.gltf`, `.obj`,
/// any case). Colours: glTF `COLOR_0` times the material's base colour
/// factor (a base colour *texture* is not sampled: we use the factor);
/// OBJ vertex colours, else the material's `Kd`, taken as sRGB and made
/// linear; else white. A file with no triangles is refused.
pub fn read_mesh(path: &Path, limits: &MeshLimits) -> Result<TriMesh, MeshError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let mesh = match ext.as_deref() {
        Some("glb") | Some("gltf") => read_gltf(path, limits)?,
        Some("obj") => read_obj(path, limits)?,
        _ => return Err(MeshError::UnknownFormat { path: path.to_path_buf() }),
    };
    if mesh.triangles.is_empty() {
        return Err(MeshError::NoTriangles);
    }
    Ok(mesh)
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> MeshError + '_ {
    move |source| MeshError::Io { path: path.to_path_buf(), source }
}

/// Appends `positions`/`colours` and `triangles` (indices local to them)
/// to `out`, checking that every position is finite.
fn append(out: &mut TriMesh, what: &str, positions: Vec<[f64; 3]>, colours: Vec<[f32; 3]>, triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    let base = out.positions.len() as u64;
    if base + positions.len() as u64 > u64::from(u32::MAX) {
        return Err(MeshError::Unsupported("the mesh has more than 4 billion vertices".into()));
    }
    for (i, p) in positions.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(MeshError::NonFinite { what: what.to_string(), vertex: i as u64, position: *p });
        }
    }
    let base = base as u32;
    out.positions.extend(positions);
    out.colours.extend(colours);
    out.triangles.extend(triangles.iter().map(|t| t.map(|i| i + base)));
    Ok(())
}

// ---------------------------------------------------------------- glTF
