//! The smoothing differentiator: zero-phase 4th-order Butterworth low-pass (forward–backward,
//! odd-reflection padding) followed by fourth-order central differences (five points).
//!
//! Why this one: it is what the EMPS authors used for their reference IDIM fit (4th order,
//! 100 Hz, forward–backward, central differences), so the parameters we fit on EMPS are
//! comparable with theirs; it has no phase lag, so velocity and acceleration line up with the
//! measured input sample by sample (a lagging differentiator would itself look like a `delay`
//! effect in the residual); and its cut-off is one number a user can reason about (keep it
//! above the motion bandwidth and below where encoder quantisation noise dominates). The
//! default cut-off is a tenth of the sample rate, at most 100 Hz. Because a forward–backward filter rings at
//! the ends, [`EDGE_CUTOFF_PERIODS`] cut-off periods are dropped from each end.
//!
//! Five points rather than three: the three-point second difference reads an acceleration at
//! a tenth of the sample rate (the default band's edge) 3.3 % low, (ω·dt)²/12, and a joint's
//! inertia torque then leaves a residual ∝ the acceleration's second derivative, which a
//! transmission mode fits (rigid joints chirped to 25 Hz at 250 Hz were named compliance). The
//! five-point error is (ω·dt)⁴/90, 0.2 % there.

/// Samples dropped at each end, in periods of the cut-off frequency.
pub const EDGE_CUTOFF_PERIODS: f64 = 5.0;

/// Zero-phase 4th-order Butterworth low-pass of `x` (sample rate `fs`, cut-off `fc`, Hz); it
/// lives in `sim_plant::effects::signal` so that fingerprints can apply the same filter.
pub use sim_plant::effects::signal::filtfilt;

/// RMS gain of the zero-phase filter for white noise (√Σh² of its impulse response).
pub fn noise_gain(fc: f64, fs: f64) -> f64 {
    let n = ((40.0 * fs / fc) as usize).clamp(64, 1 << 16);
    let mut x = vec![0.0; n];
    x[n / 2] = 1.0;
    filtfilt(&x, fc, fs)
        .iter()
        .map(|h| h * h)
        .sum::<f64>()
        .sqrt()
}

/// RMS velocity of [`differentiate`] for unit white noise on the position (per sample).
pub fn velocity_noise_gain(fc: f64, dt: f64) -> f64 {
    derivative_noise_gains(fc, dt).0
}

/// RMS acceleration of [`differentiate`] for unit white noise on the position (per sample).
pub fn acceleration_noise_gain(fc: f64, dt: f64) -> f64 {
    derivative_noise_gains(fc, dt).1
}

/// (velocity, acceleration) RMS of [`differentiate`]'s impulse response.
fn derivative_noise_gains(fc: f64, dt: f64) -> (f64, f64) {
    let n = ((40.0 / (fc * dt)) as usize).clamp(64, 1 << 16);
    let mut x = vec![0.0; n];
    x[n / 2] = 1.0;
    let d = differentiate(&x, dt, fc);
    let rms = |h: &[f64]| h.iter().map(|h| h * h).sum::<f64>().sqrt();
    (rms(&d.velocity), rms(&d.acceleration))
}

/// Peak |velocity| of [`differentiate`] for a unit step of the position: what one encoder
/// count flickering on a joint at rest shows as speed.
pub fn step_velocity_peak(fc: f64, dt: f64) -> f64 {
    let n = ((40.0 / (fc * dt)) as usize).clamp(64, 1 << 16);
    let x: Vec<f64> = (0..n).map(|i| if i < n / 2 { 0.0 } else { 1.0 }).collect();
    differentiate(&x, dt, fc)
        .velocity
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Smoothed position, velocity and acceleration.
#[derive(Debug, Clone)]
pub struct Derivatives {
    /// Filtered position.
    pub position: Vec<f64>,
    /// Velocity (five-point central difference of the filtered position).
    pub velocity: Vec<f64>,
    /// Acceleration (five-point second central difference of the filtered position).
    pub acceleration: Vec<f64>,
}

/// Differentiate a uniformly sampled position (period `dt`) with cut-off `fc` Hz.
pub fn differentiate(x: &[f64], dt: f64, fc: f64) -> Derivatives {
    let fs = 1.0 / dt;
    let p = filtfilt(x, fc, fs);
    let n = p.len();
    let mut v = vec![0.0; n];
    let mut a = vec![0.0; n];
    for i in 1..n.saturating_sub(1) {
        // Three points next to the ends (the edges are dropped anyway), five inside.
        let (vi, ai) = match (p.get(i.wrapping_sub(2)), p.get(i + 2)) {
            (Some(&m2), Some(&p2)) if i >= 2 => (
                (m2 - 8.0 * p[i - 1] + 8.0 * p[i + 1] - p2) / (12.0 * dt),
                (-m2 + 16.0 * p[i - 1] - 30.0 * p[i] + 16.0 * p[i + 1] - p2) / (12.0 * dt * dt),
            ),
            _ => (
                (p[i + 1] - p[i - 1]) / (2.0 * dt),
                (p[i + 1] - 2.0 * p[i] + p[i - 1]) / (dt * dt),
            ),
        };
        v[i] = vi;
        a[i] = ai;
    }
    if n >= 2 {
        v[0] = v[1];
        v[n - 1] = v[n - 2];
        a[0] = a[1];
        a[n - 1] = a[n - 2];
    }
    Derivatives {
        position: p,
        velocity: v,
        acceleration: a,
    }
}

/// Highest default cut-off (Hz). The encoder's noise in the acceleration grows as f_c^2.5
/// while a joint's friction, load and transmission mode sit below it; above it, a fast
/// record's quantisation error (under a count of motion per sample, correlated with the
/// motion) would pass as a structured residual. It is also the EMPS authors' band.
pub const MAX_DEFAULT_CUTOFF_HZ: f64 = 100.0;

/// Default cut-off: a tenth of the sample rate, at most [`MAX_DEFAULT_CUTOFF_HZ`].
pub fn default_cutoff(dt: f64) -> f64 {
    (0.1 / dt).min(MAX_DEFAULT_CUTOFF_HZ)
}

/// Samples to drop at each end for a cut-off `fc` at period `dt`.
pub fn edge_samples(dt: f64, fc: f64) -> usize {
    (EDGE_CUTOFF_PERIODS / (fc * dt)).ceil() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_cutoff_is_a_tenth_of_the_rate_up_to_100_hz() {
        assert_eq!(default_cutoff(1.0 / 250.0), 25.0);
        assert_eq!(default_cutoff(1e-3), 100.0);
        assert_eq!(default_cutoff(1.0 / 4000.0), 100.0);
    }

    #[test]
    fn differentiates_a_sine_without_lag() {
        let dt = 1e-3;
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let x: Vec<f64> = (0..4000).map(|i| (w * i as f64 * dt).sin()).collect();
        let d = differentiate(&x, dt, 50.0);
        let e = edge_samples(dt, 50.0);
        for i in e..x.len() - e {
            let t = i as f64 * dt;
            assert!(
                (d.velocity[i] - w * (w * t).cos()).abs() < 1e-3 * w,
                "v at {i}"
            );
            assert!(
                (d.acceleration[i] + w * w * (w * t).sin()).abs() < 1e-2 * w * w,
                "a at {i}"
            );
        }
    }

    /// One count of a position step shows as a velocity pulse of about 2.2·fc counts/s at a
    /// 40 Hz cut-off (the rest band of static friction), several times 3σ of white
    /// quantisation noise.
    #[test]
    fn one_step_velocity_peak_exceeds_white_noise_band() {
        let (fc, dt) = (40.0, 1e-3);
        let peak = step_velocity_peak(fc, dt);
        let white = 3.0 / 12f64.sqrt() * velocity_noise_gain(fc, dt);
        assert!(peak > 2.0 * white, "peak {peak}, 3σ white {white}");
        assert!(peak > 1.5 * fc && peak < 4.0 * fc, "peak {peak}");
    }

    #[test]
    fn filter_removes_high_frequency() {
        let dt = 1e-3;
        let x: Vec<f64> = (0..4000)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let y = filtfilt(&x, 50.0, 1.0 / dt);
        assert!(y[100..3900].iter().all(|v| v.abs() < 1e-3));
    }
}
