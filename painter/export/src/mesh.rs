//! Writers for the iso-surface (`dual::Mesh`): glTF 2.0 binary (.glb) and
//! Wavefront OBJ with per-vertex colours (docs/export.md, "Meshes").
//!
//! glTF stores f32 positions. A painting may span kilometres with
//! sub-millimetre detail, so the positions are written relative to the
//! centre of the mesh's bounding box and the node carries that centre as
//! its translation: the rounding is then relative to the mesh's own
//! extent, not to its distance from the canvas origin.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Write;

use glam::DVec3;
use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;

use crate::dual::Mesh;
use crate::values::ColourSpace;
use crate::{ExportError, Placement};

/// Area-weighted vertex normals, pointing out of the painted volume.
pub fn vertex_normals(mesh: &Mesh) -> Vec<DVec3> {
    let mut n = vec![DVec3::ZERO; mesh.positions.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        // Twice the area times the unit normal: larger faces weigh more.
        let f = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += f;
        }
    }
    n.into_iter().map(|v| v.try_normalize().unwrap_or(DVec3::Y)).collect()
}

fn pad4(v: &mut Vec<u8>, byte: u8) {
    while !v.len().is_multiple_of(4) {
        v.push(byte);
    }
}

/// The glTF binary of `mesh`: one node, one mesh, one primitive with
/// POSITION, NORMAL, COLOR_0 (linear, as glTF defines it, whatever
/// `colour` says; `colour` only matters to formats without a convention)
/// and u32 indices, a rough dielectric material whose base colour is the
/// vertex colour.
pub fn glb_bytes(mesh: &Mesh, placement: Placement, generator: &str) -> Result<Vec<u8>, ExportError> {
    glb_bytes_named(&[("painting", mesh)], placement, generator)
}

/// [`glb_bytes`] for several meshes (a document's layers, spec 14): one
/// node and one mesh per entry, named by it, in order, sharing the buffer
/// and the material.
pub fn glb_bytes_named(meshes: &[(&str, &Mesh)], placement: Placement, generator: &str) -> Result<Vec<u8>, ExportError> {
    struct Part {
        centre: DVec3,
        rel: Vec<[f32; 3]>,
        nv: usize,
        ni: usize,
        offset: usize,
    }
    let mut bin: Vec<u8> = Vec::new();
    let mut parts = Vec::with_capacity(meshes.len());
    let total: u64 = meshes.iter().map(|(_, m)| (m.positions.len() * 36 + m.triangles.len() * 12) as u64).sum::<u64>() + 4096;
    if total > u64::from(u32::MAX) {
        return Err(ExportError::FormatLimit { what: "a glTF binary", bytes: total });
    }
    bin.reserve(total as usize);
    for (_, mesh) in meshes {
        let positions: Vec<DVec3> = mesh.positions.iter().map(|&p| placement.apply(p, false)).collect();
        let (lo, hi) = bounds(&positions);
        let centre = (lo + hi) * 0.5;
        let rel: Vec<[f32; 3]> = positions.iter().map(|&p| (p - centre).as_vec3().to_array()).collect();
        let normals = vertex_normals(mesh);
        let colours: Vec<[f32; 3]> = mesh.colours.iter().map(|&c| ColourSpace::Linear.encode(c)).collect();
        let offset = bin.len();
        for p in &rel {
            bin.extend_from_slice(bytemuck_f32(p));
        }
        for n in &normals {
            bin.extend_from_slice(bytemuck_f32(&n.as_vec3().to_array()));
        }
        for c in &colours {
            bin.extend_from_slice(bytemuck_f32(c));
        }
        for t in &mesh.triangles {
            for i in t {
                bin.extend_from_slice(&i.to_le_bytes());
            }
        }
        parts.push(Part { centre, nv: rel.len(), ni: mesh.triangles.len() * 3, rel, offset });
    }
    pad4(&mut bin, 0);

    let mut root = json::Root::default();
    root.asset.generator = Some(generator.to_string());
    let buffer =
        root.push(json::Buffer { byte_length: USize64::from(bin.len()), extensions: Default::default(), extras: Default::default(), name: None, uri: None });
    let view = |root: &mut json::Root, offset: usize, length: usize, target: json::buffer::Target| {
        root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(length),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: Some(Valid(target)),
        })
    };
    let accessor = |root: &mut json::Root,
                    view: json::Index<json::buffer::View>,
                    count: usize,
                    component: json::accessor::ComponentType,
                    type_: json::accessor::Type,
                    min_max: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64(0)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min: min_max.map(|(lo, _)| json::Value::from(lo.to_vec())),
            max: min_max.map(|(_, hi)| json::Value::from(hi.to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType as C, Type as T};
    let mut attributes = Vec::with_capacity(parts.len());
    for part in &parts {
        let (nv, ni, o) = (part.nv, part.ni, part.offset);
        let vec3 = nv * 12;
        let v_pos = view(&mut root, o, vec3, json::buffer::Target::ArrayBuffer);
        let v_nrm = view(&mut root, o + vec3, vec3, json::buffer::Target::ArrayBuffer);
        let v_col = view(&mut root, o + 2 * vec3, vec3, json::buffer::Target::ArrayBuffer);
        let v_idx = view(&mut root, o + 3 * vec3, ni * 4, json::buffer::Target::ElementArrayBuffer);
        let (rlo, rhi) = f32_bounds(&part.rel);
        let a_pos = accessor(&mut root, v_pos, nv, C::F32, T::Vec3, Some((rlo, rhi)));
        let a_nrm = accessor(&mut root, v_nrm, nv, C::F32, T::Vec3, None);
        let a_col = accessor(&mut root, v_col, nv, C::F32, T::Vec3, None);
        let a_idx = accessor(&mut root, v_idx, ni, C::U32, T::Scalar, None);
        attributes.push((a_pos, a_nrm, a_col, a_idx));
    }
    let material = root.push(json::Material {
        name: Some("paint".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([1.0; 4]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(0.8),
            ..Default::default()
        },
        ..Default::default()
    });
    let mut nodes = Vec::with_capacity(parts.len());
    for ((part, (a_pos, a_nrm, a_col, a_idx)), (name, _)) in parts.iter().zip(attributes).zip(meshes) {
        let primitive = json::mesh::Primitive {
            attributes: BTreeMap::from([
                (Valid(json::mesh::Semantic::Positions), a_pos),
                (Valid(json::mesh::Semantic::Normals), a_nrm),
                (Valid(json::mesh::Semantic::Colors(0)), a_col),
            ]),
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(a_idx),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
        };
        let gmesh = root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: Some((*name).to_string()),
            primitives: vec![primitive],
            weights: None,
        });
        nodes.push(root.push(json::Node {
            mesh: Some(gmesh),
            name: Some((*name).to_string()),
            translation: Some(part.centre.as_vec3().to_array()),
            ..Default::default()
        }));
    }
    let scene = root.push(json::Scene { extensions: Default::default(), extras: Default::default(), name: None, nodes });
    root.scene = Some(scene);

    let mut json_bytes = json::serialize::to_vec(&root).map_err(|e| ExportError::Io(std::io::Error::other(e)))?;
    pad4(&mut json_bytes, b' ');
    let length = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let length = u32::try_from(length).map_err(|_| ExportError::FormatLimit { what: "a glTF binary", bytes: length as u64 })?;
    let glb =
        gltf::binary::Glb { header: gltf::binary::Header { magic: *b"glTF", version: 2, length }, bin: Some(Cow::Owned(bin)), json: Cow::Owned(json_bytes) };
    glb.to_vec().map_err(|e| ExportError::Io(std::io::Error::other(e)))
}

fn bytemuck_f32(v: &[f32; 3]) -> &[u8] {
    bytemuck::cast_slice(v)
}

fn bounds(p: &[DVec3]) -> (DVec3, DVec3) {
    if p.is_empty() {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    p.iter().fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), &q| (lo.min(q), hi.max(q)))
}

fn f32_bounds(p: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    if p.is_empty() {
        return ([0.0; 3], [0.0; 3]);
    }
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for q in p {
        for a in 0..3 {
            lo[a] = lo[a].min(q[a]);
            hi[a] = hi[a].max(q[a]);
        }
    }
    (lo, hi)
}

/// `mesh` as Wavefront OBJ: `v x y z r g b` (the vertex-colour extension
/// Blender, MeshLab and most importers read), `vn` normals, `f a//a b//b
/// c//c` faces. Positions in f64 (shortest round-trip decimal), relative
/// to the canvas origin; colours in `colour`.
pub fn write_obj(w: &mut dyn Write, mesh: &Mesh, placement: Placement, colour: ColourSpace, generator: &str) -> std::io::Result<()> {
    write_obj_named(w, &[("painting", mesh)], placement, colour, generator)
}

/// [`write_obj`] for several meshes (a document's layers): one object
/// (`o NAME`) per entry, in order, indices running on across them.
pub fn write_obj_named(w: &mut dyn Write, meshes: &[(&str, &Mesh)], placement: Placement, colour: ColourSpace, generator: &str) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::with_capacity(1 << 20, w);
    writeln!(w, "# {generator}")?;
    writeln!(
        w,
        "# {} vertices, {} triangles; colours {}; {} up",
        meshes.iter().map(|(_, m)| m.positions.len()).sum::<usize>(),
        meshes.iter().map(|(_, m)| m.triangles.len()).sum::<usize>(),
        match colour {
            ColourSpace::Linear => "linear",
            ColourSpace::Srgb => "sRGB",
        },
        if placement.z_up { "+z" } else { "+y" }
    )?;
    let mut base = 1u64;
    for (name, mesh) in meshes {
        // OBJ names end at the line: a name's line breaks become spaces.
        writeln!(w, "o {}", name.replace(['\n', '\r'], " "))?;
        for (p, c) in mesh.positions.iter().zip(&mesh.colours) {
            let p = placement.apply(*p, true);
            let c = colour.encode(*c);
            writeln!(w, "v {} {} {} {} {} {}", p.x, p.y, p.z, c[0], c[1], c[2])?;
        }
        for n in vertex_normals(mesh) {
            let n = placement.turn(n, true).as_vec3();
            writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
        }
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| u64::from(i) + base);
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
        }
        base += mesh.positions.len() as u64;
    }
    w.flush()
}
