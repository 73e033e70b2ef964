//! Real-time factor: simulated seconds per second for each preset, one core, at the default
//! 10 kHz substep, driven the way the HIL plant node drives it (1 kHz `step` calls with a
//! changing torque command, sensors with noise read every step).
//!
//! The command (±1.5 N·m at 0.5 Hz plus a 7 Hz wobble, periodic in 2 s) is tabulated before
//! the clock starts: the HIL node receives its commands, it does not compute them, and two
//! libm `sin` calls per step cost about 16 instructions per substep — 5–8 % of the time, which
//! the figures would otherwise charge to the simulator. (Until the speed-up of the periodic
//! torques the bench computed them inside the timed loop; `insn_probe … sin` still does.)
//!
//! `cargo bench -p sim-plant --bench realtime` (release profile). The goal is ≥ 5000× real
//! time. On a shared machine a single timing is meaningless, so each figure is the best of
//! many short runs by the wall clock (short runs are likely to go uninterrupted), printed with
//! the mean over all runs of this thread's CPU time (`/proc/thread-self/schedstat`, the
//! kernel's per-thread run time in ns — the workspace forbids `unsafe`, so no
//! `clock_gettime(CLOCK_THREAD_CPUTIME_ID)`), also as CPU µs per simulated second, the figure
//! that least depends on what else the machine runs.
//!
//! For a figure independent of the machine altogether, count instructions per substep with
//! callgrind on `examples/insn_probe.rs` (same driving as here; see its docs).

use std::hint::black_box;
use std::time::Instant;

use sim_plant::plant::{Environment, Plant, PlantOptions};
use sim_plant::presets::preset_names;

/// Nanoseconds this thread has spent on a CPU (None where schedstat is unavailable).
fn thread_cpu_ns() -> Option<u64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// One period (2 s at 1 kHz) of the command: ±1.5 N·m at 0.5 Hz plus a 7 Hz wobble — sticks,
/// breaks away, reverses.
fn command_table() -> Vec<f64> {
    (0..2000)
        .map(|k| {
            let t = k as f64 * 1e-3;
            1.5 * (std::f64::consts::TAU * 0.5 * t).sin()
                + 0.2 * (std::f64::consts::TAU * 7.0 * t).sin()
        })
        .collect()
}

/// Wall seconds for one run of `secs` simulated seconds.
fn run_once(name: &str, env: Environment, secs: f64) -> f64 {
    let mut plant = Plant::from_preset(
        name,
        PlantOptions {
            environment: env,
            seed: 1,
            ..Default::default()
        },
    )
    .expect("preset builds");
    let steps = (secs * 1000.0) as usize;
    let commands = command_table();
    let start = Instant::now();
    let mut acc = 0i64;
    for k in 0..steps {
        let cmd = commands[k % commands.len()];
        let s = plant.step(black_box(cmd), 1e-3);
        acc = acc.wrapping_add(i64::from(s.motor_counts) + i64::from(s.torque_counts));
    }
    black_box(acc);
    start.elapsed().as_secs_f64()
}

/// (best wall-clock factor, CPU-time factor over all runs).
fn measure(name: &str, env: Environment, secs: f64, runs: usize) -> (f64, f64) {
    let cpu0 = thread_cpu_ns();
    let wall0 = Instant::now();
    let best = (0..runs)
        .map(|_| run_once(name, env, secs))
        .fold(f64::INFINITY, f64::min);
    let total = secs * runs as f64;
    let cpu = match (cpu0, thread_cpu_ns()) {
        (Some(a), Some(b)) if b > a => (b - a) as f64 * 1e-9,
        _ => wall0.elapsed().as_secs_f64(),
    };
    (secs / best, total / cpu)
}

fn main() {
    // `cargo bench` passes `--bench`; a name filter may follow. `cargo test --benches` runs
    // without `--bench` and only wants a quick smoke run.
    let args: Vec<String> = std::env::args().skip(1).collect();
    let full = args.iter().any(|a| a == "--bench");
    let filter = args.iter().find(|a| !a.starts_with('-')).cloned();
    let (secs, runs) = if full { (10.0, 25) } else { (0.2, 1) };
    println!("simulated seconds per second, one core, 10 kHz substeps, 1 kHz step() calls:");
    println!(
        "best of {runs} runs of {secs} s by wall clock [mean by this thread's CPU time; \
         CPU µs per simulated s]"
    );
    println!(
        "{:<20} {:>30} {:>30}",
        "preset", "free output", "spring Kf = 7.75e5"
    );
    for name in preset_names() {
        if filter.as_ref().is_some_and(|f| !name.contains(f.as_str())) {
            continue;
        }
        let (free, free_cpu) = measure(name, Environment::Free, secs, runs);
        let spring_env = Environment::Spring {
            stiffness: 7.75e5,
            damping: 50.0,
            rest: 0.0,
        };
        let (spring, spring_cpu) = measure(name, spring_env, secs, runs);
        println!(
            "{name:<20} {:>30} {:>30}",
            format!("{free:.0}× [{free_cpu:.0}×; {:.0} µs]", 1e6 / free_cpu),
            format!(
                "{spring:.0}× [{spring_cpu:.0}×; {:.0} µs]",
                1e6 / spring_cpu
            )
        );
    }
}
