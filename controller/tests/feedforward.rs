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
