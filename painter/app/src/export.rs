//! `octopaint export`: a painting to OpenVDB (volumes) and to glTF binary
//! and OBJ (iso-surface meshes) for other tools (docs/export.md).
//!
//! Everything that can refuse the export (the depth, the size cap, the
//! triangle cap, the options) is decided before the first file is written;
//! each file is written to a temporary name beside it and renamed, so an
//! interrupted or refused export leaves the previous files as they were.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use octopaint_export::voxels::{self, VoxelGrid};
use octopaint_export::{ColourSpace, Crop, ExportError, Placement, SurfaceOptions, default_iso, mesh, surface, usd, vdb};
use octopaint_tree::layers::Document;
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::{ReplayObserver, replay_document};
use octopaint_tree::trace::{EventKind, read_trace};

#[derive(clap::Args)]
#[command(after_long_help = "\
Examples:
  octopaint export traces/scene.jsonl --vdb scene.vdb
  octopaint export traces/scene.jsonl --vdb scene.vdb --depth 9 --up z
  octopaint export traces/scene.jsonl --gltf scene.glb --obj scene.obj --iso 2
  octopaint export painting.octo --usd painting.usda --usd-mesh --up z

docs/export.md explains the values written and how Blender and Houdini open them.")]
pub struct Args {
    /// The painting: a document (.octo, with any unsaved strokes of its
    /// journal) or a .jsonl trace, replayed to its end.
    pub input: PathBuf,
    /// Write an OpenVDB file with two grids sharing one topology:
    /// `density` (a float fog volume: extinction per file unit) and
    /// `color` (vec3, the colour space of --colour).
    #[arg(long, value_name = "OUT.vdb")]
    pub vdb: Option<PathBuf>,
    /// Write the iso-surface of the density as glTF 2.0 binary: positions,
    /// normals, linear vertex colours, +y up, metres = canvas units ×
    /// --scale.
    #[arg(long, value_name = "OUT.glb")]
    pub gltf: Option<PathBuf>,
    /// Write the same iso-surface as Wavefront OBJ with vertex colours
    /// (`v x y z r g b`) and normals.
    #[arg(long, value_name = "OUT.obj")]
    pub obj: Option<PathBuf>,
    /// Write a USD stage (ASCII .usda): a Volume whose density and color
    /// fields are the grids of a .vdb written beside it (OUT.vdb, or the
    /// --vdb file when it is in the same folder), with metersPerUnit and
    /// upAxis set.
    #[arg(long, value_name = "OUT.usda")]
    pub usd: Option<PathBuf>,
    /// With --usd: add the iso-surface to the stage as a Mesh with
    /// per-vertex normals and displayColor (linear).
    #[arg(long, requires = "usd")]
    pub usd_mesh: bool,
    /// Depth of the VDB's voxels: a voxel is a cell of this depth, the
    /// canvas's root size / 2^DEPTH wide. Coarser leaves become tiles or
    /// blocks of equal voxels; finer cells are averaged into their voxel.
    /// Default: the deepest painted leaf's depth, or the deepest depth
    /// that fits --max-mib.
    #[arg(long, value_name = "DEPTH")]
    pub depth: Option<u32>,
    /// The largest VDB grid to build, in MiB of uncompressed voxel data
    /// (density and colour together; the file is smaller, compressed).
    /// An explicit --depth past it is refused with the deepest depth that
    /// fits. The grid is built in memory: keep the cap below the RAM.
    #[arg(long, value_name = "MIB", default_value_t = 1024)]
    pub max_mib: u64,
    /// Extinction (per canvas unit) at which the mesh's surface lies:
    /// leaves at or above it are inside. Default: half the median
    /// extinction of the painted leaves.
    #[arg(long, value_name = "SIGMA", allow_negative_numbers = true)]
    pub iso: Option<f64>,
    /// Build the mesh on the tree cut at this depth (deeper cells are
    /// averaged), for a lighter mesh of a very detailed painting. Default:
    /// the tree's own leaves, all of them.
    #[arg(long, value_name = "DEPTH")]
    pub mesh_depth: Option<u32>,
    /// Refuse the mesh past this many triangles.
    #[arg(long, value_name = "N", default_value_t = 50_000_000)]
    pub max_triangles: usize,
    /// Colour space of the VDB `color` grid and of the OBJ's vertex
    /// colours: linear (what Blender's and Houdini's volume shaders and
    /// glTF expect) or the sRGB encoding the painter stores. glTF vertex
    /// colours are always linear.
    #[arg(long, value_enum, default_value_t = ColourChoice::Linear)]
    pub colour: ColourChoice,
    /// File units per canvas unit (e.g. metres per canvas unit). Voxel
    /// size and positions are multiplied by it and extinction divided by
    /// it, so the painting looks the same at any scale.
    #[arg(long, value_name = "S", default_value_t = 1.0, allow_negative_numbers = true)]
    pub scale: f64,
    /// The canvas point (X,Y,Z, canvas units, on the canvas) that becomes
    /// the files' origin. Other tools hold positions in 32-bit floats, which
    /// near x = 20,000 are 2 mm apart: move a detailed part of a large
    /// canvas to the origin (e.g. the centre of --region) to keep its
    /// millimetres. Default: the canvas's corner (0,0,0).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true)]
    pub origin: Option<[f64; 3]>,
    /// Which file axis the canvas's up (+y) becomes in the VDB and the
    /// OBJ: y (Houdini, Maya, glTF) or z (Blender, which imports glTF
    /// turned but VDB and OBJ as they are unless told).
    #[arg(long, value_enum, default_value_t = UpChoice::Y)]
    pub up: UpChoice,
    /// Export the painting as it was at this snapshot event of the trace
    /// or of the document's session (a stroke still open there is ended,
    /// as at the end of a trace).
    /// Default: the end of the trace.
    #[arg(long, value_name = "SNAPSHOT")]
    pub at: Option<String>,
    /// Export only this box of the canvas, in canvas units:
    /// X0,Y0,Z0,X1,Y1,Z1 (low corner, high corner). The VDB holds the
    /// voxels that overlap it; the mesh is closed along its faces. A 40 km
    /// canvas painted down to millimetres needs it: a VDB has one voxel
    /// size, and a whole canvas at its finest depth does not fit anywhere.
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", value_parser = parse_crop, allow_hyphen_values = true)]
    pub region: Option<Crop>,
    /// Print, for every VDB depth up to the deepest painted one, the voxel
    /// size, the active voxels and the grid's size against --max-mib, then
    /// stop without writing anything.
    #[arg(long)]
    pub plan: bool,
    /// For a trace of layers (version 2, spec 14): export these layers,
    /// by name, comma-separated (default: every visible layer of non-zero
    /// opacity). Each layer's density is scaled by its opacity, as drawn;
    /// the VDB holds `NAME.density` and `NAME.color` per layer, glTF and
    /// OBJ one node or object per layer, USD one Xform per layer.
    #[arg(long, value_name = "NAME,NAME,...", value_delimiter = ',')]
    pub layers: Option<Vec<String>>,
    /// Print nothing but warnings and errors.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ColourChoice {
    Linear,
    Srgb,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum UpChoice {
    Y,
    Z,
}

/// Replays silently but for warnings.
struct Quiet;

impl ReplayObserver for Quiet {
    fn warning(&mut self, msg: &str) {
        eprintln!("octopaint: warning: {msg}");
    }
}

fn bar(quiet: bool, len: Option<u64>, template: &str) -> ProgressBar {
    let b = match len {
        Some(n) => ProgressBar::new(n),
        None => ProgressBar::new_spinner(),
    };
    b.set_style(ProgressStyle::with_template(template).expect("static template"));
    if quiet {
        b.set_draw_target(ProgressDrawTarget::hidden());
    }
    b
}

/// A refusal with its exit status: 2 for bad input or options, 1 for
/// failures to write.
struct Refusal(u8, String);

fn refuse(msg: impl Into<String>) -> Refusal {
    Refusal(2, msg.into())
}

impl From<ExportError> for Refusal {
    fn from(e: ExportError) -> Refusal {
        match e {
            ExportError::Io(e) => Refusal(1, e.to_string()),
            e => Refusal(2, e.to_string()),
        }
    }
}

pub fn run(args: &Args) -> ExitCode {
    match run_inner(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Refusal(code, msg)) => {
            eprintln!("octopaint: export: {msg}");
            ExitCode::from(code)
        }
    }
}

/// `--scale`: file units per canvas unit, in [1e-9, 1e9].
fn check_scale(scale: f64) -> Result<(), String> {
    if scale.is_finite() && (1e-9..=1e9).contains(&scale) { Ok(()) } else { Err(format!("--scale {scale} is not in [1e-9, 1e9]")) }
}

/// Where the files go from the canvas (exports) or come to it (imports):
/// `--scale`, `--origin` (default the canvas's corner, on the canvas) and
/// `--up`, checked against a canvas of `roots` roots of `root_size`.
pub fn placement_of(scale: f64, origin: Option<[f64; 3]>, up: UpChoice, roots: [u32; 3], root_size: f64) -> Result<Placement, String> {
    check_scale(scale)?;
    let origin = origin.unwrap_or([0.0; 3]);
    let size = roots.map(|r| f64::from(r) * root_size);
    if (0..3).any(|a| !(0.0..=size[a]).contains(&origin[a])) {
        return Err(format!(
            "--origin {},{},{} is off the canvas, which spans [0, {}] x [0, {}] x [0, {}]",
            origin[0], origin[1], origin[2], size[0], size[1], size[2]
        ));
    }
    Ok(Placement { scale, z_up: up == UpChoice::Z, origin })
}

pub fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().map_err(|_| format!("{x:?} is not a number"))).collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        [_, _, _] => Err("the point must be finite".into()),
        _ => Err(format!("expected 3 numbers X,Y,Z, got {}", v.len())),
    }
}

fn parse_crop(s: &str) -> Result<Crop, String> {
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().map_err(|_| format!("{x:?} is not a number"))).collect::<Result<_, _>>()?;
    if v.len() != 6 {
        return Err(format!("expected 6 numbers X0,Y0,Z0,X1,Y1,Z1, got {}", v.len()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err("the corners must be finite".into());
    }
    let (lo, hi) = ([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
    if (0..3).any(|a| lo[a] >= hi[a]) {
        return Err("each low corner coordinate must be below the high one".into());
    }
    Ok(Crop { lo, hi })
}

/// The VDB file to write: --vdb, or with --usd and no --vdb the stage's
/// name with `.vdb`. Refuses a --usd that is not `.usda`, and a --vdb the
/// stage cannot point at (another folder, or a name USD cannot quote).
fn vdb_path(args: &Args) -> Result<Option<PathBuf>, Refusal> {
    let Some(usd) = &args.usd else { return Ok(args.vdb.clone()) };
    let ext = usd.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("usda") => {}
        Some("usdc" | "usd" | "usdz") => {
            return Err(refuse(format!(
                "{}: only USD's text format is written (.usda); every USD reader opens it, and `usdcat IN.usda -o OUT.usdc` converts it to the binary format",
                usd.display()
            )));
        }
        _ => return Err(refuse(format!("{}: a USD stage is written as .usda", usd.display()))),
    }
    let vdb = match &args.vdb {
        Some(v) => {
            if octopaint_platform::durable::folder_of(v) != octopaint_platform::durable::folder_of(usd) {
                return Err(refuse(format!(
                    "--vdb {} is not in the folder of --usd {}: the stage points at its VDB beside it (leave --vdb out to write {} there)",
                    v.display(),
                    usd.display(),
                    usd.with_extension("vdb").display()
                )));
            }
            v.clone()
        }
        None => usd.with_extension("vdb"),
    };
    let name = vdb.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if !octopaint_export::usd::asset_path_ok(name) {
        return Err(refuse(format!("{}: a name USD cannot quote as an asset path (no @ or backslash)", vdb.display())));
    }
    Ok(Some(vdb))
}

fn check_options<'a>(args: &'a Args, vdb: Option<&'a Path>) -> Result<Vec<&'a Path>, Refusal> {
    let outs: Vec<&Path> = [vdb, args.gltf.as_deref(), args.obj.as_deref(), args.usd.as_deref()].into_iter().flatten().collect();
    if outs.is_empty() && !args.plan {
        return Err(refuse("nothing to write: give --vdb, --gltf, --obj or --usd (see --help)"));
    }
    for (i, a) in outs.iter().enumerate() {
        if outs[..i].contains(a) {
            return Err(refuse(format!("{} is given as two outputs", a.display())));
        }
        if a.as_os_str().is_empty() || a.file_name().is_none() {
            return Err(refuse(format!("{:?} is not a file name", a.display().to_string())));
        }
        if a.is_dir() {
            return Err(refuse(format!("{} is a folder", a.display())));
        }
        if *a == args.input.as_path() {
            return Err(refuse(format!("{} is the input: refusing to overwrite it", a.display())));
        }
    }
    // The scale before the replay, the origin once the canvas is known.
    check_scale(args.scale).map_err(refuse)?;
    if let Some(iso) = args.iso
        && !(iso.is_finite() && iso > 0.0)
    {
        return Err(refuse(format!("--iso {iso} must be a positive extinction")));
    }
    if args.max_mib == 0 || args.max_mib > 1 << 20 {
        return Err(refuse(format!("--max-mib {} is not in [1, 1048576]", args.max_mib)));
    }
    if args.max_triangles == 0 {
        return Err(refuse("--max-triangles must be at least 1"));
    }
    Ok(outs)
}

fn run_inner(args: &Args) -> Result<(), Refusal> {
    let vdb_out = vdb_path(args)?;
    let outs = check_options(args, vdb_out.as_deref())?;
    let t0 = Instant::now();
    let say = |s: String| {
        if !args.quiet {
            eprintln!("{s}");
        }
    };
    let is_doc = crate::document::is_document(&args.input);
    let mut document = None;
    let painting = if is_doc && args.at.is_none() {
        // A document opens as saved, plus what its journal holds.
        let s = octopaint_doc::Session::open_read(&args.input).map_err(|e| match e {
            octopaint_doc::DocError::Io { .. } => Refusal(1, e.to_string()),
            e => refuse(format!("{}: {e}", args.input.display())),
        })?;
        say(format!(
            "opened {}: {} events, {} cells{}",
            args.input.display(),
            s.event_count(),
            s.doc.used(),
            if s.recovered > 0 { format!(", {} unsaved stroke(s) from its journal", s.recovered) } else { String::new() }
        ));
        if s.version == 2 {
            let canvas = *s.doc.canvas();
            document = Some(s.doc);
            Painting::new(&canvas)
        } else {
            s.doc.into_current_painting()
        }
    } else {
        let mut trace = if is_doc {
            // --at in a document: its session, replayed to the snapshot.
            let s = octopaint_doc::Session::open_read(&args.input).map_err(|e| refuse(format!("{}: {e}", args.input.display())))?;
            let resolve = octopaint_doc::format::resolver(s.imports());
            let text = s.trace_text().map_err(|e| refuse(format!("{}: {e}", args.input.display())))?;
            octopaint_tree::trace::parse_trace_with(&text, Some(&resolve)).map_err(|e| refuse(format!("{}: {e}", args.input.display())))?
        } else {
            read_trace(&args.input).map_err(|e| refuse(format!("{}: {e}", args.input.display())))?
        };
        if let Some(name) = &args.at {
            let snapshots: Vec<&str> = trace
                .events
                .iter()
                .filter_map(|e| match &e.kind {
                    EventKind::Snapshot(n) => Some(n.as_str()),
                    _ => None,
                })
                .collect();
            let Some(i) = trace.events.iter().position(|e| matches!(&e.kind, EventKind::Snapshot(n) if n == name)) else {
                return Err(refuse(format!(
                    "{}: no snapshot named {name:?} (it has: {})",
                    args.input.display(),
                    if snapshots.is_empty() { "none".to_string() } else { snapshots.join(", ") }
                )));
            };
            trace.events.truncate(i + 1);
        }
        let b = bar(args.quiet, None, "{spinner} replaying {msg} [{elapsed_precise}]");
        b.set_message(args.input.display().to_string());
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        let (stats, doc) = replay_document(&trace, None, &mut Quiet).map_err(|e| Refusal(1, format!("replay failed: {e}")))?;
        b.finish_and_clear();
        let painting = if trace.version == 2 {
            document = Some(doc);
            Painting::new(&trace.canvas)
        } else {
            doc.into_current_painting()
        };
        say(format!(
            "replayed {}: {} strokes, {} cells, deepest depth {} ({:.1} s)",
            args.input.display(),
            stats.strokes,
            stats.cells,
            stats.deepest,
            t0.elapsed().as_secs_f64()
        ));
        painting
    };
    let parts = match document {
        None if args.layers.is_some() => {
            return Err(refuse(format!("--layers: {} is one painting, not a document of layers (a version 2 trace)", args.input.display())));
        }
        None => vec![(None, painting.tree)],
        Some(doc) => chosen_layers(&doc, args.layers.as_deref())?,
    };
    let tree = &parts[0].1;
    let colour = match args.colour {
        ColourChoice::Linear => ColourSpace::Linear,
        ColourChoice::Srgb => ColourSpace::Srgb,
    };
    let placement = placement_of(args.scale, args.origin, args.up, tree.lat.roots, tree.lat.root_size).map_err(refuse)?;
    let size = tree.lat.roots.map(|r| f64::from(r) * tree.lat.root_size);
    let cap = args.max_mib << 20;
    let crop = args.region;
    if let Some(c) = crop
        && (0..3).any(|a| c.hi[a] <= 0.0 || c.lo[a] >= size[a])
    {
        return Err(refuse(format!("--region misses the canvas, which spans [0, {}) x [0, {}) x [0, {})", size[0], size[1], size[2])));
    }
    let layered = parts[0].0.is_some();
    // The VDB's cap is shared by the layers' grids, which are all built
    // before the file is written.
    let cap_each = (cap / parts.len() as u64).max(1);
    if args.plan {
        for (name, tree) in &parts {
            if let Some(name) = name {
                println!("layer {name}:");
            }
            print_plan(tree, placement, crop, cap_each);
        }
        return Ok(());
    }

    // Everything that can refuse, before anything is written.
    if args.depth.is_some() && vdb_out.is_none() {
        return Err(refuse("--depth is the VDB's voxel depth: it needs --vdb or --usd (the mesh's is --mesh-depth)"));
    }
    let mut vdb_plans = Vec::new();
    if vdb_out.is_some() {
        for (name, tree) in &parts {
            let plan = voxels::plan(tree, args.depth, crop, cap_each).map_err(|e| match name {
                Some(n) => refuse(format!("layer {n:?}: {e}")),
                None => Refusal::from(e),
            })?;
            vdb_plans.push(plan);
        }
    }
    let mut meshes = Vec::new();
    if args.gltf.is_some() || args.obj.is_some() || args.usd_mesh {
        let depth_cap = args.mesh_depth.unwrap_or(tree.lat.max_depth);
        if depth_cap > tree.lat.max_depth {
            return Err(ExportError::DepthOutOfRange { depth: depth_cap, deepest: tree.lat.max_depth }.into());
        }
        for (name, tree) in &parts {
            let of = name.as_ref().map(|n| format!("layer {n:?}: ")).unwrap_or_default();
            let Some(iso) = args.iso.or_else(|| default_iso(tree)) else {
                if !layered {
                    return Err(refuse("the painting is empty: there is no surface to mesh"));
                }
                say(format!("{of}empty: no surface"));
                meshes.push(octopaint_export::Mesh::default());
                continue;
            };
            let t = Instant::now();
            let b = bar(args.quiet, None, "{spinner} meshing: {pos} triangles [{elapsed_precise}]");
            let m = surface(tree, SurfaceOptions { iso, depth_cap, max_triangles: args.max_triangles, crop }, &mut |n| b.set_position(n as u64));
            b.finish_and_clear();
            let m = m.ok_or(ExportError::TooManyTriangles { max: args.max_triangles })?;
            say(format!(
                "{of}surface at extinction {iso}: {} vertices, {} triangles ({:.1} s)",
                m.positions.len(),
                m.triangles.len(),
                t.elapsed().as_secs_f64()
            ));
            if m.triangles.is_empty() {
                say(format!("warning: {of}no leaf reaches extinction {iso}: the mesh is empty (lower --iso)"));
            }
            meshes.push(m);
        }
        let triangles: usize = meshes.iter().map(|m| m.triangles.len()).sum();
        if triangles > args.max_triangles {
            return Err(ExportError::TooManyTriangles { max: args.max_triangles }.into());
        }
        if layered && meshes.iter().all(|m| m.positions.is_empty()) && args.iso.is_none() && parts.iter().all(|(_, t)| default_iso(t).is_none()) {
            return Err(refuse("every exported layer is empty: there is no surface to mesh"));
        }
    }
    let names: Vec<&str> = parts.iter().map(|(n, _)| n.as_deref().unwrap_or("painting")).collect();
    let named_meshes: Vec<(&str, &octopaint_export::Mesh)> = names.iter().copied().zip(meshes.iter()).collect();
    let glb = match &args.gltf {
        Some(_) => Some(mesh::glb_bytes_named(&named_meshes, placement, &generator())?),
        None => None,
    };
    for p in &outs {
        check_writable(p)?;
    }

    let mut volume_extents = vec![None; parts.len()];
    if let Some(path) = &vdb_out {
        let t = Instant::now();
        let mut grids = Vec::with_capacity(parts.len());
        for ((name, tree), plan) in parts.iter().zip(&vdb_plans) {
            let e = plan.depth();
            let b = bar(args.quiet, Some(plan.estimate().regions), "{spinner} voxels at depth {msg}: {wide_bar} {pos}/{len} cells [{elapsed_precise}]");
            b.set_message(match name {
                Some(n) => format!("{e} ({n})"),
                None => e.to_string(),
            });
            grids.push(VoxelGrid::build(tree, plan, colour, placement, &mut |n| b.set_position(n)));
            b.finish_and_clear();
        }
        for (k, grid) in grids.iter().enumerate() {
            // Voxel i spans [i, i + 1) voxel sizes from the grid's translation.
            volume_extents[k] = grid.bbox.map(|(lo, hi)| {
                let at = |i: [i32; 3], k: f64| glam::DVec3::from_array([0, 1, 2].map(|a| (f64::from(i[a]) + k) * grid.voxel_size + grid.translation[a]));
                [at(lo, 0.0), at(hi, 1.0)]
            });
        }
        let resample_s = t.elapsed().as_secs_f64();
        let b = bar(args.quiet, None, "{spinner} writing {msg} [{elapsed_precise}]");
        b.set_message(path.display().to_string());
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        let prefixes: Vec<String> = parts.iter().map(|(n, _)| n.as_ref().map(|n| format!("{n}.")).unwrap_or_default()).collect();
        let named: Vec<(&str, &VoxelGrid)> = prefixes.iter().map(String::as_str).zip(grids.iter()).collect();
        let size = write_with(path, |w| vdb::write_vdb_named(w, &named, &generator()))?;
        b.finish_and_clear();
        for ((name, grid), plan) in parts.iter().map(|(n, _)| n).zip(&grids).zip(&vdb_plans) {
            say(format!(
                "{}{}: depth {}, voxel {} file units, {} active voxels",
                path.display(),
                name.as_ref().map(|n| format!(" ({n})")).unwrap_or_default(),
                plan.depth(),
                grid.voxel_size,
                grid.active_voxels,
            ));
        }
        say(format!(
            "{}: {} ({:.2} s: resampling {:.2} s, writing {:.2} s)",
            path.display(),
            human(size),
            t.elapsed().as_secs_f64(),
            resample_s,
            t.elapsed().as_secs_f64() - resample_s
        ));
    }
    if let (Some(path), Some(bytes)) = (&args.gltf, &glb) {
        write_with(path, |w| w.write_all(bytes))?;
        say(format!("{}: {}", path.display(), human(bytes.len() as u64)));
    }
    if let Some(path) = &args.obj {
        let size = write_with(path, |w| mesh::write_obj_named(w, &named_meshes, placement, colour, &generator()))?;
        say(format!("{}: {}", path.display(), human(size)));
    }
    if let (Some(path), Some(vdb)) = (&args.usd, &vdb_out) {
        let name = vdb.file_name().and_then(|n| n.to_str()).expect("checked by vdb_path");
        // An empty painting or layer has no active voxel: its volume is
        // left out (a Volume needs an extent), the stage still says its units.
        let stage = usd::Stage {
            vdb: name,
            parts: parts
                .iter()
                .enumerate()
                .map(|(k, (layer, _))| usd::Part {
                    layer: layer.as_deref(),
                    volume: volume_extents[k].map(|e| (layer.as_ref().map(|n| format!("{n}.")).unwrap_or_default(), e)),
                    mesh: if args.usd_mesh { meshes.get(k) } else { None },
                })
                .collect(),
            placement,
            colour,
            metres_per_canvas_unit: 1.0,
        };
        let size = write_with(path, |w| usd::write_usda(w, &stage, &generator()))?;
        say(format!("{}: {} (the volume's grids in {})", path.display(), human(size), vdb.display()));
    }
    Ok(())
}

/// The layers of `doc` to export: those `names` gives (refused when one is
/// not a layer), or every visible one of non-zero opacity; each tree with
/// its sigma scaled by the layer's opacity (spec 14.1: opacity scales
/// density as drawn).
fn chosen_layers(doc: &Document, names: Option<&[String]>) -> Result<Vec<(Option<String>, octopaint_tree::Tree)>, Refusal> {
    let all: Vec<&str> = doc.layers().map(|l| l.name.as_str()).collect();
    let picked: Vec<&octopaint_tree::layers::Layer> = match names {
        Some(names) => {
            let mut out = Vec::new();
            for n in names {
                match doc.layers().find(|l| l.name == *n) {
                    Some(l) if !out.iter().any(|o: &&octopaint_tree::layers::Layer| o.name == l.name) => out.push(l),
                    Some(_) => return Err(refuse(format!("--layers names {n:?} twice"))),
                    None => return Err(refuse(format!("--layers: no layer named {n:?} (the document has: {})", all.join(", ")))),
                }
            }
            out
        }
        None => doc.layers().filter(|l| l.contributes()).collect(),
    };
    if picked.is_empty() {
        return Err(refuse(format!("no layer to export: none is visible with an opacity above 0 (the document has: {}; --layers picks)", all.join(", "))));
    }
    Ok(picked
        .into_iter()
        .map(|l| {
            let mut tree = l.tree().clone();
            if l.opacity != 1.0 {
                let o = f64::from(l.opacity);
                tree.map_sigma(|s| octopaint_tree::brush::quantize_sigma(f64::from(s) * o));
            }
            (Some(l.name.clone()), tree)
        })
        .collect())
}

/// The table of --plan. Counting stops once a depth is past the cap
/// (those rows say "over").
fn print_plan(tree: &octopaint_tree::Tree, placement: Placement, crop: Option<Crop>, cap: u64) {
    let want = voxels::deepest_painted(tree, crop).min(voxels::deepest_addressable(tree));
    let chosen = voxels::choose_depth(tree, crop, cap).ok();
    println!("depth  voxel size      active voxels      leaves    nodes  MiB (cap {})", cap >> 20);
    for e in 0..=want {
        let est = voxels::estimate(tree, e, crop, cap);
        let size = tree.lat.root_size * (2.0f64).powi(-(e as i32)) * placement.scale;
        let over = est.bytes() > cap;
        println!(
            "{e:>5}  {size:<14.6e}  {:>17}  {:>8}  {:>7}  {}{}",
            if over { "-".to_string() } else { est.active_voxels.to_string() },
            if over { "-".to_string() } else { est.leaves.to_string() },
            if over { "-".to_string() } else { (est.nodes4 + est.nodes5 + est.root_tiles).to_string() },
            if over { "over".to_string() } else { format!("{:.1}", est.bytes() as f64 / f64::from(1 << 20)) },
            if chosen == Some(e) { "  <- default" } else { "" }
        );
    }
}

fn generator() -> String {
    format!("octopaint {}", env!("CARGO_PKG_VERSION"))
}

fn human(bytes: u64) -> String {
    if bytes >= 1 << 20 { format!("{:.1} MiB", bytes as f64 / f64::from(1 << 20)) } else { format!("{:.1} KiB", bytes as f64 / 1024.0) }
}

/// The folder exists and takes a new file (a temporary one, removed).
fn check_writable(path: &Path) -> Result<(), Refusal> {
    let dir = octopaint_platform::durable::folder_of(path);
    tempfile::Builder::new()
        .prefix(".octopaint-probe-")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| Refusal(1, format!("cannot write {}: {}", path.display(), octopaint_tree::trace::io_reason(&e))))
}

/// Write `path` through a temporary file beside it, synced and renamed
/// over it (octopaint_platform::durable): a reader sees the old file or
/// the whole new one. Returns the size written.
fn write_with(path: &Path, f: impl FnOnce(&mut octopaint_platform::durable::Out) -> std::io::Result<()>) -> Result<u64, Refusal> {
    octopaint_platform::durable::write_with(path, f)
        .map_err(|e| Refusal(1, format!("cannot write {}: {}", path.display(), octopaint_tree::trace::io_reason(&e))))
}
