//! Output-error validation of closed-loop data: simulate the model *inside* the loop that
//! produced the recording.
//!
//! A rigid axis is a pure integrator, so an open-loop simulation from measured input drifts;
//! closed-loop records (EMPS) must be re-simulated with the known controller. This module runs
//! the position/velocity cascade of the EMPS benchmark (Janot, Gautier & Brunot 2019, read from
//! the authors' Simulink files):
//!
//! ```text
//! qf(k)  = ½·q(k) + ½·q(k−1)                 dqf(k) = (qf(k) − qf(k−1))/T
//! c(k)   = kv·(kp·(r(k) − q(k)) − dqf(k))
//! v(k)   = sat_{±vsat}(c(k−1)) + pulse(k)      force = gain·v
//! ```
//!
//! The plant is the workbench model integrated with RK4 on `substeps` sub-steps per sample,
//! force held constant over the sample.

use super::model::Model;
use super::residual::{effect_force_at, rk4_step};

/// The cascade controller.
#[derive(Debug, Clone, Copy)]
pub struct Cascade {
    /// Position gain [1/s].
    pub kp: f64,
    /// Velocity gain [command/(m/s)].
    pub kv: f64,
    /// Command saturation (±).
    pub saturation: f64,
    /// Command → force gain.
    pub gain: f64,
    /// RK4 sub-steps per sample.
    pub substeps: usize,
}

/// Simulated closed-loop run.
#[derive(Debug, Clone)]
pub struct LoopRun {
    /// Position.
    pub position: Vec<f64>,
    /// Applied force.
    pub force: Vec<f64>,
}

/// Simulate `model` in the cascade loop following `reference`, with `pulse` added to the
/// command (same length; zeros if none), starting at rest at `q0`.
pub fn simulate(
    model: &Model,
    c: &Cascade,
    time: &[f64],
    reference: &[f64],
    pulse: &[f64],
    q0: f64,
) -> LoopRun {
    let n = time.len();
    let m = model.inertia.value;
    let (mut q, mut v, mut a) = (q0, 0.0, 0.0);
    let (mut q_prev, mut qf_prev) = (q0, q0);
    let mut c_prev = 0.0;
    let mut pos = Vec::with_capacity(n);
    let mut force = Vec::with_capacity(n);
    for k in 0..n {
        let dt = if k + 1 < n {
            time[k + 1] - time[k]
        } else {
            time[k] - time[k - 1]
        };
        let qf = 0.5 * q + 0.5 * q_prev;
        let dqf = if k == 0 { 0.0 } else { (qf - qf_prev) / dt };
        let ck = c.kv * (c.kp * (reference[k] - q) - dqf);
        let cmd = if k == 0 { ck } else { c_prev }.clamp(-c.saturation, c.saturation) + pulse[k];
        let f = c.gain * cmd;
        pos.push(q);
        force.push(f);
        c_prev = ck;
        q_prev = q;
        qf_prev = qf;
        let h = dt / c.substeps as f64;
        let acc = |x: f64, w: f64, a: f64| (f - effect_force_at(model, dt, x, w, a, f)) / m;
        for _ in 0..c.substeps {
            (q, v, a) = rk4_step(q, v, a, h, acc);
        }
    }
    LoopRun {
        position: pos,
        force,
    }
}
