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
use super::signal::{log_space, periodogram_peaks, positive_or};
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
    position_period: Some(|s, _| s.ripple_period),
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

/// Peaks of the screen handed on to the exact test.
const SCREEN_PEAKS: usize = 4;

/// The periods where `residual` correlates most with the fingerprint, from a dense screen of
/// wavenumbers (`signal::periodogram_peaks` over the position), and how many the screen
/// looked at (the search's multiplicity).
///
/// A ripple's correlation with the residual lives in a lobe 2π/span wide in wavenumber
/// (its phase drifts a whole turn over the travel at the lobe's edge): on a record that
/// travels many periods that lobe is a few per cent of the period, far narrower than the
/// log grid's step, which then steps over it.
pub fn screen(traj: &Trajectory, residual: &[f64]) -> (Vec<Shape>, usize) {
    let n = traj.len().min(residual.len());
    let periods = periods(traj);
    let (Some(&pmin), Some(&pmax)) = (periods.first(), periods.last()) else {
        return (Vec::new(), 0);
    };
    let (found, count) = periodogram_peaks(
        &traj.position[..n],
        &residual[..n],
        (pmin, pmax),
        SCREEN_PEAKS,
    );
    let shapes = found
        .into_iter()
        .map(|p| Shape {
            ripple_period: p,
            ..Shape::default()
        })
        .collect();
    (shapes, count)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A record travelling back and forth over 15 rad (tens of periods), a ripple in the
    /// residual at periods spread over a decade and a half, in white noise as strong as the
    /// ripple: the screen's strongest peak is within one of its steps of the ripple's
    /// wavenumber, wherever the period falls between the log grid's points (which step
    /// 15 % here, while the lobe is 1–13 % of the period wide).
    #[test]
    fn the_screen_finds_a_period_between_grid_points() {
        let (dt, n) = (1e-3, 12_000);
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let w = TAU * 0.25;
        let q: Vec<f64> = t.iter().map(|t| 7.5 * (1.0 - (w * t).cos())).collect();
        let v: Vec<f64> = t.iter().map(|t| 7.5 * w * (w * t).sin()).collect();
        let a: Vec<f64> = t.iter().map(|t| 7.5 * w * w * (w * t).cos()).collect();
        let zero = vec![0.0; n];
        let traj = Trajectory::unfiltered(dt, &zero, &q, &v, &a);
        let noise = super::super::signal::unit_noise;
        let grid = periods(&traj);
        assert!(grid.len() > 2 && grid[1] / grid[0] > 1.1, "{grid:?}");
        for period in log_space(0.1, 3.0, 9) {
            let e: Vec<f64> = q
                .iter()
                .enumerate()
                .map(|(i, &x)| (TAU * x / period + 0.7).sin() + noise(i as u64))
                .collect();
            let (shapes, looked_at) = screen(&traj, &e);
            let best = shapes.first().expect("a peak").ripple_period;
            // Within the screen's step (a quarter of the 2π/span lobe) in wavenumber: well
            // inside the finer grid the search then lays around it.
            let miss = (TAU / best - TAU / period).abs();
            assert!(miss <= TAU / 15.0 / 4.0, "{period}: {best}");
            assert!(looked_at > grid.len(), "{looked_at}");
        }
    }
}
