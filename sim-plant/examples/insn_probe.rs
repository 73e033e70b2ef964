//! Instruction-count probe for callgrind: runs one preset the way the `realtime` bench drives
//! it (1 kHz `step` calls, 10 kHz substeps, sensors read every step) for a given number of
//! steps. Instructions per substep = difference of two runs / (Δsteps · 10):
//!
//! ```text
//! cargo build -p sim-plant --release --example insn_probe
//! valgrind --tool=callgrind --callgrind-out-file=/dev/null \
//!     target/release/examples/insn_probe harmonic-drive-60 free 2000
//! ```
//!
//! Arguments: preset name (default harmonic-drive-60), `free` or `spring` (default free),
//! steps (default 2000), and `sin` to compute the command by two libm `sin` calls every step
//! as the bench did before it tabulated the (2 s periodic) command: about 16 instructions per
//! substep more, which are the driver's, not the simulator's.

use std::hint::black_box;

use sim_plant::plant::{Environment, Plant, PlantOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("harmonic-drive-60", String::as_str);
    let environment = match args.get(1).map(String::as_str) {
        Some("spring") => Environment::Spring {
            stiffness: 7.75e5,
            damping: 50.0,
            rest: 0.0,
        },
        _ => Environment::Free,
    };
    let steps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(2000);
    let inline_sin = args.get(3).is_some_and(|s| s == "sin");
    let command = |k: usize| {
        let t = k as f64 * 1e-3;
        1.5 * (std::f64::consts::TAU * 0.5 * t).sin()
            + 0.2 * (std::f64::consts::TAU * 7.0 * t).sin()
    };
    let table: Vec<f64> = (0..2000).map(command).collect();
    let mut plant = Plant::from_preset(
        name,
        PlantOptions {
            environment,
            seed: 1,
            ..Default::default()
        },
    )
    .expect("preset builds");
    let mut acc = 0i64;
    for k in 0..steps {
        let cmd = if inline_sin {
            command(k)
        } else {
            table[k % table.len()]
        };
        let s = plant.step(black_box(cmd), 1e-3);
        acc = acc.wrapping_add(i64::from(s.motor_counts) + i64::from(s.torque_counts));
    }
    println!("{acc}");
}
