//! How good is a model, and *where* does its error live.
//!
//! Besides the global numbers (fit %, RMS, max, noise floor, whiteness) the residual is split
//! by time window, velocity band, distance to a velocity reversal, position phase (folded on a
//! period) and load level, because the thesis's fingerprints (§7) are localised: Coulomb and
//! Stribeck errors live at reversals and low speed, ripple in position phase, load-dependent
//! friction at high load, drift in late time windows.

use serde::Serialize;

use super::residual::{Mode, Residual};
use super::stats;
pub use super::stats::noise_floor;
use super::units::eng;

/// Fit % and RMS of a model on one record.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Score {
    /// Fit %.
    pub fit_percent: f64,
    /// RMS residual.
    pub rms: f64,
    /// ‖e‖/‖u‖ %.
    pub relative_error_percent: f64,
    /// The equation error's noise floor on this record at this model's inertia
    /// ([`crate::residual::Prepared::equation_floor`]): an RMS near it leaves nothing for another effect to
    /// explain.
    pub noise_floor_rms: f64,
}

impl Score {
    /// The score of a residual `r` against the floor `noise_floor_rms` — the one formula for
    /// what `compare`, `diagnose`'s baseline, `fit` and `--auto` print for a model.
    pub fn of(r: &Residual, noise_floor_rms: f64) -> Score {
        let ss: f64 = r.residual.iter().map(|v| v * v).sum();
        let uu: f64 = r.measured.iter().map(|v| v * v).sum();
        Score {
            fit_percent: fit_percent(&r.measured, &r.predicted),
            rms: r.rms(),
            relative_error_percent: 100.0 * (ss / uu.max(1e-300)).sqrt(),
            noise_floor_rms,
        }
    }

    /// RMS over the noise floor (1 = nothing left but noise).
    pub fn floor_ratio(&self) -> f64 {
        self.rms / self.noise_floor_rms
    }
}

/// RMS and mean of the residual in one bin.
#[derive(Debug, Clone, Serialize)]
pub struct Bin {
    /// What the bin holds.
    pub label: String,
    /// Samples.
    pub count: usize,
    /// RMS residual.
    pub rms: f64,
    /// Mean residual.
    pub mean: f64,
}

/// All the numbers `compare` reports.
#[derive(Debug, Clone, Serialize)]
pub struct Metrics {
    /// Which residual.
    pub residual_mode: String,
    /// 100·(1 − ‖y − ŷ‖/‖y − ȳ‖).
    pub fit_percent: f64,
    /// RMS residual.
    pub rms: f64,
    /// Largest |residual|.
    pub max_abs: f64,
    /// Time of the largest |residual|.
    pub max_at_s: f64,
    /// Estimated white-noise RMS in the residual (second-difference estimator).
    pub noise_floor_rms: f64,
    /// Relative error ‖y − ŷ‖/‖y‖ (the EMPS papers' measure), percent.
    pub relative_error_percent: f64,
    /// Ljung–Box Q over 20 lags.
    pub ljung_box_q: f64,
    /// Its p-value (small = not white).
    pub ljung_box_p: f64,
    /// What the residual is cross-correlated with ([`driver`]: `input` for the output error,
    /// `velocity` for the equation error).
    pub xcorr_with: String,
    /// The largest corr(residual_t, x_{t−k}), k in ±[`MAX_LAG`] (signed).
    pub xcorr_max: f64,
    /// Lag of that maximum (samples; > 0: x leads the residual).
    pub xcorr_lag: i64,
    /// 99 % band of one lag's correlation if residual and x are independent ([`ccf_sigma`]).
    pub xcorr_band: f64,
    /// By time window (10 windows).
    pub by_time: Vec<Bin>,
    /// By |velocity| band (quintiles).
    pub by_velocity: Vec<Bin>,
    /// Near a velocity reversal vs elsewhere.
    pub by_reversal: Vec<Bin>,
    /// By position phase (folded on `phase_period`).
    pub by_position_phase: Vec<Bin>,
    /// Period used for folding.
    pub phase_period: f64,
    /// By |input| level (quartiles).
    pub by_load: Vec<Bin>,
}

/// Lags of the residual correlation charts (samples).
pub const MAX_LAG: usize = 50;

/// z for a two-sided 99 % band of a normal estimate (MATLAB's `resid` default).
pub const Z99: f64 = 2.575_829_303_548_901;

/// z of a two-sided 99 % test over all 2·[`MAX_LAG`] + 1 lags of a cross-correlation at once
/// (Bonferroni, 0.01 / 101 per lag): the finding's test, where one lag outside the per-lag
/// band of 151 would be chance four times in five.
pub const Z99_ALL_LAGS: f64 = 3.893_005_514_077_543;

/// The 99 % band of a sample autocorrelation of `n` samples of a white residual: ±z/√n.
pub fn band99(n: usize) -> f64 {
    Z99 / (n.max(1) as f64).sqrt()
}

/// The signal the residual is cross-correlated with: the input for the output error (as
/// MATLAB's `resid`); for the equation error the velocity, because there the residual is the
/// input minus its prediction, and correlates with the input by construction.
pub fn driver(res: &Residual) -> (&[f64], &'static str) {
    match res.mode {
        Mode::Equation => (&res.velocity, "velocity"),
        Mode::Output => (&res.input, "input"),
    }
}

/// The standard deviation of the sample cross-correlation of `e` and `x` if they are
/// independent, whatever their own autocorrelation: √(Σₖ r_e(k)·r_x(k) / N) over |k| ≤
/// [`MAX_LAG`] (MATLAB `resid`'s band; 1/√N when either is white).
pub fn ccf_sigma(e: &[f64], x: &[f64]) -> f64 {
    let n = e.len().min(x.len()).max(1) as f64;
    let re = stats::autocorrelation(e, MAX_LAG);
    let rx = stats::autocorrelation(x, MAX_LAG);
    let s: f64 = re
        .iter()
        .zip(&rx)
        .enumerate()
        .map(|(k, (a, b))| if k == 0 { a * b } else { 2.0 * a * b })
        .sum();
    (s.max(0.0) / n).sqrt()
}

fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Fit percentage 100·(1 − ‖y − ŷ‖/‖y − ȳ‖).
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let m = y.iter().sum::<f64>() / y.len() as f64;
    let num: f64 = y.iter().zip(yhat).map(|(a, b)| (a - b).powi(2)).sum();
    let den: f64 = y.iter().map(|a| (a - m).powi(2)).sum();
    100.0 * (1.0 - (num / den.max(1e-300)).sqrt())
}

fn bin(label: String, vals: &[f64]) -> Bin {
    let mean = if vals.is_empty() {
        0.0
    } else {
        vals.iter().sum::<f64>() / vals.len() as f64
    };
    Bin {
        label,
        count: vals.len(),
        rms: rms(vals),
        mean,
    }
}

fn quantile_bins(key: &[f64], r: &[f64], k: usize, name: &str) -> Vec<Bin> {
    let mut sorted: Vec<f64> = key.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let edges: Vec<f64> = (0..=k)
        .map(|i| sorted[((i * (n - 1)) / k).min(n - 1)])
        .collect();
    (0..k)
        .map(|i| {
            let (lo, hi) = (edges[i], edges[i + 1]);
            let vals: Vec<f64> = key
                .iter()
                .zip(r)
                .filter(|(v, _)| **v >= lo && (**v < hi || (i == k - 1 && **v <= hi)))
                .map(|(_, e)| *e)
                .collect();
            bin(format!("{name} {}..{}", eng(lo), eng(hi)), &vals)
        })
        .collect()
}

/// Compute all metrics. `period` folds position phase (default: the position range / 10).
pub fn compute(res: &Residual, period: Option<f64>) -> Metrics {
    let r = &res.residual;
    let n = r.len();
    let (mut max_abs, mut max_i) = (0.0, 0);
    for (i, v) in r.iter().enumerate() {
        if v.abs() > max_abs {
            max_abs = v.abs();
            max_i = i;
        }
    }
    let ynorm = res.measured.iter().map(|v| v * v).sum::<f64>().sqrt();
    let (q, p) = stats::ljung_box(r, 20);
    let (x, xcorr_with) = driver(res);
    let xc = stats::cross_correlation(r, x, MAX_LAG);
    let (lag, xmax) = xc.iter().fold(
        (0, 0.0f64),
        |(l, m), &(k, c)| if c.abs() > m.abs() { (k, c) } else { (l, m) },
    );

    let by_time = (0..10)
        .map(|w| {
            let (lo, hi) = (w * n / 10, (w + 1) * n / 10);
            bin(
                format!("t {:.3}..{:.3} s", res.time[lo], res.time[hi - 1]),
                &r[lo..hi],
            )
        })
        .collect();
    let speed: Vec<f64> = res.velocity.iter().map(|v| v.abs()).collect();
    let by_velocity = quantile_bins(&speed, r, 5, "|v|");
    // Reversals: sign changes of velocity beyond a small noise guard.
    let vmax = speed.iter().cloned().fold(0.0, f64::max);
    let guard = 0.01 * vmax;
    let mut near = vec![false; n];
    let win = (n / 200).clamp(5, 200);
    let mut last = 0.0;
    for i in 0..n {
        let s = if res.velocity[i] > guard {
            1.0
        } else if res.velocity[i] < -guard {
            -1.0
        } else {
            0.0
        };
        if s != 0.0 {
            if last != 0.0 && s != last {
                // mark the window around the crossing
                let mut j = i;
                while j > 0 && res.velocity[j - 1].abs() <= guard {
                    j -= 1;
                }
                near[j.saturating_sub(win)..(i + win).min(n)].fill(true);
            }
            last = s;
        }
    }
    let near_v: Vec<f64> = r
        .iter()
        .zip(&near)
        .filter(|(_, &b)| b)
        .map(|(e, _)| *e)
        .collect();
    let far_v: Vec<f64> = r
        .iter()
        .zip(&near)
        .filter(|(_, &b)| !b)
        .map(|(e, _)| *e)
        .collect();
    let by_reversal = vec![
        bin(format!("within {win} samples of a reversal"), &near_v),
        bin("elsewhere".into(), &far_v),
    ];
    let (xmin, xmx) = res
        .position
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let period = period.unwrap_or(((xmx - xmin) / 10.0).max(1e-12));
    let nb = 12;
    let mut groups = vec![Vec::new(); nb];
    for (x, e) in res.position.iter().zip(r) {
        let ph = (x / period).rem_euclid(1.0);
        groups[((ph * nb as f64) as usize).min(nb - 1)].push(*e);
    }
    let by_position_phase = groups
        .iter()
        .enumerate()
        .map(|(i, g)| {
            bin(
                format!(
                    "phase {:.2}..{:.2}",
                    i as f64 / nb as f64,
                    (i + 1) as f64 / nb as f64
                ),
                g,
            )
        })
        .collect();
    let load: Vec<f64> = res.input.iter().map(|u| u.abs()).collect();
    let by_load = quantile_bins(&load, r, 4, "|input|");
    Metrics {
        residual_mode: res.mode.name().into(),
        fit_percent: fit_percent(&res.measured, &res.predicted),
        rms: rms(r),
        max_abs,
        max_at_s: res.time[max_i],
        noise_floor_rms: res.noise_floor.unwrap_or_else(|| noise_floor(r)),
        relative_error_percent: 100.0 * r.iter().map(|v| v * v).sum::<f64>().sqrt()
            / ynorm.max(1e-300),
        ljung_box_q: q,
        ljung_box_p: p,
        xcorr_with: xcorr_with.to_string(),
        xcorr_max: xmax,
        xcorr_lag: lag,
        xcorr_band: Z99 * ccf_sigma(r, x),
        by_time,
        by_velocity,
        by_reversal,
        by_position_phase,
        phase_period: period,
        by_load,
    }
}

impl Metrics {
    /// Human-readable summary with the localisation tables.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(s, "residual: {}", self.residual_mode);
        let _ = writeln!(
            s,
            "fit {:.2} %   RMS {}   max {} (t = {:.3} s)   noise floor {}   rel. error {:.2} %",
            self.fit_percent,
            eng(self.rms),
            eng(self.max_abs),
            self.max_at_s,
            eng(self.noise_floor_rms),
            self.relative_error_percent
        );
        let _ = writeln!(
            s,
            "whiteness: Ljung–Box Q(20) = {:.1}, p = {:.3e}   largest corr(residual, {}) = {:.3} at lag {} (99 % band ±{:.3})",
            self.ljung_box_q, self.ljung_box_p, self.xcorr_with, self.xcorr_max, self.xcorr_lag, self.xcorr_band
        );
        for (title, bins) in [
            ("by time window", &self.by_time),
            ("by velocity band", &self.by_velocity),
            ("near velocity reversals", &self.by_reversal),
            ("by position phase", &self.by_position_phase),
            ("by load level", &self.by_load),
        ] {
            let _ = writeln!(s, "{title}:");
            for b in bins.iter() {
                let _ = writeln!(
                    s,
                    "  {:<42} n={:<7} rms={:<10} mean={}{}",
                    b.label,
                    b.count,
                    eng(b.rms),
                    if b.mean >= 0.0 { "+" } else { "" },
                    eng(b.mean)
                );
            }
        }
        s
    }
}
