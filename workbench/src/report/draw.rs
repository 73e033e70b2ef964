//! The charts drawn with plotters: SVG for the HTML report, PNG on request.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{Chart, Kind, ReportError};

const COLORS: [RGBColor; 5] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

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
    let mut palette = COLORS.iter().cycle();
    for s in &c.series {
        let col = match s.kind {
            Kind::Reference => RGBColor(140, 140, 140),
            _ => palette.next().copied().unwrap_or(BLACK),
        };
        let drawn = match s.kind {
            Kind::Dots => chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|&(x, y)| Circle::new((x, y), 1, col.filled())),
                )
                .map_err(|e| e.to_string())?,
            Kind::Line | Kind::Reference => chart
                .draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    col.stroke_width(1),
                ))
                .map_err(|e| e.to_string())?,
        };
        // An unnamed series (the lower half of a band) stays out of the legend.
        if !s.name.is_empty() {
            drawn.label(&s.name).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2))
            });
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
pub fn svg(c: &Chart) -> Result<String, ReportError> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (900, 380)).into_drawing_area();
        draw(root, c)?;
    }
    Ok(s)
}

/// Render a chart to a PNG file.
pub fn png(c: &Chart, path: &Path) -> Result<(), ReportError> {
    let root = BitMapBackend::new(path, (900, 380)).into_drawing_area();
    draw(root, c)
}
