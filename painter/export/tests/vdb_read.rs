//! The OpenVDB reader against the crate's own writer, against files that
//! OpenVDB 10 itself writes (Debian's python3-openvdb under
//! /usr/bin/python3, run by tests/vdb_read_openvdb.py, which also reports
//! what OpenVDB reads back from each file), against libblosc's chunks, and
//! against truncated, corrupted and hostile files.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use octopaint_export::Placement;
use octopaint_export::values::ColourSpace;
use octopaint_export::vdb::{write_vdb, write_vdb_named};
use octopaint_export::vdb_read::{Grid, ReadLimits, Values, VdbReadError, blosc_decompress, read_vdb};
use octopaint_export::voxels::{self, Leaf, Node4, Node5, Voxel, VoxelGrid};
use octopaint_tree::replay::{ReplayObserver, replay};
use serde_json::Value;

const SYSTEM_PYTHON: &str = "/usr/bin/python3";
const ALL: ReadLimits = ReadLimits { max_voxels: u64::MAX, tile_cover: true };

// ---------------------------------------------------------------------------
// Helpers

/// Every active item of a grid: (origin, edge) -> value components.
fn items(g: &Grid) -> HashMap<([i32; 3], u32), Vec<f32>> {
    fn comps(v: &Values, i: usize) -> Vec<f32> {
        match v {
            Values::Float(v) => vec![v[i]],
            Values::Vec3(v) => v[i].to_vec(),
        }
    }
    assert_eq!(g.voxels.len(), g.voxel_values.len(), "{}: one value per voxel", g.name);
    assert_eq!(g.tiles.len(), g.tile_values.len(), "{}: one value per tile", g.name);
    let mut out = HashMap::new();
    for (i, &p) in g.voxels.iter().enumerate() {
        assert!(out.insert((p, 1), comps(&g.voxel_values, i)).is_none(), "{}: voxel {p:?} twice", g.name);
    }
    for (i, &(p, e)) in g.tiles.iter().enumerate() {
        assert!(out.insert((p, e), comps(&g.tile_values, i)).is_none(), "{}: tile {p:?} twice", g.name);
    }
    out
}

fn grid<'a>(grids: &'a [Grid], name: &str) -> &'a Grid {
    grids.iter().find(|g| g.name == name).unwrap_or_else(|| panic!("no grid {name} in {:?}", grids.iter().map(|g| &g.name).collect::<Vec<_>>()))
}

fn read(bytes: &[u8]) -> Vec<Grid> {
    let (grids, skipped) = read_vdb(bytes, &ALL).expect("reads");
    assert!(skipped.is_empty(), "{skipped:?}");
    grids
}

// ---------------------------------------------------------------------------
// The crate's own writer

fn put(g: &mut VoxelGrid, p: [i32; 3], v: Voxel) {
    let n5 = g.nodes.entry(p.map(|a| a & !4095)).or_default();
    let n4: &mut Node4 = n5.children.entry(off(p, 7, 5)).or_default();
    let leaf = n4.leaves.entry(off(p, 3, 4)).or_insert_with(|| Leaf { mask: [0; 8], values: Box::new([Voxel { density: 0.0, colour: [0.0; 3] }; 512]) });
    let i = off(p, 0, 3) as usize;
    leaf.mask[i / 64] |= 1 << (i % 64);
    leaf.values[i] = v;
}

/// The slot of `p` in a node of `2^log2` children of `2^shift` voxels.
fn off(p: [i32; 3], shift: u32, log2: u32) -> u32 {
    let m = (1 << log2) - 1;
    let l = p.map(|a| ((a >> shift) & m) as u32);
    (l[0] << (2 * log2)) | (l[1] << log2) | l[2]
}

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn range(&mut self, lo: i32, hi: i32) -> i32 {
        lo + (self.next() % (hi - lo) as u64) as i32
    }
    fn unit(&mut self) -> f32 {
        (self.next() % 1_000_000) as f32 / 1_000_000.0
    }
}

/// A grid with voxels scattered over negative and positive indices and
/// tiles at every level: 8³, 128³ and a root tile.
fn synthetic() -> (VoxelGrid, HashMap<([i32; 3], u32), Voxel>) {
    let mut g = VoxelGrid {
        depth: 5,
        voxel_size: 0.125,
        root_tiles: BTreeMap::new(),
        nodes: BTreeMap::new(),
        translation: [1.0, -2.0, 0.5],
        active_voxels: 0,
        bbox: Some(([-9000, -300, -300], [9000, 300, 300])),
    };
    let mut want = HashMap::new();
    let mut rng = Lcg(42);
    let voxel = |rng: &mut Lcg| Voxel { density: rng.unit() * 10.0 + 1e-3, colour: [rng.unit(), rng.unit(), rng.unit()] };
    for _ in 0..5000 {
        let p = [rng.range(-5000, 5000), rng.range(-300, 300), rng.range(-300, 300)];
        let v = voxel(&mut rng);
        put(&mut g, p, v);
        want.insert((p, 1), v);
    }
    // Tiles in nodes the voxels did not touch (the writer keeps tiles and
    // children apart).
    let v = voxel(&mut rng);
    let n5: &mut Node5 = g.nodes.entry([0, 4096, 0]).or_default();
    n5.tiles.insert(off([128, 4096 + 256, 384], 7, 5), v);
    want.insert(([128, 4096 + 256, 384], 128), v);
    let n4 = n5.children.entry(off([0, 4096, 0], 7, 5)).or_default();
    for (k, p) in [[8, 4096, 16], [120, 4096 + 8, 0]].into_iter().enumerate() {
        let v = Voxel { density: 0.5 + k as f32, colour: [0.25; 3] };
        n4.tiles.insert(off(p, 3, 4), v);
        want.insert((p, 8), v);
    }
    let v = voxel(&mut rng);
    g.root_tiles.insert([-8192, 8192, 0], v);
    want.insert(([-8192, 8192, 0], 4096), v);
    (g, want)
}

fn write(grids: &[(&str, &VoxelGrid)]) -> Vec<u8> {
    let mut c = std::io::Cursor::new(Vec::new());
    write_vdb_named(&mut c, grids, "vdb_read test").expect("writes");
    c.into_inner()
}

#[test]
fn the_crates_writer_round_trips_every_voxel_and_tile() {
    let (g, want) = synthetic();
    let bytes = write(&[("a_", &g), ("b_", &g)]);
    let grids = read(&bytes);
    assert_eq!(grids.iter().map(|g| g.name.as_str()).collect::<Vec<_>>(), ["a_density", "a_color", "b_density", "b_color"]);
    for g_read in &grids {
        let colour = g_read.name.ends_with("color");
        let got = items(g_read);
        assert_eq!(got.len(), want.len(), "{}", g_read.name);
        for (k, v) in &want {
            let expect = if colour { v.colour.to_vec() } else { vec![v.density] };
            assert_eq!(got.get(k), Some(&expect), "{} item {k:?}", g_read.name);
        }
        assert_eq!(g_read.class.as_deref(), Some(if colour { "unknown" } else { "fog volume" }));
        assert!(!g_read.saved_as_half);
        assert_eq!(g_read.compression, 0x1, "the writer zips without active-mask compression");
        // Voxel i covers [i, i+1)·h + translation; index i is its centre.
        assert_eq!(g_read.transform.scale, [0.125; 3]);
        assert_eq!(g_read.transform.translate, [1.0 + 0.0625, -2.0 + 0.0625, 0.5 + 0.0625]);
        let bg = if colour { Values::Vec3(vec![[0.0; 3]]) } else { Values::Float(vec![0.0]) };
        assert_eq!(g_read.background, bg);
    }
}

struct Silent;
impl ReplayObserver for Silent {}

#[test]
fn a_painted_export_reads_back_as_the_grid_it_was_written_from() {
    for name in ["shapes_modes", "edges"] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"));
        let trace = octopaint_tree::read_trace(&path).expect("a checked-in trace");
        let tree = replay(&trace, None, &mut Silent).expect("replays").1.tree;
        let e = tree.lat.max_depth - 1;
        let g = VoxelGrid::build(&tree, &voxels::plan(&tree, Some(e), None, 1 << 40).expect("plans"), ColourSpace::Linear, Placement::default(), &mut |_| {});
        let mut c = std::io::Cursor::new(Vec::new());
        write_vdb(&mut c, &g, "test").expect("writes");
        let grids = read(c.get_ref());
        let (density, colour) = (grid(&grids, "density"), grid(&grids, "color"));
        let (d, c) = (items(density), items(colour));
        let mut voxels = 0u128;
        for ((p, e), v) in &d {
            voxels += u128::from(*e).pow(3);
            let want = g.get(*p).unwrap_or_else(|| panic!("{name}: {p:?} is not active in the grid"));
            assert_eq!(v, &vec![want.density], "{name} {p:?}");
            assert_eq!(c.get(&(*p, *e)), Some(&want.colour.to_vec()), "{name} {p:?}");
        }
        assert_eq!(voxels, g.active_voxels, "{name}: every active voxel read back");
        assert_eq!(c.len(), d.len());
    }
}

// ---------------------------------------------------------------------------
// Files written by OpenVDB

struct OpenVdb {
    dir: PathBuf,
    report: Value,
}

/// Runs the python script once for all tests.
fn openvdb() -> &'static OpenVdb {
    static ONCE: OnceLock<OpenVdb> = OnceLock::new();
    ONCE.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("vdb_read_openvdb");
        std::fs::create_dir_all(&dir).expect("a scratch directory");
        let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/vdb_read_openvdb.py");
        let out = std::process::Command::new(SYSTEM_PYTHON).arg(&script).arg(&dir).output().expect("runs /usr/bin/python3");
        assert!(
            out.status.success(),
            "{} failed (python3-openvdb is missing? `make system` installs it): {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        let report = serde_json::from_slice(&out.stdout).expect("the script prints JSON");
        OpenVdb { dir, report }
    })
}

fn openvdb_file(name: &str) -> Vec<u8> {
    std::fs::read(openvdb().dir.join(name)).expect("the script wrote it")
}

/// Compare what we read from `file` with what OpenVDB reads back from it.
fn compare_with_openvdb(file: &str) -> Vec<Grid> {
    let (grids, skipped) = read_vdb(&openvdb_file(file), &ALL).unwrap_or_else(|e| panic!("{file}: {e}"));
    let report = &openvdb().report["files"][file];
    let reported = report.as_object().expect("grids by name");
    for (name, r) in reported {
        let ty = r["value_type"].as_str().unwrap_or_default();
        if !matches!(ty, "float" | "vec3s") {
            assert!(skipped.iter().any(|s| &s.name == name), "{file}: {name} ({ty}) skipped: {skipped:?}");
            continue;
        }
        let g = grid(&grids, name);
        // OpenVDB reports a grid without class metadata as "unknown".
        assert_eq!(Some(g.class.as_deref().unwrap_or("unknown")), r["class"].as_str(), "{file} {name}");
        assert_eq!(g.saved_as_half, r["half"].as_bool().unwrap_or_default(), "{file} {name}");
        let want: HashMap<([i32; 3], u32), Vec<f32>> = r["items"]
            .as_array()
            .expect("items")
            .iter()
            .map(|it| {
                let a = it.as_array().expect("an item");
                let n = |i: usize| a[i].as_f64().expect("a number");
                (([n(0) as i32, n(1) as i32, n(2) as i32], n(3) as u32), a[4..].iter().map(|v| v.as_f64().expect("a value") as f32).collect())
            })
            .collect();
        let got = items(g);
        assert_eq!(got.len(), want.len(), "{file} {name}: active items");
        for (k, v) in &want {
            assert_eq!(got.get(k), Some(v), "{file} {name}: item {k:?}");
        }
        let bg: Vec<f32> = r["background"].as_array().expect("bg").iter().map(|v| v.as_f64().expect("f") as f32).collect();
        let bg_read = match &g.background {
            Values::Float(v) => v.clone(),
            Values::Vec3(v) => v[0].to_vec(),
        };
        assert_eq!(bg_read, bg, "{file} {name}: background");
        for pw in r["index_to_world"].as_array().expect("points") {
            let (p, w) = (&pw[0], &pw[1]);
            for a in 0..3 {
                let mine = p[a].as_f64().expect("i") * g.transform.scale[a] + g.transform.translate[a];
                let theirs = w[a].as_f64().expect("w");
                assert!((mine - theirs).abs() <= 1e-12 * theirs.abs().max(1.0), "{file} {name}: index {p} -> {mine} != {theirs}");
            }
        }
    }
    assert_eq!(grids.len() + skipped.len(), reported.len(), "{file}: every grid read or skipped");
    grids
}

#[test]
fn openvdb_float_grid_with_its_default_compression() {
    let grids = compare_with_openvdb("float.vdb");
    let g = grid(&grids, "density");
    // What OpenVDB 10's python `write` uses: blosc (LZ4) with active-mask
    // compression (io::DEFAULT_COMPRESSION_FLAGS when built with blosc).
    assert_eq!(g.compression, 0x4 | 0x2);
    assert!(g.voxels.len() > 30000, "{}", g.voxels.len());
    assert!(g.tiles.iter().any(|t| t.1 == 128) && g.tiles.iter().any(|t| t.1 == 8), "{:?}", g.tiles.len());
    assert_eq!(openvdb().report["library"][0], 10);
}

#[test]
fn openvdb_value_tables_in_every_mode() {
    let grids = compare_with_openvdb("modes.vdb");
    let g = grid(&grids, "modes");
    assert_eq!(g.background, Values::Float(vec![2.0]));
    assert_eq!(g.transform.translate, [1.0, -2.0, 3.5]);
    assert_eq!(g.transform.scale, [0.5; 3]);
}

#[test]
fn openvdb_half_float_storage() {
    let grids = compare_with_openvdb("half.vdb");
    for name in ["density", "color", "modes_half"] {
        assert!(grid(&grids, name).saved_as_half, "{name}");
        assert!(grid(&grids, name).grid_type.ends_with("_HalfFloat"), "{name}");
    }
    // The same grid saved at full precision differs: the halves were read
    // as halves, not as floats that happen to agree.
    let full = read_vdb(&openvdb_file("float.vdb"), &ALL).expect("reads").0;
    let (h, f) = (items(grid(&grids, "density")), items(grid(&full, "density")));
    assert_eq!(h.len(), f.len());
    // The scattered values (not the fill's 0.75, exact in half) differ.
    let differ = f.iter().filter(|(k, v)| h[*k] != **v).count();
    assert!(differ > 2500, "{differ} of {} differ", f.len());
    for (k, v) in &f {
        assert!((h[k][0] - v[0]).abs() <= v[0].abs() / 1024.0, "{k:?}: {} is not {} in half", h[k][0], v[0]);
    }
}

#[test]
fn openvdb_vec3_grid_bool_grid_skipped_and_an_instance() {
    let bytes = openvdb_file("vec3.vdb");
    let grids = compare_with_openvdb("vec3.vdb");
    let (_, skipped) = read_vdb(&bytes, &ALL).expect("reads");
    assert_eq!(skipped.len(), 1);
    assert_eq!((skipped[0].name.as_str(), skipped[0].grid_type.as_str()), ("mask", "Tree_bool_5_4_3"));
    let (c, i) = (grid(&grids, "color"), grid(&grids, "color_instance"));
    assert!(matches!(c.voxel_values, Values::Vec3(_)));
    assert_eq!(items(c), items(i), "an instance shares its parent's tree");
    assert_eq!(i.transform.scale, [2.0; 3], "with its own transform");
    assert!((c.transform.scale[0] - 0.1).abs() < 1e-15);
    // The file holds the instance without a tree: it must be an instance
    // for the comparison above to mean anything.
    let tag = b"color_instance";
    let at = bytes.windows(tag.len()).position(|w| w == tag).expect("its descriptor");
    let parent_at = at + tag.len() + 4 + b"Tree_vec3s_5_4_3".len();
    assert_eq!(&bytes[parent_at..parent_at + 4], &5u32.to_le_bytes(), "parent name \"color\"");
}

#[test]
fn a_root_tile_counts_as_the_voxels_it_covers() {
    let bytes = openvdb_file("root_tile.vdb");
    let grids = compare_with_openvdb("root_tile.vdb");
    assert_eq!(grid(&grids, "big").tiles, vec![([-4096, 0, 0], 4096)]);
    assert!(read_vdb(&bytes, &ReadLimits { max_voxels: 1 << 36, tile_cover: true }).is_ok());
    match read_vdb(&bytes, &ReadLimits { max_voxels: (1 << 36) - 1, tile_cover: true }) {
        Err(e @ VdbReadError::TooManyVoxels { .. }) => assert!(e.to_string().contains("\"big\""), "{e}"),
        other => panic!("{:?}", other.map(|_| ())),
    }
    // Counted as one entry (a caller that resamples tiles itself): what the
    // reader holds, leaf voxels plus tiles.
    let held = read_vdb(&bytes, &ALL).unwrap().0.iter().map(|g| (g.voxels.len() + g.tiles.len()) as u64).sum::<u64>();
    assert!(read_vdb(&bytes, &ReadLimits { max_voxels: held, tile_cover: false }).is_ok());
    assert!(matches!(read_vdb(&bytes, &ReadLimits { max_voxels: held - 1, tile_cover: false }), Err(VdbReadError::TooManyVoxels { .. })));
}

#[test]
fn the_voxel_limit_counts_leaf_voxels() {
    let bytes = openvdb_file("float.vdb");
    let n = read_vdb(&bytes, &ALL)
        .expect("reads")
        .0
        .iter()
        .map(|g| g.voxels.len() as u64 + g.tiles.iter().map(|t| u64::from(t.1).pow(3)).sum::<u64>())
        .sum::<u64>();
    assert!(read_vdb(&bytes, &ReadLimits { max_voxels: n, tile_cover: true }).is_ok());
    assert!(matches!(read_vdb(&bytes, &ReadLimits { max_voxels: n - 1, tile_cover: true }), Err(VdbReadError::TooManyVoxels { .. })));
}

#[test]
fn a_rotated_transform_is_refused_by_name() {
    let e = read_vdb(&openvdb_file("affine.vdb"), &ALL).expect_err("an AffineMap");
    assert!(matches!(e, VdbReadError::UnsupportedTransform { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(msg.contains("AffineMap") && msg.contains("\"turned\""), "{msg}");
}

#[test]
fn blosc_chunks_from_libblosc() {
    let b = &openvdb().report["blosc"];
    let hex = |s: &str| (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex")).collect::<Vec<u8>>();
    let data: HashMap<String, Vec<u8>> = b["data"].as_object().expect("data").iter().map(|(k, v)| (k.clone(), hex(v.as_str().expect("hex")))).collect();
    let mut decoded: HashMap<String, usize> = HashMap::new();
    for c in b["chunks"].as_array().expect("chunks") {
        let chunk = hex(c["chunk"].as_str().expect("hex"));
        let raw = &data[c["data"].as_str().expect("name")];
        let comp = c["compressor"].as_str().expect("name").to_string();
        let bitshuffle = chunk.len() >= 16 && chunk[2] & 0x4 != 0 && chunk[2] & 0x2 == 0 && !raw.is_empty();
        let compressed = chunk.len() >= 16 && chunk[2] & 0x2 == 0 && !raw.is_empty();
        match blosc_decompress(&chunk, raw.len()) {
            Ok(out) => {
                assert_eq!(&out, raw, "{c}");
                assert!(!(compressed && (comp == "zstd" || bitshuffle)), "{comp} decoded: {c}");
                if compressed {
                    *decoded.entry(comp).or_default() += 1;
                }
            }
            Err(e) => {
                assert!(matches!(e, VdbReadError::UnsupportedCompression { .. }), "{e}: {c}");
                let msg = e.to_string();
                if comp == "zstd" {
                    assert!(msg.contains("unsupported blosc compressor zstd"), "{msg}");
                } else {
                    assert!(bitshuffle && msg.contains("bit shuffle"), "{msg}: {c}");
                }
            }
        }
        // The wrong expected length is an error, never a panic.
        assert!(blosc_decompress(&chunk, raw.len() + 1).is_err());
        for cut in [0, 1, 15, 16, chunk.len() / 2, chunk.len().saturating_sub(1)] {
            if cut < chunk.len() {
                let _ = blosc_decompress(&chunk[..cut], raw.len());
            }
        }
    }
    for comp in ["blosclz", "lz4", "lz4hc", "zlib"] {
        assert!(decoded.get(comp).copied().unwrap_or(0) > 50, "{comp}: {decoded:?}");
    }
}

// ---------------------------------------------------------------------------
// Malformed and hostile files

fn small_files() -> Vec<(&'static str, Vec<u8>)> {
    let mut g =
        VoxelGrid { depth: 3, voxel_size: 1.0, root_tiles: BTreeMap::new(), nodes: BTreeMap::new(), translation: [0.0; 3], active_voxels: 0, bbox: None };
    for k in 0..20 {
        put(&mut g, [k * 5, k % 3, k], Voxel { density: k as f32, colour: [0.5; 3] });
    }
    vec![("openvdb small.vdb", openvdb_file("small.vdb")), ("writer", write(&[("", &g)]))]
}

#[test]
fn every_truncation_is_an_error() {
    for (what, bytes) in small_files() {
        assert!(read_vdb(&bytes, &ALL).is_ok(), "{what}");
        for n in 0..bytes.len() {
            assert!(read_vdb(&bytes[..n], &ALL).is_err(), "{what}: the first {n} of {} bytes read as a whole file", bytes.len());
        }
    }
}

#[test]
fn flipping_any_byte_never_panics() {
    // The writer's tables are whole (32768 values zipped for the 32³
    // node): one flip per byte there, three on OpenVDB's mask-compressed
    // file.
    for ((what, bytes), flips) in small_files().into_iter().zip([&[0xFF, 0x01, 0x80][..], &[0xFF]]) {
        let t = Instant::now();
        let mut b = bytes.clone();
        let (mut ok, mut err) = (0, 0);
        for i in 0..b.len() {
            for &x in flips {
                b[i] ^= x;
                match read_vdb(&b, &ReadLimits { max_voxels: 1 << 40, tile_cover: true }) {
                    Ok(_) => ok += 1,
                    Err(_) => err += 1,
                }
                b[i] ^= x;
            }
        }
        assert!(err > 0 && ok > 0, "{what}: {ok} read, {err} refused");
        eprintln!("{what}: {} bytes, {ok} read, {err} refused, {:?}", bytes.len(), t.elapsed());
    }
}

/// A file by hand: the header, one float grid "g" and its topology start;
/// the positions of the grids' end offsets, patched by [`Hand::done`].
struct Hand(Vec<u8>, Vec<usize>);

impl Hand {
    fn new(grid_count: i32) -> Hand {
        let mut b = Vec::new();
        b.extend_from_slice(&0x5644_4220i64.to_le_bytes());
        for v in [224u32, 10, 0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.push(1);
        b.extend_from_slice(&[b'0'; 36]);
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&grid_count.to_le_bytes());
        Hand(b, Vec::new())
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn i64(&mut self, v: i64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.0.extend_from_slice(v);
        self
    }
    fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32).bytes(s.as_bytes())
    }
    /// A descriptor, whose end is patched by [`Hand::done`], then the
    /// grid's compression, no metadata, a unit transform, and the tree's
    /// buffer count and background.
    fn grid(&mut self, compression: u32) -> &mut Self {
        self.string("g").string("Tree_float_5_4_3").string("");
        let pos = self.0.len() as i64 + 24;
        self.1.push(self.0.len() + 16);
        self.i64(pos).i64(0).i64(0).u32(compression).u32(0).string("UniformScaleMap");
        for _ in 0..5 {
            for _ in 0..3 {
                self.0.extend_from_slice(&1f64.to_le_bytes());
            }
        }
        self.u32(1).f32(0.0)
    }
    /// The file, each grid's end offset set to the file's length.
    fn done(&mut self) -> Vec<u8> {
        let len = self.0.len() as i64;
        let mut b = self.0.clone();
        for &at in &self.1 {
            b[at..at + 8].copy_from_slice(&len.to_le_bytes());
        }
        b
    }
}

fn mask_words(words: usize, on: &[usize]) -> Vec<u8> {
    let mut m = vec![0u64; words];
    for &i in on {
        m[i / 64] |= 1 << (i % 64);
    }
    m.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// A tree with one root child at the origin, one 16³ node at its slot 0
/// and one leaf at that node's slot 0, whose buffers `leaf_table` writes.
fn one_leaf(h: &mut Hand, leaf_mask: &[usize], leaf_table: impl Fn(&mut Hand)) -> Vec<u8> {
    h.u32(0).u32(1).bytes(&[0; 12]);
    // 32³ node: child 0, no tiles, table mode 6 of zeros, raw or zipped
    // per the grid's flags: tests below only use raw here.
    h.bytes(&mask_words(512, &[0])).bytes(&mask_words(512, &[]));
    h.bytes(&[6]).bytes(&vec![0u8; 4 * 32768]);
    h.bytes(&mask_words(64, &[0])).bytes(&mask_words(64, &[]));
    h.bytes(&[6]).bytes(&vec![0u8; 4 * 4096]);
    h.bytes(&mask_words(8, leaf_mask));
    h.bytes(&mask_words(8, leaf_mask));
    leaf_table(h);
    h.done()
}

#[test]
fn uncompressed_and_mask_compressed_tables_by_hand() {
    let on = [0usize, 5, 64, 511];
    let vals = [1.5f32, -2.0, 3.25, 4.0];
    let expect = |g: &Grid| {
        assert_eq!(g.voxels, vec![[0, 0, 0], [0, 0, 5], [1, 0, 0], [7, 7, 7]]);
        assert_eq!(g.voxel_values, Values::Float(vals.to_vec()));
    };
    // No compression at all: every value of the leaf.
    let mut h = Hand::new(1);
    h.grid(0);
    let b = one_leaf(&mut h, &on, |h| {
        h.bytes(&[6]);
        for i in 0..512 {
            h.f32(on.iter().position(|&o| o == i).map_or(9.0, |k| vals[k]));
        }
    });
    expect(&read(&b)[0]);
    // Active-mask compression, raw: the active values after each mode's
    // header (mode 0: none; 2: one inactive value; 5: two and the
    // selection mask; 6: all values).
    for mode in [0u8, 1, 2, 3, 4, 5, 6] {
        let mut h = Hand::new(1);
        h.grid(0x2);
        let b = one_leaf(&mut h, &on, |h| {
            h.bytes(&[mode]);
            let inactive = match mode {
                2 | 4 => 1,
                5 => 2,
                _ => 0,
            };
            for _ in 0..inactive {
                h.f32(7.0);
            }
            if (3..=5).contains(&mode) {
                h.bytes(&mask_words(8, &[1, 2, 3]));
            }
            if mode == 6 {
                for i in 0..512 {
                    h.f32(on.iter().position(|&o| o == i).map_or(7.0, |k| vals[k]));
                }
            } else {
                for v in vals {
                    h.f32(v);
                }
            }
        });
        expect(&read(&b)[0]);
    }
    // Zip with active-mask compression, and a raw (negative length) block.
    for zip in [true, false] {
        let mut h = Hand::new(1);
        h.grid(0x1 | 0x2);
        // The internal nodes' tables are zipped too: rebuild them raw
        // (n < 0), as zipToStream writes incompressible data.
        h.u32(0).u32(1).bytes(&[0; 12]);
        h.bytes(&mask_words(512, &[0])).bytes(&mask_words(512, &[]));
        h.bytes(&[0]).i64(0);
        h.bytes(&mask_words(64, &[0])).bytes(&mask_words(64, &[]));
        h.bytes(&[0]).i64(0);
        h.bytes(&mask_words(8, &on)).bytes(&mask_words(8, &on)).bytes(&[0]);
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        if zip {
            use std::io::Write;
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&raw).expect("zips");
            let zipped = z.finish().expect("zips");
            h.i64(zipped.len() as i64).bytes(&zipped);
        } else {
            h.i64(-(raw.len() as i64)).bytes(&raw);
        }
        expect(&read(&h.done())[0]);
    }
}

/// Each hostile file must be refused, quickly.
fn refused_quickly(what: &str, bytes: &[u8], limits: ReadLimits) -> VdbReadError {
    let t = Instant::now();
    let e = read_vdb(bytes, &limits).err().unwrap_or_else(|| panic!("{what}: read"));
    assert!(t.elapsed() < Duration::from_secs(1), "{what}: {:?}", t.elapsed());
    e
}

#[test]
fn absurd_counts_and_lengths_are_refused_quickly() {
    // 2^31 − 1 grids, none there.
    let e = refused_quickly("grid count", &Hand::new(i32::MAX).done(), ALL);
    assert!(matches!(e, VdbReadError::Truncated { .. }), "{e}");
    let e = refused_quickly("negative grid count", &Hand::new(-1).done(), ALL);
    assert!(matches!(e, VdbReadError::Malformed { .. }), "{e}");
    // A name of 4 GiB.
    let mut h = Hand::new(1);
    h.u32(u32::MAX);
    let e = refused_quickly("name length", &h.done(), ALL);
    assert!(e.to_string().contains("needs 4294967295 bytes"), "{e}");
    // 2^32 − 1 metadata entries.
    let mut b = Hand::new(1).0;
    let at = b.len() - 8;
    b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    refused_quickly("metadata count", &b, ALL);
    // 2^32 − 1 root tiles and children.
    for (t, c) in [(u32::MAX, 0), (0, u32::MAX), (u32::MAX, u32::MAX)] {
        let mut h = Hand::new(1);
        h.grid(0).u32(t).u32(c);
        let e = refused_quickly("root counts", &h.done(), ALL);
        assert!(matches!(e, VdbReadError::Truncated { .. }), "{e}");
    }
    // A zip block of 2^60 bytes, and a raw one of −2^60.
    for n in [1i64 << 60, -(1i64 << 60), i64::MIN, i64::MAX] {
        let mut h = Hand::new(1);
        h.grid(0x1).u32(0).u32(1).bytes(&[0; 12]);
        h.bytes(&mask_words(512, &[])).bytes(&mask_words(512, &[])).bytes(&[6]).i64(n);
        let e = refused_quickly("block length", &h.done(), ALL);
        assert!(e.to_string().contains("g"), "{e}");
    }
    // A blosc chunk declaring 2 GiB.
    let mut h = Hand::new(1);
    h.grid(0x4).u32(0).u32(1).bytes(&[0; 12]);
    h.bytes(&mask_words(512, &[])).bytes(&mask_words(512, &[])).bytes(&[6]).i64(16);
    h.bytes(&[2, 1, 0x21, 4]).u32(1 << 31).u32(1 << 31).u32(16);
    refused_quickly("blosc size", &h.done(), ALL);
    // A 32³ node all of whose 32768 slots are active tiles of 128³
    // (2^36 voxels): over the limit before any tile is listed.
    let mut h = Hand::new(1);
    h.grid(0x1 | 0x2).u32(0).u32(1).bytes(&[0; 12]);
    h.bytes(&mask_words(512, &[])).bytes(&vec![0xFF; 4096]).bytes(&[0]);
    {
        use std::io::Write;
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&vec![0u8; 4 * 32768]).expect("zips");
        let zipped = z.finish().expect("zips");
        h.i64(zipped.len() as i64).bytes(&zipped);
    }
    let b = h.done();
    let e = refused_quickly("tiles", &b, ReadLimits { max_voxels: 1 << 30, tile_cover: true });
    assert!(matches!(e, VdbReadError::TooManyVoxels { max: 1073741824, .. }), "{e}");
    assert!(e.to_string().contains("\"g\""), "{e}");
    let (g, _) = read_vdb(&b, &ALL).expect("within an unlimited budget");
    assert_eq!(g[0].tiles.len(), 32768);
}

#[test]
fn not_vdb_and_old_versions_say_so() {
    assert!(matches!(read_vdb(b"", &ALL), Err(VdbReadError::NotVdb)));
    assert!(matches!(read_vdb(b"glTF\x02\0\0\0abcdefgh", &ALL), Err(VdbReadError::NotVdb)));
    let mut b = Hand::new(0).done();
    assert!(read_vdb(&b, &ALL).expect("an empty file").0.is_empty());
    b[8..12].copy_from_slice(&221u32.to_le_bytes());
    let e = read_vdb(&b, &ALL).expect_err("version 221");
    assert!(e.to_string().contains("version 221") && e.to_string().contains("newer OpenVDB"), "{e}");
    b[8..12].copy_from_slice(&300u32.to_le_bytes());
    assert!(matches!(read_vdb(&b, &ALL), Err(VdbReadError::UnsupportedVersion { version: 300 })));
}
