//! The window as a front end of the real-time engine, under a real X
//! server (Xvfb): a trace played into it (`--play`) with the stroke thread
//! held at a gate (`--hold-painting`) while the window keeps presenting
//! frames; once released, the document it saves equals the trace replayed
//! into a document, layers included, and its recorded session replays to
//! the same document. A still window casts nothing new and draws no frame
//! while nothing changes. Needs `Xvfb` and `xdotool` (`make system`
//! installs them); without them the tests fail and say so.

#![cfg(unix)]

mod x11;

use std::path::Path;
use std::time::{Duration, Instant};

use x11::*;

fn traces() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../traces")
}

/// The frame log's rows (header checked).
fn frame_rows(log: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let mut lines = text.lines();
    if let Some(h) = lines.next() {
        assert_eq!(h, "t_ms,interval_ms,scale,width,height,still,mirror,cast,engine,prepare_ms");
    }
    lines.filter_map(|l| l.split(',').map(|v| v.parse().ok()).collect()).collect()
}

/// Whether two documents dump to the same bytes (`octopaint dump`, the
/// journal recovered), their dumps written into `dir`.
fn same_document(dir: &Path, a: &Path, b: &Path) -> bool {
    let dump = |doc: &Path| {
        let out = dir.join(format!("{}.npz", doc.file_stem().unwrap().to_string_lossy()));
        run_ok(octopaint().arg("dump").arg(doc).arg(&out));
        std::fs::read(&out).unwrap()
    };
    dump(a) == dump(b)
}

fn run_ok(c: &mut std::process::Command) -> String {
    let res = c.output().unwrap();
    assert!(res.status.success(), "{:?}: {}", c, String::from_utf8_lossy(&res.stderr));
    String::from_utf8_lossy(&res.stdout).to_string()
}

/// Play `trace` into a new document in the window with painting held, check
/// frames go on while held, release, and compare the saved document with
/// the trace replayed into a document.
fn play_held(trace: &str, layers: bool) {
    let (_x, display) = start_xvfb();
    let scratch = tempfile::tempdir().unwrap();
    let s = scratch.path();
    let runtime = runtime_folder(s);
    let trace = traces().join(trace);
    let doc = s.join("played.octo");
    let mut new = octopaint();
    new.arg("new").arg(&doc).arg("--like").arg(&trace);
    if layers {
        new.arg("--layers");
    }
    run_ok(&mut new);
    let hold = s.join("hold");
    std::fs::write(&hold, b"").unwrap();
    let log = s.join("frames.csv");
    let mut window = on_display(&display, &runtime)
        .arg("window")
        .arg(&doc)
        .args(["--size", "320x240", "--play"])
        .arg(&trace)
        .arg("--exit-after-play")
        .arg("--hold-painting")
        .arg(&hold)
        .arg("--frame-log")
        .arg(&log)
        .spawn()
        .unwrap();
    // Frames come while the stroke thread waits at its gate with the
    // trace's first jobs queued: the frame loop never waits for painting.
    wait_for("a first frame", Duration::from_secs(120), || !frame_rows(&log).is_empty());
    let held = frame_rows(&log).len();
    wait_for("frames while painting is held", Duration::from_secs(120), || frame_rows(&log).len() >= held + 20);
    assert!(window.try_wait().unwrap().is_none(), "the window closed while painting was held");
    std::fs::remove_file(&hold).unwrap();
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = window.try_wait().unwrap() {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(180), "the window did not close after playing");
        std::thread::sleep(Duration::from_millis(100));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(window.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{err}");
    assert!(err.contains("saved"), "{err}");
    // The saved document as the trace replayed into a document.
    let replayed = s.join("replayed.octo");
    run_ok(octopaint().arg("import").arg(&trace).arg(&replayed));
    assert!(same_document(s, &doc, &replayed), "the played document differs from the replayed trace");
    // The window's session, recorded, replays to the same document.
    let rec = s.join("rec.jsonl");
    run_ok(octopaint().arg("record").arg(&doc).arg("--out").arg(&rec));
    let again = s.join("again.octo");
    run_ok(octopaint().arg("import").arg(&rec).arg(&again));
    assert!(same_document(s, &doc, &again), "the recorded session replays to another document");
}

#[test]
fn a_trace_played_with_painting_held_keeps_frames_coming_and_saves_the_replay() {
    play_held("undo_redo.jsonl", false);
}

#[test]
fn a_trace_of_layers_played_into_the_window_saves_the_replay() {
    play_held("layers.jsonl", true);
}

#[test]
fn a_still_window_casts_nothing_new_and_draws_no_frame() {
    let (_x, display) = start_xvfb();
    let (scratch, runtime, doc) = scratch_with_document("still.octo");
    let log = scratch.path().join("frames.csv");
    let mut window = on_display(&display, &runtime).arg("window").arg(&doc).args(["--size", "400x300", "--frame-log"]).arg(&log).spawn().unwrap();
    let id = window_of(&mut window, &display, "the window");
    ready_for_keys(&display, &id, &log);
    // Orbit a little (moving frames, cast at a dynamic resolution), then
    // leave the mouse over the view.
    xdotool(&display, &["mousemove", "--window", &id, "300", "150", "mousedown", "3"]);
    for i in 1..=6 {
        xdotool(&display, &["mousemove", "--window", &id, &(300 + i * 6).to_string(), "150"]);
        std::thread::sleep(Duration::from_millis(30));
    }
    xdotool(&display, &["mouseup", "3"]);
    // Once the last frame is a still one, nothing more is drawn: count the
    // frames over two seconds of nothing happening.
    wait_for("a still frame", Duration::from_secs(60), || frame_rows(&log).last().is_some_and(|r| r[5] == 1.0));
    std::thread::sleep(Duration::from_millis(500));
    let before = frame_rows(&log).len();
    std::thread::sleep(Duration::from_secs(2));
    let after = frame_rows(&log).len();
    close_with_ctrl_q(&display, &mut window);
    assert!(after <= before + 1, "{} frames drawn while nothing changed", after - before);
    // Every still frame after a still frame of the same size casts nothing.
    let rows = frame_rows(&log);
    let mut reused = 0;
    for w in rows.windows(2) {
        let (prev, cur) = (&w[0], &w[1]);
        if cur[5] == 1.0 && prev[5] == 1.0 && prev[3..5] == cur[3..5] {
            assert_eq!(cur[7], 0.0, "a still frame cast again: {cur:?}");
            reused += 1;
        }
        if cur[5] == 0.0 {
            assert_eq!(cur[7], 1.0, "a moving frame did not cast: {cur:?}");
        }
    }
    let _ = reused;
    assert!(rows.iter().any(|r| r[5] == 1.0 && r[7] == 1.0), "the still view was cast at full size once");
}

#[test]
fn a_window_killed_mid_session_keeps_every_journalled_stroke() {
    // A trace of 35 strokes played at its pace, the window killed (SIGKILL)
    // once its journal holds a few completed strokes: the next open
    // recovers each of them, and the document is the trace cut after them.
    let (_x, display) = start_xvfb();
    let scratch = tempfile::tempdir().unwrap();
    let s = scratch.path();
    let runtime = runtime_folder(s);
    let trace = traces().join("shapes_modes.jsonl");
    let doc = s.join("killed.octo");
    run_ok(octopaint().arg("new").arg(&doc).arg("--like").arg(&trace));
    let journal = s.join("killed.octo.journal");
    let mut window = on_display(&display, &runtime).arg("window").arg(&doc).args(["--size", "320x240", "--play"]).arg(&trace).spawn().unwrap();
    let ended = || std::fs::read_to_string(&journal).map(|j| j.matches("\"stroke_end\"").count()).unwrap_or(0);
    wait_for("three strokes in the journal", Duration::from_secs(180), || ended() >= 3);
    window.kill().unwrap();
    window.wait().unwrap();
    let kept = ended();
    assert!((3..35).contains(&kept), "{kept} strokes journalled");
    // Every completed stroke comes back.
    let res = octopaint().arg("info").arg(&doc).output().unwrap();
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{err}");
    // The trace up to its kept-th stroke's end, imported: the same tree.
    let text = std::fs::read_to_string(&trace).unwrap();
    let mut cut = Vec::new();
    let mut n = 0;
    for line in text.lines() {
        cut.push(line);
        if line.contains("\"stroke_end\"") {
            n += 1;
            if n == kept {
                break;
            }
        }
    }
    let cut_trace = s.join("cut.jsonl");
    std::fs::write(&cut_trace, cut.join("\n") + "\n").unwrap();
    let replayed = s.join("cut.octo");
    run_ok(octopaint().arg("import").arg(&cut_trace).arg(&replayed));
    assert!(same_document(s, &doc, &replayed), "the recovered document is not the trace's first {kept} strokes");
}
