//! Voxel sets' files (spec 15.1): an `.npz` of `depth`, `ijk`, `rgb` and
//! `sigma`, stored, read here with every check of the spec, written with
//! fixed timestamps (the same bytes for the same set). Reference twin:
//! reference/octopaint_ref/voxelset.py (`parse`, `write_bytes`).

use std::io::Cursor;

use octopaint_model::{Canvas, MAX_VOXELS, VoxelSet};
use sha2::{Digest, Sha256};

use crate::npz::{NpyArray, Values, write_npz};

/// The SHA-256 of some bytes, as 64 lowercase hexadecimal digits.
pub fn sha256_hex(data: &[u8]) -> String {
    let digest = Sha256::digest(data);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// A voxel set's file: stored entries in the order of spec 15.1, every
/// timestamp 1980-01-01 (the same bytes for the same set).
pub fn voxel_set_bytes(vs: &VoxelSet) -> Vec<u8> {
    let depth = [vs.depth];
    let ijk: Vec<u32> = vs.ijk.iter().flatten().copied().collect();
    let rgb: Vec<u8> = vs.rgb.iter().flatten().copied().collect();
    let n = vs.len();
    let arrays = [
        NpyArray { name: "depth", shape: vec![], values: Values::U32(&depth) },
        NpyArray { name: "ijk", shape: vec![n, 3], values: Values::U32(&ijk) },
        NpyArray { name: "rgb", shape: vec![n, 3], values: Values::U8(&rgb) },
        NpyArray { name: "sigma", shape: vec![n], values: Values::F32(&vs.sigma) },
    ];
    write_npz(Cursor::new(Vec::new()), &arrays).expect("writing to memory").into_inner()
}

/// The little-endian u16 at `at` in `bytes`, if it is there.
fn le_u16(bytes: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(bytes.get(at..at + 2)?.try_into().ok()?))
}

/// One entry of a voxel set: checked to be stored (not compressed), with
/// its dtype, rank (and a last dimension of 3 for rank 2), C order, and at
/// most MAX_VOXELS rows; its shape and values.
fn entry<T: npyz::Deserialize>(
    zip: &mut zip::ZipArchive<Cursor<&[u8]>>,
    bytes: &[u8],
    name: &str,
    dtype: &str,
    rank: usize,
) -> Result<(Vec<u64>, Vec<T>), String> {
    let mut f = zip.by_name(&format!("{name}.npy")).map_err(|e| match e {
        zip::result::ZipError::FileNotFound => format!("the entry {name}.npy is missing"),
        e => format!("{name}.npy: {e}"),
    })?;
    if f.compression() != zip::CompressionMethod::Stored {
        return Err(format!("{name}.npy is compressed (write voxel sets with numpy's savez, not savez_compressed)"));
    }
    // A well-formed archive (spec 15.1): a stored entry's sizes agree, and
    // its local header names the file its central directory entry does.
    if f.compressed_size() != f.size() {
        return Err(format!("damaged .npz: {name}.npy is stored in {} bytes but holds {}", f.compressed_size(), f.size()));
    }
    let local = usize::try_from(f.header_start()).ok().and_then(|h| {
        let len = usize::from(le_u16(bytes, h + 26)?);
        bytes.get(h + 30..h + 30 + len)
    });
    if local != Some(f.name_raw()) {
        return Err(format!("damaged .npz: the local header of {name}.npy names another file"));
    }
    // Neither encrypted, patched nor strongly encrypted (its central
    // directory entry's flags, as Python's zipfile reads them).
    let flags = usize::try_from(f.central_header_start()).ok().and_then(|h| le_u16(bytes, h + 8)).unwrap_or(0);
    if f.encrypted() || flags & 0x61 != 0 {
        return Err(format!("damaged .npz: {name}.npy is encrypted or patched"));
    }
    let mut data = Vec::new();
    std::io::Read::read_to_end(&mut f, &mut data).map_err(|e| format!("{name}.npy: {e}"))?;
    let npy = npyz::NpyFile::new(&data[..]).map_err(|e| format!("{name}.npy: not an .npy array: {e}"))?;
    let got = npy.dtype().descr();
    let got = got.trim();
    if got != format!("'{dtype}'") && !(dtype == "|u1" && got == "'<u1'") {
        return Err(format!("{name}.npy has dtype {got}, expected {dtype}"));
    }
    let shape = npy.shape().to_vec();
    if shape.len() != rank || (rank == 2 && shape[1] != 3) {
        let want = ["[]", "[n]", "[n, 3]"][rank];
        return Err(format!("{name}.npy has shape {shape:?}, expected {want}"));
    }
    if rank == 2 && npy.order() != npyz::Order::C {
        return Err(format!("{name}.npy is Fortran-ordered (C order is required)"));
    }
    if rank > 0 && shape[0] > MAX_VOXELS {
        return Err(format!("{name}.npy holds {} voxels, more than {MAX_VOXELS}", shape[0]));
    }
    let values = npy.into_vec::<T>().map_err(|e| format!("{name}.npy: {e}"))?;
    Ok((shape, values))
}

/// The archive's end-of-central-directory record, as spec 15.1 requires
/// it (and as reference/octopaint_ref/voxelset.py checks it): the last
/// `PK\5\6` in the file's final 65,557 bytes, one disk (both disk numbers
/// 0), its two entry counts equal, its central directory ending where the
/// record begins (nothing between them, nothing before the archive) and
/// filled exactly by its entries, each needing zip 6.3 at most, and its
/// comment within the file. zip readers differ on each of these (one
/// takes a comment cut short, another refuses it), so the rule is the
/// spec's. Returns the entry count.
fn check_end_record(data: &[u8]) -> Result<u16, String> {
    let damaged = |why: &str| Err(format!("not an .npz (zip) file: {why}"));
    let tail_start = data.len().saturating_sub(22 + 0xFFFF);
    let tail = &data[tail_start..];
    let Some(at) = tail.windows(4).rposition(|w| w == b"PK\x05\x06") else { return damaged("no end of central directory record") };
    let Some(rec) = tail.get(at..at + 22) else { return damaged("its end record is cut short") };
    let u16_at = |i: usize| u16::from_le_bytes([rec[i], rec[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes([rec[i], rec[i + 1], rec[i + 2], rec[i + 3]]);
    if u16_at(4) != 0 || u16_at(6) != 0 {
        return damaged("it spans several disks");
    }
    if u16_at(8) != u16_at(10) {
        return damaged("its end record counts its entries two ways");
    }
    let record = (tail_start + at) as u64;
    if u64::from(u32_at(16)) + u64::from(u32_at(12)) != record {
        return damaged("its central directory does not end where its end record begins");
    }
    if at + 22 + usize::from(u16_at(20)) > tail.len() {
        return damaged("its end record's comment runs past the end of the file");
    }
    // Each central directory entry: a zip version this reader knows (6.3 at
    // most, as Python's zipfile requires).
    let mut p = u32_at(16) as usize;
    for _ in 0..u16_at(8) {
        let Some(e) = data.get(p..p + 46) else { return damaged("its central directory is cut short") };
        if e[..4] != *b"PK\x01\x02" {
            return damaged("its central directory is damaged");
        }
        if e[6] > 63 {
            return damaged(&format!("an entry needs zip version {}.{} to be read", e[6] / 10, e[6] % 10));
        }
        let len = |i: usize| usize::from(u16::from_le_bytes([e[i], e[i + 1]]));
        p += 46 + len(28) + len(30) + len(32);
        if p as u64 > record {
            return damaged("an entry of its central directory runs past its end");
        }
    }
    if p as u64 != record {
        return damaged("its central directory holds more than its entries");
    }
    Ok(u16_at(8))
}

/// Check `data` as a voxel set for `canvas` (spec 15.1); the error says
/// what is wrong.
pub fn parse_voxel_set(data: &[u8], canvas: &Canvas) -> Result<VoxelSet, String> {
    let entries = check_end_record(data)?;
    let mut zip = zip::ZipArchive::new(Cursor::new(data)).map_err(|e| format!("not an .npz (zip) file: {e}"))?;
    if zip.len() != usize::from(entries) {
        return Err(format!("not an .npz (zip) file: its end record counts {entries} entries, its central directory holds {}", zip.len()));
    }
    let (_, depth) = entry::<u32>(&mut zip, data, "depth", "<u4", 0)?;
    let (sh, ijk) = entry::<u32>(&mut zip, data, "ijk", "<u4", 2)?;
    let (sr, rgb) = entry::<u8>(&mut zip, data, "rgb", "|u1", 2)?;
    let (ss, sigma) = entry::<f32>(&mut zip, data, "sigma", "<f4", 1)?;
    let n = sh[0];
    if sr[0] != n || ss[0] != n {
        return Err(format!("ijk, rgb and sigma hold {n}, {} and {} voxels", sr[0], ss[0]));
    }
    let depth = depth[0];
    if depth > canvas.max_depth {
        return Err(format!("depth {depth} is deeper than the canvas's max_depth {}", canvas.max_depth));
    }
    let extent = canvas.roots.map(|r| u64::from(r) << depth);
    let ijk: Vec<[u32; 3]> = ijk.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    if let Some(i) = ijk.iter().position(|q| (0..3).any(|a| u64::from(q[a]) >= extent[a])) {
        return Err(format!("voxel {i} at {:?} is outside the canvas ({extent:?} voxels at depth {depth})", ijk[i]));
    }
    if let Some(i) = sigma.iter().position(|s| !s.is_finite() || s.is_sign_negative()) {
        return Err(format!("voxel {i} has sigma {:?} (finite, >= 0 and not -0 required)", sigma[i]));
    }
    let mut order: Vec<u32> = (0..n as u32).collect();
    order.sort_by_key(|&i| key(ijk[i as usize]));
    if let Some(w) = order.windows(2).find(|w| ijk[w[0] as usize] == ijk[w[1] as usize]) {
        let (i, j) = (w[0].min(w[1]), w[0].max(w[1]));
        return Err(format!("voxels {i} and {j} are both at {:?}", ijk[i as usize]));
    }
    let rgb = rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(VoxelSet { depth, ijk, rgb, sigma })
}

/// Sort key of a coordinate: (z, y, x).
#[inline]
fn key(q: [u32; 3]) -> [u32; 3] {
    [q[2], q[1], q[0]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn canvas() -> Canvas {
        Canvas { roots: [2, 1, 1], max_depth: 6, root_size: 1.0, capacity: 1 << 20 }
    }

    #[test]
    fn a_voxel_set_round_trips_through_its_file_and_bad_ones_are_refused() {
        let vs = VoxelSet { depth: 2, ijk: vec![[1, 1, 1], [7, 3, 0]], rgb: vec![[1, 2, 3], [4, 5, 6]], sigma: vec![1.5, 0.0] };
        let bytes = voxel_set_bytes(&vs);
        assert_eq!(parse_voxel_set(&bytes, &canvas()).unwrap(), vs);
        let bad = |f: &dyn Fn(&mut VoxelSet)| {
            let mut v = vs.clone();
            f(&mut v);
            parse_voxel_set(&voxel_set_bytes(&v), &canvas()).unwrap_err()
        };
        assert!(bad(&|v| v.depth = 7).contains("deeper"));
        assert!(bad(&|v| v.ijk[1] = [8, 0, 0]).contains("outside"));
        assert!(bad(&|v| v.ijk[1] = [1, 1, 1]).contains("both at"));
        assert!(bad(&|v| v.sigma[0] = f32::NAN).contains("sigma"));
        assert!(bad(&|v| v.sigma[0] = -0.0).contains("sigma"));
        for cut in [0, 10, bytes.len() / 2, bytes.len() - 1] {
            assert!(parse_voxel_set(&bytes[..cut], &canvas()).is_err(), "a file cut at {cut} was read");
        }
    }

    #[test]
    fn the_digest_is_sha256() {
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }
}
