//! Tree dumps (spec 11): the `.npz` both implementations write at a trace's
//! `snapshot` events and the conformance driver compares. Reference twin:
//! reference/octopaint_ref/dump.py.
//!
//! The bytes are fixed by the spec so that the same tree always gives the
//! same file, in either implementation: a zip of stored `.npy` entries laid
//! out exactly as CPython's `zipfile.writestr` and numpy's `write_array`
//! (format 1.0) write them. No zip or npy crate promises those exact bytes:
//! the `zip` crate (2.6) writes "version made by 4.5" where CPython writes
//! 2.0 and decides zip64 records differently, and numpy's header carries
//! growth-axis spaces and 64-byte padding. So both formats are written out
//! here, and the conformance driver compares the files byte for byte.
//!
//! ```text
//!  local header (30 bytes)         central entry (46 bytes)      end record (22)
//!  50 4b 03 04  signature          50 4b 01 02  signature        50 4b 05 06
//!  14 00        version needed 20  14 03        made by 2.0,Unix 0000 0000 disks
//!  00 00        flags              14 00        needed 20        count, count
//!  00 00        stored             00 00 00 00  flags, stored    dir size
//!  00 00 21 00  1980-01-01 00:00   00 00 21 00  time, date       dir offset
//!  crc  csize  usize  nlen  0      crc csize usize nlen 0 0 0 0  00 00 comment
//!  name                            a4 01 00 00 attrs  offset name
//! ```

use std::io::Write;

use crate::g3::g3_table;
use crate::pool::{FREE, NONE, Tree};

#[cfg(target_endian = "big")]
compile_error!("tree dumps are written by reinterpreting little-endian pools");

/// Python's `zipfile.ZIP64_LIMIT`.
const ZIP64_LIMIT: u64 = (1 << 31) - 1;

/// One `.npy` entry: dtype descr, shape, little-endian C-order bytes.
pub struct NpyArray<'a> {
    pub name: &'static str,
    pub descr: &'static str,
    pub shape: Vec<usize>,
    pub data: &'a [u8],
}

/// numpy's `_write_array_header` + `_wrap_header` for format 1.0: the dict
/// repr, spaces for a growth axis of up to 21 digits, padding so the data
/// starts at a multiple of 64, and a newline.
pub fn npy_header(descr: &str, shape: &[usize]) -> Vec<u8> {
    let shape_repr = match shape {
        [] => "()".to_string(),
        [n] => format!("({n},)"),
        dims => format!("({})", dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    };
    let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_repr}, }}");
    if let Some(first) = shape.first() {
        header.push_str(&" ".repeat(21usize.saturating_sub(first.to_string().len())));
    }
    let hlen = header.len() + 1;
    let padlen = 64 - ((8 + 2 + hlen) % 64);
    let mut out = Vec::with_capacity(10 + hlen + padlen);
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&((hlen + padlen) as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend(std::iter::repeat_n(b' ', padlen));
    out.push(b'\n');
    out
}

struct Entry {
    name: &'static str,
    crc: u32,
    size: u64,
    offset: u64,
}

fn u16le(v: u64) -> [u8; 2] {
    (v as u16).to_le_bytes()
}
fn u32le(v: u64) -> [u8; 4] {
    (v as u32).to_le_bytes()
}

/// Write the arrays as a zip of stored `.npy` entries, byte for byte what
/// CPython's zipfile writes for the same entries (zip64 fields included
/// where it would add them).
pub fn write_npz(out: &mut impl Write, arrays: &[NpyArray]) -> std::io::Result<()> {
    let mut entries = Vec::new();
    let mut pos: u64 = 0;
    for a in arrays {
        let header = npy_header(a.descr, &a.shape);
        let size = (header.len() + a.data.len()) as u64;
        let mut h = crc32fast::Hasher::new();
        h.update(&header);
        h.update(a.data);
        let crc = h.finalize();
        let name = format!("{}.npy", a.name);
        let zip64 = size as f64 * 1.05 > ZIP64_LIMIT as f64;
        let big = size > ZIP64_LIMIT;
        let mut local = Vec::with_capacity(64);
        local.extend_from_slice(b"PK\x03\x04");
        local.extend_from_slice(&[if big { 45 } else { 20 }, 0]);
        local.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0x21, 0]); // flags, stored, time, date
        local.extend_from_slice(&crc.to_le_bytes());
        let field = if big { 0xFFFF_FFFF } else { size };
        local.extend_from_slice(&u32le(field));
        local.extend_from_slice(&u32le(field));
        local.extend_from_slice(&u16le(name.len() as u64));
        local.extend_from_slice(&u16le(if zip64 { 20 } else { 0 }));
        local.extend_from_slice(name.as_bytes());
        if zip64 {
            local.extend_from_slice(&[1, 0, 16, 0]);
            local.extend_from_slice(&size.to_le_bytes());
            local.extend_from_slice(&size.to_le_bytes());
        }
        out.write_all(&local)?;
        out.write_all(&header)?;
        out.write_all(a.data)?;
        entries.push(Entry { name: a.name, crc, size, offset: pos });
        pos += local.len() as u64 + size;
    }
    let dir_start = pos;
    for e in &entries {
        let name = format!("{}.npy", e.name);
        let mut extra: Vec<u64> = Vec::new();
        let size_field = if e.size > ZIP64_LIMIT {
            extra.extend([e.size, e.size]);
            0xFFFF_FFFF
        } else {
            e.size
        };
        let offset_field = if e.offset > ZIP64_LIMIT {
            extra.push(e.offset);
            0xFFFF_FFFF
        } else {
            e.offset
        };
        let version = if extra.is_empty() { 20 } else { 45 };
        let mut c = Vec::with_capacity(46 + name.len() + 28);
        c.extend_from_slice(b"PK\x01\x02");
        c.extend_from_slice(&[version, 3, version, 0]);
        c.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0x21, 0]);
        c.extend_from_slice(&e.crc.to_le_bytes());
        c.extend_from_slice(&u32le(size_field));
        c.extend_from_slice(&u32le(size_field));
        c.extend_from_slice(&u16le(name.len() as u64));
        c.extend_from_slice(&u16le(if extra.is_empty() { 0 } else { 4 + 8 * extra.len() as u64 }));
        c.extend_from_slice(&[0, 0, 0, 0, 0, 0]); // comment length, disk, internal attributes
        c.extend_from_slice(&(0o644u32 << 16).to_le_bytes());
        c.extend_from_slice(&u32le(offset_field));
        c.extend_from_slice(name.as_bytes());
        if !extra.is_empty() {
            c.extend_from_slice(&u16le(1));
            c.extend_from_slice(&u16le(8 * extra.len() as u64));
            for v in &extra {
                c.extend_from_slice(&v.to_le_bytes());
            }
        }
        out.write_all(&c)?;
        pos += c.len() as u64;
    }
    let dir_size = pos - dir_start;
    let count = entries.len() as u64;
    if dir_start > ZIP64_LIMIT || dir_size > ZIP64_LIMIT {
        let mut z = Vec::with_capacity(76);
        z.extend_from_slice(b"PK\x06\x06");
        z.extend_from_slice(&44u64.to_le_bytes());
        z.extend_from_slice(&[45, 0, 45, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        z.extend_from_slice(&count.to_le_bytes());
        z.extend_from_slice(&count.to_le_bytes());
        z.extend_from_slice(&dir_size.to_le_bytes());
        z.extend_from_slice(&dir_start.to_le_bytes());
        z.extend_from_slice(b"PK\x06\x07");
        z.extend_from_slice(&0u32.to_le_bytes());
        z.extend_from_slice(&pos.to_le_bytes());
        z.extend_from_slice(&1u32.to_le_bytes());
        out.write_all(&z)?;
    }
    let mut end = Vec::with_capacity(22);
    end.extend_from_slice(b"PK\x05\x06");
    end.extend_from_slice(&[0, 0, 0, 0]);
    end.extend_from_slice(&u16le(count.min(0xFFFF)));
    end.extend_from_slice(&u16le(count.min(0xFFFF)));
    end.extend_from_slice(&u32le(dir_size.min(0xFFFF_FFFF)));
    end.extend_from_slice(&u32le(dir_start.min(0xFFFF_FFFF)));
    end.extend_from_slice(&[0, 0]);
    out.write_all(&end)
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
        NpyArray { name: "parent", descr: "<u4", shape: vec![n], data: bytemuck::cast_slice(&tree.parent) },
        NpyArray { name: "first_child", descr: "<u4", shape: vec![n], data: bytemuck::cast_slice(&tree.first_child) },
        NpyArray { name: "depth", descr: "|u1", shape: vec![n], data: &tree.depth },
        NpyArray { name: "rgb", descr: "|u1", shape: vec![n, 3], data: bytemuck::cast_slice(&tree.rgb) },
        NpyArray { name: "sigma", descr: "<f4", shape: vec![n], data: bytemuck::cast_slice(&tree.sigma) },
        NpyArray { name: "g3", descr: "<u4", shape: vec![n, 3], data: bytemuck::cast_slice(g3) },
        NpyArray { name: "origin", descr: "<u4", shape: vec![n, 3], data: bytemuck::cast_slice(&origin) },
        NpyArray { name: "roots", descr: "<u4", shape: vec![3], data: bytemuck::cast_slice(&roots[..]) },
        NpyArray { name: "max_depth", descr: "<u4", shape: vec![], data: bytemuck::cast_slice(&max_depth[..]) },
        NpyArray { name: "root_size", descr: "<f8", shape: vec![], data: bytemuck::cast_slice(&root_size[..]) },
    ];
    let mut out = Vec::new();
    write_npz(&mut out, &arrays).expect("writing to memory cannot fail");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn npy_headers_match_numpy() {
        // Header text numpy 2.4 writes (format 1.0), and its total length.
        let h = npy_header("<u4", &[17784]);
        assert_eq!(h.len(), 128);
        let text = std::str::from_utf8(&h[10..]).unwrap();
        assert_eq!(text.trim_end(), "{'descr': '<u4', 'fortran_order': False, 'shape': (17784,), }");
        assert_eq!(npy_header("<f8", &[]).len(), 128);
        assert!(std::str::from_utf8(&npy_header("|u1", &[8, 3])[10..]).unwrap().starts_with("{'descr': '|u1', 'fortran_order': False, 'shape': (8, 3), }"));
        for n in [0, 1, 10usize.pow(19), usize::MAX] {
            assert_eq!(npy_header("<u4", &[n]).len() % 64, 0);
        }
    }

    #[test]
    fn zip_layout_is_cpythons() {
        let data = [1u8, 2, 3];
        let mut out = Vec::new();
        write_npz(&mut out, &[NpyArray { name: "a", descr: "|u1", shape: vec![3], data: &data }]).unwrap();
        // 30 + 5 name + 128 header + 3 data, then 46 + 5, then 22.
        assert_eq!(out.len(), 30 + 5 + 131 + 51 + 22);
        assert_eq!(&out[..12], b"PK\x03\x04\x14\x00\x00\x00\x00\x00\x00\x00");
        let c = 30 + 5 + 131;
        assert_eq!(&out[c..c + 8], b"PK\x01\x02\x14\x03\x14\x00");
        assert_eq!(&out[c + 38..c + 42], &(0o644u32 << 16).to_le_bytes());
    }
}
