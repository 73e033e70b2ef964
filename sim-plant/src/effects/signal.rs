//! Signal helpers for fingerprints: smoothed sign, differentiation, moving averages, grids.

/// sign(v) with a linear zone |v| < eps (a deadbanded, continuous sign). Why: near v = 0 the
/// measured velocity is dominated by quantisation noise, and a hard sign() would turn that
/// noise into ±amplitude chatter in the regressor.
#[inline]
pub fn smooth_sign(v: f64, eps: f64) -> f64 {
    if eps > 0.0 {
        (v / eps).clamp(-1.0, 1.0)
    } else if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Central-difference derivative (one-sided at the ends); `x.len() < 2` gives zeros.
pub fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    if n < 2 || dt <= 0.0 {
        return vec![0.0; n];
    }
    (0..n)
        .map(|i| {
            if i == 0 {
                (x[1] - x[0]) / dt
            } else if i == n - 1 {
                (x[n - 1] - x[n - 2]) / dt
            } else {
                (x[i + 1] - x[i - 1]) / (2.0 * dt)
            }
        })
        .collect()
}

/// Centred moving average of odd length `2*(len/2)+1`, shrinking at the ends.
pub fn moving_average(x: &[f64], len: usize) -> Vec<f64> {
    let n = x.len();
    let h = len / 2;
    if h == 0 || n == 0 {
        return x.to_vec();
    }
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(0.0);
    for v in x {
        prefix.push(prefix.last().unwrap() + v);
    }
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(h);
            let hi = (i + h + 1).min(n);
            (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// `count` log-spaced values from `lo` to `hi` inclusive (`lo`, `hi` > 0).
pub fn log_space(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    if count <= 1 || hi <= lo {
        return vec![lo];
    }
    let (a, b) = (lo.ln(), hi.ln());
    (0..count)
        .map(|i| (a + (b - a) * i as f64 / (count - 1) as f64).exp())
        .collect()
}

/// A positive scale, falling back to `fallback` when `x` is zero or not finite.
pub fn positive_or(x: f64, fallback: f64) -> f64 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        fallback
    }
}

/// One second-order section (direct form II transposed).
#[derive(Debug, Clone, Copy)]
struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
}

impl Biquad {
    /// Butterworth-section low-pass (bilinear transform), cut-off `fc`, quality `q`.
    fn lowpass(fc: f64, fs: f64, q: f64) -> Self {
        let k = (std::f64::consts::PI * fc / fs).tan();
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Biquad {
            b0,
            b1: 2.0 * b0,
            b2: b0,
            a1: 2.0 * (k * k - 1.0) * norm,
            a2: (1.0 - k / q + k * k) * norm,
        }
    }

    /// `(n₂s² + n₁s + n₀)/(s² + 2ζω·s + ω²)` (bilinear transform prewarped at ω = 2π·`f0`;
    /// `num` = [n₂, n₁, n₀]; ζ at least 10⁻³). `f0` must be below the Nyquist frequency.
    fn mode(num: [f64; 3], f0: f64, zeta: f64, fs: f64) -> Self {
        let k = (std::f64::consts::PI * f0 / fs).tan();
        let c = std::f64::consts::TAU * f0 / k;
        let zeta = zeta.max(1e-3);
        let norm = 1.0 / (1.0 + 2.0 * zeta * k + k * k);
        let [n2, n1, n0] = num;
        let (p1, p0) = (n1 / c, n0 / (c * c));
        Biquad {
            b0: (n2 + p1 + p0) * norm,
            b1: 2.0 * (p0 - n2) * norm,
            b2: (n2 - p1 + p0) * norm,
            a1: 2.0 * (k * k - 1.0) * norm,
            a2: (1.0 - 2.0 * zeta * k + k * k) * norm,
        }
    }

    /// Filter in place, starting from the steady state of the first sample.
    fn run(&self, x: &mut [f64]) {
        let Some(&c) = x.first() else { return };
        let mut z = self.steady(c);
        for v in x.iter_mut() {
            *v = self.step(*v, &mut z);
        }
    }

    /// The state `(z1, z2)` at rest under a constant input `c`, whose output is
    /// `c·Σb/(1 + Σa)`.
    fn steady(&self, c: f64) -> (f64, f64) {
        let g = (self.b0 + self.b1 + self.b2) / (1.0 + self.a1 + self.a2);
        let y0 = g * c;
        let z2 = self.b2 * c - self.a2 * y0;
        (self.b1 * c - self.a1 * y0 + z2, z2)
    }

    /// One sample through the section.
    #[inline(always)]
    fn step(&self, xi: f64, z: &mut (f64, f64)) -> f64 {
        let y = self.b0 * xi + z.0;
        z.0 = self.b1 * xi - self.a1 * y + z.1;
        z.1 = self.b2 * xi - self.a2 * y;
        y
    }
}

/// Two sections in cascade over `x` in place, in the direction `forward` or backward, each
/// started from the steady state of its own first input: [`Biquad::run`] of one, then of the
/// other, to the bit. In one pass the second section's recursion overlaps the first's (each
/// alone is a chain of dependent multiply–adds), about halving the time.
fn run_cascade(first: &Biquad, second: &Biquad, x: &mut [f64], forward: bool) {
    let start = if forward { x.first() } else { x.last() };
    let Some(&c) = start else { return };
    let (mut z1, mut z2) = cascade_start(first, second, c);
    let mut each = |v: &mut f64| *v = second.step(first.step(*v, &mut z1), &mut z2);
    if forward {
        x.iter_mut().for_each(&mut each);
    } else {
        x.iter_mut().rev().for_each(&mut each);
    }
}

/// The two sections' states at rest for a cascade whose first input is `c`: the second starts
/// from the first's first output (taken without advancing the first's state).
fn cascade_start(first: &Biquad, second: &Biquad, c: f64) -> ((f64, f64), (f64, f64)) {
    let z1 = first.steady(c);
    let mut probe = z1;
    (z1, second.steady(first.step(c, &mut probe)))
}

/// [`run_cascade`] over `x` and `y` (of one length) in one loop, each to the bit as alone.
fn run_cascade_pair(first: &Biquad, second: &Biquad, x: &mut [f64], y: &mut [f64], forward: bool) {
    let start = |v: &[f64]| if forward { v.first() } else { v.last() }.copied();
    let (Some(cx), Some(cy)) = (start(x), start(y)) else {
        return;
    };
    let (mut x1, mut x2) = cascade_start(first, second, cx);
    let (mut y1, mut y2) = cascade_start(first, second, cy);
    let mut each = |(u, v): (&mut f64, &mut f64)| {
        *u = second.step(first.step(*u, &mut x1), &mut x2);
        *v = second.step(first.step(*v, &mut y1), &mut y2);
    };
    if forward {
        x.iter_mut().zip(y.iter_mut()).for_each(&mut each);
    } else {
        x.iter_mut()
            .rev()
            .zip(y.iter_mut().rev())
            .for_each(&mut each);
    }
}

/// Zero-phase 4th-order Butterworth low-pass of `x` (sample rate `fs`, cut-off `fc`, Hz):
/// forward–backward, odd-reflection padding. The forward–backward pass squares the magnitude
/// response (−6 dB at `fc`). `fc` ≤ 0 or ≥ `fs`/2 (or fewer than 3 samples): `x` unchanged.
///
/// This is the workbench's smoothing differentiator's filter: fingerprints built from the
/// recorded input apply it (`Trajectory::lowpass_hz`) so that they see the bandwidth the
/// residual saw.
pub fn filtfilt(x: &[f64], fc: f64, fs: f64) -> Vec<f64> {
    let n = x.len();
    let Some((secs, pad)) = lowpass_cascade(n, fc, fs) else {
        return x.to_vec();
    };
    let mut buf = padded(x, pad);
    let [a, b] = &secs;
    run_cascade(a, b, &mut buf, true);
    run_cascade(a, b, &mut buf, false);
    unpadded(buf, pad, n)
}

/// [`filtfilt`] of each of `xs`, to the bit, two at a time: each column's recursion is a
/// chain of dependent multiply–adds, and two independent chains in one loop fill the core's
/// pipeline that one leaves idle (a ripple's sine and cosine columns, a grid of them per
/// diagnosis).
pub fn filtfilt_each(xs: Vec<Vec<f64>>, fc: f64, fs: f64) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(xs.len());
    let mut it = xs.into_iter();
    while let Some(x) = it.next() {
        let Some(y) = it.next() else {
            out.push(filtfilt(&x, fc, fs));
            break;
        };
        let n = x.len();
        match lowpass_cascade(n, fc, fs) {
            Some((secs, pad)) if y.len() == n => {
                let (mut bx, mut by) = (padded(&x, pad), padded(&y, pad));
                let [a, b] = &secs;
                run_cascade_pair(a, b, &mut bx, &mut by, true);
                run_cascade_pair(a, b, &mut bx, &mut by, false);
                out.push(unpadded(bx, pad, n));
                out.push(unpadded(by, pad, n));
            }
            _ => {
                out.push(filtfilt(&x, fc, fs));
                out.push(filtfilt(&y, fc, fs));
            }
        }
    }
    out
}

/// [`filtfilt`]'s two Butterworth sections and its padding for `n` samples; `None` where it
/// leaves the signal as it is.
fn lowpass_cascade(n: usize, fc: f64, fs: f64) -> Option<([Biquad; 2], usize)> {
    if n < 3 || !(fc > 0.0 && fc < fs / 2.0) {
        return None;
    }
    let secs = [
        Biquad::lowpass(fc, fs, 0.541_196_100_146_197),
        Biquad::lowpass(fc, fs, 1.306_562_964_876_376_6),
    ];
    // Saturating: a cut-off far below the sample rate (a clock in µs read as s) asks for
    // more padding than a usize holds, and the record's length caps it anyway.
    let pad = ((3.0 * fs / fc).ceil() as usize)
        .saturating_add(12)
        .min(n - 1);
    Some((secs, pad))
}

/// `x` with `pad` samples (fewer than `x.len()`) added at each end by odd reflection about
/// the end points, which keeps value and slope continuous.
fn padded(x: &[f64], pad: usize) -> Vec<f64> {
    let n = x.len();
    let mut buf = Vec::with_capacity(n + 2 * pad);
    for i in (1..=pad).rev() {
        buf.push(2.0 * x[0] - x[i]);
    }
    buf.extend_from_slice(x);
    for i in 1..=pad {
        buf.push(2.0 * x[n - 1] - x[n - 1 - i]);
    }
    buf
}

/// The `n` samples of `buf` between its paddings.
fn unpadded(mut buf: Vec<f64>, pad: usize, n: usize) -> Vec<f64> {
    buf.drain(..pad);
    buf.truncate(n);
    buf
}

/// Causal second-order high-pass `s²/(s² + 2ζω·s + ω²)`, ω = 2π·`f0` (Hz), sample rate `fs`,
/// started at rest for the first sample's level (a constant input gives zeros).
pub fn highpass2(x: &[f64], f0: f64, zeta: f64, fs: f64) -> Vec<f64> {
    let mut y = x.to_vec();
    if f0 > 0.0 && f0 < fs / 2.0 {
        Biquad::mode([1.0, 0.0, 0.0], f0, zeta, fs).run(&mut y);
    }
    y
}

/// `(n₂s² + n₁s + n₀)/(s² + 2ζω·s + ω²)` applied to `x` (bilinear transform prewarped at
/// ω = 2π·`f0`; `num` = [n₂, n₁, n₀]), from the steady state of the first sample. `x` unchanged
/// when `f0` is not below the Nyquist frequency.
pub fn biquad2(x: &[f64], num: [f64; 3], f0: f64, zeta: f64, fs: f64) -> Vec<f64> {
    let mut y = x.to_vec();
    if f0 > 0.0 && f0 < fs / 2.0 {
        Biquad::mode(num, f0, zeta, fs).run(&mut y);
    }
    y
}

/// The two free responses (`n` samples) of [`biquad2`]'s denominator `s² + 2ζω·s + ω²`
/// (same discretisation): the output the filter adds, with no input, for each of its two
/// initial states. Any start of the filter — a record that begins mid-transient, or a filter
/// started on samples it should not trust — differs from another by a combination of these.
/// Empty when `f0` is not below the Nyquist frequency (the filter is the identity then).
pub fn free_response2(n: usize, f0: f64, zeta: f64, fs: f64) -> Vec<Vec<f64>> {
    if !(f0 > 0.0 && f0 < fs / 2.0) {
        return Vec::new();
    }
    let Biquad { a1, a2, .. } = Biquad::mode([0.0, 0.0, 1.0], f0, zeta, fs);
    [(1.0, 0.0), (0.0, 1.0)]
        .iter()
        .map(|&(mut y1, mut y2)| {
            (0..n)
                .map(|_| {
                    let y = -a1 * y1 - a2 * y2;
                    (y2, y1) = (y1, y);
                    y
                })
                .collect()
        })
        .collect()
}

/// Wavenumbers a [`band_power`] pass carries at once.
const BLOCK: usize = 4;

/// `(k, |Σ e·exp(i·k·(x − mid))|²)` for the `count` wavenumbers `k = lo + j·dk`, appended to
/// `power`. The phasors are advanced by a rotation per sample and wavenumber; `BLOCK`
/// wavenumbers share a pass over the samples, each rotated on from the last: every sum still
/// runs in sample order (the same figures as one pass per wavenumber), but their chains of
/// dependent additions overlap.
fn band_power(
    x: &[f64],
    e: &[f64],
    mid: f64,
    (lo, dk, count): (f64, f64, usize),
    power: &mut Vec<(f64, f64)>,
) {
    let rotor = |k: f64| -> (Vec<f64>, Vec<f64>) {
        x.iter()
            .map(|&v| {
                let (s, c) = (k * (v - mid)).sin_cos();
                (c, s)
            })
            .unzip()
    };
    let (mut re, mut im) = rotor(lo);
    let (wr, wi) = rotor(dk);
    let n = x.len().min(e.len());
    for j0 in (0..count).step_by(BLOCK) {
        let (mut sr, mut si) = ([0.0; BLOCK], [0.0; BLOCK]);
        for i in 0..n {
            let (mut r, mut m) = (re[i], im[i]);
            for q in 0..BLOCK {
                sr[q] += e[i] * r;
                si[q] += e[i] * m;
                (r, m) = (r * wr[i] - m * wi[i], r * wi[i] + m * wr[i]);
            }
            (re[i], im[i]) = (r, m);
        }
        for q in 0..BLOCK.min(count - j0) {
            power.push((lo + dk * (j0 + q) as f64, sr[q] * sr[q] + si[q] * si[q]));
        }
    }
}

/// Wavenumbers a [`periodogram_peaks`] looks at, at most: a record whose `x` spans 1000
/// periods of the shortest one would need about 4000 at its steps; beyond this they widen.
const PERIODOGRAM_MAX: usize = 2048;

/// The periods in `x` (between `pmin` and `pmax`) at which `e` correlates most with
/// `exp(i·2π·x/p)`, strongest first (at most `peaks`), and how many periods were looked at.
/// The screen of a torque periodic in a signal `x` (a ripple in the position, a quantiser's
/// sawtooth in the command): its correlation with a residual lives in a lobe 2π/span(x) wide
/// in wavenumber, far narrower than a log grid's step once x spans many periods.
///
/// The wavenumber is walked in octaves, each in steps of a quarter lobe or 1 % of it,
/// whichever is finer; all steps widen alike when that would exceed `PERIODOGRAM_MAX`.
/// |Σ e·exp(i·k·x)|² is the fingerprint's correlation with a residual that is already
/// orthogonal to the model; it is advanced by a rotation per sample, so it costs a complex
/// multiply per sample and wavenumber rather than a sine per sample and a regression.
pub fn periodogram_peaks(
    x: &[f64],
    e: &[f64],
    (pmin, pmax): (f64, f64),
    peaks: usize,
) -> (Vec<f64>, usize) {
    use std::f64::consts::TAU;
    let n = x.len().min(e.len());
    let (x, e) = (&x[..n], &e[..n]);
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let span = hi - lo;
    if !(span > 0.0 && pmin > 0.0 && pmax > pmin) {
        return (Vec::new(), 0);
    }
    let (k0, k1) = (TAU / pmax, TAU / pmin);
    let mut bands: Vec<(f64, f64)> = Vec::new();
    let mut k = k0;
    while k < k1 {
        let top = (2.0 * k).min(k1);
        bands.push((k, top));
        k = top;
    }
    let step = |lo: f64| (TAU / span / 4.0).min(0.01 * lo);
    let need: f64 = bands.iter().map(|&(lo, hi)| (hi - lo) / step(lo)).sum();
    let widen = (need / PERIODOGRAM_MAX as f64).max(1.0);
    // Values from the span's middle keep the rotations' phases small.
    let mid = 0.5 * (lo + hi);
    let mut power: Vec<(f64, f64)> = Vec::new();
    for &(lo, hi) in &bands {
        let dk = step(lo) * widen;
        let count = ((hi - lo) / dk).ceil().max(1.0) as usize;
        band_power(x, e, mid, (lo, dk, count), &mut power);
    }
    let count = power.len();
    // Local maxima, strongest first.
    let at = |j: usize| power.get(j).map_or(0.0, |&(_, p)| p);
    let mut found: Vec<usize> = (0..count)
        .filter(|&j| {
            let left = j.checked_sub(1).map_or(0.0, at);
            at(j) > 0.0 && at(j) >= left && at(j) >= at(j + 1)
        })
        .collect();
    found.sort_by(|&a, &b| at(b).total_cmp(&at(a)));
    let periods = found
        .into_iter()
        .take(peaks)
        .filter_map(|j| power.get(j))
        .map(|&(k, _)| TAU / k)
        .collect();
    (periods, count)
}

/// White noise for tests: a counter hash (SplitMix64) of `i`, uniform with unit RMS.
#[cfg(test)]
pub(crate) fn unit_noise(i: u64) -> f64 {
    let mut z = i.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    ((z >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block of wavenumbers per pass gives each wavenumber's power as one pass per
    /// wavenumber does, to the bit, for counts that are and are not multiples of the block.
    #[test]
    fn band_power_is_one_pass_per_wavenumber_to_the_bit() {
        let x: Vec<f64> = (0..997)
            .map(|k| 0.37 * k as f64 + (k as f64 * 0.01).sin())
            .collect();
        let e: Vec<f64> = (0..997)
            .map(|k| ((k * 31 % 17) as f64 - 8.0) * 0.1)
            .collect();
        let (mid, lo, dk) = (180.0, 0.8, 0.013);
        for count in [1, 4, 7, 9] {
            let mut power = Vec::new();
            band_power(&x, &e, mid, (lo, dk, count), &mut power);
            assert_eq!(power.len(), count);
            let (mut re, mut im): (Vec<f64>, Vec<f64>) = x
                .iter()
                .map(|&v| (lo * (v - mid)).sin_cos())
                .map(|(s, c)| (c, s))
                .unzip();
            let (wr, wi): (Vec<f64>, Vec<f64>) = x
                .iter()
                .map(|&v| (dk * (v - mid)).sin_cos())
                .map(|(s, c)| (c, s))
                .unzip();
            for (j, &(k, p)) in power.iter().enumerate() {
                let (mut sr, mut si) = (0.0, 0.0);
                for i in 0..x.len() {
                    sr += e[i] * re[i];
                    si += e[i] * im[i];
                    let r = re[i] * wr[i] - im[i] * wi[i];
                    im[i] = re[i] * wi[i] + im[i] * wr[i];
                    re[i] = r;
                }
                assert_eq!(k.to_bits(), (lo + dk * j as f64).to_bits());
                assert_eq!(
                    p.to_bits(),
                    (sr * sr + si * si).to_bits(),
                    "count {count}, {j}"
                );
            }
        }
    }

    /// [`filtfilt_each`] is [`filtfilt`] of each column, to the bit: paired columns, an odd
    /// one out, columns of unequal length (not paired), and columns too short to filter.
    #[test]
    fn filtfilt_each_is_filtfilt_of_each_to_the_bit() {
        let col = |n: usize, f: f64| -> Vec<f64> {
            (0..n)
                .map(|k| (f * k as f64).sin() + if k % 11 < 4 { 0.5 } else { -0.25 })
                .collect()
        };
        let sets = [
            vec![col(3000, 0.01), col(3000, 0.03), col(3000, 0.2)],
            vec![col(3000, 0.01), col(2999, 0.03)],
            vec![col(2, 0.1), col(2, 0.2)],
            vec![col(40, 0.1), col(40, 0.7), col(0, 0.1), col(0, 0.2)],
            vec![],
        ];
        for (fc, fs) in [(40.0, 1000.0), (0.0, 1000.0), (600.0, 1000.0), (5.0, 250.0)] {
            for set in &sets {
                let each = filtfilt_each(set.clone(), fc, fs);
                assert_eq!(each.len(), set.len());
                for (x, y) in set.iter().zip(&each) {
                    let alone = filtfilt(x, fc, fs);
                    assert_eq!(alone.len(), y.len());
                    assert!(alone.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()));
                }
            }
        }
    }

    /// The one-pass cascade is the two sections run one after the other, to the bit, both
    /// ways (the zero-phase filter's results must not depend on how it is scheduled).
    #[test]
    fn the_cascade_is_two_runs_to_the_bit() {
        let x: Vec<f64> = (0..3000)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (7.0 * t).sin() + 0.3 * (k % 7) as f64 + if k > 1500 { 2.0 } else { -1.0 }
            })
            .collect();
        let (a, b) = (
            Biquad::lowpass(40.0, 1000.0, 0.541_196_100_146_197),
            Biquad::lowpass(40.0, 1000.0, 1.306_562_964_876_376_6),
        );
        let mut by_runs = x.clone();
        a.run(&mut by_runs);
        b.run(&mut by_runs);
        let mut fused = x.clone();
        run_cascade(&a, &b, &mut fused, true);
        assert!(by_runs
            .iter()
            .zip(&fused)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
        by_runs.reverse();
        a.run(&mut by_runs);
        b.run(&mut by_runs);
        by_runs.reverse();
        run_cascade(&a, &b, &mut fused, false);
        assert!(by_runs
            .iter()
            .zip(&fused)
            .all(|(p, q)| p.to_bits() == q.to_bits()));
        let mut empty: Vec<f64> = Vec::new();
        run_cascade(&a, &b, &mut empty, false);
        assert!(empty.is_empty());
    }

    #[test]
    fn helpers_behave() {
        assert_eq!(smooth_sign(0.5, 1.0), 0.5);
        assert_eq!(smooth_sign(-3.0, 1.0), -1.0);
        assert_eq!(smooth_sign(-3.0, 0.0), -1.0);
        let x: Vec<f64> = (0..10).map(|i| (i * i) as f64).collect();
        let d = derivative(&x, 1.0);
        assert_eq!(d[5], 10.0);
        let m = moving_average(&[1.0, 2.0, 3.0, 4.0, 5.0], 3);
        assert_eq!(m, vec![1.5, 2.0, 3.0, 4.0, 4.5]);
        let g = log_space(1.0, 100.0, 3);
        assert!((g[1] - 10.0).abs() < 1e-12 && (g[2] - 100.0).abs() < 1e-9);
    }

    #[test]
    fn free_responses_span_any_restart_of_the_filter() {
        // A filter started later (at its input's level there) differs from one that ran
        // through by a combination of the two free responses.
        let fs = 1000.0;
        let x: Vec<f64> = (0..3000)
            .map(|i| (i as f64 * 0.013).sin() + 0.3 * (i as f64 * 0.21).cos())
            .collect();
        let (num, f0, zeta, m) = ([0.0, 0.3, 2.0], 7.0, 0.04, 500);
        let full = biquad2(&x, num, f0, zeta, fs);
        let late = biquad2(&x[m..], num, f0, zeta, fs);
        let d: Vec<f64> = full[m..].iter().zip(&late).map(|(a, b)| a - b).collect();
        let f = free_response2(d.len(), f0, zeta, fs);
        let c = crate::lstsq::solve(&f, &d).expect("two independent free responses");
        let (c1, c2) = (c[0], c[1]);
        let worst = d
            .iter()
            .enumerate()
            .map(|(k, v)| (v - c1 * f[0][k] - c2 * f[1][k]).abs())
            .fold(0.0, f64::max);
        let scale = d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(
            scale > 1e-3 && worst < 1e-9 * scale.max(1.0),
            "{worst} of {scale}"
        );
    }

    #[test]
    fn biquad2_with_a_pure_s2_numerator_is_the_highpass() {
        let x: Vec<f64> = (0..500).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        let a = biquad2(&x, [1.0, 0.0, 0.0], 30.0, 0.2, 1000.0);
        let b = highpass2(&x, 30.0, 0.2, 1000.0);
        assert!(a.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-9));
        // A constant numerator ω² is the unit-gain low-pass: DC passes.
        let w = std::f64::consts::TAU * 30.0;
        let dc = biquad2(&[2.0; 50], [0.0, 0.0, w * w], 30.0, 0.2, 1000.0);
        assert!((dc[49] - 2.0).abs() < 1e-9, "{}", dc[49]);
    }

    #[test]
    fn filters_pass_and_stop_what_they_should() {
        let fs = 1000.0;
        let tone = |f: f64| -> Vec<f64> {
            (0..4000)
                .map(|i| (std::f64::consts::TAU * f * i as f64 / fs).sin())
                .collect()
        };
        let rms = |x: &[f64]| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        // Low-pass: 2 Hz through, 200 Hz out, no lag.
        let lo = tone(2.0);
        let y = filtfilt(&lo, 40.0, fs);
        assert!(y[200..3800]
            .iter()
            .zip(&lo[200..3800])
            .all(|(a, b)| (a - b).abs() < 1e-3));
        assert!(rms(&filtfilt(&tone(200.0), 40.0, fs)[200..3800]) < 1e-3);
        // High-pass at 20 Hz: 2 Hz attenuated by ≈ (2/20)², 200 Hz through.
        let r = rms(&highpass2(&lo, 20.0, 0.05, fs)[2000..]) / rms(&lo[2000..]);
        assert!((r - 0.01).abs() < 0.002, "{r}");
        let hi = tone(200.0);
        let r = rms(&highpass2(&hi, 20.0, 0.05, fs)[2000..]) / rms(&hi[2000..]);
        assert!((r - 1.0).abs() < 0.02, "{r}");
        // A constant gives zeros.
        assert!(highpass2(&[3.0; 50], 20.0, 0.05, fs)
            .iter()
            .all(|v| v.abs() < 1e-12));
    }
}
