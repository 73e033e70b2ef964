//! Where the substep time goes: the HD preset with effects removed one group at a time.
use sim_plant::plant::{Plant, PlantOptions};
use sim_plant::presets::preset;
use std::time::Instant;
fn cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .map(|s| {
            s.split_whitespace()
                .next()
                .unwrap_or("0")
                .parse()
                .unwrap_or(0)
        })
        .unwrap_or(0)
}
fn time(m: &sim_plant::Model, label: &str) {
    let mut p = Plant::new(m, PlantOptions::default()).unwrap();
    let steps = 60_000;
    let c0 = cpu_ns();
    let t = Instant::now();
    let mut acc = 0i64;
    for k in 0..steps {
        let tt = k as f64 * 1e-3;
        let s = p.step(1.5 * (6.28 * 0.5 * tt).sin(), 1e-3);
        acc += s.motor_counts as i64;
    }
    let cpu = (cpu_ns() - c0) as f64;
    println!(
        "{label:<30} {:>6.1} ns/substep cpu ({:.1} wall) {}",
        cpu / (steps as f64 * 10.0),
        t.elapsed().as_nanos() as f64 / (steps as f64 * 10.0),
        acc % 2
    );
}
fn main() {
    let full = preset("harmonic-drive-60").unwrap();
    time(&full, "full");
    let mut m = full.clone();
    m.effects.cogging = None;
    time(&m, "no cogging");
    m.effects.ripple = None;
    time(&m, "no cogging, ripple");
    m.effects.stribeck = None;
    m.effects.asymmetry = None;
    time(&m, "…, stribeck, asym");
    m.effects.coulomb = None;
    time(&m, "…, coulomb");
    m.effects.compliance = None;
    m.effects.viscous = None;
    time(&m, "rigid, no effects");
}
