//! The document file (`.octo`), format version 1: a painting's tree, its
//! undo history and the whole session that made it, as a trace
//! (docs/documents.md).
//!
//! ```text
//! header   16 B magic "OCTOPAINTDOC\r\n\x1a\n" | u32 version | u32 oldest
//!          version that can read it | u32 section count | u32 CRC-32 of
//!          the 28 bytes before
//! section  4 B tag | u32 flags (bit 0: zlib, bit 1: optional) | u64 stored
//!          length | u64 raw length | u32 CRC-32 of the raw bytes | u32 0
//!          | stored bytes
//! trailer  "END!" | u32 CRC-32 of every byte before it | u64 file length
//! ```
//!
//! Sections of version 1, all zlib: `TRCE` the session as trace text
//! (header line and one line per event), `POOL` the pools (u32 n, then the
//! columns parent, first child, depth, rgb, sigma), `HIST` the undo and
//! redo steps, `META` JSON about the save. A reader skips optional
//! sections it does not know and refuses required ones: a newer writer
//! marks what an older reader may ignore. Little-endian throughout.
//!
//! The magic's `\r\n\x1a\n` (PNG's trick) shows a file mangled by a text
//! transfer; the CRCs show any other damage; the trailer's length shows a
//! truncated file before anything is decompressed.

use std::io::{Read, Write};

use flate2::Compression;
use flate2::read::ZlibDecoder;
use flate2::write::ZlibEncoder;
use octopaint_tree::history::{History, UndoStep};
use octopaint_tree::layers::{self, DocumentStep, Layer, LayerList, LayerRow};
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::{CellRecord, FREE, NONE, Tree};
use octopaint_tree::trace::{Trace, parse_trace_with};

use crate::DocError;
use crate::trace_log::Deflated;

pub const MAGIC: &[u8; 16] = b"OCTOPAINTDOC\r\n\x1a\n";
/// The newest version this reader reads and the version a document of
/// layers is written in; a one-tree document is still written as version 1,
/// which every reader opens.
pub const VERSION: u32 = 3;

/// The voxel sets a session's `import` events name (spec 15), by the
/// `file` the events give; saved as one `VOXL` section each.
pub type Imports = std::collections::BTreeMap<String, Vec<u8>>;

/// The format version a document with imports is written in (one tree or
/// layers alike): older readers refuse it as too new instead of failing
/// on an `import` event they cannot resolve.
pub const IMPORTS_VERSION: u32 = 3;

/// One `VOXL` section: u32 length and the UTF-8 `file` name, then the
/// voxel set's bytes.
fn voxl_bytes(file: &str, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(file.len() + 4 + data.len());
    put_u32(&mut out, file.len() as u32);
    out.extend_from_slice(file.as_bytes());
    out.extend_from_slice(data);
    out
}
const HEADER: usize = 32;
const SECTION_HEAD: usize = 32;
const TRAILER: usize = 16;
const ZLIB: u32 = 1;
const OPTIONAL: u32 = 2;
const RECORD: usize = 16;

/// Everything a document holds.
pub struct Document {
    /// The session so far: a valid trace (header and events).
    pub trace_text: String,
    pub content: Content,
    /// Free-form JSON written at save (application, time, counts).
    pub meta: String,
    /// The voxel sets its session imported.
    pub imports: Imports,
}

/// A resolver for a session's `import` events: the document's own voxel
/// sets, by file name (spec 15.2).
pub fn resolver(imports: &Imports) -> impl Fn(&str) -> std::io::Result<Vec<u8>> + '_ {
    move |file: &str| imports.get(file).cloned().ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not in the document"))
}

/// What a document paints: one tree (version 1, a version 1 session) or
/// the layers of a version 2 session (format version 2, spec 14).
#[expect(clippy::large_enum_variant, reason = "one per open document; a box would only move the tree")]
pub enum Content {
    Tree { tree: Tree, history: History },
    Layers(layers::Document),
}

/// What `read` found, besides the document.
pub struct Loaded {
    pub doc: Document,
    /// The parsed session (its canvas is the tree's).
    pub trace: Trace,
    /// CRC-32 of the whole file but its trailer: the document's identity
    /// (a journal names the document it extends by it).
    pub crc: u32,
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_record(out: &mut Vec<u8>, r: &CellRecord) {
    put_u32(out, r.parent);
    put_u32(out, r.first_child);
    out.push(r.depth);
    out.extend_from_slice(&r.rgb);
    out.extend_from_slice(&r.sigma.to_le_bytes());
}

fn pools_bytes(t: &Tree) -> Vec<u8> {
    let n = t.n_used() as usize;
    let mut out = Vec::with_capacity(4 + n * 16);
    put_u32(&mut out, n as u32);
    for v in t.parent() {
        put_u32(&mut out, *v);
    }
    for v in t.first_child() {
        put_u32(&mut out, *v);
    }
    out.extend_from_slice(t.depth());
    for v in t.rgb() {
        out.extend_from_slice(v);
    }
    for v in t.sigma() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// `h`'s steps with all their records; `tree` holds the newest done
/// step's after-records (a done step's tail is read from the pools).
fn history_bytes(h: &History, tree: &Tree) -> Vec<u8> {
    let mut out = Vec::new();
    put_u32(&mut out, h.done.len() as u32);
    put_u32(&mut out, h.undone.len() as u32);
    for s in h.full_steps(tree) {
        put_u32(&mut out, s.n_before);
        put_u32(&mut out, s.n_after);
        put_u32(&mut out, s.len() as u32);
        for (c, _, _) in s.entries() {
            put_u32(&mut out, c);
        }
        for (_, r, _) in s.entries() {
            put_record(&mut out, &r);
        }
        for (_, _, r) in s.entries() {
            put_record(&mut out, &r);
        }
    }
    out
}

/// A document's `TRCE` section: the session's text, deflated when
/// written, or deflated already (a writing session's [`TraceLog`]).
///
/// [`TraceLog`]: crate::trace_log::TraceLog
pub enum TraceSection<'a> {
    Text(&'a str),
    Deflated(Deflated<'a>),
}

impl<'a> From<&'a str> for TraceSection<'a> {
    fn from(t: &'a str) -> Self {
        TraceSection::Text(t)
    }
}

impl<'a> From<&'a String> for TraceSection<'a> {
    fn from(t: &'a String) -> Self {
        TraceSection::Text(t)
    }
}

impl<'a> From<Deflated<'a>> for TraceSection<'a> {
    fn from(d: Deflated<'a>) -> Self {
        TraceSection::Deflated(d)
    }
}

/// A section's content: raw bytes, or a zlib stream made already (in
/// three parts) with its raw length and CRC.
enum Body<'a> {
    Raw(&'a [u8]),
    Stored(Deflated<'a>),
}

impl<'a> From<TraceSection<'a>> for Body<'a> {
    fn from(t: TraceSection<'a>) -> Self {
        match t {
            TraceSection::Text(t) => Body::Raw(t.as_bytes()),
            TraceSection::Deflated(d) => Body::Stored(d),
        }
    }
}

fn section(out: &mut Vec<u8>, tag: &[u8; 4], body: &Body<'_>, flags: u32) -> std::io::Result<()> {
    let (deflated, raw_len, crc);
    let stored: [&[u8]; 3] = match body {
        Body::Raw(raw) => {
            let mut z = ZlibEncoder::new(Vec::with_capacity(raw.len() / 4), Compression::fast());
            z.write_all(raw)?;
            deflated = z.finish()?;
            (raw_len, crc) = (raw.len() as u64, crc32fast::hash(raw));
            [&deflated, &[], &[]]
        }
        Body::Stored(d) => {
            (raw_len, crc) = (d.raw_len, d.crc);
            [&d.spilled, d.stream, &d.end]
        }
    };
    out.extend_from_slice(tag);
    put_u32(out, flags | ZLIB);
    out.extend_from_slice(&(stored.iter().map(|s| s.len()).sum::<usize>() as u64).to_le_bytes());
    out.extend_from_slice(&raw_len.to_le_bytes());
    put_u32(out, crc);
    put_u32(out, 0);
    for s in stored {
        out.extend_from_slice(s);
    }
    Ok(())
}

/// A document's parts as bytes, and the file's CRC (the identity a
/// journal refers to).
pub fn write<'a>(trace_text: impl Into<TraceSection<'a>>, tree: &Tree, history: &History, meta: &str) -> std::io::Result<(Vec<u8>, u32)> {
    write_with(trace_text, tree, history, meta, &Imports::new())
}

/// [`write`] with the voxel sets the session imported (format version 3
/// when there are any).
pub fn write_with<'a>(
    trace_text: impl Into<TraceSection<'a>>,
    tree: &Tree,
    history: &History,
    meta: &str,
    imports: &Imports,
) -> std::io::Result<(Vec<u8>, u32)> {
    // One tree: version 1, which every reader opens, unless it imported.
    let (pools, hist) = (pools_bytes(tree), history_bytes(history, tree));
    let voxl: Vec<Vec<u8>> = imports.iter().map(|(f, d)| voxl_bytes(f, d)).collect();
    let trace: TraceSection<'a> = trace_text.into();
    let mut sections = vec![(b"TRCE", Body::from(trace), 0), (b"POOL", Body::Raw(&pools), 0), (b"HIST", Body::Raw(&hist), 0)];
    sections.extend(voxl.iter().map(|raw| (b"VOXL", Body::Raw(raw), 0)));
    sections.push((b"META", Body::Raw(meta.as_bytes()), OPTIONAL));
    file_bytes(if imports.is_empty() { 1 } else { IMPORTS_VERSION }, &sections)
}

/// A file of `version` (also the oldest version that reads it): header,
/// the sections (tag, raw bytes, flags) in order, trailer; and the CRC of
/// everything but the trailer (the identity a journal refers to).
fn file_bytes(version: u32, sections: &[(&[u8; 4], Body<'_>, u32)]) -> std::io::Result<(Vec<u8>, u32)> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    put_u32(&mut out, version);
    put_u32(&mut out, version);
    put_u32(&mut out, sections.len() as u32);
    let crc = crc32fast::hash(&out);
    put_u32(&mut out, crc);
    for (tag, body, flags) in sections {
        section(&mut out, tag, body, *flags)?;
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(b"END!");
    put_u32(&mut out, crc);
    let len = out.len() as u64 + 8;
    out.extend_from_slice(&len.to_le_bytes());
    Ok((out, crc))
}

fn put_name(out: &mut Vec<u8>, name: &str) {
    put_u32(out, name.len() as u32);
    out.extend_from_slice(name.as_bytes());
}

fn settings_bytes(out: &mut Vec<u8>, s: &LayerList) {
    put_u32(out, s.selected as u32);
    put_u32(out, s.rows.len() as u32);
    for r in &s.rows {
        put_u32(out, r.id);
        out.push(u8::from(r.visible));
        out.push(u8::from(r.locked));
        out.extend_from_slice(&r.opacity.to_le_bytes());
        put_name(out, &r.name);
    }
}

/// The `DOCU` section: the next id, the selection, the list of layer ids,
/// then the history's done and undone steps (0 and a layer id: a stroke;
/// 1 and the settings before and after: a layer operation).
fn document_bytes(doc: &layers::Document) -> Vec<u8> {
    let (_, order, selected, next_id, done, undone) = doc.parts();
    let mut out = Vec::new();
    put_u32(&mut out, next_id);
    put_u32(&mut out, selected as u32);
    put_u32(&mut out, order.len() as u32);
    for id in order {
        put_u32(&mut out, *id);
    }
    put_u32(&mut out, done.len() as u32);
    put_u32(&mut out, undone.len() as u32);
    for step in done.iter().chain(undone) {
        match step {
            DocumentStep::Stroke(id) => {
                out.push(0);
                put_u32(&mut out, *id);
            }
            DocumentStep::Layers(b) => {
                out.push(1);
                settings_bytes(&mut out, &b.0);
                settings_bytes(&mut out, &b.1);
            }
        }
    }
    out
}

/// One `LAYR` section: the layer's id and settings, its pools (with their
/// length in bytes first) and its own undo steps.
fn layer_bytes(id: u32, l: &Layer) -> Vec<u8> {
    let mut out = Vec::new();
    put_u32(&mut out, id);
    out.push(u8::from(l.visible));
    out.push(u8::from(l.locked));
    out.extend_from_slice(&l.opacity.to_le_bytes());
    put_name(&mut out, &l.name);
    let pools = pools_bytes(l.tree());
    out.extend_from_slice(&(pools.len() as u64).to_le_bytes());
    out.extend_from_slice(&pools);
    out.extend_from_slice(&history_bytes(&l.painting.history, l.tree()));
    out
}

/// A document of layers as bytes (format version 2: `TRCE`, `DOCU`, one
/// `LAYR` per layer the document or its history holds, `META`), and the
/// file's CRC.
pub fn write_layers<'a>(trace_text: impl Into<TraceSection<'a>>, doc: &layers::Document, meta: &str, imports: &Imports) -> std::io::Result<(Vec<u8>, u32)> {
    let (layers, ..) = doc.parts();
    let docu = document_bytes(doc);
    let layrs: Vec<Vec<u8>> = layers.map(|(id, l)| layer_bytes(id, l)).collect();
    let voxl: Vec<Vec<u8>> = imports.iter().map(|(f, d)| voxl_bytes(f, d)).collect();
    let trace: TraceSection<'a> = trace_text.into();
    let mut sections = vec![(b"TRCE", Body::from(trace), 0), (b"DOCU", Body::Raw(&docu), 0)];
    sections.extend(layrs.iter().map(|raw| (b"LAYR", Body::Raw(raw), 0)));
    sections.extend(voxl.iter().map(|raw| (b"VOXL", Body::Raw(raw), 0)));
    sections.push((b"META", Body::Raw(meta.as_bytes()), OPTIONAL));
    file_bytes(if imports.is_empty() { 2 } else { IMPORTS_VERSION }, &sections)
}

/// A little-endian cursor that refuses to read past its end.
struct Cursor<'a> {
    data: &'a [u8],
    at: usize,
    what: &'static str,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], DocError> {
        if self.data.len() - self.at < n {
            return Err(DocError::Corrupt(format!("the {} section ends early", self.what)));
        }
        let s = &self.data[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, DocError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u8(&mut self) -> Result<u8, DocError> {
        Ok(self.take(1)?[0])
    }
    fn flag(&mut self) -> Result<bool, DocError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(DocError::Corrupt(format!("the {} section holds a flag that is neither 0 nor 1", self.what))),
        }
    }
    fn f32(&mut self) -> Result<f32, DocError> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn name(&mut self) -> Result<String, DocError> {
        let n = self.u32()? as usize;
        let b = self.take(n)?;
        String::from_utf8(b.to_vec()).map_err(|_| DocError::Corrupt(format!("the {} section holds a name that is not UTF-8", self.what)))
    }
    fn u32s(&mut self, n: usize) -> Result<Vec<u32>, DocError> {
        Ok(self.take(n.checked_mul(4).ok_or_else(|| self.too_big())?)?.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().expect("4"))).collect())
    }
    fn record(&mut self) -> Result<CellRecord, DocError> {
        let b = self.take(RECORD)?;
        Ok(CellRecord {
            parent: u32::from_le_bytes(b[0..4].try_into().expect("4")),
            first_child: u32::from_le_bytes(b[4..8].try_into().expect("4")),
            depth: b[8],
            rgb: [b[9], b[10], b[11]],
            sigma: f32::from_le_bytes(b[12..16].try_into().expect("4")),
        })
    }
    fn too_big(&self) -> DocError {
        DocError::Corrupt(format!("the {} section declares an impossible size", self.what))
    }
    fn done(&self) -> Result<(), DocError> {
        if self.at != self.data.len() {
            return Err(DocError::Corrupt(format!("the {} section has {} bytes too many", self.what, self.data.len() - self.at)));
        }
        Ok(())
    }
}

fn inflate(stored: &[u8], raw_len: u64, tag: &str) -> Result<Vec<u8>, DocError> {
    // The declared size bounds the output (no zip bomb), and the buffer
    // grows as data really arrives (no allocation from a lying header).
    let mut out = Vec::with_capacity(raw_len.min(stored.len() as u64 * 4) as usize);
    ZlibDecoder::new(stored).take(raw_len + 1).read_to_end(&mut out).map_err(|e| DocError::Corrupt(format!("the {tag} section does not decompress: {e}")))?;
    if out.len() as u64 != raw_len {
        return Err(DocError::Corrupt(format!("the {tag} section holds {} bytes, its header says {raw_len}", out.len())));
    }
    Ok(out)
}

/// Read a document, checking everything; nothing is trusted before its
/// CRC has been checked, and nothing decoded is trusted before the tree
/// it makes has passed every structural check.
pub fn read(data: &[u8]) -> Result<Loaded, DocError> {
    if data.len() < 16 || &data[..16] != MAGIC {
        if data.len() >= 12 && &data[..12] == b"OCTOPAINTDOC" {
            return Err(DocError::Corrupt("the file was changed by a text-mode transfer (its line endings were rewritten)".into()));
        }
        return Err(DocError::NotADocument);
    }
    if data.len() < HEADER + TRAILER {
        return Err(DocError::Corrupt(format!("the file is truncated ({} bytes)", data.len())));
    }
    let word = |at: usize| u32::from_le_bytes(data[at..at + 4].try_into().expect("4 bytes"));
    if crc32fast::hash(&data[..28]) != word(28) {
        return Err(DocError::Corrupt("the header is damaged (checksum mismatch)".into()));
    }
    let (version, oldest, sections) = (word(16), word(20), word(24));
    if oldest > VERSION {
        return Err(DocError::TooNew { version, reads: VERSION });
    }
    // Trailer: length first (a truncated file says so), then the CRC.
    let tail = &data[data.len() - TRAILER..];
    let declared = u64::from_le_bytes(tail[8..16].try_into().expect("8 bytes"));
    if &tail[..4] != b"END!" {
        return Err(DocError::Corrupt(format!("the file is truncated ({} bytes, no end marker)", data.len())));
    }
    if declared != data.len() as u64 {
        return Err(DocError::Corrupt(format!("the file is {} bytes, its end marker says {declared}: truncated or extended", data.len())));
    }
    let body = &data[..data.len() - TRAILER];
    let crc = crc32fast::hash(body);
    if crc != u32::from_le_bytes(tail[4..8].try_into().expect("4 bytes")) {
        return Err(DocError::Corrupt("the file is damaged (checksum mismatch)".into()));
    }
    let mut at = HEADER;
    let (mut trace_text, mut pools, mut hist, mut meta) = (None, None, None, String::new());
    let (mut docu, mut layrs) = (None, Vec::new());
    let mut imports = Imports::new();
    for _ in 0..sections {
        if body.len() - at < SECTION_HEAD {
            return Err(DocError::Corrupt("a section header runs past the end".into()));
        }
        let h = &body[at..at + SECTION_HEAD];
        let tag = String::from_utf8_lossy(&h[..4]).into_owned();
        let flags = u32::from_le_bytes(h[4..8].try_into().expect("4"));
        let stored_len = u64::from_le_bytes(h[8..16].try_into().expect("8"));
        let raw_len = u64::from_le_bytes(h[16..24].try_into().expect("8"));
        let raw_crc = u32::from_le_bytes(h[24..28].try_into().expect("4"));
        at += SECTION_HEAD;
        if stored_len > (body.len() - at) as u64 {
            return Err(DocError::Corrupt(format!("the {tag} section runs past the end")));
        }
        let stored = &body[at..at + stored_len as usize];
        at += stored_len as usize;
        let known = matches!(&h[..4], b"TRCE" | b"POOL" | b"HIST" | b"META" | b"DOCU" | b"LAYR" | b"VOXL");
        if !known {
            if flags & OPTIONAL != 0 {
                continue;
            }
            return Err(DocError::TooNew { version, reads: VERSION });
        }
        let raw = if flags & ZLIB != 0 { inflate(stored, raw_len, &tag)? } else { stored.to_vec() };
        if crc32fast::hash(&raw) != raw_crc {
            return Err(DocError::Corrupt(format!("the {tag} section is damaged (checksum mismatch)")));
        }
        match &h[..4] {
            b"TRCE" => trace_text = Some(String::from_utf8(raw).map_err(|_| DocError::Corrupt("the session is not UTF-8".into()))?),
            b"POOL" => pools = Some(raw),
            b"HIST" => hist = Some(raw),
            b"DOCU" => docu = Some(raw),
            b"LAYR" => layrs.push(raw),
            b"VOXL" => {
                let mut c = Cursor { data: &raw, at: 0, what: "VOXL" };
                let file = c.name()?;
                let data = raw[c.at..].to_vec();
                if imports.insert(file.clone(), data).is_some() {
                    return Err(DocError::Corrupt(format!("the voxel set {file} is in the file twice")));
                }
            }
            _ => meta = String::from_utf8_lossy(&raw).into_owned(),
        }
    }
    if at != body.len() {
        return Err(DocError::Corrupt("bytes between the last section and the end".into()));
    }
    let missing = |what: &str| DocError::Corrupt(format!("the {what} section is missing"));
    let trace_text = trace_text.ok_or_else(|| missing("TRCE"))?;
    let trace = {
        let resolve = resolver(&imports);
        parse_trace_with(&trace_text, Some(&resolve)).map_err(|e| DocError::Corrupt(format!("its session does not read as a trace: {e}")))?
    };
    let content = match docu {
        None => {
            if trace.version != 1 {
                return Err(DocError::Corrupt("its session has layers but the file holds one tree".into()));
            }
            let mut tree = decode_pools(&trace, &pools.ok_or_else(|| missing("POOL"))?)?;
            let history = decode_history(&tree, &hist.ok_or_else(|| missing("HIST"))?)?;
            tree.prefilter_all();
            Content::Tree { tree, history }
        }
        Some(docu) => {
            if trace.version != 2 || pools.is_some() || hist.is_some() {
                return Err(DocError::Corrupt("it mixes a document of layers with a one-tree one".into()));
            }
            Content::Layers(decode_document(&trace, &docu, &layrs)?)
        }
    };
    Ok(Loaded { doc: Document { trace_text, content, meta, imports }, trace, crc })
}

fn decode_settings(c: &mut Cursor) -> Result<LayerList, DocError> {
    let selected = c.u32()? as usize;
    let n = c.u32()? as usize;
    if n > layers::MAX_LAYERS {
        return Err(c.too_big());
    }
    let mut rows = Vec::with_capacity(n);
    for _ in 0..n {
        let id = c.u32()?;
        let visible = c.flag()?;
        let locked = c.flag()?;
        let opacity = c.f32()?;
        let name = c.name()?;
        rows.push(LayerRow { id, name, visible, opacity, locked });
    }
    Ok(LayerList { rows, selected })
}

fn decode_document(trace: &Trace, docu: &[u8], layrs: &[Vec<u8>]) -> Result<layers::Document, DocError> {
    let mut c = Cursor { data: docu, at: 0, what: "DOCU" };
    let next_id = c.u32()?;
    let selected = c.u32()? as usize;
    let n = c.u32()? as usize;
    if n > layers::MAX_LAYERS {
        return Err(c.too_big());
    }
    let order = c.u32s(n)?;
    let done = c.u32()? as usize;
    let undone = c.u32()? as usize;
    if done.saturating_add(undone) > docu.len() / 5 {
        return Err(c.too_big());
    }
    let mut steps = Vec::with_capacity(done + undone);
    for _ in 0..done + undone {
        steps.push(match c.u8()? {
            0 => DocumentStep::Stroke(c.u32()?),
            1 => {
                let before = decode_settings(&mut c)?;
                let after = decode_settings(&mut c)?;
                DocumentStep::Layers(Box::new((before, after)))
            }
            k => return Err(DocError::Corrupt(format!("the DOCU section holds a step of unknown kind {k}"))),
        });
    }
    c.done()?;
    let undone_steps = steps.split_off(done);
    let mut found = Vec::with_capacity(layrs.len());
    for raw in layrs {
        let mut c = Cursor { data: raw, at: 0, what: "LAYR" };
        let id = c.u32()?;
        let visible = c.flag()?;
        let locked = c.flag()?;
        let opacity = c.f32()?;
        let name = c.name()?;
        let pools_len = u64::from_le_bytes(c.take(8)?.try_into().expect("8 bytes"));
        if pools_len > (raw.len() - c.at) as u64 {
            return Err(c.too_big());
        }
        let mut tree = decode_pools(trace, c.take(pools_len as usize)?)?;
        let history = decode_history(&tree, &raw[c.at..])?;
        tree.prefilter_all();
        let mut layer = Layer::new(&name, Painting::from_parts(tree, history));
        layer.visible = visible;
        layer.locked = locked;
        layer.opacity = opacity;
        found.push((id, layer));
    }
    layers::Document::from_parts(&trace.canvas, found, order, selected, next_id, steps, undone_steps)
        .map_err(|e| DocError::Corrupt(format!("its layers do not fit together: {e}")))
}

/// The tree of a `POOL` section, its interior values as stored: its reader
/// computes them afresh (spec 4.4) once the undo history has been checked
/// against the stored ones, so that a document saved before the rule opens
/// (its undo steps come back to the rule as they are applied).
fn decode_pools(trace: &Trace, raw: &[u8]) -> Result<Tree, DocError> {
    let mut c = Cursor { data: raw, at: 0, what: "POOL" };
    let n = c.u32()? as usize;
    if (n as u64) > u64::from(trace.canvas.capacity) || raw.len() != 4 + n * 16 {
        return Err(c.too_big());
    }
    let parent = c.u32s(n)?;
    let first_child = c.u32s(n)?;
    let depth = c.take(n)?.to_vec();
    let rgb = c.take(n * 3)?.chunks_exact(3).map(|v| [v[0], v[1], v[2]]).collect();
    let sigma = c.take(n * 4)?.chunks_exact(4).map(|v| f32::from_le_bytes(v.try_into().expect("4"))).collect();
    c.done()?;
    Tree::from_pools(&trace.canvas, parent, first_child, depth, rgb, sigma).map_err(|p| DocError::Corrupt(format!("its tree is not valid: {p}")))
}

/// Undo steps are checked for what `apply_step` relies on (lengths within
/// the budget, cells within them, records that are cells) and the newest
/// done and undone steps against the tree; a step deeper in the stacks that
/// passed the CRC is trusted.
fn decode_history(tree: &Tree, raw: &[u8]) -> Result<History, DocError> {
    let mut c = Cursor { data: raw, at: 0, what: "HIST" };
    let done = c.u32()? as usize;
    let undone = c.u32()? as usize;
    if done.saturating_add(undone) > raw.len() / 12 {
        return Err(c.too_big());
    }
    let mut steps = Vec::with_capacity(done + undone);
    let padded = tree.lat.padded;
    let bad = |m: String| DocError::Corrupt(format!("its undo history is not valid: {m}"));
    for i in 0..done + undone {
        let n_before = c.u32()?;
        let n_after = c.u32()?;
        let k = c.u32()? as usize;
        for n in [n_before, n_after] {
            if n < padded || n % 8 != 0 || n > tree.capacity {
                return Err(bad(format!("step {i} has a used length of {n}")));
            }
        }
        let cells = c.u32s(k)?;
        let len = n_before.max(n_after);
        if let Some(x) = cells.iter().find(|&&x| x >= len) {
            return Err(bad(format!("step {i} names cell {x} past its length {len}")));
        }
        let mut sorted = cells.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(bad(format!("step {i} names cell {} twice", w[0])));
        }
        let mut recs = Vec::with_capacity(2 * k);
        for _ in 0..2 * k {
            let r = c.record()?;
            let ok = if r.depth == FREE {
                r.parent == NONE && r.first_child == NONE
            } else {
                u32::from(r.depth) <= tree.lat.max_depth && r.sigma.is_finite() && r.sigma >= 0.0 && (r.parent == NONE || r.parent < len)
            };
            if !ok {
                return Err(bad(format!("step {i} holds an impossible cell record")));
            }
            recs.push(r);
        }
        let after = recs.split_off(k);
        let mut step = UndoStep::new(n_before, n_after);
        for ((c, b), a) in cells.into_iter().zip(recs).zip(after) {
            step.push(c, b, a);
        }
        step.shrink();
        steps.push(step);
    }
    c.done()?;
    let undone_steps = steps.split_off(done);
    let h = History { done: steps, undone: undone_steps };
    let n = tree.n_used();
    if let Some(s) = h.done.last()
        && (s.n_after != n || s.entries().any(|(c, _, r)| !tree.record(c).same_bits(&r)))
    {
        return Err(bad("its last stroke is not the tree's state".into()));
    }
    if let Some(s) = h.undone.last()
        && (s.n_before != n || s.entries().any(|(c, r, _)| !tree.record(c).same_bits(&r)))
    {
        return Err(bad("its last undone stroke does not start from the tree's state".into()));
    }
    Ok(h)
}
