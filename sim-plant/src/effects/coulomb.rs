//! Coulomb (kinetic dry) friction: constant magnitude opposing motion, thesis §3.2 "Friction",
//! Table 4.1 Coulomb columns. Direction-dependent levels are `coulomb` + `asymmetry`.
//!
//! Dynamics: while sliding `R = τc·sign(v)`; at rest the friction node sticks (see
//! [`crate::plant`]) and holds any torque up to the breakaway level (= τc without a
//! `stribeck` excess) — a stick state, not a chattering sign().
//!
//! Fingerprint: `[sign_ε(v)]`, a sign with a linear zone |v| < ε (`Shape::sign_epsilon`)
//! because measured velocity near zero is quantisation noise (thesis-notes §7.1: residual
//! ±τc flipping at reversals; torque-position loop 2τc wide). A fitter may shift the switch
//! by a small time lead (`Shape::sign_lead`, the sign of v + lead·a): real (dynamic) friction
//! reverses over a pre-sliding displacement, not exactly at the measured v = 0.

use super::signal::{log_space, positive_or, smooth_sign};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "Coulomb friction R = τc·sign(v), sticks at rest; residual is a \
     ±τc square wave flipping at velocity reversals (loop 2τc wide)";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["torque"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    search: ShapeSearch::Sign,
    dry_friction: true,
    sign_shaped: true,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Coulomb friction level (N·m, output-referred), both directions.
    torque: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
}

/// Add to both directions of the friction curve.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.friction.coulomb_pos += p.torque.value;
    laws.friction.coulomb_neg += p.torque.value;
}

/// `[sign_ε(v + lead·a)]` (lead = `Shape::sign_lead`, 0 by default: `[sign_ε(v)]`), times
/// `1 − w(v)` inside a stick window (`Shape::stick_velocity` > 0, see
/// [`super::stribeck::fingerprint`]): at rest the stiction hold is the friction.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let (eps, lead) = (shape.sign_epsilon, shape.sign_lead);
    let n = traj.len();
    let vh = shape.stick_velocity;
    let w = super::stribeck::stick_weights(traj, vh);
    vec![traj.velocity[..n]
        .iter()
        .zip(&traj.acceleration[..n])
        .zip(&w)
        .map(|((&v, &a), w)| (1.0 - w) * smooth_sign(v + lead * a, eps))
        .collect()]
}

/// Grid of sign-smoothing velocities: 1e-4 … 3e-2 of the largest |v|.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    sign_epsilon_grid(traj)
}

/// Shared by coulomb, asymmetry: a log grid of `sign_epsilon`.
pub(crate) fn sign_epsilon_grid(traj: &Trajectory) -> Vec<Shape> {
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    log_space(1e-4 * vmax, 3e-2 * vmax, 5)
        .into_iter()
        .map(|eps| Shape {
            sign_epsilon: eps,
            ..Shape::default()
        })
        .collect()
}
