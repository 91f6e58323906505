//! Tree dumps (spec 11): the `.npz` both implementations write at a trace's
//! `snapshot` events and the conformance driver compares. Reference twin:
//! reference/octopaint_ref/dump.py.
//!
//! A dump is a zip (the `zip` crate) of `.npy` entries (the `npyz` crate),
//! stored without compression, with a fixed timestamp: what the two
//! implementations must agree on is the arrays (names, dtypes, shapes,
//! values), which numpy and `octopaint-ref check` read; the file's bytes
//! are each library's business. The painter's own dumps of one tree are
//! still identical byte for byte, which its undo tests use.

use std::io::{Cursor, Seek, Write};

pub use octopaint_trace::npz::{NpyArray, Values, write_npz};

pub use crate::pool::origins;

use crate::g3::g3_table;
use crate::pool::Tree;

/// One entry of a dump: `name.npy` with dtype `dtype` (numpy's descr,
/// e.g. `<u4`) and a shape whose given dimensions (None: any) it must
/// have; its shape and values in C order.
fn read_entry<T: npyz::Deserialize>(
    zip: &mut zip::ZipArchive<Cursor<&[u8]>>,
    name: &str,
    dtype: &str,
    shape: &[Option<u64>],
) -> Result<(Vec<u64>, Vec<T>), String> {
    let mut data = Vec::new();
    let mut f = zip.by_name(&format!("{name}.npy")).map_err(|e| format!("{name}.npy: {e}"))?;
    std::io::Read::read_to_end(&mut f, &mut data).map_err(|e| format!("{name}.npy: {e}"))?;
    let npy = npyz::NpyFile::new(&data[..]).map_err(|e| format!("{name}.npy: not an .npy array: {e}"))?;
    let got = npy.dtype().descr();
    let want = format!("'{dtype}'");
    // One-byte types have no byte order: numpy writes '|u1'.
    if got.trim() != want && !(dtype == "|u1" && got.trim() == "'<u1'") {
        return Err(format!("{name}.npy: dtype {} where {dtype} is expected", got.trim()));
    }
    let sh = npy.shape().to_vec();
    if sh.len() != shape.len() || sh.iter().zip(shape).any(|(g, w)| w.is_some_and(|w| w != *g)) {
        return Err(format!("{name}.npy: shape {sh:?} where {} is expected", fmt_shape(shape)));
    }
    if npy.order() != npyz::Order::C {
        return Err(format!("{name}.npy: Fortran order is not read"));
    }
    let values = npy.into_vec::<T>().map_err(|e| format!("{name}.npy: {e}"))?;
    Ok((sh, values))
}

/// A tree from a dump's bytes (spec 11.1; what either implementation
/// wrote at a snapshot, or `octopaint-ref` wrote for any tree): the pools
/// and the canvas, refused with a message naming the entry or the first
/// problem unless every array is there with its dtype and shape, the
/// canvas is one a trace may declare, and the tree passes every check of
/// `octopaint-ref check` but g3 (which is not read: it follows from the
/// links). The cell budget is the dump's length.
pub fn read_dump(bytes: &[u8]) -> Result<Tree, String> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| format!("not an .npz (zip) file: {e}"))?;
    let (_, roots) = read_entry::<u32>(&mut zip, "roots", "<u4", &[Some(3)])?;
    let (_, max_depth) = read_entry::<u32>(&mut zip, "max_depth", "<u4", &[])?;
    let (_, root_size) = read_entry::<f64>(&mut zip, "root_size", "<f8", &[])?;
    let (sh, parent) = read_entry::<u32>(&mut zip, "parent", "<u4", &[None])?;
    let n = sh[0];
    if n > octopaint_model::MAX_CAPACITY as u64 {
        return Err(format!("{n} cells are more than the {} a canvas may hold", octopaint_model::MAX_CAPACITY));
    }
    let header = serde_json::json!({"roots": roots, "max_depth": max_depth[0], "root_size": root_size[0], "capacity": n});
    let canvas = octopaint_trace::parse_canvas(0, &header).map_err(|e| format!("the dump's canvas: {}", e.message))?;
    let (_, first_child) = read_entry::<u32>(&mut zip, "first_child", "<u4", &[Some(n)])?;
    let (_, depth) = read_entry::<u8>(&mut zip, "depth", "|u1", &[Some(n)])?;
    let (_, rgb) = read_entry::<u8>(&mut zip, "rgb", "|u1", &[Some(n), Some(3)])?;
    let rgb: Vec<[u8; 3]> = rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let (_, sigma) = read_entry::<f32>(&mut zip, "sigma", "<f4", &[Some(n)])?;
    Tree::from_pools(&canvas, parent, first_child, depth, rgb, sigma).map_err(|e| format!("not a valid tree: {e}"))
}

fn fmt_shape(shape: &[Option<u64>]) -> String {
    let dims: Vec<String> = shape.iter().map(|d| d.map_or("N".to_string(), |d| d.to_string())).collect();
    format!("[{}]", dims.join(", "))
}

/// The dump of a tree, as bytes (spec 11.1).
pub fn dump_bytes(tree: &Tree) -> Vec<u8> {
    write_dump(Cursor::new(Vec::with_capacity(dump_size(tree))), tree, None).expect("writing to memory cannot fail").into_inner()
}

/// About the bytes of a tree's dump (its arrays, 40 bytes a cell, and a
/// little for the zip's headers): the buffer a dump is written into is
/// made this large at once, rather than grown by copying.
fn dump_size(tree: &Tree) -> usize {
    tree.n_used() as usize * 40 + 8192
}

/// Write the dump of a tree (spec 11.1) to `out` with its g3 table, or
/// with the CPU port's (`g3` None), which is then computed beside the
/// cells' origins, on a second thread: the two are independent walks of
/// the tree, each about 15 ms for the scene's million cells.
pub fn write_dump<W: Write + Seek>(out: W, tree: &Tree, g3: Option<&[[u32; 3]]>) -> std::io::Result<W> {
    debug_assert!(tree.prefilter_is_current(), "a dump before the interior values were updated (spec 4.4)");
    let names = TREE_ARRAYS.map(String::from);
    match g3 {
        Some(g3) => {
            assert_eq!(g3.len(), tree.n_used() as usize, "one g3 row per cell");
            write_npz(out, &dump_arrays(tree, g3, &origins(tree), &names))
        }
        None => {
            let (g3, origin) = std::thread::scope(|s| {
                let g3 = s.spawn(|| g3_table(tree));
                let origin = origins(tree);
                (g3.join().unwrap_or_else(|e| std::panic::resume_unwind(e)), origin)
            });
            write_npz(out, &dump_arrays(tree, &g3, &origin, &names))
        }
    }
}

/// The dump of a tree with a given g3 table (read back from the GPU).
pub fn dump_bytes_with(tree: &Tree, g3: &[[u32; 3]]) -> Vec<u8> {
    write_dump(Cursor::new(Vec::with_capacity(dump_size(tree))), tree, Some(g3)).expect("writing to memory cannot fail").into_inner()
}

/// The names of a tree's per-cell arrays, in the order of spec 11.1 (a
/// document's dump has them per layer under `k/`, spec 14.5).
pub const TREE_ARRAYS: [&str; 7] = ["parent", "first_child", "depth", "rgb", "sigma", "g3", "origin"];

/// A tree's per-cell arrays in the order of spec 11.1, named by `names`
/// (TREE_ARRAYS, or those with a layer's prefix).
pub fn layer_arrays<'a>(tree: &'a Tree, g3: &'a [[u32; 3]], origin: &'a [[u32; 3]], names: &'a [String]) -> Vec<NpyArray<'a>> {
    let n = tree.n_used() as usize;
    vec![
        NpyArray { name: &names[0], shape: vec![n], values: Values::U32(&tree.parent) },
        NpyArray { name: &names[1], shape: vec![n], values: Values::U32(&tree.first_child) },
        NpyArray { name: &names[2], shape: vec![n], values: Values::U8(&tree.depth) },
        NpyArray { name: &names[3], shape: vec![n, 3], values: Values::U8(bytemuck::cast_slice(&tree.rgb)) },
        NpyArray { name: &names[4], shape: vec![n], values: Values::F32(&tree.sigma) },
        NpyArray { name: &names[5], shape: vec![n, 3], values: Values::U32(bytemuck::cast_slice(g3)) },
        NpyArray { name: &names[6], shape: vec![n, 3], values: Values::U32(bytemuck::cast_slice(origin)) },
    ]
}

/// The arrays of a dump in the order of spec 11.1, borrowing the tree, its
/// g3 table and its cells' origins.
fn dump_arrays<'a>(tree: &'a Tree, g3: &'a [[u32; 3]], origin: &'a [[u32; 3]], names: &'a [String]) -> Vec<NpyArray<'a>> {
    let mut out = layer_arrays(tree, g3, origin, names);
    out.extend([
        NpyArray { name: "roots", shape: vec![3], values: Values::U32(&tree.lat.roots[..]) },
        NpyArray { name: "max_depth", shape: vec![], values: Values::U32(std::slice::from_ref(&tree.lat.max_depth)) },
        NpyArray { name: "root_size", shape: vec![], values: Values::F64(std::slice::from_ref(&tree.lat.root_size)) },
    ]);
    out
}

#[cfg(test)]
mod tests {
    use zip::CompressionMethod;

    use super::*;
    use crate::pool::FREE;

    /// The entries of an `.npz`, read back by the zip and npyz crates:
    /// name, dtype descr, shape and values as f64.
    fn read_npz(bytes: &[u8]) -> Vec<(String, String, Vec<u64>, Vec<f64>)> {
        let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).unwrap();
        (0..zip.len())
            .map(|i| {
                let mut e = zip.by_index(i).unwrap();
                assert_eq!(e.compression(), CompressionMethod::Stored);
                let mut data = Vec::new();
                std::io::Read::read_to_end(&mut e, &mut data).unwrap();
                let f = npyz::NpyFile::new(&data[..]).unwrap();
                let descr = f.dtype().descr().trim_matches('\'').to_string();
                let shape = f.shape().to_vec();
                let values: Vec<f64> = match descr.as_str() {
                    "|u1" => f.into_vec::<u8>().unwrap().into_iter().map(f64::from).collect(),
                    "<u4" => f.into_vec::<u32>().unwrap().into_iter().map(f64::from).collect(),
                    "<f4" => f.into_vec::<f32>().unwrap().into_iter().map(f64::from).collect(),
                    "<f8" => f.into_vec::<f64>().unwrap(),
                    other => panic!("{other}"),
                };
                (e.name().to_string(), descr, shape, values)
            })
            .collect()
    }

    #[test]
    fn a_dump_holds_every_array_with_its_dtype_and_shape() {
        let tree = Tree::new(&octopaint_model::Canvas { roots: [2, 1, 1], max_depth: 4, root_size: 0.5, capacity: 64 });
        let bytes = dump_bytes(&tree);
        let entries = read_npz(&bytes);
        let n = tree.n_used() as u64;
        let want: [(&str, &str, Vec<u64>); 10] = [
            ("parent.npy", "<u4", vec![n]),
            ("first_child.npy", "<u4", vec![n]),
            ("depth.npy", "|u1", vec![n]),
            ("rgb.npy", "|u1", vec![n, 3]),
            ("sigma.npy", "<f4", vec![n]),
            ("g3.npy", "<u4", vec![n, 3]),
            ("origin.npy", "<u4", vec![n, 3]),
            ("roots.npy", "<u4", vec![3]),
            ("max_depth.npy", "<u4", vec![]),
            ("root_size.npy", "<f8", vec![]),
        ];
        assert_eq!(entries.len(), want.len());
        for ((name, descr, shape, _), (wn, wd, ws)) in entries.iter().zip(&want) {
            assert_eq!((name.as_str(), descr.as_str(), shape), (*wn, *wd, ws));
        }
        assert_eq!(entries[7].3, [2.0, 1.0, 1.0]);
        assert_eq!(entries[8].3, [4.0]);
        assert_eq!(entries[9].3, [0.5]);
        assert_eq!(entries[2].3[..2], [0.0, 0.0]);
        assert_eq!(entries[2].3[2], f64::from(FREE));
        // The same tree gives the same bytes.
        assert_eq!(bytes, dump_bytes(&tree));
    }

    #[test]
    fn a_dump_reads_back_as_the_same_tree_and_bad_dumps_are_refused() {
        let canvas = octopaint_model::Canvas { roots: [2, 1, 1], max_depth: 4, root_size: 0.5, capacity: 256 };
        let mut tree = Tree::new(&canvas);
        let u = tree.allocate_unit().unwrap();
        tree.make_children(0, u);
        tree.set_value(u + 3, [10, 20, 30], 2.5);
        tree.update_prefilter();
        let bytes = dump_bytes(&tree);
        let back = read_dump(&bytes).unwrap();
        assert_eq!((&back.parent, &back.first_child, &back.depth, &back.rgb), (&tree.parent, &tree.first_child, &tree.depth, &tree.rgb));
        assert_eq!(back.sigma.iter().map(|s| s.to_bits()).collect::<Vec<_>>(), tree.sigma.iter().map(|s| s.to_bits()).collect::<Vec<_>>());
        assert_eq!((back.lat.roots, back.lat.max_depth, back.lat.root_size), ([2, 1, 1], 4, 0.5));
        assert_eq!(dump_bytes(&back), bytes);

        let e = read_dump(b"hello").map(|_| ()).unwrap_err();
        assert!(e.contains("not an .npz"), "{e}");
        // Rewrite the dump with one array changed (None: left out).
        let n = tree.n_used() as usize;
        let (origin, g3) = (origins(&tree), g3_table(&tree));
        let names = TREE_ARRAYS.map(String::from);
        let with = |name: &str, values: Option<Values>, shape: Vec<usize>| {
            let mut arrays = dump_arrays(&tree, &g3, &origin, &names);
            let k = arrays.iter().position(|a| a.name == name).unwrap();
            match values {
                Some(v) => arrays[k] = NpyArray { name: arrays[k].name, shape, values: v },
                None => drop(arrays.remove(k)),
            }
            read_dump(&write_npz(Cursor::new(Vec::new()), &arrays).unwrap().into_inner()).map(|_| ()).unwrap_err()
        };
        let e = with("sigma", None, vec![]);
        assert!(e.contains("sigma.npy"), "{e}");
        let sigma64: Vec<f64> = tree.sigma.iter().map(|&s| f64::from(s)).collect();
        let e = with("sigma", Some(Values::F64(&sigma64)), vec![n]);
        assert!(e.contains("sigma.npy: dtype '<f8' where <f4 is expected"), "{e}");
        let e = with("depth", Some(Values::U8(&tree.depth[..n - 8])), vec![n - 8]);
        assert!(e.contains("depth.npy: shape [") && e.contains("where ["), "{e}");
        let mut parent = tree.parent.clone();
        parent[u as usize + 5] = 1;
        let e = with("parent", Some(Values::U32(&parent)), vec![n]);
        assert!(e.starts_with("not a valid tree"), "{e}");
        let e = with("max_depth", Some(Values::U32(&[40])), vec![]);
        assert!(e.contains("the dump's canvas") && e.contains("max_depth"), "{e}");
        let nan = [f64::NAN];
        let e = with("root_size", Some(Values::F64(&nan)), vec![]);
        assert!(e.contains("the dump's canvas") && e.contains("root_size"), "{e}");
    }
}
