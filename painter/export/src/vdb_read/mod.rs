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

mod codecs;
mod reader;

pub use codecs::blosc_decompress;

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
