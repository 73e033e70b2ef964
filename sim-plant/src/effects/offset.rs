//! Constant offset: a bias torque the input must supply regardless of motion (amplifier or
//! D/A offset with the opposite sign, a constant external load). Thesis-notes §7.19 ("seal
//! friction or magnetic drag missing: a constant extra friction") is the velocity-signed
//! cousin; this one is unsigned.
//!
//! Dynamics: `R = torque`. Fingerprint: `[1]`.

use super::{AdditiveTorque, EffectLaws, Node, Shape, Trajectory};
use super::FitTraits;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "constant bias torque R = c (amplifier/D-A offset, constant load); \
     residual is a constant shift, the same in both directions and at rest";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["torque"];

/// Admissible sign of the first amplitude: either.
pub const SIGN: Option<f64> = None;

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits { band_limit: false, ..FitTraits::PLAIN };

crate::define_params! {
    /// Constant resisting torque (N·m, output-referred; negative = an assisting bias).
    torque: "N·m" = 0.0, [-1e6, 1e6], Amplitude(0);
}

/// A constant: the torque law of this effect.
fn constant(params: &[f64; 4], _q: f64, _v: f64, _load: f64) -> f64 {
    params[0]
}

/// Add the bias to the output torque balance, through the generic [`AdditiveTorque`] slot
/// (this effect doubles as the worked example of that extension point).
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.additive.push(AdditiveTorque {
        node: Node::Output,
        law: constant,
        params: [p.torque.value, 0.0, 0.0, 0.0],
    });
}

/// `[1]`.
pub fn fingerprint(traj: &Trajectory, _shape: &Shape) -> Vec<Vec<f64>> {
    vec![vec![1.0; traj.len()]]
}

/// No shape parameters.
pub fn shape_grid(_traj: &Trajectory) -> Vec<Shape> {
    vec![Shape::default()]
}
