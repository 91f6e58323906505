//! `octopaint import-vdb` and `octopaint import-mesh`: a fog volume or a
//! closed mesh turned into a voxel set (spec 15) and painted into a layer
//! of a document as one undoable step (docs/documents.md, "Imports").
//! All or nothing: a file that cannot be read, a mesh with holes, a layer
//! that is locked or a cell budget that cannot hold the whole import
//! leaves the document as it was.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use octopaint_doc::{DocError, Session};
use octopaint_export::import::{nearest_depth, voxels_from_mesh, voxels_from_vdb};
use octopaint_export::mesh_read::{MeshLimits, read_mesh};
use octopaint_export::vdb_read::{ReadLimits, Values, read_vdb};
use octopaint_export::{ColourSpace, Placement};
use octopaint_tree::trace::{Event, EventKind, LayerOp, LayerOpKind};
use octopaint_tree::voxels::{MAX_VOXELS, VoxelSet};

use crate::export::{ColourChoice, UpChoice, parse_point, placement_of};

/// Where the file goes on the canvas, and into which layer.
#[derive(clap::Args)]
pub struct Target {
    /// The layer to paint into: made (above the selected one) if the
    /// document has none of that name; a one-tree document becomes a
    /// document of layers first. Without it: the selected layer (the tree
    /// of a one-tree document).
    #[arg(long, value_name = "NAME")]
    pub layer: Option<String>,
    /// File units per canvas unit, as for `export --scale`: positions are
    /// divided by it and extinction multiplied, so an export read back with
    /// the same options lands where it came from.
    #[arg(long, value_name = "S", default_value_t = 1.0, allow_negative_numbers = true)]
    pub scale: f64,
    /// The canvas point the file's origin goes to (X,Y,Z, canvas units);
    /// default the canvas's corner, as for `export --origin`.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    pub origin: Option<[f64; 3]>,
    /// The file's up axis (the VDB and OBJ; glTF is +y up by definition).
    #[arg(long, value_enum, default_value_t = UpChoice::Y)]
    pub up: UpChoice,
    /// The voxel depth of the import (voxel edge = root size / 2^DEPTH).
    #[arg(long, value_name = "DEPTH")]
    pub depth: Option<u32>,
}

#[derive(clap::Args)]
pub struct VdbArgs {
    /// The OpenVDB file: a fog volume (a float density grid, extinction
    /// per file unit) and optionally a vec3 colour grid on the same
    /// transform.
    pub input: PathBuf,
    /// The document to paint into.
    pub doc: PathBuf,
    #[command(flatten)]
    pub target: Target,
    /// The float grid to read: default `density`, or the one float grid of
    /// the file, or `NAME.density` for --layer NAME (a layered export).
    #[arg(long, value_name = "NAME")]
    pub grid: Option<String>,
    /// The vec3 grid with the colours: default the density grid's name
    /// with `color` for `density` (`color`, `NAME.color`, `Cd`) if the file
    /// has it.
    #[arg(long, value_name = "NAME")]
    pub color_grid: Option<String>,
    /// Colour space of the colour grid, as `export --colour`.
    #[arg(long, value_enum, default_value_t = ColourChoice::Linear)]
    pub colour: ColourChoice,
    /// The colour (sRGB, R,G,B in 0..1) of voxels without one.
    #[arg(long, value_name = "R,G,B", value_parser = parse_point, default_value = "1,1,1")]
    pub tint: [f64; 3],
}

#[derive(clap::Args)]
pub struct MeshArgs {
    /// A closed triangle mesh: glTF (.glb, .gltf) or Wavefront OBJ (.obj).
    pub input: PathBuf,
    /// The document to paint into.
    pub doc: PathBuf,
    #[command(flatten)]
    pub target: Target,
    /// Extinction per canvas unit of the solid (default: 99% of the light
    /// absorbed across one voxel edge).
    #[arg(long, value_name = "SIGMA")]
    pub sigma: Option<f64>,
    /// Refuse meshes past this many triangles.
    #[arg(long, value_name = "N", default_value_t = 50_000_000)]
    pub max_triangles: u64,
}

fn refuse(msg: impl std::fmt::Display) -> ExitCode {
    eprintln!("octopaint: {msg}");
    ExitCode::from(2)
}

fn placement(t: &Target, s: &Session) -> Result<Placement, String> {
    let c = s.doc.canvas();
    placement_of(t.scale, t.origin, t.up, c.roots, c.root_size)
}

/// Select (or make) the target layer, then import: the layer events are
/// steps of their own, the import one more (undo takes it back first).
fn paint_into(s: &mut Session, layer: Option<&str>, vs: &VoxelSet, label: &str) -> Result<(), DocError> {
    if let Some(name) = layer {
        if s.version != 2 {
            s.upgrade_to_layers()?;
        }
        let t = s.last_time();
        let exists = s.doc.layers().any(|l| l.name == name);
        let mut op = LayerOp::new(if exists { LayerOpKind::Select } else { LayerOpKind::Add });
        if exists {
            op.layer = Some(name.to_string());
        } else {
            op.name = Some(name.to_string());
        }
        if !(exists && s.doc.current().name == name) {
            s.apply(&Event { line: 0, t, kind: EventKind::Layer(op) })?;
        }
    }
    s.import(vs, Some(label))
}

/// A label for the import event: the file's name, made a valid layer-style
/// name (spec 15.2).
fn label(path: &Path) -> String {
    let n: String = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
    let n: String = n.chars().filter(|c| !c.is_control()).take(64).collect();
    if n.is_empty() { "import".into() } else { n }
}

pub fn vdb(a: &VdbArgs) -> ExitCode {
    let bytes = match std::fs::read(&a.input) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("octopaint: cannot read {}: {}", a.input.display(), octopaint_tree::trace::io_reason(&e));
            return ExitCode::from(1);
        }
    };
    let (grids, skipped) = match read_vdb(&bytes, &ReadLimits { max_voxels: MAX_VOXELS, tile_cover: false }) {
        Ok(g) => g,
        Err(e) => return refuse(format!("{}: {e}", a.input.display())),
    };
    let mut s = match Session::open(&a.doc) {
        Ok(s) => s,
        Err(e) => return refuse(e),
    };
    let floats: Vec<&str> = grids.iter().filter(|g| matches!(g.voxel_values, Values::Float(_))).map(|g| g.name.as_str()).collect();
    let wanted = match (&a.grid, &a.target.layer) {
        (Some(g), _) => Some(g.clone()),
        (None, _) if floats.contains(&"density") => Some("density".to_string()),
        (None, Some(l)) if floats.contains(&format!("{l}.density").as_str()) => Some(format!("{l}.density")),
        (None, _) if floats.len() == 1 => Some(floats[0].to_string()),
        _ => None,
    };
    let Some(wanted) = wanted else {
        return refuse(format!(
            "{}: which grid? float grids: {} (name one with --grid){}",
            a.input.display(),
            if floats.is_empty() { "none".to_string() } else { floats.join(", ") },
            if skipped.is_empty() {
                String::new()
            } else {
                format!("; not read: {}", skipped.iter().map(|k| format!("{} ({})", k.name, k.grid_type)).collect::<Vec<_>>().join(", "))
            }
        ));
    };
    let Some(density) = grids.iter().find(|g| g.name == wanted && matches!(g.voxel_values, Values::Float(_))) else {
        return refuse(format!("{}: no float grid {wanted:?} (float grids: {})", a.input.display(), floats.join(", ")));
    };
    let colour_name = a.color_grid.clone().or_else(|| {
        let guess = wanted.replace("density", "color");
        [guess.as_str(), "color", "Cd"]
            .into_iter()
            .find(|n| grids.iter().any(|g| g.name == *n && matches!(g.voxel_values, Values::Vec3(_))))
            .map(str::to_string)
    });
    let color = match &colour_name {
        Some(n) => match grids.iter().find(|g| &g.name == n && matches!(g.voxel_values, Values::Vec3(_))) {
            Some(g) => Some(g),
            None => return refuse(format!("{}: no vec3 grid {n:?}", a.input.display())),
        },
        None => None,
    };
    let pl = match placement(&a.target, &s) {
        Ok(p) => p,
        Err(e) => return refuse(e),
    };
    let colour = if a.colour == ColourChoice::Srgb { ColourSpace::Srgb } else { ColourSpace::Linear };
    if a.tint.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return refuse("--tint: each channel in [0, 1]");
    }
    let canvas = *s.doc.canvas();
    let (vs, report) = match voxels_from_vdb(density, color, &canvas, a.target.depth, &pl, colour, a.tint) {
        Ok(r) => r,
        Err(e) => return refuse(format!("{}: {e}", a.input.display())),
    };
    eprintln!(
        "{}: grid {:?}{}: {} active voxels (VDB voxel {:.4} canvas units) -> {} voxels at depth {} (edge {:.4}){}",
        a.input.display(),
        wanted,
        colour_name.map(|n| format!(" with colours from {n:?}")).unwrap_or_default(),
        report.active,
        report.vdb_voxel,
        report.voxels,
        report.depth,
        canvas.root_size * (2.0f64).powi(-(report.depth as i32)),
        if report.outside > 0 { format!("; {} outside the canvas dropped", report.outside) } else { String::new() },
    );
    if a.target.depth.is_none() && report.depth != nearest_depth(&canvas, report.vdb_voxel) {
        eprintln!("octopaint: warning: depth {} chosen", report.depth);
    }
    finish(&mut s, &a.doc, a.target.layer.as_deref(), &vs, &label(&a.input))
}

pub fn mesh(a: &MeshArgs) -> ExitCode {
    let mesh = match read_mesh(&a.input, &MeshLimits { max_triangles: a.max_triangles }) {
        Ok(m) => m,
        Err(e) => return refuse(format!("{}: {e}", a.input.display())),
    };
    let mut s = match Session::open(&a.doc) {
        Ok(s) => s,
        Err(e) => return refuse(e),
    };
    let pl = match placement(&a.target, &s) {
        Ok(p) => p,
        Err(e) => return refuse(e),
    };
    let canvas = *s.doc.canvas();
    let gltf = a.input.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    // Default depth: about 256 voxels across the mesh's longest side.
    let depth = a.target.depth.unwrap_or_else(|| {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in &mesh.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let side = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max) / pl.scale;
        nearest_depth(&canvas, side / 256.0)
    });
    let h = canvas.root_size * (2.0f64).powi(-(depth as i32));
    let sigma = a.sigma.unwrap_or(100f64.ln() / h);
    let (vs, report) = match voxels_from_mesh(&mesh, &canvas, depth, &pl, !gltf, sigma) {
        Ok(r) => r,
        Err(e) => return refuse(format!("{}: {e}", a.input.display())),
    };
    eprintln!(
        "{}: {} triangles, closed; {} voxels inside at depth {} (edge {:.4}), extinction {sigma}",
        a.input.display(),
        report.triangles,
        report.voxels,
        depth,
        h
    );
    finish(&mut s, &a.doc, a.target.layer.as_deref(), &vs, &label(&a.input))
}

fn finish(s: &mut Session, doc: &Path, layer: Option<&str>, vs: &VoxelSet, label: &str) -> ExitCode {
    if vs.is_empty() {
        return refuse("nothing to import: the file has no voxel with extinction above 0 on the canvas");
    }
    match paint_into(s, layer, vs, label) {
        Ok(()) => {
            eprintln!("{}: imported into layer {:?}: {} cells in use", doc.display(), s.doc.current().name, s.doc.used());
            ExitCode::SUCCESS
        }
        Err(e) => refuse(format!("{}: {e}; the document is unchanged", doc.display())),
    }
}
