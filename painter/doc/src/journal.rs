//! The journal `<document>.journal` (docs/documents.md): a header line
//! naming the document it extends (the CRC of its file and its number of
//! events), then event lines of the trace format, appended and synced as
//! strokes end. What is read back of it after a crash: the lines up to the
//! last one that ended something (a stroke, an undo, a redo, a layer
//! operation); a line without its newline was being written and is not
//! part of it.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use octopaint_platform::durable;

use crate::{DocError, io};

pub fn journal_path(doc: &Path) -> PathBuf {
    let mut p = doc.as_os_str().to_owned();
    p.push(".journal");
    PathBuf::from(p)
}

/// The journal's bytes, None when there is none.
pub(crate) fn read(jp: &Path) -> Result<Option<Vec<u8>>, DocError> {
    match std::fs::read(jp) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io(jp)(e)),
    }
}

/// The complete event lines the journal of document `doc` holds beyond
/// the saved document, as a writer's recovery would replay them (None:
/// there is no journal; 0 right after a save).
pub fn lines_beyond(doc: &Path) -> Result<Option<usize>, DocError> {
    let jp = journal_path(doc);
    let Some(bytes) = read(&jp)? else { return Ok(None) };
    let text = String::from_utf8_lossy(&bytes);
    Ok(Some(parse(&jp, &text)?.map_or(0, |r| r.body.len())))
}

pub(crate) fn header(crc: u32, events: usize) -> String {
    format!("{{\"journal\": \"octopaint\", \"version\": 1, \"document_crc\": {crc}, \"document_events\": {events}}}")
}

fn parse_header(line: &str) -> Option<(u32, usize)> {
    let j: serde_json::Value = serde_json::from_str(line).ok()?;
    if j.get("journal")?.as_str()? != "octopaint" {
        return None;
    }
    let num = |k: &str| j.get(k)?.as_u64();
    Some((u32::try_from(num("document_crc")?).ok()?, usize::try_from(num("document_events")?).ok()?))
}

/// What a journal holds: the document it extends and its complete lines.
pub(crate) struct Read<'a> {
    pub crc: u32,
    /// The document's number of events it extends.
    pub base: usize,
    /// Event lines up to the last that ended something.
    pub body: Vec<&'a str>,
}

/// Read journal `text` (from `jp`); None when it is empty (created,
/// nothing written yet).
pub(crate) fn parse<'a>(jp: &Path, text: &'a str) -> Result<Option<Read<'a>>, DocError> {
    // A line without its newline was being written when the session died:
    // it is not part of the journal.
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut lines = complete.lines();
    let Some(head) = lines.next() else { return Ok(None) };
    let (crc, base) = parse_header(head).ok_or_else(|| DocError::Journal { path: jp.to_path_buf(), why: "its first line is not a journal header".into() })?;
    let mut body: Vec<&str> = lines.collect();
    // Only up to the last event that ended something: a stroke in progress
    // at the crash is not a stroke.
    let ends = |l: &str| {
        l.contains("\"stroke_end\"") || l.contains("\"undo\"") || l.contains("\"redo\"") || l.contains("\"ev\": \"layer\"") || l.contains("\"ev\":\"layer\"")
    };
    let keep = body.iter().rposition(|l| ends(l)).map_or(0, |i| i + 1);
    body.truncate(keep);
    Ok(Some(Read { crc, base, body }))
}

/// Replace the journal `jp` whole, atomically and durably: the header of
/// `base`, then `lines` (after an append failed part way, when what is in
/// the file cannot be trusted to end where the journal does).
pub(crate) fn rewrite<'a>(jp: &Path, base: (u32, usize), lines: impl Iterator<Item = &'a str>) -> Result<(), DocError> {
    let mut text = header(base.0, base.1);
    text.push('\n');
    for l in lines {
        text.push_str(l);
        text.push('\n');
    }
    durable::write(jp, text.as_bytes()).map_err(io(jp))
}

/// Append `lines` to the journal `jp` and sync it, opening it into `slot`
/// first when it is not open; a journal that is missing or empty gets the
/// header of `base` (the document's CRC and events) first.
pub(crate) fn append(slot: &mut Option<File>, jp: &Path, base: (u32, usize), lines: &[String]) -> Result<(), DocError> {
    let mut created = false;
    if slot.is_none() {
        let exists = jp.exists();
        let mut f = OpenOptions::new().create(true).append(true).open(jp).map_err(io(jp))?;
        if !exists || f.metadata().map_err(io(jp))?.len() == 0 {
            writeln!(f, "{}", header(base.0, base.1)).map_err(io(jp))?;
            created = true;
        }
        *slot = Some(f);
    }
    let f = slot.as_mut().expect("opened above");
    let mut text = String::new();
    for l in lines {
        text.push_str(l);
        text.push('\n');
    }
    f.write_all(text.as_bytes()).map_err(io(jp))?;
    f.sync_data().map_err(io(jp))?;
    if created {
        // A new journal's folder entry must outlive a power cut too.
        durable::sync_new_entry(jp).map_err(io(jp))?;
    }
    Ok(())
}
