//! USD (ASCII, `.usda`) stages for pipelines built on Pixar's USD
//! (docs/export.md, "USD"): one `Volume` prim whose `density` and `color`
//! fields are `OpenVDBAsset`s pointing at the grids of the `.vdb` this
//! export writes beside the stage, and optionally the iso-surface as a
//! `Mesh` with per-vertex normals and `displayColor`. The stage says its
//! units (`metersPerUnit`) and up axis, so importers place it without
//! being told.
//!
//! Text only: the binary crate format (`.usdc`) needs Pixar's library or a
//! reimplementation of its compressed layout; `usdcat stage.usda -o
//! stage.usdc` converts, and every USD reader opens `.usda` directly.

use std::io::Write;

use glam::DVec3;

use crate::{ColourSpace, Mesh, Placement, mesh::vertex_normals};

/// What a stage holds besides its header.
pub struct Stage<'a> {
    /// The `.vdb` file's name, relative to the stage (written beside it).
    pub vdb: &'a str,
    /// One entry for a painting; one per exported layer of a document
    /// (spec 14), in order.
    pub parts: Vec<Part<'a>>,
    pub placement: Placement,
    /// The colour space of the VDB's `color` grid (its metadata says so
    /// too); the mesh's `displayColor` is always linear, as USD expects.
    pub colour: ColourSpace,
    /// Metres per canvas unit (the export reads canvas units as metres).
    pub metres_per_canvas_unit: f64,
}

/// One painting or one layer of a document on the stage.
pub struct Part<'a> {
    /// The layer's name, None for a painting: a layer's prims go under an
    /// `Xform` named after it (made a valid prim name) whose `doc` holds
    /// the name itself.
    pub layer: Option<&'a str>,
    /// The prefix of its grids' names in the `.vdb` ("" for a painting),
    /// and the volume's extent in file units (low, high corner); None when
    /// it has no active voxel (a Volume needs an extent).
    pub volume: Option<(String, [DVec3; 2])>,
    /// The iso-surface, if any, in canvas coordinates (placed here).
    pub mesh: Option<&'a Mesh>,
}

/// A layer's name as a prim name (`[A-Za-z_][A-Za-z0-9_]*`): other
/// characters become `_`, a leading digit gets a `_` before it, and
/// `taken` names get `_2`, `_3`, ...
pub fn prim_name(name: &str, taken: &[String]) -> String {
    let mut base: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect();
    if base.is_empty() || base.starts_with(|c: char| c.is_ascii_digit()) {
        base.insert(0, '_');
    }
    let mut out = base.clone();
    let mut k = 2;
    while taken.contains(&out) {
        out = format!("{base}_{k}");
        k += 1;
    }
    out
}

/// A string as USD's text format quotes it.
fn quoted(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A number as USD's text format reads it back to the same f32 (the
/// stage's points and extents are `float3`).
fn num(x: f64) -> String {
    let v = x as f32;
    if v == v.trunc() && v.abs() < 1e7 { format!("{v:.1}") } else { format!("{v:?}") }
}

fn triple(v: DVec3) -> String {
    format!("({}, {}, {})", num(v.x), num(v.y), num(v.z))
}

/// `items` as the body of a USD array, `a, b, c`, written as they come.
fn write_list(w: &mut impl Write, items: impl IntoIterator<Item = String>) -> std::io::Result<()> {
    for (k, item) in items.into_iter().enumerate() {
        write!(w, "{}{item}", if k > 0 { ", " } else { "" })?;
    }
    Ok(())
}

/// A path written as a USD asset path `@...@`; refused when it holds
/// characters the text format cannot carry there.
pub fn asset_path_ok(name: &str) -> bool {
    !name.is_empty() && !name.contains(['@', '\n', '\r', '\\'])
}

/// Write the stage as USD ASCII.
pub fn write_usda(w: &mut dyn Write, stage: &Stage, generator: &str) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::with_capacity(1 << 20, w);
    let up = if stage.placement.z_up { "Z" } else { "Y" };
    // A file unit is 1/scale canvas units.
    let metres_per_unit = stage.metres_per_canvas_unit / stage.placement.scale;
    writeln!(w, "#usda 1.0")?;
    writeln!(w, "(")?;
    writeln!(w, "    defaultPrim = \"Painting\"")?;
    writeln!(w, "    doc = \"{generator}\"")?;
    writeln!(w, "    metersPerUnit = {metres_per_unit:?}")?;
    writeln!(w, "    upAxis = \"{up}\"")?;
    writeln!(w, ")")?;
    writeln!(w)?;
    writeln!(w, "def Xform \"Painting\" (")?;
    writeln!(w, "    kind = \"component\"")?;
    writeln!(w, ")")?;
    writeln!(w, "{{")?;
    let mut taken: Vec<String> = Vec::new();
    for (k, part) in stage.parts.iter().enumerate() {
        if k > 0 {
            writeln!(w)?;
        }
        match part.layer {
            None => write_part(&mut w, stage, part, "    ", "/Painting")?,
            Some(name) => {
                let prim = prim_name(name, &taken);
                writeln!(w, "    def Xform \"{prim}\" (")?;
                writeln!(w, "        doc = {}", quoted(&format!("layer {name}")))?;
                writeln!(w, "    )")?;
                writeln!(w, "    {{")?;
                write_part(&mut w, stage, part, "        ", &format!("/Painting/{prim}"))?;
                writeln!(w, "    }}")?;
                taken.push(prim);
            }
        }
    }
    writeln!(w, "}}")?;
    w.flush()
}

/// One part's Volume and Mesh, indented by `ind`, under prim path `path`.
fn write_part(w: &mut impl Write, stage: &Stage, part: &Part, ind: &str, path: &str) -> std::io::Result<()> {
    if let Some((prefix, [lo, hi])) = &part.volume {
        let vdb = stage.vdb;
        let space = match stage.colour {
            ColourSpace::Linear => "linear",
            ColourSpace::Srgb => "sRGB-encoded",
        };
        writeln!(w, "{ind}def Volume \"Volume\" (")?;
        writeln!(w, "{ind}    doc = \"density: extinction per file unit; color: {space}\"")?;
        writeln!(w, "{ind})")?;
        writeln!(w, "{ind}{{")?;
        writeln!(w, "{ind}    float3[] extent = [{}, {}]", triple(*lo), triple(*hi))?;
        writeln!(w, "{ind}    rel field:color = <{path}/Volume/color>")?;
        writeln!(w, "{ind}    rel field:density = <{path}/Volume/density>")?;
        for (prim, grid, kind) in [("density", "density", "float"), ("color", "color", "vector3f")] {
            writeln!(w)?;
            writeln!(w, "{ind}    def OpenVDBAsset \"{prim}\"")?;
            writeln!(w, "{ind}    {{")?;
            writeln!(w, "{ind}        token fieldDataType = \"{kind}\"")?;
            writeln!(w, "{ind}        token fieldName = {}", quoted(&format!("{prefix}{grid}")))?;
            writeln!(w, "{ind}        asset filePath = @./{vdb}@")?;
            writeln!(w, "{ind}    }}")?;
        }
        writeln!(w, "{ind}}}")?;
    }
    if let Some(mesh) = part.mesh {
        let p = stage.placement;
        let points: Vec<DVec3> = mesh.positions.iter().map(|&v| p.apply(v, true)).collect();
        let (lo, hi) = points.iter().fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        if part.volume.is_some() {
            writeln!(w)?;
        }
        writeln!(w, "{ind}def Mesh \"Surface\"")?;
        writeln!(w, "{ind}{{")?;
        if !points.is_empty() {
            writeln!(w, "{ind}    float3[] extent = [{}, {}]", triple(lo), triple(hi))?;
        }
        write!(w, "{ind}    int[] faceVertexCounts = [")?;
        write_list(w, mesh.triangles.iter().map(|_| "3".to_string()))?;
        writeln!(w, "]")?;
        write!(w, "{ind}    int[] faceVertexIndices = [")?;
        write_list(w, mesh.triangles.iter().map(|t| format!("{}, {}, {}", t[0], t[1], t[2])))?;
        writeln!(w, "]")?;
        write!(w, "{ind}    normal3f[] normals = [")?;
        write_list(w, vertex_normals(mesh).into_iter().map(|n| triple(p.turn(n, true))))?;
        writeln!(w, "] (")?;
        writeln!(w, "{ind}        interpolation = \"vertex\"")?;
        writeln!(w, "{ind}    )")?;
        write!(w, "{ind}    point3f[] points = [")?;
        write_list(w, points.iter().map(|&v| triple(v)))?;
        writeln!(w, "]")?;
        write!(w, "{ind}    color3f[] primvars:displayColor = [")?;
        write_list(w, mesh.colours.iter().map(|&c| triple(ColourSpace::Linear.encode(c).map(f64::from).into())))?;
        writeln!(w, "] (")?;
        writeln!(w, "{ind}        interpolation = \"vertex\"")?;
        writeln!(w, "{ind}    )")?;
        writeln!(w, "{ind}    uniform token orientation = \"rightHanded\"")?;
        writeln!(w, "{ind}    uniform token subdivisionScheme = \"none\"")?;
        writeln!(w, "{ind}}}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_back_as_the_same_f32() {
        for x in [0.0, 1.0, -2.5, 0.1, 1e-9, 12345.678, 3.4e38, 1e7, 16777217.0] {
            let t = num(x);
            assert_eq!(t.parse::<f32>().unwrap(), x as f32, "{x} -> {t}");
        }
        assert_eq!(num(2.0), "2.0");
    }

    #[test]
    fn a_stage_without_a_mesh_has_the_volume_and_its_header() {
        let stage = Stage {
            vdb: "p.vdb",
            parts: vec![Part { layer: None, volume: Some((String::new(), [DVec3::ZERO, DVec3::new(1.0, 2.0, 0.5)])), mesh: None }],
            placement: Placement { scale: 100.0, z_up: true, origin: [0.0; 3] },
            colour: ColourSpace::Linear,
            metres_per_canvas_unit: 1.0,
        };
        let mut out = Vec::new();
        write_usda(&mut out, &stage, "test").unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("#usda 1.0\n"), "{text}");
        assert!(text.contains("metersPerUnit = 0.01\n") && text.contains("upAxis = \"Z\""), "{text}");
        assert!(text.contains("asset filePath = @./p.vdb@") && text.contains("float3[] extent = [(0.0, 0.0, 0.0), (1.0, 2.0, 0.5)]"), "{text}");
        assert!(!text.contains("def Mesh"));
        assert!(asset_path_ok("p.vdb") && !asset_path_ok("a@b.vdb") && !asset_path_ok(""));
    }

    #[test]
    fn layer_names_become_unique_prim_names() {
        let mut taken = Vec::new();
        for (name, want) in [("Layer 1", "Layer_1"), ("Layer_1", "Layer_1_2"), ("3d", "_3d"), ("été", "_t_"), ("", "_")] {
            let got = prim_name(name, &taken);
            assert_eq!(got, want);
            taken.push(got);
        }
        assert_eq!(quoted("a \"b\" \\ c"), "\"a \\\"b\\\" \\\\ c\"");
    }
}
