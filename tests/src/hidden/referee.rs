//! The referee: how strong a hidden effect is (ρ), and the noise floor a refit is judged
//! against, from the truth alone — its noise-free signals and the noise it added — never
//! from the workbench's own fits, and with none of its code.
//!
//! Both are measured in the band the workbench is told to judge its residual in: a
//! zero-phase (forward–backward) 4th-order Butterworth low-pass at the trial's cut-off, the
//! differentiator the workbench documents. It is implemented here afresh, in the frequency
//! domain: the bilinear Butterworth's amplitude after a forward and a backward pass is
//! 1/(1 + (tan(πf)/tan(πf_c))⁸), f in cycles per sample.
//!
//! * **Floor**: what a perfect model leaves — the input's noise and the encoder's error (the
//!   logged minus the true position) through the inertia's five-point second difference, low-passed:
//!   `RMS(L·(n_u + J·D²·n_q))` over the record's interior.
//! * **Strength ρ**: the RMS of what the *start model* (rigid inertia + viscous friction, and
//!   Coulomb friction when the hidden effect is Stribeck) cannot explain of the noise-free
//!   joint, over the floor. It is fitted here by least squares on the truth's fine grid —
//!   the held command and the true motor position at every integration sub-step, so no
//!   sampling or hold convention enters it. Of a hidden effect, ρ counts only what it adds
//!   ([`beyond`]) to what the start model leaves of the truth's joint without it (a stiff
//!   transmission, a Coulomb law that is not a static sign).

use nalgebra::{DMatrix, DVector};
use rustfft::{num_complex::Complex64, FftPlanner};

use super::record::TruthRecord;

/// Fraction of a record dropped at each end (and at least four cut-off periods): the
/// low-pass rings at the ends, and the workbench drops its own edges too.
const EDGE_FRACTION: f64 = 0.05;

/// Amplitude response of the zero-phase low-pass at `f` cycles/sample for a cut-off `fc`
/// (cycles/sample).
fn lowpass(f: f64, fc: f64) -> f64 {
    let f = f.abs().min(0.499_999);
    let r = (std::f64::consts::PI * f).tan() / (std::f64::consts::PI * fc).tan();
    1.0 / (1.0 + r.powi(8))
}

/// Frequency (cycles/sample) of FFT bin `k` of `n`.
fn bin(k: usize, n: usize) -> f64 {
    let k = k as f64;
    let n = n as f64;
    if k <= n / 2.0 {
        k / n
    } else {
        k / n - 1.0
    }
}

/// `x` through the frequency response `h(f)` (f in cycles/sample), circularly: the ends are
/// dropped by the callers.
fn filter(x: &[f64], h: impl Fn(f64) -> Complex64) -> Vec<f64> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let mut planner = FftPlanner::new();
    let mut buf: Vec<Complex64> = x.iter().map(|&v| Complex64::new(v, 0.0)).collect();
    planner.plan_fft_forward(n).process(&mut buf);
    for (k, c) in buf.iter_mut().enumerate() {
        *c *= h(bin(k, n));
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    buf.iter().map(|c| c.re / n as f64).collect()
}

/// Interior of a record of `n` samples for a cut-off `fc` cycles/sample.
fn interior(n: usize, fc: f64) -> std::ops::Range<usize> {
    let edge = ((EDGE_FRACTION * n as f64) as usize).max((4.0 / fc).ceil() as usize);
    edge.min(n / 2)..n.saturating_sub(edge).max(n / 2)
}

fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// How the encoders' error reaches the residual of the model a refit is judged as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoisePath {
    /// A rigid joint's model: J·s² on the motor encoder's error.
    Rigid,
    /// A model with the joint's transmission spring: J1·s² + J2·s²·G(s), G the load's
    /// response to the motor (rigid when the record has no linear spring).
    Spring,
    /// A model that reads the load encoder too (a backlash on the measured deflection):
    /// J1·s² on the motor encoder's error and J2·s² on the load encoder's.
    TwoEncoders,
}

/// The noise floor of `rec`'s equation error at the cut-off `cutoff_hz` for a rigid model:
/// the input's noise plus the motor encoder's error through J·s².
pub fn floor(rec: &TruthRecord, cutoff_hz: f64) -> f64 {
    floor_with(rec, cutoff_hz, NoisePath::Rigid)
}

/// The noise floor for a model whose encoder noise takes `path`.
pub fn floor_on(rec: &TruthRecord, cutoff_hz: f64, path: NoisePath) -> f64 {
    floor_with(rec, cutoff_hz, path)
}

fn floor_with(rec: &TruthRecord, cutoff_hz: f64, path: NoisePath) -> f64 {
    let load = path == NoisePath::TwoEncoders;
    let fc = cutoff_hz * rec.dt;
    let dt = rec.dt;
    let error = |logged: &[f64], truth: &[f64]| -> Vec<f64> {
        logged.iter().zip(truth).map(|(m, t)| m - t).collect()
    };
    let nq = error(&rec.position, &rec.position_true);
    let (j, j2) = (rec.inertia, rec.inertia_load);
    let j1 = j - j2;
    // D², the documented five-point second difference (−1, 16, −30, 16, −1)/12:
    // (32·cos θ − 2·cos 2θ − 30)/(12·dt²) at θ = 2πf; s at the same frequency for G.
    let d2 = |f: f64| {
        let th = std::f64::consts::TAU * f;
        (32.0 * th.cos() - 2.0 * (2.0 * th).cos() - 30.0) / (12.0 * dt * dt)
    };
    let lu = filter(&rec.input_noise, |f| Complex64::new(lowpass(f, fc), 0.0));
    let motor_path = |f: f64| -> Complex64 {
        let jd = if load {
            Complex64::new(j1, 0.0)
        } else if let Some((k, c)) = rec.spring.filter(|_| path == NoisePath::Spring) {
            let s = Complex64::new(0.0, std::f64::consts::TAU * f / dt);
            let g = (s * c + k) / (s * s * j2 + s * c + k);
            j1 + g * j2
        } else {
            Complex64::new(j, 0.0)
        };
        jd * d2(f) * lowpass(f, fc)
    };
    let lq = filter(&nq, motor_path);
    let mut r: Vec<f64> = lu.iter().zip(&lq).map(|(u, q)| u - q).collect();
    if load && rec.load_position_true.len() == rec.load_position.len() {
        let nl = error(&rec.load_position, &rec.load_position_true);
        let ll = filter(&nl, |f| Complex64::new(j2 * d2(f) * lowpass(f, fc), 0.0));
        r.iter_mut().zip(&ll).for_each(|(x, l)| *x -= l);
    }
    rms(&r[interior(r.len(), fc)])
}

/// RMS of what the start model cannot explain of `rec`'s noise-free joint (see the module
/// docs), at the cut-off `cutoff_hz`; `coulomb` adds the start model's Coulomb friction.
pub fn excess(rec: &TruthRecord, cutoff_hz: f64, coulomb: bool) -> f64 {
    excess_with(rec, cutoff_hz, coulomb, Also::Nothing)
}

/// What the referee lets the start model explain beyond its own terms, to measure how much
/// of a hidden effect a simpler one could stand for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Also {
    /// The start model alone.
    Nothing,
    /// A constant torque: what of gravity an offset cannot explain.
    Offset,
    /// Any linear spring to a second mass with its own damping: what of a gap behind a
    /// spring a transmission without the gap cannot explain. Multiplied through by the
    /// load's `J_l·s² + c·s + k`, the motor-side law of a linear two-mass joint is linear
    /// in its coefficients: `u = −α·u̇ − β·ü + Σ γ_k·q⁽ᵏ⁾, k = 1…4`.
    Spring,
}

/// [`excess`] with more terms allowed (`also`).
pub fn excess_with(rec: &TruthRecord, cutoff_hz: f64, coulomb: bool, also: Also) -> f64 {
    let h = rec.fine_dt;
    let n = rec.fine_position.len().min(rec.fine_command.len());
    if n < 16 || h <= 0.0 {
        return f64::NAN;
    }
    let fc = cutoff_hz * h;
    // Position minus the line through its ends: periodic enough for the FFT's derivatives;
    // the line's own derivative (a constant velocity) is added back.
    let x = &rec.fine_position[..n];
    let slope = (x[n - 1] - x[0]) / ((n - 1) as f64 * h);
    let detrended: Vec<f64> = x
        .iter()
        .enumerate()
        .map(|(i, v)| v - x[0] - slope * i as f64 * h)
        .collect();
    let w = |f: f64| std::f64::consts::TAU * f / h;
    // The k-th derivative, band-limited: (iω)^k·L(f).
    let derivative = |y: &[f64], k: i32| {
        filter(y, |f| {
            Complex64::new(0.0, w(f)).powi(k) * Complex64::new(lowpass(f, fc), 0.0)
        })
    };
    // The command's k-th derivative, band-limited. Its sample i is the value held over
    // [i·h, (i+1)·h), centred half a sub-step after the position's sample i: delayed by h/2
    // onto the positions' instants (else a rigid joint leaves ω·h/2 of its in-band command
    // as excess, which on a quiet record is more than the floor).
    let held = |k: i32| {
        filter(&rec.fine_command[..n], |f| {
            Complex64::new(0.0, w(f)).powi(k)
                * Complex64::from_polar(lowpass(f, fc), -std::f64::consts::PI * f)
        })
    };
    let v: Vec<f64> = derivative(&detrended, 1)
        .into_iter()
        .map(|v| v + slope)
        .collect();
    let a = derivative(&detrended, 2);
    let u = held(0);
    let mut cols = vec![a, v.clone()];
    // The start model's Coulomb column: the sign of the true velocity, band-limited.
    let sign: Option<Vec<f64>> = coulomb.then(|| {
        filter(&detrended, |f| Complex64::new(0.0, w(f)))
            .into_iter()
            .map(|v| (v + slope).signum())
            .collect()
    });
    if let Some(sign) = &sign {
        cols.push(derivative(sign, 0));
    }
    let keep = interior(n, fc);
    match also {
        Also::Nothing => {}
        Also::Offset => cols.push(vec![1.0; n]),
        Also::Spring => {
            cols.push(derivative(&detrended, 3));
            cols.push(derivative(&detrended, 4));
            if let Some(sign) = &sign {
                // Multiplied through as well: the motor's Coulomb torque times J_l·s² + c·s + k.
                cols.push(derivative(sign, 1));
                cols.push(derivative(sign, 2));
            }
            let du = cols.len();
            cols.push(held(1));
            cols.push(held(2));
            return beyond_spring(&cols, &u, du, keep, w, h).unwrap_or(f64::NAN);
        }
    }
    fit(&cols, &u, keep).map_or(f64::NAN, |(_, r)| rms(&r))
}

/// Least squares of `u` on `cols` over the interior `keep`, every sub-step (the band is far
/// below the fine rate), columns scaled to unit norm as derivatives up to the fourth span many
/// decades: the coefficients (of the unscaled columns) and the residual.
fn fit(cols: &[Vec<f64>], u: &[f64], keep: std::ops::Range<usize>) -> Option<(Vec<f64>, Vec<f64>)> {
    let m = keep.len();
    let scale: Vec<f64> = cols
        .iter()
        .map(|c| {
            let s = rms(&c[keep.clone()]);
            if s > 0.0 {
                1.0 / s
            } else {
                1.0
            }
        })
        .collect();
    let xm = DMatrix::from_fn(m, cols.len(), |i, j| cols[j][keep.start + i] * scale[j]);
    let y = DVector::from_iterator(m, u[keep].iter().copied());
    let theta = xm.clone().svd(true, true).solve(&y, 1e-12).ok()?;
    let r = y - xm * &theta;
    let theta = theta.iter().zip(&scale).map(|(t, s)| t * s).collect();
    Some((theta, r.iter().copied().collect()))
}

/// Iterations of [`beyond_spring`]'s refit (it settles in two or three).
const PREFILTER_PASSES: usize = 4;

/// RMS torque residual of the best linear two-mass joint, in the output-error sense. The
/// multiplied-through law `A(s)·u = B(s)·q` with `A = 1 − α·s − β·s²` (the coefficients of
/// the columns `du`, `du + 1`: u̇, ü) is linear in its coefficients, but its equation error
/// is the torque error times A, which is small near the load's antiresonance and large above
/// it. Steiglitz–McBride: refit with every column and `u` through 1/A of the last fit, so
/// that the residual is the torque error itself.
fn beyond_spring(
    cols: &[Vec<f64>],
    u: &[f64],
    du: usize,
    keep: std::ops::Range<usize>,
    w: impl Fn(f64) -> f64,
    h: f64,
) -> Option<f64> {
    let (mut theta, mut r) = fit(cols, u, keep.clone())?;
    for _ in 0..PREFILTER_PASSES {
        let (alpha, beta) = (*theta.get(du)?, *theta.get(du + 1)?);
        // 1/A rings for 1/σ, σ the slowest decay among A's roots: the ends' artefacts (the
        // circular filters wrap there) are kept out for six of those, or the residual stays the
        // equation error's.
        let Some(edge) = ring_samples(alpha, beta, h).filter(|&e| 4 * e < keep.len()) else {
            break;
        };
        let inner = keep.start + edge..keep.end - edge;
        let inverse = |f: f64| {
            let s = Complex64::new(0.0, w(f));
            let a = 1.0 - alpha * s - beta * s * s;
            // A zero of A on the axis would be a load without damping: cap the gain there.
            if a.norm() < 1e-6 {
                Complex64::new(1e6, 0.0)
            } else {
                1.0 / a
            }
        };
        let through: Vec<Vec<f64>> = cols.iter().map(|c| filter(c, inverse)).collect();
        (theta, r) = fit(&through, &filter(u, inverse), inner)?;
    }
    Some(rms(&r))
}

/// Six decay times of 1/A, A(s) = 1 − α·s − β·s², in samples of `h` (None for an A whose
/// slowest root does not decay).
fn ring_samples(alpha: f64, beta: f64, h: f64) -> Option<usize> {
    let sigma = if beta.abs() < 1e-300 {
        // First order: the root 1/α.
        (1.0 / alpha).abs()
    } else {
        // β·s² + α·s − 1 = 0.
        let disc = Complex64::new(alpha * alpha + 4.0 * beta, 0.0).sqrt();
        let r1 = (-alpha + disc) / (2.0 * beta);
        let r2 = (-alpha - disc) / (2.0 * beta);
        r1.re.abs().min(r2.re.abs())
    };
    let samples = 6.0 / (sigma * h);
    (sigma > 0.0 && samples.is_finite()).then(|| samples.ceil() as usize)
}

/// What an effect adds to an excess the start model leaves without it (`base`), both as
/// RMS torques: in quadrature, as independent parts of a residual add (0 where the base is
/// the larger; NaN if either is). Parts at the same instants (a Stribeck excess and
/// presliding, both at the reversals) are not independent: there it is an estimate.
pub fn beyond(excess: f64, base: f64) -> f64 {
    if excess.is_finite() && base.is_finite() {
        (excess * excess - base * base).max(0.0).sqrt()
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A truth record from a fine grid (`sub` sub-steps per sample of `dt`): the positions
    /// logged exactly at the samples, the given input noise, inertias `(J, J2)`.
    fn fine_record(
        dt: f64,
        sub: usize,
        fine_position: Vec<f64>,
        fine_command: Vec<f64>,
        (inertia, inertia_load): (f64, f64),
        input_noise: Vec<f64>,
    ) -> TruthRecord {
        let n = fine_position.len() / sub;
        let sampled: Vec<f64> = (0..n).map(|k| fine_position[k * sub]).collect();
        TruthRecord {
            dt,
            time: (0..n).map(|k| k as f64 * dt).collect(),
            input: vec![0.0; n],
            position: sampled.clone(),
            load_position: Vec::new(),
            input_noise,
            position_true: sampled,
            fine_dt: dt / sub as f64,
            fine_command,
            fine_position,
            inertia,
            inertia_load,
            spring: None,
            load_position_true: Vec::new(),
            gear_ratio: 1.0,
        }
    }

    /// A rigid joint driven by a smooth torque leaves no excess; white input noise of σ
    /// leaves a floor of σ times the low-pass's noise gain (√(2·f_c·∫…) ≈ √(2f_c) for a
    /// sharp filter).
    #[test]
    fn rigid_joint_has_no_excess_and_white_noise_its_band_share() {
        let (dt, sub, n) = (1e-3, 10, 8000);
        let h = dt / sub as f64;
        let (j, b) = (0.01, 0.05);
        let m = n * sub;
        // x(t) = sin(2πt) + 0.3 sin(2π·3.1t): u = J·ẍ + b·ẋ exactly.
        let (w1, w2) = (std::f64::consts::TAU, std::f64::consts::TAU * 3.1);
        let t = |i: usize| i as f64 * h;
        let x: Vec<f64> = (0..m)
            .map(|i| (w1 * t(i)).sin() + 0.3 * (w2 * t(i)).sin())
            .collect();
        // Held over each sub-step, as every truth logs it: the sub-step's mean, its midpoint
        // value to O(h²).
        let u: Vec<f64> = (0..m)
            .map(|i| {
                let t = t(i) + 0.5 * h;
                let a = -w1 * w1 * (w1 * t).sin() - 0.3 * w2 * w2 * (w2 * t).sin();
                let v = w1 * (w1 * t).cos() + 0.3 * w2 * (w2 * t).cos();
                j * a + b * v
            })
            .collect();
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise: Vec<f64> = (0..n)
            .map(|_| 0.01 * (rng.random::<f64>() - 0.5) * 12f64.sqrt())
            .collect();
        let rec = fine_record(dt, sub, x, u, (j, 0.0), noise.clone());
        let fl = floor(&rec, 40.0);
        let band = (2.0 * 40.0 * dt).sqrt() * rms(&noise);
        assert!((fl / band - 1.0).abs() < 0.25, "floor {fl} vs {band}");
        let ex = excess(&rec, 40.0, false);
        assert!(ex < 1e-3 * rms(&rec.fine_command), "excess {ex}");
        // A constant offset torque is excess.
        let mut off = rec.clone();
        off.fine_command.iter_mut().for_each(|u| *u += 0.05);
        assert!(excess(&off, 40.0, false) > 0.01);
        // ... which a constant column explains; a torque varying with the position does not
        // go away with it.
        assert!(excess_with(&off, 40.0, false, Also::Offset) < 1e-3 * 0.05);
        let mut grav = rec.clone();
        let (x, u) = (grav.fine_position.clone(), &mut grav.fine_command);
        u.iter_mut()
            .zip(&x)
            .for_each(|(u, x)| *u += 0.05 * (3.0 * x).sin());
        assert!(excess_with(&grav, 40.0, false, Also::Offset) > 0.01);
    }

    /// A linear two-mass joint is all excess to the rigid model and none beyond a spring; a
    /// torque nonlinear in the position stays excess beyond it.
    #[test]
    fn a_linear_spring_is_no_excess_beyond_a_spring_and_a_nonlinear_torque_is() {
        let (dt, sub, n) = (1e-3, 10, 8000);
        let h = dt / sub as f64;
        let m = n * sub;
        let (jm, b, jl, c, k) = (0.01, 0.05, 0.02, 0.3, 400.0);
        let s = |w: f64| Complex64::new(0.0, w);
        // Each tone of the motor position drags the load through the spring; the motor
        // torque drives both: u = (J_m·s² + b·s)·q_m + (c·s + k)·(q_m − q_l).
        let tones = [(1.0, 1.0), (3.1, 0.3), (11.7, 0.05), (23.0, 0.01)];
        let (mut x, mut u) = (vec![0.0; m], vec![0.0; m]);
        for &(f, amp) in &tones {
            let w = std::f64::consts::TAU * f;
            let spring = c * s(w) + k;
            let load = spring / (jl * s(w) * s(w) + spring);
            let torque = (jm * s(w) * s(w) + b * s(w)) + spring * (1.0 - load);
            for i in 0..m {
                let e = |t: f64| Complex64::from_polar(amp, w * t);
                x[i] += e(i as f64 * h).re;
                // Held over the sub-step: its value at the middle.
                u[i] += (torque * e((i as f64 + 0.5) * h)).re;
            }
        }
        let rec = fine_record(dt, sub, x.clone(), u.clone(), (jm, jl), vec![0.0; n]);
        let size = rms(&u);
        let rigid = excess(&rec, 40.0, false);
        let spring = excess_with(&rec, 40.0, false, Also::Spring);
        assert!(rigid > 1e-2 * size, "rigid excess {rigid} of {size}");
        assert!(
            spring < 1e-3 * rigid,
            "beyond a spring {spring}, rigid {rigid}"
        );
        let mut cubic = rec.clone();
        cubic
            .fine_command
            .iter_mut()
            .zip(&x)
            .for_each(|(u, x)| *u += 0.2 * x * x * x);
        let term: Vec<f64> = x.iter().map(|x| 0.2 * x * x * x).collect();
        let beyond = excess_with(&cubic, 40.0, false, Also::Spring);
        assert!(
            beyond > 0.5 * rms(&term),
            "a cubic torque of RMS {} beyond a spring {beyond}",
            rms(&term)
        );
    }

    /// A command held over whole ticks drives a rigid inertia, integrated exactly: its
    /// positions at the sub-step starts leave no excess. Read as samples at those instants
    /// instead of holds over the sub-steps, the command would lead them by h/2, ω·h/2 of it.
    #[test]
    fn a_held_command_on_a_rigid_joint_leaves_no_excess() {
        let (dt, sub, n) = (1e-3, 10, 6000);
        let h = dt / sub as f64;
        let j = 0.002;
        let tone = |t: f64| {
            [(7.0, 1.0), (19.0, 0.6), (31.0, 0.3)]
                .iter()
                .map(|&(f, a)| a * (std::f64::consts::TAU * f * t).sin())
                .sum::<f64>()
        };
        let (mut x, mut v) = (0.0, 0.0);
        let (mut q, mut u) = (Vec::new(), Vec::new());
        for k in 0..n {
            let held = tone(k as f64 * dt);
            for _ in 0..sub {
                q.push(x);
                u.push(held);
                x += v * h + 0.5 * held / j * h * h;
                v += held / j * h;
            }
        }
        let rec = fine_record(dt, sub, q, u.clone(), (j, 0.0), vec![0.0; n]);
        let ex = excess(&rec, 40.0, false);
        assert!(ex < 1e-3 * rms(&u), "excess {ex} of {}", rms(&u));
    }
}
