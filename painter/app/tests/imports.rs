//! `octopaint import-vdb` and `import-mesh` on documents (docs/documents.md,
//! "Imports"): an export imported into a new layer, undone in one step,
//! recorded as a trace with its voxel sets beside it that replays to the
//! document's own layers; every refusal (a locked layer, a cell budget too
//! small, a mesh with a hole, a file that is not a VDB) leaves the document
//! byte for byte as it was.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn octopaint(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_octopaint"));
    for a in args {
        c.arg(a);
    }
    c.output().unwrap()
}

/// What it said (stdout then stderr), after checking it succeeded.
fn ok(o: &Output) -> String {
    let said = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    said
}

fn refused(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    err
}

fn cube_obj(lo: f64, hi: f64, drop_face: bool) -> String {
    let mut s = String::new();
    for k in 0..8 {
        let p = [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(|b| if b == 1 { hi } else { lo });
        s += &format!("v {} {} {} 0.2 0.6 0.9\n", p[0], p[1], p[2]);
    }
    let faces = [[1, 3, 4, 2], [5, 6, 8, 7], [1, 2, 6, 5], [3, 7, 8, 4], [1, 5, 7, 3], [2, 4, 8, 6]];
    for (i, f) in faces.iter().enumerate() {
        if !(drop_face && i == 0) {
            s += &format!("f {} {} {}\nf {} {} {}\n", f[0], f[1], f[2], f[0], f[2], f[3]);
        }
    }
    s
}

#[test]
fn an_export_imported_into_a_layer_is_one_step_and_records_as_a_trace() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let trace = repo().join("traces/shapes_modes.jsonl");
    let vdb = d.join("shapes.vdb");
    let doc = d.join("doc.octo");
    ok(&octopaint(&[&"export", &trace, &"--vdb", &vdb, &"--depth", &"7", &"--quiet"]));
    ok(&octopaint(&[&"new", &doc, &"--like", &trace]));
    let said = ok(&octopaint(&[&"import-vdb", &vdb, &doc, &"--layer", &"shapes"]));
    assert!(said.contains("at depth 7"), "{said}");
    let info = ok(&octopaint(&[&"info", &doc]));
    assert!(info.contains("\"shapes\""), "{info}");
    // A mesh into the same document, another layer.
    let obj = d.join("cube.obj");
    std::fs::write(&obj, cube_obj(0.1, 0.3, false)).unwrap();
    ok(&octopaint(&[&"import-mesh", &obj, &doc, &"--layer", &"cube", &"--depth", &"5"]));
    // Recorded: the voxel sets beside the trace, and both replayers agree
    // with the document's own dump.
    let rec = d.join("rec/session.jsonl");
    std::fs::create_dir_all(rec.parent().unwrap()).unwrap();
    ok(&octopaint(&[&"record", &doc, &"--out", &rec]));
    let imports: Vec<_> = std::fs::read_dir(d.join("rec/imports")).unwrap().collect();
    assert_eq!(imports.len(), 2);
    let text = std::fs::read_to_string(&rec).unwrap() + "{\"ev\": \"snapshot\", \"t\": 1e9, \"name\": \"end\"}\n";
    std::fs::write(&rec, text).unwrap();
    ok(&octopaint(&[&"replay", &rec, &"--out", &d.join("out")]));
    ok(&octopaint(&[&"dump", &doc, &d.join("doc.npz")]));
    let replayed = std::fs::read(d.join("out/end.npz")).unwrap();
    let dumped = std::fs::read(d.join("doc.npz")).unwrap();
    assert_eq!(replayed, dumped, "the recorded session replays to another document");
    // One undo takes the mesh away, the next the layer it went into.
    let before_undo = ok(&octopaint(&[&"info", &doc]));
    ok(&octopaint(&[&"undo", &doc]));
    let after = ok(&octopaint(&[&"info", &doc]));
    assert!(after.contains("\"cube\": 8 cells"), "{before_undo}\n{after}");
}

#[test]
fn refused_imports_leave_the_document_as_it_was() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let trace = repo().join("traces/single_stamp.jsonl");
    let vdb = d.join("stamp.vdb");
    ok(&octopaint(&[&"export", &trace, &"--vdb", &vdb, &"--quiet"]));
    // A document whose budget cannot hold the import.
    let small = d.join("small.octo");
    ok(&octopaint(&[&"new", &small, &"--roots", &"1,1,1", &"--max-depth", &"8", &"--root-size", &"1", &"--capacity", &"200", &"--layers"]));
    let bytes = std::fs::read(&small).unwrap();
    let err = refused(&octopaint(&[&"import-vdb", &vdb, &small]));
    assert!(err.contains("cell budget") && err.contains("unchanged"), "{err}");
    assert_eq!(std::fs::read(&small).unwrap(), bytes);
    // A locked layer.
    let doc = d.join("doc.octo");
    ok(&octopaint(&[&"new", &doc, &"--like", &trace, &"--layers"]));
    let layer = d.join("lock.jsonl");
    let head = std::fs::read_to_string(&trace).unwrap().lines().next().unwrap().replace("\"version\": 1", "\"version\": 2");
    std::fs::write(&layer, format!("{head}\n{{\"ev\": \"layer\", \"t\": 0, \"op\": \"set\", \"layer\": \"Layer 1\", \"locked\": true}}\n")).unwrap();
    ok(&octopaint(&[&"paint", &doc, &"--input", &layer]));
    let bytes = std::fs::read(&doc).unwrap();
    let err = refused(&octopaint(&[&"import-vdb", &vdb, &doc]));
    assert!(err.contains("locked"), "{err}");
    assert_eq!(std::fs::read(&doc).unwrap(), bytes);
    // A mesh with a hole, and a file that is not a VDB.
    let obj = d.join("open.obj");
    std::fs::write(&obj, cube_obj(0.1, 0.3, true)).unwrap();
    let err = refused(&octopaint(&[&"import-mesh", &obj, &doc, &"--layer", &"x"]));
    assert!(err.contains("boundary"), "{err}");
    let err = refused(&octopaint(&[&"import-vdb", &obj, &doc]));
    assert!(!err.is_empty());
    assert_eq!(std::fs::read(&doc).unwrap(), bytes);
}
