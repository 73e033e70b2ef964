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
fn main() {
    let n = 20_000_000;
    let c0 = cpu_ns();
    let t = Instant::now();
    let mut x = 0.3f64;
    let mut acc = 0.0;
    for i in 0..n {
        let (s, c) = sim_plant::fastmath::sin_cos(x);
        acc += c;
        x = s * 1e-3 + i as f64 * 1e-4;
    }
    println!(
        "dependent fast: {:.2} ns ({:.2} wall) {acc}",
        (cpu_ns() - c0) as f64 / n as f64,
        t.elapsed().as_nanos() as f64 / n as f64
    );
    let c0 = cpu_ns();
    let mut x = 0.3f64;
    let mut acc = 0.0;
    for i in 0..n {
        let (s, c) = x.sin_cos();
        acc += c;
        x = s * 1e-3 + i as f64 * 1e-4;
    }
    println!(
        "dependent libm: {:.2} ns {acc}",
        (cpu_ns() - c0) as f64 / n as f64
    );
    let c0 = cpu_ns();
    let mut acc = 0.0;
    for i in 0..n {
        let (s, c) = sim_plant::fastmath::sin_cos(i as f64 * 1e-4);
        acc += c + s;
    }
    println!(
        "independent fast: {:.2} ns {acc}",
        (cpu_ns() - c0) as f64 / n as f64
    );
}
