//! Plots (SVG always, PNG on request) and one self-contained HTML report.
//!
//! Five plots, each answering one question: *overlay* (does the model follow the measurement
//! at all?), *residual vs time* (is the error in bursts, drifting?), *residual vs velocity*
//! (friction fingerprints: a step at v = 0 is Coulomb, a slope is viscous, a bump near 0 is
//! Stribeck), *residual vs position folded on a period* (ripple, cogging, gravity), and the
//! *residual spectrum* (resonances, quantisation fuzz, periodic effects at speed × spatial
//! frequency). The HTML inlines the SVGs so the report is one file you can mail.
//!
//! Drawing (`svg`, `png`, `write`) needs the default `plot` feature (plotters and its
//! font and image stack); without it the charts' data ([`charts`], [`welch`]) is still here.

#[cfg(feature = "plot")]
use std::path::Path;
use std::path::PathBuf;

#[cfg(feature = "plot")]
use plotters::coord::Shift;
#[cfg(feature = "plot")]
use plotters::prelude::*;

use super::metrics::Metrics;
use super::residual::Residual;

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

/// A curve to draw.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend name.
    pub name: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
    /// Dots instead of a line.
    pub scatter: bool,
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

#[cfg(feature = "plot")]
const COLORS: [RGBColor; 5] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

fn thin(points: Vec<(f64, f64)>, max: usize) -> Vec<(f64, f64)> {
    if points.len() <= max {
        return points;
    }
    let step = points.len().div_ceil(max);
    points.into_iter().step_by(step).collect()
}

#[cfg(feature = "plot")]
fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, c: &Chart) -> Result<(), ReportError>
where
    DB::ErrorType: 'static,
{
    draw_plot(root, c).map_err(|message| ReportError::Plot {
        chart: c.id.clone(),
        message,
    })
}

/// [`draw`], with the plotting library's errors as text (its error type is the backend's).
#[cfg(feature = "plot")]
fn draw_plot<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, c: &Chart) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let all = c.series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in all {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0);
    let mut chart = ChartBuilder::on(&root)
        .caption(&c.title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(&c.x_label)
        .y_desc(&c.y_label)
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, s) in c.series.iter().enumerate() {
        let col = COLORS[i % COLORS.len()];
        if s.scatter {
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), 1, col.filled())),
                )
                .map_err(|e| e.to_string())?
                .label(&s.name)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, col.filled()));
        } else {
            chart
                .draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    col.stroke_width(1),
                ))
                .map_err(|e| e.to_string())?
                .label(&s.name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col));
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// Render a chart to an SVG string.
#[cfg(feature = "plot")]
pub fn svg(c: &Chart) -> Result<String, ReportError> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (900, 380)).into_drawing_area();
        draw(root, c)?;
    }
    Ok(s)
}

/// Render a chart to a PNG file.
#[cfg(feature = "plot")]
pub fn png(c: &Chart, path: &Path) -> Result<(), ReportError> {
    let root = BitMapBackend::new(path, (900, 380)).into_drawing_area();
    draw(root, c)
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
    (1..=nseg / 2)
        .map(|k| (k as f64 / (nseg as f64 * dt), acc[k] * scale * 2.0))
        .collect()
}

/// The five standard charts for a residual.
pub fn charts(res: &Residual, m: &Metrics, unit: &str) -> Vec<Chart> {
    const MAX: usize = 6000;
    let t = &res.time;
    let r = &res.residual;
    let zip = |a: &[f64], b: &[f64]| a.iter().copied().zip(b.iter().copied()).collect::<Vec<_>>();
    let what = if res.mode == super::residual::Mode::Equation {
        "input"
    } else {
        "position"
    };
    let dt = if t.len() > 1 {
        (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64
    } else {
        1.0
    };
    let spec: Vec<(f64, f64)> = welch(r, dt)
        .into_iter()
        .map(|(f, p)| (f, p.max(1e-300).log10()))
        .collect();
    let folded: Vec<(f64, f64)> = res
        .position
        .iter()
        .zip(r)
        .map(|(x, e)| ((x / m.phase_period).rem_euclid(1.0), *e))
        .collect();
    vec![
        Chart {
            id: "overlay".into(),
            title: format!("measured vs model {what} ({})", res.mode.name()),
            x_label: "time [s]".into(),
            y_label: format!("{what} [{unit}]"),
            series: vec![
                Series {
                    name: "measured".into(),
                    points: thin(zip(t, &res.measured), MAX),
                    scatter: false,
                },
                Series {
                    name: "model".into(),
                    points: thin(zip(t, &res.predicted), MAX),
                    scatter: false,
                },
            ],
        },
        Chart {
            id: "residual_time".into(),
            title: "residual vs time".into(),
            x_label: "time [s]".into(),
            y_label: format!("residual [{unit}]"),
            series: vec![Series {
                name: "residual".into(),
                points: thin(zip(t, r), MAX),
                scatter: false,
            }],
        },
        Chart {
            id: "residual_velocity".into(),
            title: "residual vs velocity".into(),
            x_label: "velocity".into(),
            y_label: format!("residual [{unit}]"),
            series: vec![Series {
                name: "residual".into(),
                points: thin(zip(&res.velocity, r), MAX),
                scatter: true,
            }],
        },
        Chart {
            id: "residual_position".into(),
            title: format!("residual vs position, folded on {:.4e}", m.phase_period),
            x_label: "position phase [periods]".into(),
            y_label: format!("residual [{unit}]"),
            series: vec![Series {
                name: "residual".into(),
                points: thin(folded, MAX),
                scatter: true,
            }],
        },
        Chart {
            id: "residual_spectrum".into(),
            title: "residual spectrum (Welch)".into(),
            x_label: "frequency [Hz]".into(),
            y_label: "log10 PSD".into(),
            series: vec![Series {
                name: "PSD".into(),
                points: spec,
                scatter: false,
            }],
        },
    ]
}

#[cfg(feature = "plot")]
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Write SVGs (and PNGs if asked) of `charts` into `dir`, plus `report.html` with the charts
/// inlined and `sections` (title, preformatted text) above them. Returns the HTML path.
#[cfg(feature = "plot")]
pub fn write(
    dir: &Path,
    title: &str,
    sections: &[(String, String)],
    charts: &[Chart],
    with_png: bool,
) -> Result<PathBuf, ReportError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| ReportError::Io { path, source }
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let mut html = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>{t}</title><style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}pre{{background:#f4f4f4;padding:8px;overflow-x:auto}}</style></head><body><h1>{t}</h1>\n",
        t = esc(title)
    );
    for (h, body) in sections {
        html.push_str(&format!("<h2>{}</h2><pre>{}</pre>\n", esc(h), esc(body)));
    }
    for c in charts {
        let s = svg(c)?;
        let p = dir.join(format!("{}.svg", c.id));
        std::fs::write(&p, &s).map_err(io(&p))?;
        if with_png {
            png(c, &dir.join(format!("{}.png", c.id)))?;
        }
        html.push_str(&format!(
            "<h2 id=\"{}\">{}</h2>\n{}\n",
            c.id,
            esc(&c.title),
            s
        ));
    }
    html.push_str("</body></html>\n");
    let p = dir.join("report.html");
    std::fs::write(&p, html).map_err(io(&p))?;
    Ok(p)
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
}
