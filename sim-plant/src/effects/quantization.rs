//! Quantisation of the input (D/A steps of the torque command; thesis §3.2 "Quantization":
//! torque-sensor and D/A steps, 2304 counts/rev). Sensor quantisation (encoder counts, torque
//! sensor LSB) is always modelled by the plant's sensors ([`crate::plant::sensors`]); in an
//! equation-error residual it appears as white-ish fuzz bounded by ≈ 1 LSB × gain, not as a
//! regressor, so this effect covers the input path.
//!
//! Dynamics: applied = `u − g·(u − Δ·round(u/Δ))` (g = 1: fully quantised).
//! Fingerprint: `R = u − applied = g·(u − Q_Δ(u))`: column `[u − Q_Δ(u)]` — the recorded
//! command's own quantisation sawtooth — low-passed as the residual was
//! (`Trajectory::lowpass_hz`), amplitude g. Noise on the recorded command does not bias the
//! test: the sawtooth's mean slope over a period is zero, so (Stein's lemma) it is uncorrelated
//! with additive Gaussian noise once the command spans several steps.

use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};
use super::{FitTraits, ShapeSearch};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "quantisation of the command (D/A steps Δ); residual is a bounded \
     sawtooth of the command within ±Δ/2, fuzz band, no effect at very low amplitude";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["gain"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

/// What the fitter needs to know beyond the columns (see [`FitTraits`]).
pub const FIT: FitTraits = FitTraits {
    searched_shape: true,
    search: ShapeSearch::Quantum,
    file_shape: &[same_shape!("step" => quantum)],
    band_limit: false,
    ..FitTraits::PLAIN
};

crate::define_params! {
    /// Quantiser step Δ (N·m, output-referred); 0 = none.
    step: "N·m" = 0.0, [0.0, 1e6], Shape;
    /// Fraction of the quantisation error present (1 = fully quantised).
    gain: "1" = 1.0, [0.0, 1.0], Amplitude(0);
}

/// Rounding error `x − Δ·round(x/Δ)`, in (−Δ/2, Δ/2].
#[inline(always)]
pub fn error(x: f64, step: f64) -> f64 {
    x - step * (x / step).round()
}

/// Expectation of [`error`] at `x + n`, n ~ N(0, σ²): the Fourier series of the sawtooth,
/// x − Δ·round(x/Δ) = Σ (Δ/π)·(−1)^(k+1)/k·sin(2πkx/Δ), each harmonic damped by
/// exp(−2π²k²σ²/Δ²) (truncated where that is below 1e-4). Noise on the recorded command
/// blurs the jumps of its quantisation sawtooth.
pub fn blurred_error(x: f64, step: f64, sigma: f64) -> f64 {
    let r = sigma / step;
    let c = -2.0 * std::f64::consts::PI * std::f64::consts::PI * r * r;
    let (s1, c1) = (std::f64::consts::TAU * x / step).sin_cos();
    let (mut sk, mut ck) = (s1, c1);
    let mut out = 0.0;
    for k in 1..=200 {
        let kf = k as f64;
        let damp = (c * kf * kf).exp();
        if damp < 1e-4 {
            break;
        }
        let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
        out += sign / kf * damp * sk;
        (sk, ck) = (sk * c1 + ck * s1, ck * c1 - sk * s1);
    }
    step / std::f64::consts::PI * out
}

/// Set the actuator quantiser.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.actuator.quant_step = p.step.value;
    laws.actuator.quant_gain = p.gain.value;
}

/// `[lowpass(u − Q_Δ(u))]` of the recorded command (zeros when Δ = 0).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let (u, window) = traj.recorded_input();
    let d = shape.quantum;
    vec![if d > 0.0 {
        let saw: Vec<f64> = if shape.quantum_blur > 0.0 {
            u.iter().map(|&u| blurred_error(u, d, shape.quantum_blur)).collect()
        } else {
            u.iter().map(|&u| error(u, d)).collect()
        };
        traj.input_lowpass(&saw)[window].to_vec()
    } else {
        vec![0.0; window.len()]
    }]
}

/// Sample-to-sample scatter of the recorded command (RMS of the second difference / √6): the
/// scale of its noise and dither, below which a quantiser leaves nothing to see.
fn scatter(u: &[f64]) -> f64 {
    let m = u.len().saturating_sub(2);
    if m == 0 {
        return 0.0;
    }
    let s: f64 = u
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).powi(2))
        .sum();
    (s / m as f64 / 6.0).sqrt()
}

/// Steps log-spaced (≈ 6 % apart) from 0.3× the command's sample-to-sample scatter (or a
/// hundredth of its range if smaller) to ⅔ of its peak |u|, so a command swinging ±|u| spans at
/// least three levels (−Δ, 0, Δ). A coarse D/A with few steps across the range is the
/// strongest case (capped at a third of the peak, such a quantiser was fitted as a third of its
/// step with gain 3); a coarser grid point would be a two-level relay whose sawtooth stands
/// in for other reversal effects (backlash chatter ranked as quantization). The sawtooth of
/// a wrong step decorrelates quickly, hence the fine spacing; [`refine_grid`] polishes it.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let (u, window) = traj.recorded_input();
    let u = &u[window];
    let range = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let range = positive_or(range, 1.0);
    let lo = positive_or(scatter(u), 1e-3 * range);
    let lo = (0.3 * lo).min(0.01 * range);
    let hi = (range / 1.5).max(lo);
    let count = (((hi / lo).ln() / 1.06f64.ln()).ceil() as usize).max(1);
    log_space(lo, hi, count)
        .into_iter()
        .map(|quantum| Shape {
            quantum,
            ..Shape::default()
        })
        .collect()
}

/// Steps a screen of `residual` picks out (strongest first, at most four), and how many it
/// looked at: the sawtooth `u − Q_Δ(u)` is periodic in the command with period Δ, so its
/// fundamental shows as a peak of the residual's periodogram over the recorded command
/// (`signal::periodogram_peaks`), from the grid's coarsest step down to 1/1000 of the
/// command's span. The sawtooth's correlation peak is about 1/(2K) wide in Δ (K = max|u|/Δ
/// steps, see the refit's search): a command spanning 27 steps kept 40 % of a residual at its
/// step and 4 % two per cent off, so the log grid's 6 % steps can pass over it.
///
/// The screen reaches below the grid's floor (the command's sample-to-sample scatter): where
/// the log holds the very command the converter got, a step finer than the command moves in
/// one sample still leaves its sawtooth, exactly computable, in the residual; where the log
/// adds noise to it, the noise blurs that sawtooth away and the peak does not stand out.
/// Below 1/1000 of the span (K ≈ 500) the walk would outgrow its budget, and a step whose
/// whole sawtooth (RMS Δ/√12, which the low-pass only lowers) is under 0.3 of the residual's
/// RMS could explain less than a tenth of it, so neither is walked.
pub fn screen(traj: &Trajectory, residual: &[f64]) -> (Vec<Shape>, usize) {
    let hi = shape_grid(traj)
        .iter()
        .fold(0.0f64, |h, s| h.max(s.quantum));
    let (u, window) = traj.recorded_input();
    let Some(u) = u.get(window) else {
        return (Vec::new(), 0);
    };
    let (a, b) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
    let rms = (residual.iter().map(|r| r * r).sum::<f64>() / residual.len().max(1) as f64).sqrt();
    let lo = ((b - a) / 1000.0).max(0.3 * 12f64.sqrt() * rms).min(hi);
    let (steps, count) = super::signal::periodogram_peaks(u, residual, (lo, hi), 4);
    let shapes = steps
        .into_iter()
        .map(|quantum| Shape {
            quantum,
            ..Shape::default()
        })
        .collect();
    (shapes, count)
}

/// Steps within ±3 % of `best`, 1 % apart.
pub fn refine_grid(_traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    (-3i32..=3)
        .filter(|&i| i != 0)
        .map(|i| Shape {
            quantum: best.quantum * 1.01f64.powi(i),
            ..best.clone()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A command sweeping ±0.6 (a chirp-like sine of growing frequency) and a residual that
    /// is its sawtooth at a step Δ in noise as strong: the screen's strongest peak is
    /// within a quarter of the sawtooth's correlation peak (1/(2K) of Δ) of the step,
    /// wherever it falls between the log grid's points.
    #[test]
    fn the_screen_finds_a_step_between_grid_points() {
        let (dt, n) = (1e-3, 12_000);
        let u: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                0.6 * (std::f64::consts::TAU * (0.2 + 0.3 * t) * t).sin()
            })
            .collect();
        let zero = vec![0.0; n];
        let traj = Trajectory::unfiltered(dt, &u, &zero, &zero, &zero);
        let noise = super::super::signal::unit_noise;
        for d in log_space(0.012, 0.2, 7) {
            let rms = d / 12f64.sqrt();
            let e: Vec<f64> = u
                .iter()
                .enumerate()
                .map(|(i, &x)| error(x, d) + rms * noise(i as u64))
                .collect();
            let (shapes, looked_at) = screen(&traj, &e);
            let found = shapes.first().expect("a peak").quantum;
            let k = 0.6 / d;
            assert!((found / d - 1.0).abs() < 0.25 / k, "{d}: {found}");
            assert!(looked_at > shape_grid(&traj).len(), "{looked_at}");
        }
    }

    /// A digital log of a dithered command (a 0.1 mN·m lattice, moving ~0.04 per sample):
    /// a converter's step well under that scatter, below the grid's floor, still leaves the
    /// exact sawtooth of the logged command, and the screen finds it in noise half as strong.
    #[test]
    fn the_screen_finds_a_step_finer_than_the_command_moves_per_sample() {
        let (dt, n) = (1e-3, 12_000);
        let noise = super::super::signal::unit_noise;
        let u: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                let x = 0.5 * (std::f64::consts::TAU * 0.3 * t).sin() + 0.05 * noise(i as u64);
                (x / 1e-4).round() * 1e-4
            })
            .collect();
        let zero = vec![0.0; n];
        let traj = Trajectory::unfiltered(dt, &u, &zero, &zero, &zero);
        let d = 0.00263;
        let floor = shape_grid(&traj)[0].quantum;
        assert!(d < 0.5 * floor, "the step {d} is not below the grid's floor {floor}");
        let e: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(i, &x)| error(x, d) + 0.5 * d / 12f64.sqrt() * noise(i as u64 + 7 * n as u64))
            .collect();
        let (shapes, _) = screen(&traj, &e);
        let found = shapes.first().expect("a peak").quantum;
        let k = 0.55 / d;
        assert!((found / d - 1.0).abs() < 0.25 / k, "{d}: {found}");
    }

    #[test]
    fn blurred_sawtooth_is_the_sawtooth_without_blur_and_its_expectation_with() {
        let d = 0.1;
        // Away from the jumps a light blur leaves the sawtooth (Gibbs ripple aside).
        for &x in &[0.013, 0.031, -0.022, 0.27] {
            let (a, b) = (blurred_error(x, d, 0.002), error(x, d));
            assert!((a - b).abs() < 2e-3, "{x}: {a} vs {b}");
        }
        // With a heavy blur it is the mean of the sawtooth at x + n, n ~ N(0, s²) (numerical
        // integral over the Gaussian density).
        let (x, s) = (0.04, 0.03);
        let m = 40_000;
        let h = 16.0 / m as f64;
        let mean: f64 = (0..=m)
            .map(|i| {
                let z = -8.0 + i as f64 * h;
                let w = (-0.5 * z * z).exp() / (std::f64::consts::TAU).sqrt() * h;
                w * error(x + s * z, d)
            })
            .sum();
        let b = blurred_error(x, d, s);
        assert!((b - mean).abs() < 5e-4, "{b} vs {mean}");
    }
}
