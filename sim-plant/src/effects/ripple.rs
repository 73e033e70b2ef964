//! Position-periodic transmission ripple (thesis §3.2 "Transmission torque ripple": HD 2–8 N·m
//! at tooth spacing growing with load and misalignment; REDEX 10–15 %; DOJEN 5–10 %; KAMO
//! < 5 % at the ball-lobe period; Sumitomo spikes; cable ≈ none).
//!
//! Dynamics: a resisting torque on the output,
//! `R = (s·sin(2πq/P) + c·cos(2πq/P))·(1 + g·|τ_T|)`, q = output angle, τ_T = transmitted
//! torque (amplitude grows with load, g in 1/(N·m)).
//!
//! Fingerprint: `[sin(2πq/P), cos(2πq/P)]` (the load growth is left to the dynamics; at
//! constant load it rescales s and c). Thesis-notes §7.7: periodic in *output position*,
//! frequency ∝ speed — search periods, i.e. an FFT against position, not time.

use std::f64::consts::TAU;

use super::laws::PeriodicTorque;
use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};
use super::{EffectKind, FitTraits, ShapeSearch, SmoothShape};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "transmission ripple periodic in output angle (tooth/lobe/roller \
     spacing), amplitude may grow with load; residual periodic in output position with \
     frequency proportional to speed";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["sin", "cos"];

/// Admissible sign of the first amplitude: either.
pub const SIGN: Option<f64> = None;

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    smooth_shape: Some(SmoothShape {
        get: |s| s.ripple_period,
        unit: "rad",
        set: |s, v| s.ripple_period = v,
    }),
    search: ShapeSearch::Period,
    file_shape: &[same_shape!("period" => ripple_period)],
    nests: &[EffectKind::Gravity],
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Sine amplitude (N·m).
    sin: "N·m" = 0.0, [-1e6, 1e6], Amplitude(0);
    /// Cosine amplitude (N·m).
    cos: "N·m" = 0.0, [-1e6, 1e6], Amplitude(1);
    /// Spatial period P (rad of output angle).
    period: "rad" = 0.05, [1e-9, 1e6], Shape;
    /// Relative amplitude growth per N·m of transmitted torque (1/(N·m)).
    load_gain: "1/(N·m)" = 0.0, [0.0, 1e6], Setting;
}

/// Set the output-side periodic torque.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.ripple = PeriodicTorque {
        sin: p.sin.value,
        cos: p.cos.value,
        wavenumber: TAU / p.period.value,
        load_gain: p.load_gain.value,
    };
}

/// `[sin(2πq/P), cos(2πq/P)]`.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    periodic_columns(traj, shape.ripple_period)
}

/// Periods log-spaced between max(span/1000, 4 samples of travel at top speed) and span/2.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    periods(traj)
        .into_iter()
        .map(|ripple_period| Shape {
            ripple_period,
            ..Shape::default()
        })
        .collect()
}

/// Finer periods around `best`: ±11 % (half a coarse step either way) in steps of a fifth of
/// a period over the travel (the phase drift that halves the correlation), at most 121 points.
pub fn refine_grid(traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = hi - lo;
    let p = best.ripple_period;
    if !(span > 0.0 && p > 0.0) {
        return Vec::new();
    }
    let step = (0.2 * p / span).max(0.11 / 60.0);
    let k = (0.11 / step).ceil() as i32;
    (-k..=k)
        .filter(|&i| i != 0)
        .map(|i| Shape {
            ripple_period: p * (1.0 + step * i as f64),
            ..best.clone()
        })
        .collect()
}

/// Shared with cogging and gravity-like features.
pub(crate) fn periodic_columns(traj: &Trajectory, period: f64) -> Vec<Vec<f64>> {
    let k = TAU / positive_or(period, 1.0);
    let (s, c): (Vec<f64>, Vec<f64>) = traj.position[..traj.len()]
        .iter()
        .map(|&q| (k * q).sin_cos())
        .unzip();
    vec![s, c]
}

/// Log-spaced candidate periods for the trajectory (see [`shape_grid`]).
pub(crate) fn periods(traj: &Trajectory) -> Vec<f64> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = hi - lo;
    if span.is_nan() || span <= 0.0 {
        return vec![Shape::default().ripple_period];
    }
    let pmin = (span / 1000.0).max(4.0 * traj.dt * traj.max_abs_velocity());
    let pmax = span / 2.0;
    if pmin >= pmax {
        return vec![pmax];
    }
    log_space(pmin, pmax, 32)
}
