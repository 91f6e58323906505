//! The bodies of the import fuzz targets (painter/fuzz: `vdb`, `gltf`,
//! `obj`), also run by `octopaint fuzz-smoke`: any bytes give grids or a
//! mesh, or a clear error, never a panic; what reads is finite and within
//! the limits.

use std::sync::atomic::{AtomicU64, Ordering};

use crate::mesh_read::{MeshLimits, read_mesh};
use crate::vdb_read::{ReadLimits, read_vdb};

/// Voxels a fuzzed OpenVDB file may hold.
const MAX_VOXELS: u64 = 1 << 16;
/// Triangles a fuzzed mesh may hold.
const MAX_TRIANGLES: u64 = 1 << 14;

/// Any bytes as an OpenVDB file.
pub fn vdb(data: &[u8]) {
    let limits = ReadLimits { max_voxels: MAX_VOXELS, tile_cover: false };
    let _ = read_vdb(data, &limits);
}

/// Any bytes as a mesh file of `ext` (`glb`, `gltf`, `obj`): the reader
/// reads files (a glTF's buffers and an OBJ's materials are found beside
/// them), so the bytes are written to a file of its own in the temporary
/// folder first.
pub fn mesh(data: &[u8], ext: &str) {
    static N: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!("octopaint-fuzz-mesh-{}-{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let path = dir.join(format!("in.{ext}"));
    std::fs::write(&path, data).expect("a temporary file");
    let read = read_mesh(&path, &MeshLimits { max_triangles: MAX_TRIANGLES });
    let _ = std::fs::remove_dir_all(&dir);
    if let Ok(mesh) = read {
        assert!(mesh.triangles.len() as u64 <= MAX_TRIANGLES);
        assert!(mesh.positions.iter().all(|p| p.iter().all(|v| v.is_finite())));
        let n = mesh.positions.len() as u64;
        assert!(mesh.triangles.iter().all(|t| t.iter().all(|&i| u64::from(i) < n)), "a triangle names a vertex the mesh does not have");
    }
}
