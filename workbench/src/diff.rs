//! The smoothing differentiator: zero-phase 4th-order Butterworth low-pass (forward–backward,
//! odd-reflection padding) followed by fourth-order central differences (five points).
//!
//! Why this one: it is what the EMPS authors used for their reference IDIM fit (4th order,
//! 100 Hz, forward–backward, central differences), so the parameters we fit on EMPS are
//! comparable with theirs; it has no phase lag, so velocity and acceleration line up with the
//! measured input sample by sample (a lagging differentiator would itself look like a `delay`
//! effect in the residual); and its cut-off is one number a user can reason about (keep it
//! above the motion bandwidth and below where encoder quantisation noise dominates). The
//! default cut-off follows the record's own encoder noise ([`default_cutoff`]), within a
//! tenth of the sample rate and 100 Hz. Because a forward–backward filter rings at the ends,
//! [`EDGE_CUTOFF_PERIODS`] cut-off periods are dropped from each end.
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
pub use sim_plant::effects::signal::{filtfilt, filtfilt_each};

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

/// The reference band: 40 Hz for a 2¹⁶-count/rev encoder logged at 1 kHz, the band advised
/// for it (its noise in the acceleration is a tenth of what it is at 100 Hz). A rotary
/// record's default band holds its own encoder's noise in the acceleration at this
/// reference's level.
pub const REFERENCE_CUTOFF_HZ: f64 = 40.0;

/// The reference encoder's noise (rad RMS): one count of 2¹⁶ per revolution, uniform.
pub const REFERENCE_ENCODER_NOISE_RAD: f64 =
    std::f64::consts::TAU / 65_536.0 / 3.464_101_615_137_754_6;

/// Lowest default cut-off, as a fraction of the sample rate: below it the differentiator's
/// edges (several periods of the cut-off) eat a short record.
pub const MIN_DEFAULT_CUTOFF_RATE: f64 = 0.005;

/// Default cut-off for a record at period `dt` whose position noise (encoder quantisation
/// and sensor noise, RMS, rad) is `encoder_noise_rad`: the band where that noise reaches the
/// acceleration at the level [`REFERENCE_ENCODER_NOISE_RAD`] does at [`REFERENCE_CUTOFF_HZ`]
/// and 1 kHz (found on this differentiator's own noise gain), within
/// [[`MIN_DEFAULT_CUTOFF_RATE`]·f_s, min(f_s/10, [`MAX_DEFAULT_CUTOFF_HZ`])]. The encoder's
/// noise in the acceleration grows as f_c^2.5 while the effects sit at the motion's
/// frequencies: a coarse encoder logged at 100 Hz of band buries them. `None` (a linear axis,
/// whose counts have no revolution to scale by, or no noise measured) gives the upper limit.
pub fn default_cutoff(dt: f64, encoder_noise_rad: Option<f64>) -> f64 {
    let hi = (0.1 / dt).min(MAX_DEFAULT_CUTOFF_HZ);
    let lo = (MIN_DEFAULT_CUTOFF_RATE / dt).min(hi);
    let Some(sigma) = encoder_noise_rad.filter(|s| s.is_finite() && *s > 0.0) else {
        return hi;
    };
    let target = REFERENCE_ENCODER_NOISE_RAD * acceleration_noise_gain(REFERENCE_CUTOFF_HZ, 1e-3);
    let noise = |fc: f64| sigma * acceleration_noise_gain(fc, dt);
    if noise(hi) <= target {
        return hi;
    }
    if noise(lo) >= target {
        return lo;
    }
    // The gain rises with the cut-off: bisect on its logarithm to a tenth of a percent.
    let (mut a, mut b) = (lo.ln(), hi.ln());
    for _ in 0..24 {
        let m = 0.5 * (a + b);
        if noise(m.exp()) > target {
            b = m;
        } else {
            a = m;
        }
    }
    a.exp()
}

/// Samples to drop at each end for a cut-off `fc` at period `dt`.
pub fn edge_samples(dt: f64, fc: f64) -> usize {
    (EDGE_CUTOFF_PERIODS / (fc * dt)).ceil() as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_cutoff_without_a_rotary_encoder_is_a_tenth_of_the_rate_up_to_100_hz() {
        assert_eq!(default_cutoff(1.0 / 250.0, None), 25.0);
        assert_eq!(default_cutoff(1e-3, None), 100.0);
        assert_eq!(default_cutoff(1.0 / 4000.0, None), 100.0);
    }

    #[test]
    fn default_cutoff_follows_the_encoder_noise() {
        let count = |bits: i32| std::f64::consts::TAU / 2f64.powi(bits) / 12f64.sqrt();
        // The reference encoder at the reference rate: the reference band.
        let f16 = default_cutoff(1e-3, Some(count(16)));
        assert!((f16 - 40.0).abs() < 0.5, "{f16}");
        // Noise in the acceleration ∝ σ·f_c^2.5: four times the step, 4^-0.4 the band.
        let f14 = default_cutoff(1e-3, Some(count(14)));
        assert!((f14 / f16 - 0.25f64.powf(0.4)).abs() < 0.05, "{f14}");
        // A fine encoder reaches the upper limit, a very coarse one the lower.
        assert_eq!(default_cutoff(1e-3, Some(count(22))), 100.0);
        assert_eq!(default_cutoff(1e-3, Some(count(4))), 5.0);
        // More samples per second average more of the noise: a faster log's band is higher.
        assert!(default_cutoff(2e-4, Some(count(16))) > f16 * 1.2);
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
