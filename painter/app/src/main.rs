//! `octopaint`: the painter's command line. Today: headless replay of traces
//! to tree dumps, trace validation, and the tree benchmark.

mod bench_tree;
mod canonical;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use octopaint_tree::paint::Painting;
use octopaint_tree::pool::CellRecord;
use octopaint_tree::replay::{ReplayObserver, replay};
use octopaint_tree::trace::{Event, EventKind, read_trace};

#[derive(Parser)]
#[command(name = "octopaint", version, about = "Octopaint, volumetric painting on a dynamic deep octree")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Replay a trace: write DIR/<name>.npz tree dumps at its snapshot events.
    ///
    /// The whole trace is validated first; a malformed trace is refused
    /// with a message naming its line and field, and nothing is written
    /// (exit status 2).
    Replay {
        /// A .jsonl trace (docs/spec.md section 12).
        trace: PathBuf,
        /// Output folder, created if missing.
        #[arg(long)]
        out: PathBuf,
        /// Print nothing but warnings and errors.
        #[arg(long)]
        quiet: bool,
        /// Print every change of this cell's record, event by event (the
        /// conformance report uses it to show a differing cell's history).
        #[arg(long, value_name = "CELL")]
        history: Option<u32>,
    },
    /// Validate traces without replaying them: print `PATH: ok` or
    /// `PATH: MESSAGE` for each (exit status 2 if any is malformed).
    Check {
        traces: Vec<PathBuf>,
        /// Print each trace as parsed, one canonical line per event (the
        /// conformance driver compares it with the reference reader's).
        #[arg(long)]
        canonical: bool,
    },
    /// Benchmarks that print figures (docs/benchmarks.md).
    Bench {
        #[command(subcommand)]
        which: Bench,
    },
}

#[derive(Subcommand)]
enum Bench {
    /// Stamping and refinement throughput on a deterministic stroke set.
    Tree(bench_tree::Args),
}

/// Prints warnings as they happen; shows progress on a terminal; records a
/// cell's history when asked.
struct Reporter<'a> {
    trace: &'a Path,
    bar: ProgressBar,
    history: Option<(u32, CellRecord)>,
}

impl ReplayObserver for Reporter<'_> {
    fn warning(&mut self, msg: &str) {
        self.bar.suspend(|| eprintln!("octopaint: warning: {}: {msg}", self.trace.display()));
    }

    fn after_event(&mut self, ev: &Event, painting: &Painting) {
        self.bar.inc(1);
        if let Some((cell, last)) = &mut self.history {
            let now = painting.tree.record(*cell);
            if !now.same_bits(last) {
                let kind = match &ev.kind {
                    EventKind::Brush(_) => "brush",
                    EventKind::StrokeBegin => "stroke_begin",
                    EventKind::Sample(_) => "sample",
                    EventKind::StrokeEnd => "stroke_end",
                    EventKind::Camera(_) => "camera",
                    EventKind::Render(_) => "render",
                    EventKind::Snapshot(_) => "snapshot",
                    EventKind::Undo => "undo",
                    EventKind::Redo => "redo",
                };
                println!(
                    "history: line {} {kind}: parent {} first_child {} depth {} rgb {:?} sigma {}",
                    ev.line,
                    now.parent,
                    now.first_child,
                    now.depth,
                    now.rgb,
                    octopaint_tree::pyrepr::py_float_repr(f64::from(now.sigma))
                );
                *last = now;
            }
        }
    }
}

fn cmd_replay(trace_path: &Path, out: &Path, quiet: bool, history: Option<u32>) -> ExitCode {
    let trace = match read_trace(trace_path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("octopaint: {}: {e}", trace_path.display());
            return ExitCode::from(2);
        }
    };
    let bar = ProgressBar::new(trace.events.len() as u64);
    bar.set_style(ProgressStyle::with_template("{spinner} replaying {pos}/{len} events [{elapsed_precise}] {wide_bar}").expect("static template"));
    if quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let mut rep = Reporter { trace: trace_path, bar, history: history.map(|c| (c, CellRecord::FREE)) };
    let result = replay(&trace, Some(out), &mut rep);
    rep.bar.finish_and_clear();
    let (stats, _) = match result {
        Ok(r) => r,
        Err(e) => {
            eprintln!("octopaint: {}: cannot write to {}: {}", trace_path.display(), out.display(), octopaint_tree::trace::io_reason(&e));
            return ExitCode::from(1);
        }
    };
    if !stats.renders.is_empty() {
        eprintln!(
            "octopaint: {} render event(s) not drawn: the GPU ray caster is not built yet",
            stats.renders.len()
        );
    }
    if !quiet {
        eprintln!(
            "replayed {} strokes, {} samples in {:.2} s: {} cells in use, deepest cell at depth {}",
            stats.strokes, stats.samples, stats.seconds, stats.cells, stats.deepest
        );
        for p in &stats.written {
            println!("{}", p.display());
        }
    }
    ExitCode::SUCCESS
}

fn cmd_check(traces: &[PathBuf], canonical: bool) -> ExitCode {
    let mut status = ExitCode::SUCCESS;
    for path in traces {
        let result = read_trace(path);
        if result.is_err() {
            status = ExitCode::from(2);
        }
        if canonical {
            println!("== {}", path.display());
            for line in canonical::canonical(&result) {
                println!("{line}");
            }
        } else {
            match result {
                Ok(_) => println!("{}: ok", path.display()),
                Err(e) => println!("{}: {e}", path.display()),
            }
        }
    }
    status
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Replay { trace, out, quiet, history } => cmd_replay(&trace, &out, quiet, history),
        Command::Check { traces, canonical } => cmd_check(&traces, canonical),
        Command::Bench { which: Bench::Tree(args) } => match bench_tree::run(&args) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("octopaint: bench tree: {e:#}");
                ExitCode::from(1)
            }
        },
    }
}
