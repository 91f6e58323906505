//! Writing `.npz` files: a zip (the `zip` crate) of stored `.npy` entries
//! (the `npyz` crate) with fixed timestamps, so the same arrays give the
//! same bytes. Tree dumps (spec 11) and voxel sets (spec 15.1) are written
//! with it.

use std::io::{Seek, Write};

use npyz::WriterBuilder;

use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, DateTime, ZipWriter};

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
    pub name: &'a str,
    pub shape: Vec<usize>,
    pub values: Values<'a>,
}

/// One `.npy` file: npyz's header, then the values. On a little-endian
/// machine the values' bytes are already the file's (`<` dtypes) and go out
/// in one write: element by element, every 4-byte write went through the
/// zip writer's CRC and counters, a fifth of a replay's time.
fn npy<T: npyz::AutoSerialize + bytemuck::Pod>(mut out: impl Write, shape: &[usize], values: &[T]) -> std::io::Result<()> {
    let shape: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    let opts = npyz::WriteOptions::<T>::new().default_dtype().shape(&shape);
    if cfg!(target_endian = "little") {
        opts.writer(&mut out).write_header_only()?;
        out.write_all(bytemuck::cast_slice(values))
    } else {
        let mut w = opts.writer(out).begin_nd()?;
        w.extend(values.iter().copied())?;
        w.finish()
    }
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
