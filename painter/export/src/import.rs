//! Imports: OpenVDB fog volumes and closed meshes turned into voxel sets
//! (spec 15) that an `import` event paints into a layer
//! (docs/documents.md, "Imports"). The inverse of the exports: the same
//! [`Placement`] (origin, scale, up axis) and colour space put a file's
//! contents back where an export with those options took them from.

use std::collections::HashMap;

use glam::DVec3;
use octopaint_tree::trace::Canvas;
use octopaint_tree::voxels::{MAX_VOXELS, VoxelSet};

use crate::Placement;
use crate::mesh_read::TriMesh;
use crate::values::ColourSpace;
use crate::vdb_read::{Grid, Values};
use crate::voxelise::{SolidGrid, check_closed, voxelise};

/// A file position back on the canvas: `p = origin + unturn(file) / scale`
/// (the inverse of [`Placement::apply`]).
fn to_canvas(pl: &Placement, w: DVec3, allow_z_up: bool) -> DVec3 {
    DVec3::from_array(pl.origin) + unturn(pl, w, allow_z_up) / pl.scale
}

/// The inverse of [`Placement::turn`]: (x, −z, y) → (x, y, z).
fn unturn(pl: &Placement, v: DVec3, allow_z_up: bool) -> DVec3 {
    if pl.z_up && allow_z_up { DVec3::new(v.x, v.z, -v.y) } else { v }
}

/// The stored sRGB byte of a colour channel (spec 5: `floor(v·255 + 0.5)`
/// clamped), from linear or sRGB-encoded values as `colour` says.
fn srgb_byte(v: f32, colour: ColourSpace) -> u8 {
    let v = f64::from(v);
    let e = match colour {
        ColourSpace::Srgb => v,
        ColourSpace::Linear => linear_to_srgb(v),
    };
    let q = (e * 255.0 + 0.5).floor();
    if q.is_nan() { 0 } else { q.clamp(0.0, 255.0) as u8 }
}

/// The sRGB transfer function (IEC 61966-2-1), for values in [0, 1].
pub fn linear_to_srgb(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.0031308 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// The edge of a voxel at `depth` in canvas units.
fn edge(canvas: &Canvas, depth: u32) -> f64 {
    canvas.root_size * (2.0f64).powi(-(depth as i32))
}

/// The depth whose cell edge is nearest `size` canvas units (on a log
/// scale), within [0, max_depth].
pub fn nearest_depth(canvas: &Canvas, size: f64) -> u32 {
    let d = (canvas.root_size / size).log2().round();
    if d.is_nan() { 0 } else { d.clamp(0.0, f64::from(canvas.max_depth)) as u32 }
}

/// The voxel of depth `depth` holding canvas point `p`, or None outside.
fn voxel_of(canvas: &Canvas, depth: u32, p: DVec3) -> Option<[u32; 3]> {
    let h = edge(canvas, depth);
    let mut q = [0u32; 3];
    for a in 0..3 {
        let x = (p[a] / h).floor();
        let extent = f64::from(canvas.roots[a]) * (2.0f64).powi(depth as i32);
        if !(x >= 0.0 && x < extent) {
            return None;
        }
        q[a] = x as u32;
    }
    Some(q)
}

/// What [`voxels_from_vdb`] did, for the command to report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VdbImportReport {
    pub depth: u32,
    /// The VDB's voxel edge in canvas units (largest axis).
    pub vdb_voxel: f64,
    /// Active voxels and tiles read from the density grid.
    pub active: u64,
    /// Of those, how many fell outside the canvas (dropped).
    pub outside: u64,
    pub voxels: usize,
}

/// Accumulated extinction·volume and colour weight of one target voxel.
#[derive(Clone, Copy, Default)]
struct Acc {
    sigma_vol: f64,
    rgb_w: [f64; 3],
    w: f64,
}

/// A fog volume (a float `density` grid, extinction per file unit, and an
/// optional vec3 `color` grid on the same transform) as a voxel set at
/// `depth` (default: the depth nearest the VDB's voxel size), placed as
/// `placement` says. Where the VDB's voxels are at least as large as the
/// set's, every set voxel whose centre lies in an active VDB voxel or tile
/// takes its value (point sampling, exact when both grids align, as after
/// an export); where they are smaller, each set voxel takes the average
/// extinction of the VDB voxels whose centres it holds (inactive ones
/// count as 0) and their extinction-weighted colour. Voxels with no
/// colour grid value take `tint` (sRGB, 0..1). Voxels of extinction 0 are
/// left out: the import keeps what is painted there.
pub fn voxels_from_vdb(
    density: &Grid,
    color: Option<&Grid>,
    canvas: &Canvas,
    depth: Option<u32>,
    placement: &Placement,
    colour: ColourSpace,
    tint: [f64; 3],
) -> Result<(VoxelSet, VdbImportReport), String> {
    let Values::Float(dv) = &density.voxel_values else { return Err(format!("grid {:?} is not a float grid", density.name)) };
    let Values::Float(tv) = &density.tile_values else { return Err(format!("grid {:?} is not a float grid", density.name)) };
    if !(placement.scale.is_finite() && placement.scale > 0.0) {
        return Err(format!("--scale {}: expected a positive number", placement.scale));
    }
    let s = density.transform.scale;
    let t = density.transform.translate;
    if s.iter().chain(&t).any(|v| !v.is_finite()) || s.contains(&0.0) {
        return Err(format!("grid {:?} has a degenerate transform (scale {s:?})", density.name));
    }
    // The VDB voxel's edges on the canvas, per canvas axis.
    let vox_canvas = unturn(placement, DVec3::from_array(s), true).abs() / placement.scale;
    let vdb_voxel = vox_canvas.max_element();
    let depth = match depth {
        Some(d) if d > canvas.max_depth => return Err(format!("--depth {d} is deeper than the canvas's max depth {}", canvas.max_depth)),
        Some(d) => d,
        None => nearest_depth(canvas, vdb_voxel),
    };
    let h = edge(canvas, depth);
    // Colour lookup by index (both grids share the transform in files the
    // exports write; otherwise the colour grid is sampled at the centre).
    let mut report = VdbImportReport { depth, vdb_voxel, ..Default::default() };
    let world = |i: [f64; 3]| DVec3::new(i[0] * s[0] + t[0], i[1] * s[1] + t[1], i[2] * s[2] + t[2]);
    let coarse = vdb_voxel >= h * (1.0 - 1e-9);
    // Sources: (index of the lowest voxel, edge in voxels, density, colour).
    // Sources: (the density grid's voxel or tile, its place in the grid's
    // lists: a colour grid of the same topology is read by that place).
    let n_vox = density.voxels.len();
    let voxels = density.voxels.iter().zip(dv).enumerate().map(|(i, (c, &v))| (i, *c, 1u32, v));
    let tiles = density.tiles.iter().zip(tv).enumerate().map(move |(i, (&(c, e), &v))| (n_vox + i, c, e, v));
    // How many voxels the set could get, counted before any is made, so
    // that a depth too fine is refused at once, with one that fits.
    let estimate_at = |d: u32| estimate_voxels(density, canvas, d, placement);
    let estimate = estimate_at(depth);
    if estimate > MAX_VOXELS as f64 {
        let fits = (0..depth).rev().find(|&d| estimate_at(d) <= MAX_VOXELS as f64);
        return Err(match fits {
            Some(fits) => format!(
                "the import would make up to {estimate:.0} voxels at depth {depth}, more than {MAX_VOXELS}: --depth {fits} or coarser fits (cells of {:.4} canvas units)",
                edge(canvas, fits)
            ),
            None => format!("the import would make up to {estimate:.0} voxels even at depth 0: import a part of the file"),
        });
    }
    let colour_at = build_colour_lookup(color, density)?;
    let mut acc: HashMap<[u32; 3], Acc> = HashMap::new();
    let mut budget = MAX_VOXELS;
    for (place, c, e, dens) in voxels.chain(tiles) {
        report.active += u64::from(e).pow(3);
        if !(dens.is_finite() && dens > 0.0) {
            continue; // empty (or absurd): nothing to paint
        }
        let sigma = f64::from(dens) * placement.scale;
        // The colour as the stored sRGB byte would hold it (0..1).
        let rgb = match colour_at(place, c) {
            Some(v) => v.map(|x| f64::from(srgb_byte(x, colour)) / 255.0),
            None => tint.map(|x| (x * 255.0 + 0.5).floor().clamp(0.0, 255.0) / 255.0),
        };
        let lo_i = c.map(|v| f64::from(v) - 0.5);
        let hi_i = c.map(|v| f64::from(v) + f64::from(e) - 0.5);
        // The box on the canvas (a turn swaps axes and may flip one).
        let (a, b) = (to_canvas(placement, world(lo_i), true), to_canvas(placement, world(hi_i), true));
        let (lo, hi) = (a.min(b), a.max(b));
        if coarse || e > 1 {
            // Every set voxel whose centre lies in the box.
            let first = (lo / h - 0.5).ceil();
            let last = (hi / h - 0.5).ceil() - DVec3::ONE; // centres < hi
            let n = (last - first + DVec3::ONE).max(DVec3::ZERO);
            let count = n.x * n.y * n.z;
            if count > budget as f64 {
                return Err(format!("the import would make more than {MAX_VOXELS} voxels at depth {depth}: choose a coarser --depth"));
            }
            if count == 0.0 && !coarse {
                // A fine tile smaller than a set voxel: its centre's voxel.
                add_fine(&mut acc, canvas, depth, (lo + hi) * 0.5, sigma, (hi - lo).x * (hi - lo).y * (hi - lo).z, rgb, &mut report);
                continue;
            }
            let mut any = false;
            for k in first.z as i64..=last.z as i64 {
                for j in first.y as i64..=last.y as i64 {
                    for i in first.x as i64..=last.x as i64 {
                        let p = DVec3::new((i as f64 + 0.5) * h, (j as f64 + 0.5) * h, (k as f64 + 0.5) * h);
                        if let Some(q) = voxel_of(canvas, depth, p) {
                            any = true;
                            let slot = acc.entry(q).or_default();
                            // Point sampling: the last source wins (sources do not overlap).
                            *slot = Acc { sigma_vol: sigma * h * h * h, rgb_w: rgb.map(|x| x * sigma), w: sigma };
                        }
                    }
                }
            }
            budget = MAX_VOXELS.saturating_sub(acc.len() as u64);
            if !any {
                report.outside += u64::from(e).pow(3);
            }
        } else {
            let vol = vox_canvas.x * vox_canvas.y * vox_canvas.z;
            add_fine(&mut acc, canvas, depth, (lo + hi) * 0.5, sigma, vol, rgb, &mut report);
            if acc.len() as u64 > MAX_VOXELS {
                return Err(format!("the import would make more than {MAX_VOXELS} voxels at depth {depth}: choose a coarser --depth"));
            }
        }
    }
    let mut entries: Vec<([u32; 3], Acc)> = acc.into_iter().collect();
    entries.sort_unstable_by_key(|(q, _)| [q[2], q[1], q[0]]);
    let cell_vol = h * h * h;
    let mut vs = VoxelSet { depth, ..Default::default() };
    for (q, a) in entries {
        let sigma = a.sigma_vol / cell_vol;
        let sigma = if sigma > f64::from(f32::MAX) { f32::MAX } else { sigma as f32 };
        if !(sigma > 0.0) {
            continue;
        }
        let rgb = a.rgb_w.map(|x| {
            let v = (x / a.w * 255.0 + 0.5).floor();
            if v.is_nan() { 0 } else { v.clamp(0.0, 255.0) as u8 }
        });
        vs.ijk.push(q);
        vs.rgb.push(rgb);
        vs.sigma.push(sigma);
    }
    report.voxels = vs.len();
    Ok((vs, report))
}

#[allow(clippy::too_many_arguments)]
fn add_fine(acc: &mut HashMap<[u32; 3], Acc>, canvas: &Canvas, depth: u32, p: DVec3, sigma: f64, vol: f64, rgb: [f64; 3], report: &mut VdbImportReport) {
    match voxel_of(canvas, depth, p) {
        Some(q) => {
            let a = acc.entry(q).or_default();
            a.sigma_vol += sigma * vol;
            for c in 0..3 {
                a.rgb_w[c] += rgb[c] * sigma * vol;
            }
            a.w += sigma * vol;
        }
        None => report.outside += 1,
    }
}

/// An upper bound on the voxels [`voxels_from_vdb`] makes of `density` at
/// `depth` (counted, not made: each source's box in cells, at least one).
pub fn estimate_voxels(density: &Grid, canvas: &Canvas, depth: u32, placement: &Placement) -> f64 {
    let (Values::Float(dv), Values::Float(tv)) = (&density.voxel_values, &density.tile_values) else { return 0.0 };
    let (s, t) = (density.transform.scale, density.transform.translate);
    let world = |i: [f64; 3]| DVec3::new(i[0] * s[0] + t[0], i[1] * s[1] + t[1], i[2] * s[2] + t[2]);
    let vdb_voxel = (unturn(placement, DVec3::from_array(s), true).abs() / placement.scale).max_element();
    let h = edge(canvas, depth);
    let coarse = vdb_voxel >= h * (1.0 - 1e-9);
    let mut estimate = 0.0f64;
    let sources = density.voxels.iter().zip(dv).map(|(c, &v)| (*c, 1u32, v)).chain(density.tiles.iter().zip(tv).map(|(&(c, e), &v)| (c, e, v)));
    for (c, e, dens) in sources {
        if !(dens.is_finite() && dens > 0.0) {
            continue;
        }
        if coarse || e > 1 {
            let lo_i = c.map(|v| f64::from(v) - 0.5);
            let hi_i = c.map(|v| f64::from(v) + f64::from(e) - 0.5);
            let (a, b) = (to_canvas(placement, world(lo_i), true), to_canvas(placement, world(hi_i), true));
            let (lo, hi) = (a.min(b), a.max(b));
            let n = (((hi / h - 0.5).ceil() - (lo / h - 0.5).ceil()).max(DVec3::ZERO)).max(DVec3::ONE);
            estimate += n.x * n.y * n.z;
        } else {
            estimate += 1.0;
        }
    }
    estimate
}

type ColourAt<'a> = Box<dyn Fn(usize, [i32; 3]) -> Option<[f32; 3]> + 'a>;

/// The colour grid's value for a density voxel or tile: by its place in
/// the lists when the two grids have the same topology (what the exports
/// write: one topology for both), else by its index (a tile's value for
/// the voxels it covers, the background elsewhere). The grids must share
/// their transform: resampling one grid onto another is not done here.
fn build_colour_lookup<'a>(color: Option<&'a Grid>, density: &Grid) -> Result<ColourAt<'a>, String> {
    let Some(g) = color else { return Ok(Box::new(|_, _| None)) };
    if g.transform != density.transform {
        return Err(format!("the colour grid {:?} and the density grid {:?} have different transforms", g.name, density.name));
    }
    let (Values::Vec3(vv), Values::Vec3(tv)) = (&g.voxel_values, &g.tile_values) else {
        return Err(format!("grid {:?} is not a vec3 grid", g.name));
    };
    if g.voxels == density.voxels && g.tiles == density.tiles {
        let n = vv.len();
        return Ok(Box::new(move |place: usize, _| if place < n { vv.get(place).copied() } else { tv.get(place - n).copied() }));
    }
    let voxels: HashMap<[i32; 3], [f32; 3]> = g.voxels.iter().copied().zip(vv.iter().copied()).collect();
    let tiles: Vec<([i32; 3], u32, [f32; 3])> = g.tiles.iter().zip(tv).map(|(&(c, e), &v)| (c, e, v)).collect();
    let bg = match &g.background {
        Values::Vec3(b) => b.first().copied(),
        Values::Float(_) => None,
    };
    Ok(Box::new(move |_, c: [i32; 3]| {
        if let Some(v) = voxels.get(&c) {
            return Some(*v);
        }
        for &(o, e, v) in &tiles {
            let e = i64::from(e);
            if (0..3).all(|a| i64::from(c[a]) >= i64::from(o[a]) && i64::from(c[a]) < i64::from(o[a]) + e) {
                return Some(v);
            }
        }
        bg
    }))
}

/// What [`voxels_from_mesh`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshImportReport {
    pub depth: u32,
    pub triangles: u64,
    pub welded_vertices: u64,
    pub voxels: usize,
}

/// A closed mesh (file units, placed by `placement`; glTF is +y up and
/// ignores `z_up`, `allow_z_up` false) as solid voxels at `depth`: every
/// voxel whose centre is inside (ray parity; a mesh with holes or
/// inconsistent orientation is refused by [`check_closed`]), with the
/// mesh's colour there and extinction `sigma` per canvas unit.
pub fn voxels_from_mesh(
    mesh: &TriMesh,
    canvas: &Canvas,
    depth: u32,
    placement: &Placement,
    allow_z_up: bool,
    sigma: f64,
) -> Result<(VoxelSet, MeshImportReport), String> {
    if depth > canvas.max_depth {
        return Err(format!("--depth {depth} is deeper than the canvas's max depth {}", canvas.max_depth));
    }
    if !(sigma.is_finite() && sigma > 0.0 && sigma <= f64::from(f32::MAX)) {
        return Err(format!("--sigma {sigma}: expected a positive extinction per canvas unit"));
    }
    if !(placement.scale.is_finite() && placement.scale > 0.0) {
        return Err(format!("--scale {}: expected a positive number", placement.scale));
    }
    let closed = check_closed(mesh).map_err(|e| e.to_string())?;
    // The mesh on the canvas, then voxelised on the canvas's own grid at
    // `depth`, clipped to the canvas.
    let placed = TriMesh {
        positions: mesh.positions.iter().map(|p| to_canvas(placement, DVec3::from_array(*p), allow_z_up).to_array()).collect(),
        colours: mesh.colours.clone(),
        triangles: mesh.triangles.clone(),
    };
    let h = edge(canvas, depth);
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in &placed.positions {
        let p = DVec3::from_array(*p);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let mut report = MeshImportReport { depth, triangles: closed.triangles, welded_vertices: closed.vertices_welded, voxels: 0 };
    if placed.positions.is_empty() {
        return Ok((VoxelSet { depth, ..Default::default() }, report));
    }
    let extent = canvas.roots.map(|r| f64::from(r) * (2.0f64).powi(depth as i32));
    let first = [0, 1, 2].map(|a| (lo[a] / h).floor().clamp(0.0, extent[a]));
    let last = [0, 1, 2].map(|a| (hi[a] / h).ceil().clamp(0.0, extent[a]));
    let dims = [0, 1, 2].map(|a| last[a] - first[a]);
    if dims.iter().any(|&d| d <= 0.0) {
        return Err("the mesh lies outside the canvas (check --origin and --scale)".into());
    }
    if dims.iter().any(|&d| d > f64::from(u32::MAX)) {
        return Err(format!("the mesh spans more than 2^32 voxels at depth {depth}: choose a coarser --depth"));
    }
    let grid = SolidGrid { origin: first.map(|f| f * h), h, dims: dims.map(|d| d as u32) };
    let inside = voxelise(&placed, &grid, MAX_VOXELS).map_err(|e| e.to_string())?;
    let mut vs = VoxelSet { depth, ..Default::default() };
    let s32 = sigma as f32;
    for (ijk, rgb) in inside {
        vs.ijk.push([0, 1, 2].map(|a| ijk[a] + first[a] as u32));
        vs.rgb.push(rgb.map(|v| srgb_byte(v, ColourSpace::Linear)));
        vs.sigma.push(s32);
    }
    report.voxels = vs.len();
    Ok((vs, report))
}
