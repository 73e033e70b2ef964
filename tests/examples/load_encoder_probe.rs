//! Probe: what the measured deflection δ = motor − load looks like with a load encoder.
//!
//! `cargo run --release -p jointlab-tests --example load_encoder_probe -- FAMILY SEED RHO [SEED RHO …]`
//! (FAMILY `null` for no hidden effect).
//!
//! For each trial (recorded with the load encoder): the histogram of the low-passed δ over
//! its measured extent (20 bins, % of samples), the share of samples in its central 40 %
//! (`backlash::shows_gap`), and the share of the transmitted torque's
//! energy (J2·ẍ₂ + b·ẋ₂ from the truth's parameters and the measured load) inside the
//! central half of the extent — what a gap model calls "free". `SERIES=est|val`: δ, the true
//! δ and the load torque every 100th sample; `RAW=val:FROM:TO`: raw encoder counts next to
//! the truth.

use hil_host::workbench::residual::Prepared;
use jointlab_tests::hidden::{cutoff, generate_with, probe_args, Family, TrialOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "load_encoder_probe FAMILY SEED RHO [SEED RHO …] (FAMILY `null`: no hidden effect)";
    let fam_name = args.first().map_or("", String::as_str);
    let fam = Family::ALL.iter().copied().find(|f| f.name() == fam_name);
    if fam.is_none() && fam_name != "null" {
        eprintln!("unknown family `{fam_name}`");
    }
    let trials = if fam.is_none() && fam_name != "null" {
        probe_args(&[], usage)
    } else {
        probe_args(args.get(1..).unwrap_or_default(), usage)
    };
    for (seed, rho) in trials {
        let opts = TrialOptions { load_encoder: true };
        let Some(t) = generate_with(seed, fam.as_slice(), rho, opts) else {
            println!("seed {seed}: unstable");
            continue;
        };
        for (name, rec) in [("est", &t.est), ("val", &t.val)] {
            let p = Prepared::new(rec, cutoff());
            let n = p.len();
            let d: Vec<f64> = (0..n).map(|i| p.position[i] - p.load_position[i]).collect();
            let mut s = d.clone();
            s.sort_by(f64::total_cmp);
            let (lo, hi) = (s[n / 100], s[99 * n / 100]);
            let c = 0.5 * (lo + hi);
            let half = 0.5 * (hi - lo);
            let mut h = [0usize; 20];
            for x in &d {
                let k = (((x - c) / half + 1.0) * 10.0).floor().clamp(0.0, 19.0) as usize;
                h[k] += 1;
            }
            let dt = p.dt;
            let pl = &t.plant;
            let torque: Vec<f64> = (1..n - 1)
                .map(|i| {
                    let x = &p.load_position;
                    let a = (x[i + 1] - 2.0 * x[i] + x[i - 1]) / (dt * dt);
                    let v = (x[i + 1] - x[i - 1]) / (2.0 * dt);
                    pl.j2 * a + pl.b_pos * v
                })
                .collect();
            let (mut inside, mut all) = (0.0, 0.0);
            for (i, tq) in torque.iter().enumerate() {
                all += tq * tq;
                if (d[i + 1] - c).abs() < 0.5 * half {
                    inside += tq * tq;
                }
            }
            let counts = 2.0 * half / (std::f64::consts::TAU / 65536.0);
            let hs: Vec<String> = h
                .iter()
                .map(|k| format!("{:.0}", 100.0 * *k as f64 / n as f64))
                .collect();
            // RAW=val:11000:12500 — raw encoder counts and the truth, every 50th sample.
            let raw = std::env::var("RAW").unwrap_or_default();
            let mut it = raw.split(':');
            if it.next() == Some(name) {
                let from: usize = it.next().and_then(|x| x.parse().ok()).unwrap_or(0);
                let to: usize = it.next().and_then(|x| x.parse().ok()).unwrap_or(rec.len());
                let enc = std::f64::consts::TAU / 65536.0;
                let k = usize::from(name == "val");
                let lo = rec.load_output.as_ref().expect("load");
                for i in (from..to.min(rec.len())).step_by(50) {
                    println!(
                        "{i:6} x1 enc {:10.1} true {:10.1}  x2 enc {:10.1} true {:10.1} (counts)",
                        rec.output[i] / enc,
                        t.motor[k][i] / enc,
                        lo[i] / enc,
                        t.load[k][i] / enc
                    );
                }
            }
            if std::env::var("SERIES").ok().as_deref() == Some(name) {
                // Every 100th sample: δ in counts from the centre, the measured load torque.
                let enc = std::f64::consts::TAU / 65536.0;
                let k = usize::from(name == "val");
                let o = p.raw_offset;
                for i in (1..n - 1).step_by(100) {
                    println!(
                        "{i:6} δ {:7.2} true δ/half {:6.2} T {:9.4} v {:8.3}",
                        (d[i] - c) / enc,
                        (t.motor[k][o + i] - t.load[k][o + i]) / (0.5 * t.plant.backlash),
                        torque[i - 1],
                        p.velocity[i]
                    );
                }
            }
            let centre = d.iter().filter(|x| (*x - c).abs() < 0.4 * half).count() as f64 / n as f64;
            println!(
                "{} seed {seed} {name}: ρ {:.2} extent {:.1} counts, central 40 %: {:.1} % of samples, torque energy inside ½: {:.1} %, hist {}",
                fam.map_or("null", |f| f.name()),
                t.rho,
                counts,
                100.0 * centre,
                100.0 * inside / all,
                hs.join(" ")
            );
        }
    }
}
