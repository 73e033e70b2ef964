//! The two residuals.
//!
//! * **Equation error** (inverse dynamics): predict the input from the measured motion —
//!   `û = M·a + Σ θ·fingerprint(x, v, a, u)` with `v`, `a` from the smoothing differentiator
//!   ([`super::diff`]) — and compare with the measured input. Linear in every amplitude, so it
//!   is what `diagnose` tests and `fit` fits; it works on closed-loop data (EMPS) because it never
//!   integrates the plant.
//! * **Output error** (simulation): integrate the model from the measured input (RK4, input held
//!   over each sample, 4 sub-steps) starting from the measured initial state, and compare
//!   positions. This is the honest "does the model predict" check for open-loop data; a rigid
//!   axis is a pure integrator, so on long open-loop records small force errors accumulate into
//!   drift — the report says which residual it shows.
//!
//! The parts: `prepared` the recording differentiated, with its noise estimates;
//! `design` the regressor columns, the bias-compensated refit and the prediction; `memo` the
//! columns kept across a shape search's refits; this file
//! the two residuals and the simulator they share with `compare`.

mod design;
mod memo;
mod prepared;

pub use design::*;
pub use memo::{ColumnMemo, DIAGNOSIS_BUDGET};
pub use prepared::*;

use sim_plant::effects::{fingerprint, Trajectory};

use super::model::Model;

/// Which residual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Inverse dynamics / equation error (predicted input vs measured input).
    Equation,
    /// Simulation / output error (simulated position vs measured position).
    Output,
}

impl Mode {
    /// Name used in reports and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Equation => "equation_error",
            Mode::Output => "output_error",
        }
    }
}

/// Measured, predicted and residual series with the signals the localisation needs.
#[derive(Debug, Clone)]
pub struct Residual {
    /// Which residual.
    pub mode: Mode,
    /// Time.
    pub time: Vec<f64>,
    /// Measured signal (input for equation error, position for output error).
    pub measured: Vec<f64>,
    /// Model prediction of it.
    pub predicted: Vec<f64>,
    /// measured − predicted.
    pub residual: Vec<f64>,
    /// Velocity (smoothed).
    pub velocity: Vec<f64>,
    /// Position (smoothed).
    pub position: Vec<f64>,
    /// Measured input.
    pub input: Vec<f64>,
    /// Noise floor of this residual, if known from the data (equation error: see
    /// [`Prepared::equation_floor`]); otherwise the metrics estimate it from the residual.
    pub noise_floor: Option<f64>,
}

impl Residual {
    /// RMS of the residual.
    pub fn rms(&self) -> f64 {
        (self.residual.iter().map(|r| r * r).sum::<f64>() / self.residual.len() as f64).sqrt()
    }
}

/// Equation-error residual of a model on prepared data.
pub fn equation_error(model: &Model, p: &Prepared) -> Residual {
    let pred = predict(model, p);
    Residual {
        mode: Mode::Equation,
        time: p.time.clone(),
        measured: p.input.clone(),
        residual: p.input.iter().zip(&pred).map(|(a, b)| a - b).collect(),
        predicted: pred,
        velocity: p.velocity.clone(),
        position: p.position.clone(),
        input: p.input.clone(),
        noise_floor: Some(p.equation_floor(model.inertia.value)),
    }
}

/// Force the model applies besides inertia at one state (for simulation). History-dependent
/// fingerprints (backlash gap state, compliance derivatives, delay) are evaluated on a
/// single sample and so contribute their memoryless part only.
pub fn effect_force_at(model: &Model, dt: f64, x: f64, v: f64, a: f64, u: f64) -> f64 {
    let (xs, vs, as_, us) = ([x], [v], [a], [u]);
    let t = Trajectory::unfiltered(dt, &us, &xs, &vs, &as_);
    let mut f = 0.0;
    for e in &model.effects {
        for (c, par) in fingerprint(e.kind, &t, &e.shape).iter().zip(&e.params) {
            f += par.value * c[0];
        }
    }
    f
}

/// One classical Runge–Kutta step of `ẍ = acc(x, ẋ, ẍ_prev)` over `h`; returns position,
/// velocity and the last stage's acceleration (fed to the next call: effects such as
/// compliance read the acceleration). Shared by the output-error simulation and the
/// closed-loop re-simulation.
pub fn rk4_step(
    x: f64,
    v: f64,
    a: f64,
    h: f64,
    acc: impl Fn(f64, f64, f64) -> f64,
) -> (f64, f64, f64) {
    let k1v = acc(x, v, a);
    let k1x = v;
    let k2v = acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v, k1v);
    let k2x = v + 0.5 * h * k1v;
    let k3v = acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v, k2v);
    let k3x = v + 0.5 * h * k2v;
    let k4v = acc(x + h * k3x, v + h * k3v, k3v);
    let k4x = v + h * k3v;
    (
        x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
        k4v,
    )
}

/// Simulate the model from the measured input (output error). Returns simulated position.
pub fn simulate(model: &Model, time: &[f64], input: &[f64], x0: f64, v0: f64) -> Vec<f64> {
    let m = model.inertia.value;
    let n = time.len();
    let mut xs = Vec::with_capacity(n);
    let (mut x, mut v, mut a) = (x0, v0, 0.0);
    const SUB: usize = 4;
    for k in 0..n {
        xs.push(x);
        if k + 1 == n {
            break;
        }
        let dt = time[k + 1] - time[k];
        let h = dt / SUB as f64;
        let u = input[k];
        let acc = |x: f64, v: f64, a: f64| (u - effect_force_at(model, dt, x, v, a, u)) / m;
        for _ in 0..SUB {
            (x, v, a) = rk4_step(x, v, a, h, acc);
        }
    }
    xs
}

/// Output-error residual of a model on prepared data (raw measured position vs simulation).
pub fn output_error(model: &Model, p: &Prepared) -> Residual {
    let sim = simulate(model, &p.time, &p.input, p.position[0], p.velocity[0]);
    Residual {
        mode: Mode::Output,
        time: p.time.clone(),
        measured: p.raw_position.clone(),
        residual: p
            .raw_position
            .iter()
            .zip(&sim)
            .map(|(a, b)| a - b)
            .collect(),
        predicted: sim,
        velocity: p.velocity.clone(),
        position: p.position.clone(),
        input: p.input.clone(),
        noise_floor: None,
    }
}
