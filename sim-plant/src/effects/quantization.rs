//! Quantisation of the input (D/A steps of the torque command; thesis §3.2 "Quantization":
//! torque-sensor and D/A steps, 2304 counts/rev). Sensor quantisation (encoder counts, torque
//! sensor LSB) is always modelled by the plant's sensors ([`crate::plant::sensors`]); in an
//! equation-error residual it appears as white-ish fuzz bounded by ≈ 1 LSB × gain, not as a
//! regressor, so this effect covers the input path.
//!
//! Dynamics: applied = `u − g·(u − Δ·round(u/Δ))` (g = 1: fully quantised).
//! Fingerprint: `R = u − applied = g·(u − Q_Δ(u))`: column `[u − Q_Δ(u)]`, amplitude g.

use super::signal::positive_or;
use super::{EffectLaws, Shape, Trajectory};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "quantisation of the command (D/A steps Δ); residual is a bounded \
     sawtooth of the command within ±Δ/2, fuzz band, no effect at very low amplitude";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["gain"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

crate::define_params! {
    /// Quantiser step Δ (N·m, output-referred); 0 = none.
    step: "N·m" = 0.0, [0.0, 1e6], Shape;
    /// Fraction of the quantisation error present (1 = fully quantised).
    gain: "1" = 1.0, [0.0, 1.0], Amplitude(0);
}

/// Rounding error `x − Δ·round(x/Δ)`, in (−Δ/2, Δ/2].
#[inline(always)]
pub fn error(x: f64, step: f64) -> f64 {
    x - step * (x / step).round()
}

/// Set the actuator quantiser.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.actuator.quant_step = p.step.value;
    laws.actuator.quant_gain = p.gain.value;
}

/// `[u − Q_Δ(u)]` (zeros when Δ = 0).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let u = &traj.input[..traj.len()];
    let d = shape.quantum;
    vec![if d > 0.0 {
        u.iter().map(|&u| error(u, d)).collect()
    } else {
        vec![0.0; u.len()]
    }]
}

/// The smallest non-zero step between consecutive inputs, ×1, ×2, ×5, ×10.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let u = &traj.input[..traj.len()];
    let est = u
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 1e-12)
        .fold(f64::INFINITY, f64::min);
    let est = positive_or(est, 1e-3 * positive_or(traj.max_abs_input(), 1.0));
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| Shape {
            quantum: m * est,
            ..Shape::default()
        })
        .collect()
}
