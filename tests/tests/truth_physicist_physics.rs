//! Physics sanity of the joint model, checked against closed-form facts (no fitting).

use jointlab_tests::hidden::physicist::joint::{friction_kick, Coupling, Joint, State};
use jointlab_tests::hidden::physicist::torques::DryFriction;
use std::f64::consts::TAU;

fn two_body(j1: f64, j2: f64, coupling: Coupling) -> Joint {
    Joint {
        j_motor: j1,
        j_load: j2,
        b_motor: 0.0,
        b_load: 0.0,
        coupling,
        ..Joint::rigid(j1 + j2, 0.0)
    }
}

#[test]
fn free_rigid_body_keeps_its_energy_and_moves_exactly() {
    let joint = Joint::rigid(5e-3, 0.0);
    let mut s = State {
        v_motor: 1.7,
        ..State::default()
    };
    let e0 = joint.kinetic_energy(&s);
    let h = 2e-5;
    for _ in 0..200_000 {
        joint.step(&mut s, 0.0, h);
    }
    assert_eq!(joint.kinetic_energy(&s), e0);
    assert!((s.q_motor - 1.7 * 4.0).abs() < 1e-9);

    // Constant torque: velocity Verlet is exact for a uniformly accelerated body.
    let mut s = State::default();
    let (tau, n) = (0.02, 50_000);
    for _ in 0..n {
        joint.step(&mut s, tau, h);
    }
    let t = n as f64 * h;
    let a = tau / 5e-3;
    assert!((s.v_motor - a * t).abs() < 1e-10 * a * t);
    assert!((s.q_motor - 0.5 * a * t * t).abs() < 1e-10 * a * t * t);
}

#[test]
fn driven_damped_rigid_body_energy_balance() {
    // ΔKE = ∫τ·dq − ∫B·v²dt, to second order in h.
    let (j, b) = (8e-3, 4e-3);
    let joint = Joint::rigid(j, b);
    let mut s = State::default();
    let h = 5e-5;
    let (mut work, mut loss) = (0.0, 0.0);
    for i in 0..200_000 {
        let t = i as f64 * h;
        let tau = 0.05 * (TAU * 1.3 * t).sin() + 0.02 * (TAU * 7.0 * t).cos();
        let before = s;
        joint.step(&mut s, tau, h);
        work += tau * (s.q_motor - before.q_motor);
        let v = 0.5 * (s.v_motor + before.v_motor);
        loss += b * v * v * h;
    }
    let de = joint.kinetic_energy(&s);
    let budget = work - loss;
    assert!(
        loss > 0.1 * work.abs(),
        "the test must dissipate: {loss} vs {work}"
    );
    assert!(
        (de - budget).abs() < 1e-5 * (work.abs() + loss),
        "ΔKE {de} vs work − loss {budget}"
    );
}

#[test]
fn undamped_shaft_mode_conserves_energy_without_drift() {
    let (j1, j2) = (3e-3, 5e-3);
    let jr = j1 * j2 / (j1 + j2);
    let f = 80.0;
    let joint = two_body(
        j1,
        j2,
        Coupling::Shaft {
            stiffness: (TAU * f).powi(2) * jr,
            damping: 0.0,
        },
    );
    assert!((joint.fastest_mode_hz() - f).abs() < 1e-9);
    let mut s = State {
        q_motor: 0.01,
        v_load: 0.3,
        ..State::default()
    };
    let energy = |s: &State| joint.kinetic_energy(s) + joint.elastic_energy(s);
    let e0 = energy(&s);
    let h = 1.0 / (20.0 * f); // the rule's coarsest: 20 steps per period
    let steps_per_period = 20;
    let periods = 2000;
    let (mut first, mut last, mut worst) = (0.0, 0.0, 0.0_f64);
    for p in 0..periods {
        for _ in 0..steps_per_period {
            joint.step(&mut s, 0.0, h);
            let e = energy(&s);
            worst = worst.max((e - e0).abs() / e0);
            if p < 10 {
                first += e;
            }
            if p >= periods - 10 {
                last += e;
            }
        }
    }
    // Second-order wobble, no secular drift; momentum of the pair is conserved exactly.
    assert!(worst < 0.03, "energy wobble {worst}"); // ≈ (ωh)²/4
    assert!((first - last).abs() / first < 1e-4, "energy drift");
    let p = j1 * s.v_motor + j2 * s.v_load;
    assert!((p - j2 * 0.3).abs() < 1e-12);
}

fn friction_joint() -> Joint {
    Joint {
        friction: DryFriction {
            coulomb: 0.1,
            breakaway: 0.15,
            stribeck_velocity: 0.05,
        },
        ..Joint::rigid(1e-2, 2e-3)
    }
}

#[test]
fn stuck_joint_holds_below_breakaway() {
    let joint = friction_joint();
    let h = 5e-5;
    for tau in [0.0, 0.05, -0.12, 0.1499, -0.1499] {
        let mut s = State::default();
        for _ in 0..40_000 {
            joint.step(&mut s, tau, h);
        }
        assert_eq!(s.q_motor, 0.0, "moved under {tau}");
        assert_eq!(s.v_motor, 0.0);
    }
}

#[test]
fn stuck_joint_breaks_away_above_breakaway() {
    let joint = friction_joint();
    let h = 5e-5;
    for tau in [0.151, -0.151, 0.3] {
        let mut s = State::default();
        for _ in 0..20_000 {
            joint.step(&mut s, tau, h);
        }
        assert!(s.q_motor * tau > 0.0, "did not break away under {tau}");
        // Sliding at speed: net torque is tau − sign·Coulomb − B·v, so the terminal speed is
        // (|tau| − Coulomb)/B once past the Stribeck hump.
        let v_end = (tau.abs() - 0.1) / 2e-3;
        assert!(s.v_motor.abs() < v_end * 1.0001);
    }
    // Ramp the torque: it moves first when the ramp passes breakaway.
    let mut s = State::default();
    let mut moved_at = None;
    for i in 0..40_000 {
        let tau = 0.3 * i as f64 / 40_000.0;
        joint.step(&mut s, tau, h);
        if moved_at.is_none() && s.q_motor != 0.0 {
            moved_at = Some(tau);
        }
    }
    let at = moved_at.expect("never moved");
    assert!((at - 0.15).abs() < 1e-5, "broke away at {at}");
}

#[test]
fn sliding_joint_stops_and_stays_stopped_without_chatter() {
    let joint = friction_joint();
    let h = 5e-5;
    let mut s = State {
        v_motor: 2.0,
        ..State::default()
    };
    let mut stopped_at = None;
    for i in 0..60_000 {
        joint.step(&mut s, -0.13, h); // pushes back, but below breakaway
        if s.v_motor == 0.0 && stopped_at.is_none() {
            stopped_at = Some((i, s.q_motor));
        }
        if let Some((_, q)) = stopped_at {
            assert_eq!(s.v_motor, 0.0, "chatter after sticking");
            assert_eq!(s.q_motor, q);
        }
    }
    assert!(stopped_at.is_some());
    // Deceleration time from 2 rad/s under 0.23 N·m (+drag) is about 0.08 s.
    let (i, _) = stopped_at.unwrap_or((usize::MAX, 0.0));
    assert!((i as f64) * h < 0.09);
}

#[test]
fn friction_kick_reverses_through_zero_above_breakaway() {
    let fr = DryFriction {
        coulomb: 0.1,
        breakaway: 0.1,
        stribeck_velocity: 1.0,
    };
    // Moving slowly forward under a large reverse torque: stops and restarts backwards.
    let v = friction_kick(1e-3, -1.0, 5e-4, 1e-2, 0.0, 0.0, &fr);
    assert!(v < 0.0);
    // Same under a small reverse torque: stops.
    assert_eq!(friction_kick(1e-3, -0.05, 5e-4, 1e-2, 0.0, 0.0, &fr), 0.0);
}

fn geared(gap: f64, b_load: f64) -> Joint {
    let (j1, j2) = (4e-3, 6e-3);
    let jr = j1 * j2 / (j1 + j2);
    let w = TAU * 50.0;
    Joint {
        b_load,
        ..two_body(
            j1,
            j2,
            Coupling::Backlash {
                gap,
                stiffness: w * w * jr,
                damping: 2.0 * 0.1 * w * jr,
            },
        )
    }
}

#[test]
fn backlash_load_feels_nothing_inside_the_gap() {
    let gap = 0.02;
    let joint = geared(gap, 0.0);
    let h = 2e-5;
    let mut s = State::default();
    // From mid-gap the motor turns forward; the load does not move until the motor has taken
    // up half the gap.
    for _ in 0..50_000 {
        joint.step(&mut s, 0.02, h);
        if s.q_motor < 0.5 * gap {
            assert_eq!(s.q_load, 0.0);
            assert_eq!(s.v_load, 0.0);
        }
    }
    assert!(s.q_load > 0.05, "load never driven: {}", s.q_load);
    // The motor brakes hard: while the teeth are apart the load coasts untouched (no drag on it
    // here, so its speed is frozen) until the other flank catches it.
    let mut free_steps = 0;
    let mut reengaged = false;
    for _ in 0..100_000 {
        let before = s;
        joint.step(&mut s, -0.2, h);
        let inside = |x: &State| (x.q_motor - x.q_load).abs() < 0.5 * gap;
        if inside(&s) && inside(&before) {
            assert_eq!(
                s.v_load, before.v_load,
                "load felt the motor inside the gap"
            );
            free_steps += 1;
        }
        reengaged |= s.q_motor - s.q_load < -0.5 * gap;
    }
    assert!(free_steps > 100 && reengaged);
}

#[test]
fn backlash_shows_lost_motion_at_a_reversal() {
    // A stiff position loop on the motor follows a slow triangle; the load has heavy drag so
    // it stops when not pushed. At the top reversal the motor must travel back through the
    // whole gap before the load starts back: that is the lost motion.
    let gap = 0.02;
    let joint = geared(gap, 1.2);
    let h = 2e-5;
    let (kp, kd) = (4e-3 * (TAU * 30.0_f64).powi(2), 2.0 * 4e-3 * TAU * 30.0);
    let reference = |t: f64| 0.1 * (1.0 - 2.0 * (2.0 * (t / 4.0).fract() - 1.0).abs()); // top at 2 s
    let mut s = State::default();
    let (mut q_motor_top, mut q_load_top) = (f64::MIN, f64::MIN);
    let mut load_back_at = None;
    for i in 0..175_000 {
        let t = i as f64 * h;
        let tau = kp * (reference(t) - s.q_motor) - kd * s.v_motor;
        joint.step(&mut s, tau, h);
        if t > 1.0 {
            q_motor_top = q_motor_top.max(s.q_motor);
            q_load_top = q_load_top.max(s.q_load);
            if load_back_at.is_none() && q_motor_top > 0.09 && s.v_load < -1e-6 {
                load_back_at = Some((s.q_motor, s.q_load));
            }
        }
    }
    let (q_motor_then, q_load_then) = load_back_at.expect("the load never came back");
    let lost = q_motor_top - q_motor_then;
    eprintln!(
        "lost motion {lost:.5} (gap {gap}), load moved {:.2e}",
        q_load_top - q_load_then
    );
    assert!(
        (lost - gap).abs() < 0.2 * gap,
        "lost motion {lost} for a gap of {gap}"
    );
    assert!(
        q_load_top - q_load_then < 0.05 * lost,
        "the load moved while the gap was crossed"
    );
}

#[test]
fn shaft_mode_and_backlash_contact_pull_nothing() {
    // The contact may push but never pull: separating teeth with fast relative speed.
    use jointlab_tests::hidden::physicist::torques::backlash_torque;
    assert_eq!(backlash_torque(0.0101, -10.0, 0.02, 1e3, 5.0), 0.0);
    assert!(backlash_torque(0.0101, 0.0, 0.02, 1e3, 5.0) > 0.0);
    assert!(backlash_torque(-0.0101, 0.0, 0.02, 1e3, 5.0) < 0.0);
    assert_eq!(backlash_torque(0.0099, 1.0, 0.02, 1e3, 5.0), 0.0);
}

#[test]
fn reference_velocity_is_the_derivative_of_its_position() {
    use jointlab_tests::hidden::physicist::excite::plan;
    use jointlab_tests::hidden::record::{Conditions, Excitation, Logging, Which};
    for ex in [
        Excitation::PdTracking,
        Excitation::OpenLoopChirp,
        Excitation::MultisinePrbs,
    ] {
        let cond = Conditions {
            dt: 1e-3,
            duration: 12.0,
            counts_per_rev: 65536.0,
            logging: Logging::Zoh,
            excitation: ex,
            noise: 1.0,
        };
        let p = plan(4, Which::Validation, &cond, 1e-2, 1e-3);
        let e = 1e-5;
        for k in 0..1200 {
            let t = k as f64 * 0.01;
            let fd = (p.reference.position(t + e) - p.reference.position(t - e)) / (2.0 * e);
            let v = p.reference.velocity(t);
            assert!(
                (fd - v).abs() < 1e-6 * (1.0 + v.abs()),
                "{ex:?} t={t}: {fd} vs {v}"
            );
        }
    }
}
