//! Velocity estimation figures at the thesis's 2304 cpr and at a fine 2²⁰ cpr encoder
//! (`cargo test -p controller --test sensing_velocity -- --nocapture` prints the tables).
//!
//! Note the discrete α-β loop needs α = 2ζωT < 2: with ζ = 1 at 1 kHz the bandwidth is
//! limited to < 318 Hz (`units::observer_config` refuses more).
//!
//! The encoder is simulated exactly: a raw wrapping 32-bit count `floor(θ·cpr/2π)` with a
//! random phase, fed through `Unwrapper` → estimator at 1 kHz.

use controller::sensing::{BackwardDifference, ObserverConfig, TrackingObserver, Unwrapper};
use controller::units::{self, Scale};
use std::f64::consts::TAU;

const T: f64 = 1e-3;

fn ocfg(cpr: u32, bw: f64) -> ObserverConfig {
    let s = Scale {
        motor_cpr: cpr,
        ..Scale::thesis(1.0)
    };
    units::observer_config(&s, bw, 1.0, 30000).unwrap()
}

fn to_rad_s(v: controller::fixed_math::Vel, cpr: u32) -> f64 {
    v.to_num::<f64>() * TAU / cpr as f64
}

struct Stats {
    mean: f64,
    rms: f64,
    peak: f64,
    bd_rms: f64,
}

/// Constant speed `w` rad/s for 3 s; statistics over the last 2 s.
fn constant_speed(cpr: u32, bw: f64, w: f64, phase: f64) -> Stats {
    let cfg = ocfg(cpr, bw);
    let mut u = Unwrapper::new();
    let mut obs = TrackingObserver::new();
    let mut bd = BackwardDifference::new();
    let (mut s, mut s2, mut peak, mut b2, mut n) = (0.0, 0.0, 0.0f64, 0.0, 0.0);
    for k in 0..3000 {
        let th = phase + w * k as f64 * T;
        let raw = ((th * cpr as f64 / TAU).floor() as i64) as u32;
        let x = u.update(raw);
        let (v, _) = obs.step(&cfg, x);
        let (vb, _) = bd.step(1000, x);
        if k >= 1000 {
            let e = to_rad_s(v, cpr) - w;
            let eb = to_rad_s(vb, cpr) - w;
            s += e;
            s2 += e * e;
            b2 += eb * eb;
            peak = peak.max(e.abs());
            n += 1.0;
        }
    }
    Stats {
        mean: s / n,
        rms: (s2 / n).sqrt(),
        peak,
        bd_rms: (b2 / n).sqrt(),
    }
}

/// Velocity lag under constant acceleration `a` (rad/s²): mean(v_true − v̂)/a over the last
/// second, and the 90 % rise time after a velocity step to `w`.
fn lag(cpr: u32, bw: f64, a: f64, w: f64) -> (f64, f64) {
    let cfg = ocfg(cpr, bw);
    let (mut u, mut obs) = (Unwrapper::new(), TrackingObserver::new());
    let mut acc = 0.0;
    for k in 0..2000 {
        let t = k as f64 * T;
        let th = 0.5 * a * t * t;
        let x = u.update(((th * cpr as f64 / TAU).floor() as i64) as u32);
        let (v, _) = obs.step(&cfg, x);
        if k >= 1000 {
            acc += a * t - to_rad_s(v, cpr);
        }
    }
    let lag_s = acc / 1000.0 / a;
    let (mut u, mut obs) = (Unwrapper::new(), TrackingObserver::new());
    let mut t90 = f64::NAN;
    for k in 0..1000 {
        let th = if k < 100 {
            0.0
        } else {
            w * (k - 100) as f64 * T
        };
        let x = u.update(((th * cpr as f64 / TAU).floor() as i64) as u32);
        let (v, _) = obs.step(&cfg, x);
        if k >= 100 && t90.is_nan() && to_rad_s(v, cpr) >= 0.9 * w {
            t90 = (k - 100) as f64 * T;
        }
    }
    (lag_s, t90)
}

#[test]
fn constant_speed_error_table() {
    println!(
        "\n[velocity] constant speed, tracking observer (ζ = 1) vs backward difference, 1 kHz"
    );
    println!(
        "[velocity] {:>8} {:>6} {:>9} | {:>11} {:>11} {:>11} | {:>11} {:>7}",
        "cpr", "bw Hz", "ω rad/s", "mean err", "RMS err", "peak err", "BD RMS err", "RMS %"
    );
    // (cpr, bw, speed, max RMS % of speed for the observer)
    let cases: &[(u32, f64, f64, f64)] = &[
        (2304, 20.0, 0.1, 60.0),
        (2304, 20.0, 1.0, 3.0),
        (2304, 20.0, 10.0, 0.3),
        (2304, 20.0, 100.0, 0.05),
        (2304, 50.0, 1.0, 15.0),
        (2304, 50.0, 10.0, 1.5),
        (1 << 20, 50.0, 0.01, 4.0),
        (1 << 20, 50.0, 0.1, 0.5),
        (1 << 20, 50.0, 1.0, 0.06),
        (1 << 20, 50.0, 10.0, 0.006),
        (1 << 20, 100.0, 10.0, 0.02),
    ];
    for &(cpr, bw, w, max_pct) in cases {
        let st = constant_speed(cpr, bw, w, 0.1234);
        let pct = st.rms / w * 100.0;
        println!(
            "[velocity] {cpr:>8} {bw:>6.0} {w:>9.2} | {:>11.2e} {:>11.2e} {:>11.2e} | {:>11.2e} {pct:>7.3}",
            st.mean, st.rms, st.peak, st.bd_rms
        );
        assert!(
            pct < max_pct,
            "cpr {cpr} bw {bw} ω {w}: RMS {pct:.3} % ≥ {max_pct} %"
        );
        // type-2 loop: no mean error at constant speed (quantisation averages out)
        assert!(
            st.mean.abs() < 0.01 * w + 2e-4,
            "mean error {:.3e}",
            st.mean
        );
        if w * cpr as f64 / TAU * T < 1.0 {
            // below one count per tick the observer must beat backward difference clearly
            assert!(
                st.rms < 0.3 * st.bd_rms,
                "observer {:.3e} vs BD {:.3e}",
                st.rms,
                st.bd_rms
            );
        }
    }
    // the thesis figure: one count per 1 ms tick at 2304 cpr
    let q = TAU / 2304.0 / T;
    println!("[velocity] 2304 cpr differenced at 1 kHz: {q:.3} rad/s per count (notes §1: 2.73)");
    assert!((q - 2.727).abs() < 0.01);
}

#[test]
fn lag_figures() {
    println!("\n[velocity] lag: constant acceleration (mean lag = v error / a) and 90 % rise after a speed step");
    for &(cpr, bw) in &[
        (2304u32, 20.0),
        (2304, 50.0),
        (1 << 20, 50.0),
        (1 << 20, 100.0),
    ] {
        let (lag_s, t90) = lag(cpr, bw, 20.0, 10.0);
        let theory = 2.0 / (TAU * bw); // 2ζ/ω for the continuous PLL
        println!(
            "[velocity] cpr {cpr:>8} bw {bw:>5.0} Hz: lag {:.2} ms (2ζ/ω = {:.2} ms), 90 % rise {:.1} ms",
            lag_s * 1e3,
            theory * 1e3,
            t90 * 1e3
        );
        assert!(
            (lag_s / theory - 1.0).abs() < 0.25,
            "lag {lag_s} vs {theory}"
        );
        assert!(t90 < 3.0 * theory + 0.002, "rise {t90}");
    }
}

#[test]
fn wrap_and_jump_handling() {
    // speed across the 32-bit wrap at 2^20 cpr: no glitch
    let cpr = 1u32 << 20;
    let cfg = ocfg(cpr, 50.0);
    let (mut u, mut obs) = (Unwrapper::new(), TrackingObserver::new());
    let start = u32::MAX - 3_000_000;
    let per_tick = 10_000u32;
    let mut worst: f64 = 0.0;
    for k in 0..1000u32 {
        let raw = start.wrapping_add(k.wrapping_mul(per_tick));
        let x = u.update(raw);
        let (v, f) = obs.step(&cfg, x);
        assert!(f.is_empty());
        if k > 300 {
            worst = worst.max((v.to_num::<f64>() - per_tick as f64 * 1000.0).abs());
        }
    }
    assert!(worst < 1.0, "counts/s error across wrap {worst}");
    // a jump larger than max_jump re-primes instead of kicking the velocity
    let x = u.position() + 1_000_000;
    let (v, f) = obs.step(&cfg, x);
    assert!(f.contains(controller::fixed_math::Flags::SENSOR_JUMP));
    assert!((v.to_num::<f64>() - per_tick as f64 * 1000.0).abs() < 1000.0);
}

#[test]
fn observer_config_rejects_unstable() {
    assert!(ObserverConfig::new(0, 100, 1000, 100).is_err());
    assert!(ObserverConfig::new(2 << 24, 100, 1000, 100).is_err());
    assert!(ObserverConfig::new(1 << 24, 2 << 24, 1000, 100).is_err());
    assert!(ObserverConfig::new(1 << 23, 1 << 20, 0, 100).is_err());
    assert!(ObserverConfig::new(1 << 23, 1 << 20, 1000, 0).is_err());
    assert!(ObserverConfig::new(1 << 23, 1 << 20, 1000, 100).is_ok());
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 2000, failure_persistence: None, ..Default::default() })]
    #[test]
    fn observer_never_panics(a in 1u32..(1 << 25), b in 1u32..(1 << 24), jump in 1i32..=32767,
                             xs in proptest::collection::vec(proptest::prelude::any::<i64>(), 1..100),
                             raws in proptest::collection::vec(proptest::prelude::any::<u32>(), 1..100)) {
        if let Ok(cfg) = ObserverConfig::new(a, b, 1000, jump) {
            let mut o = TrackingObserver::new();
            for x in xs { let _ = o.step(&cfg, x); }
            let mut u = Unwrapper::with_modulus(2304);
            let mut bd = BackwardDifference::new();
            for r in raws { let p = u.update(r); let _ = o.step(&cfg, p); let _ = bd.step(1000, p); }
        }
    }
}
