//! Print the referee's floor parts for one trial (development probe).
use jointlab_tests::hidden::{self, referee, Family, Logging};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let truth = hidden::truth(&a[1]).unwrap();
    let fam: Vec<Family> = a[2].split('+').filter_map(Family::from_name).collect();
    let seed: u64 = a[3].parse().unwrap();
    let rho: f64 = a[4].parse().unwrap();
    let t = hidden::generate(truth.as_ref(), seed, &fam, rho, Logging::Zoh).unwrap();
    let r = &t.est;
    let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    let nq: Vec<f64> = r
        .position
        .iter()
        .zip(&r.position_true)
        .map(|(a, b)| a - b)
        .collect();
    println!(
        "cutoff {} dt {} J {} J2 {} spring {:?}",
        t.cutoff, r.dt, r.inertia, r.inertia_load, r.spring
    );
    println!(
        "input noise rms {:.3e}, encoder error rms {:.3e}",
        rms(&r.input_noise),
        rms(&nq)
    );
    let mut z = r.clone();
    z.position = z.position_true.clone();
    println!(
        "floor {:.3e}; input part {:.3e}",
        referee::floor(r, t.cutoff),
        referee::floor(&z, t.cutoff)
    );
    let mut q = r.clone();
    q.input_noise = vec![0.0; q.input_noise.len()];
    println!("encoder part {:.3e}", referee::floor(&q, t.cutoff));
}
