//! Wavefront `.obj` (with its `.mtl`) through the `tobj` crate, after a
//! pre-scan of our own that counts triangles and refuses what would make
//! the parser panic.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::{MeshError, MeshLimits, TriMesh, append, io_err};
use crate::values::srgb_to_linear;

/// Reads a Wavefront OBJ: every face of every object and group, polygons
/// triangulated as fans (right for the convex polygons exporters write),
/// one index per vertex.
///
/// Colour: the `v x y z r g b` vertex colours if every vertex has them,
/// else the diffuse `Kd` of the face's material from the `.mtl` files the
/// OBJ names, else white. OBJ has no colour-space convention, but both are
/// in practice display (sRGB-encoded) values, as tools write them from
/// colour pickers: they are taken as sRGB, clamped to [0, 1] and converted
/// to linear.
///
/// Refused: line (`l`) and point elements, faces with fewer than three
/// corners, indices out of range, a mix of coloured and uncoloured
/// vertices (which OBJ readers cannot line up), an `.mtl` that cannot be
/// read.
pub(super) fn read_obj(path: &Path, limits: &MeshLimits) -> Result<TriMesh, MeshError> {
    // Our own pass first: it counts the triangles before anything is
    // allocated for them and rejects what would make the parser panic or
    // misattribute colours.
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    prescan_obj(BufReader::new(file), path, limits)?;

    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mtl_error: std::cell::RefCell<Option<MeshError>> = std::cell::RefCell::new(None);
    // Any failure of a material library (missing file, parse error) is
    // kept here with its path: tobj reports only the first, without it.
    let loader = |name: &Path| -> tobj::MTLLoadResult {
        let r = load_mtl_checked(&dir.join(name));
        match r {
            Ok(Ok(r)) => Ok(r),
            Ok(Err(e)) => {
                mtl_error.borrow_mut().get_or_insert(MeshError::Obj(format!("material library {}: {e}", dir.join(name).display())));
                Err(e)
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    // `..Default::default()`: tobj's optional features add fields.
    #[allow(clippy::needless_update)]
    let opts = tobj::LoadOptions { single_index: true, triangulate: true, ignore_points: true, ignore_lines: true, ..Default::default() };
    let file = std::fs::File::open(path).map_err(io_err(path))?;
    let mut reader = BufReader::new(file);
    // The pre-scan rules out the inputs known to panic tobj 4.0 (short
    // `Kd` lines, out-of-range texture/normal indices); this guard turns
    // any other panic in it into a refusal.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| tobj::load_obj_buf(&mut reader, &opts, loader)))
        .map_err(|_| MeshError::Obj("the OBJ parser failed on this file".into()))?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let (models, materials) = parsed.map_err(|e| MeshError::Obj(e.to_string()))?;
    // Every library loaded (or we returned above), so an error here only
    // means "no materials".
    let materials = materials.unwrap_or_default();

    let mut out = TriMesh::default();
    for model in &models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(MeshError::Obj(format!("object '{}' is inconsistent after parsing", model.name)));
        }
        let nv = m.positions.len() / 3;
        let coloured = m.vertex_color.len() == m.positions.len() && !m.vertex_color.is_empty();
        let kd = m.material_id.and_then(|i| materials.get(i)).and_then(|mat| mat.diffuse);
        let mut positions = Vec::with_capacity(nv);
        let mut colours = Vec::with_capacity(nv);
        for v in 0..nv {
            positions.push([m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]]);
            let srgb = if coloured { [m.vertex_color[3 * v], m.vertex_color[3 * v + 1], m.vertex_color[3 * v + 2]] } else { kd.unwrap_or([1.0; 3]) };
            if !srgb.iter().all(|c| c.is_finite()) {
                return Err(MeshError::Obj(format!("object '{}' has a colour that is not a finite number", model.name)));
            }
            colours.push(srgb.map(|c| srgb_to_linear(c.clamp(0.0, 1.0)) as f32));
        }
        let mut tris = Vec::with_capacity(m.indices.len() / 3);
        for t in m.indices.chunks_exact(3) {
            if t.iter().any(|&i| i as usize >= nv) {
                return Err(MeshError::Obj(format!("object '{}' has a face index out of range", model.name)));
            }
            tris.push([t[0], t[1], t[2]]);
        }
        append(&mut out, &format!("object '{}'", model.name), positions, colours, &tris)?;
    }
    Ok(out)
}

/// One streaming pass over the OBJ: counts triangles (a polygon of n
/// corners makes n − 2) against the limit, and checks every face index
/// against the vertices, texture coordinates and normals defined before
/// it (negative indices count back from there, as OBJ says).
fn prescan_obj(mut r: impl BufRead, path: &Path, limits: &MeshLimits) -> Result<(), MeshError> {
    let (mut nv, mut nv_coloured, mut nvt, mut nvn) = (0u64, 0u64, 0u64, 0u64);
    let mut triangles = 0u64;
    let mut raw = Vec::new();
    let mut line_no = 0u64;
    loop {
        raw.clear();
        let n = r.read_until(b'\n', &mut raw).map_err(io_err(path))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let line = std::str::from_utf8(&raw).map_err(|_| MeshError::Obj(format!("line {line_no} is not text (UTF-8)")))?;
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let rest: Vec<&str> = words.collect();
        match key {
            "v" => {
                match rest.len() {
                    3 | 4 => {}
                    6 => nv_coloured += 1,
                    k => return Err(MeshError::Obj(format!("line {line_no}: a vertex has {k} numbers (3, 4 or 6 expected)"))),
                }
                nv += 1;
            }
            "vt" => nvt += 1,
            "vn" => nvn += 1,
            "l" | "p" => {
                return Err(MeshError::Unsupported(format!(
                    "line {line_no}: the OBJ has {} elements; import-mesh takes closed triangle meshes only (delete the loose edges and points)",
                    if key == "l" { "line" } else { "point" }
                )));
            }
            "f" => {
                if rest.len() < 3 {
                    return Err(MeshError::Unsupported(format!(
                        "line {line_no}: a face with {} corner(s); import-mesh takes closed triangle meshes only",
                        rest.len()
                    )));
                }
                for corner in &rest {
                    let parts: Vec<&str> = corner.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(MeshError::Obj(format!("line {line_no}: bad face corner '{corner}'")));
                    }
                    for (k, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let have = [nv, nvt, nvn][k];
                        let ok = match part.parse::<i64>() {
                            Ok(i) if i > 0 => (i as u64) <= have,
                            Ok(i) if i < 0 => i.unsigned_abs() <= have,
                            _ => false,
                        };
                        if !ok {
                            return Err(MeshError::Obj(format!(
                                "line {line_no}: face corner '{corner}' refers to a {} that does not exist ({have} defined so far)",
                                ["vertex", "texture coordinate", "normal"][k]
                            )));
                        }
                    }
                }
                triangles += rest.len() as u64 - 2;
                if triangles > limits.max_triangles {
                    return Err(MeshError::TooManyTriangles { count: triangles, max: limits.max_triangles });
                }
            }
            _ => {}
        }
    }
    if nv_coloured != 0 && nv_coloured != nv {
        return Err(MeshError::Obj(format!("{nv_coloured} of its {nv} vertices have colours: give every vertex a colour, or none")));
    }
    Ok(())
}

/// Reads an `.mtl` after checking the lines tobj 4.0 would panic on
/// (`Ka`/`Kd`/`Ks`/`Ke` with fewer than three numbers): Err for those and
/// for a file that cannot be read, tobj's own result otherwise.
fn load_mtl_checked(path: &Path) -> Result<tobj::MTLLoadResult, MeshError> {
    let mut text = String::new();
    std::fs::File::open(path).and_then(|mut f| f.read_to_string(&mut text)).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })?;
    for (n, line) in text.lines().enumerate() {
        let mut w = line.split_whitespace();
        if let Some("Ka" | "Kd" | "Ks" | "Ke") = w.next()
            && w.count() < 3
        {
            return Err(MeshError::Obj(format!("{} line {}: a colour needs three numbers (r g b)", path.display(), n + 1)));
        }
    }
    Ok(tobj::load_mtl_buf(&mut text.as_bytes()))
}
