//! The fingerprints agree with the dynamics: simulate a plant with one effect at a known
//! amplitude, form the inverse-dynamics residual of the model without it, r = u − J·a, and
//! least-squares fit the effect's fingerprint columns. The fitted amplitudes must be the
//! parameters (exactly for effects whose residual is linear, within the stated linearisation
//! error otherwise). This pins the shared sign convention `J·a = u − Σ R`.

mod common;

use std::f64::consts::TAU;

use common::*;
use sim_plant::effects::{
    asymmetry, backlash, cogging, compliance, deadband, delay, fingerprint, gravity, offset,
    quantization, ripple, signal, stribeck, viscous, EffectKind, Shape, Trajectory,
};
use sim_plant::plant::{Plant, PlantOptions};
use sim_plant::Model;

const DT: f64 = 1e-3;

struct Run {
    u: Vec<f64>,
    q: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    moving: Vec<bool>,
}

impl Run {
    fn traj(&self) -> Trajectory<'_> {
        Trajectory::unfiltered(DT, &self.u, &self.q, &self.v, &self.a)
    }

    fn residual(&self, j: f64) -> Vec<f64> {
        self.u.iter().zip(&self.a).map(|(u, a)| u - j * a).collect()
    }
}

/// Drive with a two-tone torque for `secs`, recording the motor side (`motor`) or the output.
fn simulate(model: &Model, secs: f64, amp: f64, motor: bool) -> Run {
    let mut plant = Plant::new(model, PlantOptions::default()).unwrap();
    let n = model.plant.gear_ratio.value;
    let mut r = Run {
        u: vec![],
        q: vec![],
        v: vec![],
        a: vec![],
        moving: vec![],
    };
    for k in 0..(secs / DT) as usize {
        let t = k as f64 * DT;
        // Cosines: a free inertia's velocity then has zero mean and reverses.
        let u = amp * ((TAU * 1.0 * t).cos() + 0.3 * (TAU * 3.7 * t).cos());
        plant.step(u, DT);
        let s = plant.state();
        r.u.push(u * n);
        if motor {
            r.q.push(s.motor_angle / n);
            r.v.push(s.motor_velocity / n);
            r.a.push(s.motor_acceleration / n);
        } else {
            r.q.push(s.output_angle);
            r.v.push(s.output_velocity);
            r.a.push(s.output_acceleration);
        }
        r.moving.push(!s.stuck && s.output_velocity.abs() > 0.05);
    }
    r
}

fn fit(kinds: &[(EffectKind, Shape)], run: &Run, j: f64, mask: &[bool]) -> Vec<f64> {
    let traj = run.traj();
    let cols: Vec<Vec<f64>> = kinds
        .iter()
        .flat_map(|(k, s)| fingerprint(*k, &traj, s))
        .collect();
    lstsq(&cols, &run.residual(j), mask)
}

/// Each amplitude within `rel` of itself plus `rel`/10 of the largest (cross-talk between
/// columns: the dynamics see positions at mid-substep, the fingerprint at the sample).
fn assert_close(got: &[f64], want: &[f64], rel: f64) {
    let big = want.iter().fold(0.0f64, |m, w| m.max(w.abs()));
    for (g, w) in got.iter().zip(want) {
        assert!(
            (g - w).abs() <= rel * (w.abs() + 0.1 * big),
            "fitted {got:?} vs parameters {want:?}"
        );
    }
}

const J: f64 = 0.01;

fn all(run: &Run) -> Vec<bool> {
    vec![true; run.u.len()]
}

#[test]
fn offset_viscous_gravity_ripple_cogging_are_recovered_exactly() {
    let mut m = rigid(J);
    m.effects.offset = Some(offset::Params { torque: p(0.3) });
    m.effects.viscous = Some(viscous::Params { damping: p(0.1) });
    m.effects.gravity = Some(gravity::Params {
        sin: p(0.4),
        cos: p(-0.2),
    });
    m.effects.ripple = Some(ripple::Params {
        sin: p(0.05),
        cos: p(0.02),
        period: p(0.3),
        load_gain: p(0.0),
    });
    m.effects.cogging = Some(cogging::Params {
        sin: p(-0.03),
        cos: p(0.01),
        cycles_per_rev: p(9.0),
    });
    let run = simulate(&m, 6.0, 2.0, false);
    let kinds = [
        (EffectKind::Offset, Shape::default()),
        (EffectKind::Viscous, Shape::default()),
        (EffectKind::Gravity, Shape::default()),
        (
            EffectKind::Ripple,
            Shape {
                ripple_period: 0.3,
                ..Shape::default()
            },
        ),
        (
            EffectKind::Cogging,
            Shape {
                cogging_period: TAU / 9.0,
                ..Shape::default()
            },
        ),
    ];
    let got = fit(&kinds, &run, J, &all(&run));
    assert_close(&got, &[0.3, 0.1, 0.4, -0.2, 0.05, 0.02, -0.03, 0.01], 0.01);
}

#[test]
fn coulomb_asymmetry_and_stribeck_are_recovered_while_sliding() {
    let mut m = with_friction(rigid(J), 0.5, 0.3, 0.2, 0.1);
    m.effects.stribeck = Some(stribeck::Params {
        excess: p(0.3),
        velocity: p(0.2),
        exponent: p(2.0),
    });
    m.effects.asymmetry = Some(asymmetry::Params {
        coulomb_extra: p(0.2),
        viscous_extra: p(0.05),
        stiction_extra: p(0.3),
    });
    let run = simulate(&m, 8.0, 2.0, false);
    let eps = Shape {
        sign_epsilon: 1e-6,
        ..Shape::default()
    };
    let kinds = [
        (EffectKind::Coulomb, eps.clone()),
        (EffectKind::Viscous, eps.clone()),
        (EffectKind::Asymmetry, eps.clone()),
        (
            EffectKind::Stribeck,
            Shape {
                stribeck_velocity: 0.2,
                stribeck_exponent: 2.0,
                ..eps.clone()
            },
        ),
    ];
    let mask = run.moving.clone();
    assert!(mask.iter().filter(|m| **m).count() > 4000);
    let got = fit(&kinds, &run, J, &mask);
    // coulomb, viscous, asym coulomb, asym viscous, stribeck excess (the positive-direction
    // stiction extra makes the + excess 0.6 — fitted as the mean 0.3 plus what the + columns
    // absorb — so the stribeck amplitude is checked over negative motion below).
    assert_close(&got[..2], &[0.5, 0.1], 0.02);
    let neg: Vec<bool> = mask
        .iter()
        .zip(&run.v)
        .map(|(m, v)| *m && *v < 0.0)
        .collect();
    let only_neg = [
        (EffectKind::Coulomb, eps.clone()),
        (EffectKind::Viscous, eps.clone()),
        (
            EffectKind::Stribeck,
            Shape {
                stribeck_velocity: 0.2,
                stribeck_exponent: 2.0,
                ..eps.clone()
            },
        ),
    ];
    let got_neg = fit(&only_neg, &run, J, &neg);
    assert_close(&got_neg, &[0.5, 0.1, 0.3], 0.02);
    // Positive motion alone: coulomb + extra, viscous + extra, excess + stiction extra.
    let pos: Vec<bool> = mask
        .iter()
        .zip(&run.v)
        .map(|(m, v)| *m && *v > 0.0)
        .collect();
    let got_pos = fit(&only_neg, &run, J, &pos);
    assert_close(&got_pos, &[0.7, 0.15, 0.6], 0.02);
    // And the joint fit's asymmetry columns carry exactly the ± differences.
    let joint = [
        (EffectKind::Coulomb, eps.clone()),
        (EffectKind::Viscous, eps.clone()),
        (EffectKind::Asymmetry, eps.clone()),
    ];
    let cols_mask: Vec<bool> = mask
        .iter()
        .zip(&run.v)
        .map(|(m, v)| *m && v.abs() > 1.0)
        .collect(); // well above vs: the Stribeck term has decayed
    let got_joint = fit(&joint, &run, J, &cols_mask);
    assert_close(&got_joint, &[0.5, 0.1, 0.2, 0.05], 0.02);
}

#[test]
fn deadband_quantization_and_delay_follow_the_command() {
    let mut m = rigid(J);
    m.effects.deadband = Some(deadband::Params {
        width: p(0.05),
        nonlinearity: p(0.02),
        input_scale: p(2.6),
    });
    let run = simulate(&m, 4.0, 2.0, false);
    let shape = Shape {
        deadband_width: 0.05,
        input_scale: 2.6,
        ..Shape::default()
    };
    let got = fit(&[(EffectKind::Deadband, shape)], &run, J, &all(&run));
    assert_close(&got, &[0.05, 0.02], 0.01);

    let mut m = rigid(J);
    m.effects.quantization = Some(quantization::Params {
        step: p(0.04),
        gain: p(1.0),
    });
    let run = simulate(&m, 4.0, 2.0, false);
    let shape = Shape {
        quantum: 0.04,
        ..Shape::default()
    };
    let got = fit(&[(EffectKind::Quantization, shape)], &run, J, &all(&run));
    assert_close(&got, &[1.0], 0.01);

    let mut m = rigid(J);
    m.effects.delay = Some(delay::Params { delay: p(3e-3) });
    let run = simulate(&m, 4.0, 2.0, false);
    let shape = Shape {
        smoothing: 1,
        ..Shape::default()
    };
    // Linearised u(t − τ) ≈ u − τ·u̇: error of order (ω·τ)² ≈ 5e-3 at 3.7 Hz.
    let got = fit(&[(EffectKind::Delay, shape)], &run, J, &all(&run));
    assert_close(&got, &[3e-3], 0.03);
    // At the matching shape delay the difference-quotient column is exact.
    let shape = Shape {
        delay: 3e-3,
        ..Shape::default()
    };
    let got = fit(&[(EffectKind::Delay, shape)], &run, J, &all(&run));
    assert_close(&got, &[3e-3], 0.002);
}

/// Rigid model of a compliant joint, measured at the motor: residual = −(J2/J1)·H·u with H the
/// second-order high-pass at the coupled mode (derivation in effects/compliance.rs) — exact for
/// a linear spring, up to the discretisation of H (bilinear, ≈ (π·f/fs)² ≈ 2 % here).
#[test]
fn compliance_fingerprint_amplitude_is_minus_j2_over_j1_at_the_coupled_mode() {
    let (j1, j2, k, c) = (0.01, 0.005, 400.0, 0.2);
    let mut m = two_mass(j1, 1.0, j2, k);
    m.effects.compliance = Some(compliance::Params {
        stiffness: p(k),
        damping: p(c),
        ..Default::default()
    });
    let run = simulate(&m, 6.0, 1.0, true);
    let (f, zeta) = compliance::mode_from_spring(k, c, j1, j2);
    assert!((f - (k * (1.0 / j1 + 1.0 / j2)).sqrt() / TAU).abs() < 1e-9);
    let (k2, c2) = compliance::spring_from_mode(f, zeta, j1, j2);
    assert!((k2 - k).abs() < 1e-9 * k && (c2 - c).abs() < 1e-12);
    let shape = Shape {
        compliance_frequency: f,
        compliance_damping: zeta,
        ..Shape::default()
    };
    let mut mask = all(&run);
    mask[..500].iter_mut().for_each(|m| *m = false); // start-up transient of the mode
    let got = fit(
        &[(EffectKind::Compliance, shape.clone())],
        &run,
        j1 + j2,
        &mask,
    );
    assert_close(&got, &[-j2 / j1], 0.05);
    // The amplitude is tied to the mode: below it the column is ≈ u⁽²⁾/ω², so a column built
    // for half the frequency is four times larger and its amplitude a quarter.
    let wrong = Shape {
        compliance_frequency: 0.5 * f,
        ..shape
    };
    let got = fit(&[(EffectKind::Compliance, wrong)], &run, j1 + j2, &mask);
    assert_close(&got, &[-0.25 * j2 / j1], 0.1);
}

/// Rigid model of a joint with backlash, measured at the motor: the residual is
/// −J_load·(δ̈ + δ̇/τ) of the motor–load deflection δ, which the column simulates (the load
/// coasts through the gap, is pushed at its edges); the fitted amplitude is the load inertia
/// and it explains the residual in the band a workbench looks at (40 Hz low-pass of both
/// sides; 99 % here: equal inertias, a well-damped contact, open loop). Above that band the
/// contact ringing is the compliance effect's business.
#[test]
fn backlash_fingerprint_amplitude_is_the_load_inertia() {
    let (j1, j2, width) = (0.01, 0.01, 0.02);
    let mut m = two_mass(j1, 1.0, j2, 2e4);
    m.effects.compliance = Some(compliance::Params {
        stiffness: p(2e4),
        damping: p(10.0),
        ..Default::default()
    });
    m.effects.backlash = Some(backlash::Params { width: p(width) });
    let run = simulate(&m, 6.0, 1.0, true);
    // A free, frictionless load: no viscous decay while it coasts.
    let shape = Shape {
        backlash_width: width,
        backlash_load_time: 0.0,
        ..Shape::default()
    };
    // As a workbench sees it: the sampled acceleration misses the contact impulses, which are
    // shorter than a sample, so the motion is differentiated from the low-passed position and
    // the input gets the same low-pass.
    let fc = 40.0;
    let q = signal::filtfilt(&run.q, fc, 1.0 / DT);
    let v = signal::derivative(&q, DT);
    let a = signal::derivative(&v, DT);
    let u = signal::filtfilt(&run.u, fc, 1.0 / DT);
    let traj = Trajectory {
        position: &q,
        velocity: &v,
        acceleration: &a,
        input: &u,
        raw_input: &u,
        lowpass_hz: fc,
        ..run.traj()
    };
    let r: Vec<f64> = u.iter().zip(&a).map(|(u, a)| u - (j1 + j2) * a).collect();
    let col = &fingerprint(EffectKind::Backlash, &traj, &shape)[0];
    // Away from the filter's edges.
    let keep: Vec<bool> = (0..r.len())
        .map(|i| i >= 200 && i + 200 < r.len())
        .collect();
    let got = lstsq(std::slice::from_ref(col), &r, &keep);
    assert_close(&got, &[j2], 0.05);
    let kept = || {
        r.iter()
            .zip(col)
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(x, _)| x)
    };
    let before: f64 = kept().map(|(x, _)| x * x).sum();
    let after: f64 = kept().map(|(x, c)| (x - got[0] * c).powi(2)).sum();
    assert!(
        after < 0.05 * before,
        "explained only {:.0} %",
        100.0 * (1.0 - after / before)
    );
}
