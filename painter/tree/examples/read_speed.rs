//! How fast the trace reader reads a trace (docs/benchmarks.md, "Trace
//! reader"): the file is read once, then parsed and validated `N` times;
//! prints the best and the median time and the rate in MB/s and lines/s.
//!
//!     cargo run --release -p octopaint-tree --example read_speed -- traces/scene.jsonl 50

use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| "traces/scene.jsonl".into());
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(50).max(1);
    let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let lines = data.iter().filter(|&&b| b == b'\n').count();
    let mut times = Vec::with_capacity(n);
    let mut events = 0;
    for _ in 0..n {
        let t0 = Instant::now();
        let t = octopaint_tree::trace::parse_trace_bytes(&data).unwrap_or_else(|e| panic!("{path}: {e}"));
        times.push(t0.elapsed().as_secs_f64());
        events = t.events.len();
    }
    times.sort_by(f64::total_cmp);
    let (best, median) = (times[0], times[n / 2]);
    println!(
        "{path}: {} bytes, {lines} lines, {events} events; best {:.2} ms, median {:.2} ms over {n} reads; {:.1} MB/s, {:.0} lines/s (best)",
        data.len(),
        best * 1e3,
        median * 1e3,
        data.len() as f64 / best / 1e6,
        lines as f64 / best
    );
}
