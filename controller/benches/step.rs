//! One full control computation of the card — position PID + input damping + friction
//! compensation + impedance compensation + ripple table, through `JointState::step` — against
//! the `pid` crate (f32) doing only the PID part. Run:
//! `cargo bench -p controller --bench step -- --warm-up-time 1 --measurement-time 3`.
//! After criterion's own report, a plain timing loop prints both per-step times and the ratio.

use controller::fixed_math::{Alpha, Vel};
use controller::laws::*;
use controller::units::{self, Scale};
use criterion::{criterion_group, Criterion};
use std::hint::black_box;
use std::time::Instant;

const N: usize = 1024;

fn joint_cfg() -> JointConfig {
    let s = Scale::thesis(30.0);
    let pos = units::position_config(
        &s,
        &units::PositionSi {
            ke: 0.4,
            be: 0.009,
            ki: 5.0,
            i_limit_nm: 1.0,
            tau_max_nm: 2.0,
            feedback: Feedback::Colocated,
        },
    )
    .unwrap();
    let tab: Vec<f64> = (0..64)
        .map(|i| 0.03 * (std::f64::consts::TAU * i as f64 / 64.0).sin())
        .collect();
    JointConfig {
        mode: Mode::Position(pos),
        input_damping: units::input_damping(&s, 0.002).unwrap(),
        friction: Some(
            units::friction_config(
                &s,
                &units::FrictionSi {
                    tau_c_pos: 0.03,
                    tau_c_neg: 0.02,
                    ramp_rad_s: 0.3,
                    viscous: 0.001,
                    undercomp: 0.8,
                    limit_nm: 0.5,
                },
            )
            .unwrap(),
        ),
        imp_comp: Some(ImpCompConfig {
            alpha: Alpha::from_num(0.03),
            ..units::imp_comp_config(
                &s,
                &units::ImpCompSi {
                    kd_out: 300.0,
                    kc: 1.0,
                    cutoff_hz: 5.0,
                    limit_nm: 0.5,
                    feedback: Feedback::Colocated,
                },
            )
            .unwrap()
        }),
        ripple: Some(units::ripple_table(&s, 128, &tab).unwrap()),
        friction_on_setpoint: false,
        offset: 120,
        gravity: Gravity::new(138_240, 900, -400),
        tau_max: 20000,
        transfer_shift: 6,
    }
}

fn samples() -> Vec<(Setpoint, Measurements)> {
    (0..N)
        .map(|k| {
            let x = (k as i64 * 37) % 5000 - 2500;
            (
                Setpoint {
                    x_d: (k as i64 * 13) % 3000,
                    tau_d: 0,
                    ..Default::default()
                },
                Measurements {
                    x1: x,
                    v1: Vel::from_num(((k * 7919) % 4001) as i32 - 2000),
                    x2: 0,
                    v2: Vel::ZERO,
                    tau_env: ((k * 104729) % 2001) as i32 - 1000,
                },
            )
        })
        .collect()
}

fn pid_f32() -> ::pid::Pid<f32> {
    let mut p = ::pid::Pid::new(0.0f32, 2.0);
    p.p(0.4f32 * std::f32::consts::TAU / 2304.0, 2.0)
        .i(5.0f32 * std::f32::consts::TAU / 2304.0 * 1e-3, 1.0)
        .d(0.009f32 * std::f32::consts::TAU / 2304.0 / 1e-3, 2.0);
    p
}

fn bench(c: &mut Criterion) {
    let cfg = joint_cfg();
    let smp = samples();
    let mut st = JointState::new();
    let mut k = 0usize;
    c.bench_function("card_step_fixed (PID+B1e+friction+impcomp+ripple)", |b| {
        b.iter(|| {
            k = (k + 1) & (N - 1);
            let (sp, m) = &smp[k];
            black_box(st.step(black_box(&cfg), black_box(sp), black_box(m)))
        })
    });
    let Mode::Position(pc) = cfg.mode else {
        unreachable!()
    };
    let mut law = PositionLaw::default();
    let mut k = 0usize;
    c.bench_function("position_pid_fixed (PID only)", |b| {
        b.iter(|| {
            k = (k + 1) & (N - 1);
            let (sp, m) = &smp[k];
            black_box(law.step(black_box(&pc), sp.x_d, m.x1, m.v1))
        })
    });
    let mut p = pid_f32();
    let mut k = 0usize;
    c.bench_function("pid_crate_f32 (PID only)", |b| {
        b.iter(|| {
            k = (k + 1) & (N - 1);
            let (sp, m) = &smp[k];
            p.setpoint(sp.x_d as f32);
            black_box(p.next_control_output(black_box(m.x1 as f32)).output)
        })
    });
}

criterion_group!(benches, bench);

fn ratio_report() {
    let cfg = joint_cfg();
    let smp = samples();
    let iters = 20_000_000usize;
    let mut st = JointState::new();
    let t0 = Instant::now();
    for i in 0..iters {
        let (sp, m) = &smp[i & (N - 1)];
        black_box(st.step(black_box(&cfg), black_box(sp), black_box(m)));
    }
    let fixed = t0.elapsed().as_secs_f64() / iters as f64 * 1e9;
    let mut p = pid_f32();
    let t0 = Instant::now();
    for i in 0..iters {
        let (sp, m) = &smp[i & (N - 1)];
        p.setpoint(sp.x_d as f32);
        black_box(p.next_control_output(black_box(m.x1 as f32)).output);
    }
    let f32t = t0.elapsed().as_secs_f64() / iters as f64 * 1e9;
    let Mode::Position(pc) = cfg.mode else {
        unreachable!()
    };
    let mut law = PositionLaw::default();
    let t0 = Instant::now();
    for i in 0..iters {
        let (sp, m) = &smp[i & (N - 1)];
        black_box(law.step(black_box(&pc), sp.x_d, m.x1, m.v1));
    }
    let pidfix = t0.elapsed().as_secs_f64() / iters as f64 * 1e9;
    println!("\n[bench] full card step (fixed point, 5 terms): {fixed:.2} ns/step");
    println!("[bench] pid crate f32, PID part only:          {f32t:.2} ns/step");
    println!("[bench] fixed-point position PID only:         {pidfix:.2} ns/step");
    println!("[bench] ratio full-step / pid-f32: {:.2}", fixed / f32t);
    println!(
        "[bench] ratio fixed PID / pid-f32 (same work): {:.2}",
        pidfix / f32t
    );
    println!(
        "[bench] 1 kHz budget used on this host: {:.5} %",
        fixed / 1e6 * 100.0
    );
}

fn main() {
    benches();
    Criterion::default().configure_from_args().final_summary();
    ratio_report();
}
