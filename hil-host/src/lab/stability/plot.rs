//! The maps' plots: per map the Routh boundary as a line over a fine grid, the closed form's
//! points, and the lab's bisected points as circles; x on a log axis where it spans decades.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;

use super::{routh, specs, Map, Spec};

const COLOURS: [RGBColor; 3] = [RED, BLUE, GREEN];

/// One PNG per map in `out`; returns their paths.
pub fn plot(out: &Path, maps: &[Map]) -> Result<Vec<PathBuf>> {
    let specs = specs();
    let mut files = Vec::new();
    for (m, s) in maps.iter().zip(&specs) {
        let path = out.join(format!("stability-{}.png", m.name));
        let (x0, x1) = s
            .curves
            .iter()
            .flat_map(|c| c.xs.iter())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(*x), b.max(*x))
            });
        if x0 > 0.0 && x1 / x0 > 50.0 {
            draw(&path, m, s, (x0 * 0.8..x1 * 1.25).log_scale(), true)?;
        } else {
            let pad = 0.05 * (x1 - x0);
            draw(&path, m, s, x0 - pad..x1 + pad, false)?;
        }
        files.push(path);
    }
    Ok(files)
}

fn draw<X>(path: &Path, m: &Map, s: &Spec, x: X, log: bool) -> Result<()>
where
    X: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
{
    let lines: Vec<(usize, Vec<(f64, f64)>)> = s
        .curves
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let (lo, hi) = (c.xs[0], c.xs[c.xs.len() - 1]);
            let pts = (0..=120)
                .filter_map(|k| {
                    let f = k as f64 / 120.0;
                    let x = if log {
                        lo * (hi / lo).powf(f)
                    } else {
                        lo + (hi - lo) * f
                    };
                    let law = c.law;
                    let g = routh::boundary(
                        |g| routh::stable(&routh::characteristic(&c.plant, &law(x, g))),
                        c.lo,
                        c.hi,
                        1e-4,
                    )?;
                    (g < c.hi).then_some((x, g * m.y_scale))
                })
                .collect();
            (i, pts)
        })
        .collect();
    let y_max = m
        .curves
        .iter()
        .flat_map(|c| c.points.iter())
        .filter_map(|p| p.lab.at().or(p.routh.at()))
        .chain(
            lines
                .iter()
                .flat_map(|(_, l)| l.iter().map(|p| p.1 / m.y_scale)),
        )
        .fold(0.0f64, f64::max)
        * m.y_scale
        * 1.15;
    let root = BitMapBackend::new(path, (1000, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(m.title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x, 0.0..y_max.max(1e-9))
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc(m.x_label)
        .y_desc(m.y_label)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    for (i, pts) in lines {
        let colour = COLOURS[i % COLOURS.len()];
        let curve = &m.curves[i];
        if pts.is_empty() && curve.points.iter().all(|p| p.lab.at().is_none()) {
            // Stable over the whole search range, by both: say so in the legend.
            let top = curve
                .points
                .iter()
                .filter_map(|p| match p.lab {
                    super::Edge::Beyond(h) => Some(h * m.y_scale),
                    _ => None,
                })
                .fold(0.0f64, f64::max);
            chart
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                .map_err(|e| anyhow!("{e}"))?
                .label(format!(
                    "{}: stable to the top of the range (up to {top:.0}), Routh and lab",
                    curve.name
                ))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
            continue;
        }
        chart
            .draw_series(LineSeries::new(pts, colour))
            .map_err(|e| anyhow!("{e}"))?
            .label(format!("{}: Routh", m.curves[i].name))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        // The points one judge placed an edge at, in the plot's units.
        let edges = |edge: fn(&super::Point) -> &super::Edge| -> Vec<(f64, f64)> {
            curve
                .points
                .iter()
                .filter_map(|p| Some((p.x, edge(p).at()? * m.y_scale)))
                .collect()
        };
        chart
            .draw_series(
                edges(|p| &p.lab)
                    .into_iter()
                    .map(move |p| Circle::new(p, 5, colour.stroke_width(2))),
            )
            .map_err(|e| anyhow!("{e}"))?
            .label(format!("{}: lab", m.curves[i].name))
            .legend(move |(x, y)| Circle::new((x + 9, y), 5, colour.stroke_width(2)));
        chart
            .draw_series(
                edges(|p| &p.sampled)
                    .into_iter()
                    .map(move |p| Cross::new(p, 5, colour.stroke_width(1))),
            )
            .map_err(|e| anyhow!("{e}"))?
            .label(format!("{}: sampled at 1 ms", m.curves[i].name))
            .legend(move |(x, y)| Cross::new((x + 9, y), 5, colour.stroke_width(1)));
    }
    // Where each map's curves leave room.
    let corner = if m.name == "impedance" {
        SeriesLabelPosition::LowerRight
    } else {
        SeriesLabelPosition::LowerLeft
    };
    chart
        .configure_series_labels()
        .position(corner)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(())
}
