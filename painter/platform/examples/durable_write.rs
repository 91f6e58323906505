//! Durable writes with and without early writeback, in one process.
//!
//!     cargo run --release --locked -p octopaint-platform --example durable_write -- [DIR] [MiB ...]
//!
//! For each size (default 40 and 400 MiB), writes the same bytes to
//! `DIR/durable-write.bin` (default: the system's temporary folder) in
//! turns, `RUNS` times each (default 5):
//! - **plain**: what `durable::write` did before it started writeback as it
//!   goes: a temporary file beside the target, one `write_all` through a 1 MiB
//!   buffer, `fsync`, rename, `fsync` of the folder;
//! - **durable**: `octopaint_platform::durable::write`, the same steps with
//!   writeback started every 4 MiB (Linux).
//!
//! Prints the medians and their ratio (docs/benchmarks.md, "Durable writes").

use std::io::Write;
use std::path::Path;
use std::time::Instant;

fn plain(path: &Path, data: &[u8]) -> std::io::Result<()> {
    let dir = octopaint_platform::durable::folder_of(path);
    let (file, tmp) = tempfile::Builder::new().prefix(".tmp-").tempfile_in(dir)?.into_parts();
    let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
    w.write_all(data)?;
    let file = w.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()?;
    drop(file);
    tmp.persist(path).map_err(|e| e.error)?;
    octopaint_platform::durable::sync_new_entry(path)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> std::io::Result<()> {
    let mut args = std::env::args().skip(1).peekable();
    let dir = match args.peek() {
        Some(a) if a.parse::<u64>().is_err() => std::path::PathBuf::from(args.next().unwrap_or_default()),
        _ => std::env::temp_dir(),
    };
    let sizes: Vec<u64> = args.map(|a| a.parse().expect("sizes in MiB")).collect();
    let sizes = if sizes.is_empty() { vec![40, 400] } else { sizes };
    let runs: usize = std::env::var("RUNS").ok().and_then(|r| r.parse().ok()).unwrap_or(5).max(1);
    let path = dir.join("durable-write.bin");
    println!("folder {}, {runs} runs each, in turns", dir.display());
    println!("| MiB | plain (s) | durable (s) | plain / durable |");
    println!("| ---: | ---: | ---: | ---: |");
    for mib in sizes {
        // Bytes that do not compress or repeat page by page.
        let data: Vec<u8> = (0..mib << 20).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..runs {
            let t = Instant::now();
            plain(&path, &data)?;
            a.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            octopaint_platform::durable::write(&path, &data)?;
            b.push(t.elapsed().as_secs_f64());
        }
        assert!(std::fs::read(&path)? == data, "the file read back differs");
        let (a, b) = (median(a), median(b));
        println!("| {mib} | {a:.3} | {b:.3} | {:.2}x |", a / b);
    }
    std::fs::remove_file(&path)
}
