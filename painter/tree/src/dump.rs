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

use npyz::WriterBuilder;
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, DateTime, ZipWriter};

use crate::g3::g3_table;
use crate::pool::{FREE, NONE, Tree};

/// The values of one array, flat in C order.
pub enum Values<'a> {
    U8(&'a [u8]),
    U32(&'a [u32]),
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl Values<'_> {
    fn len(&self) -> usize {
        match self {
            Values::U8(v) => v.len(),
            Values::U32(v) => v.len(),
            Values::F32(v) => v.len(),
            Values::F64(v) => v.len(),
        }
    }

    fn item_size(&self) -> usize {
        match self {
            Values::U8(_) => 1,
            Values::U32(_) | Values::F32(_) => 4,
            Values::F64(_) => 8,
        }
    }
}

/// One `.npy` entry: its name (without `.npy`), shape and values.
pub struct NpyArray<'a> {
    pub name: &'static str,
    pub shape: Vec<usize>,
    pub values: Values<'a>,
}

fn npy<T: npyz::AutoSerialize + Copy>(out: impl Write, shape: &[usize], values: &[T]) -> std::io::Result<()> {
    let shape: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    let mut w = npyz::WriteOptions::new().default_dtype().shape(&shape).writer(out).begin_nd()?;
    w.extend(values.iter().copied())?;
    w.finish()
}

/// Write the arrays as an `.npz`: one stored `.npy` entry per array, in
/// order, every timestamp 1980-01-01 00:00.
pub fn write_npz<W: Write + Seek>(out: W, arrays: &[NpyArray]) -> std::io::Result<W> {
    let mut zip = ZipWriter::new(out);
    for a in arrays {
        assert_eq!(a.shape.iter().product::<usize>(), a.values.len(), "{}: shape and values disagree", a.name);
        // Entries past 4 GiB need zip64 fields, which the zip crate writes
        // only when told before the data (the header is under 1 KiB).
        let size = (a.values.len() * a.values.item_size()) as u64 + 1024;
        let options = SimpleFileOptions::default()
            .compression_method(CompressionMethod::Stored)
            .last_modified_time(DateTime::default())
            .unix_permissions(0o644)
            .large_file(size >= u64::from(u32::MAX));
        zip.start_file(format!("{}.npy", a.name), options).map_err(std::io::Error::other)?;
        match a.values {
            Values::U8(v) => npy(&mut zip, &a.shape, v)?,
            Values::U32(v) => npy(&mut zip, &a.shape, v)?,
            Values::F32(v) => npy(&mut zip, &a.shape, v)?,
            Values::F64(v) => npy(&mut zip, &a.shape, v)?,
        }
    }
    zip.finish().map_err(std::io::Error::other)
}

/// Lattice origin of every cell (NONE for free cells), parents first.
pub fn origins(tree: &Tree) -> Vec<[u32; 3]> {
    let n = tree.n_used() as usize;
    let mut o = vec![[NONE; 3]; n];
    let mut stack: Vec<u32> = (0..tree.lat.n_roots).collect();
    for &r in &stack {
        o[r as usize] = tree.lat.root_origin(r);
    }
    while let Some(c) = stack.pop() {
        let fc = tree.first_child[c as usize];
        if fc == NONE {
            continue;
        }
        let d = u32::from(tree.depth[c as usize]);
        for k in 0..8 {
            o[(fc + k) as usize] = tree.child_origin(o[c as usize], d, k);
            stack.push(fc + k);
        }
    }
    debug_assert!((0..n).all(|c| (tree.depth[c] == FREE) == (o[c][0] == NONE)));
    o
}

/// The dump of a tree, as bytes (spec 11.1).
pub fn dump_bytes(tree: &Tree) -> Vec<u8> {
    dump_bytes_with(tree, &g3_table(tree))
}

/// The dump of a tree with a given g3 table (read back from the GPU).
pub fn dump_bytes_with(tree: &Tree, g3: &[[u32; 3]]) -> Vec<u8> {
    let n = tree.n_used() as usize;
    assert_eq!(g3.len(), n, "one g3 row per cell");
    let origin = origins(tree);
    let roots = tree.lat.roots;
    let max_depth = [tree.lat.max_depth];
    let root_size = [tree.lat.root_size];
    let arrays = [
        NpyArray { name: "parent", shape: vec![n], values: Values::U32(&tree.parent) },
        NpyArray { name: "first_child", shape: vec![n], values: Values::U32(&tree.first_child) },
        NpyArray { name: "depth", shape: vec![n], values: Values::U8(&tree.depth) },
        NpyArray { name: "rgb", shape: vec![n, 3], values: Values::U8(bytemuck::cast_slice(&tree.rgb)) },
        NpyArray { name: "sigma", shape: vec![n], values: Values::F32(&tree.sigma) },
        NpyArray { name: "g3", shape: vec![n, 3], values: Values::U32(bytemuck::cast_slice(g3)) },
        NpyArray { name: "origin", shape: vec![n, 3], values: Values::U32(bytemuck::cast_slice(&origin)) },
        NpyArray { name: "roots", shape: vec![3], values: Values::U32(&roots[..]) },
        NpyArray { name: "max_depth", shape: vec![], values: Values::U32(&max_depth[..]) },
        NpyArray { name: "root_size", shape: vec![], values: Values::F64(&root_size[..]) },
    ];
    write_npz(Cursor::new(Vec::new()), &arrays).expect("writing to memory cannot fail").into_inner()
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let tree = Tree::new(&crate::trace::Canvas { roots: [2, 1, 1], max_depth: 4, root_size: 0.5, capacity: 64 });
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
}
