//! One writer per document, across processes (docs/documents.md, "One
//! writer at a time"): two painting sessions started together on one
//! document, as an artist who double-clicks twice starts them. One paints,
//! the other is refused at once (exit status 2, a message naming the
//! document), and the document holds exactly the strokes of one session.
//! The killed-writer case is in cli.rs
//! (`a_session_killed_mid_stroke_recovers_every_completed_stroke`).

use std::path::PathBuf;
use std::process::{Command, Stdio};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn octopaint() -> Command {
    Command::new(env!("CARGO_BIN_EXE_octopaint"))
}

#[test]
fn two_writers_started_together_one_is_refused_and_nothing_is_lost() {
    let scratch = tempfile::tempdir().unwrap();
    let s = scratch.path();
    let input = repo().join("traces/shapes_modes.jsonl");
    // What one session alone leaves: the trace imported.
    let alone = s.join("alone.octo");
    let res = octopaint().arg("import").arg(&input).arg(&alone).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    for round in 0..3 {
        let doc = s.join(format!("art{round}.octo"));
        let res = octopaint().arg("new").arg(&doc).arg("--like").arg(&input).output().unwrap();
        assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
        let start = || {
            octopaint()
                .arg("paint")
                .arg(&doc)
                .arg("--input")
                .arg(&input)
                .args(["--events-per-second", "400", "--quiet"])
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        };
        let (a, b) = (start(), start());
        let outcomes: Vec<(Option<i32>, String)> = [a, b]
            .into_iter()
            .map(|c| {
                let out = c.wait_with_output().unwrap();
                (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
            })
            .collect();
        let painted: Vec<_> = outcomes.iter().filter(|(code, _)| *code == Some(0)).collect();
        let refused: Vec<_> = outcomes.iter().filter(|(code, _)| *code == Some(2)).collect();
        assert_eq!((painted.len(), refused.len()), (1, 1), "round {round}: {outcomes:?}");
        let why = &refused[0].1;
        assert!(why.contains(&format!("art{round}.octo")) && why.contains("another Octopaint has this document open"), "{why}");
        assert!(!why.contains("recovered"), "the refused writer read the journal: {why}");
        // The document: one session's strokes, no more, no fewer.
        let dump = |p: &PathBuf, name: &str| {
            let out = s.join(name);
            let res = octopaint().arg("dump").arg(p).arg(&out).output().unwrap();
            assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
            std::fs::read(out).unwrap()
        };
        assert!(dump(&doc, "doc.npz") == dump(&alone, "alone.npz"), "round {round}: the document is not one session's painting");
        let info = octopaint().arg("info").arg(&doc).output().unwrap();
        assert!(String::from_utf8_lossy(&info.stdout).contains("nothing unsaved"));
    }
}
