//! Torque-constant nonlinearity and small deadband of the actuator (thesis §3.2 "Torque
//! linearity": 1–2 % RMS of max, worst near max torque, "a slight indication of a small torque
//! deadband"; D/A plus analogue amplifier).
//!
//! Dynamics: applied = `dz(u)·(1 − c·|u|/S)` with `dz(u) = u − clamp(u, ±w)` — a dead zone of
//! half-width w and a torque constant that sags by the fraction c at |u| = S (zero torque
//! inside the dead zone, never a sign flip for c < 1).
//!
//! Fingerprint: `R = u − applied = w·clamp(u/w, −1, 1) + c·dz(u)·|u|/S`, i.e. columns
//! `[clamp(u/w, −1, 1), dz(u)·|u|/S]` with amplitudes w (the deadband half-width; the shape
//! grid supplies w inside the columns, the fitted amplitude re-estimates it) and c. Thesis-notes §7.9: residual ∝ command, worse near max; small dead
//! zone at zero command.

use super::signal::positive_or;
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, SmoothShape};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "actuator deadband and torque-constant nonlinearity; residual tracks \
     the command: a step of ±w around zero command and a term growing like u·|u| near max";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["width", "nonlinearity"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    smooth_shape: Some(SmoothShape {
        get: |s| s.deadband_width,
        unit: "N·m",
        set: |s, v| s.deadband_width = v,
    }),
    file_shape: &[same_shape!("input_scale" => input_scale)],
    band_limit: false,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Deadband half-width w (N·m, output-referred).
    width: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
    /// Torque-constant sag c at |u| = input_scale (dimensionless, e.g. 0.02).
    nonlinearity: "1" = 0.0, [-1.0, 1.0], Amplitude(1);
    /// Input scale S of the nonlinearity, normally the maximum torque (N·m).
    input_scale: "N·m" = 1.0, [1e-9, 1e9], Shape;
}

/// The part of `x` a dead zone of half-width `w` removes: `clamp(x, −w, w)`.
#[inline(always)]
pub fn dead(x: f64, w: f64) -> f64 {
    x.clamp(-w, w)
}

/// Set the actuator's deadband and nonlinearity.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.actuator.deadband = p.width.value;
    laws.actuator.nonlinearity = p.nonlinearity.value;
    laws.actuator.input_scale = p.input_scale.value;
}

/// `[clamp(u/w, −1, 1), dz(u)·|u|/S]`.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let u = &traj.input[..traj.len()];
    let w = positive_or(shape.deadband_width, 1e-9);
    let s = positive_or(shape.input_scale, 1.0);
    vec![
        u.iter().map(|&u| (u / w).clamp(-1.0, 1.0)).collect(),
        u.iter().map(|&u| (u - dead(u, w)) * u.abs() / s).collect(),
    ]
}

/// Deadbands of 0.5–10 % of the largest |input|, scale = largest |input|.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let umax = positive_or(traj.max_abs_input(), 1.0);
    [0.005, 0.01, 0.02, 0.05, 0.1]
        .into_iter()
        .map(|f| Shape {
            deadband_width: f * umax,
            input_scale: umax,
            ..Shape::default()
        })
        .collect()
}
