//! Viscous friction: resisting torque proportional to velocity (bearing/grease shear), thesis
//! §3.2 "Friction", Table 4.1 viscous columns (N·m/(deg/s) in the thesis; N·m·s/rad here).
//! Direction-dependent viscous is `viscous` + `asymmetry.viscous_extra`.
//!
//! Dynamics: `R = B·v`. Fingerprint: `[v]` (thesis-notes §7.4: residual ∝ ω, loop widens with
//! speed).

use super::{EffectLaws, Shape, Trajectory};
use super::FitTraits;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "viscous friction R = B·v (grease/bearing shear); residual \
     proportional to velocity, torque-velocity loop widens with speed";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["damping"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    band_limit: false,
    motion_linear: |_| true,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Viscous coefficient (N·m·s/rad, output-referred), both directions.
    damping: "N·m·s/rad" = 0.0, [0.0, 1e6], Amplitude(0);
}

/// Add to both directions of the friction curve.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.friction.viscous_pos += p.damping.value;
    laws.friction.viscous_neg += p.damping.value;
}

/// `[v]`.
pub fn fingerprint(traj: &Trajectory, _shape: &Shape) -> Vec<Vec<f64>> {
    vec![traj.velocity[..traj.len()].to_vec()]
}

/// No shape parameters.
pub fn shape_grid(_traj: &Trajectory) -> Vec<Shape> {
    vec![Shape::default()]
}
