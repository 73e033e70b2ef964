//! Closed-loop tests: each law drives a small rigid-inertia model written here (f64, 20
//! substeps per 1 ms tick, quantised 2304 cpr encoder, torque sensor quantised to 0.1 mN·m,
//! zero-order hold of the `i16` command). The card side runs exactly as on the target:
//! unwrap → tracking observer → `JointState::step` → `i16` command.
//!
//! Figures are printed (`--nocapture`); every assertion compares against a physical
//! expectation and could fail.

use controller::fixed_math::Vel;
use controller::laws::*;
use controller::proto::scale::MOTOR_TORQUE_NM_PER_LSB;
use controller::sensing::{ObserverConfig, TrackingObserver, Unwrapper};
use controller::units::{self, Scale};
use std::f64::consts::TAU;

const T: f64 = 1e-3;
const SUB: usize = 20;

/// Rigid rotor I·θ̈ + B·θ̇ + friction + ripple(θ) + spring wall = τ + τ_ext.
#[derive(Clone, Debug)]
struct Plant {
    th: f64,
    w: f64,
    i: f64,
    b: f64,
    coul_pos: f64,
    coul_neg: f64,
    ext: f64,
    ripple_amp: f64,
    ripple_period: f64,
    /// wall: spring kf for θ > wall (environment / force sensor)
    wall: Option<(f64, f64)>,
}

impl Plant {
    fn new(i: f64) -> Self {
        Plant {
            th: 0.0,
            w: 0.0,
            i,
            b: 1e-4,
            coul_pos: 0.0,
            coul_neg: 0.0,
            ext: 0.0,
            ripple_amp: 0.0,
            ripple_period: 1.0,
            wall: None,
        }
    }
    fn env_torque(&self) -> f64 {
        match self.wall {
            Some((kf, x0)) if self.th > x0 => kf * (self.th - x0),
            _ => 0.0,
        }
    }
    fn step(&mut self, tau: f64) {
        let dt = T / SUB as f64;
        for _ in 0..SUB {
            let ripple = self.ripple_amp * (TAU * self.th / self.ripple_period).sin();
            let drive = tau + self.ext + ripple - self.env_torque();
            // Coulomb friction with stiction at zero velocity
            let fric = if self.w > 0.0 {
                -self.coul_pos
            } else if self.w < 0.0 {
                self.coul_neg
            } else if drive > self.coul_pos {
                -self.coul_pos
            } else if drive < -self.coul_neg {
                self.coul_neg
            } else {
                -drive
            };
            let acc = (drive + fric - self.b * self.w) / self.i;
            let w_new = self.w + acc * dt;
            // crossing zero under friction: stop (stick), next substep decides breakaway
            self.w = if self.w != 0.0 && w_new.signum() != self.w.signum() {
                0.0
            } else {
                w_new
            };
            self.th += self.w * dt;
        }
    }
    fn counts(&self, cpr: u32) -> u32 {
        // raw 32-bit wrapping counter, like the card's hardware
        ((self.th * cpr as f64 / TAU).floor() as i64) as u32
    }
}

struct Card {
    unwrap: Unwrapper,
    obs: TrackingObserver,
    ocfg: ObserverConfig,
    st: JointState,
    cpr: u32,
}

impl Card {
    fn new(cpr: u32, bw_hz: f64) -> Self {
        let s = Scale {
            motor_cpr: cpr,
            ..Scale::thesis(1.0)
        };
        Card {
            unwrap: Unwrapper::new(),
            obs: TrackingObserver::new(),
            ocfg: units::observer_config(&s, bw_hz, 1.0, 2000).unwrap(),
            st: JointState::new(),
            cpr,
        }
    }
    /// One tick: sense, control, return the torque in N·m (ZOH for the next ms).
    fn tick(&mut self, p: &Plant, cfg: &JointConfig, sp: &Setpoint) -> (f64, Measurements) {
        let x = self.unwrap.update(p.counts(self.cpr));
        let (v, _) = self.obs.step(&self.ocfg, x);
        let tau_env = (p.env_torque() / MOTOR_TORQUE_NM_PER_LSB).round() as i32;
        let m = Measurements {
            x1: x,
            v1: v,
            x2: 0,
            v2: Vel::ZERO,
            tau_env,
        };
        let o = self.st.step(cfg, sp, &m);
        (o.command() as f64 * MOTOR_TORQUE_NM_PER_LSB, m)
    }
}

fn scale() -> Scale {
    Scale::thesis(1.0)
}
fn rad2counts(r: f64) -> i64 {
    (r * 2304.0 / TAU).round() as i64
}
fn counts2rad(c: i64) -> f64 {
    c as f64 * TAU / 2304.0
}

const I_ROT: f64 = 1e-4; // kg·m², rotor + reflected load
const WN: f64 = TAU * 10.0; // 10 Hz position loop
fn ke() -> f64 {
    I_ROT * WN * WN
}
fn be() -> f64 {
    2.0 * 0.7 * WN * I_ROT
}

fn pd_cfg(ki: f64) -> JointConfig {
    let pos = units::position_config(
        &scale(),
        &units::PositionSi {
            ke: ke(),
            be: be(),
            ki,
            i_limit_nm: 1.0,
            tau_max_nm: 2.0,
            feedback: Feedback::Colocated,
        },
    )
    .unwrap();
    // the guard agrees these gains are safe at T = 1 ms
    units::pd_stability(ke(), be(), I_ROT, T, units::DEFAULT_MARGIN).unwrap();
    JointConfig {
        mode: Mode::Position(pos),
        tau_max: 20000,
        ..JointConfig::default()
    }
}

fn run(
    plant: &mut Plant,
    card: &mut Card,
    cfg: &JointConfig,
    ticks: usize,
    mut sp: impl FnMut(usize) -> Setpoint,
    mut log: impl FnMut(usize, &Plant, &Measurements, f64),
) {
    for k in 0..ticks {
        let s = sp(k);
        let (tau, m) = card.tick(plant, cfg, &s);
        log(k, plant, &m, tau);
        plant.step(tau);
    }
}

#[test]
fn pd_step_settles() {
    let mut p = Plant::new(I_ROT);
    let mut c = Card::new(2304, 50.0);
    let cfg = pd_cfg(0.0);
    let target = 500i64;
    let mut peak = 0i64;
    let mut settle_k = None;
    run(
        &mut p,
        &mut c,
        &cfg,
        1500,
        |_| Setpoint {
            x_d: target,
            tau_d: 0,
            ..Default::default()
        },
        |k, _, m, _| {
            peak = peak.max(m.x1);
            if (m.x1 - target).abs() > 3 {
                settle_k = None;
            } else if settle_k.is_none() {
                settle_k = Some(k);
            }
        },
    );
    let x = c.unwrap.position();
    let overshoot = (peak - target) as f64 / target as f64 * 100.0;
    println!(
        "[closed loop] PD 10 Hz step 500 counts: final {x}, overshoot {overshoot:.1} %, settled (±3 counts) at {} ms",
        settle_k.unwrap_or(usize::MAX)
    );
    assert!((x - target).abs() <= 2);
    assert!(overshoot < 15.0, "ζ = 0.7 should overshoot ≈ 5 %");
    assert!(settle_k.unwrap() < 400);
}

#[test]
fn pid_removes_constant_load_error() {
    let load = -0.05; // N·m
    let mut errs = vec![];
    for ki in [0.0, ke() * WN / 4.0] {
        let mut p = Plant::new(I_ROT);
        p.ext = load;
        let mut c = Card::new(2304, 50.0);
        let cfg = pd_cfg(ki);
        run(
            &mut p,
            &mut c,
            &cfg,
            3000,
            |_| Setpoint {
                x_d: 0,
                tau_d: 0,
                ..Default::default()
            },
            |_, _, _, _| {},
        );
        let mut e_sum = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            500,
            |_| Setpoint {
                x_d: 0,
                tau_d: 0,
                ..Default::default()
            },
            |_, _, m, _| e_sum += m.x1 as f64,
        );
        errs.push(e_sum / 500.0);
    }
    let expected_pd = rad2counts(load / ke()) as f64;
    println!(
        "[closed loop] constant load {load} N·m: PD error {:.1} counts (expected {expected_pd:.1}), PID error {:.2} counts",
        errs[0], errs[1]
    );
    assert!((errs[0] - expected_pd).abs() < 3.0);
    assert!(errs[1].abs() <= 1.0);
}

fn wall_plant(kf: f64) -> Plant {
    let mut p = Plant::new(I_ROT);
    p.wall = Some((kf, 0.0));
    p
}

fn force_cfg(kp: f64, ki: f64, b_in: f64) -> JointConfig {
    let f = units::force_config(
        &scale(),
        &units::ForceSi {
            ke: kp,
            ki,
            damping: units::ForceDampingSi::InputVelocity { be: b_in },
            i_limit_nm: 1.0,
            tau_max_nm: 2.0,
        },
    )
    .unwrap();
    JointConfig {
        mode: Mode::Force(f),
        tau_max: 20000,
        ..JointConfig::default()
    }
}

#[test]
fn force_p_and_pi_track_against_a_spring() {
    let kf = 5.0; // N·m/rad contact stiffness
    let tau_d = 0.1; // N·m
    let kp = 2.0;
    let wn = (kf * (1.0 + kp) / I_ROT).sqrt();
    let b_in = 2.0 * 0.7 * wn * I_ROT;
    let mut res = vec![];
    for ki in [0.0, 20.0] {
        let mut p = wall_plant(kf);
        let mut c = Card::new(2304, 100.0);
        let cfg = force_cfg(kp, ki, b_in);
        let sp = Setpoint {
            x_d: 0,
            tau_d: (tau_d / MOTOR_TORQUE_NM_PER_LSB) as i32,
            ..Default::default()
        };
        run(&mut p, &mut c, &cfg, 2000, |_| sp, |_, _, _, _| {});
        let mut s = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            500,
            |_| sp,
            |_, p, _, _| s += p.env_torque(),
        );
        res.push(s / 500.0);
    }
    let p_expect = tau_d * kp / (1.0 + kp);
    println!(
        "[closed loop] force P (Ke={kp}): τenv {:.4} N·m (static theory {p_expect:.4}); PI: {:.4} N·m (τD {tau_d})",
        res[0], res[1]
    );
    assert!((res[0] - p_expect).abs() / p_expect < 0.03);
    assert!((res[1] - tau_d).abs() / tau_d < 0.01);
}

#[test]
fn input_velocity_damping_calms_force_p() {
    // thesis Eqn 5.2: P force control alone is barely damped in contact; adding −B1e·ẋ1
    // damps it. Compare the oscillation energy of τenv after a force step.
    let kf = 5.0;
    let kp = 2.0;
    let wn = (kf * (1.0 + kp) / I_ROT).sqrt();
    let mut rms = vec![];
    for b in [0.0, 2.0 * 0.7 * wn * I_ROT] {
        let mut p = wall_plant(kf);
        p.b = 2e-5;
        let mut c = Card::new(2304, 100.0);
        let mut cfg = force_cfg(kp, 0.0, 1e-6);
        cfg.input_damping = units::input_damping(&scale(), b.max(1e-6)).unwrap();
        let sp = Setpoint {
            x_d: 0,
            tau_d: 1000,
            ..Default::default()
        };
        let fin = 0.1 * kp / (1.0 + kp);
        let mut s = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            400,
            |_| sp,
            |k, p, _, _| {
                if k >= 50 {
                    s += (p.env_torque() - fin).powi(2)
                }
            },
        );
        rms.push((s / 350.0).sqrt());
    }
    println!(
        "[closed loop] force P step, RMS(τenv − final) over 50–400 ms: no input damping {:.5} N·m, with B1e {:.5} N·m",
        rms[0], rms[1]
    );
    assert!(rms[1] < rms[0] / 3.0);
}

#[test]
fn force_rate_damping_calms_force_p() {
    // Thesis §2.3 implementation: D on the force rate by backward difference + low-pass.
    // Equivalent viscous damping Be·Kf; small Be only (too much destabilises).
    let kf = 5.0;
    let kp = 2.0;
    let wn = (kf * (1.0 + kp) / I_ROT).sqrt();
    let be_s = 2.0 * 0.5 * wn * I_ROT / kf; // ζ ≈ 0.5 worth of Be·Kf
    let mut rms = vec![];
    for (be, cutoff) in [(0.0, 200.0), (be_s, 200.0)] {
        let mut p = wall_plant(kf);
        p.b = 2e-5;
        let mut c = Card::new(2304, 100.0);
        let damping = if be > 0.0 {
            units::ForceDampingSi::ForceRate {
                be_s: be,
                cutoff_hz: cutoff,
            }
        } else {
            units::ForceDampingSi::None
        };
        let f = units::force_config(
            &scale(),
            &units::ForceSi {
                ke: kp,
                ki: 0.0,
                damping,
                i_limit_nm: 0.0,
                tau_max_nm: 2.0,
            },
        )
        .unwrap();
        let cfg = JointConfig {
            mode: Mode::Force(f),
            tau_max: 20000,
            ..JointConfig::default()
        };
        let sp = Setpoint {
            x_d: 0,
            tau_d: 1000,
            ..Default::default()
        };
        let fin = 0.1 * kp / (1.0 + kp);
        let mut s = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            400,
            |_| sp,
            |k, p, _, _| {
                if k >= 50 {
                    s += (p.env_torque() - fin).powi(2)
                }
            },
        );
        rms.push((s / 350.0).sqrt());
    }
    println!(
        "[closed loop] force P step, RMS(τenv − final) over 50–400 ms: no D {:.5} N·m, force-rate D (Be = {be_s:.2e} s, LPF 200 Hz) {:.5} N·m",
        rms[0], rms[1]
    );
    assert!(rms[1] < rms[0] / 3.0);
}

#[test]
fn impedance_achieves_desired_stiffness() {
    let kf = 2.0;
    let ke = 0.5;
    for km in [0.0, 0.5, -0.5] {
        let mut p = wall_plant(kf);
        let mut c = Card::new(2304, 50.0);
        let k_eff = ke + kf * (1.0 - km);
        let be = 2.0 * 0.7 * (k_eff / I_ROT).sqrt() * I_ROT;
        let imp = units::impedance_config(
            &scale(),
            &units::ImpedanceSi {
                ke,
                be,
                km,
                tau_max_nm: 2.0,
                feedback: Feedback::Colocated,
            },
        )
        .unwrap();
        let cfg = JointConfig {
            mode: Mode::Impedance(imp),
            tau_max: 20000,
            ..JointConfig::default()
        };
        let xd = 1.0; // rad into the wall
        let sp = Setpoint {
            x_d: rad2counts(xd),
            tau_d: 0,
            ..Default::default()
        };
        run(&mut p, &mut c, &cfg, 3000, |_| sp, |_, _, _, _| {});
        let x = counts2rad(c.unwrap.position());
        let k_app = p.env_torque() / (xd - x);
        let want = ke / (1.0 - km);
        println!(
            "[closed loop] impedance Ke={ke} Km={km}: apparent stiffness {k_app:.4} N·m/rad, desired Ke/(1−Km) = {want:.4} ({:+.2} %)",
            (k_app / want - 1.0) * 100.0
        );
        assert!((k_app / want - 1.0).abs() < 0.03);
    }
}

fn friction_cfg(tc_pos: f64, tc_neg: f64, under: f64) -> FrictionConfig {
    units::friction_config(
        &scale(),
        &units::FrictionSi {
            tau_c_pos: tc_pos,
            tau_c_neg: tc_neg,
            ramp_rad_s: 0.3,
            viscous: 0.0,
            undercomp: under,
            limit_nm: 0.5,
        },
    )
    .unwrap()
}

#[test]
fn friction_comp_reduces_tracking_error() {
    // The PD's own tracking lag (D on the measurement) is not friction's fault: the error is
    // measured against the same loop run on a frictionless plant.
    let (cp, cn) = (0.03, 0.02);
    let traj = |k: usize| 1.0 * (TAU * 0.5 * k as f64 * T).sin();
    let sim = |coul: bool, comp: bool| -> Vec<f64> {
        let mut p = Plant::new(I_ROT);
        if coul {
            p.coul_pos = cp;
            p.coul_neg = cn;
        }
        let mut c = Card::new(2304, 50.0);
        let mut cfg = pd_cfg(0.0);
        if comp {
            cfg.friction = Some(friction_cfg(cp, cn, 0.8));
        }
        let mut th = vec![];
        run(
            &mut p,
            &mut c,
            &cfg,
            4000,
            |k| Setpoint {
                x_d: rad2counts(traj(k)),
                tau_d: 0,
                ..Default::default()
            },
            |_, p, _, _| th.push(p.th),
        );
        th
    };
    let ideal = sim(false, false);
    let rms = |th: &[f64]| {
        (th[1000..]
            .iter()
            .zip(&ideal[1000..])
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / 3000.0)
            .sqrt()
    };
    let without = rms(&sim(true, false));
    let with = rms(&sim(true, true));
    println!(
        "[closed loop] Coulomb {cp}/{cn} N·m, 0.5 Hz ±1 rad: RMS deviation from the frictionless response without FF {without:.4} rad, with FF (u=0.8, ramp 0.3 rad/s) {with:.4} rad"
    );
    assert!(with < 0.4 * without);
}

#[test]
fn ripple_comp_cancels_known_ripple() {
    let amp = 0.03;
    let period_counts = 128u32; // 2304/18: the Sensorimotor's 18 cycles per rev
    let period_rad = counts2rad(period_counts as i64);
    let mut rms = vec![];
    for comp in [false, true] {
        let mut p = Plant::new(I_ROT);
        p.ripple_amp = amp;
        p.ripple_period = period_rad;
        let mut c = Card::new(2304, 50.0);
        let mut cfg = pd_cfg(0.0);
        if comp {
            // the table holds −ripple(θ) sampled at 64 phases
            let tab: Vec<f64> = (0..64)
                .map(|i| -amp * (TAU * i as f64 / 64.0).sin())
                .collect();
            cfg.ripple = Some(units::ripple_table(&scale(), period_counts, &tab).unwrap());
        }
        let speed = 0.5; // rad/s: ripple at 1.4 Hz, inside the loop bandwidth
        let mut s = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            5000,
            |k| Setpoint {
                x_d: rad2counts(speed * k as f64 * T),
                tau_d: 0,
                ..Default::default()
            },
            |k, p, _, _| {
                if k >= 1000 {
                    s += (p.th - speed * k as f64 * T).powi(2)
                }
            },
        );
        rms.push((s / 4000.0).sqrt());
    }
    println!(
        "[closed loop] ripple ±{amp} N·m per 128 counts: RMS error without table {:.5} rad, with table {:.5} rad",
        rms[0], rms[1]
    );
    assert!(rms[1] < 0.3 * rms[0]);
}

#[test]
fn damper_emulation_gives_desired_damping() {
    let bdes = 0.01; // N·m·s/rad
    let ext = 0.05;
    let mut p = Plant::new(I_ROT);
    p.b = 0.0;
    p.ext = ext;
    let mut c = Card::new(2304, 50.0);
    let cfg = JointConfig {
        mode: Mode::Damper(units::damper_config(&scale(), bdes, 2.0).unwrap()),
        tau_max: 20000,
        ..JointConfig::default()
    };
    run(
        &mut p,
        &mut c,
        &cfg,
        500,
        |_| Setpoint::default(),
        |_, _, _, _| {},
    );
    let th0 = p.th;
    run(
        &mut p,
        &mut c,
        &cfg,
        1000,
        |_| Setpoint::default(),
        |_, _, _, _| {},
    );
    let speed = (p.th - th0) / 1.0;
    let b_meas = ext / speed;
    println!(
        "[closed loop] damper Bdes={bdes}: speed {speed:.3} rad/s under {ext} N·m → B = {b_meas:.5} N·m·s/rad ({:+.2} %)",
        (b_meas / bdes - 1.0) * 100.0
    );
    assert!((b_meas / bdes - 1.0).abs() < 0.02);
}

#[test]
fn impedance_compensation_reduces_torque_deficit() {
    // Position PD against a wall with Coulomb friction in the drive: the output torque falls
    // short of Kd·Δx by the friction; the FF (Kc = 3) cuts the deficit ≈ (1 + Kc)×.
    let kf = 2.0;
    let mut res = vec![];
    for kc in [0.0, 3.0] {
        let mut p = wall_plant(kf);
        p.coul_pos = 0.03;
        p.coul_neg = 0.03;
        let mut c = Card::new(2304, 50.0);
        let mut cfg = pd_cfg(0.0);
        if kc > 0.0 {
            cfg.imp_comp = Some(
                units::imp_comp_config(
                    &scale(),
                    &units::ImpCompSi {
                        kd_out: ke(),
                        kc,
                        cutoff_hz: 5.0,
                        limit_nm: 0.5,
                        feedback: Feedback::Colocated,
                    },
                )
                .unwrap(),
            );
        }
        // slow ramp into the wall, then hold
        let xd = |k: usize| (k as f64 * T * 0.5).min(1.0);
        let mut deficit = 0.0;
        run(
            &mut p,
            &mut c,
            &cfg,
            5000,
            |k| Setpoint {
                x_d: rad2counts(xd(k)),
                tau_d: 0,
                ..Default::default()
            },
            |k, p, m, _| {
                if k >= 4000 {
                    deficit += ke() * (xd(k) - counts2rad(m.x1)) - p.env_torque();
                }
            },
        );
        res.push(deficit / 1000.0);
    }
    println!(
        "[closed loop] impedance comp, Coulomb 0.03 N·m: deficit Kd·Δx − τenv without {:.4} N·m, with Kc=3 {:.4} N·m",
        res[0], res[1]
    );
    assert!(res[0].abs() > 0.015, "friction must create a deficit");
    assert!(res[1].abs() < 0.5 * res[0].abs());
}

#[test]
fn noncolocated_pd_step_on_two_mass_plant() {
    // Motor I1 — spring KT — output I2 with an output encoder (2^16 cpr): τ = Ke(xD − x2) − Be·ẋ2.
    let (i1, i2, kt) = (1e-4, 1e-4, 50.0);
    let (mut th1, mut w1, mut th2, mut w2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let cpr2 = 1u32 << 16;
    let s = Scale {
        output_cpr: cpr2,
        ..Scale::thesis(1.0)
    };
    let wn = TAU * 5.0;
    let itot = i1 + i2;
    let pos = units::position_config(
        &s,
        &units::PositionSi {
            ke: itot * wn * wn,
            be: 2.0 * 0.8 * wn * itot,
            ki: 0.0,
            i_limit_nm: 0.0,
            tau_max_nm: 2.0,
            feedback: Feedback::NonColocated,
        },
    )
    .unwrap();
    let cfg = JointConfig {
        mode: Mode::Position(pos),
        tau_max: 20000,
        ..JointConfig::default()
    };
    let ocfg = units::observer_config(
        &Scale {
            motor_cpr: cpr2,
            ..s
        },
        80.0,
        1.0,
        30000,
    )
    .unwrap();
    let mut obs = TrackingObserver::new();
    let mut st = JointState::new();
    let target = (0.5 * cpr2 as f64 / TAU) as i64;
    let mut last = 0;
    for _ in 0..2000 {
        let x2 = (th2 * cpr2 as f64 / TAU).floor() as i64;
        let x1 = (th1 * 2304.0 / TAU).floor() as i64;
        let (v2, _) = obs.step(&ocfg, x2);
        let m = Measurements {
            x1,
            v1: Vel::ZERO,
            x2,
            v2,
            tau_env: 0,
        };
        let tau = st
            .step(
                &cfg,
                &Setpoint {
                    x_d: target,
                    tau_d: 0,
                    ..Default::default()
                },
                &m,
            )
            .command() as f64
            * MOTOR_TORQUE_NM_PER_LSB;
        let dt = T / SUB as f64;
        for _ in 0..SUB {
            let f = kt * (th1 - th2) + 0.002 * (w1 - w2);
            w1 += (tau - f - 1e-4 * w1) / i1 * dt;
            w2 += (f - 1e-4 * w2) / i2 * dt;
            th1 += w1 * dt;
            th2 += w2 * dt;
        }
        last = x2;
    }
    println!("[closed loop] non-colocated PD 5 Hz on a two-mass plant: final x2 {last} counts, target {target}");
    assert!(
        (last - target).abs() <= 20,
        "within 20 of 2^16 cpr counts (0.11°)"
    );
}

/// Velocity PI (`Mode::Velocity`) on the rigid rotor with Coulomb friction and a constant
/// load: Kv for a 20 Hz velocity loop, Ki = Kv·ω/4. The integrator takes the steady error
/// against load and friction away (P alone leaves (load + friction)/Kv), and its clamp bounds
/// what a long stall winds into it (the overshoot after release).
#[test]
fn velocity_pi_tracks_against_load_and_does_not_wind_up() {
    let w = TAU * 20.0;
    let kv = I_ROT * w; // N·m·s/rad
    let ki = kv * w / 4.0; // N·m/rad
    let s = scale();
    let pos = units::position_config(
        &s,
        &units::PositionSi {
            ke: ki,
            be: kv,
            ki: 0.0,
            i_limit_nm: 0.5,
            tau_max_nm: 2.0,
            feedback: Feedback::Colocated,
        },
    )
    .unwrap();
    // Ki·T per (1/16 count/s) per tick in 2⁻¹⁶ torque LSB, as the card converts Ke.
    let ki_t = units::gain_from_f64("ki_t", pos.pid.kp.to_f64() * 4096.0 * T).unwrap();
    let cfg = |with_i: bool| JointConfig {
        mode: Mode::Velocity(VelocityConfig {
            pid: PidConfig {
                kp: pos.pid.kd,
                kd: controller::fixed_math::Gain::ZERO,
                ki_t: if with_i {
                    ki_t
                } else {
                    controller::fixed_math::Gain::ZERO
                },
                i_limit: if with_i { 5000 } else { 0 },
                tau_max: 20000,
            },
        }),
        tau_max: 20000,
        ..JointConfig::default()
    };
    let v_ref = 20.0; // rad/s
    let sp = Setpoint {
        v_d: Vel::from_num(v_ref * 2304.0 / TAU),
        ..Default::default()
    };
    let steady = |with_i: bool| {
        let mut p = Plant::new(I_ROT);
        p.coul_pos = 0.05;
        p.coul_neg = 0.05;
        p.ext = -0.1;
        let mut c = Card::new(2304, 50.0);
        let (mut sum, mut n) = (0.0, 0);
        run(
            &mut p,
            &mut c,
            &cfg(with_i),
            1500,
            |_| sp,
            |k, p, _, _| {
                if k >= 1000 {
                    sum += p.w;
                    n += 1;
                }
            },
        );
        sum / n as f64
    };
    let (p_only, pi) = (steady(false), steady(true));
    println!("velocity loop at {v_ref} rad/s: P only {p_only:.3}, PI {pi:.3} rad/s");
    assert!((pi - v_ref).abs() < 0.02 * v_ref, "PI {pi}");
    let p_err = 0.15 / kv; // (load + friction) / Kv
    assert!(
        (v_ref - p_only - p_err).abs() < 0.3 * p_err,
        "P only {p_only}"
    );
    // Held for 1 s by a brake (static friction above the torque limit), then released: the
    // overshoot with the integrator clamped at 0.5 N·m, and with it clamped only by the
    // output limit.
    let stall = |i_limit: i32| {
        let mut c = cfg(true);
        if let Mode::Velocity(v) = &mut c.mode {
            v.pid.i_limit = i_limit;
        }
        let mut p = Plant::new(I_ROT);
        p.coul_pos = 3.0;
        p.coul_neg = 3.0;
        let mut card = Card::new(2304, 50.0);
        let mut peak: f64 = 0.0;
        for k in 0..2500 {
            if k == 1000 {
                p.coul_pos = 0.05;
                p.coul_neg = 0.05;
            }
            let (tau, _) = card.tick(&p, &c, &sp);
            peak = peak.max(p.w);
            p.step(tau);
        }
        peak
    };
    let (peak, unclamped) = (stall(5000), stall(20000));
    println!("after a 1 s stall: peak {peak:.2} rad/s clamped, {unclamped:.2} unclamped");
    // The overshoot grows with what the integrator holds at release: a quarter of the
    // output limit's (0.5 of 2 N·m) must overshoot well under the unclamped run.
    assert!(peak < 0.5 * unclamped, "{peak} {unclamped}");
}
