//! Where the substep time goes: the HD preset with effects removed one group at a time.
//! Best of 7 runs of 200 simulated seconds, this thread's CPU time (the machine may be shared;
//! the kernel accounts CPU time in ticks, so runs must be long).
//! `cargo run -p sim-plant --release --example cost_probe`

use std::hint::black_box;

use sim_plant::plant::{Plant, PlantOptions};
use sim_plant::presets::preset;

fn cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

fn time(m: &sim_plant::Model, label: &str) {
    let mut best = f64::INFINITY;
    for _ in 0..7 {
        let mut p = Plant::new(m, PlantOptions::default()).expect("model builds");
        let steps = 200_000;
        let c0 = cpu_ns();
        let mut acc = 0i64;
        for k in 0..steps {
            let t = k as f64 * 1e-3;
            let s = p.step(1.5 * (std::f64::consts::TAU * 0.5 * t).sin(), 1e-3);
            acc += i64::from(s.motor_counts);
        }
        black_box(acc);
        best = best.min((cpu_ns() - c0) as f64 / (steps as f64 * 10.0));
    }
    println!(
        "{label:<28} {best:>6.1} ns/substep  ({:>6.0}× real time)",
        1e5 / best
    );
}

fn main() {
    let full = preset("harmonic-drive-60").expect("preset");
    time(&full, "HD 60:1, all effects");
    let mut m = full.clone();
    m.effects.cogging = None;
    time(&m, "  without cogging");
    m.effects.ripple = None;
    time(&m, "  … and ripple");
    m.effects.stribeck = None;
    m.effects.asymmetry = None;
    time(&m, "  … and stribeck, asymmetry");
    m.effects.coulomb = None;
    time(&m, "  … and coulomb");
    m.effects.compliance = None;
    m.effects.viscous = None;
    time(&m, "rigid, no effects");
}
