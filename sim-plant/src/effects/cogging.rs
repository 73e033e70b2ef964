//! Motor cogging / torque ripple, periodic in rotor angle (thesis §3.2 "Motor ripple/detent":
//! SEIBERCO ±1 % of max, 0.016 N·m at the motor, 18 magnets → 9 electrical cycles per rev,
//! 60–65 Hz at test speed; reflected ±0.4 N·m at 30:1, ±0.9 N·m at 60:1).
//!
//! Dynamics: a resisting torque on the motor node,
//! `R = s·sin(n·θm) + c·cos(n·θm)`, θm = motor angle (rad), n = cycles per motor rev; the
//! amplitudes are output-referred (motor-side value × N) like every other parameter.
//!
//! Fingerprint: `[sin(2πq/P), cos(2πq/P)]` of the trajectory position with P the cogging
//! period (`Shape::cogging_period`) in that position's units — 2π/(n·N) for output-referred data. Thesis-notes §7.8:
//! periodic in *rotor* angle, constant magnitude, visible only when friction is smaller.

use super::laws::PeriodicTorque;
use super::{EffectLaws, Shape, Trajectory};
use super::{FileShape, FitTraits};
use std::f64::consts::TAU;

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "motor cogging periodic in rotor angle (9 cycles/rev for the \
     SEIBERCO), constant magnitude; residual periodic in motor position at N× the output \
     ripple frequency";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["sin", "cos"];

/// Admissible sign of the first amplitude: either.
pub const SIGN: Option<f64> = None;

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    // The file counts cycles per motor revolution; the fit's period is at the output.
    file_shape: &[FileShape {
        param: "cycles_per_rev",
        get: |s, n| (s.cogging_period > 0.0).then(|| TAU / (s.cogging_period * n)),
        set: |s, v, n| s.cogging_period = TAU / (v * n),
    }],
    position_period: Some(|s, _| s.cogging_period),
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Sine amplitude (N·m, output-referred).
    sin: "N·m" = 0.0, [-1e6, 1e6], Amplitude(0);
    /// Cosine amplitude (N·m, output-referred).
    cos: "N·m" = 0.0, [-1e6, 1e6], Amplitude(1);
    /// Ripple cycles per motor revolution.
    cycles_per_rev: "cycles/rev" = 9.0, [1e-6, 1e6], Shape;
}

/// Set the motor-side periodic torque (wavenumber per rad of motor angle).
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.cogging = PeriodicTorque {
        sin: p.sin.value,
        cos: p.cos.value,
        wavenumber: p.cycles_per_rev.value,
        load_gain: 0.0,
    };
}

/// `[sin(2πq/P), cos(2πq/P)]` with `P = Shape::cogging_period`; empty (not testable) when
/// the period is unknown (0).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    if shape.cogging_period > 0.0 {
        super::ripple::periodic_columns(traj, shape.cogging_period)
    } else {
        Vec::new()
    }
}

/// Same period grid as ripple (the ratio N is not known from a trajectory; a caller who knows
/// it sets `cogging_period = 2π/(cycles·N)` directly).
/// Why the record rules cogging out as a candidate of its own: with its period unknown, its
/// columns are a periodic torque in the measured position — ripple's, period for period — so
/// a diagnosis tests the fingerprint once, as ripple, and the verdict's period tells which
/// (a rotor-angle period of 2π/cycles, an output one of 2π/(cycles·N) at the motor). With
/// the period known (`Shape::cogging_period`) a model still holds and fits it.
pub fn ruled_out(_traj: &Trajectory) -> Option<&'static str> {
    Some(
        "the same fingerprint as ripple (a torque periodic in the measured position) while \
         its period is unknown: tested as ripple, whose period tells which",
    )
}

pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    super::ripple::periods(traj)
        .into_iter()
        .map(|cogging_period| Shape {
            cogging_period,
            ..Shape::default()
        })
        .collect()
}
