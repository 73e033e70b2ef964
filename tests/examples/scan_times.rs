//! Time each effect's shape scan in `diagnose` on a 12 k-sample record (development probe).
use std::time::Instant;

use jointlab_tests::hidden::long_record;
use jointlab_workbench::diagnose::scan_shape;
use jointlab_workbench::fit::{self, gram, gram_inverse};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::{self, Prepared};
use sim_plant::effects::{shape_grid, EffectKind};

fn main() {
    let rec = long_record(42, 12.0, 1);
    let t0 = Instant::now();
    let p = Prepared::new(&rec, None);
    println!("prepare {:.1} ms", 1e3 * t0.elapsed().as_secs_f64());
    let mut m = Model::baseline();
    let t0 = Instant::now();
    refine::refit_all(&mut m, &p).unwrap();
    println!("baseline refit {:.1} ms", 1e3 * t0.elapsed().as_secs_f64());
    let d = residual::design(&m, &p);
    let g0i = gram_inverse(&gram(&d.cols));
    let base = fit::least_squares(&d.cols, &d.y).unwrap();
    for k in EffectKind::ALL {
        let t0 = Instant::now();
        let r = scan_shape(k, &m, &p, &d.cols, &g0i, &base.residual, base.rss);
        println!(
            "{:<13} grid {:>4}  {:>7.1} ms  err {:?}",
            k.name(),
            shape_grid(k, &p.trajectory()).len(),
            1e3 * t0.elapsed().as_secs_f64(),
            r.map(|x| x.1)
        );
    }
    let x: Vec<f64> = p.position.clone();
    let t0 = Instant::now();
    for _ in 0..100 {
        std::hint::black_box(sim_plant::effects::signal::filtfilt(&x, 100.0, 1000.0));
    }
    println!("filtfilt 12k: {:.3} ms", 10.0 * t0.elapsed().as_secs_f64());
    let t = p.trajectory();
    let sh = sim_plant::effects::shape_grid(EffectKind::Ripple, &t)[10].clone();
    let t0 = Instant::now();
    for _ in 0..100 {
        std::hint::black_box(residual::candidate_columns_on(EffectKind::Ripple, &t, &sh));
    }
    println!(
        "ripple columns: {:.3} ms",
        10.0 * t0.elapsed().as_secs_f64()
    );
    let t0 = Instant::now();
    let refine = sim_plant::effects::refine_grid(EffectKind::Ripple, &t, &sh);
    println!("ripple refine grid {} shapes", refine.len());
    let _ = t0;
    let t0 = Instant::now();
    let dg = jointlab_workbench::diagnose::diagnose(&m, &p, &Default::default());
    println!(
        "diagnose {:.1} ms: {}",
        1e3 * t0.elapsed().as_secs_f64(),
        dg.verdict.text
    );
}

#[allow(dead_code)]
fn micro() {}
