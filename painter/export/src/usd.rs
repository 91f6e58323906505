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
    /// The `.vdb` file's name, relative to the stage (written beside it),
    /// and the volume's extent in file units (low, high corner).
    pub volume: Option<(&'a str, [DVec3; 2])>,
    /// The iso-surface, if any, in canvas coordinates (placed here).
    pub mesh: Option<&'a Mesh>,
    pub placement: Placement,
    /// The colour space of the VDB's `color` grid (its metadata says so
    /// too); the mesh's `displayColor` is always linear, as USD expects.
    pub colour: ColourSpace,
    /// Metres per canvas unit (the export reads canvas units as metres).
    pub metres_per_canvas_unit: f64,
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
    if let Some((vdb, [lo, hi])) = stage.volume {
        let space = match stage.colour {
            ColourSpace::Linear => "linear",
            ColourSpace::Srgb => "sRGB-encoded",
        };
        writeln!(w, "    def Volume \"Volume\" (")?;
        writeln!(w, "        doc = \"density: extinction per file unit; color: {space}\"")?;
        writeln!(w, "    )")?;
        writeln!(w, "    {{")?;
        writeln!(w, "        float3[] extent = [{}, {}]", triple(lo), triple(hi))?;
        writeln!(w, "        rel field:color = </Painting/Volume/color>")?;
        writeln!(w, "        rel field:density = </Painting/Volume/density>")?;
        for (prim, grid, kind) in [("density", "density", "float"), ("color", "color", "vector3f")] {
            writeln!(w)?;
            writeln!(w, "        def OpenVDBAsset \"{prim}\"")?;
            writeln!(w, "        {{")?;
            writeln!(w, "            token fieldDataType = \"{kind}\"")?;
            writeln!(w, "            token fieldName = \"{grid}\"")?;
            writeln!(w, "            asset filePath = @./{vdb}@")?;
            writeln!(w, "        }}")?;
        }
        writeln!(w, "    }}")?;
    }
    if let Some(mesh) = stage.mesh {
        let p = stage.placement;
        let points: Vec<DVec3> = mesh.positions.iter().map(|&v| p.apply(v, true)).collect();
        let (lo, hi) = points.iter().fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        if stage.volume.is_some() {
            writeln!(w)?;
        }
        writeln!(w, "    def Mesh \"Surface\"")?;
        writeln!(w, "    {{")?;
        if !points.is_empty() {
            writeln!(w, "        float3[] extent = [{}, {}]", triple(lo), triple(hi))?;
        }
        write!(w, "        int[] faceVertexCounts = [")?;
        write_list(&mut w, mesh.triangles.iter().map(|_| "3".to_string()))?;
        writeln!(w, "]")?;
        write!(w, "        int[] faceVertexIndices = [")?;
        write_list(&mut w, mesh.triangles.iter().map(|t| format!("{}, {}, {}", t[0], t[1], t[2])))?;
        writeln!(w, "]")?;
        write!(w, "        normal3f[] normals = [")?;
        write_list(&mut w, vertex_normals(mesh).into_iter().map(|n| triple(p.turn(n, true))))?;
        writeln!(w, "] (")?;
        writeln!(w, "            interpolation = \"vertex\"")?;
        writeln!(w, "        )")?;
        write!(w, "        point3f[] points = [")?;
        write_list(&mut w, points.iter().map(|&v| triple(v)))?;
        writeln!(w, "]")?;
        write!(w, "        color3f[] primvars:displayColor = [")?;
        write_list(&mut w, mesh.colours.iter().map(|&c| triple(ColourSpace::Linear.encode(c).map(f64::from).into())))?;
        writeln!(w, "] (")?;
        writeln!(w, "            interpolation = \"vertex\"")?;
        writeln!(w, "        )")?;
        writeln!(w, "        uniform token orientation = \"rightHanded\"")?;
        writeln!(w, "        uniform token subdivisionScheme = \"none\"")?;
        writeln!(w, "    }}")?;
    }
    writeln!(w, "}}")?;
    w.flush()
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
            volume: Some(("p.vdb", [DVec3::ZERO, DVec3::new(1.0, 2.0, 0.5)])),
            mesh: None,
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
}
