//! Transport delay of the actuator command (thesis §2.7 first-order lag, §2.9 ZOH/sampling,
//! "a delay of one full sample" in the 10 Hz loops; thesis-notes §7.15/7.17).
//!
//! Dynamics: the applied command is `u(t − τ)`, τ rounded to the integrator substep.
//!
//! Fingerprint (linearised): `u(t − τ) ≈ u(t) − τ·u̇(t)`, so `R = u − applied ≈ τ·u̇`:
//! column `[u̇]` (smoothed derivative), amplitude τ in seconds. Valid while τ is short compared
//! with the time scale of u.

use super::signal::{derivative, moving_average};
use super::{EffectLaws, Shape, Trajectory};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "transport delay τ of the command; residual ≈ τ·du/dt (leads the \
     command's rate), optimistic margins, one-sample lag";

crate::define_params! {
    /// Delay τ (s).
    delay: "s" = 0.0, [0.0, 10.0], Amplitude(0);
}

/// Set the actuator delay.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.actuator.delay = p.delay.value;
}

/// `[u̇]`.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let u = moving_average(&traj.input[..traj.len()], shape.smoothing);
    vec![derivative(&u, traj.dt)]
}

/// Smoothing lengths 1, 5, 11 samples.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    super::compliance::shape_grid(traj)
}
