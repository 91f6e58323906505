//! What handing a short parallel pass to a second thread costs
//! (docs/benchmarks.md, "How the core got here", the 11th step): `R` rounds of a serial
//! stretch of `GAP` microseconds followed by a pass of two tasks of `TASK`
//! microseconds each (a stroke's rhythm: serial allocation, then a
//! parallel batch), run three ways on two threads:
//! - serially, both tasks on the calling thread;
//! - with `rayon::join` on a pool of two threads (the caller a worker);
//! - with the painter core's team (`octopaint_tree::team::run`).
//!
//! Prints each way's time per round and the gain over serial.
//!
//!     cargo run --release -p octopaint-tree --example hand_off -- [TASK GAP R]
//!
//! (defaults 30 100 3000: a pass of a few thousand cells, as at r = 10.)

use std::hint::black_box;
use std::time::{Duration, Instant};

/// `n` rounds of arithmetic (a stand-in for a pass's work: a fixed amount
/// of work, not of time, so a thread pushed off its core takes longer).
fn busy(n: u64) -> u64 {
    let mut x = 1u64;
    for i in 0..n {
        x = black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(i));
    }
    x
}

/// Rounds of [`busy`] that take `d` on this thread (the best of 20 tries).
fn calibrate(d: Duration) -> u64 {
    let n = 1_000_000;
    let best = (0..20)
        .map(|_| {
            let t0 = Instant::now();
            busy(n);
            t0.elapsed()
        })
        .min()
        .expect("tries");
    (n as f64 * d.as_secs_f64() / best.as_secs_f64()).max(1.0) as u64
}

fn main() {
    let mut args = std::env::args().skip(1).map(|s| s.parse::<u64>().expect("numbers: TASK GAP R"));
    let task = Duration::from_micros(args.next().unwrap_or(30));
    let gap = Duration::from_micros(args.next().unwrap_or(100));
    let rounds = args.next().unwrap_or(3000).max(1) as u32;
    let (task_n, gap_n) = (calibrate(task), calibrate(gap));
    let per_round = |t: Duration| t.as_secs_f64() * 1e6 / f64::from(rounds);

    let t0 = Instant::now();
    for _ in 0..rounds {
        busy(gap_n);
        busy(task_n);
        busy(task_n);
    }
    let serial = per_round(t0.elapsed());

    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("pool");
    let rayon_join = pool.install(|| {
        let t0 = Instant::now();
        for _ in 0..rounds {
            busy(gap_n);
            rayon::join(|| busy(task_n), || busy(task_n));
        }
        per_round(t0.elapsed())
    });

    let team = pool.install(|| {
        let t0 = Instant::now();
        for _ in 0..rounds {
            busy(gap_n);
            octopaint_tree::team::run(2, 2, &|_| {
                busy(task_n);
            });
        }
        per_round(t0.elapsed())
    });

    let ideal = per_round((gap + task) * rounds);
    println!(
        "pass of 2 x {} us after {} us serial, {rounds} rounds, 2 threads: serial {serial:.1} us a round, rayon::join {rayon_join:.1} us ({:.2}x), team {team:.1} us ({:.2}x); ideal {ideal:.1} us ({:.2}x)",
        task.as_micros(),
        gap.as_micros(),
        serial / rayon_join,
        serial / team,
        serial / ideal,
    );
}
