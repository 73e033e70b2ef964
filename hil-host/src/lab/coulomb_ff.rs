//! `demo --scenario coulomb-ff`: the thesis's friction-compensation finding (§4, friction
//! compensation) on the lab. Coulomb feed-forward on the measured velocity, as the thesis
//! implemented it (its τc± determined off-line: here the preset's own), at under-compensation
//! factors below and above 1, on a held step at the high stiffness and along the tracking
//! triangle. The thesis: with backlash and a high gain the feed-forward keeps a small limit
//! cycle "about the size of the zone of lost motion" going; "slightly below" the friction is
//! safe; over-compensation injects energy.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use plotters::style::colors::{BLACK, BLUE, GREEN, MAGENTA, RED};
use sim_plant::Model;

use super::close_loop::{held_step, track};
use super::compensate::Compensation;
use super::plot::{line_chart, Line};
use super::recorder::Row;
use super::scenario::{Scenario, ScenarioKind};

/// The under-compensation factors swept; 0 is the run without the feed-forward.
pub const UNDERS: [f64; 5] = [0.0, 0.6, 0.8, 1.0, 1.2];

/// One factor's figures.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct UnderRow {
    /// Under-compensation factor (0: no feed-forward).
    pub under: f64,
    /// The held step's motor encoder peak-to-peak over its last 0.5 s, counts.
    pub limit_cycle_counts: f64,
    /// The same referred to the output, degrees (counts ÷ counts per rev ÷ N): the motor's
    /// motion, not the output's own.
    pub limit_cycle_deg: f64,
    /// Mean power the motor puts into the held joint, W: zero at rest; while a cycle lasts,
    /// what the card feeds it.
    pub hold_power_w: f64,
    /// Tracking error RMS along the triangle, output rad.
    pub tracking_rms_rad: f64,
}

/// What the sweep measured.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// Per factor, in [`UNDERS`]' order.
    pub rows: Vec<UnderRow>,
    /// The feed-forward at factor 1: τc⁺, τc⁻ (output N·m).
    pub coulomb: [f64; 2],
    /// The model's backlash, output degrees (0: none).
    pub backlash_deg: f64,
    /// Every file written.
    pub files: Vec<PathBuf>,
}

/// Runs the sweep on `model`; `out` receives a recording per run and the plot.
pub fn sweep(model: &Model, label: &str, seed: u64, out: &Path) -> Result<Sweep> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let step = Scenario::new(ScenarioKind::Step, model)?;
    let scale = step.scale;
    // Coulomb only, as the thesis implemented it ("for simplicity's sake and stability
    // guarantees"): the viscous term is dropped.
    let mut friction = Compensation::from_model(model, &scale, 1.0)
        .context("the preset's friction as a compensation")?
        .friction
        .ok_or_else(|| anyhow!("{label} has no Coulomb friction to compensate"))?;
    friction.viscous = 0.0;
    friction.on_setpoint = false;
    let deg_per_count = 360.0 / (scale.motor_cpr() * scale.gear_ratio());
    let mut rows = vec![];
    let mut files = vec![];
    let mut holds: Vec<(f64, Vec<Row>)> = vec![];
    for u in UNDERS {
        let with = |mut sc: Scenario| {
            if u > 0.0 {
                let mut f = friction;
                f.under = u;
                sc.gains.friction = Some(f);
            }
            sc
        };
        let csv = out.join(format!("hold-u{u}.csv"));
        let held = held_step(model, seed, &csv, with)?;
        files.push(csv);
        let csv = out.join(format!("track-u{u}.csv"));
        let (rms, _, _) = track(model, seed, &csv, with)?;
        files.push(csv);
        rows.push(UnderRow {
            under: u,
            limit_cycle_counts: held.limit_cycle_counts,
            limit_cycle_deg: held.limit_cycle_counts * deg_per_count,
            hold_power_w: held.power_w,
            tracking_rms_rad: rms,
        });
        holds.push((u, held.rows));
    }
    let png = out.join(format!("coulomb-ff-{label}.png"));
    plot_holds(&png, label, &holds, scale.motor_cpr())?;
    files.push(png);
    let backlash_deg = model
        .effects
        .backlash
        .as_ref()
        .map_or(0.0, |b| b.width.value.to_degrees());
    Ok(Sweep {
        rows,
        coulomb: [friction.coulomb_pos, friction.coulomb_neg],
        backlash_deg,
        files,
    })
}

impl Sweep {
    /// The table, with the thesis's finding beside it.
    pub fn table(&self) -> String {
        let mut s = format!(
            "  {:>6} {:>14} {:>12} {:>14} {:>16}\n",
            "under", "cycle (counts)", "cycle (°)", "hold power", "tracking RMS"
        );
        for r in &self.rows {
            let u = if r.under == 0.0 {
                "off".to_string()
            } else {
                format!("{:.1}", r.under)
            };
            s += &format!(
                "  {u:>6} {:>14} {:>12.4} {:>12.3e} W {:>12.3e} rad\n",
                r.limit_cycle_counts, r.limit_cycle_deg, r.hold_power_w, r.tracking_rms_rad
            );
        }
        s += &format!(
            "  thesis (§4, friction compensation): with backlash and high gain, a limit cycle \
             about the size of the lost motion (here {:.2}°); \"slightly below\" the friction \
             is safe; over-compensation injects energy\n",
            self.backlash_deg
        );
        s
    }
}

/// The held motor position (counts about its mean) for each factor: the thesis's limit-cycle
/// traces.
fn plot_holds(path: &Path, label: &str, holds: &[(f64, Vec<Row>)], cpr: f64) -> Result<()> {
    let counts = |r: &Row| r.motor_pos_rad / std::f64::consts::TAU * cpr;
    let centred: Vec<(f64, Vec<(f64, f64)>)> = holds
        .iter()
        .map(|(u, rows)| {
            let mean = rows.iter().map(counts).sum::<f64>() / rows.len().max(1) as f64;
            let t0 = rows.first().map_or(0.0, |r| r.time_s);
            (
                *u,
                rows.iter()
                    .map(|r| (r.time_s - t0, (counts(r) - mean).round()))
                    .collect(),
            )
        })
        .collect();
    let t1 = centred
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.0))
        .fold(1e-3, f64::max);
    let ext = centred
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1.abs()))
        .fold(2.0, f64::max)
        * 1.1;
    let colours = [BLACK, GREEN, BLUE, MAGENTA, RED];
    let lines = centred
        .into_iter()
        .zip(colours.iter().cycle())
        .map(|((u, points), colour)| Line {
            name: if u == 0.0 {
                "no feed-forward".to_string()
            } else {
                format!("under {u}")
            },
            colour: *colour,
            points,
        })
        .collect();
    line_chart(
        path,
        &format!("{label}: the held step with Coulomb feed-forward on the measured velocity"),
        ("time in the last 0.5 s of the hold (s)", 0.0..t1),
        ("motor position about its mean (counts)", -ext..ext),
        lines,
    )
}
