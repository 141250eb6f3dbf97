//! `hil-sim soak --scans N --seed S`: random valid plans through the board
//! core on the virtual clock; prints missed, late and out-of-window edges and
//! the worst timing errors.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use anyhow::Context;
use hil_sim::soak::{soak_scan, DeviceFaults, SoakTotals};
use protocol::limits::{ticks_to_ns, BoardLimits};

/// Options of `hil-sim soak`.
#[derive(clap::Args)]
pub struct Args {
    /// Number of random scans.
    #[arg(long, default_value_t = 10_000)]
    pub scans: u64,
    /// Seed of the plan and device-jitter generators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores); results do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Fault injection: every camera misses this trigger index in every scan
    /// (to see the checks catch it).
    #[arg(long)]
    pub camera_miss: Option<u64>,
    /// Fault injection: device latency jitter at this many times its
    /// profile's peak (1 = as specified).
    #[arg(long, default_value_t = 1)]
    pub jitter_scale: u64,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `hil-sim soak`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(args.scans)
    };
    let faults = DeviceFaults {
        camera_miss: args.camera_miss,
        jitter_scale: args.jitter_scale,
    };
    let injected = faults != DeviceFaults::NONE;
    let next = AtomicU64::new(0);
    let started = Instant::now();
    let totals = std::thread::scope(|scope| -> anyhow::Result<SoakTotals> {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| -> anyhow::Result<SoakTotals> {
                    let mut totals = SoakTotals::default();
                    loop {
                        // Batches of 256 keep the shared counter cold.
                        let first = next.fetch_add(256, Ordering::Relaxed);
                        if first >= args.scans {
                            return Ok(totals);
                        }
                        let last = (first + 256).min(args.scans);
                        for index in first..last {
                            let scan = soak_scan(args.seed, index, &faults)
                                .with_context(|| format!("scan {index} of seed {}", args.seed))?;
                            totals.merge(&scan);
                        }
                        bar.inc(last - first);
                    }
                })
            })
            .collect();
        let mut all = SoakTotals::default();
        for worker in workers {
            let part = worker
                .join()
                .map_err(|_| anyhow::anyhow!("a soak worker panicked"))??;
            all.merge(&part);
        }
        Ok(all)
    })?;
    bar.finish_and_clear();
    print_report(&args, threads, &totals, started.elapsed().as_secs_f64());
    let failed = totals.feedback_missing
        + totals.feedback_late
        + totals.feedback_unexpected
        + totals.output_mismatches
        + totals.out_of_window
        + totals.measured_out_of_window
        + totals.device_missed
        + (totals.scans - totals.done);
    if failed > 0 && !injected {
        anyhow::bail!("the soak found {failed} timing faults (see the table)");
    }
    Ok(())
}

fn print_report(args: &Args, threads: usize, t: &SoakTotals, seconds: f64) {
    let hz = BoardLimits::STM32G474.timer_clock_hz;
    let ns = |ticks: u64| ticks_to_ns(ticks, hz);
    println!(
        "hil-sim soak --scans {} --seed {}  ({threads} threads, {seconds:.1} s)",
        args.scans, args.seed
    );
    if let Some(k) = args.camera_miss {
        println!("injected: every camera misses trigger {k} of each scan");
    }
    if args.jitter_scale != 1 {
        println!(
            "injected: device jitter {} x its profile",
            args.jitter_scale
        );
    }
    println!(
        "scans                      {:>14}  (dual-head {}, head-only {}, 24-pattern multiplexed {}, flood {})",
        t.scans, t.by_kind[0], t.by_kind[1], t.by_kind[2], t.by_kind[3]
    );
    println!("scans done                 {:>14}", t.done);
    println!("output edges played        {:>14}", t.output_edges);
    println!(
        "output edges off-plan      {:>14}  (worst {} ticks = {} ns)",
        t.output_mismatches,
        t.worst_output_error_ticks,
        ns(t.worst_output_error_ticks)
    );
    println!("feedback edges expected    {:>14}", t.feedback_expected);
    println!("feedback edges missed      {:>14}", t.feedback_missing);
    println!("feedback edges late        {:>14}", t.feedback_late);
    println!("feedback edges unexpected  {:>14}", t.feedback_unexpected);
    println!(
        "worst feedback timing error{:>14} ns  ({} ticks; device latency jitter included)",
        ns(t.worst_feedback_error_ticks),
        t.worst_feedback_error_ticks
    );
    println!("triggers missed by devices {:>14}", t.device_missed);
    println!("patterns shown             {:>14}", t.patterns);
    println!("patterns out of window     {:>14}", t.out_of_window);
    println!(
        "board's own window check   {:>14}  patterns judged from captures, {} outside, {} unchecked",
        t.patterns_checked, t.measured_out_of_window, t.patterns_unchecked
    );
    println!("patterns inside < margin   {:>14}", t.inside_margin);
}
