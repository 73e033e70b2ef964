//! Every law against an `f64` reference implementation, with a stated LSB bound over the
//! documented input ranges (design.md non-negotiable), plus extreme-value no-panic tests and
//! the bumpless transfer tests.
//!
//! Bounds (torque LSB = 0.1 mN·m), derived from the rounding steps of each law:
//!
//! | law | bound | why |
//! |---|---|---|
//! | PD (position, damper via kp=0) | 1 | two products, each rounded (≤ ½) |
//! | PID | 3 | P, D, I→torque rounding (3 × ½), the I clamp uses the rounded P−D (≤ 1) |
//! | damper / input damping | ½ → 1 | one product |
//! | impedance | 2 | three rounded products |
//! | force P/PI/PID, D on input velocity | 3 | as PID |
//! | force PD, D on force rate | 3 + ½·|Kd| | the low-passed force rate is an integer LSB/tick |
//! | friction compensation | 2 | Coulomb/viscous rounding × u ≤ 1.5, final rounding |
//! | impedance compensation | 2 (|Kc/N| ≤ 1) | Kd·Δx rounding, filter output rounding, gain rounding |
//! | ripple table | 1 | one rounded interpolation |
//! | joint pipeline (PID + B1e + friction + impcomp + ripple) | 9 | sum of the above |
//!
//! Input ranges: errors, velocities, forces over the full `i32` domain (position errors are the
//! clamped `i64` differences); gains |g| ≤ 2¹⁰ per input LSB (≈ 37 N·m/rad at 2304 cpr, 5× the
//! §2.9 stability limit of a 10⁻⁵ kg·m² rotor), any exponent; limits up to `i16::MAX`.
//! The largest deviation seen in each proptest is printed (`--nocapture`).

use controller::fixed_math::{Alpha, Flags, Gain, Vel};
use controller::laws::*;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::sync::atomic::{AtomicU64, Ordering};

// ------------------------------------------------------------------------------------------
// helpers

fn gain_strat() -> impl Strategy<Value = Gain> {
    prop_oneof![
        Just(Gain::ZERO),
        (-(1i32 << 30)..(1i32 << 30), 20u8..=62).prop_map(|(m, s)| Gain::from_parts(m, s).unwrap()),
    ]
}
fn pos_gain_strat() -> impl Strategy<Value = Gain> {
    prop_oneof![
        Just(Gain::ZERO),
        (0i32..(1i32 << 30), 20u8..=62).prop_map(|(m, s)| Gain::from_parts(m, s).unwrap()),
    ]
}
fn lim_strat() -> impl Strategy<Value = i32> {
    prop_oneof![Just(32767), 1i32..=32767]
}
fn i32_strat() -> impl Strategy<Value = i32> {
    prop_oneof![
        any::<i32>(),
        -100_000i32..100_000,
        Just(i32::MIN),
        Just(i32::MAX),
        Just(0)
    ]
}
fn alpha_strat() -> impl Strategy<Value = Alpha> {
    (1u16..=32768).prop_map(Alpha::from_bits)
}
fn g(x: Gain) -> f64 {
    x.to_f64()
}
fn clamp(x: f64, l: i32) -> f64 {
    x.clamp(-(l.abs() as f64), l.abs() as f64)
}

/// Largest error seen per test (in 1/1000 LSB), printed at the end of each proptest.
struct Worst(&'static str, AtomicU64);
impl Worst {
    fn new(n: &'static str) -> Self {
        Worst(n, AtomicU64::new(0))
    }
    fn see(&self, err: f64) {
        self.1.fetch_max((err * 1000.0) as u64, Ordering::Relaxed);
    }
    fn report(&self, bound: &str) {
        println!(
            "[bound] {:<34} worst |fixed − f64| = {:.3} LSB (bound {bound})",
            self.0,
            self.1.load(Ordering::Relaxed) as f64 / 1000.0
        );
    }
}

// ------------------------------------------------------------------------------------------
// f64 references

#[derive(Default)]
struct RefPid {
    i: f64,
}
impl RefPid {
    fn step(&mut self, c: &PidConfig, e: f64, r: f64) -> f64 {
        let pd = g(c.kp) * e - g(c.kd) * r;
        if c.has_integrator() {
            let di = g(c.ki_t) * e / 65536.0;
            let tmax = c.tau_max.abs() as f64;
            let i0 = self.i;
            let cand = i0 + di;
            let mut i1 = cand;
            if cand > i0 {
                i1 = i1.min(i0.max(tmax - pd));
            } else if cand < i0 {
                i1 = i1.max(i0.min(-tmax - pd));
            }
            let il = c.i_limit.abs() as f64;
            self.i = i1.clamp(-il, il);
        }
        clamp(pd + self.i, c.tau_max)
    }
}

fn ref_impedance(c: &ImpedanceConfig, e: f64, v: f64, tau_env: f64) -> f64 {
    clamp(g(c.ke) * e - g(c.be) * v + g(c.km) * tau_env, c.tau_max)
}

fn ref_friction(c: &FrictionConfig, v: f64) -> f64 {
    let coul = if v >= 0.0 {
        (g(c.slope_pos) * v).min(c.tau_c_pos as f64)
    } else {
        (g(c.slope_neg) * v).max(-(c.tau_c_neg as f64))
    };
    let u = c.undercomp.to_num::<f64>();
    clamp(u * (coul + g(c.viscous) * v), c.limit)
}

#[derive(Default)]
struct RefLp {
    y: f64,
}
impl RefLp {
    fn step(&mut self, u: f64, a: Alpha) -> f64 {
        self.y += a.to_num::<f64>() * (u - self.y);
        self.y
    }
}

fn ref_ripple(t: &RippleTable, x: i64) -> f64 {
    let p = t.period() as f64;
    let n = t.entries().len() as f64;
    let phase = x.rem_euclid(t.period() as i64) as f64;
    let s = phase * n / p;
    let i0 = s.floor() as usize;
    let i1 = (i0 + 1) % t.entries().len();
    let a = t.entries()[i0] as f64;
    let b = t.entries()[i1] as f64;
    a + (b - a) * (s - i0 as f64)
}

fn pos_err(a: i64, b: i64) -> f64 {
    (a.saturating_sub(b)).clamp(i32::MIN as i64, i32::MAX as i64) as f64
}

// ------------------------------------------------------------------------------------------
// proptests: fixed vs f64

fn run<S: Strategy>(cases: u32, strat: &S, f: impl Fn(S::Value) -> Result<(), TestCaseError>) {
    use proptest::test_runner::{Config, TestRunner};
    let mut runner = TestRunner::new(Config {
        cases,
        failure_persistence: None,
        ..Config::default()
    });
    if let Err(e) = runner.run(strat, f) {
        panic!("{e}");
    }
}

const NAME_W_PD: &str = "position PD";
const NAME_W_PID: &str = "position PID (sequence)";
const NAME_W_DAMP: &str = "damper / input damping";
const NAME_W_IMP: &str = "impedance";
const NAME_W_FORCE_V: &str = "force PID, D on input velocity";
const NAME_W_FORCE_R: &str = "force PID, D on force rate";
const NAME_W_FRIC: &str = "friction compensation";
const NAME_W_IC: &str = "impedance compensation (sequence)";
const NAME_W_RIP: &str = "ripple table";
const NAME_W_JOINT: &str = "joint pipeline (sequence)";

#[test]
fn pd_tracks_f64() {
    let w = Worst::new(NAME_W_PD);
    run(
        3000,
        &(
            gain_strat(),
            gain_strat(),
            lim_strat(),
            any::<i64>(),
            any::<i64>(),
            i32_strat(),
            any::<bool>(),
        ),
        |(kp, kd, lim, xd, x, v, nonco)| {
            let c = PositionConfig {
                pid: PidConfig::pd(kp, kd, lim),
                feedback: if nonco {
                    Feedback::NonColocated
                } else {
                    Feedback::Colocated
                },
            };
            let out = PositionLaw::default().step(&c, xd, x, Vel::from_bits(v));
            let r = RefPid::default().step(&c.pid, pos_err(xd, x), v as f64);
            let err = (out.tau as f64 - r).abs();
            w.see(err);
            prop_assert!(err <= 1.0, "fixed {} ref {r}", out.tau);
            prop_assert!(out.tau.abs() <= lim);
            let unclamped = (g(kp) * pos_err(xd, x) - g(kd) * v as f64).abs();
            if unclamped > lim as f64 + 1.0 {
                prop_assert!(out.flags.contains(Flags::OUTPUT_SATURATED));
            }
            if unclamped < lim as f64 - 1.0 {
                prop_assert!(!out.flags.contains(Flags::OUTPUT_SATURATED));
            }
            let clamped = xd
                .checked_sub(x)
                .map(|d| d != d as i32 as i64)
                .unwrap_or(true);
            prop_assert_eq!(out.flags.contains(Flags::INPUT_CLAMPED), clamped);
            Ok(())
        },
    );
    w.report("1");
}

#[test]
fn pid_sequence_tracks_f64() {
    let w = Worst::new(NAME_W_PID);
    run(
        400,
        &(
            gain_strat(),
            gain_strat(),
            gain_strat(),
            0i32..=32767,
            lim_strat(),
            prop::collection::vec((i32_strat(), i32_strat()), 1..300),
        ),
        |(kp, kd, ki, il, lim, seq)| {
            let c = PidConfig {
                kp,
                kd,
                ki_t: ki,
                i_limit: il,
                tau_max: lim,
            };
            let mut s = PidState::default();
            let mut r = RefPid::default();
            for (e, v) in seq {
                let o = s.step(&c, e, v);
                let y = r.step(&c, e as f64, v as f64);
                let err = (o.tau as f64 - y).abs();
                w.see(err);
                prop_assert!(err <= 3.0, "fixed {} ref {y}", o.tau);
                prop_assert!(o.tau.abs() <= lim);
                prop_assert!(s.integrator().abs() <= il);
            }
            Ok(())
        },
    );
    w.report("3");
}

#[test]
fn damper_tracks_f64() {
    let w = Worst::new(NAME_W_DAMP);
    run(
        3000,
        &(gain_strat(), lim_strat(), i32_strat()),
        |(b, lim, v)| {
            let c = DamperConfig { b, tau_max: lim };
            let o = DamperLaw.step(&c, Vel::from_bits(v));
            let r = clamp(-g(b) * v as f64, lim);
            let err = (o.tau as f64 - r).abs();
            w.see(err);
            prop_assert!(err <= 0.5);
            let idamp = InputDamping { b1e: b }.torque(Vel::from_bits(v));
            prop_assert!((idamp as f64 + g(b) * v as f64).abs() <= 0.5);
            Ok(())
        },
    );
    w.report("0.5");
}

#[test]
fn impedance_tracks_f64() {
    let w = Worst::new(NAME_W_IMP);
    run(
        3000,
        &(
            gain_strat(),
            gain_strat(),
            gain_strat(),
            lim_strat(),
            any::<i64>(),
            any::<i64>(),
            i32_strat(),
            i32_strat(),
        ),
        |(ke, be, km, lim, xd, x, v, te)| {
            let c = ImpedanceConfig {
                ke,
                be,
                km,
                tau_max: lim,
                feedback: Feedback::Colocated,
            };
            let o = ImpedanceLaw.step(&c, xd, x, Vel::from_bits(v), te);
            let r = ref_impedance(&c, pos_err(xd, x), v as f64, te as f64);
            let err = (o.tau as f64 - r).abs();
            w.see(err);
            prop_assert!(err <= 2.0, "fixed {} ref {r}", o.tau);
            Ok(())
        },
    );
    w.report("2");
}

#[test]
fn force_input_velocity_tracks_f64() {
    let w = Worst::new(NAME_W_FORCE_V);
    run(
        400,
        &(
            gain_strat(),
            gain_strat(),
            gain_strat(),
            0i32..=32767,
            lim_strat(),
            prop::collection::vec((i32_strat(), i32_strat(), i32_strat()), 1..200),
        ),
        |(kp, kd, ki, il, lim, seq)| {
            let c = ForceConfig {
                pid: PidConfig {
                    kp,
                    kd,
                    ki_t: ki,
                    i_limit: il,
                    tau_max: lim,
                },
                damping: ForceDamping::InputVelocity,
            };
            let mut s = ForceLaw::default();
            let mut r = RefPid::default();
            for (td, te, v) in seq {
                let o = s.step(&c, td, te, Vel::from_bits(v));
                let e = (td as i64 - te as i64).clamp(i32::MIN as i64, i32::MAX as i64) as f64;
                let y = r.step(&c.pid, e, v as f64);
                let err = (o.tau as f64 - y).abs();
                w.see(err);
                prop_assert!(err <= 3.0, "fixed {} ref {y}", o.tau);
            }
            Ok(())
        },
    );
    w.report("3");
}

#[test]
fn force_rate_tracks_f64() {
    let w = Worst::new(NAME_W_FORCE_R);
    let kd_strat =
        (-(1i32 << 24)..(1i32 << 24), 20u8..=30).prop_map(|(m, s)| Gain::from_parts(m, s).unwrap());
    let seq_strat =
        prop::collection::vec((-1_000_000i32..1_000_000, -1_000_000i32..1_000_000), 1..200);
    run(
        400,
        &(
            gain_strat(),
            kd_strat,
            gain_strat(),
            0i32..=32767,
            lim_strat(),
            alpha_strat(),
            seq_strat,
        ),
        |(kp, kd, ki, il, lim, a, seq)| {
            let c = ForceConfig {
                pid: PidConfig {
                    kp,
                    kd,
                    ki_t: ki,
                    i_limit: il,
                    tau_max: lim,
                },
                damping: ForceDamping::ForceRate { alpha: a },
            };
            let mut s = ForceLaw::default();
            let mut r = RefPid::default();
            let mut lp = RefLp::default();
            let mut last: Option<f64> = None;
            let bound = 3.0 + 0.5 * g(kd).abs() + 1e-9;
            for (td, te) in seq {
                let o = s.step(&c, td, te, Vel::ZERO);
                let rate = last.map(|l| te as f64 - l).unwrap_or(0.0);
                last = Some(te as f64);
                let rf = lp.step(rate, a);
                let y = r.step(&c.pid, td as f64 - te as f64, rf);
                let err = (o.tau as f64 - y).abs();
                w.see(err - 0.5 * g(kd).abs());
                prop_assert!(err <= bound, "fixed {} ref {y} bound {bound}", o.tau);
            }
            Ok(())
        },
    );
    w.report("3 + 0.5·|Kd| (figure shown: err − 0.5·|Kd|)");
}

#[test]
fn friction_tracks_f64() {
    let w = Worst::new(NAME_W_FRIC);
    run(
        3000,
        &(
            0i32..=32767,
            0i32..=32767,
            pos_gain_strat(),
            pos_gain_strat(),
            pos_gain_strat(),
            0u16..=49152,
            lim_strat(),
            i32_strat(),
        ),
        |(tp, tn, sp, sn, visc, u, lim, v)| {
            let c = FrictionConfig {
                tau_c_pos: tp,
                tau_c_neg: tn,
                slope_pos: sp,
                slope_neg: sn,
                viscous: visc,
                undercomp: Alpha::from_bits(u),
                limit: lim,
                alpha: Alpha::ONE,
            };
            let o = FrictionComp::default().step(&c, Vel::from_bits(v));
            let r = ref_friction(&c, v as f64);
            let err = (o.tau as f64 - r).abs();
            w.see(err);
            prop_assert!(err <= 2.0, "fixed {} ref {r}", o.tau);
            // direction: the feed-forward never opposes the motion
            prop_assert!(o.tau as i64 * v as i64 >= 0);
            Ok(())
        },
    );
    w.report("2");
}

#[test]
fn impcomp_tracks_f64() {
    let w = Worst::new(NAME_W_IC);
    let seq_strat = prop::collection::vec(
        (
            -(1i64 << 40)..(1i64 << 40),
            -(1i64 << 40)..(1i64 << 40),
            i32_strat(),
        ),
        1..200,
    );
    run(
        400,
        &(
            gain_strat(),
            -(1i32 << 30)..(1i32 << 30),
            alpha_strat(),
            lim_strat(),
            seq_strat,
        ),
        |(kd, gm, a, lim, seq)| {
            // |Kc/N| ≤ 1: mantissa < 2³⁰ with shift 30
            let gain = Gain::from_parts(gm, 30).unwrap();
            let c = ImpCompConfig {
                kd,
                gain,
                alpha: a,
                limit: lim,
            };
            let mut s = ImpComp::default();
            let mut lp = RefLp::default();
            for (xd, x, te) in seq {
                let o = s.step(&c, xd, x, te);
                let df =
                    (g(kd) * pos_err(xd, x) - te as f64).clamp(i32::MIN as f64, i32::MAX as f64);
                let y = clamp(g(gain) * lp.step(df, a), lim);
                let err = (o.tau as f64 - y).abs();
                w.see(err);
                prop_assert!(err <= 2.0, "fixed {} ref {y}", o.tau);
            }
            Ok(())
        },
    );
    w.report("2");
}

#[test]
fn ripple_tracks_f64() {
    let w = Worst::new(NAME_W_RIP);
    run(
        3000,
        &(
            prop::collection::vec(any::<i16>(), 2..=64),
            0u32..100_000,
            any::<i64>(),
        ),
        |(entries, extra, x)| {
            let period = entries.len() as u32 + extra;
            let t = RippleTable::new(period, &entries).unwrap();
            let y = t.torque(x);
            let r = ref_ripple(&t, x);
            let err = (y as f64 - r).abs();
            w.see(err);
            prop_assert!(err <= 0.5 + 1e-9, "fixed {y} ref {r}");
            Ok(())
        },
    );
    w.report("0.5");
}

#[test]
fn joint_pipeline_tracks_f64() {
    let w = Worst::new(NAME_W_JOINT);
    run(
        400,
        &(
            gain_strat(),
            gain_strat(),
            gain_strat(),
            gain_strat(),
            pos_gain_strat(),
            pos_gain_strat(),
            gain_strat(),
            alpha_strat(),
            prop::collection::vec(-3000i16..3000, 2..=64),
            prop::collection::vec(
                (
                    -(1i64 << 40)..(1i64 << 40),
                    -(1i64 << 40)..(1i64 << 40),
                    i32_strat(),
                    i32_strat(),
                ),
                1..100,
            ),
        ),
        |(kp, kd, ki, b1e, fsl, fv, ickd, a, entries, seq)| {
            let pid = PidConfig {
                kp,
                kd,
                ki_t: ki,
                i_limit: 20000,
                tau_max: 30000,
            };
            let fr = FrictionConfig {
                tau_c_pos: 300,
                tau_c_neg: 250,
                slope_pos: fsl,
                slope_neg: fsl,
                viscous: fv,
                undercomp: DEFAULT_UNDERCOMP,
                limit: 2000,
                alpha: Alpha::ONE,
            };
            let ic = ImpCompConfig {
                kd: ickd,
                gain: Gain::from_parts(1 << 29, 30).unwrap(),
                alpha: a,
                limit: 3000,
            };
            let rip = RippleTable::new(128, &entries).unwrap();
            let cfg = JointConfig {
                mode: Mode::Position(PositionConfig {
                    pid,
                    feedback: Feedback::Colocated,
                }),
                input_damping: InputDamping { b1e },
                friction: Some(fr),
                imp_comp: Some(ic),
                ripple: Some(rip.clone()),
                friction_on_setpoint: false,
                offset: 0,
                gravity: None,
                tau_max: 32767,
                transfer_shift: 6,
            };
            let mut st = JointState::new();
            let mut rp = RefPid::default();
            let mut lp = RefLp::default();
            for (xd, x, v, te) in seq {
                let m = Measurements {
                    x1: x,
                    v1: Vel::from_bits(v),
                    x2: 0,
                    v2: Vel::ZERO,
                    tau_env: te,
                };
                let o = st.step(
                    &cfg,
                    &Setpoint {
                        x_d: xd,
                        tau_d: 0,
                        ..Default::default()
                    },
                    &m,
                );
                let e = pos_err(xd, x);
                let mut y = rp.step(&pid, e, v as f64);
                y += -g(b1e) * v as f64;
                y += ref_friction(&fr, v as f64);
                let df = (g(ickd) * e - te as f64).clamp(i32::MIN as f64, i32::MAX as f64);
                y += clamp(g(ic.gain) * lp.step(df, a), ic.limit);
                y += ref_ripple(&rip, x);
                let y = clamp(y, 32767);
                let err = (o.out.tau as f64 - y).abs();
                w.see(err);
                prop_assert!(err <= 9.0, "fixed {} ref {y}", o.out.tau);
            }
            Ok(())
        },
    );
    w.report("9");
}

// ------------------------------------------------------------------------------------------
// extreme values: no panic, limits hold, saturation flagged

fn any_gain() -> impl Strategy<Value = Gain> {
    (any::<i32>(), 0u8..=62).prop_map(|(m, s)| Gain::from_parts(m, s).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn extremes_never_panic_and_respect_limits(
        kp in any_gain(), kd in any_gain(), ki in any_gain(), km in any_gain(), b in any_gain(),
        il in any::<i32>(), lim in any::<i32>(), a in any::<u16>(),
        entries in prop::collection::vec(any::<i16>(), 2..=64), period in 64u32..=u32::MAX,
        tp in any::<i32>(), tn in any::<i32>(), shift in any::<u8>(),
        seq in prop::collection::vec((any::<i64>(), any::<i64>(), any::<i32>(), any::<i32>(), any::<i32>()), 1..60),
        mode_sel in 0u8..5, fb in any::<bool>(),
    ) {
        let pid = PidConfig { kp, kd, ki_t: ki, i_limit: il, tau_max: lim };
        let feedback = if fb { Feedback::NonColocated } else { Feedback::Colocated };
        let alpha = Alpha::from_bits(a);
        let mode = match mode_sel {
            0 => Mode::Position(PositionConfig { pid, feedback }),
            1 => Mode::Force(ForceConfig { pid, damping: ForceDamping::ForceRate { alpha } }),
            2 => Mode::Force(ForceConfig { pid, damping: ForceDamping::InputVelocity }),
            3 => Mode::Impedance(ImpedanceConfig { ke: kp, be: kd, km, tau_max: lim, feedback }),
            _ => Mode::Damper(DamperConfig { b, tau_max: lim }),
        };
        let cfg = JointConfig {
            mode,
            input_damping: InputDamping { b1e: b },
            friction: Some(FrictionConfig { tau_c_pos: tp, tau_c_neg: tn, slope_pos: kp, slope_neg: kd, viscous: b, undercomp: alpha, limit: lim, alpha: Alpha::ONE }),
            imp_comp: Some(ImpCompConfig { kd: km, gain: ki, alpha, limit: lim }),
            ripple: Some(RippleTable::new(period, &entries).unwrap()),
            friction_on_setpoint: false,
            offset: 0,
            gravity: None,
            tau_max: lim,
            transfer_shift: shift,
        };
        let mut st = JointState::new();
        let final_lim = lim.clamp(0, 32767);
        let mut prev = 0;
        for (k, (xd, x, v, te, td)) in seq.into_iter().enumerate() {
            let m = Measurements { x1: x, v1: Vel::from_bits(v), x2: xd ^ x, v2: Vel::from_bits(te), tau_env: te };
            let sp = Setpoint { x_d: xd, tau_d: td, ..Default::default() };
            if k % 7 == 3 {
                st.init_bumpless(&cfg, prev, &sp, &m);
            }
            let o = st.step(&cfg, &sp, &m);
            prop_assert!(o.out.tau.abs() <= final_lim);
            prop_assert!(o.command() as i32 == o.out.tau);
            prev = o.out.tau;
        }
    }
}

#[test]
fn saturation_is_flagged() {
    let c = PositionConfig {
        pid: PidConfig::pd(Gain::from_parts(100, 0).unwrap(), Gain::ZERO, 1000),
        feedback: Feedback::Colocated,
    };
    let o = PositionLaw::default().step(&c, 11, 0, Vel::ZERO);
    assert_eq!(o.tau, 1000);
    assert!(o.flags.contains(Flags::OUTPUT_SATURATED));
    let o = PositionLaw::default().step(&c, 10, 0, Vel::ZERO);
    assert_eq!(o.tau, 1000);
    assert!(!o.flags.contains(Flags::OUTPUT_SATURATED));
    let o = PositionLaw::default().step(&c, i64::MAX, i64::MIN, Vel::ZERO);
    assert!(o.flags.contains(Flags::INPUT_CLAMPED) && o.flags.contains(Flags::OUTPUT_SATURATED));
    // integrator limit flagged
    let pid = PidConfig {
        kp: Gain::ZERO,
        kd: Gain::ZERO,
        ki_t: Gain::from_parts(1 << 16, 0).unwrap(),
        i_limit: 50,
        tau_max: 1000,
    };
    let mut s = PidState::default();
    let mut f = Flags::NONE;
    for _ in 0..100 {
        f = s.step(&pid, 1, 0).flags;
    }
    assert_eq!(s.integrator(), 50);
    assert!(f.contains(Flags::INTEGRATOR_LIMITED));
    // joint final clamp flagged
    let cfg = JointConfig {
        mode: Mode::Position(c),
        ripple: Some(RippleTable::new(10, &[500, 500]).unwrap()),
        tau_max: 1200,
        ..JointConfig::default()
    };
    let o = JointState::new().step(
        &cfg,
        &Setpoint {
            x_d: 50,
            tau_d: 0,
            ..Default::default()
        },
        &Measurements::default(),
    );
    assert_eq!(o.out.tau, 1200);
    assert!(o.out.flags.contains(Flags::OUTPUT_SATURATED));
}

// ------------------------------------------------------------------------------------------
// bumpless transfer

fn gain(v: f64) -> Gain {
    controller::units::gain_from_f64("test", v).unwrap()
}

fn pos_cfg(ke: f64, be: f64, ki_t: f64) -> JointConfig {
    JointConfig {
        mode: Mode::Position(PositionConfig {
            pid: PidConfig {
                kp: gain(ke),
                kd: gain(be),
                ki_t: if ki_t == 0.0 { Gain::ZERO } else { gain(ki_t) },
                i_limit: 20000,
                tau_max: 30000,
            },
            feedback: Feedback::Colocated,
        }),
        friction: Some(FrictionConfig {
            tau_c_pos: 200,
            tau_c_neg: 150,
            slope_pos: gain(0.5),
            slope_neg: gain(0.4),
            viscous: Gain::ZERO,
            undercomp: DEFAULT_UNDERCOMP,
            limit: 1000,
            alpha: Alpha::ONE,
        }),
        input_damping: InputDamping { b1e: gain(0.01) },
        tau_max: 32000,
        transfer_shift: 6,
        ..JointConfig::default()
    }
}

#[test]
fn bumpless_gain_commit_pd_and_pid() {
    let sp = Setpoint {
        x_d: 1000,
        tau_d: 0,
        ..Default::default()
    };
    let m = Measurements {
        x1: 800,
        v1: Vel::from_num(37.5),
        tau_env: 123,
        ..Default::default()
    };
    for (a, b) in [
        (pos_cfg(10.0, 0.02, 0.0), pos_cfg(25.0, 0.05, 0.0)), // PD → PD
        (pos_cfg(10.0, 0.02, 300.0), pos_cfg(4.0, 0.01, 900.0)), // PID → PID
        (pos_cfg(10.0, 0.02, 0.0), pos_cfg(30.0, 0.02, 500.0)), // PD → PID
        (pos_cfg(30.0, 0.02, 500.0), pos_cfg(3.0, 0.0, 0.0)), // PID → PD
    ] {
        let mut st = JointState::new();
        let mut prev = 0;
        for _ in 0..50 {
            prev = st.step(&a, &sp, &m).out.tau;
        }
        let would_jump = {
            let mut t = st;
            t.step(&b, &sp, &m).out.tau
        };
        st.init_bumpless(&b, prev, &sp, &m);
        let next = st.step(&b, &sp, &m).out.tau;
        println!("[bumpless] commit: prev {prev}, without hook {would_jump}, with hook {next}");
        assert!((next - prev).abs() <= 1, "prev {prev} next {next}");
        assert!(
            (would_jump - prev).abs() > 100,
            "test must exercise a real jump"
        );
        // and the new law takes over: offset decays to zero in bounded time
        let mut k = 0;
        while st.offset != 0 && k < 2000 {
            st.step(&b, &sp, &m);
            k += 1;
        }
        assert_eq!(st.offset, 0, "offset must decay");
        if let Mode::Position(pc) = b.mode {
            if !pc.pid.has_integrator() {
                // after the transfer a PD is exactly the PD: no hidden integrator bias
                let fresh = JointState::new().step(&b, &sp, &m).out.tau;
                assert_eq!(st.step(&b, &sp, &m).out.tau, fresh);
            }
        }
        println!("[bumpless]   offset decayed in {k} ticks");
    }
}

#[test]
fn ki_change_is_bumpless_without_the_hook() {
    // integrator is kept in torque units: changing Ki changes only the slope
    let mut c = PidConfig {
        kp: gain(5.0),
        kd: Gain::ZERO,
        ki_t: gain(2000.0),
        i_limit: 30000,
        tau_max: 32000,
    };
    let mut s = PidState::default();
    let mut prev = 0;
    for _ in 0..100 {
        prev = s.step(&c, 40, 0).tau;
    }
    c.ki_t = gain(9000.0);
    let next = s.step(&c, 40, 0).tau;
    let step_inc = 9000.0 * 40.0 / 65536.0;
    assert!(
        ((next - prev) as f64 - step_inc).abs() <= 1.0,
        "prev {prev} next {next}"
    );
}

#[test]
fn bumpless_mode_switches() {
    let imp = Mode::Impedance(ImpedanceConfig {
        ke: gain(8.0),
        be: gain(0.01),
        km: gain(-0.3),
        tau_max: 30000,
        feedback: Feedback::Colocated,
    });
    let force_pi = Mode::Force(ForceConfig {
        pid: PidConfig {
            kp: gain(0.5),
            kd: gain(0.2),
            ki_t: gain(500.0),
            i_limit: 20000,
            tau_max: 30000,
        },
        damping: ForceDamping::ForceRate {
            alpha: Alpha::from_num(0.3),
        },
    });
    let force_p = Mode::Force(ForceConfig {
        pid: PidConfig::pd(gain(2.0), gain(0.05), 30000),
        damping: ForceDamping::InputVelocity,
    });
    let damper = Mode::Damper(DamperConfig {
        b: gain(3.0),
        tau_max: 30000,
    });
    let pos = pos_cfg(10.0, 0.02, 200.0).mode;
    let modes = [pos, imp, force_pi, damper, force_p, pos, Mode::Off, imp];
    let sp = Setpoint {
        x_d: 1000,
        tau_d: 2500,
        ..Default::default()
    };
    let m = Measurements {
        x1: 700,
        v1: Vel::from_num(-120),
        x2: 7,
        tau_env: 900,
        ..Default::default()
    };
    let mut st = JointState::new();
    let base = JointConfig {
        tau_max: 32000,
        ..JointConfig::default()
    };
    let mut cfg = JointConfig {
        mode: modes[0],
        ..base.clone()
    };
    let mut prev = 0;
    for _ in 0..30 {
        prev = st.step(&cfg, &sp, &m).out.tau;
    }
    for mode in &modes[1..] {
        cfg = JointConfig {
            mode: *mode,
            ..base.clone()
        };
        st.init_bumpless(&cfg, prev, &sp, &m);
        let next = st.step(&cfg, &sp, &m).out.tau;
        println!(
            "[bumpless] switch to {:?}: prev {prev} next {next}",
            mode.kind()
        );
        assert!(
            (next - prev).abs() <= 1,
            "{:?}: prev {prev} next {next}",
            mode.kind()
        );
        prev = next;
        for _ in 0..30 {
            prev = st.step(&cfg, &sp, &m).out.tau;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]
    #[test]
    fn bumpless_commit_any_gains(ke1 in 0.0f64..200.0, be1 in 0.0f64..2.0, ki1 in 0.0f64..5000.0,
                                 ke2 in 0.0f64..200.0, be2 in 0.0f64..2.0, ki2 in 0.0f64..5000.0,
                                 xd in -100_000i64..100_000, x in -100_000i64..100_000, v in -50_000i32..50_000,
                                 warm in 0usize..50) {
        let a = pos_cfg(ke1, be1, if ki1 < 1.0 { 0.0 } else { ki1 });
        let b = pos_cfg(ke2, be2, if ki2 < 1.0 { 0.0 } else { ki2 });
        let sp = Setpoint { x_d: xd, tau_d: 0, ..Default::default() };
        let m = Measurements { x1: x, v1: Vel::from_bits(v), ..Default::default() };
        let mut st = JointState::new();
        let mut prev = 0;
        for _ in 0..warm {
            prev = st.step(&a, &sp, &m).out.tau;
        }
        st.init_bumpless(&b, prev, &sp, &m);
        let next = st.step(&b, &sp, &m).out.tau;
        prop_assert!((next - prev).abs() <= 1, "prev {prev} next {next}");
    }
}
