//! How well the input's white-noise estimate (the diagnosis's input floor) measures the
//! *sensor* noise of the recorded input on hidden trials: the recorded command's k-th
//! difference, RMS and median-absolute-deviation forms, against the trial's true σ.
//!
//! ```sh
//! cargo run --release -p jointlab-tests --example noise_est
//! ```
//! On the trials the command's white content is 1.1–18× the sensor's noise at any order k:
//! the excitation's broadband dither and the PD's answer to encoder steps are real torque,
//! which the motion follows, and no difference of the command alone tells them from noise.
//! (Why the diagnosis cannot take the input noise a compliance column shares with the
//! residual off its ERR: see docs/workbench.md, *Status on main*.)

use jointlab_tests::hidden::{generate, Family};
fn diffk(x: &[f64], k: usize) -> Vec<f64> {
    let mut y = x.to_vec();
    for _ in 0..k {
        y = y.windows(2).map(|w| w[1] - w[0]).collect();
    }
    y
}
fn binom(n: u64, k: u64) -> f64 {
    (0..k).fold(1.0, |a, i| a * (n - i) as f64 / (i + 1) as f64)
}
fn main() {
    let fams = [
        ("stribeck", Family::Stribeck),
        ("compliance", Family::Compliance),
        ("coulomb", Family::Coulomb),
        ("backlash", Family::Backlash),
    ];
    for (name, f) in fams {
        for seed in [1, 2, 3, 4, 5, 6] {
            let base = match f {
                Family::Stribeck => 1300000,
                Family::Compliance => 1500000,
                Family::Backlash => 1400000,
                _ => 1200000,
            };
            let Some(t) = generate(base + seed, &[f], 2.0) else {
                continue;
            };
            let u = &t.est.input;
            let mut line = format!("{name} {seed}: truth {:.3e}", t.noise_u);
            for k in [2usize, 3, 4, 6] {
                let d = diffk(u, k);
                let c = binom(2 * k as u64, k as u64);
                let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64 / c).sqrt();
                let mut a: Vec<f64> = d.iter().map(|x| x.abs()).collect();
                a.sort_by(|x, y| x.total_cmp(y));
                let mad = a[a.len() / 2] / 0.674_489_75 / c.sqrt();
                line += &format!(
                    " | k{k} rms {:.2} mad {:.2}",
                    rms / t.noise_u,
                    mad / t.noise_u
                );
            }
            println!("{line}");
        }
    }
}
