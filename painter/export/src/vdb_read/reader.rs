//! Reading the file's parts: a cursor over the bytes with every length and
//! count checked before use, and the node readers of OpenVDB's 5-4-3 tree
//! (RootNode, InternalNode, LeafNode and their value tables).

use super::codecs::{CodecError, blosc_decode, zlib_decode};
use super::*;

impl<'a> Reader<'a> {
    pub(super) fn left(&self) -> usize {
        self.data.len() - self.pos
    }

    pub(super) fn malformed(&self, at: usize, what: impl Into<String>) -> VdbReadError {
        VdbReadError::Malformed { grid: self.grid.clone(), offset: at as u64, what: what.into() }
    }

    pub(super) fn unsupported(&self, at: usize, what: impl Into<String>) -> VdbReadError {
        VdbReadError::UnsupportedCompression { grid: self.grid.clone(), offset: at as u64, what: what.into() }
    }

    /// The next `n` bytes, checked against what is left before anything
    /// else happens with `n`.
    pub(super) fn take(&mut self, n: u64, what: &str) -> Result<&'a [u8]> {
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

    pub(super) fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N as u64, what)?);
        Ok(a)
    }

    pub(super) fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }
    pub(super) fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    pub(super) fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    pub(super) fn i64(&mut self, what: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }
    pub(super) fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
    pub(super) fn coord(&mut self, what: &str) -> Result<[i32; 3]> {
        Ok([self.i32(what)?, self.i32(what)?, self.i32(what)?])
    }
    pub(super) fn vec3d(&mut self, what: &str) -> Result<[f64; 3]> {
        Ok([self.f64(what)?, self.f64(what)?, self.f64(what)?])
    }

    /// util/Name.h readString: u32 length, then the bytes.
    pub(super) fn string(&mut self, what: &str) -> Result<String> {
        let n = self.u32(what)?;
        Ok(String::from_utf8_lossy(self.take(u64::from(n), what)?).into_owned())
    }

    pub(super) fn mask(&mut self, words: usize, what: &str) -> Result<Mask> {
        let bytes = self.take(8 * words as u64, what)?;
        Ok(Mask(bytes.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect()))
    }

    /// One value at full precision (root background and tiles, inactive
    /// values of a table header).
    pub(super) fn full_value(&mut self, ty: ValueType, out: &mut Vec<f32>, what: &str) -> Result<()> {
        let bytes = self.take((ty.comps() * ty.width()) as u64, what)?;
        decode_components(bytes, ty.width(), out);
        Ok(())
    }

    /// Count `n` more active voxels against the limit.
    pub(super) fn count_voxels(&mut self, n: u64) -> Result<()> {
        self.voxels = self.voxels.saturating_add(n);
        if self.voxels > self.max_voxels {
            return Err(VdbReadError::TooManyVoxels { grid: self.grid.clone().unwrap_or_default(), max: self.max_voxels, offset: self.pos as u64 });
        }
        Ok(())
    }

    /// MetaMap::readMeta (MetaMap.cc): u32 count, then per entry string
    /// name, string type name, u32 size and `size` bytes of value. Returns
    /// the grid class and whether `is_saved_as_half_float` is true.
    pub(super) fn metadata(&mut self) -> Result<(Option<String>, bool)> {
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
    pub(super) fn transform(&mut self) -> Result<Transform> {
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
    pub(super) fn data(&mut self, bytes: usize, compression: u32) -> Result<Vec<u8>> {
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
    pub(super) fn values(&mut self, st: Storage, count: usize, mask: &Mask) -> Result<Vec<f32>> {
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
    pub(super) fn node4(&mut self, st: Storage, origin: [i32; 3], topo: &mut Topology) -> Result<()> {
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
    pub(super) fn node5(&mut self, st: Storage, origin: [i32; 3]) -> Result<Topology> {
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
    pub(super) fn count_tiles(&mut self, child: &Mask, value: &Mask, child_total: u32) -> Result<()> {
        let n: u64 = value.0.iter().zip(&child.0).map(|(v, c)| u64::from((v & !c).count_ones())).sum();
        self.count_voxels(if self.tile_cover { n << (3 * child_total) } else { n })
    }

    /// The active tiles of a node: value-mask bits on where the child mask
    /// is off. `vals` holds the values at the value mask's on bits.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tiles(
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
    pub(super) fn topology(&mut self, st: Storage) -> Result<(Vec<f32>, Topology)> {
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
    pub(super) fn buffers(&mut self, st: Storage, topo: &Topology) -> Result<(Vec<[i32; 3]>, Vec<f32>)> {
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
