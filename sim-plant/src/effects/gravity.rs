//! Gravity on the output: `R = m·g·l·sin(q + φ) = s·sin q + c·cos q` (thesis-notes §3.2/§7;
//! the JASON arm's joints carry their links). Written with sine and cosine amplitudes so it is
//! linear in its parameters (m·g·l = √(s² + c²), φ = atan2(c, s)).
//!
//! Fingerprint: `[sin q, cos q]`, q = position in rad.

use super::laws::PeriodicTorque;
use super::{EffectLaws, Shape, Trajectory};
use super::FitTraits;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "gravity on the output m·g·l·sin(q+φ); residual is a sinusoid of \
     position with period 2π, present at rest";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["sin", "cos"];

/// Admissible sign of the first amplitude: either.
pub const SIGN: Option<f64> = None;

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    position_period: Some(|_, n| std::f64::consts::TAU * super::signal::positive_or(n, 1.0)),
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Sine amplitude, m·g·l·cos φ (N·m).
    sin: "N·m" = 0.0, [-1e6, 1e6], Amplitude(0);
    /// Cosine amplitude, m·g·l·sin φ (N·m).
    cos: "N·m" = 0.0, [-1e6, 1e6], Amplitude(1);
}

/// Set the gravity torque on the output.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.gravity = PeriodicTorque {
        sin: p.sin.value,
        cos: p.cos.value,
        wavenumber: 1.0,
        load_gain: 0.0,
    };
}

/// `[sin q, cos q]` of the output angle q (the position over the trajectory's gear ratio).
pub fn fingerprint(traj: &Trajectory, _shape: &Shape) -> Vec<Vec<f64>> {
    let n = super::signal::positive_or(traj.gear_ratio, 1.0);
    super::ripple::periodic_columns(traj, std::f64::consts::TAU * n)
}

/// No shape parameters.
pub fn shape_grid(_traj: &Trajectory) -> Vec<Shape> {
    vec![Shape::default()]
}
