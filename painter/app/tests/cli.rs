//! The `octopaint` command as a user meets it: malformed traces are refused
//! on their line with the reader's message and exit status 2, writing nothing; a good
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
    let expected: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("expected.json")).unwrap()).unwrap();
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
        // One line naming the trace and the line traces/malformed/expected.json gives.
        let line = &expected[path.file_name().unwrap().to_str().unwrap()]["line"];
        let prefix = format!("octopaint: {}: line {line}: ", path.display());
        assert!(stderr.starts_with(&prefix) && stderr.lines().count() == 1, "{stderr}");
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
    assert!(stdout.contains("nan_sample.jsonl: line 4: not valid JSON: "), "{stdout}");
    // The canonical verdict is the spec's line and error kind.
    let res = octopaint().args(["check", "--canonical"]).arg(repo().join("traces/malformed/absurd_segment.jsonl")).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    assert!(String::from_utf8(res.stdout).unwrap().ends_with("\n[\"error\",5,\"budget\"]\n"));
}

#[test]
fn an_unwritable_output_folder_is_a_clear_error() {
    let scratch = tempfile::tempdir().unwrap();
    let blocker = scratch.path().join("file");
    std::fs::write(&blocker, b"not a folder").unwrap();
    let res = octopaint().arg("replay").arg(repo().join("traces/single_stamp.jsonl")).arg("--out").arg(blocker.join("sub")).output().unwrap();
    assert_eq!(res.status.code(), Some(1));
    let stderr = String::from_utf8(res.stderr).unwrap();
    assert!(stderr.contains("cannot write to"), "{stderr}");
    assert_eq!(std::fs::read(&blocker).unwrap(), b"not a folder");
}

/// `bench realtime --quick` on a short live stroke: every configuration
/// runs, every job gets a latency, the strategy runs get a corruption
/// figure, and the results file is complete JSON.
#[test]
fn bench_realtime_runs_and_writes_its_results() {
    let scratch = tempfile::tempdir().unwrap();
    let res = octopaint()
        .args(["bench", "realtime"])
        .arg(repo().join("traces/scene.jsonl"))
        .args(["--quick", "--samples", "12", "--size", "48x27", "--out"])
        .arg(scratch.path())
        .env("NODEVICE_SELECT", "1")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&res.stdout);
    assert!(res.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&res.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(scratch.path().join("results.json")).unwrap()).unwrap();
    let live = doc["live_jobs"].as_u64().unwrap();
    assert_eq!(live, 14, "begin, 12 samples, end");
    let runs = doc["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 5);
    for r in runs {
        assert_eq!(r["jobs"].as_u64(), Some(live), "{}", r["label"]);
        assert!(r["frames"].as_u64().unwrap() > 0);
        let lat = &r["latency_ms"];
        assert!(lat["p50"].as_f64().unwrap() > 0.0 && lat["p50"].as_f64() <= lat["max"].as_f64());
        assert!(r["staging_copies"].as_u64().unwrap() > 0);
        assert_eq!(r["frame_series"].as_array().unwrap().len() as u64, r["frames"].as_u64().unwrap());
        if r["group"] == "fig9_k4" {
            let c = &r["corruption"];
            assert_eq!(c["frames"], r["frames"]);
            assert!(c["corrupted"].as_u64().unwrap() <= c["frames"].as_u64().unwrap());
        } else {
            assert!(r["corruption"].is_null());
        }
    }
    // The grouped strategy never shows a partial batch.
    let grouped = runs.iter().find(|r| r["grouped"] == true && r["group"] == "fig9_k4").unwrap();
    assert_eq!(grouped["corruption"]["corrupted"].as_u64(), Some(0));
}

#[test]
fn bench_realtime_refuses_absurd_settings() {
    let scratch = tempfile::tempdir().unwrap();
    for args in [["--size", "0x10"], ["--size", "99999x10"], ["--size", "wide"], ["--hz", "NaN"], ["--stroke", "99"]] {
        let res = octopaint().args(["bench", "realtime"]).arg(repo().join("traces/scene.jsonl")).args(args).arg("--out").arg(scratch.path()).output().unwrap();
        assert_eq!(res.status.code(), Some(1), "{args:?}");
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert!(stderr.starts_with("octopaint: bench realtime: "), "{args:?}: {stderr}");
    }
    assert!(!scratch.path().join("results.json").exists());
}

/// Count the lines of a trace's text that end a stroke.
fn stroke_ends(text: &str) -> usize {
    text.lines().filter(|l| l.contains("\"stroke_end\"")).count()
}

/// Replay `trace_text` with a final snapshot and return the dump's bytes.
fn final_dump(trace_text: &str, scratch: &Path, name: &str) -> Vec<u8> {
    let path = scratch.join(format!("{name}.jsonl"));
    let mut text = trace_text.trim_end().to_string();
    text.push_str("\n{\"ev\": \"snapshot\", \"t\": 1e9, \"name\": \"end\"}\n");
    std::fs::write(&path, text).unwrap();
    let out = scratch.join(name);
    let res = octopaint().arg("replay").arg(&path).arg("--out").arg(&out).args(["--renderer", "none", "--quiet"]).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    std::fs::read(out.join("end.npz")).unwrap()
}

#[test]
fn a_session_killed_mid_stroke_recovers_every_completed_stroke() {
    use std::io::{BufRead, BufReader};
    let scratch = tempfile::tempdir().unwrap();
    let s = scratch.path();
    let input = repo().join("traces/shapes_modes.jsonl");
    let doc = s.join("art.octo");
    let res = octopaint().arg("new").arg(&doc).arg("--like").arg(&input).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    // A live session at an artist's pace, killed (SIGKILL: no cleanup of
    // any kind) once a dozen strokes are journalled.
    let mut child = octopaint()
        .arg("paint")
        .arg(&doc)
        .arg("--input")
        .arg(&input)
        .args(["--events-per-second", "150", "--no-save"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let mut journalled = 0;
    while journalled < 12 {
        let line = lines.next().expect("the session reports its strokes").unwrap();
        if line.ends_with("journalled") {
            journalled += 1;
        }
    }
    // While it paints: a reader reads the saved document and the journal's
    // strokes; a second writer is refused at once, writing nothing.
    let res = octopaint().arg("info").arg(&doc).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    assert!(String::from_utf8_lossy(&res.stdout).contains("recovered here"));
    let before = (std::fs::read(&doc).unwrap(), std::fs::read(doc.with_extension("octo.journal")).unwrap());
    let res = octopaint().arg("recover").arg(&doc).output().unwrap();
    assert_eq!(res.status.code(), Some(2), "{}", String::from_utf8_lossy(&res.stderr));
    assert!(String::from_utf8_lossy(&res.stderr).contains("another Octopaint has this document open"), "{}", String::from_utf8_lossy(&res.stderr));
    let after = std::fs::read(&doc).unwrap();
    assert_eq!(after, before.0, "the refused writer changed the document");
    let journal = std::fs::read(doc.with_extension("octo.journal")).unwrap();
    assert!(journal.starts_with(&before.1), "the refused writer changed the journal");
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(!status.success(), "killed, not finished");
    // Reopening recovers what the journal holds: at least the 12 reported;
    // the dead writer's lock went with it.
    let res = octopaint().arg("info").arg(&doc).output().unwrap();
    let info = String::from_utf8_lossy(&res.stdout);
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    assert!(info.contains("recovered here"), "{info}");
    let recorded = s.join("recorded.jsonl");
    let res = octopaint().arg("record").arg(&doc).arg("--out").arg(&recorded).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let recorded_text = std::fs::read_to_string(&recorded).unwrap();
    let k = stroke_ends(&recorded_text);
    assert!(k >= 12, "{k} strokes recovered");
    // They are the input's first k strokes: same tree as replaying them.
    let input_text = std::fs::read_to_string(&input).unwrap();
    let mut prefix = String::new();
    let mut ends = 0;
    for line in input_text.lines() {
        if ends == k {
            break;
        }
        prefix.push_str(line);
        prefix.push('\n');
        ends += usize::from(line.contains("\"stroke_end\""));
    }
    assert_eq!(final_dump(&recorded_text, s, "recovered"), final_dump(&prefix, s, "expected"));
    // `recover` saves them; the session then continues to the end, and the
    // document is the whole trace's replay.
    let res = octopaint().arg("recover").arg(&doc).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let res = octopaint().arg("info").arg(&doc).output().unwrap();
    assert!(String::from_utf8_lossy(&res.stdout).contains("nothing unsaved"));
    let rest: String = input_text.lines().skip(prefix.lines().count()).map(|l| format!("{l}\n")).collect();
    let rest_trace = s.join("rest.jsonl");
    std::fs::write(&rest_trace, format!("{}\n{rest}", input_text.lines().next().unwrap())).unwrap();
    let res = octopaint().arg("paint").arg(&doc).arg("--input").arg(&rest_trace).arg("--quiet").output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let res = octopaint().arg("record").arg(&doc).arg("--out").arg(&recorded).output().unwrap();
    assert!(res.status.success());
    let whole = std::fs::read_to_string(&recorded).unwrap();
    assert_eq!(final_dump(&whole, s, "whole"), final_dump(&input_text, s, "input"));
}

/// One writer per document, across processes (docs/documents.md, "One
/// writer at a time"): two painting sessions started together on one
/// document, as an artist who double-clicks twice starts them. One paints,
/// the other is refused at once (exit status 2, a message naming the
/// document), and the document holds exactly the strokes of one session.
/// The killed-writer case is
/// `a_session_killed_mid_stroke_recovers_every_completed_stroke` above.
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
                .stderr(std::process::Stdio::piped())
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
        let dump = |p: &std::path::PathBuf, name: &str| {
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

#[test]
fn damaged_documents_are_refused_and_left_alone() {
    let scratch = tempfile::tempdir().unwrap();
    let doc = scratch.path().join("d.octo");
    let res = octopaint().arg("import").arg(repo().join("traces/undo_redo.jsonl")).arg(&doc).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let good = std::fs::read(&doc).unwrap();
    for (what, bytes) in [
        ("truncated", good[..good.len() / 2].to_vec()),
        ("flipped", {
            let mut b = good.clone();
            let i = b.len() / 3;
            b[i] ^= 0x10;
            b
        }),
    ] {
        std::fs::write(&doc, &bytes).unwrap();
        for cmd in ["info", "recover"] {
            let res = octopaint().arg(cmd).arg(&doc).output().unwrap();
            assert_eq!(res.status.code(), Some(2), "{what} {cmd}");
            let err = String::from_utf8_lossy(&res.stderr);
            assert!(err.contains("the document is damaged"), "{what} {cmd}: {err}");
            assert_eq!(std::fs::read(&doc).unwrap(), bytes, "{what} {cmd} changed the file");
        }
    }
    // Undo and redo persist through saves.
    std::fs::write(&doc, &good).unwrap();
    let res = octopaint().arg("undo").arg(&doc).args(["--steps", "2"]).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let res = octopaint().arg("info").arg(&doc).output().unwrap();
    assert!(String::from_utf8_lossy(&res.stdout).contains("to redo"), "{}", String::from_utf8_lossy(&res.stdout));
    let res = octopaint().arg("redo").arg(&doc).args(["--steps", "2"]).output().unwrap();
    assert!(res.status.success());
    let rec = scratch.path().join("r.jsonl");
    assert!(octopaint().arg("record").arg(&doc).arg("--out").arg(&rec).status().unwrap().success());
    let input = std::fs::read_to_string(repo().join("traces/undo_redo.jsonl")).unwrap();
    assert_eq!(final_dump(&std::fs::read_to_string(&rec).unwrap(), scratch.path(), "a"), final_dump(&input, scratch.path(), "b"));
}

#[test]
fn without_an_openxr_runtime_xr_info_says_what_is_missing() {
    // No runtime here (CI has none; a machine with a headset would):
    // point the loader at a runtime manifest that does not exist.
    let scratch = tempfile::tempdir().unwrap();
    let res = octopaint().arg("xr-info").env("XR_RUNTIME_JSON", scratch.path().join("none.json")).output().unwrap();
    assert_eq!(res.status.code(), Some(3), "{}", String::from_utf8_lossy(&res.stderr));
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(err.contains("octopaint: no VR here: no OpenXR"), "{err}");
}

#[test]
fn bench_doc_prints_its_table() {
    let res = octopaint().args(["bench", "doc"]).arg(repo().join("traces/undo_redo.jsonl")).args(["--runs", "1"]).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
    let out = String::from_utf8_lossy(&res.stdout);
    assert!(out.contains("| document (tree, history, session; zlib, CRCs) |") && out.contains("| tree dump (.npz"), "{out}");
    assert!(out.contains("ratios, document / dump"), "{out}");
    let res = octopaint().args(["bench", "doc"]).arg(repo().join("traces/undo_redo.jsonl")).args(["--runs", "0"]).output().unwrap();
    assert_eq!(res.status.code(), Some(1));
}

#[test]
fn with_no_command_it_paints_on_the_default_document() {
    // What a double-click runs: the default document is made in
    // OCTOPAINT_HOME (a Documents folder otherwise), then VR is tried and,
    // with no runtime, the window; with no display that is a clear error
    // and the document is kept for the next start.
    let scratch = tempfile::tempdir().unwrap();
    let home = scratch.path().join("Art");
    for round in 0..2 {
        let res = octopaint()
            .env("OCTOPAINT_HOME", &home)
            .env("XR_RUNTIME_JSON", scratch.path().join("none.json"))
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(1), "{err}");
        assert_eq!(err.contains("created"), round == 0, "{err}");
        assert!(err.contains(&format!("painting on {}", home.join("painting.octo").display())), "{err}");
        assert!(err.contains("no VR here") && err.contains("opening the desktop window instead"), "{err}");
        assert!(err.contains("is there a display"), "{err}");
    }
    let res = octopaint().arg("info").arg(home.join("painting.octo")).output().unwrap();
    assert!(res.status.success(), "{}", String::from_utf8_lossy(&res.stderr));
}

#[test]
fn a_render_larger_than_the_gpu_binds_is_drawn_by_the_cpu_port() {
    // 6000 x 5800 pixels need 139 MB, above lavapipe's 128 MiB storage
    // binding (a trace may ask for up to 16384 a side): the GPU path used
    // to panic in wgpu's validation; now the CPU port draws that image.
    let scratch = tempfile::tempdir().unwrap();
    let trace = scratch.path().join("big.jsonl");
    std::fs::write(
        &trace,
        concat!(
            r#"{"format": "ddo-trace", "version": 1, "canvas": {"roots": [1, 1, 1], "max_depth": 6, "root_size": 1, "capacity": 4096}}"#,
            "\n",
            r#"{"ev": "camera", "t": 0, "eye": [0.5, 0.5, 3], "q": [0, 0, 0, 1], "fov": [-0.5, 0.5, 0.5, -0.5], "size": [6000, 5800]}"#,
            "\n",
            r#"{"ev": "render", "t": 0, "name": "big"}"#,
            "\n"
        ),
    )
    .unwrap();
    let out = scratch.path().join("out");
    let res = octopaint().arg("replay").arg(&trace).arg("--out").arg(&out).arg("--quiet").env("NODEVICE_SELECT", "1").output().unwrap();
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let info = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(out.join("big.png")).unwrap())).read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (6000, 5800));
    // Where the GPU could not bind it, the painter said who drew it.
    if err.contains("binds at most") {
        assert!(err.contains("drawn by the CPU port instead"), "{err}");
    }
}

/// A reader that stops early (`octopaint check --canonical TRACE | head`):
/// on Unix the painter ends quietly by SIGPIPE, with no panic message.
#[cfg(unix)]
#[test]
fn a_closed_standard_output_ends_the_painter_quietly() {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    let mut child = octopaint()
        .args(["check", "--canonical"])
        .arg(repo().join("traces/scene.jsonl"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Read one line's worth, then close the pipe: the scene's canonical
    // form (over a megabyte) cannot fit in the pipe's buffer.
    let mut first = [0u8; 64];
    child.stdout.as_mut().unwrap().read_exact(&mut first).unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.signal(), Some(13), "{:?} {stderr}", out.status);
}
