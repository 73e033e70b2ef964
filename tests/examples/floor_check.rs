//! The workbench's noise-floor estimate against the referee's, on null trials of every truth
//! (development probe): ratio quartiles, and the null baseline's RMS over each.
use jointlab_tests::hidden::{self, Logging};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;

fn main() {
    for t in hidden::truths() {
        let mut r = Vec::new();
        for seed in 7_000_000..7_000_030u64 {
            let Ok(tr) = hidden::generate(t.as_ref(), seed, &[], 1.0, Logging::Zoh) else {
                continue;
            };
            let rec = hidden::recording(&tr.est, Logging::Zoh, false, "x");
            let p = Prepared::new(&rec, Some(tr.cutoff));
            let mut m = Model::baseline();
            refine::refit_all(&mut m, &p).unwrap();
            let wb = p.equation_floor(m.inertia.value);
            let rms = refine::score(&m, &p).rms;
            // Robust input-noise estimate: MAD of the second difference.
            let mut d2: Vec<f64> = rec
                .input
                .windows(3)
                .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
                .collect();
            d2.sort_by(f64::total_cmp);
            let mad = d2[d2.len() / 2] * 1.4826 / 6f64.sqrt();
            let gain = jointlab_workbench::diff::noise_gain(tr.cutoff, 1.0 / rec.dt);
            let robust = (mad * gain).hypot(p.encoder_floor(m.inertia.value));
            let true_u = {
                let n = &tr.est.input_noise;
                (n.iter().map(|v| v * v).sum::<f64>() / n.len() as f64).sqrt() * gain
            };
            eprintln!("    input: 2nd-diff {:.3e} MAD {:.3e} true {:.3e}; encoder {:.3e}; robust/ref {:.3}",
                p.noise_floor, mad * gain, true_u, p.encoder_floor(m.inertia.value), robust / tr.floor_est);
            r.push((wb / tr.floor_est, rms / tr.floor_est, rms / wb, tr.cond));
        }
        r.sort_by(|a, b| a.0.total_cmp(&b.0));
        println!("{}: {} nulls", t.name(), r.len());
        for (a, b, c, cond) in &r {
            println!(
                "  wb/ref {a:.3}  rms/ref {b:.3}  rms/wb {c:.3}   {:.0} Hz 2^{} {:?} noise {:.2}",
                1.0 / cond.dt,
                cond.counts_per_rev.log2(),
                cond.excitation,
                cond.noise
            );
        }
    }
}
