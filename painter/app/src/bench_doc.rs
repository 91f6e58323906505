//! `octopaint bench doc`: saving and opening a document against writing and
//! reading the same tree as a dump (.npz, uncompressed, no history, no
//! session), in the same process (docs/benchmarks.md, "Documents").
//!
//! The trace is replayed into a document session (each stroke journalled
//! with fdatasync, as a live session does), then `--runs` times each
//! (median printed): the document's encoding (zlib and CRCs) and its atomic
//! save (temporary file, fsync, rename, folder fsync), its decoding with
//! every check (trace reader, tree checks, history checks), and the peer:
//! the tree dump's bytes and the same atomic write.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use crate::bench_gpu::median;
use octopaint_doc::Session;
use octopaint_doc::format;
use octopaint_platform::durable;
use octopaint_tree::trace::{EventKind, read_trace};

#[derive(clap::Args)]
pub struct Args {
    /// The trace whose session becomes the document.
    trace: PathBuf,
    /// Runs per figure (the median is printed).
    #[arg(long, default_value_t = 5)]
    runs: usize,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    anyhow::ensure!((1..=100).contains(&a.runs), "--runs must be 1 to 100");
    let trace = read_trace(&a.trace).map_err(|e| anyhow::anyhow!("{}: {e}", a.trace.display()))?;
    let dir = tempfile::tempdir().context("a scratch folder")?;
    let path = dir.path().join("bench.octo");
    let t = Instant::now();
    let mut s = Session::create(&path, &trace.canvas, &trace.meta).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut strokes = 0;
    for ev in &trace.events {
        s.apply(ev).map_err(|e| anyhow::anyhow!("{e}"))?;
        strokes += usize::from(matches!(ev.kind, EventKind::StrokeEnd));
    }
    let session_s = t.elapsed().as_secs_f64();
    let text = s.trace_text().map_err(|e| anyhow::anyhow!("{e}"))?;
    let (tree, history) = (&s.painting().tree, &s.painting().history);
    let (mut enc, mut save, mut dec, mut dump, mut dump_save, mut dump_read) = (vec![], vec![], vec![], vec![], vec![], vec![]);
    let (mut doc_bytes, mut dump_bytes) = (0, 0);
    let peer = dir.path().join("bench.npz");
    for _ in 0..a.runs {
        let t = Instant::now();
        let (bytes, _) = format::write(text.trim_end(), tree, history, "{}").context("encoding")?;
        enc.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        durable::write(&path, &bytes).context("saving")?;
        save.push(t.elapsed().as_secs_f64());
        doc_bytes = bytes.len();
        let t = Instant::now();
        let data = std::fs::read(&path).context("reading")?;
        let loaded = format::read(&data).map_err(|e| anyhow::anyhow!("{e}"))?;
        dec.push(t.elapsed().as_secs_f64());
        let same = matches!(&loaded.doc.content, octopaint_doc::format::Content::Tree { tree: t, .. } if t.n_used() == tree.n_used());
        anyhow::ensure!(same, "the document read back differs");
        let t = Instant::now();
        let npz = octopaint_tree::dump::dump_bytes(tree);
        dump.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        durable::write(&peer, &npz).context("writing the dump")?;
        dump_save.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let back = std::fs::read(&peer).context("reading the dump")?;
        dump_read.push(t.elapsed().as_secs_f64());
        dump_bytes = back.len();
    }
    let (enc, save, dec, dump, dump_save, dump_read) = (median(enc), median(save), median(dec), median(dump), median(dump_save), median(dump_read));
    println!(
        "{}: {} events, {} strokes, {} cells, undo history {:.1} MiB",
        a.trace.display(),
        trace.events.len(),
        strokes,
        tree.n_used(),
        history.bytes() as f64 / 1048576.0
    );
    println!("live session (paint + journal, fdatasync per stroke): {session_s:.2} s");
    println!("| | encode s | write (atomic) s | read + check s | MiB |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    println!("| document (tree, history, session; zlib, CRCs) | {enc:.3} | {save:.3} | {dec:.3} | {:.1} |", doc_bytes as f64 / 1048576.0);
    println!("| tree dump (.npz, tree only, stored) | {dump:.3} | {dump_save:.3} | {dump_read:.3} (read only) | {:.1} |", dump_bytes as f64 / 1048576.0);
    println!(
        "ratios, document / dump: save {:.2}x the time, {:.2}x the bytes (the document also holds the undo history and the session)",
        (enc + save) / (dump + dump_save).max(1e-9),
        doc_bytes as f64 / dump_bytes.max(1) as f64
    );
    Ok(())
}
