//! The record loop: sample, control, hold, integrate, log.
//!
//! Time runs on a fine grid t = i·h with h = T/m. At each sample instant t_k the controller reads
//! the encoder, computes u_k, and the ZOH holds it for the m sub-steps of [t_k, t_k+T). The
//! actuator path (D/A, transport delay, disturbance) turns the held command into the motor
//! torque of each sub-step; a delay that is not a whole number of sub-steps is applied exactly by
//! averaging the delayed staircase over the sub-step.

use super::control::Controller;
use super::excite::{plan, sample_count, Plan};
use super::joint::{Coupling, Joint, State};
use super::plant::{draw_effects, draw_plant, with_effects, Actuator, Plant};
use super::rng::stream;
use super::torques::dac;
use crate::hidden::record::{Conditions, Family, Logging, TruthRecord, Which};
use std::f64::consts::TAU;

/// Longest sub-step, s: keeps the Karnopp band (∝ h) small and the hold edges sharp.
pub const MAX_SUBSTEP: f64 = 50e-6;
/// Sub-steps per period of the fastest mode.
pub const STEPS_PER_PERIOD: f64 = 20.0;
/// Fewest sub-steps per sample.
pub const MIN_STEPS_PER_SAMPLE: usize = 10;
/// A state beyond this (rad) is a divergence.
pub const MAX_ANGLE: f64 = 50.0;
/// A command beyond this (N·m) is a divergence.
pub const MAX_COMMAND: f64 = 1e6;

/// Sub-steps per sample: at least 10, h ≤ 50 µs, ≥ 20 per period of the fastest mode, and even
/// so that the middle of the hold (Mid logging) is a grid point.
pub fn substeps(dt: f64, fastest_hz: f64) -> usize {
    let need = |x: f64| (x - 1e-9).ceil().max(1.0);
    let m = (MIN_STEPS_PER_SAMPLE as f64)
        .max(need(dt / MAX_SUBSTEP))
        .max(need(STEPS_PER_PERIOD * fastest_hz * dt)) as usize;
    m + m % 2
}

/// One fully specified simulation.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub seed: u64,
    pub which: Which,
    pub cond: Conditions,
    pub plant: Plant,
    /// The joint with the hidden effect in it.
    pub joint: Joint,
    pub actuator: Actuator,
    pub plan: Plan,
    /// σ of the input noise, N·m.
    pub noise_sigma: f64,
    /// Sub-steps per sample.
    pub substeps: usize,
}

/// What the referee does not get but the tests look at.
#[derive(Debug, Clone)]
pub struct Trace {
    /// Reference at the sample instants.
    pub reference: Vec<f64>,
    /// True load position at the logged instants.
    pub load_true: Vec<f64>,
    /// True load position on the fine grid.
    pub fine_load: Vec<f64>,
    /// Motor torque actually applied on each sub-step (after D/A, delay, disturbance).
    pub fine_applied: Vec<f64>,
}

fn which_index(which: Which) -> u64 {
    match which {
        Which::Estimation => 0,
        Which::Validation => 1,
    }
}

fn check_conditions(cond: &Conditions, amplitude: f64) -> Result<(), String> {
    let ok = cond.dt.is_finite()
        && cond.dt > 0.0
        && cond.duration.is_finite()
        && cond.duration >= cond.dt
        && cond.counts_per_rev.is_finite()
        && cond.counts_per_rev >= 1.0
        && cond.noise.is_finite()
        && cond.noise >= 0.0;
    if !ok {
        return Err(format!("invalid conditions: {cond:?}"));
    }
    if !(amplitude.is_finite() && amplitude >= 0.0) {
        return Err(format!(
            "invalid amplitude {amplitude}: must be finite and ≥ 0"
        ));
    }
    Ok(())
}

/// Assemble the scenario for (seed, effects, conditions, which).
pub fn scenario(
    seed: u64,
    effects: &[(Family, f64)],
    cond: &Conditions,
    which: Which,
) -> Result<Scenario, String> {
    for &(_, amplitude) in effects {
        check_conditions(cond, amplitude)?;
    }
    if effects.is_empty() {
        check_conditions(cond, 0.0)?;
    }
    let plant = draw_plant(seed);
    let (joint, actuator) = with_effects(&plant, &draw_effects(seed), effects);
    let j = plant.joint.total_inertia();
    let b = plant.joint.b_motor + plant.joint.b_load;
    let plan = plan(seed, which, cond, j, b);
    Ok(Scenario {
        seed,
        which,
        cond: *cond,
        plant,
        joint,
        actuator,
        noise_sigma: plant.noise_fraction * plan.rms_command * cond.noise,
        plan,
        substeps: substeps(cond.dt, joint.fastest_mode_hz()),
    })
}

fn diverged(t: f64, what: &str) -> String {
    format!("diverged at t = {t:.4} s: {what}")
}

impl Scenario {
    /// Simulate the record.
    pub fn run(&self) -> Result<(TruthRecord, Trace), String> {
        let cond = &self.cond;
        let dt = cond.dt;
        let n = sample_count(cond);
        let m = self.substeps;
        let h = dt / m as f64;
        let count = TAU / cond.counts_per_rev;
        let encoder = |q: f64| (q / count).round() * count;
        let sensor = self.plant.sensor_counts * count;
        let wi = which_index(self.which);
        let e_ctrl = stream(self.seed, "sensor-motor", wi).normals(n);
        let e_mid = stream(self.seed, "sensor-motor-mid", wi).normals(n);
        let e_load = stream(self.seed, "sensor-load", wi).normals(n);
        let input_noise: Vec<f64> = stream(self.seed, "input-noise", wi)
            .normals(n)
            .into_iter()
            .map(|x| self.noise_sigma * x)
            .collect();

        // Transport delay in sub-steps: whole part and fraction.
        let mut lag = self.actuator.delay / h;
        if (lag - lag.round()).abs() < 1e-9 {
            lag = lag.round();
        }
        let lag_whole = lag.floor() as usize;
        let lag_frac = lag - lag.floor();

        let mut ctrl = Controller::new(&self.plant, dt, self.plan.integral);
        let mut s = State::default();
        let mut converter = Vec::with_capacity(n);
        let mut rec = TruthRecord {
            dt,
            time: (0..n).map(|k| k as f64 * dt).collect(),
            input: Vec::with_capacity(n),
            position: vec![0.0; n],
            load_position: vec![0.0; n],
            input_noise: input_noise.clone(),
            position_true: vec![0.0; n],
            fine_dt: h,
            fine_command: Vec::with_capacity(n * m),
            fine_position: Vec::with_capacity(n * m),
            inertia: self.joint.total_inertia(),
            inertia_load: self.joint.j_load,
            spring: match self.joint.coupling {
                Coupling::Shaft { stiffness, damping } => Some((stiffness, damping)),
                _ => None,
            },
            load_position_true: Vec::new(),
            gear_ratio: 1.0,
        };
        let mut trace = Trace {
            reference: self.plan.r[..n].to_vec(),
            load_true: vec![0.0; n],
            fine_load: Vec::with_capacity(n * m),
            fine_applied: Vec::with_capacity(n * m),
        };
        let log_at = match cond.logging {
            Logging::Zoh => 0,
            Logging::Mid => m / 2,
        };

        for k in 0..n {
            let t = k as f64 * dt;
            let y = encoder(s.q_motor + sensor * e_ctrl[k]);
            let mut u = self.plan.feedforward[k] + self.plan.dither[k];
            if self.plan.closed_loop {
                u += ctrl.feedback(self.plan.r[k], y);
            }
            if !u.is_finite() || u.abs() > MAX_COMMAND {
                return Err(diverged(t, &format!("command {u}")));
            }
            converter.push(dac(u, self.actuator.dac_step));
            let disturbance = if self.actuator.noise_after_dac {
                rec.input.push(u);
                input_noise[k]
            } else {
                rec.input.push(u + input_noise[k]);
                0.0
            };
            // The delayed staircase of the converter output, read at fine index i (0 before start).
            let held = |i: isize| {
                if i < 0 {
                    0.0
                } else {
                    converter[i as usize / m]
                }
            };
            for i in 0..m {
                if i == log_at {
                    let own = if log_at == 0 {
                        y
                    } else {
                        encoder(s.q_motor + sensor * e_mid[k])
                    };
                    rec.position[k] = own;
                    rec.position_true[k] = s.q_motor;
                    rec.load_position[k] = encoder(s.q_load + sensor * e_load[k]);
                    trace.load_true[k] = s.q_load;
                }
                // What the start model takes as input: the command, plus a torque disturbance
                // after the converter (the referee's excess is then the hidden effect alone).
                rec.fine_command.push(u + disturbance);
                rec.fine_position.push(s.q_motor);
                trace.fine_load.push(s.q_load);
                let idx = (k * m + i) as isize - lag_whole as isize;
                let tau = (1.0 - lag_frac) * held(idx) + lag_frac * held(idx - 1) + disturbance;
                trace.fine_applied.push(tau);
                self.joint.step(&mut s, tau, h);
            }
            let finite = s.q_motor.is_finite()
                && s.q_load.is_finite()
                && s.v_motor.is_finite()
                && s.v_load.is_finite();
            if !finite {
                return Err(diverged(t + dt, "non-finite state"));
            }
            if s.q_motor.abs() > MAX_ANGLE || s.q_load.abs() > MAX_ANGLE {
                return Err(diverged(
                    t + dt,
                    &format!(
                        "|q| > {MAX_ANGLE} rad (motor {:.3}, load {:.3})",
                        s.q_motor, s.q_load
                    ),
                ));
            }
        }
        rec.load_position_true = trace.load_true.clone();
        Ok((rec, trace))
    }
}
