//! `octopaint fuzz-smoke SEEDS` (docs/documents.md,
//! "Fuzzing"): every fuzz target's body (the readers of outside bytes:
//! documents, journals, OpenVDB, glTF and GLB, OBJ, voxel sets, traces, and
//! traces replayed) run on its seed corpus and on a fixed number of
//! deterministic variants of it, on stable Rust, in the release build:
//! CI's short run of the targets. `make fuzz-long` runs the same targets
//! under libFuzzer (painter/fuzz), guided by coverage, for as long as asked.
//!
//! SEEDS holds one folder per target (conformance/fuzz_seeds.py writes
//! them). An input that panics is written to `--crashes` and counted; the
//! exit status is 1 if any did.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use octopaint_tree::fuzz_harness::mutate;

#[derive(clap::Args)]
pub struct Args {
    /// The seed corpora, a folder per target.
    pub seeds: PathBuf,
    /// Variants of the seeds run per target (besides the seeds).
    #[arg(long, default_value_t = 2000)]
    pub runs: u64,
    /// Where inputs that panicked are written.
    #[arg(long, value_name = "DIR")]
    pub crashes: Option<PathBuf>,
    /// Only these targets (default: all).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Write the empty document the journal target's inputs extend to
    /// FILE and stop (the seed script paints journals against it).
    #[arg(long, value_name = "FILE")]
    pub journal_base: Option<PathBuf>,
}

/// Every target: its name (its cargo-fuzz target and seed folder) and body.
pub const TARGETS: [(&str, fn(&[u8])); 9] = [
    ("trace_reader", |d| octopaint_tree::fuzz_harness::read(d)),
    ("replay", |d| {
        octopaint_tree::fuzz_harness::replay_bounded(d);
    }),
    ("voxels", octopaint_tree::fuzz_harness::voxels),
    ("document", octopaint_doc::fuzz_harness::document),
    ("journal", octopaint_doc::fuzz_harness::journal),
    ("vdb", octopaint_export::fuzz_harness::vdb),
    ("glb", |d| octopaint_export::fuzz_harness::mesh(d, "glb")),
    ("gltf", |d| octopaint_export::fuzz_harness::mesh(d, "gltf")),
    ("obj", |d| octopaint_export::fuzz_harness::mesh(d, "obj")),
];

fn seeds(dir: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_file()).collect();
    files.sort();
    files.iter().map(|p| std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))).collect()
}

pub fn run(a: &Args) -> ExitCode {
    if let Some(p) = &a.journal_base {
        return match octopaint_platform::durable::write(p, octopaint_doc::fuzz_harness::base()) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("octopaint: cannot write {}: {e}", p.display());
                ExitCode::from(1)
            }
        };
    }
    // A panic is what the run looks for: say which input, once, not the
    // default hook's backtrace per input.
    std::panic::set_hook(Box::new(|info| eprintln!("octopaint: fuzz-smoke: panic: {info}")));
    let mut failed = 0u64;
    for (name, body) in TARGETS {
        if !a.only.is_empty() && !a.only.iter().any(|o| o == name) {
            continue;
        }
        let corpus = match seeds(&a.seeds.join(name)) {
            Ok(c) if !c.is_empty() => c,
            Ok(_) => {
                eprintln!("octopaint: fuzz-smoke: {name}: no seeds in {}", a.seeds.join(name).display());
                return ExitCode::from(2);
            }
            Err(e) => {
                eprintln!("octopaint: fuzz-smoke: {name}: {e} (conformance/fuzz_seeds.py writes the seeds)");
                return ExitCode::from(2);
            }
        };
        let t0 = Instant::now();
        let mut panicked = 0u64;
        let inputs = corpus.iter().cloned().chain((0..a.runs).map(|n| mutate(&corpus[(n % corpus.len() as u64) as usize], &corpus, n)));
        let mut count = 0u64;
        for (k, input) in inputs.enumerate() {
            count += 1;
            if std::panic::catch_unwind(|| body(&input)).is_err() {
                panicked += 1;
                let at = a.crashes.as_ref().map(|d| d.join(format!("crash-{name}-{k}")));
                if let Some(p) = &at {
                    let _ = std::fs::create_dir_all(a.crashes.as_ref().expect("set"));
                    let _ = std::fs::write(p, &input);
                }
                eprintln!("octopaint: fuzz-smoke: {name}: input {k} panicked{}", at.map(|p| format!(" (written to {})", p.display())).unwrap_or_default());
            }
        }
        println!("{name:13} {} seeds, {count} inputs, {panicked} panics, {:.1} s", corpus.len(), t0.elapsed().as_secs_f64());
        failed += panicked;
    }
    if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS }
}
