//! The feed-forward terms a workbench model turns into (offset, gravity, ripple phase),
//! checked against a float reference written here, not against the card's own table.

use controller::card::config;
use controller::card::ParamStore;
use controller::laws::{JointState, Measurements, RippleTable, Setpoint};
use controller::proto::params as p;
use proptest::prelude::*;

fn built(entries: &[(u16, i32)]) -> config::CardConfig {
    let mut s = ParamStore::new();
    s.apply(entries);
    config::build(&s, None).expect("a valid set")
}

fn torque_at(cfg: &config::CardConfig, x1: i64) -> i32 {
    let m = Measurements {
        x1,
        ..Measurements::default()
    };
    JointState::new()
        .step(&cfg.joint, &Setpoint::default(), &m)
        .out
        .tau
}

proptest! {
    /// Gravity is `s·sin θ + c·cos θ` of the output angle θ = 2π·x / (cpr·N), to 0.2 % of
    /// the amplitude and 1 LSB, over several turns either way; the offset adds exactly.
    #[test]
    fn gravity_and_offset_follow_the_output_angle(
        gs in -20_000i32..20_000,
        gc in -20_000i32..20_000,
        offset in -3_000i32..3_000,
        ratio in 1u32..120,
        turns in -5.0f64..5.0,
    ) {
        let cpr = 2304i32;
        let cfg = built(&[
            (p::TORQUE_LIMIT, 32_767),
            (p::MOTOR_COUNTS_PER_REV, cpr),
            (p::GEAR_RATIO, (ratio << 16) as i32),
            (p::GRAVITY_SIN, gs),
            (p::GRAVITY_COS, gc),
            (p::TORQUE_OFFSET, offset),
        ]);
        let per_rev = f64::from(cpr) * f64::from(ratio);
        let x = (turns * per_rev).round() as i64;
        let theta = std::f64::consts::TAU * x as f64 / per_rev;
        let want = f64::from(gs) * theta.sin() + f64::from(gc) * theta.cos() + f64::from(offset);
        let amp = f64::from(gs).hypot(f64::from(gc));
        let got = f64::from(torque_at(&cfg, x));
        prop_assert!((got - want.clamp(-32767.0, 32767.0)).abs() <= 0.002 * amp + 1.5,
            "x {x}: got {got}, want {want:.1} (amplitude {amp:.0})");
    }

    /// A phase shifts the lookup: the table at x + phase is the unshifted table there.
    #[test]
    fn ripple_phase_shifts_the_lookup(
        entries in prop::collection::vec(-3000i16..3000, 2..=64),
        period_extra in 0u32..5000,
        phase in 0u32..100_000,
        x in -1_000_000i64..1_000_000,
    ) {
        let period = entries.len() as u32 + period_extra;
        let t = RippleTable::new(period, &entries).unwrap();
        let shifted = t.clone().with_phase(phase);
        prop_assert_eq!(shifted.torque(x), t.torque(x + i64::from(phase)));
    }
}

/// The card's parameter path: ripple_phase reaches the table.
#[test]
fn ripple_phase_parameter_reaches_the_table() {
    let mut e = vec![
        (p::TORQUE_LIMIT, 32_767),
        (p::RIPPLE_ENABLE, 1),
        (p::RIPPLE_PERIOD, 400),
        (p::RIPPLE_LENGTH, 4),
        (p::RIPPLE_PHASE, 100),
    ];
    e.extend((0..4).map(|i| (p::RIPPLE_TABLE + i, 1000 * i32::from(i))));
    let cfg = built(&e);
    // x = 0 looks up phase 100 = entry 1.
    assert_eq!(torque_at(&cfg, 0), 1000);
    assert_eq!(torque_at(&cfg, 200), 3000);
    assert_eq!(torque_at(&cfg, 300), 0);
}

/// Both amplitudes 0: no table, no cost in the 1 kHz path.
#[test]
fn no_gravity_without_amplitudes() {
    let cfg = built(&[(p::TORQUE_LIMIT, 1000)]);
    assert!(cfg.joint.gravity.is_none());
}

/// Under-compensation above 1 reaches the law (the thesis's over-compensation, shown by the
/// lab's coulomb-ff scenario): at 1.2 the friction term is 1.2× its value at 1.0.
#[test]
fn under_compensation_above_one_scales_the_friction_term() {
    let friction = |u: Option<i32>| {
        let mut e = vec![];
        if let Some(u) = u {
            e.extend([
                (p::FRICTION_ENABLE, 1),
                (p::COULOMB_POS, 2000),
                (p::BE, 0),
                (p::TORQUE_LIMIT, 10_000),
                (p::FRICTION_FILTER, 65_536),
                (p::UNDER_COMPENSATION, u),
            ]);
        }
        let cfg = built(&e);
        let m = Measurements {
            v1: controller::fixed_math::Vel::from_num(2000),
            ..Measurements::default()
        };
        JointState::new()
            .step(&cfg.joint, &Setpoint::default(), &m)
            .out
            .tau
    };
    let none = friction(None);
    let full = friction(Some(65_536)) - none;
    let over = friction(Some(78_643)) - none;
    assert_eq!(full, 2000);
    assert!((over - 2400).abs() <= 1, "{over}");
}

/// The velocity mode built from the card's parameters, against its definition: with Be as Kv
/// and Ke as Ki, a constant velocity error e gives τ = Be·e + Ke·(e·t) — here Be = 10 τLSB
/// per count/tick and Ke = 1 τLSB per count, e = 1000 counts/s = 1 count per 1 ms tick, so
/// tick n commands 10 + n (±1 for where the integrator's first step lands).
#[test]
fn velocity_mode_is_kv_times_the_error_plus_ki_times_its_integral() {
    let mut s = ParamStore::new();
    s.apply(&[
        (p::KE, 65_536),
        (p::BE, 10 * 65_536),
        (p::INTEGRATOR_LIMIT, 10_000),
        (p::TORQUE_LIMIT, 20_000),
    ]);
    let cfg = config::build(&s, Some(controller::proto::Mode::Velocity)).expect("a valid set");
    let m = Measurements::default();
    let mut st = JointState::new();
    let sp = Setpoint {
        v_d: controller::fixed_math::Vel::from_num(1000),
        ..Setpoint::default()
    };
    for n in 1..=200 {
        let tau = st.step(&cfg.joint, &sp, &m).out.tau;
        assert!((tau - (10 + n)).abs() <= 1, "tick {n}: {tau}");
    }
}

/// In the non-colocated modes Ke and Be are per output-encoder count (protocol, "Modes"), so
/// the §2.9 guard must take them to the motor through the encoders' ratio: with 8 output
/// counts per motor-equivalent count, the largest Ke it admits per output count is 8 times
/// smaller than per motor count at the same damping, and the same rigid joint.
#[test]
fn the_guard_reads_non_colocated_gains_per_output_count() {
    use controller::proto::Mode;
    let n = 30;
    let base = [
        (p::ROTOR_INERTIA, 10_000),
        (p::MOTOR_COUNTS_PER_REV, 2304),
        (p::GEAR_RATIO, n * 65_536),
        (p::OUTPUT_COUNTS_PER_REV, 2304 * n * 8),
        (p::TORQUE_LIMIT, 20_000),
        (p::STABILITY_MARGIN, 65_536),
    ];
    // The largest KE the card accepts in `mode` with BE = `be`, by bisection on the raw value.
    let largest = |mode: Mode, be: i32| {
        let accepts = |ke: i32| {
            let mut s = ParamStore::new();
            s.apply(&base);
            s.apply(&[(p::KE, ke), (p::BE, be)]);
            config::build(&s, Some(mode)).is_ok()
        };
        let (mut lo, mut hi) = (1i32, i32::MAX / 2);
        assert!(accepts(lo) && !accepts(hi));
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if accepts(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    for be in [8 * 20_000, 8 * 200_000, 8 * 2_000_000] {
        let colocated = largest(Mode::PositionPdColocated, be);
        let per_output = largest(Mode::PositionPdNonColocated, be / 8);
        let ratio = f64::from(colocated) / f64::from(per_output);
        assert!(
            (ratio / 8.0 - 1.0).abs() < 1e-3,
            "BE {be}: {colocated} vs {per_output}"
        );
    }
}

/// The position hold (a colocated PD on the motor encoder, used by the `HoldPosition`
/// reaction) takes a non-colocated mode's gains to motor counts: with 8 output counts per
/// motor count, the same raw gain per output count is 8 times the torque per motor count.
#[test]
fn the_hold_takes_non_colocated_gains_to_motor_counts() {
    use controller::proto::Mode;
    let mut s = ParamStore::new();
    s.apply(&[
        (p::MOTOR_COUNTS_PER_REV, 2304),
        (p::GEAR_RATIO, 30 * 65_536),
        (p::OUTPUT_COUNTS_PER_REV, 2304 * 30 * 8),
        (p::KE, 8 * 65_536),
        (p::BE, 800 * 65_536),
        (p::ROTOR_INERTIA, 1_000_000),
    ]);
    let nc = config::build(&s, Some(Mode::PositionPdNonColocated)).expect("a valid set");
    let co = config::build(&s, Some(Mode::PositionPdColocated)).expect("a valid set");
    let ratio =
        |a: controller::fixed_math::Gain, b: controller::fixed_math::Gain| a.to_f64() / b.to_f64();
    assert!((ratio(nc.hold.pid.kp, co.hold.pid.kp) - 8.0).abs() < 1e-3);
    assert!((ratio(nc.hold.pid.kd, co.hold.pid.kd) - 8.0).abs() < 1e-3);
}
