//! `demo --scenario fidelity`: the thesis's stiffness-fidelity test (Ch. 4) on the six
//! transmissions. Each emulates a spring at the thesis's low, medium and high desired output
//! stiffness while the output is cranked back and forth; the torque-vs-deflection loop's area
//! is the work the joint loses per cycle (a perfect spring loses none). The thesis ranks the
//! cable ≈ KAMO 30:1 best, DOJEN/REDEX next, the harmonic drive and SUMITOMO worst.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use rayon::prelude::*;

use super::scenario::{Scenario, ScenarioKind, SETTLE_S};

/// The thesis's six transmissions, in its table's order.
pub const SIX: [&str; 6] = [
    "whoi-cable-30",
    "kamo-ball-30",
    "redex-corbac-30",
    "dojen-cam-33",
    "harmonic-drive-60",
    "sumitomo-59",
];

/// The thesis's desired output stiffnesses, N·m/deg (low, medium, high).
pub const STIFFNESSES: [f64; 3] = [0.21, 1.1, 7.1];

/// The spring's peak torque the crank asks for, output N·m: a quarter of the weakest joint's
/// (the 30:1 ones: 2 N·m × 30), so that no motor saturates and every transmission is cranked
/// through the same deflection at a given stiffness.
const PEAK_TORQUE: f64 = 15.0;

/// The crank's deflection amplitude at most, output rad (the scenario's own).
const MAX_AMPLITUDE: f64 = 0.15;

/// The emulated spring's damping, as a share of the scenario's ζ ≈ 0.7 (a lightly damped
/// spring: the loop is then the transmission's, not the damping asked for).
const DAMPING_SHARE: f64 = 0.3;

/// One transmission at one stiffness.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Cell {
    /// Preset name.
    pub preset: String,
    /// Desired stiffness, N·m/deg at the output.
    pub stiffness_nm_per_deg: f64,
    /// Work lost per crank cycle, J.
    pub loop_area_j: f64,
    /// Achieved over desired stiffness.
    pub achieved_ratio: f64,
    /// (deflection deg, torque N·m) along the crank, for the plot.
    #[serde(skip)]
    pub points: Vec<(f64, f64)>,
}

/// The crank's deflection amplitude at stiffness `k` (N·m/rad), output rad.
pub fn amplitude(k: f64) -> f64 {
    (PEAK_TORQUE / k).min(MAX_AMPLITUDE)
}

/// Runs every transmission at every stiffness, in parallel; `tick` is called once per run
/// finished. Cells come in [`SIX`] × [`STIFFNESSES`] order.
pub fn sweep(seed: u64, out: &Path, tick: impl Fn() + Sync) -> Result<Vec<Cell>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let jobs: Vec<(&str, f64)> = SIX
        .iter()
        .flat_map(|p| STIFFNESSES.iter().map(move |k| (*p, *k)))
        .collect();
    jobs.par_iter()
        .map(|&(preset, k_deg)| {
            let cell = one(preset, k_deg, seed, out);
            tick();
            cell
        })
        .collect()
}

fn one(preset: &str, k_deg: f64, seed: u64, out: &Path) -> Result<Cell> {
    let model = sim_plant::presets::preset(preset).ok_or_else(|| anyhow!("no preset {preset}"))?;
    let mut sc = Scenario::new(ScenarioKind::Stiffness, &model)?;
    let k = k_deg.to_degrees();
    // ζ scales with √k on the same inertia.
    sc.gains.damping *= DAMPING_SHARE * (k / sc.gains.stiffness).sqrt();
    sc.gains.stiffness = k;
    sc.set_crank_amplitude(amplitude(k));
    let csv = out.join(format!("{preset}-k{k_deg}.csv"));
    let (rows, mut lab) = super::close_loop::run(&model, sc, seed, &csv)
        .with_context(|| format!("{preset} at {k_deg} N·m/deg"))?;
    let s = lab.summary()?;
    let get = |name: &str| {
        s.get(name)
            .ok_or_else(|| anyhow!("the stiffness summary has no `{name}`"))
    };
    let points = rows
        .iter()
        .filter(|r| r.time_s > SETTLE_S + 0.3)
        .map(|r| {
            (
                (r.output_pos_rad - r.setpoint_pos_rad).to_degrees(),
                -r.torque_sensor_nm,
            )
        })
        .collect();
    Ok(Cell {
        preset: preset.to_string(),
        stiffness_nm_per_deg: k_deg,
        loop_area_j: get("loop area (work lost)")?,
        achieved_ratio: get("achieved / desired")?,
        points,
    })
}

/// The presets at stiffness `k_deg`, best (least work lost) first.
pub fn ranking(cells: &[Cell], k_deg: f64) -> Vec<&Cell> {
    let mut r: Vec<&Cell> = cells
        .iter()
        .filter(|c| c.stiffness_nm_per_deg == k_deg)
        .collect();
    r.sort_by(|a, b| a.loop_area_j.total_cmp(&b.loop_area_j));
    r
}

/// The table: loop area and achieved/desired per transmission and stiffness, then the
/// ranking at each stiffness beside the thesis's.
pub fn table(cells: &[Cell]) -> String {
    let mut s = format!("  {:<18}", "loop area (J)");
    for k in STIFFNESSES {
        s += &format!(
            " {:>22}",
            format!("{k} N·m/deg (±{:.3} rad)", amplitude(k.to_degrees()))
        );
    }
    s += "\n";
    for p in SIX {
        s += &format!("  {p:<18}");
        for k in STIFFNESSES {
            match cells
                .iter()
                .find(|c| c.preset == p && c.stiffness_nm_per_deg == k)
            {
                Some(c) => {
                    s += &format!(
                        " {:>22}",
                        format!("{:.4} (×{:.2})", c.loop_area_j, c.achieved_ratio)
                    )
                }
                None => s += &format!(" {:>22}", "—"),
            }
        }
        s += "\n";
    }
    s += "  (×: achieved / desired stiffness)\n";
    for k in STIFFNESSES {
        let names: Vec<&str> = ranking(cells, k)
            .iter()
            .map(|c| c.preset.as_str())
            .collect();
        s += &format!(
            "  ranking at {k} N·m/deg, best first: {}\n",
            names.join(", ")
        );
    }
    s += "  thesis (Ch. 4): cable ≈ KAMO 30:1 best; DOJEN/REDEX next; harmonic drive and \
          SUMITOMO worst\n";
    s
}

/// The thesis's figure: torque against deflection, one panel per stiffness, a loop per
/// transmission.
pub fn plot(path: &Path, cells: &[Cell]) -> Result<PathBuf> {
    let root = BitMapBackend::new(path, (1500, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let panels = root.split_evenly((1, STIFFNESSES.len()));
    let colours = [BLUE, GREEN, CYAN, MAGENTA, RED, BLACK];
    for (area, k) in panels.iter().zip(STIFFNESSES) {
        let here: Vec<&Cell> = cells
            .iter()
            .filter(|c| c.stiffness_nm_per_deg == k)
            .collect();
        let x = amplitude(k.to_degrees()).to_degrees() * 1.3;
        let y = here
            .iter()
            .flat_map(|c| c.points.iter().map(|p| p.1.abs()))
            .fold(1e-3, f64::max)
            * 1.1;
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{k} N·m/deg desired"), ("sans-serif", 20))
            .margin(8)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(-x..x, -y..y)
            .map_err(|e| anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("deflection (output deg)")
            .y_desc("torque (output N·m)")
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
        for c in here {
            let i = SIX.iter().position(|p| *p == c.preset).unwrap_or(0);
            let colour = colours.get(i).copied().unwrap_or(BLACK);
            chart
                .draw_series(LineSeries::new(c.points.iter().copied(), colour))
                .map_err(|e| anyhow!("{e}"))?
                .label(c.preset.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow!("{e}"))?;
    Ok(path.to_path_buf())
}
