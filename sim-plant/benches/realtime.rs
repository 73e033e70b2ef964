//! Real-time factor: simulated seconds per wall-clock second for each preset, one core, at
//! the default 10 kHz substep, driven like the HIL plant node drives it (1 kHz `step` calls
//! with a changing torque command, sensors read every step, noise on).
//!
//! `cargo bench -p sim-plant --bench realtime` (release profile). Prints one line per preset;
//! the goal is ≥ 5000× real time. The factor is computed from this thread's CPU time
//! (`/proc/thread-self/schedstat`, Linux) so that a busy shared machine does not distort it;
//! the wall-clock factor is printed beside it.

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

/// (CPU-time factor, wall-clock factor).
fn run(name: &str, env: Environment, secs: f64) -> (f64, f64) {
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
    let start = Instant::now();
    let cpu0 = thread_cpu_ns();
    let mut acc = 0i64;
    for k in 0..steps {
        let t = k as f64 * 1e-3;
        // ±1.5 N·m at 0.5 Hz plus a 7 Hz wobble: sticks, breaks away, reverses.
        let cmd = 1.5 * (std::f64::consts::TAU * 0.5 * t).sin()
            + 0.2 * (std::f64::consts::TAU * 7.0 * t).sin();
        let s = plant.step(black_box(cmd), 1e-3);
        acc = acc.wrapping_add(i64::from(s.motor_counts) + i64::from(s.torque_counts));
    }
    black_box(acc);
    let wall = start.elapsed().as_secs_f64();
    let cpu = match (cpu0, thread_cpu_ns()) {
        (Some(a), Some(b)) if b > a => (b - a) as f64 * 1e-9,
        _ => wall,
    };
    (secs / cpu, secs / wall)
}

fn main() {
    // `cargo bench` passes `--bench`; a name filter may follow. `cargo test --benches` passes
    // no `--bench` and expects a quick smoke run.
    let args: Vec<String> = std::env::args().skip(1).collect();
    let full = args.iter().any(|a| a == "--bench");
    let filter = args.iter().find(|a| !a.starts_with('-')).cloned();
    let secs = if full { 60.0 } else { 0.5 };
    println!("simulated seconds per second of one core's CPU time (wall clock in brackets),");
    println!("10 kHz substeps, 1 kHz step() calls, sensors with noise read every step");
    println!(
        "{:<20} {:>22} {:>22}",
        "preset", "free output", "spring Kf = 7.75e5"
    );
    for name in preset_names() {
        if filter.as_ref().is_some_and(|f| !name.contains(f.as_str())) {
            continue;
        }
        let (free, free_wall) = run(name, Environment::Free, secs);
        let (spring, spring_wall) = run(
            name,
            Environment::Spring {
                stiffness: 7.75e5,
                damping: 50.0,
                rest: 0.0,
            },
            secs,
        );
        println!(
            "{name:<20} {:>22} {:>22}",
            format!("{free:.0}× ({free_wall:.0}×)"),
            format!("{spring:.0}× ({spring_wall:.0}×)")
        );
    }
}
