//! Plots (SVG always, PNG on request) and one self-contained HTML report.
//!
//! The charts follow MATLAB's `compare` and `resid`, one question each: *overlay* (does each
//! model follow the measurement, and how well: fit % in the legend), *residual vs time* (bursts,
//! drift), the residual's *autocorrelation* and its *cross-correlation with the input*, each
//! with the 99 % band of a white residual independent of the input (outside it: dynamics the
//! model misses), *residual vs velocity* (friction fingerprints: a step at v = 0 is Coulomb, a
//! slope viscous, a bump near 0 Stribeck), *residual vs position*, unfolded (gravity, a
//! position-dependent load) and folded on a period (ripple, cogging), and the *residual
//! spectrum* against the noise floor (resonances, periodic effects at speed × spatial
//! frequency). The HTML inlines the SVGs and an interactive, zoomable time view, so the
//! report is one file you can mail ([`page`]).
//!
//! Drawing needs the default `plot` feature (plotters and its font and image stack); without
//! it the charts' data ([`charts`], [`welch`]) is still here.

#[cfg(feature = "plot")]
mod draw;
#[cfg(feature = "plot")]
pub mod page;

#[cfg(feature = "plot")]
pub use draw::{png, svg};

use std::path::PathBuf;

use super::metrics::Metrics;
pub use super::metrics::{band99, ccf_sigma, driver, MAX_LAG, Z99, Z99_ALL_LAGS};
use super::residual::{Mode, Residual};
pub use super::units::eng;

/// Why a report or plot was not written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file or directory could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The plotting library failed to draw a chart.
    #[error("chart `{chart}`: {message}")]
    Plot {
        /// The chart's id.
        chart: String,
        /// The plotting library's message.
        message: String,
    },
}

/// How a curve is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A line in the next palette colour.
    Line,
    /// Dots in the next palette colour (a scatter of residual against a state).
    Dots,
    /// A thin grey line: a reference (confidence band, noise floor), not a model.
    Reference,
}

/// A curve to draw.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
    /// How it is drawn.
    pub kind: Kind,
}

impl Series {
    /// A line.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: Kind::Line,
        }
    }
    /// Dots.
    pub fn dots(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: Kind::Dots,
        }
    }
    /// A grey reference line.
    pub fn reference(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Series {
            name: name.into(),
            points,
            kind: Kind::Reference,
        }
    }
}

/// A chart: title, axes, curves.
#[derive(Debug, Clone)]
pub struct Chart {
    /// File stem and anchor.
    pub id: String,
    /// Title.
    pub title: String,
    /// X label.
    pub x_label: String,
    /// Y label.
    pub y_label: String,
    /// Curves.
    pub series: Vec<Series>,
}

use super::spectral::fft;

/// Welch power spectral density (Hann, 1024-point segments, 50 % overlap): (Hz, PSD).
pub fn welch(x: &[f64], dt: f64) -> Vec<(f64, f64)> {
    let mut nseg = 1024;
    while nseg > x.len() && nseg > 16 {
        nseg /= 2;
    }
    let w: Vec<f64> = (0..nseg)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / nseg as f64).cos())
        .collect();
    let wss: f64 = w.iter().map(|v| v * v).sum();
    let mut acc = vec![0.0; nseg / 2 + 1];
    let mut count = 0;
    let mut start = 0;
    while start + nseg <= x.len() {
        let seg = &x[start..start + nseg];
        let m = seg.iter().sum::<f64>() / nseg as f64;
        let mut re: Vec<f64> = seg.iter().zip(&w).map(|(v, w)| (v - m) * w).collect();
        let mut im = vec![0.0; nseg];
        fft(&mut re, &mut im);
        for k in 0..=nseg / 2 {
            acc[k] += re[k] * re[k] + im[k] * im[k];
        }
        count += 1;
        start += nseg / 2;
    }
    let scale = dt / (wss * count.max(1) as f64);
    // One-sided: every bin but DC and Nyquist (which have no mirror image) doubled.
    (1..=nseg / 2)
        .map(|k| {
            let fold = if k == nseg / 2 { 1.0 } else { 2.0 };
            (k as f64 / (nseg as f64 * dt), acc[k] * scale * fold)
        })
        .collect()
}

/// Keep at most about `max` points, evenly spaced: a chart of 10⁶ dots says no more than one of
/// 10⁴, and an SVG of them is unusable.
fn thin(points: Vec<(f64, f64)>, max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max {
        return points;
    }
    let step = points.len().div_ceil(max);
    points.into_iter().step_by(step).collect()
}

/// A time series cut to about `max` points that keeps its extremes: each run of samples
/// gives its lowest and highest, in order, so a burst one sample wide still shows.
fn envelope(points: Vec<(f64, f64)>, max: usize) -> Vec<(f64, f64)> {
    let step = points.len().div_ceil(max.max(2) / 2).max(1);
    if step <= 2 {
        return points;
    }
    let mut out = Vec::with_capacity(2 * points.len() / step + 2);
    for run in points.chunks(step) {
        let lo = run.iter().min_by(|a, b| a.1.total_cmp(&b.1));
        let hi = run.iter().max_by(|a, b| a.1.total_cmp(&b.1));
        if let (Some(&lo), Some(&hi)) = (lo, hi) {
            if lo.0 == hi.0 {
                out.push(lo);
            } else if lo.0 < hi.0 {
                out.extend([lo, hi]);
            } else {
                out.extend([hi, lo]);
            }
        }
    }
    out
}

/// The units of a record's axes, for labels: the residual's (the input's for the equation
/// error, the position's for the output error) and the position's (`m` or `rad`; velocity is
/// that per second).
#[derive(Debug, Clone)]
pub struct Units {
    /// Unit of the residual and of the compared signal.
    pub signal: String,
    /// Unit of position.
    pub position: String,
}

/// One model's residual on the record, and its metrics, as `compare` draws them.
#[derive(Debug, Clone, Copy)]
pub struct Compared<'a> {
    /// The model's name (legends).
    pub name: &'a str,
    /// Its residual.
    pub residual: &'a Residual,
    /// Its metrics.
    pub metrics: &'a Metrics,
}

/// The largest |cross-correlation| of the residual with its [`driver`], (lag, value).
pub fn worst_ccf(res: &Residual) -> (i64, f64) {
    let (x, _) = driver(res);
    super::stats::cross_correlation(&res.residual, x, MAX_LAG)
        .into_iter()
        .fold(
            (0, 0.0f64),
            |(l, m), (k, c)| {
                if c.abs() > m.abs() {
                    (k, c)
                } else {
                    (l, m)
                }
            },
        )
}

/// The charts of `compare` for one or several models on one record (all residuals share the
/// record's time, position and velocity; the first model's are used for the axes).
pub fn charts(models: &[Compared<'_>], units: &Units) -> Vec<Chart> {
    const MAX: usize = 6000;
    let Some(first) = models.first() else {
        return Vec::new();
    };
    let res0 = first.residual;
    let t = &res0.time;
    let zip = |a: &[f64], b: &[f64]| a.iter().copied().zip(b.iter().copied()).collect::<Vec<_>>();
    let what = if res0.mode == Mode::Equation {
        "input"
    } else {
        "position"
    };
    let (su, pu) = (&units.signal, &units.position);
    let dt = if t.len() > 1 {
        (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
    } else {
        1.0
    };
    let legend = |c: &Compared<'_>| format!("{} (fit {:.1} %)", c.name, c.metrics.fit_percent);
    let per_model = |f: &dyn Fn(&Compared<'_>) -> Series| models.iter().map(f).collect::<Vec<_>>();
    let band_lines = |lo: f64, hi: f64, band: f64, name: &str| {
        vec![
            Series::reference(name, vec![(lo, band), (hi, band)]),
            Series::reference("", vec![(lo, -band), (hi, -band)]),
        ]
    };
    let (_, driven_by) = driver(res0);
    let period = first.metrics.phase_period;

    let mut overlay = vec![Series::reference(
        "measured",
        envelope(zip(t, &res0.measured), MAX),
    )];
    overlay.extend(per_model(&|c| {
        Series::line(legend(c), envelope(zip(t, &c.residual.predicted), MAX))
    }));
    let mut acf = per_model(&|c| {
        let r = super::stats::autocorrelation(&c.residual.residual, MAX_LAG);
        Series::line(
            c.name,
            r.iter().enumerate().map(|(k, v)| (k as f64, *v)).collect(),
        )
    });
    acf.extend(band_lines(
        0.0,
        MAX_LAG as f64,
        band99(t.len()),
        "99 % band",
    ));
    let mut ccf = per_model(&|c| {
        let (x, _) = driver(c.residual);
        let r = super::stats::cross_correlation(&c.residual.residual, x, MAX_LAG);
        Series::line(c.name, r.iter().map(|&(k, v)| (k as f64, v)).collect())
    });
    // The band of the first model's residual (each model's differs with its whiteness).
    let (x0, _) = driver(res0);
    ccf.extend(band_lines(
        -(MAX_LAG as f64),
        MAX_LAG as f64,
        Z99 * ccf_sigma(&res0.residual, x0),
        &format!("99 % band ({})", first.name),
    ));
    let mut spectrum = per_model(&|c| {
        Series::line(
            c.name,
            welch(&c.residual.residual, dt)
                .into_iter()
                .map(|(f, p)| (f, p.max(1e-300).log10()))
                .collect(),
        )
    });
    // White noise of RMS σ has the one-sided density 2σ²·dt, flat up to Nyquist.
    let floor = first.metrics.noise_floor_rms;
    if floor > 0.0 && dt > 0.0 {
        let level = (2.0 * floor * floor * dt).log10();
        spectrum.push(Series::reference(
            format!("noise floor ({})", first.name),
            vec![(0.0, level), (0.5 / dt, level)],
        ));
    }
    vec![
        Chart {
            id: "overlay".into(),
            title: format!("measured vs model {what} ({})", res0.mode.name()),
            x_label: "time [s]".into(),
            y_label: format!("{what} [{su}]"),
            series: overlay,
        },
        Chart {
            id: "residual_time".into(),
            title: "residual vs time".into(),
            x_label: "time [s]".into(),
            y_label: format!("residual [{su}]"),
            series: per_model(&|c| {
                Series::line(c.name, envelope(zip(t, &c.residual.residual), MAX))
            }),
        },
        Chart {
            id: "residual_acf".into(),
            title: "residual autocorrelation, 99 % band of a white residual".into(),
            x_label: format!("lag [samples of {} s]", eng(dt)),
            y_label: "correlation".into(),
            series: acf,
        },
        Chart {
            id: "input_ccf".into(),
            title: format!("{driven_by}–residual cross-correlation corr(e(t), x(t−k)), 99 % band"),
            x_label: format!("lag k [samples of {} s]", eng(dt)),
            y_label: "correlation".into(),
            series: ccf,
        },
        Chart {
            id: "residual_velocity".into(),
            title: "residual vs velocity".into(),
            x_label: format!(
                "velocity [{}/s]",
                if pu.is_empty() { "1" } else { pu.as_str() }
            ),
            y_label: format!("residual [{su}]"),
            series: per_model(&|c| {
                Series::dots(c.name, thin(zip(&res0.velocity, &c.residual.residual), MAX))
            }),
        },
        Chart {
            id: "residual_position".into(),
            title: "residual vs position".into(),
            x_label: format!("position [{pu}]"),
            y_label: format!("residual [{su}]"),
            series: per_model(&|c| {
                Series::dots(c.name, thin(zip(&res0.position, &c.residual.residual), MAX))
            }),
        },
        Chart {
            id: "residual_position_folded".into(),
            title: format!("residual vs position, folded on {} {pu}", eng(period)),
            x_label: format!("position mod {} {pu} [periods]", eng(period)),
            y_label: format!("residual [{su}]"),
            series: per_model(&|c| {
                let folded = res0
                    .position
                    .iter()
                    .zip(&c.residual.residual)
                    .map(|(x, e)| ((x / period).rem_euclid(1.0), *e))
                    .collect();
                Series::dots(c.name, thin(folded, MAX))
            }),
        },
        Chart {
            id: "residual_spectrum".into(),
            title: "residual spectrum (Welch) and the noise floor".into(),
            x_label: "frequency [Hz]".into(),
            y_label: format!("log10 PSD [{su}²/Hz]"),
            series: spectrum,
        },
    ]
}

/// What `compare` found, in a few sentences for the top of the report: the best model, whether
/// anything is left above the noise, and where to look next.
pub fn finding(models: &[Compared<'_>]) -> String {
    let Some(best) = models
        .iter()
        .max_by(|a, b| a.metrics.fit_percent.total_cmp(&b.metrics.fit_percent))
    else {
        return String::new();
    };
    let m = best.metrics;
    let mut s = if models.len() > 1 {
        format!(
            "Best of {} models: {}, fit {} % ({} residual), RMS {} = {}× the noise floor.",
            models.len(),
            best.name,
            eng(m.fit_percent),
            m.residual_mode,
            eng(m.rms),
            eng(m.rms / m.noise_floor_rms)
        )
    } else {
        format!(
            "{}: fit {} % ({} residual), RMS {} = {}× the noise floor.",
            best.name,
            eng(m.fit_percent),
            m.residual_mode,
            eng(m.rms),
            eng(m.rms / m.noise_floor_rms)
        )
    };
    let res = best.residual;
    let n = res.residual.len();
    let dt = match (res.time.first(), res.time.last()) {
        (Some(a), Some(b)) if n > 1 => (b - a) / (n - 1) as f64,
        _ => 0.0,
    };
    let (x, driven_by) = driver(res);
    let (lag, r) = worst_ccf(res);
    let limit = Z99_ALL_LAGS * ccf_sigma(&res.residual, x);
    let white = m.ljung_box_p >= 0.01;
    let correlated = r.abs() > limit;
    if white && !correlated {
        s.push_str(&format!(
            " Its residual is white (Ljung–Box p = {:.2}) and uncorrelated with the \
             {driven_by} at every lag (99 %): the data hold nothing more this model class can \
             explain.",
            m.ljung_box_p
        ));
        return s;
    }
    if correlated {
        let at = format!(
            "r = {} at lag {lag} ({} s), beyond ±{} for all lags at 99 %",
            eng(r),
            eng(lag as f64 * dt),
            eng(limit)
        );
        s.push_str(&if lag >= 0 {
            format!(
                " The residual correlates with the {driven_by}'s past ({at}): the model \
                 misses dynamics the {driven_by} drives."
            )
        } else {
            format!(
                " The residual leads the {driven_by} ({at}): feedback — a controller acted on \
                 the error, as on closed-loop data."
            )
        });
    }
    if !white {
        s.push_str(&format!(
            " The residual is not white (Ljung–Box p = {:.2e}): structure a model could still \
             explain.",
            m.ljung_box_p
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welch_finds_a_sine() {
        let dt = 1e-3;
        let x: Vec<f64> = (0..8192)
            .map(|i| (2.0 * std::f64::consts::PI * 50.0 * i as f64 * dt).sin())
            .collect();
        let s = welch(&x, dt);
        let peak = s
            .iter()
            .cloned()
            .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        assert!((peak.0 - 50.0).abs() < 1.5, "{peak:?}");
    }

    #[test]
    fn the_envelope_keeps_a_one_sample_burst() {
        let mut pts: Vec<(f64, f64)> = (0..100_000).map(|i| (i as f64, 0.0)).collect();
        pts[54_321].1 = 7.0;
        pts[77_777].1 = -3.0;
        let e = envelope(pts, 6000);
        assert!(e.len() <= 6200, "{}", e.len());
        assert!(e.contains(&(54_321.0, 7.0)) && e.contains(&(77_777.0, -3.0)));
        assert!(e.windows(2).all(|w| w[0].0 < w[1].0), "in time order");
    }

    #[test]
    fn white_noise_psd_sits_at_the_floor_level() {
        // Uniform noise of variance 1/12 from a fixed LCG: the one-sided density 2σ²·dt.
        let dt = 2e-3;
        let mut state = 12345u64;
        let x: Vec<f64> = (0..65536)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let s = welch(&x, dt);
        let mean = s.iter().map(|p| p.1).sum::<f64>() / s.len() as f64;
        let want = 2.0 * dt / 12.0;
        assert!((mean / want - 1.0).abs() < 0.05, "{mean} vs {want}");
    }
}
