//! One gain point on the lab: the card's law against the two-mass plant in `sim-plant`, a
//! small step, and whether the motor's motion dies out or grows. The verdict reads the
//! plant's true motor velocity from the recording; it knows nothing of the Routh analysis.

use std::path::Path;

use anyhow::{Context, Result};
use controller::proto::Mode;
use sim_plant::effects::compliance;
use sim_plant::{Environment, Model, Param};

use nalgebra::Complex;

use super::routh::{self, Law, TwoMass};

type Complex64 = Complex<f64>;
use crate::lab::gains::GainSet;
use crate::lab::recorder::Row;
use crate::lab::scenario::{Scenario, ScenarioKind};
use crate::lab::supervisor::Target;
use crate::lab::trajectory::Trajectory;

/// The joint the maps run on: gear ratio, motor torque limit and encoders.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Joint {
    /// Gear ratio N.
    pub ratio: f64,
    /// Motor torque limit, N·m at the motor.
    pub max_torque: f64,
}

/// Seconds of each trial after the step.
const TRIAL_S: f64 = 10.0;
/// The step comes this long after the card is enabled, s.
const STEP_AT: f64 = 0.05;
/// The step's torque at the output, N·m: a position step of this over Ke, or a force step of
/// this. A sixth of the motor's limit at the start, so the motion near a boundary spans
/// hundreds of the card's torque LSBs (0.1 mN·m at the motor) without saturating.
const STEP_TORQUE: f64 = 30.0;
/// The largest force step, output N·m.
const MAX_FORCE_STEP: f64 = 200.0;

/// Encoder counts per revolution, motor and output: fine enough that the motion near a
/// boundary spans many counts (the thesis's analysis assumes exact sensing).
const MOTOR_CPR: f64 = 1_048_576.0;
const OUTPUT_CPR: f64 = 16_777_216.0;

/// How one trial ended.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Verdict {
    /// The motion died out (or stayed at the encoder's floor).
    pub stable: bool,
    /// Growth rate of the motor's motion in the run's second half, 1/s (NaN if the run
    /// saturated before it).
    pub sigma: f64,
    /// The dominant oscillating pair's (ζ, ωn in rad/s), if any (see `routh::dominant`).
    pub dominant: Option<(f64, f64)>,
    /// The motor reached its torque limit or the card faulted.
    pub saturated: bool,
}

/// The plant as a model file would state it: motor-side inertia and damping (÷ N²), a linear
/// transmission spring with no structural damping, output inertia and damping, fine encoders
/// on both sides and an exact torque sensor. No friction, backlash or ripple: the thesis's
/// linear two-mass plant.
pub fn model(p: &TwoMass, joint: &Joint) -> Model {
    let n2 = joint.ratio * joint.ratio;
    let mut m = Model {
        name: "two-mass".into(),
        description: "the thesis's linear two-mass plant (§3.3), for the stability maps".into(),
        ..Model::default()
    };
    m.motor.inertia = Param::fixed(p.j1 / n2);
    m.motor.damping = Param::fixed(p.b1 / n2);
    m.motor.max_torque = Param::fixed(joint.max_torque);
    m.motor.counts_per_rev = Param::fixed(MOTOR_CPR);
    m.plant.gear_ratio = Param::fixed(joint.ratio);
    m.plant.output_inertia = Param::fixed(p.j2);
    m.plant.output_damping = Param::fixed(p.b2);
    m.effects.compliance = Some(compliance::Params {
        stiffness: Param::fixed(p.kt),
        soft_stiffness: Param::fixed(0.0),
        knee: Param::fixed(0.0),
        damping: Param::fixed(0.0),
    });
    m.sensors.output_counts_per_rev = Param::fixed(OUTPUT_CPR);
    m.sensors.torque_resolution = Param::fixed(1e-4);
    m.sensors.torque_noise = Param::fixed(0.0);
    m.sensors.velocity_resolution = Param::fixed(1e-6);
    m
}

/// The scenario: `law`'s mode and gains (output-referred, converted to the card's by the
/// supervisor as usual), the output against a spring Kf when the plant has one, and a small
/// step of the law's setpoint.
pub fn scenario(p: &TwoMass, law: &Law, joint: &Joint, model: &Model) -> Result<Scenario> {
    let mut sc = Scenario::new(ScenarioKind::Wall, model)?;
    let n = joint.ratio;
    let base = GainSet {
        torque_limit: joint.max_torque,
        velocity_limit: 50.0,
        quick_stop_damping: sc.gains.quick_stop_damping,
        // The card's own guard is the discrete rigid-rotor bound (§2.9); the maps probe the
        // continuous two-mass boundaries far below it.
        stability_fraction: 1.0,
        ..GainSet::default()
    };
    let mode = match law {
        Law::PdColocated { .. } => Mode::PositionPdColocated,
        Law::PdNonColocated { .. } => Mode::PositionPdNonColocated,
        Law::ForceInputDamping { .. } => Mode::ForceP,
        Law::ForceRate { .. } => Mode::ForcePd,
        Law::ImpedanceColocated { .. } => Mode::ImpedanceColocated,
        Law::ImpedanceNonColocated { .. } => Mode::ImpedanceNonColocated,
    };
    // The card's force gains are motor N·m per output N·m: the thesis's output-referred Ke
    // is N times that.
    let (gains, target) = match *law {
        Law::PdColocated { ke, be } | Law::PdNonColocated { ke, be } => (
            GainSet {
                stiffness: ke,
                damping: be,
                ..base
            },
            Target::Position,
        ),
        Law::ImpedanceColocated { ke, be, km } | Law::ImpedanceNonColocated { ke, be, km } => (
            GainSet {
                stiffness: ke,
                damping: be,
                km,
                ..base
            },
            Target::Position,
        ),
        Law::ForceInputDamping { ke, be } => (
            GainSet {
                force_kp: ke / n,
                input_damping: be,
                ..base
            },
            Target::Force,
        ),
        Law::ForceRate { ke, be } => (
            GainSet {
                force_kp: ke / n,
                force_kd: be / n,
                ..base
            },
            Target::Force,
        ),
    };
    let to = match *law {
        Law::PdColocated { ke, .. } | Law::PdNonColocated { ke, .. } => STEP_TORQUE / ke,
        // Km·τenv feeds the contact force back: the static torque grows as 1/(1 − Km).
        Law::ImpedanceColocated { ke, km, .. } | Law::ImpedanceNonColocated { ke, km, .. } => {
            STEP_TORQUE * (1.0 - km).max(0.1) / ke
        }
        // The command starts at Ke·τD: the same torque, within the force setpoint's range.
        Law::ForceInputDamping { ke, .. } | Law::ForceRate { ke, .. } => {
            (STEP_TORQUE / ke).min(MAX_FORCE_STEP)
        }
    };
    sc.mode = mode;
    sc.gains = gains;
    sc.target = target;
    sc.trajectory = Trajectory::Step {
        from: 0.0,
        to,
        at: STEP_AT,
    };
    sc.duration_s = STEP_AT + TRIAL_S;
    sc.set_wall((p.kf > 0.0).then_some(Environment::Spring {
        stiffness: p.kf,
        damping: 0.0,
        rest: 0.0,
    }));
    Ok(sc)
}

/// Runs `law` on the plant `p` and judges it; the recording goes to `csv`.
pub fn run(p: &TwoMass, law: &Law, joint: &Joint, seed: u64, csv: &Path) -> Result<Verdict> {
    let model = model(p, joint);
    let sc = scenario(p, law, joint, &model)?;
    let (rows, lab) = crate::lab::close_loop::run(&model, sc, seed, csv)
        .with_context(|| format!("{law:?} on {p:?}"))?;
    let t0 = lab.supervisor.trajectory_start_s().unwrap_or(0.0) + STEP_AT;
    Ok(judge(&rows, t0, joint.max_torque, joint.ratio))
}

/// The growth rate σ of the least damped mode left after the step, read from the recording
/// by linear prediction (Prony): the motor's encoder and the output's true angle, taken
/// every 20 ms from 1 s after the step, obey one linear recurrence of the closed
/// loop's order; its roots z give each mode's σ = ln|z|/Δt, however small its share of the
/// motion. Unstable when σ > 0, the motor hit its torque limit, or the card faulted; stable
/// when the motion has died into the encoders' resolution.
pub fn judge(rows: &[Row], t_step: f64, max_torque: f64, ratio: f64) -> Verdict {
    // The first second is the step's transient: a linear loop's stability does not depend on
    // where it starts, so a torque limit touched there only sets the initial condition.
    let after: Vec<&Row> = rows.iter().filter(|r| r.time_s >= t_step + 1.0).collect();
    let faulted = rows.iter().any(|r| r.fault);
    let end = after
        .iter()
        .position(|r| r.fault || r.torque_cmd_nm.abs() >= 0.99 * max_torque)
        .unwrap_or(after.len());
    let saturated = faulted || end < after.len();
    let kept: Vec<&Row> = after[..end].iter().step_by(DECIMATE).copied().collect();
    let channels: Vec<Vec<f64>> = vec![
        kept.iter().map(|r| r.motor_pos_rad / ratio).collect(),
        kept.iter().map(|r| r.output_pos_rad).collect(),
    ];
    let dt = DECIMATE as f64 * 1e-3;
    let poles = prony_poles(&channels, ORDER, dt).unwrap_or_default();
    let sigma = poles.iter().map(|s| s.re).fold(f64::NAN, f64::max);
    // The motion's size over the last second against the encoders' resolution.
    let tail = channels[0].len().saturating_sub((1.0 / dt) as usize);
    let swing = channels[0][tail..]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    let at_floor = swing.1 - swing.0 < 10.0 * std::f64::consts::TAU / (MOTOR_CPR * ratio);
    Verdict {
        stable: !saturated && (at_floor || sigma < 0.0),
        sigma,
        dominant: routh::dominant(&poles),
        saturated,
    }
}

/// Ticks between the samples the recurrence is fitted to: 20 ms, 28 samples a period of
/// the plants' fastest mode (1.8 Hz), while the card's own fast dynamics (its 100 Hz observer,
/// a tick of latency) and the encoders' quantisation average out between samples.
const DECIMATE: usize = 20;
/// The recurrence's order: the two-mass plant's four states and two to spare.
const ORDER: usize = 6;

/// The s-plane poles s = ln(z)/`dt` of the order-`p` recurrence `y[k] = Σ a_i·y[k−i] + c`
/// shared by every channel (each with its own constant c), fitted by least squares.
pub fn prony_poles(channels: &[Vec<f64>], p: usize, dt: f64) -> Option<Vec<Complex64>> {
    use nalgebra::{DMatrix, DVector};
    let rows: usize = channels.iter().map(|c| c.len().saturating_sub(p)).sum();
    let cols = p + channels.len();
    if rows < 4 * cols {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(rows, cols);
    let mut b = DVector::<f64>::zeros(rows);
    let mut r = 0;
    for (ch, y) in channels.iter().enumerate() {
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let scale = y.iter().map(|v| (v - mean).abs()).fold(0.0, f64::max);
        if scale <= 0.0 {
            continue;
        }
        for k in p..y.len() {
            for i in 1..=p {
                a[(r, i - 1)] = (y[k - i] - mean) / scale;
            }
            a[(r, p + ch)] = 1.0;
            b[r] = (y[k] - mean) / scale;
            r += 1;
        }
    }
    let coef = a.svd(true, true).solve(&b, 1e-14).ok()?;
    // z^p − a1 z^(p−1) − … − ap
    let poly: Vec<f64> = std::iter::once(1.0)
        .chain(coef.iter().take(p).map(|v| -v))
        .collect();
    Some(routh::roots(&poly).iter().map(|z| z.ln() / dt).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small growing mode under a large decaying one, an offset per channel, and a
    /// channel that sees the small mode only: the fit finds the growth rate of the small
    /// mode, not the slope of the total.
    #[test]
    fn prony_finds_a_small_growing_mode_under_a_large_decaying_one() {
        let dt = 0.02;
        for sigma in [0.03, -0.03] {
            let t: Vec<f64> = (0..450).map(|k| k as f64 * dt).collect();
            let big = |t: f64| (-0.6 * t).exp() * (std::f64::consts::TAU * 0.7 * t).cos();
            let small =
                |t: f64| 1e-3 * (sigma * t).exp() * (std::f64::consts::TAU * 3.1 * t + 0.4).cos();
            let a: Vec<f64> = t.iter().map(|&t| 5.0 + big(t) + small(t)).collect();
            let b: Vec<f64> = t.iter().map(|&t| -2.0 + 0.3 * small(t)).collect();
            let poles = prony_poles(&[a, b], ORDER, dt).unwrap();
            let top = poles.iter().map(|s| s.re).fold(f64::NAN, f64::max);
            assert!((top - sigma).abs() < 2e-3, "σ {sigma}: {poles:?}");
            let (zeta, wn) = routh::dominant(&poles).unwrap();
            assert!((wn - std::f64::consts::TAU * 3.1).abs() < 0.01, "{wn}");
            assert!((zeta + sigma / wn).abs() < 1e-3, "{zeta}");
        }
    }
}
