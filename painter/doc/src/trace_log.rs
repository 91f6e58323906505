//! The session's trace as a writing session holds it between saves: what
//! has been saved once is kept deflated, as the document's `TRCE` section
//! stores it, and out of memory, in a spill file of the session's own
//! beside the document; only the events since the last save are kept as
//! text. A session of hours so holds no more of its trace than the events
//! of one save interval, and a save deflates only what is new: the stream
//! is never finished, only flushed (zlib's sync flush, which ends on a
//! byte), and each save's section is that stream with an empty final
//! block and the Adler-32 of everything before, an ordinary zlib stream
//! any reader inflates (docs/documents.md, "Memory over a long session").
//!
//! The spill file is an anonymous temporary file in the document's folder
//! (on the document's disk, not a RAM-backed /tmp), gone when the session
//! ends however it ends; where one cannot be made the stream stays in
//! memory. The text is the trace format's: the header line, then `\n` and
//! one event line per event, with no newline at the end.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use flate2::Compression;
use flate2::read::ZlibDecoder;
use flate2::write::ZlibEncoder;

/// A `TRCE` section's content, deflated: `spilled`, `stream` then `end`,
/// `raw_len` bytes of text whose CRC-32 is `crc`.
pub struct Deflated<'a> {
    pub spilled: Vec<u8>,
    pub stream: &'a [u8],
    pub end: [u8; 6],
    pub raw_len: u64,
    pub crc: u32,
}

/// What the stream holds so far, with its checksums.
struct Stream {
    /// The stream's bytes not yet in the spill file.
    z: ZlibEncoder<Vec<u8>>,
    /// The spill file and the stream's bytes in it (None: the stream is
    /// all in `z`).
    spill: Option<(File, u64)>,
    crc: crc32fast::Hasher,
    adler: adler2::Adler32,
    raw_len: u64,
}

impl Stream {
    fn new(folder: &Path) -> Stream {
        let spill = tempfile::tempfile_in(folder).ok().map(|f| (f, 0));
        Stream { z: ZlibEncoder::new(Vec::new(), Compression::fast()), spill, crc: crc32fast::Hasher::new(), adler: adler2::Adler32::new(), raw_len: 0 }
    }

    fn write(&mut self, text: &str) -> std::io::Result<()> {
        self.z.write_all(text.as_bytes())?;
        self.crc.update(text.as_bytes());
        self.adler.write_slice(text.as_bytes());
        self.raw_len += text.len() as u64;
        Ok(())
    }

    /// Move the bytes in `z` to the end of the spill file (kept in `z`
    /// when that fails: the next seal tries again).
    fn spill(&mut self) -> std::io::Result<()> {
        let Some((f, len)) = &mut self.spill else { return Ok(()) };
        f.seek(SeekFrom::Start(*len))?;
        f.write_all(self.z.get_ref())?;
        *len += self.z.get_ref().len() as u64;
        self.z.get_mut().clear();
        Ok(())
    }

    /// The spilled bytes, read back.
    fn spilled(&self) -> std::io::Result<Vec<u8>> {
        let Some((f, len)) = &self.spill else { return Ok(Vec::new()) };
        let mut out = Vec::with_capacity(*len as usize);
        let mut f = f;
        f.seek(SeekFrom::Start(0))?;
        f.take(*len).read_to_end(&mut out)?;
        if out.len() as u64 != *len {
            return Err(std::io::Error::new(std::io::ErrorKind::UnexpectedEof, "the trace's spill file is shorter than written"));
        }
        Ok(out)
    }

    /// The empty final block (static Huffman: BFINAL 1, BTYPE 01, the
    /// end-of-block code, seven zero bits) and the Adler-32, big-endian.
    fn end(&self) -> [u8; 6] {
        let a = self.adler.checksum().to_be_bytes();
        [0x03, 0x00, a[0], a[1], a[2], a[3]]
    }
}

pub struct TraceLog {
    /// Everything sealed so far; None before the first seal.
    stream: Option<Stream>,
    /// Before the first seal: the text the session began with (the
    /// document's trace as opened); empty after it.
    head: String,
    /// The events since the last save, each as `\n` and its line.
    since: String,
    /// Events in `since`.
    since_events: usize,
    /// Bytes at the start of `since` the stream already holds (a seal
    /// whose save then failed: the document on disk is still the one
    /// before, so they stay "since").
    sealed: usize,
}

impl TraceLog {
    /// A log holding `text` (a header, or a document's whole trace) as
    /// saved.
    pub fn new(text: String) -> TraceLog {
        TraceLog { stream: None, head: text, since: String::new(), since_events: 0, sealed: 0 }
    }

    /// Add one event's line (after the last save).
    pub fn push(&mut self, line: &str) {
        self.since.push('\n');
        self.since.push_str(line);
        self.since_events += 1;
    }

    /// The event lines since the last save, oldest first.
    pub fn since_lines(&self) -> impl Iterator<Item = &str> + '_ {
        self.since.split('\n').skip(1)
    }

    pub fn since_events(&self) -> usize {
        self.since_events
    }

    /// The whole text: the header and every event (the spilled part read
    /// back from its file).
    pub fn text(&self) -> std::io::Result<String> {
        let mut out = String::new();
        if let Some(s) = &self.stream {
            let mut whole = s.spilled()?;
            whole.extend_from_slice(s.z.get_ref());
            whole.extend_from_slice(&s.end());
            ZlibDecoder::new(whole.as_slice())
                .read_to_string(&mut out)
                .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("the trace's deflated part does not inflate: {e}")))?;
        }
        out.push_str(&self.head);
        out.push_str(&self.since[self.sealed..]);
        Ok(out)
    }

    /// Deflate everything not yet in the stream, and give the section a
    /// save writes; [`TraceLog::saved`] once that save is on disk. The
    /// spill file, if there is one, is made in `folder` (the document's).
    pub fn seal(&mut self, folder: &Path) -> std::io::Result<Deflated<'_>> {
        if self.stream.is_none() {
            let mut s = Stream::new(folder);
            s.write(&self.head)?;
            self.head = String::new();
            self.stream = Some(s);
        }
        let stream = self.stream.as_mut().expect("made above");
        stream.write(&self.since[self.sealed..])?;
        self.sealed = self.since.len();
        stream.z.flush()?;
        stream.spill()?;
        let spilled = stream.spilled()?;
        Ok(Deflated { spilled, stream: stream.z.get_ref(), end: stream.end(), raw_len: stream.raw_len, crc: stream.crc.clone().finalize() })
    }

    /// The sealed text is the saved document's: nothing is "since" any more.
    pub fn saved(&mut self) {
        self.since = self.since.split_off(self.sealed);
        self.since_events = self.since.matches('\n').count();
        self.sealed = 0;
    }

    /// Bytes the log holds in memory: the deflated stream's not spilled
    /// (its spare capacity is never written, so never resident) and the
    /// text's, for the soak's figures.
    pub fn bytes(&self) -> usize {
        self.stream.as_ref().map_or(0, |s| s.z.get_ref().len()) + self.head.len() + self.since.len()
    }

    /// Whether the saved part is spilled to a file (false before the
    /// first save, or where no spill file could be made).
    pub fn spilled(&self) -> bool {
        self.stream.as_ref().is_some_and(|s| s.spill.is_some())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inflate(d: &Deflated<'_>) -> String {
        let mut whole = d.spilled.clone();
        whole.extend_from_slice(d.stream);
        whole.extend_from_slice(&d.end);
        let mut out = String::new();
        ZlibDecoder::new(whole.as_slice()).read_to_string(&mut out).unwrap();
        assert_eq!(out.len() as u64, d.raw_len);
        assert_eq!(crc32fast::hash(out.as_bytes()), d.crc);
        out
    }

    #[test]
    fn every_seal_is_a_whole_zlib_stream_of_the_text_so_far() {
        let dir = tempfile::tempdir().unwrap();
        let mut log = TraceLog::new("{\"octopaint_trace\": 2}".into());
        let mut want = String::from("{\"octopaint_trace\": 2}");
        for save in 0..5 {
            for k in 0..200 {
                let line = format!("{{\"t\": {save}.{k:03}, \"ev\": \"sample\", \"p\": [{k}, {save}, 3]}}");
                log.push(&line);
                want.push('\n');
                want.push_str(&line);
            }
            assert_eq!(log.text().unwrap(), want);
            let got = inflate(&log.seal(dir.path()).unwrap());
            assert_eq!(got, want);
            log.saved();
            assert!(log.spilled());
            assert_eq!(log.since_events(), 0);
            assert_eq!(log.text().unwrap(), want);
        }
        // Spilled, the saved text takes no memory; the spill file goes
        // with the log (on Windows it has a name until then).
        assert_eq!(log.bytes(), 0);
        drop(log);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_seal_whose_save_failed_keeps_its_events_since_the_save() {
        let dir = tempfile::tempdir().unwrap();
        let mut log = TraceLog::new("H".into());
        log.push("a");
        log.push("b");
        let _ = log.seal(dir.path()).unwrap(); // the save then fails: no saved()
        log.push("c");
        assert_eq!(log.since_lines().collect::<Vec<_>>(), ["a", "b", "c"]);
        assert_eq!(log.text().unwrap(), "H\na\nb\nc");
        assert_eq!(inflate(&log.seal(dir.path()).unwrap()), "H\na\nb\nc");
        log.saved();
        assert_eq!(log.since_lines().count(), 0);
        log.push("d");
        assert_eq!(log.since_lines().collect::<Vec<_>>(), ["d"]);
        assert_eq!(log.text().unwrap(), "H\na\nb\nc\nd");
    }

    #[test]
    fn without_a_spill_file_the_stream_stays_in_memory() {
        let mut log = TraceLog::new("H".into());
        log.push("a");
        let d = log.seal(Path::new("/no/such/folder")).unwrap();
        assert!(d.spilled.is_empty());
        assert_eq!(inflate(&d), "H\na");
        log.saved();
        assert!(!log.spilled() && log.bytes() > 0);
        log.push("b");
        assert_eq!(inflate(&log.seal(Path::new("/no/such/folder")).unwrap()), "H\na\nb");
    }

    #[test]
    fn an_empty_log_seals_to_an_empty_stream() {
        let dir = tempfile::tempdir().unwrap();
        let mut log = TraceLog::new(String::new());
        let d = log.seal(dir.path()).unwrap();
        assert_eq!(inflate(&d), "");
        assert_eq!(&d.end[..2], &[0x03, 0x00]);
    }
}
