//! Documents against replays: a session painted event by event, saved and
//! opened again, is the replay's tree and history byte for byte; every
//! truncation and many corruptions of a file are refused with a message
//! (never a panic); a session that dies keeps every stroke its journal
//! holds; a bounded undo history still records a trace that replays to
//! the same tree. The process-level tests (a session killed with SIGKILL)
//! are in app/tests/cli.rs.

use std::path::{Path, PathBuf};

use octopaint_doc::format::{self, MAGIC};
use octopaint_doc::{DocError, Session, journal_path};
use octopaint_tree::dump::dump_bytes;
use octopaint_tree::paint::Painting;
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::trace::{Event, EventKind, LayerOp, LayerOpKind, Trace, parse_trace};

struct Silent;
impl ReplayObserver for Silent {}

fn trace(name: &str) -> Trace {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../traces").join(format!("{name}.jsonl"));
    octopaint_tree::read_trace(&path).unwrap()
}

fn replayed(t: &Trace) -> Painting {
    replay(t, None, &mut Silent).unwrap().1
}

/// A trace's first `n` events (an open stroke at the cut is ended, as
/// replay does at the end of a trace).
fn prefix(t: &Trace, n: usize) -> Trace {
    Trace { events: t.events[..n].to_vec(), ..t.clone() }
}

fn session_from(dir: &Path, t: &Trace) -> (Session, PathBuf) {
    let path = dir.join("painting.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    for ev in &t.events {
        s.apply(ev).unwrap();
    }
    (s, path)
}

fn same_history(a: &Painting, b: &Painting) {
    assert_eq!(a.history.done.len(), b.history.done.len());
    assert_eq!(a.history.undone.len(), b.history.undone.len());
    for (x, y) in a.history.full_steps(&a.tree).iter().zip(&b.history.full_steps(&b.tree)) {
        assert_eq!((x.n_before, x.n_after, x.len()), (y.n_before, y.n_after, y.len()));
        for ((c, b, a), (d, e, f)) in x.entries().zip(y.entries()) {
            assert_eq!(c, d);
            assert!(b.same_bits(&e) && a.same_bits(&f), "cell {c} differs");
        }
    }
}

#[test]
fn a_saved_session_opens_as_its_replay() {
    for name in ["shapes_modes", "undo_redo", "capacity_limit", "edges"] {
        let dir = tempfile::tempdir().unwrap();
        let t = trace(name);
        let (mut s, path) = session_from(dir.path(), &t);
        s.save().unwrap();
        drop(s);
        let want = replayed(&t);
        let opened = Session::open(&path).unwrap();
        assert_eq!(opened.recovered, 0);
        assert_eq!(dump_bytes(&opened.painting().tree), dump_bytes(&want.tree), "{name}");
        same_history(opened.painting(), &want);
        // The session reads back as a trace that replays to the same tree.
        let again = parse_trace(&opened.trace_text().unwrap()).unwrap();
        assert_eq!(again.events.len(), t.events.len());
        assert_eq!(dump_bytes(&replayed(&again).tree), dump_bytes(&want.tree), "{name}");
        // Undo and redo continue from the saved history exactly.
        let mut a = opened.painting().clone();
        let mut b = want.clone();
        while a.undo() {
            assert!(b.undo());
            assert_eq!(dump_bytes(&a.tree), dump_bytes(&b.tree));
        }
        assert!(!b.undo());
        while a.redo() {
            assert!(b.redo());
        }
        assert_eq!(dump_bytes(&a.tree), dump_bytes(&want.tree));
    }
}

#[test]
fn a_session_saved_after_every_stroke_holds_only_what_is_new_and_reads_back_whole() {
    // Each save deflates what is new onto the spilled stream; every saved
    // file opens as the replay of the events so far, and the session
    // holds no more trace in memory after a save than its unsaved events.
    let t = trace("undo_redo");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("painting.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    let mut saves = 0;
    for (k, ev) in t.events.iter().enumerate() {
        s.apply(ev).unwrap();
        if matches!(ev.kind, EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo) {
            s.save().unwrap();
            saves += 1;
            assert_eq!(s.trace_bytes(), 0, "after save {saves}");
            let opened = Session::open_read(&path).unwrap();
            assert_eq!(dump_bytes(&opened.painting().tree), dump_bytes(&replayed(&prefix(&t, k + 1)).tree), "save {saves}");
            assert_eq!(opened.trace_text().unwrap(), s.trace_text().unwrap(), "save {saves}");
        }
    }
    assert!(saves >= 4, "{saves}");
    assert_eq!(parse_trace(&s.trace_text().unwrap()).unwrap().events.len(), t.events.len());
    // The spill file goes with the session (on Linux it never has a name;
    // on Windows it is deleted when closed): the folder then holds the
    // document, its journal and its lock only.
    drop(s);
    let mut names: Vec<String> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["painting.octo", "painting.octo.journal", "painting.octo.lock"]);
}

fn small_document() -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let (mut s, path) = session_from(dir.path(), &trace("single_stamp"));
    s.save().unwrap();
    std::fs::read(path).unwrap()
}

#[test]
fn every_truncation_is_refused() {
    let data = small_document();
    assert!(format::read(&data).is_ok());
    for n in 0..data.len() {
        match format::read(&data[..n]) {
            Err(DocError::NotADocument) => assert!(n < 16),
            Err(DocError::Corrupt(m)) => assert!(n >= 12, "{n}: {m}"),
            Err(e) => panic!("{n}: unexpected {e}"),
            Ok(_) => panic!("a document cut at {n} of {} bytes was accepted", data.len()),
        }
    }
}

#[test]
fn damage_anywhere_is_refused() {
    let data = small_document();
    // Every byte, one bit flipped at a time (the low and high bit).
    for i in 0..data.len() {
        for bit in [0, 7] {
            let mut d = data.clone();
            d[i] ^= 1 << bit;
            let r = format::read(&d);
            assert!(r.is_err(), "flipping bit {bit} of byte {i} went unnoticed");
        }
    }
    // Extra bytes at the end.
    let mut d = data.clone();
    d.push(0);
    assert!(matches!(format::read(&d), Err(DocError::Corrupt(_))));
    // A text-mode transfer (\r\n -> \n).
    let mut d = data.clone();
    d.remove(12);
    match format::read(&d) {
        Err(DocError::Corrupt(m)) => assert!(m.contains("text-mode"), "{m}"),
        other => panic!("{:?}", other.err()),
    }
}

#[test]
fn a_newer_format_is_refused_with_a_message() {
    let mut d = small_document();
    // Version 4 that version 3 cannot read: bump both fields, fix the CRC.
    d[16..20].copy_from_slice(&4u32.to_le_bytes());
    d[20..24].copy_from_slice(&4u32.to_le_bytes());
    let crc = crc32(&d[..28]);
    d[28..32].copy_from_slice(&crc.to_le_bytes());
    let e = format::read(&d).err().expect("refused");
    assert!(matches!(e, DocError::TooNew { version: 4, reads: 3 }), "{e}");
    assert!(e.to_string().contains("newer octopaint"));
    assert!(format::read(b"not a document at all").is_err());
    assert_eq!(&MAGIC[..12], b"OCTOPAINTDOC");
}

fn crc32(b: &[u8]) -> u32 {
    // The same CRC-32 (IEEE) the format uses, bit by bit.
    let mut c = !0u32;
    for &x in b {
        c ^= u32::from(x);
        for _ in 0..8 {
            c = if c & 1 != 0 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}

#[test]
fn a_session_that_dies_keeps_its_completed_strokes() {
    let t = trace("shapes_modes");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    // Paint up to the middle of the 20th stroke, then "crash" (drop the
    // session without saving).
    let mut strokes = 0;
    let mut cut = 0;
    for (i, ev) in t.events.iter().enumerate() {
        if matches!(ev.kind, EventKind::StrokeBegin) {
            strokes += 1;
        }
        if strokes == 20 && matches!(ev.kind, EventKind::Sample(_)) {
            cut = i;
            break;
        }
        s.apply(ev).unwrap();
    }
    // The 19 strokes before it are complete.
    let last_end = t.events[..cut].iter().rposition(|e| matches!(e.kind, EventKind::StrokeEnd)).unwrap() + 1;
    drop(s);
    // A torn line at the end of the journal (a write cut by the crash).
    let jp = journal_path(&path);
    let mut j = std::fs::read(&jp).unwrap();
    j.extend_from_slice(b"{\"ev\": \"sample\", \"t\": 99, \"p\": [0.");
    std::fs::write(&jp, &j).unwrap();

    let opened = Session::open(&path).unwrap();
    assert_eq!(opened.recovered, 19);
    let want = replayed(&prefix(&t, last_end));
    assert_eq!(dump_bytes(&opened.painting().tree), dump_bytes(&want.tree));
    same_history(opened.painting(), &want);
    // Saving the recovered session makes it the document; the journal
    // starts again.
    let mut opened = opened;
    opened.save().unwrap();
    drop(opened);
    let again = Session::open(&path).unwrap();
    assert_eq!(again.recovered, 0);
    assert_eq!(dump_bytes(&again.painting().tree), dump_bytes(&want.tree));
    // And it continues: the rest of the trace gives the whole replay.
    let mut again = again;
    for ev in &t.events[last_end..] {
        again.apply(ev).unwrap();
    }
    assert_eq!(dump_bytes(&again.painting().tree), dump_bytes(&replayed(&t).tree));
}

#[test]
fn a_crash_between_save_and_new_journal_loses_nothing() {
    let t = trace("undo_redo");
    let dir = tempfile::tempdir().unwrap();
    let (mut s, path) = session_from(dir.path(), &t);
    let jp = journal_path(&path);
    let old_journal = std::fs::read(&jp).unwrap();
    s.save().unwrap();
    // As if the process died after renaming the document but before the
    // new journal replaced the old one.
    std::fs::write(&jp, &old_journal).unwrap();
    drop(s);
    let opened = Session::open(&path).unwrap();
    assert_eq!(opened.recovered, 0, "the document holds the journal's events already");
    assert_eq!(dump_bytes(&opened.painting().tree), dump_bytes(&replayed(&t).tree));
    // A journal that belongs to nothing here is refused, not applied.
    let other = tempfile::tempdir().unwrap();
    let (mut s2, p2) = session_from(other.path(), &trace("single_stamp"));
    s2.save().unwrap();
    let mut ev = t.events.iter().find(|e| matches!(e.kind, EventKind::Brush(_))).unwrap().clone();
    ev.t = 1e3;
    s2.apply(&ev).unwrap();
    std::fs::copy(&jp, journal_path(&p2)).unwrap();
    drop(s2);
    match Session::open(&p2) {
        Err(DocError::Journal { why, .. }) => assert!(why.contains("another version"), "{why}"),
        other => panic!("{:?}", other.err()),
    }
}

#[test]
fn a_bounded_undo_history_still_records_its_tree() {
    let t = trace("shapes_modes");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    s.undo_bytes = 200_000;
    for ev in &t.events {
        s.apply(ev).unwrap();
    }
    assert!(s.forgotten > 0);
    assert!(s.painting().history.bytes() <= 200_000 || s.painting().history.done.len() == 1);
    // Undo everything it still can, then more: the extra undos do nothing
    // and are not recorded, so the trace replays to this tree.
    let undo = octopaint_tree::trace::Event { line: 0, t: 1e6, kind: EventKind::Undo };
    for _ in 0..100 {
        s.apply(&undo).unwrap();
    }
    assert!(s.painting().history.done.is_empty());
    let recorded = parse_trace(&s.trace_text().unwrap()).unwrap();
    assert_eq!(dump_bytes(&replayed(&recorded).tree), dump_bytes(&s.painting().tree));
}

#[test]
fn refused_events_change_nothing() {
    let t = trace("single_stamp");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    let sample = t.events.iter().find(|e| matches!(e.kind, EventKind::Sample(_))).unwrap().clone();
    assert!(matches!(s.apply(&sample), Err(DocError::BadEvent(_))), "a sample outside a stroke");
    let begin = octopaint_tree::trace::Event { line: 0, t: 0.0, kind: EventKind::StrokeBegin };
    assert!(s.apply(&begin).is_err(), "a stroke before any brush");
    for ev in &t.events {
        if matches!(ev.kind, EventKind::StrokeEnd) {
            break;
        }
        s.apply(ev).unwrap();
    }
    let before = dump_bytes(&s.painting().tree);
    let mut nan = sample.clone();
    if let EventKind::Sample(ref mut p) = nan.kind {
        p.p[0] = f64::NAN;
    }
    assert!(s.apply(&nan).is_err());
    let mut back = sample.clone();
    back.t = -1.0;
    assert!(s.apply(&back).is_err(), "time going back");
    assert!(s.save().is_err(), "no save inside a stroke");
    assert_eq!(dump_bytes(&s.painting().tree), before);
    assert!(matches!(Session::create(&path, &t.canvas, &t.meta), Err(DocError::Exists(_))));
}

#[test]
fn a_step_naming_a_cell_twice_is_refused() {
    let doc = format::read(&small_document()).unwrap().doc;
    let format::Content::Tree { tree, history: kept } = &doc.content else { panic!("a one-tree document") };
    let mut history = kept.clone();
    let last = history.done.pop().expect("the stamp is one undo step");
    // The same changes, the first one listed twice (a record before and
    // after as the stroke left them, so nothing else is wrong).
    let mut step = octopaint_tree::history::UndoStep::new(last.n_before, last.n_after);
    let first = last.entries().next().expect("the stroke changed cells");
    step.push(first.0, first.1, first.2);
    for (c, b, a) in last.entries() {
        step.push(c, b, a);
    }
    history.done.push(step);
    let (data, _) = format::write(&doc.trace_text, tree, &history, &doc.meta).unwrap();
    match format::read(&data) {
        Err(DocError::Corrupt(m)) => assert!(m.contains(&format!("names cell {} twice", first.0)), "{m}"),
        other => panic!("accepted or refused for another reason: {:?}", other.err()),
    }
    // Written back whole, the same history opens.
    let (data, _) = format::write(&doc.trace_text, tree, kept, &doc.meta).unwrap();
    assert!(format::read(&data).is_ok());
}

/// A session of layers (spec 14), event by event, as `import` makes it.
fn layered_session(dir: &Path, t: &Trace) -> (Session, PathBuf) {
    let path = dir.join("layers.octo");
    let mut s = Session::create_layered(&path, &t.canvas, &t.meta).unwrap();
    for ev in &t.events {
        s.apply(ev).unwrap();
    }
    (s, path)
}

#[test]
fn a_document_of_layers_opens_as_its_replay_and_one_tree_ones_stay_version_1() {
    let dir = tempfile::tempdir().unwrap();
    let t = trace("layers");
    let (mut s, path) = layered_session(dir.path(), &t);
    s.save().unwrap();
    let data = std::fs::read(&path).unwrap();
    assert_eq!(&data[16..24], &[2, 0, 0, 0, 2, 0, 0, 0], "written as version 2, read by 2 and later");
    let (_, want) = octopaint_tree::replay::replay_document(&t, None, &mut Silent).unwrap();
    drop(s);
    let mut opened = Session::open(&path).unwrap();
    assert_eq!((opened.version, opened.recovered), (2, 0));
    assert_eq!(opened.doc.dump_bytes(), want.dump_bytes());
    assert_eq!(opened.doc.steps(), want.steps());
    // Its history goes on from the file: every step back, then forward.
    let mut replayed = want;
    let mut k = 0;
    while opened.doc.undo() {
        assert!(replayed.undo());
        assert_eq!(opened.doc.dump_bytes(), replayed.dump_bytes(), "after {} undos", k + 1);
        k += 1;
    }
    assert!(k > 10 && !replayed.undo());
    while opened.doc.redo() {
        assert!(replayed.redo());
    }
    assert_eq!(opened.doc.dump_bytes(), replayed.dump_bytes());
    // A one-tree session is still written as version 1 (older readers open it).
    let one = small_document();
    assert_eq!(&one[16..24], &[1, 0, 0, 0, 1, 0, 0, 0]);
}

#[test]
fn layer_events_are_journalled_and_recovered_and_refused_when_bad() {
    let dir = tempfile::tempdir().unwrap();
    let t = trace("layers");
    // Saved after the first stroke; the rest lives only in the journal.
    let cut = t.events.iter().position(|e| matches!(e.kind, EventKind::Layer(_))).unwrap();
    let (mut s, path) = layered_session(dir.path(), &prefix(&t, cut));
    s.save().unwrap();
    for ev in &t.events[cut..] {
        s.apply(ev).unwrap();
    }
    let want = s.doc.dump_bytes();
    drop(s); // a crash: nothing saved after the cut
    let opened = Session::open(&path).unwrap();
    assert!(opened.recovered > 5, "{}", opened.recovered);
    assert_eq!(opened.doc.dump_bytes(), want);
    // Refused, and nothing changes: an unknown layer, a locked merge, a
    // name taken; a layer event in a one-tree document.
    let mut s = opened;
    let last = s.last_time();
    let layer = |op: LayerOpKind, layer: Option<&str>, name: Option<&str>| Event {
        line: 0,
        t: last,
        kind: EventKind::Layer(LayerOp { layer: layer.map(String::from), name: name.map(String::from), ..LayerOp::new(op) }),
    };
    s.apply(&layer(LayerOpKind::Add, None, Some("sky"))).unwrap();
    let mid = s.doc.dump_bytes();
    for bad in [
        layer(LayerOpKind::Rename, Some("x"), Some("y")),
        layer(LayerOpKind::Rename, Some("sky"), Some("Layer 1")),
        layer(LayerOpKind::MergeDown, Some("detail copy"), None),
        layer(LayerOpKind::Delete, Some("nope"), None),
    ] {
        let e = s.apply(&bad).expect_err("refused");
        assert!(matches!(e, DocError::BadEvent(_)), "{e}");
        assert_eq!(s.doc.dump_bytes(), mid);
    }
    let one = dir.path().join("one.octo");
    let mut plain = Session::create(&one, &t.canvas, &t.meta).unwrap();
    assert!(matches!(plain.apply(&layer(LayerOpKind::Add, None, Some("sky"))), Err(DocError::BadEvent(_))));
}

#[test]
fn damage_anywhere_in_a_document_of_layers_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = concat!(
        r#"{"format": "ddo-trace", "version": 2, "canvas": {"roots": [1, 1, 1], "max_depth": 4, "root_size": 1.0, "capacity": 4096}}"#,
        "\n",
        r#"{"ev": "brush", "t": 0, "shape": "sphere", "mode": "paint", "radius": 0.2, "color": [1, 0, 0], "opacity": 1, "hardness": 0.5}"#,
        "\n",
        r#"{"ev": "stroke_begin", "t": 0}"#,
        "\n",
        r#"{"ev": "sample", "t": 0, "p": [0.5, 0.5, 0.5]}"#,
        "\n",
        r#"{"ev": "stroke_end", "t": 0}"#,
        "\n",
        r#"{"ev": "layer", "t": 0, "op": "add", "name": "top"}"#,
        "\n",
        r#"{"ev": "layer", "t": 0, "op": "duplicate", "layer": "Layer 1", "name": "copy"}"#,
        "\n",
        r#"{"ev": "layer", "t": 0, "op": "delete", "layer": "copy"}"#,
    );
    let t = parse_trace(text).unwrap();
    let (mut s, path) = layered_session(dir.path(), &t);
    s.save().unwrap();
    let data = std::fs::read(&path).unwrap();
    assert!(format::read(&data).is_ok());
    // Every byte, its low bit flipped (the CRCs catch every one).
    for i in 0..data.len() {
        let mut d = data.clone();
        d[i] ^= 1;
        assert!(format::read(&d).is_err(), "flipping byte {i} went unnoticed");
    }
    for n in (0..data.len()).step_by(101) {
        assert!(format::read(&data[..n]).is_err());
    }
}

#[test]
fn a_one_tree_document_takes_layers_once_upgraded() {
    let dir = tempfile::tempdir().unwrap();
    let t = trace("single_stamp");
    let (mut s, path) = session_from(dir.path(), &t);
    let before = dump_bytes(&s.painting().tree);
    s.upgrade_to_layers().unwrap();
    assert_eq!(s.version, 2);
    // Saved at once as a document of layers; the one tree is `Layer 1`.
    assert_eq!(&std::fs::read(&path).unwrap()[16..20], &[2, 0, 0, 0]);
    let last = s.last_time();
    let add = Event { line: 0, t: last, kind: EventKind::Layer(LayerOp { name: Some("top".into()), ..LayerOp::new(LayerOpKind::Add) }) };
    s.apply(&add).unwrap();
    drop(s);
    let opened = Session::open(&path).unwrap();
    assert_eq!((opened.version, opened.doc.len(), opened.recovered), (2, 2, 1));
    assert_eq!(dump_bytes(opened.doc.layer(0).tree()), before);
    assert_eq!(opened.doc.layer(1).name, "top");
    // Its session reads back as a version 2 trace that replays to it.
    let again = parse_trace(&opened.trace_text().unwrap()).unwrap();
    assert_eq!(again.version, 2);
    let (_, replayed) = octopaint_tree::replay::replay_document(&again, None, &mut Silent).unwrap();
    assert_eq!(replayed.dump_bytes(), opened.doc.dump_bytes());
}

#[test]
fn a_document_keeps_its_imports_and_refuses_any_change_to_them() {
    use octopaint_tree::voxels::VoxelSet;
    let dir = tempfile::tempdir().unwrap();
    let t = trace("single_stamp");
    let (mut s, path) = session_from(dir.path(), &t);
    let before = dump_bytes(&s.painting().tree);
    let vs = VoxelSet {
        depth: 4,
        ijk: (0..40u32).map(|i| [i % 8 + 4, i / 8 + 2, 5]).collect(),
        rgb: (0..40u8).map(|i| [i * 6, 200, 40]).collect(),
        sigma: (0..40).map(|i| 2.0 + i as f32).collect(),
    };
    s.import(&vs, Some("strip")).unwrap();
    let after = dump_bytes(&s.painting().tree);
    assert_ne!(before, after);
    let data = std::fs::read(&path).unwrap();
    assert_eq!(u32::from_le_bytes(data[16..20].try_into().unwrap()), format::IMPORTS_VERSION);
    // Opened again: the same tree, the import one undo step.
    drop(s);
    let mut again = Session::open(&path).unwrap();
    assert_eq!(dump_bytes(&again.painting().tree), after);
    assert_eq!(again.imports().len(), 1);
    assert!(again.trace_text().unwrap().contains("\"ev\":\"import\"") || again.trace_text().unwrap().contains("\"ev\": \"import\""));
    again.apply(&Event { line: 0, t: again.last_time(), kind: EventKind::Undo }).unwrap();
    assert_eq!(dump_bytes(&again.painting().tree), before);
    // A refused import (a voxel outside the canvas) changes nothing.
    let bad = VoxelSet { depth: 4, ijk: vec![[16, 0, 0]], rgb: vec![[1, 2, 3]], sigma: vec![1.0] };
    let saved = std::fs::read(&path).unwrap();
    assert!(again.import(&bad, None).is_err());
    assert_eq!(std::fs::read(&path).unwrap(), saved);
    // Every byte of the file with imports: its low bit flipped, caught.
    for i in (0..data.len()).step_by(3) {
        let mut d = data.clone();
        d[i] ^= 1;
        assert!(format::read(&d).is_err(), "flipping byte {i} went unnoticed");
    }
}

/// One writer at a time (docs/documents.md): a second session on a
/// document is refused before it reads anything while the first lives,
/// whatever the first has done; a reader reads what the writer journalled;
/// once the writer is gone (its session dropped, as a process that died
/// lets go of its lock) the next writer recovers every completed stroke.
#[test]
fn one_writer_at_a_time_and_readers_beside_it() {
    let t = trace("shapes_modes");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    // A second creator and a second writer are refused, naming the
    // document; nothing on disk changes.
    assert!(matches!(Session::create(&path, &t.canvas, &t.meta), Err(DocError::Exists(_))));
    let saved = std::fs::read(&path).unwrap();
    let refused = |e: Result<Session, DocError>| match e {
        Err(e @ DocError::Locked { .. }) => {
            let m = e.to_string();
            assert!(m.contains("p.octo") && m.contains("another Octopaint has this document open"), "{m}");
        }
        other => panic!("a second writer was not refused: {:?}", other.map(|s| s.event_count())),
    };
    refused(Session::open(&path));
    // Half the trace's strokes, journalled, then one stroke in progress.
    let ends: Vec<usize> = t.events.iter().enumerate().filter(|(_, e)| matches!(e.kind, EventKind::StrokeEnd)).map(|(i, _)| i).collect();
    let half = ends[ends.len() / 2];
    for ev in &t.events[..=half] {
        s.apply(ev).unwrap();
    }
    let begin = half + t.events[half + 1..].iter().position(|e| matches!(e.kind, EventKind::StrokeBegin)).unwrap() + 1;
    for ev in &t.events[half + 1..=begin + 1] {
        s.apply(ev).unwrap();
    }
    refused(Session::open(&path));
    assert_eq!(std::fs::read(&path).unwrap(), saved, "the refused writer changed the document");
    // A reader sees the saved document plus the completed strokes, and
    // writes nothing.
    let mut reader = Session::open_read(&path).unwrap();
    assert!(!reader.writable());
    let strokes = t.events[..=half].iter().filter(|e| matches!(e.kind, EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo | EventKind::Layer(_))).count();
    assert_eq!(reader.recovered, strokes);
    let upto = Trace { events: t.events[..=half].to_vec(), ..t.clone() };
    assert_eq!(dump_bytes(&reader.painting().tree), dump_bytes(&replayed(&upto).tree));
    assert!(matches!(reader.save(), Err(DocError::ReadOnly(_))));
    assert!(matches!(reader.apply(&Event { line: 0, t: reader.last_time(), kind: EventKind::Undo }), Err(DocError::ReadOnly(_))));
    assert_eq!(reader.recovered, strokes, "a refused write changed the reader");
    // The writer dies; the next writer recovers every completed stroke.
    drop(s);
    let next = Session::open(&path).unwrap();
    assert_eq!(next.recovered, strokes);
    assert_eq!(dump_bytes(&next.painting().tree), dump_bytes(&reader.painting().tree));
}

/// A journal append that fails (here: a full device, the journal pointed
/// at Linux's /dev/full, where every write is ENOSPC) is reported, keeps
/// the session's events, and leaves no torn line behind: once the disk
/// takes writes again the next stroke's flush writes the journal whole,
/// and reopening recovers every stroke. (A save whose journal step fails
/// after the document was replaced: conformance/tests/test_faults.py.)
#[cfg(target_os = "linux")]
#[test]
fn a_failed_journal_append_is_written_whole_by_the_next_flush() {
    let t = trace("shapes_modes");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let jp = journal_path(&path);
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    let ends: Vec<usize> = t.events.iter().enumerate().filter(|(_, e)| matches!(e.kind, EventKind::StrokeEnd)).map(|(i, _)| i).collect();
    assert!(ends.len() >= 4);
    // Two strokes journalled, then saved: the journal is a fresh header.
    for ev in &t.events[..=ends[1]] {
        s.apply(ev).unwrap();
    }
    s.save().unwrap();
    // The disk fills: the third stroke's end cannot be journalled.
    std::fs::remove_file(&jp).unwrap();
    std::os::unix::fs::symlink("/dev/full", &jp).unwrap();
    for ev in &t.events[ends[1] + 1..ends[2]] {
        s.apply(ev).unwrap();
    }
    match s.apply(&t.events[ends[2]]) {
        Err(DocError::Io { reason, .. }) => assert!(reason.contains("No space left"), "{reason}"),
        other => panic!("the failed append was not reported: {other:?}"),
    }
    // Room again; the fourth stroke's end writes the journal whole.
    std::fs::remove_file(&jp).unwrap();
    for ev in &t.events[ends[2] + 1..=ends[3]] {
        s.apply(ev).unwrap();
    }
    let text = std::fs::read_to_string(&jp).unwrap();
    assert_eq!(text.lines().filter(|l| l.contains("\"stroke_end\"")).count(), 2, "{text}");
    drop(s);
    let opened = Session::open(&path).unwrap();
    assert_eq!(
        opened.recovered,
        t.events[ends[1] + 1..=ends[3]].iter().filter(|e| matches!(e.kind, EventKind::StrokeEnd | EventKind::Undo | EventKind::Redo)).count()
    );
    let upto = Trace { events: t.events[..=ends[3]].to_vec(), ..t.clone() };
    assert_eq!(dump_bytes(&opened.painting().tree), dump_bytes(&replayed(&upto).tree));
}

/// A render or snapshot name is used once per kind in a session, as in any
/// trace: a second one is refused (changing nothing), so the saved
/// session always reads back. (Applied twice, a trace's snapshots once
/// made a document that could not be opened.)
#[test]
fn a_name_used_twice_is_refused_and_the_session_still_reads() {
    let t = trace("undo_redo");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.octo");
    let mut s = Session::create(&path, &t.canvas, &t.meta).unwrap();
    for ev in &t.events {
        s.apply(ev).unwrap();
    }
    let named: Vec<&Event> = t.events.iter().filter(|e| matches!(e.kind, EventKind::Render(_) | EventKind::Snapshot(_))).collect();
    assert!(!named.is_empty(), "the trace has renders or snapshots");
    let count = s.event_count();
    for ev in named {
        let again = Event { t: s.last_time(), ..ev.clone() };
        match s.apply(&again) {
            Err(DocError::BadEvent(m)) => assert!(m.contains("is already used by an earlier"), "{m}"),
            other => panic!("a name used twice was taken: {other:?}"),
        }
    }
    assert_eq!(s.event_count(), count);
    s.save().unwrap();
    drop(s);
    let opened = Session::open(&path).unwrap();
    assert_eq!(opened.event_count(), count);
    // The saved session reads back as a trace.
    assert!(parse_trace(&opened.trace_text().unwrap()).is_ok());
}
