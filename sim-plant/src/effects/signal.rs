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

#[cfg(test)]
mod tests {
    use super::*;

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
}
