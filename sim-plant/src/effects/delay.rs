//! Transport delay of the actuator command (thesis §2.7 first-order lag, §2.9 ZOH/sampling,
//! "a delay of one full sample" in the 10 Hz loops; thesis-notes §7.15/7.17).
//!
//! Dynamics: the applied command is `u(t − τ)`, τ rounded to the integrator substep.
//!
//! Fingerprint: for a shape delay τs > 0 the column is the difference quotient
//! `(u(t) − u(t − τs))/τs` (u interpolated linearly between samples), so a plant with delay τ
//! leaves `R = u − u(t − τ) = τ·column` exactly when τ = τs, and to first order in τ − τs
//! otherwise: the amplitude *is* the delay estimate, and the best shape is the one whose τs the
//! fit returns. For τs = 0 the column is the (smoothed) derivative u̇ — the limit
//! `u(t − τ) ≈ u − τ·u̇` for delays short against the time scale of u.

use super::signal::{derivative, moving_average};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "transport delay τ of the command; residual ≈ τ·du/dt (leads the \
     command's rate), optimistic margins, one-sample lag";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["delay"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    search: ShapeSearch::Delay,
    band_limit: false,
    amplitude_by_search: true,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Delay τ (s).
    delay: "s" = 0.0, [0.0, 10.0], Amplitude(0);
}

/// Set the actuator delay.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.actuator.delay = p.delay.value;
}

/// `[(u(t) − u(t − τs))/τs]`, or `[u̇]` for τs = 0.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let u = &traj.input[..n];
    let ts = shape.delay;
    if ts > 0.0 && traj.dt > 0.0 {
        let lag = ts / traj.dt;
        let whole = lag.floor() as usize;
        let frac = lag - whole as f64;
        let at = |i: usize| -> f64 {
            // u(t_i − τs), holding the first sample before the record starts.
            if i < whole + 1 {
                return u[0];
            }
            let j = i - whole;
            (1.0 - frac) * u[j] + frac * u[j - 1]
        };
        return vec![(0..n).map(|i| (u[i] - at(i)) / ts).collect()];
    }
    let smooth = moving_average(u, shape.smoothing);
    vec![derivative(&smooth, traj.dt)]
}

/// The derivative form (τs = 0) and τs = 1, 2, 3, 5, 10, 20 samples.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    std::iter::once(0.0)
        .chain([1.0, 2.0, 3.0, 5.0, 10.0, 20.0].map(|k| k * traj.dt))
        .map(|delay| Shape {
            delay,
            smoothing: 1,
            ..Shape::default()
        })
        .collect()
}
