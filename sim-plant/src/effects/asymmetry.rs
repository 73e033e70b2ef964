//! Direction asymmetry of friction: the positive direction has extra Coulomb, stiction and
//! viscous friction (negative values = less). Thesis §3.2: "direction-dependent τs±, τc±, B±";
//! every row of Table 4.1 differs by direction (HD stiction +8/−12 N·m); thesis-notes §7.5.
//!
//! With `coulomb.torque = τc⁻` and `asymmetry.coulomb_extra = τc⁺ − τc⁻`, the friction is
//! `τc⁺` moving positive and `τc⁻` moving negative.
//!
//! Fingerprint: `[step_ε(v), max(v, 0)]` with `step_ε(v) = (1 + sign_ε(v))/2` — the residual
//! mean differs between ± motion, and the viscous slope differs.

use super::coulomb::dry_sign;
use super::{EffectLaws, Shape, Trajectory};
use super::FitTraits;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "direction-dependent friction (extra Coulomb/stiction/viscous in the \
     + direction); residual mean and slope differ between + and − motion";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["coulomb_extra", "viscous_extra"];

/// Admissible sign of the first amplitude: either.
pub const SIGN: Option<f64> = None;

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits { sign_shaped: true, ..FitTraits::PLAIN };

crate::define_params! {
    /// Extra Coulomb level in the positive direction, τc⁺ − τc⁻ (N·m).
    coulomb_extra: "N·m" = 0.0, [-1e6, 1e6], Amplitude(0);
    /// Extra viscous coefficient in the positive direction, B⁺ − B⁻ (N·m·s/rad).
    viscous_extra: "N·m·s/rad" = 0.0, [-1e6, 1e6], Amplitude(1);
    /// Extra stiction excess in the positive direction (N·m); dynamics only.
    stiction_extra: "N·m" = 0.0, [-1e6, 1e6], Setting;
}

/// Shift the positive branch of the friction curve (additively; [`EffectLaws::finalize`]
/// clamps the sums at zero once every effect is installed, so the order does not matter).
pub fn install(p: &Params, laws: &mut EffectLaws) {
    let f = &mut laws.friction;
    f.coulomb_pos += p.coulomb_extra.value;
    f.viscous_pos += p.viscous_extra.value;
    f.excess_pos += p.stiction_extra.value;
}

/// `[step_ε(v + lead·a), max(v, 0)]` (lead = `Shape::sign_lead`, 0 by default; a fitter
/// gives it Coulomb's, so both friction levels switch at the same moment). The step is off
/// inside a stick window like Coulomb's (`Shape::stick_velocity`).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let v = &traj.velocity[..n];
    let vh = shape.stick_velocity;
    let w = super::stribeck::stick_weights(traj, vh);
    vec![
        v.iter()
            .zip(&traj.acceleration[..n])
            .zip(&w)
            .map(|((&v, &a), w)| (1.0 - w) * (0.5 * (1.0 + dry_sign(v, a, shape))))
            .collect(),
        v.iter().map(|&v| v.max(0.0)).collect(),
    ]
}

/// Same sign-smoothing grid as Coulomb.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    super::coulomb::sign_grid(traj)
}
