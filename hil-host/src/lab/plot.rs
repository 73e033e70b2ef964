//! A PNG of a run: position (setpoint, motor/N, output), torque command, torque sensor.

use std::path::Path;

use anyhow::{anyhow, Result};
use plotters::prelude::*;

use super::recorder::Row;

fn range(v: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let lo = v.clone().fold(f64::INFINITY, f64::min);
    let hi = v.fold(f64::NEG_INFINITY, f64::max);
    if !lo.is_finite() || !hi.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = ((hi - lo) * 0.08).max(1e-6);
    (lo - pad, hi + pad)
}

/// A curve of a run's plot: legend name, PNG colour, drawn as a reference (a setpoint, grey
/// in the HTML view) rather than a measurement, and how to read it from a row.
type Curve<'a> = (&'a str, RGBColor, bool, Box<dyn Fn(&Row) -> f64 + 'a>);

/// The three panels every plot of a run shows, (id, y label with unit, curves): the PNG and
/// the HTML report draw the same ones.
fn panels<'a>(gear_ratio: f64) -> Vec<(&'a str, &'a str, Vec<Curve<'a>>)> {
    vec![
        (
            "position",
            "position [output rad]",
            vec![
                (
                    "setpoint",
                    BLACK,
                    true,
                    Box::new(|r: &Row| r.setpoint_pos_rad),
                ),
                (
                    "motor / N",
                    BLUE,
                    false,
                    Box::new(move |r: &Row| r.motor_pos_rad / gear_ratio),
                ),
                ("output", RED, false, Box::new(|r: &Row| r.output_pos_rad)),
            ],
        ),
        (
            "torque_command",
            "torque command [motor N·m]",
            vec![("command", BLUE, false, Box::new(|r: &Row| r.torque_cmd_nm))],
        ),
        (
            "torque_sensor",
            "torque sensor [output N·m]",
            vec![
                ("sensor", RED, false, Box::new(|r: &Row| r.torque_sensor_nm)),
                (
                    "setpoint",
                    BLACK,
                    true,
                    Box::new(|r: &Row| r.setpoint_torque_nm),
                ),
            ],
        ),
    ]
}

/// Draws the three panels of a recording to `path` (PNG, 1200×900).
pub fn plot_run(path: &Path, title: &str, rows: &[Row], gear_ratio: f64) -> Result<()> {
    let root = BitMapBackend::new(path, (1200, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| anyhow!("{e}"))?;
    let panels = root.split_evenly((3, 1));
    let t0 = rows.first().map(|r| r.time_s).unwrap_or(0.0);
    let t1 = rows.last().map(|r| r.time_s).unwrap_or(1.0).max(t0 + 1e-3);
    let specs = self::panels(gear_ratio);
    for (area, (_, ylabel, series)) in panels.iter().zip(specs) {
        let all = series.iter().flat_map(|(_, _, _, f)| rows.iter().map(f));
        let (lo, hi) = range(all.collect::<Vec<_>>().into_iter());
        let mut chart = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, lo..hi)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(ylabel)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for (name, color, _, f) in series {
            chart
                .draw_series(LineSeries::new(
                    rows.iter().map(|r| (r.time_s, f(r))),
                    color,
                ))
                .map_err(|e| anyhow!("{e}"))?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Points a plot of a recording draws at most (a 1200-pixel-wide panel shows no more).
pub const PLOT_POINTS: u64 = 20_000;

/// Plots a recording on disk with [`plot_run`], reading every k-th of its `rows` rows so
/// that at most [`PLOT_POINTS`] are held in memory, however long the run.
pub fn plot_recording(
    png: &Path,
    title: &str,
    csv: &Path,
    rows: u64,
    gear_ratio: f64,
) -> Result<()> {
    let every = rows.div_ceil(PLOT_POINTS).max(1) as usize;
    let kept = super::recorder::read_rows(csv)?
        .step_by(every)
        .collect::<Result<Vec<Row>>>()?;
    plot_run(png, title, &kept, gear_ratio)
}

/// The run's HTML report in `dir` (as `compare` writes one): the verdict first, a zoomable
/// view of position and torques, the same panels as charts (`png`: also as PNGs), the text
/// report, the files written with their SHA-256, and provenance (`inputs`: the files the run
/// read). The recording is read every k-th row, as for [`plot_recording`].
#[allow(clippy::too_many_arguments)]
pub fn html_report(
    dir: &Path,
    title: &str,
    report: &super::report::Report,
    csv: &Path,
    rows: u64,
    gear_ratio: f64,
    written: &[&Path],
    inputs: &[std::path::PathBuf],
    png: bool,
) -> Result<std::path::PathBuf> {
    use jointlab_workbench::report::page::{InputFile, Page, Panel, Provenance, Trace, ZoomView};
    use jointlab_workbench::report::{Chart, Series};
    let every = rows.div_ceil(PLOT_POINTS).max(1) as usize;
    let kept = super::recorder::read_rows(csv)?
        .step_by(every)
        .collect::<Result<Vec<Row>>>()?;
    let panels = self::panels(gear_ratio);
    let time: Vec<f64> = kept.iter().map(|r| r.time_s).collect();
    let zoom = ZoomView {
        x_label: "time [s]".into(),
        time: time.clone(),
        panels: panels
            .iter()
            .map(|(_, label, cols)| Panel {
                y_label: label.to_string(),
                series: cols
                    .iter()
                    .map(|(name, _, reference, f)| Trace {
                        name: name.to_string(),
                        y: kept.iter().map(|r| f(r) as f32).collect(),
                        reference: *reference,
                    })
                    .collect(),
            })
            .collect(),
    };
    let charts: Vec<Chart> = panels
        .iter()
        .map(|(id, label, cols)| Chart {
            id: id.to_string(),
            title: label.to_string(),
            x_label: "time [s]".into(),
            y_label: label.to_string(),
            series: cols
                .iter()
                .map(|(name, _, reference, f)| {
                    let points = kept.iter().map(|r| (r.time_s, f(r))).collect();
                    if *reference {
                        Series::reference(*name, points)
                    } else {
                        Series::line(*name, points)
                    }
                })
                .collect(),
        })
        .collect();
    let mut files = String::new();
    for p in written {
        let f = InputFile::hash(p)?;
        files.push_str(&format!(
            "{}  {} bytes  SHA-256 {}\n",
            f.path.display(),
            f.bytes,
            f.sha256
        ));
    }
    let provenance = Provenance::now(concat!("hil-host ", env!("CARGO_PKG_VERSION")), inputs)?;
    let finding = format!("{}: {}", report.verdict.word(), report.headline);
    let path = jointlab_workbench::report::page::write(
        dir,
        &Page {
            title,
            finding: &finding,
            provenance: &provenance,
            sections: &[
                ("report".into(), report.text()),
                ("files written".into(), files),
            ],
            charts: &charts,
            zoom: Some(&zoom),
            models: &[],
        },
        png,
    )?;
    Ok(path)
}

/// One curve of a [`line_chart`]: legend name, colour, points.
#[derive(Clone, Debug)]
pub struct Line {
    /// Legend name.
    pub name: String,
    /// Colour.
    pub colour: RGBColor,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
}

/// A 1200×600 PNG of `lines` over `x` and `y` (axis label, range), with a legend.
pub fn line_chart(
    path: &Path,
    title: &str,
    x: (&str, std::ops::Range<f64>),
    y: (&str, std::ops::Range<f64>),
    lines: Vec<Line>,
) -> Result<()> {
    let root = BitMapBackend::new(path, (1200, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(80)
        .build_cartesian_2d(x.1, y.1)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc(x.0)
        .y_desc(y.0)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    for line in lines {
        let colour = line.colour;
        chart
            .draw_series(LineSeries::new(line.points, colour))
            .map_err(|e| anyhow!("{e}"))?
            .label(line.name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Tracking error over time, without and with compensation, on one chart.
pub fn plot_before_after(path: &Path, title: &str, before: &[Row], after: &[Row]) -> Result<()> {
    let err = |r: &Row| r.setpoint_pos_rad - r.output_pos_rad;
    let t1 = before
        .iter()
        .chain(after)
        .map(|r| r.time_s)
        .fold(1e-3, f64::max);
    let (lo, hi) = range(before.iter().chain(after).map(err));
    let line = |name: &str, rows: &[Row], colour| Line {
        name: name.to_string(),
        colour,
        points: rows.iter().map(|r| (r.time_s, err(r))).collect(),
    };
    line_chart(
        path,
        title,
        ("time (s)", 0.0..t1),
        ("tracking error (output rad)", lo..hi),
        vec![
            line("without", before, RED),
            line("with compensation", after, BLUE),
        ],
    )
}
