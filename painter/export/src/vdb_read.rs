//! An OpenVDB file reader for fog volumes: float and vec3 grids of the
//! standard 5-4-3 tree, file formats 222 to 225 (OpenVDB 3.0 and later;
//! OpenVDB 6 to 11 and Blender write 224). It returns each grid's active
//! leaf voxels and active tiles with their values; everything inactive is
//! dropped. The layout follows OpenVDB's own source, cited at each rule:
//! `io/Archive.cc` (header, grids), `io/GridDescriptor.cc`, `MetaMap.cc`,
//! `math/Maps.h`, `tree/Tree.h`, `tree/RootNode.h`, `tree/InternalNode.h`,
//! `tree/LeafNode.h` and `io/Compression.{h,cc}`; the blosc chunks follow
//! c-blosc 1.x (`blosc/blosc.c`, `blosc/blosclz.c`) and the LZ4 block
//! format. Everything is little-endian.
//!
//! ```text
//! file    i64 magic 0x56444220 | u32 version | u32 library major | u32 minor
//!         | u8 has grid offsets | 36-char uuid | metadata | i32 grids | grid...
//! grid    string unique name | string type | string instance parent
//!         | i64 grid pos | i64 block pos | i64 end pos
//!  @grid  u32 compression | metadata | transform | topology (if not an
//!         instance) | buffers; the next descriptor is at `end pos`
//! topology i32 buffer count | root: background | u32 tiles | u32 children
//!         | tiles (3 × i32, value, u8 active) | children (3 × i32, node5)
//! node5/4 child mask | value mask | value table | children in mask order
//! leaf    value mask (topology) ; value mask | value table (buffers)
//! table   u8 mode | inactive values | selection mask | data
//! data    i64 n | n bytes of zlib or blosc; n <= 0: -n raw bytes
//! ```
//!
//! Robustness: every length and count is checked against the bytes left
//! before anything is allocated from it; the largest allocation a file can
//! ask for per step is one node's value table (32768 values), and the
//! active voxels (tiles counted as the voxels they cover) are checked
//! against [`ReadLimits::max_voxels`] while the topology is read, before
//! any value is expanded. Malformed input gives an error, never a panic.

use std::collections::BTreeMap;

/// What the reader refuses to expand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadLimits {
    /// Active leaf voxels plus active tiles counted as the voxels they
    /// cover, over all grids returned (an instance counts again): the file
    /// is refused beyond it.
    pub max_voxels: u64,
    /// Count a tile as the voxels it covers (true: for a caller that
    /// expands tiles) or as one entry (false: for a caller that resamples
    /// tiles itself and bounds what it makes, such as the import: then
    /// `max_voxels` bounds what the reader holds, leaf voxels plus tiles).
    pub tile_cover: bool,
}

impl Default for ReadLimits {
    /// 2^31 voxels: about 8 GiB of float values and coordinates.
    fn default() -> Self {
        ReadLimits { max_voxels: 1 << 31, tile_cover: true }
    }
}

/// A grid's values: one f32 (float, double and half grids) or three (vec3s
/// and vec3d grids) per voxel or tile.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    Float(Vec<f32>),
    Vec3(Vec<[f32; 3]>),
}

impl Values {
    pub fn len(&self) -> usize {
        match self {
            Values::Float(v) => v.len(),
            Values::Vec3(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn from_flat(comps: usize, flat: Vec<f32>) -> Values {
        if comps == 3 { Values::Vec3(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()) } else { Values::Float(flat) }
    }
}

/// Index space to world space: `world = index · scale + translate`, where
/// index `i` is the centre of voxel `i` (OpenVDB's convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    pub scale: [f64; 3],
    pub translate: [f64; 3],
}

/// One grid read from the file.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// The grid's name, without the "\x1e N" suffix OpenVDB adds to tell
    /// apart grids of the same name.
    pub name: String,
    /// The grid type as the file spells it, e.g. `Tree_float_5_4_3` or
    /// `Tree_vec3s_5_4_3_HalfFloat`.
    pub grid_type: String,
    /// The "class" metadata: "fog volume", "level set", "unknown", ...
    pub class: Option<String>,
    /// Whether the values were stored as 16-bit floats.
    pub saved_as_half: bool,
    /// The grid's compression flags as stored (io/Compression.h): 0x1 zip,
    /// 0x2 active mask, 0x4 blosc.
    pub compression: u32,
    pub transform: Transform,
    /// The value of every voxel that is neither active nor set: one element.
    pub background: Values,
    /// Active leaf voxels (leaf values whose value-mask bit is on), with
    /// their values in the same order.
    pub voxels: Vec<[i32; 3]>,
    pub voxel_values: Values,
    /// Active tiles: origin (the lowest voxel index covered) and edge in
    /// voxels (8, 128 or 4096), with their values in the same order.
    pub tiles: Vec<([i32; 3], u32)>,
    pub tile_values: Values,
}

/// A grid of a type this reader does not read (int, bool, points, masks...).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Skipped {
    pub name: String,
    pub grid_type: String,
}

/// Why a file was refused. Offsets are from the start of the file.
#[derive(Debug, thiserror::Error)]
pub enum VdbReadError {
    #[error("not an OpenVDB file: it does not start with the VDB magic number")]
    NotVdb,
    #[error(
        "OpenVDB file format version {version} is not supported: this reader reads versions 222 to 225 (OpenVDB 3.0 and later){}",
        if *version < 222 { "; re-save the file with a newer OpenVDB" } else { "" }
    )]
    UnsupportedVersion { version: u32 },
    #[error("the file ends early{}: {what} at byte {offset} needs {needed} bytes, {left} are left", in_grid(grid))]
    Truncated { grid: Option<String>, offset: u64, what: String, needed: u64, left: u64 },
    #[error("malformed OpenVDB file{}: {what} (at byte {offset})", in_grid(grid))]
    Malformed { grid: Option<String>, offset: u64, what: String },
    #[error(
        "grid \"{grid}\" uses the transform {map} (at byte {offset}); only UniformScaleMap, UniformScaleTranslateMap, ScaleMap, ScaleTranslateMap and TranslationMap are supported"
    )]
    UnsupportedTransform { grid: String, map: String, offset: u64 },
    #[error("unsupported compression{}: {what} (at byte {offset})", in_grid(grid))]
    UnsupportedCompression { grid: Option<String>, offset: u64, what: String },
    #[error("grid \"{grid}\" has more active voxels than the limit of {max} (reached at byte {offset})")]
    TooManyVoxels { grid: String, max: u64, offset: u64 },
    #[error("grid \"{grid}\" is an instance of grid \"{parent}\", which the file does not hold")]
    MissingInstanceParent { grid: String, parent: String },
}

fn in_grid(grid: &Option<String>) -> String {
    match grid {
        Some(g) => format!(" in grid \"{g}\""),
        None => String::new(),
    }
}

/// io::OPENVDB_MAGIC.
const MAGIC: i64 = 0x5644_4220;
/// OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION: per-grid compression flags
/// and per-node value-table modes. Older files (OpenVDB 2) are refused.
const VERSION_MIN: u32 = 222;
/// OPENVDB_FILE_VERSION_HALF_GRID (OpenVDB 12.1): adds half grids, leaves
/// the layout of the others as it was.
const VERSION_MAX: u32 = 225;

// io/Compression.h: the grid's compression flags.
const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;

// io/Compression.h: the per-node value-table modes of readCompressedValues.
// 0 NO_MASK_OR_INACTIVE_VALS and 1 NO_MASK_AND_MINUS_BG: no header; the
// inactive values are +background or -background.
const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
const NO_MASK_AND_ALL_VALS: u8 = 6;

/// The value types read, by the tree type's name (Types.h
/// typeNameAsString; the grid type is "Tree_<value>_5_4_3").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ValueType {
    Float,
    Double,
    Half,
    Vec3s,
    Vec3d,
}

impl ValueType {
    fn from_tree_type(t: &str) -> Option<ValueType> {
        // GridDescriptor.cc: the "_HalfFloat" suffix names the storage,
        // not the type.
        let t = t.strip_suffix("_HalfFloat").unwrap_or(t);
        Some(match t {
            "Tree_float_5_4_3" => ValueType::Float,
            "Tree_double_5_4_3" => ValueType::Double,
            "Tree_half_5_4_3" => ValueType::Half,
            "Tree_vec3s_5_4_3" => ValueType::Vec3s,
            "Tree_vec3d_5_4_3" => ValueType::Vec3d,
            _ => return None,
        })
    }

    fn comps(self) -> usize {
        match self {
            ValueType::Float | ValueType::Double | ValueType::Half => 1,
            ValueType::Vec3s | ValueType::Vec3d => 3,
        }
    }

    /// Bytes per component at full precision (root values, inactive values
    /// of a table's header, and tables not saved as half).
    fn width(self) -> usize {
        match self {
            ValueType::Half => 2,
            ValueType::Float | ValueType::Vec3s => 4,
            ValueType::Double | ValueType::Vec3d => 8,
        }
    }
}

/// Decode `bytes` (components of `width` bytes each) to f32.
fn decode_components(bytes: &[u8], width: usize, out: &mut Vec<f32>) {
    match width {
        2 => out.extend(bytes.chunks_exact(2).map(|c| half::f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32())),
        4 => out.extend(bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))),
        _ => out.extend(bytes.chunks_exact(8).map(|c| {
            let mut a = [0u8; 8];
            a.copy_from_slice(c);
            f64::from_le_bytes(a) as f32
        })),
    }
}

/// A bit mask as OpenVDB saves it (util/NodeMasks.h `NodeMask::load`):
/// u64 words, bit `i` in word `i / 64` at bit `i % 64`.
#[derive(Clone)]
struct Mask(Vec<u64>);

impl Mask {
    fn on(&self, i: usize) -> bool {
        self.0[i / 64] >> (i % 64) & 1 == 1
    }
    fn count(&self) -> u64 {
        self.0.iter().map(|w| u64::from(w.count_ones())).sum()
    }
    fn iter_on(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(wi, &w)| {
            let mut w = w;
            std::iter::from_fn(move || {
                if w == 0 {
                    return None;
                }
                let b = w.trailing_zeros() as usize;
                w &= w - 1;
                Some(wi * 64 + b)
            })
        })
    }
}

/// A leaf (LeafNode<T, 3>): its origin and value mask from the topology.
struct Leaf {
    origin: [i32; 3],
    mask: Mask,
}

/// A tree or one root child as far as the buffers need it: the leaves in
/// the order their buffers follow, and the active tiles with their values.
#[derive(Default)]
struct Topology {
    leaves: Vec<Leaf>,
    tiles: Vec<([i32; 3], u32)>,
    tile_values: Vec<f32>,
}

/// What one root-table entry holds (RootNode's std::map<Coord, NodeStruct>).
enum RootEntry {
    Tile,
    Child(Topology),
}

/// How a grid's values are stored.
#[derive(Clone, Copy)]
struct Storage {
    ty: ValueType,
    compression: u32,
    half: bool,
}

/// A cursor over the file with the grid being read, for error messages.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    grid: Option<String>,
    voxels: u64,
    max_voxels: u64,
    tile_cover: bool,
}

type Result<T> = std::result::Result<T, VdbReadError>;

impl<'a> Reader<'a> {
    fn left(&self) -> usize {
        self.data.len() - self.pos
    }

    fn malformed(&self, at: usize, what: impl Into<String>) -> VdbReadError {
        VdbReadError::Malformed { grid: self.grid.clone(), offset: at as u64, what: what.into() }
    }

    fn unsupported(&self, at: usize, what: impl Into<String>) -> VdbReadError {
        VdbReadError::UnsupportedCompression { grid: self.grid.clone(), offset: at as u64, what: what.into() }
    }

    /// The next `n` bytes, checked against what is left before anything
    /// else happens with `n`.
    fn take(&mut self, n: u64, what: &str) -> Result<&'a [u8]> {
        if n > self.left() as u64 {
            return Err(VdbReadError::Truncated {
                grid: self.grid.clone(),
                offset: self.pos as u64,
                what: what.to_string(),
                needed: n,
                left: self.left() as u64,
            });
        }
        let s = &self.data[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(s)
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N as u64, what)?);
        Ok(a)
    }

    fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    fn i64(&mut self, what: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
    fn coord(&mut self, what: &str) -> Result<[i32; 3]> {
        Ok([self.i32(what)?, self.i32(what)?, self.i32(what)?])
    }
    fn vec3d(&mut self, what: &str) -> Result<[f64; 3]> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }

    /// util/Name.h readString: u32 length, then the bytes.
    fn string(&mut self, what: &str) -> Result<String> {
        let n = self.u32(what)?;
        Ok(String::from_utf8_lossy(self.take(u64::from(n), what)?).into_owned())
    }

    fn mask(&mut self, words: usize, what: &str) -> Result<Mask> {
        let bytes = self.take(8 * words as u64, what)?;
        Ok(Mask(bytes.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect()))
    }

    /// One value at full precision (root background and tiles, inactive
    /// values of a table header).
    fn full_value(&mut self, ty: ValueType, out: &mut Vec<f32>, what: &str) -> Result<()> {
        let bytes = self.take((ty.comps() * ty.width()) as u64, what)?;
        decode_components(bytes, ty.width(), out);
        Ok(())
    }

    /// Count `n` more active voxels against the limit.
    fn count_voxels(&mut self, n: u64) -> Result<()> {
        self.voxels = self.voxels.saturating_add(n);
        if self.voxels > self.max_voxels {
            return Err(VdbReadError::TooManyVoxels { grid: self.grid.clone().unwrap_or_default(), max: self.max_voxels, offset: self.pos as u64 });
        }
        Ok(())
    }

    /// MetaMap::readMeta (MetaMap.cc): u32 count, then per entry string
    /// name, string type name, u32 size and `size` bytes of value. Returns
    /// the grid class and whether `is_saved_as_half_float` is true.
    fn metadata(&mut self) -> Result<(Option<String>, bool)> {
        let count = self.u32("the metadata count")?;
        let (mut class, mut half) = (None, false);
        for _ in 0..count {
            let name = self.string("a metadata name")?;
            let ty = self.string("a metadata type name")?;
            let size = self.u32("a metadata size")?;
            let at = self.pos;
            let value = self.take(u64::from(size), "a metadata value")?;
            match name.as_str() {
                "class" if ty == "string" => class = Some(String::from_utf8_lossy(value).into_owned()),
                // Grid.cc GridBase::saveFloatAsHalf: the metadata's asBool
                // (TypedMetadata: the value is not zero).
                "is_saved_as_half_float" => {
                    half = match ty.as_str() {
                        "bool" if size == 1 => value[0] != 0,
                        "bool" => return Err(self.malformed(at, format!("the bool metadata is_saved_as_half_float holds {size} bytes, not 1"))),
                        _ => value.iter().any(|&b| b != 0),
                    }
                }
                _ => {}
            }
        }
        Ok((class, half))
    }

    /// Transform::read then the map's read (math/Maps.h): the map's type
    /// name, then its vectors. Scale maps store the scale followed by four
    /// vectors derived from it (voxel size, 1/scale, 1/scale², 1/(2·scale));
    /// translate maps put the translation first.
    fn transform(&mut self) -> Result<Transform> {
        let at = self.pos;
        let map = self.string("the transform's map type")?;
        let (translate, scale) = match map.as_str() {
            "TranslationMap" => (self.vec3d("a translation")?, [1.0; 3]),
            "ScaleMap" | "UniformScaleMap" => {
                let s = self.vec3d("a scale")?;
                self.take(4 * 24, "the scale map's derived vectors")?;
                ([0.0; 3], s)
            }
            "ScaleTranslateMap" | "UniformScaleTranslateMap" => {
                let t = self.vec3d("a translation")?;
                let s = self.vec3d("a scale")?;
                self.take(4 * 24, "the scale map's derived vectors")?;
                (t, s)
            }
            _ => {
                return Err(VdbReadError::UnsupportedTransform { grid: self.grid.clone().unwrap_or_default(), map, offset: at as u64 });
            }
        };
        if !scale.iter().chain(&translate).all(|v| v.is_finite()) || scale.contains(&0.0) {
            return Err(self.malformed(at, format!("the {map} has scale {scale:?} and translation {translate:?}")));
        }
        Ok(Transform { scale, translate })
    }

    /// io::readData (Compression.h) for `bytes` bytes: blosc or zip (i64
    /// n, then n compressed bytes; n <= 0 means -n raw bytes) or raw.
    fn data(&mut self, bytes: usize, compression: u32) -> Result<Vec<u8>> {
        if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
            return Ok(self.take(bytes as u64, "a value table")?.to_vec());
        }
        let at = self.pos;
        let n = self.i64("a compressed block's size")?;
        if n <= 0 {
            // Compression.cc unzipFromStream / bloscFromStream.
            if n.unsigned_abs() != bytes as u64 {
                return Err(self.malformed(at, format!("an uncompressed block of {} bytes where {bytes} were expected", n.unsigned_abs())));
            }
            return Ok(self.take(bytes as u64, "a value table")?.to_vec());
        }
        let body_at = self.pos;
        let body = self.take(n as u64, "a compressed value table")?;
        // Blosc first, as readData tests it first.
        let decoded = if compression & COMPRESS_BLOSC != 0 { blosc_decode(body, bytes) } else { zlib_decode(body, bytes) };
        decoded.map_err(|e| match e {
            CodecError::Unsupported(what) => self.unsupported(body_at, what),
            CodecError::Corrupt(what) => self.malformed(body_at, what),
        })
    }

    /// io::readCompressedValues (Compression.h) for a node of `count`
    /// values with value mask `mask`: the values at the mask's on bits, in
    /// bit order, flattened (`comps` f32 each).
    fn values(&mut self, st: Storage, count: usize, mask: &Mask) -> Result<Vec<f32>> {
        let ty = st.ty;
        let at = self.pos;
        let mode = self.u8("a value table's mode")?;
        if mode > NO_MASK_AND_ALL_VALS {
            return Err(self.malformed(at, format!("value table mode {mode} (0 to 6 exist)")));
        }
        // The header's inactive values are full precision even in half
        // files (writeCompressedValues writes sizeof(ValueT)); they are
        // inactive, so only skipped.
        let inactive = match mode {
            NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL => 1,
            MASK_AND_TWO_INACTIVE_VALS => 2,
            _ => 0,
        };
        self.take((inactive * ty.comps() * ty.width()) as u64, "a value table's inactive values")?;
        if matches!(mode, MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS) {
            // The selection mask between two inactive values.
            self.take((count / 8) as u64, "a value table's selection mask")?;
        }
        // With active-mask compression only the active values are saved,
        // unless the mode says all are.
        let active = mask.count() as usize;
        let stored = if st.compression & COMPRESS_ACTIVE_MASK != 0 && mode != NO_MASK_AND_ALL_VALS { active } else { count };
        // HalfReader: half storage for real types (Tree_half is half
        // already), and nothing at all, not even a size, for no values.
        let width = if st.half { 2 } else { ty.width() };
        if st.half && stored == 0 {
            return Ok(Vec::new());
        }
        let bytes = self.data(stored * ty.comps() * width, st.compression)?;
        let mut all = Vec::with_capacity(stored * ty.comps());
        decode_components(&bytes, width, &mut all);
        if stored == active && stored != count {
            return Ok(all);
        }
        let c = ty.comps();
        let mut out = Vec::with_capacity(active * c);
        for i in mask.iter_on() {
            out.extend_from_slice(&all[i * c..i * c + c]);
        }
        Ok(out)
    }

    /// InternalNode<_, 4>::readTopology (InternalNode.h): child mask, value
    /// mask, the value table (all 4096 slots), then the leaves' topology
    /// (LeafNode::readTopology: the value mask) in child-mask order.
    fn node4(&mut self, st: Storage, origin: [i32; 3], topo: &mut Topology) -> Result<()> {
        let child = self.mask(64, "a 16³ node's child mask")?;
        let value = self.mask(64, "a 16³ node's value mask")?;
        self.count_tiles(&child, &value, 3)?;
        let vals = self.values(st, 4096, &value)?;
        self.tiles(&child, &value, &vals, origin, 4, 3, st.ty.comps(), topo)?;
        for i in child.iter_on() {
            let o = local(origin, i, 4, 3);
            let mask = self.mask(8, "a leaf's value mask")?;
            self.count_voxels(mask.count())?;
            topo.leaves.push(Leaf { origin: o, mask });
        }
        Ok(())
    }

    /// InternalNode<_, 5>::readTopology, as [`Reader::node4`].
    fn node5(&mut self, st: Storage, origin: [i32; 3]) -> Result<Topology> {
        let mut topo = Topology::default();
        let child = self.mask(512, "a 32³ node's child mask")?;
        let value = self.mask(512, "a 32³ node's value mask")?;
        self.count_tiles(&child, &value, 7)?;
        let vals = self.values(st, 32768, &value)?;
        self.tiles(&child, &value, &vals, origin, 5, 7, st.ty.comps(), &mut topo)?;
        for i in child.iter_on() {
            self.node4(st, local(origin, i, 5, 7), &mut topo)?;
        }
        Ok(topo)
    }

    /// Count a node's active tiles (value bits on where the child bits are
    /// off), of edge `2^child_total`, before its table is read.
    fn count_tiles(&mut self, child: &Mask, value: &Mask, child_total: u32) -> Result<()> {
        let n: u64 = value.0.iter().zip(&child.0).map(|(v, c)| u64::from((v & !c).count_ones())).sum();
        self.count_voxels(if self.tile_cover { n << (3 * child_total) } else { n })
    }

    /// The active tiles of a node: value-mask bits on where the child mask
    /// is off. `vals` holds the values at the value mask's on bits.
    #[allow(clippy::too_many_arguments)]
    fn tiles(
        &mut self,
        child: &Mask,
        value: &Mask,
        vals: &[f32],
        origin: [i32; 3],
        log2: u32,
        child_total: u32,
        comps: usize,
        topo: &mut Topology,
    ) -> Result<()> {
        let edge = 1u32 << child_total;
        for (k, i) in value.iter_on().enumerate() {
            if child.on(i) {
                continue;
            }
            topo.tiles.push((local(origin, i, log2, child_total), edge));
            topo.tile_values.extend_from_slice(&vals[k * comps..k * comps + comps]);
        }
        Ok(())
    }

    /// Tree::readTopology and RootNode::readTopology (Tree.h, RootNode.h):
    /// i32 buffer count, background, u32 tile count, u32 child count, the
    /// tiles, then the children. The table is a std::map keyed by origin: a
    /// later entry at the same origin replaces an earlier one, and the
    /// buffers follow in key order (RootNode::readBuffers).
    fn topology(&mut self, st: Storage) -> Result<(Vec<f32>, Topology)> {
        self.i32("the tree's buffer count")?;
        let mut background = Vec::new();
        self.full_value(st.ty, &mut background, "the background value")?;
        let n_tiles = self.u32("the root's tile count")?;
        let n_children = self.u32("the root's child count")?;
        let mut table: BTreeMap<[i32; 3], RootEntry> = BTreeMap::new();
        let mut root_tiles: BTreeMap<[i32; 3], Vec<f32>> = BTreeMap::new();
        for _ in 0..n_tiles {
            let c = self.coord("a root tile's origin")?;
            let mut v = Vec::new();
            self.full_value(st.ty, &mut v, "a root tile's value")?;
            let active = self.u8("a root tile's active flag")? != 0;
            table.insert(c, RootEntry::Tile);
            root_tiles.remove(&c);
            if active {
                self.count_voxels(if self.tile_cover { 1 << 36 } else { 1 })?;
                root_tiles.insert(c, v);
            }
        }
        for _ in 0..n_children {
            let c = self.coord("a root child's origin")?;
            // InternalNode(PartialCreate, origin): the origin rounded down
            // to the node's 4096-voxel grid.
            let origin = c.map(|v| v & !4095);
            let child = self.node5(st, origin)?;
            table.insert(c, RootEntry::Child(child));
            root_tiles.remove(&c);
        }
        let mut topo = Topology::default();
        for (c, v) in root_tiles {
            topo.tiles.push((c, 4096));
            topo.tile_values.extend_from_slice(&v);
        }
        for entry in table.into_values() {
            if let RootEntry::Child(child) = entry {
                topo.leaves.extend(child.leaves);
                topo.tiles.extend(child.tiles);
                topo.tile_values.extend(child.tile_values);
            }
        }
        Ok((background, topo))
    }

    /// LeafNode::readBuffers (LeafNode.h) for every leaf in order: the
    /// value mask again (a seekable File skips it and keeps the
    /// topology's), then the value table.
    fn buffers(&mut self, st: Storage, topo: &Topology) -> Result<(Vec<[i32; 3]>, Vec<f32>)> {
        let (mut voxels, mut values) = (Vec::new(), Vec::new());
        for leaf in &topo.leaves {
            self.take(64, "a leaf's value mask")?;
            let vals = self.values(st, 512, &leaf.mask)?;
            values.extend_from_slice(&vals);
            for i in leaf.mask.iter_on() {
                voxels.push(local(leaf.origin, i, 3, 0));
            }
        }
        Ok((voxels, values))
    }
}

/// The global origin of slot `i` of a node of `2^log2` slots per axis at
/// `origin` whose children span `2^child_total` voxels
/// (InternalNode::offsetToLocalCoord: x major, z minor).
fn local(origin: [i32; 3], i: usize, log2: u32, child_total: u32) -> [i32; 3] {
    let i = i as i32;
    let m = (1 << log2) - 1;
    let l = [i >> (2 * log2), (i >> log2) & m, i & m];
    [0, 1, 2].map(|a| origin[a].wrapping_add(l[a] << child_total))
}

/// A grid descriptor (GridDescriptor::read).
struct Descriptor {
    unique_name: String,
    grid_type: String,
    parent: String,
}

/// Read every float and vec3 grid of an OpenVDB file held in memory; grids
/// of other types are listed in the second vector.
pub fn read_vdb(bytes: &[u8], limits: &ReadLimits) -> std::result::Result<(Vec<Grid>, Vec<Skipped>), VdbReadError> {
    let mut r = Reader { data: bytes, pos: 0, grid: None, voxels: 0, max_voxels: limits.max_voxels, tile_cover: limits.tile_cover };
    // Archive::readHeader (Archive.cc).
    if bytes.len() < 8 || r.i64("the magic number")? != MAGIC {
        return Err(VdbReadError::NotVdb);
    }
    let version = r.u32("the file format version")?;
    if !(VERSION_MIN..=VERSION_MAX).contains(&version) {
        return Err(VdbReadError::UnsupportedVersion { version });
    }
    r.u32("the library major version")?;
    r.u32("the library minor version")?;
    let has_offsets = r.u8("the grid-offsets flag")? != 0;
    // From version 222 on there is no file-wide compression byte here.
    r.take(36, "the file's UUID")?;
    r.metadata()?;
    let at = r.pos;
    let count = r.i32("the grid count")?;
    if count < 0 {
        return Err(r.malformed(at, format!("a grid count of {count}")));
    }

    let mut grids: Vec<Grid> = Vec::new();
    let mut skipped = Vec::new();
    // Unique name -> index in `grids`, or None for a skipped grid.
    let mut by_name: BTreeMap<String, Option<usize>> = BTreeMap::new();
    let mut instances: Vec<(Descriptor, Grid)> = Vec::new();
    for _ in 0..count {
        r.grid = None;
        let start = r.pos;
        let d = Descriptor { unique_name: r.string("a grid's name")?, grid_type: r.string("a grid's type")?, parent: r.string("a grid's instance parent")? };
        // GridDescriptor::stripSuffix: the name before "\x1e".
        let name = d.unique_name.split('\x1e').next().unwrap_or_default().to_string();
        r.grid = Some(name.clone());
        let pos_at = r.pos;
        let offsets = [r.i64("the grid's position")?, r.i64("the grid's block position")?, r.i64("the grid's end position")?];
        let after = r.pos;
        let end = if has_offsets {
            let [grid_pos, _, end_pos] = offsets;
            let inside = |p: i64| p >= 0 && (p as u64) <= bytes.len() as u64;
            // The grid follows its descriptor, and the next descriptor
            // follows the grid: both after this one, so reading moves on.
            if !inside(grid_pos) || !inside(end_pos) || (grid_pos as usize) < after || end_pos < grid_pos {
                return Err(r.malformed(pos_at, format!("grid offsets {offsets:?} outside bytes {after} to {}", bytes.len())));
            }
            r.pos = grid_pos as usize;
            Some(end_pos as usize)
        } else {
            None
        };
        let Some(ty) = ValueType::from_tree_type(&d.grid_type) else {
            let Some(end) = end else {
                return Err(r.malformed(start, format!("grid of type {} in a file without grid offsets: it cannot be skipped", d.grid_type)));
            };
            skipped.push(Skipped { name, grid_type: d.grid_type.clone() });
            by_name.insert(d.unique_name, None);
            r.pos = end;
            continue;
        };
        let grid = read_grid(&mut r, ty, name, &d)?;
        if let Some(end) = end {
            r.pos = end;
        }
        if d.parent.is_empty() {
            by_name.insert(d.unique_name.clone(), Some(grids.len()));
            grids.push(grid);
        } else {
            instances.push((d, grid));
        }
    }

    // Archive::connectInstance: an instance shares its parent's tree (its
    // own transform and metadata). Its values are copied here.
    for (d, mut g) in instances {
        match by_name.get(&d.parent) {
            Some(Some(p)) => {
                let p = &grids[*p];
                if ValueType::from_tree_type(&p.grid_type) != ValueType::from_tree_type(&g.grid_type) {
                    return Err(VdbReadError::Malformed {
                        grid: Some(g.name),
                        offset: 0,
                        what: format!("an instance of type {} of a grid of type {}", d.grid_type, p.grid_type),
                    });
                }
                r.grid = Some(g.name.clone());
                r.count_voxels(p.voxels.len() as u64)?;
                for (_, e) in &p.tiles {
                    r.count_voxels(if r.tile_cover { u64::from(*e).pow(3) } else { 1 })?;
                }
                g.background = p.background.clone();
                g.voxels = p.voxels.clone();
                g.voxel_values = p.voxel_values.clone();
                g.tiles = p.tiles.clone();
                g.tile_values = p.tile_values.clone();
                g.saved_as_half = p.saved_as_half;
                grids.push(g);
            }
            Some(None) => skipped.push(Skipped { name: g.name, grid_type: d.grid_type }),
            None => {
                let show = |s: &str| s.replacen('\x1e', "[", 1) + if s.contains('\x1e') { "]" } else { "" };
                return Err(VdbReadError::MissingInstanceParent { grid: show(&d.unique_name), parent: show(&d.parent) });
            }
        }
    }
    Ok((grids, skipped))
}

/// Archive.cc doReadGrid: compression flags, metadata, transform, and for a
/// grid that is not an instance its topology and buffers.
fn read_grid(r: &mut Reader, ty: ValueType, name: String, d: &Descriptor) -> Result<Grid> {
    // Archive::readGridCompression: per grid from version 222 on.
    // (Every version read is at least 222.)
    let compression = r.u32("the grid's compression flags")?;
    let (class, half) = r.metadata()?;
    let transform = r.transform()?;
    // Grid::readTopology and readBuffers take saveFloatAsHalf() after the
    // metadata replaced the grid's: the metadata decides, not the type
    // name's suffix (which OpenVDB writes alongside it).
    let st = Storage { ty, compression, half: half && ty != ValueType::Half };
    let comps = ty.comps();
    let empty = || Values::from_flat(comps, Vec::new());
    let mut g = Grid {
        name,
        grid_type: d.grid_type.clone(),
        class,
        saved_as_half: half,
        compression,
        transform,
        background: Values::from_flat(comps, vec![0.0; comps]),
        voxels: Vec::new(),
        voxel_values: empty(),
        tiles: Vec::new(),
        tile_values: empty(),
    };
    if !d.parent.is_empty() {
        return Ok(g);
    }
    let (background, topo) = r.topology(st)?;
    let (voxels, values) = r.buffers(st, &topo)?;
    g.background = Values::from_flat(comps, background);
    g.voxels = voxels;
    g.voxel_values = Values::from_flat(comps, values);
    g.tiles = topo.tiles;
    g.tile_values = Values::from_flat(comps, topo.tile_values);
    Ok(g)
}

// ---------------------------------------------------------------------------
// Codecs: zlib (flate2), and blosc 1 with its blosclz, LZ4 and zlib codecs.

enum CodecError {
    Unsupported(String),
    Corrupt(String),
}

/// zlib to exactly `expected` bytes, as Compression.cc unzipFromStream:
/// uncompress() into a buffer of that size, which must come out full.
fn zlib_decode(src: &[u8], expected: usize) -> std::result::Result<Vec<u8>, CodecError> {
    let mut out = vec![0u8; expected];
    let mut z = flate2::Decompress::new(true);
    loop {
        let (i, o) = (z.total_in() as usize, z.total_out() as usize);
        let status = z
            .decompress(&src[i.min(src.len())..], &mut out[o.min(expected)..], flate2::FlushDecompress::Finish)
            .map_err(|e| CodecError::Corrupt(format!("a zip block does not decompress: {e}")))?;
        let done = z.total_out() as usize >= expected || status == flate2::Status::StreamEnd;
        if done || (z.total_in() as usize == i && z.total_out() as usize == o) {
            break;
        }
    }
    if z.total_out() as usize != expected {
        return Err(CodecError::Corrupt(format!("a zip block decompresses to {} bytes where {expected} were expected", z.total_out())));
    }
    Ok(out)
}

/// Decompress one blosc 1 chunk (c-blosc `blosc_decompress`), which must
/// hold exactly `expected_len` bytes. Compressors: blosclz, LZ4 (and
/// LZ4HC, the same format), zlib; byte shuffle. Refused: snappy, zstd,
/// bit shuffle, and blosc 2's format. Public for the tests that compare it
/// with libblosc.
pub fn blosc_decompress(chunk: &[u8], expected_len: usize) -> std::result::Result<Vec<u8>, VdbReadError> {
    blosc_decode(chunk, expected_len).map_err(|e| match e {
        CodecError::Unsupported(what) => VdbReadError::UnsupportedCompression { grid: None, offset: 0, what },
        CodecError::Corrupt(what) => VdbReadError::Malformed { grid: None, offset: 0, what },
    })
}

// c-blosc blosc.h: header flags.
const BLOSC_DOSHUFFLE: u8 = 0x1;
const BLOSC_MEMCPYED: u8 = 0x2;
const BLOSC_DOBITSHUFFLE: u8 = 0x4;
const BLOSC_DONT_SPLIT: u8 = 0x10;
/// blosc.c: blocks split into one stream per byte of the type when the
/// type is at most this wide...
const MAX_SPLITS: usize = 16;
/// ...and the block holds at least this many values.
const MIN_BUFFERSIZE: usize = 128;

fn blosc_decode(src: &[u8], expected: usize) -> std::result::Result<Vec<u8>, CodecError> {
    let bad = |s: String| Err(CodecError::Corrupt(s));
    if src.len() < 16 {
        return bad(format!("a blosc block of {} bytes, shorter than its 16-byte header", src.len()));
    }
    let le = |at: usize| u32::from_le_bytes([src[at], src[at + 1], src[at + 2], src[at + 3]]) as usize;
    // blosc.c blosc_run_decompression_with_context: the 16-byte header.
    let (version, versionlz, flags, typesize) = (src[0], src[1], src[2], src[3] as usize);
    let (nbytes, blocksize, ctbytes) = (le(4), le(8), le(12));
    if nbytes != expected {
        return bad(format!("a blosc block holds {nbytes} bytes where {expected} were expected"));
    }
    if nbytes == 0 {
        return Ok(Vec::new());
    }
    if version != 2 {
        return Err(CodecError::Unsupported(format!("blosc format version {version} (only blosc 1's format 2 is read)")));
    }
    if flags & 0x08 != 0 {
        return Err(CodecError::Unsupported(format!("blosc header flags {flags:#x} (from a newer blosc)")));
    }
    if blocksize == 0 || blocksize > nbytes || typesize == 0 {
        return bad(format!("a blosc block of {nbytes} bytes in blocks of {blocksize}, type size {typesize}"));
    }
    if ctbytes > src.len() || ctbytes < 16 {
        return bad(format!("a blosc block of {ctbytes} bytes stored in {}", src.len()));
    }
    let src = &src[..ctbytes];
    if flags & BLOSC_MEMCPYED != 0 {
        if nbytes + 16 != ctbytes {
            return bad(format!("a copied blosc block of {nbytes} bytes in {ctbytes}"));
        }
        return Ok(src[16..].to_vec());
    }
    let codec = flags >> 5;
    let decode: fn(&[u8], &mut [u8]) -> Option<usize> = match codec {
        0 => blosclz_decode,
        1 => lz4_decode,
        3 => zlib_into,
        2 => return Err(CodecError::Unsupported("unsupported blosc compressor snappy".into())),
        4 => return Err(CodecError::Unsupported("unsupported blosc compressor zstd".into())),
        c => return Err(CodecError::Unsupported(format!("unsupported blosc compressor (code {c})"))),
    };
    // Each compressor's format version is 1 (blosc.h *_VERSION_FORMAT).
    if versionlz != 1 {
        return Err(CodecError::Unsupported(format!("blosc compressor format version {versionlz}")));
    }
    if flags & BLOSC_DOBITSHUFFLE != 0 && blocksize >= typesize {
        return Err(CodecError::Unsupported("blosc bit shuffle".into()));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    if 16 + 4 * nblocks > ctbytes {
        return bad(format!("a blosc block of {nblocks} blocks has no room for their starts"));
    }
    let mut out = vec![0u8; nbytes];
    let mut tmp = vec![0u8; blocksize];
    for j in 0..nblocks {
        // blosc.c blosc_d.
        let leftover = j == nblocks - 1 && nbytes % blocksize != 0;
        let bsize = if leftover { nbytes % blocksize } else { blocksize };
        let split = flags & BLOSC_DONT_SPLIT == 0 && typesize <= MAX_SPLITS && bsize / typesize >= MIN_BUFFERSIZE && !leftover;
        let nsplits = if split { typesize } else { 1 };
        let neblock = bsize / nsplits;
        let mut at = le(16 + 4 * j);
        let mut done = 0;
        for _ in 0..nsplits {
            if at + 4 > ctbytes {
                return bad(format!("blosc block {j} starts past the end"));
            }
            let cbytes = le(at);
            at += 4;
            if cbytes > ctbytes - at {
                return bad(format!("blosc block {j} runs past the end"));
            }
            let s = &src[at..at + cbytes];
            let dst = &mut tmp[done..done + neblock];
            if cbytes == neblock {
                dst.copy_from_slice(s);
            } else if decode(s, dst) != Some(neblock) {
                return bad(format!("blosc block {j} does not decompress to its {neblock} bytes"));
            }
            at += cbytes;
            done += neblock;
        }
        if done != bsize {
            return bad(format!("blosc block {j} holds {done} bytes, not {bsize}"));
        }
        let dest = &mut out[j * blocksize..j * blocksize + bsize];
        if flags & BLOSC_DOSHUFFLE != 0 && typesize > 1 {
            // shuffle.c unshuffle_generic: byte k of value i was at
            // k·(bsize / typesize) + i; the tail of bsize % typesize bytes
            // was copied as is.
            let n = bsize / typesize;
            for i in 0..n {
                for k in 0..typesize {
                    dest[i * typesize + k] = tmp[k * n + i];
                }
            }
            dest[n * typesize..].copy_from_slice(&tmp[n * typesize..bsize]);
        } else {
            dest.copy_from_slice(&tmp[..bsize]);
        }
    }
    Ok(out)
}

/// zlib into `dst` (blosc.c zlib_wrap_decompress: uncompress()).
fn zlib_into(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    zlib_decode(src, dst.len()).ok().map(|v| {
        dst.copy_from_slice(&v);
        v.len()
    })
}

/// An LZ4 block (LZ4_decompress_safe): sequences of a token (literal length
/// in the high nibble, match length − 4 in the low; 15 continues in bytes
/// that add up while they are 255), the literals, a u16 offset back; the
/// last sequence is literals alone. Returns the bytes written, or None.
fn lz4_decode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let (mut ip, mut op) = (0usize, 0usize);
    let length = |ip: &mut usize, mut n: usize| -> Option<usize> {
        if n == 15 {
            loop {
                let b = *src.get(*ip)?;
                *ip += 1;
                n = n.checked_add(usize::from(b))?;
                if b != 255 {
                    break;
                }
            }
        }
        Some(n)
    };
    loop {
        let token = *src.get(ip)?;
        ip += 1;
        let lit = length(&mut ip, usize::from(token >> 4))?;
        if lit > src.len() - ip || lit > dst.len() - op {
            return None;
        }
        dst[op..op + lit].copy_from_slice(&src[ip..ip + lit]);
        ip += lit;
        op += lit;
        if ip == src.len() {
            return Some(op);
        }
        if ip + 2 > src.len() {
            return None;
        }
        let offset = usize::from(u16::from_le_bytes([src[ip], src[ip + 1]]));
        ip += 2;
        if offset == 0 || offset > op {
            return None;
        }
        let len = length(&mut ip, usize::from(token & 15))?.checked_add(4)?;
        if len > dst.len() - op {
            return None;
        }
        // Byte by byte: the match may overlap what it writes.
        for k in 0..len {
            dst[op + k] = dst[op + k - offset];
        }
        op += len;
    }
}

/// blosclz.c blosclz_decompress: the first byte's low 5 bits are a literal
/// run; then a control byte below 32 is a literal run of ctrl + 1 bytes,
/// and above is a match of length (ctrl >> 5) + 2 (7 continues in bytes
/// while 255) at distance ((ctrl & 31) << 8) + next byte + 1, where 31 and
/// 255 mean a 16-bit distance follows (plus 8191).
fn blosclz_decode(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    const MAX_DISTANCE: usize = 8191;
    if src.is_empty() {
        return Some(0);
    }
    let (mut ip, mut op) = (1usize, 0usize);
    let mut ctrl = usize::from(src[0] & 31);
    loop {
        if ctrl >= 32 {
            let mut len = (ctrl >> 5) - 1;
            let mut ofs = (ctrl & 31) << 8;
            if len == 6 {
                loop {
                    if ip + 1 >= src.len() {
                        return None;
                    }
                    let code = src[ip];
                    ip += 1;
                    len += usize::from(code);
                    if code != 255 {
                        break;
                    }
                }
            } else if ip + 1 >= src.len() {
                return None;
            }
            let code = usize::from(src[ip]);
            ip += 1;
            len += 3;
            // The distance back from op to the match's first byte.
            let mut dist = ofs + code + 1;
            if code == 255 && ofs == 31 << 8 {
                if ip + 1 >= src.len() {
                    return None;
                }
                ofs = (usize::from(src[ip]) << 8) + usize::from(src[ip + 1]);
                ip += 2;
                dist = ofs + MAX_DISTANCE + 1;
            }
            if len > dst.len() - op || dist > op {
                return None;
            }
            // As blosclz: a stream that ends after a match's header ends
            // there, without the match.
            if ip >= src.len() {
                break;
            }
            ctrl = usize::from(src[ip]);
            ip += 1;
            for k in 0..len {
                dst[op + k] = dst[op + k - dist];
            }
            op += len;
        } else {
            let run = ctrl + 1;
            if run > dst.len() - op || run > src.len() - ip {
                return None;
            }
            dst[op..op + run].copy_from_slice(&src[ip..ip + run]);
            op += run;
            ip += run;
            if ip >= src.len() {
                break;
            }
            ctrl = usize::from(src[ip]);
            ip += 1;
        }
    }
    Some(op)
}
