//! Probe: the truth's friction on the bench's Stribeck trials — Coulomb level, stiction level,
//! their ratio and the Stribeck velocity — to set the refit's misses against the drawn shape.
//!
//! `cargo run --release -p jointlab-tests --example stribeck_draws -- [N]`
//!
//! One line per trial of `hidden-trials N` (seed 1: seeds 1 300 003 + i, target ρ cycling
//! 0.5, 1, 2, 4), with the measured ρ; `unstable` for a draw the bench skips. Replay a trial's
//! refit with `stribeck_probe SEED RHO` (`WB_ONLY=1`).

use jointlab_tests::hidden::{generate, Family};

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    let rhos = [0.5, 1.0, 2.0, 4.0];
    for (i, rho) in (0..n).zip(rhos.iter().cycle()) {
        let seed = 1_000_003 + 3 * 100_000 + i;
        match generate(seed, &[Family::Stribeck], *rho) {
            Some(t) => {
                let p = t.plant;
                println!(
                    "{seed} {rho} rho {:.2} fc {:.4e} fs {:.4e} ratio {:.2} vs {:.4} noise {:.3e}",
                    t.rho,
                    p.fc,
                    p.fs,
                    p.fs / p.fc,
                    p.vs,
                    t.noise_u
                );
            }
            None => println!("{seed} {rho} unstable"),
        }
    }
}
