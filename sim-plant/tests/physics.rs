//! Physics of the plant: conservation, modal frequencies, stick/slip, backlash, soft zone,
//! environments, actuator effects. Every expected value is computed from a stated formula.

mod common;

use std::f64::consts::TAU;

use common::*;
use sim_plant::effects::{asymmetry, deadband, delay, gravity};
use sim_plant::experiments::stiffness_test;
use sim_plant::plant::{Environment, Plant, PlantError, PlantOptions};

const DT: f64 = 1e-3;

/// Lossless 2-mass, free: ω² = KT·(1/I1' + 1/I2) with I1' = N²·I1 (thesis §3.1 reflected to the
/// output). Energy must stay within the Verlet bound and must not drift.
#[test]
fn lossless_two_mass_conserves_energy_and_rings_at_the_formula_frequency() {
    let (i1, n, i2, k) = (2.5e-4, 30.0, 0.05, 5000.0);
    let model = two_mass(i1, n, i2, k);
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    plant.set_positions(n * 0.01, 0.0); // 0.01 rad of deflection at rest
    let e0 = plant.energy();
    assert!((e0 - 0.5 * k * 0.01 * 0.01).abs() < 1e-12);
    let step = 1e-4; // sample at the substep to resolve the 56 Hz mode finely
    let mut defl = Vec::new();
    let mut energy = Vec::new();
    for _ in 0..(20.0 / step) as usize {
        plant.step(0.0, step);
        defl.push(plant.state().deflection);
        energy.push(plant.energy());
    }
    let i1r = n * n * i1;
    let omega = (k * (1.0 / i1r + 1.0 / i2)).sqrt();
    let measured = TAU / mean_period(&defl[..20_000], step);
    assert!(
        (measured / omega - 1.0).abs() < 0.01,
        "ω measured {measured:.3} vs formula {omega:.3} rad/s"
    );
    // Verlet: the energy error is bounded by ~(ω·h)² …
    let wh = omega * 1e-4;
    let err = |s: &[f64]| s.iter().map(|e| (e / e0 - 1.0).abs()).fold(0.0, f64::max);
    let worst = err(&energy);
    assert!(
        worst < wh * wh,
        "energy error {worst:.2e} > (ωh)² = {:.2e}",
        wh * wh
    );
    // … and does not grow: the error envelope over the last second (after 1100 periods)
    // is no larger than over the first.
    let (first, last) = (
        err(&energy[..10_000]),
        err(&energy[energy.len() - 10_000..]),
    );
    assert!(
        last <= first * 1.05,
        "energy error grew from {first:.3e} to {last:.3e}"
    );
    // Momentum: nothing external acts, so N²I1·v1/N… i.e. I1'·ẋ1 + I2·ẋ2 stays zero.
    let s = plant.state();
    let p = i1r * s.motor_velocity / n + i2 * s.output_velocity;
    assert!(p.abs() < 1e-9, "momentum {p}");
}

/// 3-mass (Eqn 3.3.26) with the output locked: the motor/middle pair has the 2-DOF modes
/// ω² = eigenvalues of A = [[Ks/I1', −Ks/I1'], [−Ks/Im, (Ks+KT)/Im]]. From any start both
/// modes ring; (A − ω_hi²·I)·z removes the upper one exactly, leaving the lower mode, whose
/// period is measured.
#[test]
fn three_mass_locked_rings_at_its_lower_eigenfrequency() {
    let (i1, n, im, i2, ks, kt) = (2.5e-4, 30.0, 0.01, 0.05, 14_000.0, 8_000.0);
    let mut model = two_mass(i1, n, i2, kt);
    model.plant.middle_inertia = p(im);
    model.plant.proximal_stiffness = p(ks);
    let i1r = n * n * i1;
    let (a, b, c, d) = (ks / i1r, -ks / i1r, -ks / im, (ks + kt) / im);
    let tr = a + d;
    let det = a * d - b * c;
    let w2_lo = 0.5 * (tr - (tr * tr - 4.0 * det).sqrt());
    let w2_hi = tr - w2_lo;
    let mut plant = Plant::new(
        &model,
        PlantOptions {
            environment: Environment::Locked,
            ..Default::default()
        },
    )
    .unwrap();
    plant.set_positions(n * 0.01, 0.0); // motor and middle both at 0.01 rad, output at 0
    let step = 1e-4;
    let mut low = Vec::new();
    for _ in 0..(1.0 / step) as usize {
        plant.step(0.0, step);
        let s = plant.state();
        // First row of (A − ω_hi²·I)·z, z = (x1, xm).
        low.push((a - w2_hi) * (s.motor_angle / n) + b * s.middle_angle);
    }
    let measured = TAU / mean_period(&low, step);
    assert!(
        (measured / w2_lo.sqrt() - 1.0).abs() < 0.01,
        "lower mode {measured:.2} vs {:.2} rad/s",
        w2_lo.sqrt()
    );
}

/// Rigid inertia with Coulomb 1.0 + stiction excess 0.5: a hand torque of 1.45 N·m is held
/// exactly (velocity identically zero, no chatter), 1.55 N·m breaks away; once sliding, 1.2 N·m
/// (between Coulomb and stiction) keeps it moving; removing the torque stops it for good.
#[test]
fn stiction_holds_below_breakaway_and_slips_above() {
    let model = with_friction(rigid(0.01), 1.0, 0.5, 0.01, 0.0);
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    for _ in 0..1000 {
        plant.step(1.45, DT);
        let s = plant.state();
        assert_eq!(s.output_velocity, 0.0);
        assert_eq!(s.output_angle, 0.0);
        assert!(s.stuck);
        assert!((s.friction_torque - 1.45).abs() < 1e-12);
    }
    plant.step(-1.45, DT);
    assert_eq!(plant.state().output_velocity, 0.0);
    for _ in 0..20 {
        plant.step(1.55, DT);
    }
    assert!(plant.state().output_velocity > 0.0 && !plant.state().stuck);
    let v0 = plant.state().output_velocity;
    for _ in 0..200 {
        plant.step(1.2, DT);
    }
    let s = plant.state();
    // 1.2 − 1.0 = 0.2 N·m net (the Stribeck excess has decayed at these speeds): a = 20 rad/s².
    assert!(
        s.output_velocity > v0 + 0.2 * 0.2 / 0.01 * 0.8,
        "v {}",
        s.output_velocity
    );
    let mut stopped_at = None;
    for k in 0..5000 {
        plant.step(0.0, DT);
        let s = plant.state();
        if s.output_velocity == 0.0 && stopped_at.is_none() {
            stopped_at = Some(k);
        }
        if stopped_at.is_some() {
            assert_eq!(s.output_velocity, 0.0, "chatter after stopping at step {k}");
            assert!(s.stuck);
        }
    }
    // Deceleration by Coulomb alone: v/(τc/J) seconds.
    let t_stop = stopped_at.unwrap() as f64 * DT;
    let expected = s.output_velocity / (1.0 / 0.01);
    assert!((t_stop - expected).abs() < 2e-3, "{t_stop} vs {expected}");
}

/// Direction-dependent breakaway: coulomb 1.0 + asymmetry (+0.3 Coulomb, +0.2 stiction) with
/// excess 0.5 → breakaway +2.0 / −1.5.
#[test]
fn asymmetric_breakaway_levels() {
    let mut model = with_friction(rigid(0.01), 1.0, 0.5, 0.01, 0.0);
    model.effects.asymmetry = Some(asymmetry::Params {
        coulomb_extra: p(0.3),
        viscous_extra: p(0.0),
        stiction_extra: p(0.2),
    });
    for (torque, moves) in [(1.98, false), (2.02, true), (-1.48, false), (-1.52, true)] {
        let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
        for _ in 0..50 {
            plant.step(torque, DT);
        }
        assert_eq!(
            plant.state().output_velocity != 0.0,
            moves,
            "torque {torque}"
        );
    }
}

/// Backlash and soft zone measured by the simulated stiffness test equal the parameters.
#[test]
fn stiffness_test_measures_backlash_and_soft_zone_parameters() {
    let width = 0.5f64.to_radians();
    let mut model = with_backlash(two_mass(1e-3, 30.0, 0.05, 9000.0), width);
    model.motor.max_torque = p(2.0); // the ramp goes to ±2 N·m at the motor, ±60 at the output
    let c = model.effects.compliance.as_mut().unwrap();
    c.soft_stiffness = p(3000.0);
    c.knee = p(20.0);
    c.damping = p(5.0);
    let r = stiffness_test(&model, 8.0, 7).unwrap();
    // One motor count is 2π/(2304·30) = 0.0052° at the output.
    assert!(
        (r.backlash.to_degrees() - 0.5).abs() < 0.02,
        "backlash {:.4}°",
        r.backlash.to_degrees()
    );
    for i in 0..2 {
        assert!((r.soft[i] / 3000.0 - 1.0).abs() < 0.02, "soft {:?}", r.soft);
        assert!(
            (r.stiff[i] / 9000.0 - 1.0).abs() < 0.02,
            "stiff {:?}",
            r.stiff
        );
        assert!((r.knee[i] / 20.0 - 1.0).abs() < 0.05, "knee {:?}", r.knee);
    }
}

/// Without backlash the flat zone is only the sensor-noise band (≈ 2·5σ/K).
#[test]
fn no_backlash_gives_no_flat_zone() {
    let mut model = two_mass(1e-3, 30.0, 0.05, 9000.0);
    model.motor.max_torque = p(2.0);
    let r = stiffness_test(&model, 8.0, 7).unwrap();
    assert!(
        r.backlash.to_degrees() < 0.01,
        "{}",
        r.backlash.to_degrees()
    );
}

#[test]
fn rigid_inertia_accelerates_at_torque_over_inertia_and_encoder_counts_follow() {
    let mut model = rigid(0.02);
    model.plant.gear_ratio = p(10.0);
    model.motor.inertia = p(1e-4);
    model.plant.output_inertia = p(0.01);
    let j = 100.0 * 1e-4 + 0.01; // N²·I1 + I2
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    let mut s = plant.step(0.1, DT);
    for _ in 1..500 {
        s = plant.step(0.1, DT);
    }
    let t = 0.5;
    let q = 0.5 * (10.0 * 0.1 / j) * t * t;
    let st = plant.state();
    assert!(
        (st.output_angle / q - 1.0).abs() < 1e-9,
        "{} vs {q}",
        st.output_angle
    );
    assert!((st.motor_angle - 10.0 * st.output_angle).abs() < 1e-12);
    assert_eq!(
        s.motor_counts,
        (st.motor_angle * 2304.0 / TAU).floor() as i32
    );
}

#[test]
fn spring_environment_settles_where_torque_balances_and_the_sensor_reads_it() {
    let mut model = rigid(0.01);
    model.sensors.torque_resolution = p(1e-3);
    let mut plant = Plant::new(
        &model,
        PlantOptions {
            environment: Environment::Spring {
                stiffness: 100.0,
                damping: 2.0,
                rest: 0.0,
            },
            ..Default::default()
        },
    )
    .unwrap();
    let mut s = plant.step(0.0, DT);
    for _ in 0..3000 {
        s = plant.step(1.5, DT);
    }
    assert!((plant.state().output_angle - 0.015).abs() < 1e-6);
    assert!((s.torque - 1.5).abs() <= 1e-3, "{}", s.torque);
}

#[test]
fn wall_stops_the_output_and_never_pulls() {
    let model = rigid(0.01);
    let env = Environment::Wall {
        position: 0.1,
        stiffness: 1e4,
        damping: 20.0,
        side: 1.0,
    };
    let mut plant = Plant::new(
        &model,
        PlantOptions {
            environment: env,
            ..Default::default()
        },
    )
    .unwrap();
    for _ in 0..2000 {
        plant.step(1.0, DT);
    }
    let q = plant.state().output_angle;
    assert!((q - (0.1 + 1.0 / 1e4)).abs() < 1e-5, "{q}");
    for _ in 0..500 {
        plant.step(-1.0, DT);
    }
    // Pulled away: the wall exerts nothing, the sensor reads zero.
    assert!(plant.state().output_angle < 0.1);
    assert_eq!(plant.state().environment_torque, 0.0);
}

#[test]
fn crank_imposes_speed_and_locked_output_does_not_move() {
    let mut model = with_friction(two_mass(1e-3, 30.0, 0.05, 5000.0), 2.0, 0.0, 0.01, 0.5);
    // ζ ≈ 0.5 on the motor-side mode, so the crank's start transient dies within the second.
    model.effects.compliance.as_mut().unwrap().damping = p(67.0);
    let mut plant = Plant::new(
        &model,
        PlantOptions {
            environment: Environment::Crank { speed: 0.5 },
            ..Default::default()
        },
    )
    .unwrap();
    for _ in 0..1000 {
        plant.step(0.0, DT);
    }
    let s = plant.state();
    assert_eq!(s.output_velocity, 0.5);
    assert!((s.output_angle - 0.5).abs() < 1e-9, "{}", s.output_angle);
    // Friction 2 + 0.5·0.5 is what the crank feels, plus whatever drags the motor (≈ 0 here).
    assert!(
        (s.environment_torque + 2.25).abs() < 0.05,
        "{}",
        s.environment_torque
    );
    plant.set_environment(Environment::Locked).unwrap();
    for _ in 0..100 {
        plant.step(1.0, DT);
    }
    assert!((plant.state().output_angle - 0.5).abs() < 1e-9);
}

#[test]
fn actuator_delay_postpones_motion_by_the_delay() {
    let mut model = rigid(0.01);
    model.effects.delay = Some(delay::Params { delay: p(5e-3) });
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    for k in 0..10 {
        plant.step(1.0, DT);
        let moved = plant.state().output_velocity != 0.0;
        assert_eq!(moved, k >= 5, "sample {k}");
    }
}

#[test]
fn deadband_swallows_small_commands_and_the_nonlinearity_sags_large_ones() {
    let mut model = rigid(0.01);
    model.effects.deadband = Some(deadband::Params {
        width: p(0.1),
        nonlinearity: p(0.02),
        input_scale: p(2.0),
    });
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    plant.step(0.09, DT);
    assert_eq!(plant.state().output_velocity, 0.0);
    plant.step(2.0, DT);
    let applied = plant.state().applied_torque;
    let expected = (2.0 - 0.1) * (1.0 - 0.02 * 2.0 / 2.0);
    assert!(
        (applied - expected).abs() < 1e-12,
        "{applied} vs {expected}"
    );
}

/// Small oscillations of a gravity pendulum: ω² = m·g·l / J.
#[test]
fn gravity_pendulum_swings_at_sqrt_mgl_over_j() {
    let mut model = rigid(0.05);
    model.effects.gravity = Some(gravity::Params {
        sin: p(2.0),
        cos: p(0.0),
    });
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    plant.set_positions(0.01, 0.01);
    let mut q = Vec::new();
    for _ in 0..5000 {
        plant.step(0.0, DT);
        q.push(plant.state().output_angle);
    }
    let w = TAU / mean_period(&q, DT);
    let expected = (2.0f64 / 0.05).sqrt();
    assert!((w / expected - 1.0).abs() < 0.01, "{w} vs {expected}");
}

#[test]
fn commands_saturate_at_the_motor_limit() {
    let mut model = rigid(0.01);
    model.motor.max_torque = p(2.0);
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    plant.step(5.0, DT);
    let s = plant.state();
    assert!(s.saturated);
    assert_eq!(s.applied_torque, 2.0);
    assert_eq!(s.command, 5.0);
    plant.step(f64::NAN, DT);
    assert_eq!(plant.state().applied_torque, 0.0);
}

#[test]
fn too_stiff_for_the_substep_is_refused_with_the_rate_needed() {
    let model = two_mass(1e-6, 1.0, 1e-4, 1e6);
    let err = Plant::new(&model, PlantOptions::default()).unwrap_err();
    match err {
        PlantError::TooStiff { needed, .. } => {
            assert!(needed > 10_000.0);
            let ok = Plant::new(
                &model,
                PlantOptions {
                    substep_rate: needed,
                    ..Default::default()
                },
            );
            assert!(ok.is_ok());
        }
        other => panic!("unexpected {other}"),
    }
}

#[test]
fn backlash_lets_the_motor_cross_the_gap_with_only_its_own_inertia() {
    // Thesis §3.1 Fig 4.63: in the gap only the motor-side inertia remains.
    let (i1, n) = (1e-3, 10.0);
    let width = 2f64.to_radians();
    let model = with_backlash(two_mass(i1, n, 0.5, 5000.0), width);
    let mut plant = Plant::new(&model, PlantOptions::default()).unwrap();
    plant.step(0.01, DT);
    // Motor node alone: a = N·τ / (N²·I1) at the output side.
    let a = n * 0.01 / (n * n * i1);
    let s = plant.state();
    assert!((s.output_angle).abs() < 1e-15);
    assert!((s.deflection - 0.5 * a * DT * DT).abs() < 1e-12);
    assert!(s.deflection < 0.5 * width);
}
