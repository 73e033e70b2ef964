//! Distributions and tests: χ², F, Ljung–Box, Holm, autocorrelation, batch-means covariance.
//!
//! Why batch means: an equation-error residual is *not* white — the smoothing differentiator,
//! closed-loop feedback and any unmodelled slow dynamics make it autocorrelated over tens to
//! thousands of samples. An ordinary LS covariance then understates parameter variance by that
//! correlation length and a score test would fire on almost every null trial. Summing the
//! score contributions `x_t·e_t` over `m` contiguous blocks and using the spread of the block
//! sums is a consistent long-run-variance estimate as long as the blocks are longer than the
//! correlation; with a fixed number of blocks the Wald statistic is referred to
//! `F(q, m − q)` (Hotelling's T² small-sample correction), which keeps the false-alarm rate
//! honest when only a few dozen blocks are available.

/// ln Γ(x), Lanczos (g = 7, n = 9), |rel. error| < 1e-14 for x > 0.
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if x < a + 1.0 {
        // series for P
        let mut sum = 1.0 / a;
        let mut del = sum;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        let p = sum * (-x + a * x.ln() - ln_gamma(a)).exp();
        (1.0 - p).max(0.0)
    } else {
        // continued fraction for Q (Lentz)
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

/// Survival function of χ²(k).
pub fn chi2_sf(x: f64, k: f64) -> f64 {
    gamma_q(0.5 * k, 0.5 * x)
}

fn betacf(a: f64, b: f64, x: f64) -> f64 {
    let tiny = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < tiny {
        d = tiny;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..10_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < tiny {
            d = tiny;
        }
        c = 1.0 + aa / c;
        if c.abs() < tiny {
            c = tiny;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// Regularised incomplete beta I_x(a, b).
pub fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let bt = (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        bt * betacf(a, b, x) / a
    } else {
        1.0 - bt * betacf(b, a, 1.0 - x) / b
    }
}

/// Survival function of F(d1, d2).
pub fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    if f <= 0.0 {
        return 1.0;
    }
    beta_inc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * f))
}

/// Holm step-down adjustment: adjusted p-values in the input order (family-wise error control).
pub fn holm(p: &[f64]) -> Vec<f64> {
    let m = p.len();
    let mut idx: Vec<usize> = (0..m).collect();
    idx.sort_by(|&a, &b| p[a].total_cmp(&p[b]));
    let mut out = vec![0.0; m];
    let mut run = 0.0f64;
    for (rank, &i) in idx.iter().enumerate() {
        let adj = ((m - rank) as f64 * p[i]).min(1.0);
        run = run.max(adj);
        out[i] = run;
    }
    out
}

/// Sample autocorrelation at lags 0..=max_lag (mean removed).
pub fn autocorrelation(x: &[f64], max_lag: usize) -> Vec<f64> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let d: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let c0: f64 = d.iter().map(|v| v * v).sum();
    (0..=max_lag.min(n.saturating_sub(1)))
        .map(|k| {
            if c0 == 0.0 {
                return if k == 0 { 1.0 } else { 0.0 };
            }
            d[k..]
                .iter()
                .zip(&d[..n - k])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / c0
        })
        .collect()
}

/// Ljung–Box portmanteau test of whiteness over `h` lags: (Q, p-value under χ²(h)).
pub fn ljung_box(x: &[f64], h: usize) -> (f64, f64) {
    let n = x.len() as f64;
    let r = autocorrelation(x, h);
    let q = n
        * (n + 2.0)
        * (1..r.len())
            .map(|k| r[k] * r[k] / (n - k as f64))
            .sum::<f64>();
    (q, chi2_sf(q, h as f64))
}

/// Cross-correlation ρ_xy(k) = corr(x_t, y_{t−k}) for k in −max_lag..=max_lag.
pub fn cross_correlation(x: &[f64], y: &[f64], max_lag: usize) -> Vec<(i64, f64)> {
    let n = x.len().min(y.len());
    let mx = x[..n].iter().sum::<f64>() / n as f64;
    let my = y[..n].iter().sum::<f64>() / n as f64;
    let sx = x[..n].iter().map(|v| (v - mx).powi(2)).sum::<f64>().sqrt();
    let sy = y[..n].iter().map(|v| (v - my).powi(2)).sum::<f64>().sqrt();
    let ml = max_lag as i64;
    (-ml..=ml)
        .map(|k| {
            let mut s = 0.0;
            for t in 0..n as i64 {
                let u = t - k;
                if u >= 0 && u < n as i64 {
                    s += (x[t as usize] - mx) * (y[u as usize] - my);
                }
            }
            (k, if sx * sy > 0.0 { s / (sx * sy) } else { 0.0 })
        })
        .collect()
}

/// Deterministic test noise.
/// White-noise RMS in a signal (a residual, a recorded input): Var(Δ²e) = 6σ² for white e, while smooth (model-error)
/// content cancels in the second difference. Biased low if the noise itself is low-passed.
pub fn noise_floor(r: &[f64]) -> f64 {
    if r.len() < 3 {
        return 0.0;
    }
    let s: f64 = r
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).powi(2))
        .sum();
    (s / (6.0 * (r.len() - 2) as f64)).sqrt()
}

#[cfg(test)]
pub(crate) mod tests_support {
    /// Uniform on [0, 1) from a counter (SplitMix64): white, unlike a linear congruence of the
    /// counter itself, whose successive values step by a constant.
    pub fn unit_uniform(i: u64) -> f64 {
        let mut z = i.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distributions_match_tables() {
        assert!((chi2_sf(3.841_458_820_694_124, 1.0) - 0.05).abs() < 1e-9);
        assert!((chi2_sf(31.410_432_844_230_918, 20.0) - 0.05).abs() < 1e-9);
        // F(2, 30) 5 % critical value 3.3158
        assert!((f_sf(3.315_829_501_147_07, 2.0, 30.0) - 0.05).abs() < 1e-6);
        assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-10);
    }

    #[test]
    fn holm_is_monotone_and_capped() {
        let p = holm(&[0.01, 0.04, 0.03, 0.5]);
        assert_eq!(p, vec![0.04, 0.09, 0.09, 0.5]);
    }

    #[test]
    fn ljung_box_flags_an_ar1() {
        let mut s = 12345u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let white: Vec<f64> = (0..5000).map(|_| rnd()).collect();
        let mut ar = vec![0.0; 5000];
        for i in 1..5000 {
            ar[i] = 0.5 * ar[i - 1] + white[i];
        }
        assert!(ljung_box(&white, 20).1 > 0.001);
        assert!(ljung_box(&ar, 20).1 < 1e-10);
    }
}
