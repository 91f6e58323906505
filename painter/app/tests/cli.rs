//! The `octopaint` command as a user meets it: malformed traces are refused
//! with the reader's message and exit status 2, writing nothing; a good
//! trace writes its dumps; `check` reports each trace.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn octopaint() -> Command {
    Command::new(env!("CARGO_BIN_EXE_octopaint"))
}

#[test]
fn malformed_traces_are_refused_and_nothing_is_written() {
    let dir = repo().join("traces/malformed");
    let expected = std::fs::read_to_string(dir.join("expected.json")).unwrap();
    let scratch = tempfile::tempdir().unwrap();
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "jsonl") {
            continue;
        }
        let out = scratch.path().join(path.file_stem().unwrap());
        let res = octopaint().arg("replay").arg(&path).arg("--out").arg(&out).output().unwrap();
        assert_eq!(res.status.code(), Some(2), "{}", path.display());
        let stderr = String::from_utf8(res.stderr).unwrap();
        let prefix = format!("octopaint: {}: line ", path.display());
        assert!(stderr.starts_with(&prefix), "{stderr}");
        // The message itself is the one traces/malformed/expected.json gives
        // (json escapes aside, which the reader's own test compares exactly).
        let message = stderr.trim_end().strip_prefix(&format!("octopaint: {}: ", path.display())).unwrap();
        if !message.contains('"') && !message.contains('\\') {
            assert!(expected.contains(message), "{message}");
        }
        assert!(!out.exists(), "{} created {}", path.display(), out.display());
        n += 1;
    }
    assert!(n >= 50);
}

#[test]
fn a_good_trace_writes_its_dumps_and_check_reports_ok() {
    let scratch = tempfile::tempdir().unwrap();
    let trace = repo().join("traces/undo_redo.jsonl");
    let res = octopaint().arg("replay").arg(&trace).arg("--out").arg(scratch.path()).arg("--quiet").output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let mut names: Vec<String> = std::fs::read_dir(scratch.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["undo_redo_a.npz", "undo_redo_b.npz", "undo_redo_branch.npz", "undo_redo_empty.npz", "undo_redo_redone.npz", "undo_redo_undone.npz"]);
    let a = std::fs::read(scratch.path().join("undo_redo_a.npz")).unwrap();
    assert_eq!(a, std::fs::read(scratch.path().join("undo_redo_undone.npz")).unwrap());
    let res = octopaint().arg("check").arg(&trace).arg(repo().join("traces/malformed/nan_sample.jsonl")).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    let stdout = String::from_utf8(res.stdout).unwrap();
    assert!(stdout.contains("undo_redo.jsonl: ok"), "{stdout}");
    assert!(stdout.contains("nan_sample.jsonl: line 4: p[0]: not a finite number"), "{stdout}");
}

#[test]
fn an_unwritable_output_folder_is_a_clear_error() {
    let scratch = tempfile::tempdir().unwrap();
    let blocker = scratch.path().join("file");
    std::fs::write(&blocker, b"not a folder").unwrap();
    let res = octopaint()
        .arg("replay")
        .arg(repo().join("traces/single_stamp.jsonl"))
        .arg("--out")
        .arg(blocker.join("sub"))
        .output()
        .unwrap();
    assert_eq!(res.status.code(), Some(1));
    let stderr = String::from_utf8(res.stderr).unwrap();
    assert!(stderr.contains("cannot write to"), "{stderr}");
    assert_eq!(std::fs::read(&blocker).unwrap(), b"not a folder");
}
