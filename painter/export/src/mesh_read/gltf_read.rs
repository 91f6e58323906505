//! glTF 2.0 (`.glb`, `.gltf` with external or `data:` buffers) through the
//! `gltf` crate's document model, with the accessors decoded here.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::{MeshError, MeshLimits, TriMesh, append, io_err};

/// Reads a glTF 2.0 file: every triangle primitive of every node of the
/// default scene (or the first scene; with no scene, every node that has
/// no parent; with no nodes either, every mesh untransformed), each
/// transformed by its node's world matrix (composed in f64).
///
/// Colour: `COLOR_0` (float, or normalized u8/u16; RGB or RGBA, alpha
/// ignored; linear, as glTF defines vertex colours) times the material's
/// `baseColorFactor` (linear), which is what glTF's metallic-roughness
/// model gives as the base colour; without `COLOR_0`, the factor alone. A
/// base colour *texture* is not sampled: only the factor is used, so a
/// textured model comes in in its factor's colour (often white).
///
/// Triangle strips and fans are converted to triangles; points and lines
/// are refused. A node whose matrix mirrors (negative determinant) has
/// its triangles' winding reversed, as glTF specifies.
pub(super) fn read_gltf(path: &Path, limits: &MeshLimits) -> Result<TriMesh, MeshError> {
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    // gltf 1.4 subtracts the header's size from a GLB's declared length
    // unchecked (an overflow, a panic where overflow is checked: found by
    // the `glb` fuzz target): check the length first.
    if let Some(length) = bytes.strip_prefix(b"glTF").and_then(|rest| rest.get(4..8)) {
        let length = u32::from_le_bytes(length.try_into().expect("4 bytes")) as usize;
        if length < 12 || length > bytes.len() {
            return Err(MeshError::Gltf(format!("the GLB header says the file is {length} bytes long; it is {}", bytes.len())));
        }
    }
    let gltf::Gltf { document, blob } = gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| MeshError::Gltf(e.to_string()))?;
    // gltf-json 1.4's validation indexes the POSITION accessor without a
    // bounds check (a panic on a bad index): check that one first, then
    // validate everything else.
    let json = document.into_json();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= json.accessors.len() {
                    return Err(MeshError::Gltf(format!(
                        "primitive {p} of mesh {m}: attribute {semantic:?} refers to accessor {}, which does not exist",
                        index.value()
                    )));
                }
            }
        }
    }
    let document = gltf::Document::from_json(json).map_err(|e| MeshError::Gltf(e.to_string()))?;
    let doc = &document;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut buffers = Buffers { dir, blob: blob.as_deref(), loaded: HashMap::new() };

    // The hierarchy must be a forest (glTF requires it): then walking from
    // the parentless nodes terminates and visits each node once.
    let mut parents = vec![0u32; doc.nodes().len()];
    for n in doc.nodes() {
        for c in n.children() {
            parents[c.index()] += 1;
        }
    }
    if let Some(i) = parents.iter().position(|&p| p > 1) {
        return Err(MeshError::Malformed(format!("node {i} has more than one parent (glTF nodes form trees)")));
    }

    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => doc.nodes().filter(|n| parents[n.index()] == 0).collect(),
    };
    let mut seen = vec![false; parents.len()];
    // (mesh, world matrix) for every node with a mesh under the roots.
    let mut instances: Vec<(gltf::Mesh, DMat4)> = Vec::new();
    let mut stack: Vec<(gltf::Node, DMat4)> = Vec::new();
    // Pushed in reverse so nodes come out in document order.
    for r in roots.into_iter().rev() {
        if parents[r.index()] != 0 {
            return Err(MeshError::Malformed(format!("scene root node {} is also another node's child", r.index())));
        }
        stack.push((r, DMat4::IDENTITY));
    }
    while let Some((node, parent)) = stack.pop() {
        // Guards against a scene that lists a root twice (children have
        // one parent and roots none, so nothing else repeats).
        if std::mem::replace(&mut seen[node.index()], true) {
            continue;
        }
        let world = parent * local_matrix(&node);
        if let Some(m) = node.mesh() {
            instances.push((m, world));
        }
        let children: Vec<gltf::Node> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world));
        }
    }
    if doc.scenes().len() == 0 && doc.nodes().len() == 0 {
        instances = doc.meshes().map(|m| (m, DMat4::IDENTITY)).collect();
    }

    // Count before reading: strips and fans make n − 2 triangles.
    let mut total: u64 = 0;
    for (mesh, _) in &instances {
        for prim in mesh.primitives() {
            let n = element_count(&prim)? as u64;
            let tris = match prim.mode() {
                Mode::Triangles => n / 3,
                Mode::TriangleStrip | Mode::TriangleFan => n.saturating_sub(2),
                other => {
                    return Err(MeshError::Unsupported(format!(
                        "{} draws {}: import-mesh takes closed triangle meshes only (remove the points and lines)",
                        prim_name(mesh, &prim),
                        match other {
                            Mode::Points => "points",
                            _ => "lines",
                        }
                    )));
                }
            };
            total = total.saturating_add(tris);
            if total > limits.max_triangles {
                return Err(MeshError::TooManyTriangles { count: total, max: limits.max_triangles });
            }
        }
    }

    let mut out = TriMesh::default();
    for (mesh, world) in &instances {
        for prim in mesh.primitives() {
            read_primitive(&mut out, &mut buffers, mesh, &prim, world)?;
        }
    }
    Ok(out)
}

fn prim_name(mesh: &gltf::Mesh, prim: &gltf::Primitive) -> String {
    match mesh.name() {
        Some(n) => format!("primitive {} of mesh '{n}'", prim.index()),
        None => format!("primitive {} of mesh {}", prim.index(), mesh.index()),
    }
}

/// A node's local matrix in f64: TRS composed in f64 (the quaternion
/// normalised), a matrix widened.
fn local_matrix(node: &gltf::Node) -> DMat4 {
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => DMat4::from_cols_array_2d(&matrix.map(|c| c.map(f64::from))),
        gltf::scene::Transform::Decomposed { translation, rotation, scale } => {
            let q = DQuat::from_array(rotation.map(f64::from));
            // A zero quaternion is invalid; treat it as no rotation rather
            // than fill the matrix with NaN.
            let q = if q.length_squared() > 0.0 { q.normalize() } else { DQuat::IDENTITY };
            DMat4::from_scale_rotation_translation(DVec3::from_array(scale.map(f64::from)), q, DVec3::from_array(translation.map(f64::from)))
        }
    }
}

/// Vertices a primitive draws: its index count, or its vertex count.
fn element_count(prim: &gltf::Primitive) -> Result<usize, MeshError> {
    match prim.indices() {
        Some(a) => Ok(a.count()),
        None => prim
            .get(&gltf::Semantic::Positions)
            .map(|a| a.count())
            .ok_or_else(|| MeshError::Malformed(format!("primitive {} has no POSITION attribute", prim.index()))),
    }
}

/// One instance of a primitive into `out`: only the vertices its
/// triangles use, in their original order.
fn read_primitive(out: &mut TriMesh, buffers: &mut Buffers, mesh: &gltf::Mesh, prim: &gltf::Primitive, world: &DMat4) -> Result<(), MeshError> {
    let name = prim_name(mesh, prim);
    let pos_acc = prim.get(&gltf::Semantic::Positions).ok_or_else(|| MeshError::Malformed(format!("{name} has no POSITION attribute")))?;
    if pos_acc.dimensions() != Dimensions::Vec3 {
        return Err(MeshError::Malformed(format!("{name}: POSITION is not a VEC3")));
    }
    let positions = accessor_values(&pos_acc, buffers, &name, "POSITION")?;
    let nv = pos_acc.count();

    let colours: Option<(Vec<f64>, usize)> = match prim.get(&gltf::Semantic::Colors(0)) {
        None => None,
        Some(acc) => {
            let ncomp = match acc.dimensions() {
                Dimensions::Vec3 => 3,
                Dimensions::Vec4 => 4,
                _ => return Err(MeshError::Malformed(format!("{name}: COLOR_0 is neither VEC3 nor VEC4"))),
            };
            let ok = match acc.data_type() {
                DataType::F32 => true,
                DataType::U8 | DataType::U16 => acc.normalized(),
                _ => false,
            };
            if !ok {
                return Err(MeshError::Malformed(format!("{name}: COLOR_0 must be float or normalized unsigned byte/short")));
            }
            if acc.count() != nv {
                return Err(MeshError::Malformed(format!("{name}: COLOR_0 has {} entries for {nv} vertices", acc.count())));
            }
            Some((accessor_values(&acc, buffers, &name, "COLOR_0")?, ncomp))
        }
    };
    let factor = prim.material().pbr_metallic_roughness().base_color_factor();

    // The vertex sequence the mode draws.
    let seq: Vec<u32> = match prim.indices() {
        Some(acc) => {
            if acc.dimensions() != Dimensions::Scalar || !matches!(acc.data_type(), DataType::U8 | DataType::U16 | DataType::U32) {
                return Err(MeshError::Malformed(format!("{name}: indices must be unsigned byte, short or int scalars")));
            }
            let raw = accessor_values(&acc, buffers, &name, "indices")?;
            let mut seq = Vec::with_capacity(raw.len());
            for v in raw {
                // Unsigned integers up to 2^32 − 1 are exact in f64.
                if v >= nv as f64 {
                    return Err(MeshError::Malformed(format!("{name}: index {v} is past its {nv} vertices")));
                }
                seq.push(v as u32);
            }
            seq
        }
        None => {
            if nv > u32::MAX as usize {
                return Err(MeshError::Unsupported(format!("{name} has more than 4 billion vertices")));
            }
            (0..nv as u32).collect()
        }
    };
    let mut tris: Vec<[u32; 3]> = match prim.mode() {
        Mode::Triangles => seq.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        // glTF 2.0 §3.7.2.1: strip triangle i is (i, i + 1 + i%2, i + 2 − i%2),
        // fan triangle i is (i + 1, i + 2, 0).
        Mode::TriangleStrip => (0..seq.len().saturating_sub(2)).map(|i| [seq[i], seq[i + 1 + i % 2], seq[i + 2 - i % 2]]).collect(),
        Mode::TriangleFan => (0..seq.len().saturating_sub(2)).map(|i| [seq[i + 1], seq[i + 2], seq[0]]).collect(),
        _ => return Err(MeshError::Unsupported(format!("{name} is not made of triangles"))),
    };
    if world.determinant() < 0.0 {
        for t in &mut tris {
            t.swap(1, 2);
        }
    }

    // Keep only the vertices the triangles use (several primitives may
    // share one large vertex buffer), in their original order.
    let mut remap = vec![u32::MAX; nv];
    for t in &tris {
        for &i in t {
            remap[i as usize] = 0;
        }
    }
    let mut pos_out = Vec::new();
    let mut col_out = Vec::new();
    let f = [factor[0], factor[1], factor[2]];
    for (v, slot) in remap.iter_mut().enumerate() {
        if *slot == u32::MAX {
            continue;
        }
        *slot = pos_out.len() as u32;
        let p = DVec3::new(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
        pos_out.push(world.transform_point3(p).to_array());
        let c = match &colours {
            Some((c, n)) => [0, 1, 2].map(|a| c[n * v + a] as f32 * f[a]),
            None => f,
        };
        col_out.push(c);
    }
    for t in &mut tris {
        *t = t.map(|i| remap[i as usize]);
    }
    append(out, &name, pos_out, col_out, &tris)
}

/// The glTF buffers, loaded when first used.
struct Buffers<'a> {
    /// Where relative URIs resolve.
    dir: PathBuf,
    /// A .glb's BIN chunk.
    blob: Option<&'a [u8]>,
    loaded: HashMap<usize, Vec<u8>>,
}

impl Buffers<'_> {
    /// Buffer `b`'s bytes, `byteLength` of them.
    fn get(&mut self, b: &gltf::Buffer) -> Result<&[u8], MeshError> {
        let want = b.length();
        if !self.loaded.contains_key(&b.index()) {
            let data: Vec<u8> = match b.source() {
                gltf::buffer::Source::Bin => {
                    self.blob.ok_or_else(|| MeshError::Malformed(format!("buffer {} refers to a binary chunk this file does not have", b.index())))?.to_vec()
                }
                gltf::buffer::Source::Uri(uri) => {
                    if let Some(rest) = uri.strip_prefix("data:") {
                        let (_, b64) = rest
                            .split_once(";base64,")
                            .ok_or_else(|| MeshError::Unsupported(format!("buffer {}: only base64 data URIs are supported", b.index())))?;
                        base64_decode(b64).ok_or_else(|| MeshError::Malformed(format!("buffer {}: its data URI is not valid base64", b.index())))?
                    } else if uri.contains("://") {
                        return Err(MeshError::Unsupported(format!("buffer {} is at {uri}: only files next to the glTF are read", b.index())));
                    } else {
                        let file = self.dir.join(percent_decode(uri));
                        std::fs::read(&file).map_err(io_err(&file))?
                    }
                }
            };
            if data.len() < want {
                return Err(MeshError::Malformed(format!("buffer {} holds {} bytes, fewer than its byteLength {want}", b.index(), data.len())));
            }
            self.loaded.insert(b.index(), data);
        }
        let data = self.loaded.get(&b.index()).map(Vec::as_slice).unwrap_or_default();
        Ok(&data[..want.min(data.len())])
    }

    /// A buffer view's bytes.
    fn view(&mut self, v: &gltf::buffer::View) -> Result<&[u8], MeshError> {
        let (off, len) = (v.offset(), v.length());
        let index = v.index();
        let data = self.get(&v.buffer())?;
        off.checked_add(len)
            .and_then(|end| data.get(off..end))
            .ok_or_else(|| MeshError::Malformed(format!("buffer view {index} runs past the end of its buffer")))
    }
}

/// An accessor's elements decoded to f64 (normalized integers mapped as
/// glTF §3.11 says), `count × components` of them; sparse substitution
/// applied. Every offset is bounds-checked: nothing here panics on a
/// malformed file, and nothing is allocated before its data is known to
/// be there.
fn accessor_values(acc: &gltf::Accessor, buffers: &mut Buffers, name: &str, what: &str) -> Result<Vec<f64>, MeshError> {
    let bad = |why: &str| MeshError::Malformed(format!("{name}: the {what} accessor {why}"));
    let ncomp = acc.dimensions().multiplicity();
    let ty = acc.data_type();
    let csize = ty.size();
    let elem = ncomp * csize;
    let count = acc.count();
    let norm = acc.normalized();
    let total = count.checked_mul(ncomp).ok_or_else(|| bad("is too large"))?;

    let mut values = match acc.view() {
        None => {
            // No view: zeros (sparse values may fill some in). Bound the
            // allocation by what a file could sensibly describe.
            if acc.sparse().is_none() {
                return Err(bad("has no data (no buffer view, not sparse)"));
            }
            if total > (1 << 28) {
                return Err(bad("is too large"));
            }
            vec![0.0; total]
        }
        Some(view) => {
            let stride = view.stride().unwrap_or(elem);
            if stride < elem {
                return Err(bad("has a byteStride shorter than its elements"));
            }
            let data = buffers.view(&view)?;
            let start = acc.offset();
            if count > 0 {
                let end =
                    (count - 1).checked_mul(stride).and_then(|v| v.checked_add(start)).and_then(|v| v.checked_add(elem)).ok_or_else(|| bad("is too large"))?;
                if end > data.len() {
                    return Err(bad("runs past the end of its buffer view"));
                }
            }
            let mut values = Vec::with_capacity(total);
            for e in 0..count {
                let at = start + e * stride;
                for c in 0..ncomp {
                    let o = at + c * csize;
                    values.push(decode(&data[o..o + csize], ty, norm));
                }
            }
            values
        }
    };

    if let Some(sparse) = acc.sparse() {
        let n = sparse.count();
        let idx = sparse.indices();
        let vals = sparse.values();
        let isize_ = idx.index_type().size();
        let idx_ty = match idx.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let idx_bytes = {
            let d = buffers.view(&idx.view())?;
            let end = n.checked_mul(isize_).and_then(|v| v.checked_add(idx.offset())).ok_or_else(|| bad("has a too large sparse part"))?;
            d.get(idx.offset()..end).ok_or_else(|| bad("has sparse indices past their buffer view"))?.to_vec()
        };
        let d = buffers.view(&vals.view())?;
        let end = n.checked_mul(elem).and_then(|v| v.checked_add(vals.offset())).ok_or_else(|| bad("has a too large sparse part"))?;
        let val_bytes = d.get(vals.offset()..end).ok_or_else(|| bad("has sparse values past their buffer view"))?;
        for s in 0..n {
            let i = decode(&idx_bytes[s * isize_..(s + 1) * isize_], idx_ty, false) as usize;
            if i >= count {
                return Err(bad("has a sparse index past its count"));
            }
            for c in 0..ncomp {
                let o = s * elem + c * csize;
                values[i * ncomp + c] = decode(&val_bytes[o..o + csize], ty, norm);
            }
        }
    }
    Ok(values)
}

/// One little-endian component; `b` holds exactly its bytes.
fn decode(b: &[u8], ty: DataType, normalized: bool) -> f64 {
    let raw = |n: usize| -> [u8; 4] {
        let mut a = [0u8; 4];
        a[..n].copy_from_slice(&b[..n]);
        a
    };
    match ty {
        DataType::I8 => {
            let v = f64::from(b[0] as i8);
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U8 => {
            let v = f64::from(b[0]);
            if normalized { v / 255.0 } else { v }
        }
        DataType::I16 => {
            let a = raw(2);
            let v = f64::from(i16::from_le_bytes([a[0], a[1]]));
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        DataType::U16 => {
            let a = raw(2);
            let v = f64::from(u16::from_le_bytes([a[0], a[1]]));
            if normalized { v / 65535.0 } else { v }
        }
        DataType::U32 => {
            let v = f64::from(u32::from_le_bytes(raw(4)));
            if normalized { v / 4294967295.0 } else { v }
        }
        DataType::F32 => f64::from(f32::from_le_bytes(raw(4))),
    }
}

/// Standard base64 (RFC 4648, padding optional); None on a bad character.
fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b'=' => break,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

/// A URI path's %XX escapes decoded (glTF URIs are RFC 3986).
fn percent_decode(s: &str) -> String {
    let hex = |c: u8| (c as char).to_digit(16);
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(hi), Some(lo)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((hi * 16 + lo) as u8);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

// ----------------------------------------------------------------- OBJ
