//! What a recorded command did *between* its samples (MATLAB `iddata`'s `InterSample`), and
//! the equivalent input at the instants the position was sampled.
//!
//! A digital drive reads its encoder at t_k, computes u_k and holds it over [t_k, t_k + T)
//! (zero-order hold). Band-limited, that held torque at t_k is u's value half a sample earlier
//! — a half-sample lag that the equation error J·a(t_k) = u(t_k) + … would otherwise leave in
//! its residual, where it reads as a transport delay of T/2 (at 1 kHz, a `delay` verdict on
//! every record a drive logs). With the convention known, the lag is no missing effect: the
//! input is mapped to what the plant received around each position sample, and a `delay`
//! then means a delay beyond the hold.
//!
//! The mapping is exact for the band below Nyquist: the torque the plant integrates is the
//! hold kernel `w` of each sample, and its band-limited value at the position's instant is
//! `Σ_m u_m·G(k − m)`, `G(j) = ∫ w(y)·sinc(j + δ − y) dy` (sample units; δ the position's
//! offset into the row's hold). `G` is tabulated once by quadrature and truncated with a
//! taper; its DC gain is exactly 1.

use serde::{Deserialize, Serialize};

/// How the input behaved between samples, relative to when the position was sampled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Intersample {
    /// Zero-order hold (the default: how a drive logs). Row k holds q(t_k), sampled at the
    /// instant the controller read it, and the command u_k computed from it, then held over
    /// [t_k, t_k + T). Response e^(−iπfT)·sinc(fT): a half-sample lag.
    #[default]
    Zoh,
    /// First-order hold: the input moves linearly between its samples, which are taken at the
    /// position's instants (a measured torque or current). Response sinc²(fT), no lag.
    Foh,
    /// Mid-sample: u_k is held over [t_k, t_k + T) and the position logged at t_k + T/2, the
    /// middle of that hold (a log that pairs each command with the motion it produced).
    /// Response sinc(fT), no lag.
    Mid,
    /// Band-limited: the samples are the input's values at the position's instants (a
    /// simulation's samples, or an anti-aliased measurement). Identity.
    Bl,
}

/// Taps either side of the kernel's centre. The kernel's tail falls as 1/j and alternates in
/// sign, so truncating it disturbs the response near Nyquist only; the band a residual is
/// judged in (the differentiator's, a tenth of the sample rate by default) is accurate to
/// well under 0.1 %.
const HALF_TAPS: i32 = 24;

impl Intersample {
    /// Every convention, in the order the CLI lists them.
    pub const ALL: [Intersample; 4] = [
        Intersample::Zoh,
        Intersample::Foh,
        Intersample::Mid,
        Intersample::Bl,
    ];

    /// Lowercase name (CLI, JSON, model files).
    pub fn name(self) -> &'static str {
        match self {
            Intersample::Zoh => "zoh",
            Intersample::Foh => "foh",
            Intersample::Mid => "mid",
            Intersample::Bl => "bl",
        }
    }

    /// Inverse of [`Intersample::name`].
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name() == s)
    }

    /// One line on what the convention means (help texts).
    pub fn describe(self) -> &'static str {
        match self {
            Intersample::Zoh => {
                "zero-order hold: position sampled when the command was computed, command held \
                 over the next period (a drive's log)"
            }
            Intersample::Foh => "first-order hold: the input moves linearly between samples",
            Intersample::Mid => {
                "command held over the period, position logged at the middle of that hold"
            }
            Intersample::Bl => "band-limited: samples are the input's values at those instants",
        }
    }

    /// [`Intersample::kernel`] (or the [`Intersample::short_kernel`]), computed once per
    /// behaviour: a diagnosis maps a column through it for every shape it tries.
    fn kernel_once(self, short: bool) -> &'static (i32, Vec<f64>) {
        static KERNELS: [std::sync::OnceLock<(i32, Vec<f64>)>; 8] =
            [const { std::sync::OnceLock::new() }; 8];
        let i = 2 * self as usize + usize::from(short);
        KERNELS[i].get_or_init(|| {
            if short {
                self.short_kernel()
            } else {
                self.kernel()
            }
        })
    }

    /// The kernel `G(j)` for `j` in `first..first + len`, as (first, taps).
    fn kernel(self) -> (i32, Vec<f64>) {
        // Hold density w(y) on its support [lo, hi] (sample units, relative to the row's hold
        // start) and the position's offset δ into the row.
        let (lo, hi, delta, tri) = match self {
            Intersample::Bl => return (0, vec![1.0]),
            Intersample::Zoh => (0.0, 1.0, 0.0, false),
            Intersample::Mid => (0.0, 1.0, 0.5, false),
            Intersample::Foh => (-1.0, 1.0, 0.0, true),
        };
        // The zoh kernel is centred at j = ½: one more tap on the right keeps it symmetric.
        let (first, last) = match self {
            Intersample::Zoh => (-HALF_TAPS + 1, HALF_TAPS),
            _ => (-HALF_TAPS, HALF_TAPS),
        };
        let centre = 0.5 * (first + last) as f64;
        let half = 0.5 * (last - first) as f64 + 1.0;
        let mut taps: Vec<f64> = (first..=last)
            .map(|j| {
                let g = simpson(lo, hi, 256, |y| {
                    let w = if tri { 1.0 - y.abs() } else { 1.0 };
                    w * sinc(j as f64 + delta - y)
                });
                // Hann taper over the kernel's span.
                let x = (j as f64 - centre) / half;
                g * 0.5 * (1.0 + (std::f64::consts::PI * x).cos())
            })
            .collect();
        let sum: f64 = taps.iter().sum();
        for t in &mut taps {
            *t /= sum;
        }
        (first, taps)
    }

    /// The same response for a signal already band-limited to [`SHORT_BAND`] cycles/sample:
    /// a few symmetric taps fitted by least squares to the kernel's amplitude (sinc or sinc²)
    /// on that band, at its lag (½ sample for zoh, none otherwise).
    fn short_kernel(self) -> (i32, Vec<f64>) {
        let pairs = SHORT_PAIRS as i32;
        // Offsets of the symmetric tap pairs from the kernel's centre, and the first tap.
        let (offsets, first): (Vec<f64>, i32) = match self {
            Intersample::Bl => return (0, vec![1.0]),
            Intersample::Zoh => ((1..=pairs).map(|p| p as f64 - 0.5).collect(), 1 - pairs),
            _ => ((0..=pairs).map(f64::from).collect(), -pairs),
        };
        let target = |f: f64| match self {
            Intersample::Foh => sinc(f).powi(2),
            _ => sinc(f),
        };
        let rows = 200;
        let basis = |f: f64, d: f64| {
            let w = if d == 0.0 { 1.0 } else { 2.0 };
            w * (std::f64::consts::TAU * f * d).cos()
        };
        let freqs = (0..rows).map(|r| SHORT_BAND * r as f64 / (rows - 1) as f64);
        let a = nalgebra::DMatrix::from_fn(rows, offsets.len(), |r, c| {
            basis(SHORT_BAND * r as f64 / (rows - 1) as f64, offsets[c])
        });
        let b = nalgebra::DVector::from_iterator(rows, freqs.map(target));
        let Ok(c) = a.svd(true, true).solve(&b, 1e-12) else {
            return self.kernel();
        };
        let centre = match self {
            Intersample::Zoh => 0.5,
            _ => 0.0,
        };
        let taps = (first..first + (2 * pairs + if centre == 0.0 { 1 } else { 0 }))
            .map(|j| {
                let d = (j as f64 - centre).abs();
                offsets
                    .iter()
                    .position(|&o| (o - d).abs() < 1e-9)
                    .map_or(0.0, |i| c[i])
            })
            .collect();
        (first, taps)
    }

    /// The equivalent input at the position's sample instants: `y_k = Σ_j G(j)·u_{k−j}`, the
    /// record's first and last samples held beyond its ends.
    pub fn apply(self, u: &[f64]) -> Vec<f64> {
        if self == Intersample::Bl || u.is_empty() {
            return u.to_vec();
        }
        let (first, taps) = self.kernel_once(false);
        convolve(*first, taps, u)
    }

    /// [`Intersample::apply`] followed by the zero-phase low-pass at `fc` (Hz; 0 = none) of a
    /// record sampled at `fs`: the input as the equation error sees it. When the low-pass
    /// leaves nothing above a quarter of the sample rate (a cut-off up to a tenth of it, as
    /// by default), the two commute and the short kernel does the mapping after the filter,
    /// at a sixth of the cost of the full one.
    pub fn band_limited(self, u: &[f64], fc: f64, fs: f64) -> Vec<f64> {
        if !(fc > 0.0 && fs > 0.0) {
            return self.apply(u);
        }
        if fc > 0.1 * fs {
            return super::signal::filtfilt(&self.apply(u), fc, fs);
        }
        let y = super::signal::filtfilt(u, fc, fs);
        if self == Intersample::Bl || y.is_empty() {
            return y;
        }
        let (first, taps) = self.kernel_once(true);
        convolve(*first, taps, &y)
    }
}

/// Band (cycles/sample) the short kernel is fitted on: a zero-phase 4th-order Butterworth at a
/// tenth of the sample rate passes 2·10⁻³ of the amplitude at 2.5 times its cut-off. Within
/// it the short kernel's response is the full one's to 10⁻⁵.
const SHORT_BAND: f64 = 0.25;

/// Symmetric tap pairs of the short kernel.
const SHORT_PAIRS: usize = 6;

/// `y_k = Σ_i taps[i]·u[k − first − i]`, the ends held.
fn convolve(first: i32, taps: &[f64], u: &[f64]) -> Vec<f64> {
    let n = u.len() as i64;
    let t = taps.len() as i64;
    let first = i64::from(first);
    let held = |k: i64| -> f64 {
        taps.iter()
            .enumerate()
            .map(|(i, g)| {
                let m = (k - (first + i as i64)).clamp(0, n - 1);
                g * u[m as usize]
            })
            .sum()
    };
    // Between the ends every tap reads inside the record: the same products summed in the
    // same order, without the clamp.
    let (lo, hi) = ((first + t.max(1) - 1).max(0), (n + first).min(n));
    (0..n)
        .map(|k| {
            if k < lo || k >= hi {
                return held(k);
            }
            let last = (k - first) as usize;
            let window = &u[last + 1 - taps.len()..=last];
            taps.iter()
                .zip(window.iter().rev())
                .map(|(g, x)| g * x)
                .sum()
        })
        .collect()
}

impl std::fmt::Display for Intersample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Intersample {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s).ok_or_else(|| {
            format!(
                "unknown intersample behaviour `{s}` (expected one of: {})",
                Self::ALL.map(|i| i.name()).join(", ")
            )
        })
    }
}

fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-12 {
        1.0
    } else {
        let px = std::f64::consts::PI * x;
        px.sin() / px
    }
}

/// Composite Simpson's rule over [a, b] with `n` (even) intervals.
fn simpson(a: f64, b: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let h = (b - a) / n as f64;
    let inner: f64 = (1..n)
        .map(|i| f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 })
        .sum();
    (f(a) + f(b) + inner) * h / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `convolve` is the held-end sum of every tap's product, in tap order, to the bit: for
    /// kernels reaching past either end, records shorter than the kernel, and none.
    #[test]
    fn convolve_is_the_held_sum_to_the_bit() {
        let held = |first: i32, taps: &[f64], u: &[f64]| -> Vec<f64> {
            let n = u.len() as i64;
            (0..n)
                .map(|k| {
                    let mut terms = Vec::new();
                    for (i, g) in taps.iter().enumerate() {
                        let m = (k - first as i64 - i as i64).clamp(0, n - 1);
                        terms.push(g * u[m as usize]);
                    }
                    terms.into_iter().sum()
                })
                .collect()
        };
        let taps: Vec<f64> = (0..13)
            .map(|i| 0.1 + (i as f64 * 0.7).sin() / 3.0)
            .collect();
        for n in [0usize, 1, 5, 12, 13, 14, 40, 1000] {
            let u: Vec<f64> = (0..n)
                .map(|k| (k as f64 * 0.37).cos() * 1e3 + 0.1)
                .collect();
            for first in [-20, -7, -6, 0, 1, 6, 20] {
                for len in [1usize, 2, 13] {
                    let t = &taps[..len];
                    let (a, b) = (convolve(first, t, &u), held(first, t, &u));
                    assert_eq!(a.len(), b.len());
                    assert!(
                        a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()),
                        "n {n}, first {first}, taps {len}"
                    );
                }
            }
        }
    }

    /// Complex response of the applied kernel at `f` cycles/sample, measured on a long
    /// sinusoid (away from the ends).
    fn response(is: Intersample, f: f64) -> (f64, f64) {
        let n = 4000;
        let w = std::f64::consts::TAU * f;
        let c: Vec<f64> = (0..n).map(|k| (w * k as f64).cos()).collect();
        let y = is.apply(&c);
        // Project the middle on cos/sin: y = A·cos(wk − φ).
        let (mut a, mut b) = (0.0, 0.0);
        let r = 500..3500;
        for k in r.clone() {
            a += y[k] * (w * k as f64).cos();
            b += y[k] * (w * k as f64).sin();
        }
        let m = r.len() as f64 / 2.0;
        let (a, b) = (a / m, b / m);
        (a.hypot(b), b.atan2(a))
    }

    /// zoh lags half a sample with a sinc droop; mid and foh do not lag, with sinc and sinc²
    /// droops; bl is the identity — each to 0.1 % in gain and 0.002 samples in lag up to a
    /// fifth of the sample rate.
    #[test]
    fn responses_match_the_hold_kernels() {
        let sinc_ = |f: f64| (std::f64::consts::PI * f).sin() / (std::f64::consts::PI * f);
        for f in [0.01, 0.05, 0.1, 0.2] {
            let w = std::f64::consts::TAU * f;
            for (is, gain, lag) in [
                (Intersample::Zoh, sinc_(f), 0.5),
                (Intersample::Mid, sinc_(f), 0.0),
                (Intersample::Foh, sinc_(f).powi(2), 0.0),
                (Intersample::Bl, 1.0, 0.0),
            ] {
                let (g, phase) = response(is, f);
                assert!(
                    (g / gain - 1.0).abs() < 1e-3,
                    "{is} at {f}: gain {g} vs {gain}"
                );
                assert!(
                    (phase / w - lag).abs() < 2e-3,
                    "{is} at {f}: lag {} vs {lag}",
                    phase / w
                );
            }
        }
    }

    /// On a signal low-passed at a tenth of the sample rate, the short kernel after the filter
    /// gives what the full kernel before it gives, to 10⁻⁴ of the signal.
    #[test]
    fn short_kernel_after_the_filter_matches_the_full_one() {
        let n = 3000;
        let u: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (7.0 * t).sin() + 0.3 * (90.0 * t).sin() + if k % 97 < 40 { 0.2 } else { -0.1 }
            })
            .collect();
        for is in Intersample::ALL {
            let full = crate::effects::signal::filtfilt(&is.apply(&u), 100.0, 1000.0);
            let short = is.band_limited(&u, 100.0, 1000.0);
            let worst = full[100..n - 100]
                .iter()
                .zip(&short[100..n - 100])
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-4, "{is}: {worst}");
        }
    }

    #[test]
    fn names_round_trip_and_dc_passes() {
        for is in Intersample::ALL {
            assert_eq!(is.name().parse::<Intersample>(), Ok(is));
            let y = is.apply(&[2.0; 100]);
            assert!(y.iter().all(|v| (v - 2.0).abs() < 1e-12), "{is}");
        }
        assert!("hold".parse::<Intersample>().is_err());
        assert_eq!(Intersample::default(), Intersample::Zoh);
    }
}
