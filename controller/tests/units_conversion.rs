//! `units`: SI → machine gains, typed errors, and the §2.9 stability guard (checked against a
//! direct simulation of the discrete loop, and integer vs f64 variants against each other).

use controller::fixed_math::Gain;
use controller::laws::{Feedback, RippleError};
use controller::proto::scale::MOTOR_TORQUE_NM_PER_LSB;
use controller::units::*;
use proptest::prelude::*;
use std::f64::consts::TAU;

fn s2304() -> Scale {
    Scale::thesis(30.0)
}

#[test]
fn stiffness_and_damping_scale() {
    let s = s2304();
    // 1 N·m/rad at 2304 cpr: 2π/2304 N·m per count = 27.27 LSB/count
    let g = stiffness_gain(&s, Feedback::Colocated, "ke", 1.0).unwrap();
    let want = TAU / 2304.0 / MOTOR_TORQUE_NM_PER_LSB;
    assert!((g.to_f64() / want - 1.0).abs() < 1e-9, "{}", g.to_f64());
    // damping per Vel LSB (1/16 count/s)
    let b = damping_gain(&s, Feedback::Colocated, "be", 1.0).unwrap();
    assert!((b.to_f64() / (want / 16.0) - 1.0).abs() < 1e-9);
    // non-colocated: output encoder, motor delivers 1/N
    let sn = Scale {
        output_cpr: 1 << 16,
        ..s
    };
    let g = stiffness_gain(&sn, Feedback::NonColocated, "ke", 30.0).unwrap();
    let want = TAU / 65536.0 / MOTOR_TORQUE_NM_PER_LSB;
    assert!((g.to_f64() / want - 1.0).abs() < 1e-9);
    // a coarser torque LSB (1 mN·m) gives 10× smaller machine gains and limits
    let coarse = Scale {
        torque_lsb_nm: 1e-3,
        ..s
    };
    let gc = stiffness_gain(&coarse, Feedback::Colocated, "ke", 1.0).unwrap();
    let g1 = stiffness_gain(&s, Feedback::Colocated, "ke", 1.0).unwrap();
    assert!((gc.to_f64() * 10.0 / g1.to_f64() - 1.0).abs() < 1e-9);
    assert_eq!(torque_limit(&coarse, "tau_max", 2.0), Ok(2000));
    assert_eq!(torque_limit(&s, "tau_max", 2.0), Ok(20000));
    let bad = Scale {
        torque_lsb_nm: 0.0,
        ..s
    };
    assert_eq!(
        torque_limit(&bad, "tau_max", 2.0),
        Err(UnitsError::BadScale {
            what: "torque_lsb_nm"
        })
    );
    // no output encoder configured
    assert_eq!(
        stiffness_gain(&s, Feedback::NonColocated, "ke", 1.0),
        Err(UnitsError::BadScale { what: "output_cpr" })
    );
}

#[test]
fn thesis_gain_scaling_rule() {
    // 8.41 = (29/10)²: the same output behaviour needs the output gain / N² at the motor
    assert!((motor_gain_from_output(8.41, 2.9) - 1.0).abs() < 1e-12);
    // notes §1: 0.21 N·m/deg output at 30:1 is 3.65e-5 N·m/count at the motor
    let k_out = 0.21 * 360.0 / TAU; // N·m/rad
    let k_m = motor_gain_from_output(k_out, 30.0);
    let per_count = k_m * TAU / 2304.0;
    println!("[units] 0.21 N·m/deg output @30:1 → {per_count:.3e} N·m/count at the motor");
    assert!((per_count / 3.65e-5 - 1.0).abs() < 0.01);
    // and 68 N·m/deg → 1.18e-2 N·m/count: ≈ 320:1 range, both representable
    let hi = motor_gain_from_output(68.0 * 360.0 / TAU, 30.0);
    let s = s2304();
    let lo_g = stiffness_gain(&s, Feedback::Colocated, "ke", k_m).unwrap();
    let hi_g = stiffness_gain(&s, Feedback::Colocated, "ke", hi).unwrap();
    println!(
        "[units] motor gains: {:.4} and {:.2} LSB/count (ratio {:.0})",
        lo_g.to_f64(),
        hi_g.to_f64(),
        hi_g.to_f64() / lo_g.to_f64()
    );
    assert!((hi_g.to_f64() / lo_g.to_f64() - 68.0 / 0.21).abs() < 1e-3);
}

#[test]
fn typed_errors() {
    let s = s2304();
    assert!(matches!(
        gain_from_f64("x", 3e9),
        Err(UnitsError::Overflow { what: "x", .. })
    ));
    assert!(matches!(
        gain_from_f64("x", 1e-30),
        Err(UnitsError::RoundsToZero { what: "x", .. })
    ));
    assert!(matches!(
        gain_from_f64("x", f64::NAN),
        Err(UnitsError::NotFinite { what: "x" })
    ));
    assert_eq!(gain_from_f64("x", 0.0), Ok(Gain::ZERO));
    assert!(matches!(
        torque_limit(&s, "tau_max", 3.3),
        Err(UnitsError::Overflow {
            what: "tau_max",
            ..
        })
    ));
    assert!(matches!(
        torque_limit(&s, "tau_max", -1.0),
        Err(UnitsError::OutOfRange { what: "tau_max" })
    ));
    let bad = Scale { motor_cpr: 0, ..s };
    assert!(matches!(
        stiffness_gain(&bad, Feedback::Colocated, "ke", 1.0),
        Err(UnitsError::BadScale { what: "motor_cpr" })
    ));
    let imp = ImpedanceSi {
        ke: 1.0,
        be: 0.01,
        km: 1.0,
        tau_max_nm: 1.0,
        feedback: Feedback::Colocated,
    };
    assert_eq!(
        impedance_config(&s, &imp),
        Err(UnitsError::OutOfRange { what: "km" })
    );
    assert!(impedance_config(
        &s,
        &ImpedanceSi {
            km: km_from_inertia(2.0, 1.0),
            ..imp
        }
    )
    .is_ok());
    assert_eq!(
        ripple_table(&s, 128, &[0.0; 65]).unwrap_err(),
        UnitsError::Ripple(RippleError::Length)
    );
    assert_eq!(
        ripple_table(&s, 10, &[0.0; 11]).unwrap_err(),
        UnitsError::Ripple(RippleError::Period)
    );
    assert!(matches!(
        ripple_table(&s, 128, &[0.0, 4.0]),
        Err(UnitsError::Overflow { what: "ripple", .. })
    ));
    assert_eq!(
        observer_config(&s, 400.0, 1.0, 100),
        Err(UnitsError::Observer)
    );
    let fr = FrictionSi {
        tau_c_pos: 0.1,
        tau_c_neg: -0.1,
        ramp_rad_s: 0.5,
        viscous: 0.0,
        undercomp: 0.8,
        limit_nm: 1.0,
    };
    assert_eq!(
        friction_config(&s, &fr),
        Err(UnitsError::OutOfRange { what: "tau_c_neg" })
    );
    assert!(friction_config(
        &s,
        &FrictionSi {
            tau_c_neg: 0.1,
            ..fr
        }
    )
    .is_ok());
    // a stiffness so small at a fine encoder that it rounds to zero is refused, not zeroed
    let fine = Scale {
        motor_cpr: u32::MAX,
        ..s
    };
    assert!(matches!(
        stiffness_gain(&fine, Feedback::Colocated, "ke", 1e-25),
        Err(UnitsError::RoundsToZero { what: "ke", .. })
    ));
    // the error message names the parameter
    let msg = std::format!("{}", gain_from_f64("be", 1e12).unwrap_err());
    assert!(msg.contains("be"), "{msg}");
}

#[test]
fn lowpass_alpha_uses_micromath_exp() {
    let s = s2304();
    let a = lowpass_alpha(&s, 10.0).unwrap().to_num::<f64>();
    let exact = 1.0 - (-TAU * 10.0 * 1e-3f64).exp();
    println!("[units] α(10 Hz) = {a:.5} (exact {exact:.5})");
    assert!((a - exact).abs() < 2e-3);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 5000, failure_persistence: None, ..ProptestConfig::default() })]
    #[test]
    fn gain_representation_error(m in 1.0f64..2.0, e in -30i32..31, neg in any::<bool>()) {
        let v = if neg { -m } else { m } * 2f64.powi(e);
        if let Ok(g) = gain_from_f64("v", v) {
            prop_assert!((g.to_f64() / v - 1.0).abs() <= 2f64.powi(-30));
        } else {
            prop_assert!(v.abs() >= 2147483647.0);
        }
    }
}

// ------------------------------------------------------------------------------------------
// §2.9 stability guard

#[test]
fn guard_thesis_numbers() {
    let (i, t) = (1e-5, 1e-3);
    // max kp ≈ 0.686 at kd ≈ 0.83 → Ke < 6.86 N·m/rad, Be = 0.0083
    let be = 0.83 * i / t;
    let ke_max = 0.686 * i / (t * t);
    let ok = pd_stability(0.79 * ke_max, be, i, t, DEFAULT_MARGIN).unwrap();
    println!(
        "[units] guard: kp {:.3}, kd {:.3}, kp_max {:.4}; margin {} %",
        ok.kp,
        ok.kd,
        ok.kp_max,
        DEFAULT_MARGIN * 100.0
    );
    assert!((ok.kp_max - 0.686).abs() < 0.001);
    assert_eq!(
        pd_stability(0.81 * ke_max, be, i, t, DEFAULT_MARGIN),
        Err(StabilityError::TooStiff)
    );
    // without margin the theoretical bound itself
    assert!(pd_stability(0.99 * ke_max, be, i, t, 0.0).is_ok());
    // 68 N·m/deg output through 10:1 ≈ 39 N·m/rad motor: refused (the KAMO limit cycles)
    let k = motor_gain_from_output(68.0 * 360.0 / TAU, 10.0);
    println!("[units] 68 N·m/deg @10:1 = {k:.1} N·m/rad at the motor");
    assert_eq!(
        pd_stability(k, be, i, t, DEFAULT_MARGIN),
        Err(StabilityError::TooStiff)
    );
    assert_eq!(
        pd_stability(1.0, 0.0, i, t, DEFAULT_MARGIN),
        Err(StabilityError::NoDamping)
    );
    assert_eq!(
        pd_stability(1.0, 1.7 * i / t, i, t, DEFAULT_MARGIN),
        Err(StabilityError::TooMuchDamping)
    );
    assert_eq!(
        pd_stability(-1.0, be, i, t, DEFAULT_MARGIN),
        Err(StabilityError::NegativeStiffness)
    );
    // damper mode (Ke = 0) is accepted
    assert!(pd_stability(0.0, be, i, t, DEFAULT_MARGIN).is_ok());
}

/// Rigid rotor, ZOH, τ_k = −Ke·θ_k − Be(θ_k − θ_{k−1})/T: `Some(true)` if it decays to 10⁻³,
/// `Some(false)` if it grows past 10⁶, `None` if 50 000 steps settle neither (a lightly
/// damped loop near the boundary, where the simulation is no evidence either way).
fn simulate_stable(kp: f64, kd: f64) -> Option<bool> {
    // normalised: I = 1, T = 1 ⇒ Ke = kp, Be = kd
    let (mut th, mut w, mut prev) = (1.0f64, 0.0f64, 1.0f64);
    for _ in 0..50_000 {
        let tau = -kp * th - kd * (th - prev);
        prev = th;
        th += w + 0.5 * tau;
        w += tau;
        if !th.is_finite() || th.abs() > 1e6 {
            return Some(false);
        }
    }
    (th.abs() < 1e-3 && w.abs() < 1e-3).then_some(true)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1500, failure_persistence: None, ..ProptestConfig::default() })]

    /// The closed form of notes §2.9 against the simulated discrete loop (pairs within 3 % of
    /// the boundary are skipped: convergence there is too slow to decide in 20 000 steps).
    #[test]
    fn closed_form_matches_simulation(kp in 0.001f64..1.0, kd in 0.001f64..2.2) {
        let bound = 2.0 * kd * (2.0 - kd) / (2.0 + kd);
        let inside = kd < 2.0 && kp < bound;
        let near = (kp / bound - 1.0).abs() < 0.03 || (kd - 2.0).abs() < 0.03 || bound <= 0.0 && kp < 0.03;
        if let (false, Some(stable)) = (near, simulate_stable(kp, kd)) {
            prop_assert_eq!(stable, inside, "kp {} kd {} bound {}", kp, kd, bound);
        }
    }

    /// Integer commit-time guard agrees with the f64 guard (away from the 20 % boundary).
    #[test]
    fn integer_guard_agrees(ke in 0.0f64..20.0, be in 1e-4f64..0.03, inertia in 2e-6f64..1e-4, cpr in prop::sample::select(vec![2304u32, 4096, 1 << 16, 1 << 20])) {
        let s = Scale { motor_cpr: cpr, ..s2304() };
        let f = pd_stability(ke, be, inertia, 1e-3, 0.2);
        let (Ok(keg), Ok(beg), Ok(j)) = (
            stiffness_gain(&s, Feedback::Colocated, "ke", ke),
            damping_gain(&s, Feedback::Colocated, "be", be),
            inertia_gain(&s, inertia),
        ) else {
            return Ok(());
        };
        let int = pd_stability_int(keg, beg, j, 1000, 20);
        let kp = ke * 1e-6 / inertia;
        let kd = be * 1e-3 / inertia;
        let lim = 0.8 * 2.0 * kd * (2.0 - kd) / (2.0 + kd);
        let near = (kp / lim - 1.0).abs() < 1e-6 || (kd / 1.6 - 1.0).abs() < 1e-6;
        if !near {
            prop_assert_eq!(int, f.map(|_| ()), "ke {} be {} I {} kp {} kd {}", ke, be, inertia, kp, kd);
        }
    }
}

#[test]
fn integer_guard_edge_cases() {
    let s = s2304();
    let j = inertia_gain(&s, 1e-5).unwrap();
    let be = damping_gain(&s, Feedback::Colocated, "be", 0.0083).unwrap();
    let ke_ok = stiffness_gain(&s, Feedback::Colocated, "ke", 5.0).unwrap();
    let ke_bad = stiffness_gain(&s, Feedback::Colocated, "ke", 6.0).unwrap();
    assert_eq!(pd_stability_int(ke_ok, be, j, 1000, 20), Ok(()));
    assert_eq!(
        pd_stability_int(ke_bad, be, j, 1000, 20),
        Err(StabilityError::TooStiff)
    );
    assert_eq!(pd_stability_int(ke_bad, be, j, 1000, 0), Ok(()));
    assert_eq!(
        pd_stability_int(ke_ok, Gain::ZERO, j, 1000, 20),
        Err(StabilityError::NoDamping)
    );
    assert_eq!(pd_stability_int(Gain::ZERO, be, j, 1000, 20), Ok(()));
    assert_eq!(
        pd_stability_int(ke_ok, be, Gain::ZERO, 1000, 20),
        Err(StabilityError::BadInput)
    );
    // extreme gains never panic
    for m in [1, i32::MAX, -1, i32::MIN] {
        for sh in [0u8, 31, 62] {
            let g = Gain::from_parts(m, sh).unwrap();
            let _ = pd_stability_int(g, g, g, u16::MAX, 99);
            let _ = pd_stability_int(g, g, j, 1000, 20);
            let _ = pd_stability_int(ke_ok, g, j, 1, 0);
        }
    }
}
