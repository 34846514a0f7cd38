//! How long a rayon pool's idle threads take to join a parallel loop (issue 58): on one of the
//! pool's threads, a serial stretch (as a pipeline's bucketing sort or solve), then a loop of
//! one 50 µs unit a thread. All at once the loop takes one unit; on one thread, as many units
//! as there are threads. Prints, for serial stretches of 0 to 5 000 µs, the loop's median and
//! 90th-percentile length in units and how many units the other threads ran.
//!
//! With `--hover`, the other threads wait for work by polling the pool (`rayon::yield_now`)
//! instead of going to sleep: whether keeping them awake through a scan would help.
//!
//! `cargo run --release --example pool_wake -- [--threads 2] [--hover]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Loops timed after each serial stretch.
const LOOPS: usize = 200;
/// One unit of a loop's work.
const UNIT: Duration = Duration::from_micros(50);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let threads: usize = flags.parse_or("--threads", 2)?;
    let hover = flags.has("--hover");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    let done = Arc::new(AtomicBool::new(false));
    if hover {
        for _ in 1..threads {
            let done = done.clone();
            pool.spawn(move || {
                while !done.load(Ordering::Acquire) {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        std::hint::spin_loop();
                    }
                }
            });
        }
    }
    println!(
        "{threads} threads{}; a loop of {threads} units of {} µs after a serial stretch",
        if hover { ", the others hovering" } else { "" },
        UNIT.as_micros()
    );
    println!(
        "stretch µs  median units  p90 units  units run by the other threads (of {})",
        threads - 1
    );
    for stretch in [0u64, 5, 20, 50, 100, 200, 500, 1000, 5000] {
        let (mut lengths, mut elsewhere) = (Vec::with_capacity(LOOPS), 0);
        pool.install(|| {
            for _ in 0..LOOPS {
                busy(Duration::from_micros(stretch));
                let me = rayon::current_thread_index();
                let start = Instant::now();
                elsewhere += (0..threads)
                    .into_par_iter()
                    .map(|_| {
                        busy(UNIT);
                        usize::from(rayon::current_thread_index() != me)
                    })
                    .sum::<usize>();
                lengths.push(start.elapsed().as_secs_f64() / UNIT.as_secs_f64());
            }
        });
        lengths.sort_by(f64::total_cmp);
        println!(
            "{stretch:10} {:13.2} {:10.2} {:8.2}",
            lengths[LOOPS / 2],
            lengths[LOOPS * 9 / 10],
            elsewhere as f64 / LOOPS as f64
        );
    }
    done.store(true, Ordering::Release);
    Ok(())
}

/// Keeps this thread busy for `d`.
fn busy(d: Duration) {
    let start = Instant::now();
    while start.elapsed() < d {
        std::hint::spin_loop();
    }
}
