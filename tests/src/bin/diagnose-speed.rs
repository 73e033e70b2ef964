//! Speed of `diagnose` on N = 10⁵ samples with the full effect library (release build):
//!
//! ```sh
//! cargo run --release -p jointlab-tests --bin diagnose-speed
//! ```
//! Times the whole command path after loading: differentiation + parallel filtering, baseline
//! fit, shape search over every library effect, Wald tests, Holm, ambiguity check.

use std::time::Instant;

use hil_host::workbench::diagnose::{diagnose, Options};
use hil_host::workbench::model::Model;
use hil_host::workbench::refine;
use hil_host::workbench::residual::Prepared;
use jointlab_tests::hidden::long_record;

fn main() {
    let rec = long_record(42, 5);
    let n = rec.len();
    let mut best = f64::INFINITY;
    let mut verdict = String::new();
    let mut table = String::new();
    for _ in 0..3 {
        let t0 = Instant::now();
        let p = Prepared::new(&rec, jointlab_tests::hidden::cutoff());
        let mut m = Model::baseline();
        refine::refit_all(&mut m, &p).expect("fit");
        let d = diagnose(&m, &p, &Options::default());
        best = best.min(t0.elapsed().as_secs_f64());
        verdict = d.verdict.text.clone();
        table = d.to_text();
    }
    println!(
        "diagnose on N = {n} samples, {} library effects: {best:.3} s (best of 3)",
        sim_plant::effects::EffectKind::ALL.len()
    );
    if std::env::var_os("DIAGNOSE_TABLE").is_some() {
        println!("{table}");
    }
    println!("verdict: {verdict}");
    if best > 1.0 {
        println!("SLOWER than the 1 s budget");
        std::process::exit(1);
    }
}
