//! `demo --scenario backlash-cycle`: the thesis's backlash limit cycle (§3.3, discrete PD
//! inside the backlash zone). Gains tuned for the engaged joint are outside the discrete PD
//! region of the rotor alone, which is all the motor drives while it crosses the gap; it
//! overshoots into the far flank, is caught by the engaged inertia, and goes back: a cycle
//! whose amplitude grows with the gap's width, and which a preload beyond about τb = Kd·ε
//! (the gain times the gap) holds on one flank.
//!
//! The presets cannot show it as they are: they put the whole assumed input inertia
//! (1.875e-3 kg·m²) on the motor side of the gap, so the inertia changes by 3 % (cyclo-29)
//! or 27 % (kamo-ball-10) across it where the thesis's changes "≈10×", and their transmission spring is soft enough that the
//! rotor against it is a mode of its own. The experiment's joint is the preset with the
//! thesis's rotor of Fig 3.3.21 (1e-5 kg·m²) alone before the gap, the load beyond it, and the
//! transmission as a stiff contact (the engaged joint the analysis treats as rigid). Friction,
//! ripple and cogging are off: §3.3's plant is the bare inertia.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use plotters::style::colors::{BLACK, BLUE, GREEN, MAGENTA, RED};
use rayon::prelude::*;
use sim_plant::effects::backlash;
use sim_plant::{Model, Param};

use super::plot::{line_chart, Line};
use super::recorder::{read_rows, Row};
use super::scenario::{Scenario, ScenarioKind};
use super::{Lab, LabOptions};

/// The rotor before the gap, kg·m² (the thesis's Fig 3.3.21).
pub const ROTOR_INERTIA: f64 = 1e-5;
/// The contact's stiffness at the motor, N·m/rad: fifty times the thesis's high gain at the
/// motor of the 10:1 joint (39 N·m/rad), so that the engaged joint is rigid to the controller.
const CONTACT_STIFFNESS: f64 = 2000.0;
/// The contact's damping ratio (rotor against the contact).
const CONTACT_ZETA: f64 = 0.1;
/// The plant's substep rate, Hz: 45 substeps a period of the contact's mode (2.3 kHz).
const SUBSTEP_HZ: f64 = 100_000.0;
/// The thesis's high-gain test, N·m/deg at the output.
pub const GAIN_NM_PER_DEG: f64 = 68.0;
/// Gap widths of the width sweep, output degrees.
pub const WIDTHS_DEG: [f64; 6] = [0.0, 0.1, 0.2, 0.4, 0.8, 1.1];
/// Preloads of the preload sweep, as shares of τb = Kd·ε (those the motor can hold).
pub const PRELOAD_SHARES: [f64; 8] = [0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0];
/// Seconds of hold after the tap that the cycle is measured over (the last one).
const MEASURE_S: f64 = 1.0;

/// The joint of §3.3 built from `preset`: the rotor alone before a gap of `gap_deg` (the
/// preset's own when `None`), the load beyond it, a stiff contact, no friction.
pub fn joint(preset: &Model, gap_deg: Option<f64>) -> Result<Model> {
    let mut m = preset.clone();
    let n = m.plant.gear_ratio.value;
    m.name = format!("{}-thesis-rotor", preset.name);
    m.motor.inertia = Param::fixed(ROTOR_INERTIA);
    m.motor.damping = Param::fixed(0.0);
    let k = CONTACT_STIFFNESS * n * n;
    let c = m
        .effects
        .compliance
        .as_mut()
        .ok_or_else(|| anyhow!("{} has no transmission spring", preset.name))?;
    c.stiffness = Param::fixed(k);
    c.soft_stiffness = Param::fixed(0.0);
    c.knee = Param::fixed(0.0);
    c.damping =
        Param::fixed(2.0 * CONTACT_ZETA * (CONTACT_STIFFNESS * ROTOR_INERTIA).sqrt() * n * n);
    if let Some(g) = gap_deg {
        m.effects.backlash = (g > 0.0).then(|| backlash::Params {
            width: Param::fixed(g.to_radians()),
        });
    }
    let e = &mut m.effects;
    (e.coulomb, e.stribeck, e.viscous, e.asymmetry) = (None, None, None, None);
    (e.ripple, e.cogging) = (None, None);
    Ok(m)
}

/// One hold: the cycle the tap leaves going.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Cycle {
    /// The gap, output degrees.
    pub gap_deg: f64,
    /// The constant torque on the output, N·m.
    pub preload_nm: f64,
    /// The motor's peak-to-peak over the last second, output degrees (motor ÷ N).
    pub motor_pp_deg: f64,
    /// The same in motor encoder counts.
    pub counts: f64,
    /// Share of those ticks at the torque limit.
    pub saturated: f64,
}

/// The high-gain hold on `model`: the backlash scenario's tap, at [`GAIN_NM_PER_DEG`]
/// (damping kd = 0.5 on the engaged inertia), with `preload` on the output.
pub fn hold(model: &Model, preload: f64, seed: u64, csv: &Path) -> Result<Cycle> {
    let mut sc = Scenario::new(ScenarioKind::Backlash, model)?;
    sc.gains.stiffness = GAIN_NM_PER_DEG.to_degrees();
    sc.set_preload(preload);
    let opts = LabOptions {
        seed,
        substep_rate: SUBSTEP_HZ,
        ..LabOptions::default()
    };
    let limit = sc.gains.torque_limit;
    let end = sc.streaming_s();
    let mut lab = Lab::new(model, sc, &opts)?;
    lab.recorder.write_csv(csv)?;
    lab.run(|_, _| {})?;
    let rows = read_rows(csv)?.collect::<Result<Vec<Row>>>()?;
    let late: Vec<&Row> = rows
        .iter()
        .filter(|r| r.time_s > end - MEASURE_S && r.time_s <= end)
        .collect();
    if late.is_empty() {
        return Err(anyhow!("the hold recorded nothing in its last second"));
    }
    let n = model.plant.gear_ratio.value;
    let (lo, hi) = late
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
            (a.min(r.motor_pos_rad), b.max(r.motor_pos_rad))
        });
    let per_count = std::f64::consts::TAU / model.motor.counts_per_rev.value;
    let saturated = late
        .iter()
        .filter(|r| r.torque_cmd_nm.abs() >= 0.99 * limit)
        .count() as f64
        / late.len() as f64;
    Ok(Cycle {
        gap_deg: model
            .effects
            .backlash
            .as_ref()
            .map_or(0.0, |b| b.width.value.to_degrees()),
        preload_nm: preload,
        motor_pp_deg: ((hi - lo) / n).to_degrees(),
        counts: ((hi - lo) / per_count).round(),
        saturated,
    })
}

/// What the experiment measured on one preset.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Experiment {
    /// Preset.
    pub preset: String,
    /// Engaged over rotor inertia across the gap.
    pub inertia_ratio: f64,
    /// The thesis's gain at the motor, N·m/rad, against the rotor's discrete bound
    /// 0.686·I/T² (§3.3) and the engaged joint's.
    pub gain_motor: f64,
    /// 0.686·I/T² of the rotor alone, N·m/rad.
    pub rotor_bound: f64,
    /// 0.686·I/T² of the engaged joint, N·m/rad.
    pub engaged_bound: f64,
    /// The cycle vs the gap's width (no preload).
    pub widths: Vec<Cycle>,
    /// The gap the preload sweep holds: the preset's own, or, where the motor could not hold
    /// τb of that, the smaller of 0.2° and the widest whose τb it can.
    pub preload_gap_deg: f64,
    /// τb = Kd·ε for that gap, output N·m.
    pub tau_b: f64,
    /// The cycle vs the preload.
    pub preloads: Vec<Cycle>,
    /// The preset's own gap, with the thesis's rotor (the row the thesis's table compares).
    pub own: Cycle,
}

/// Runs the width and preload sweeps on `preset` (in parallel).
pub fn run(preset: &Model, label: &str, seed: u64, out: &Path) -> Result<Experiment> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let n = preset.plant.gear_ratio.value;
    let own_gap = preset
        .effects
        .backlash
        .as_ref()
        .map_or(0.0, |b| b.width.value.to_degrees());
    let kd_rad = GAIN_NM_PER_DEG.to_degrees();
    // The motor must hold the preload: τb above 80 % of what it can give moves the sweep to
    // a narrower gap.
    let reach = 0.8 * preset.motor.max_torque.value * n;
    let preload_gap = if own_gap > 0.0 && kd_rad * own_gap.to_radians() <= reach {
        own_gap
    } else {
        (reach / kd_rad).to_degrees().min(0.2)
    };
    let tau_b = kd_rad * preload_gap.to_radians();
    let mut jobs: Vec<(Option<f64>, f64)> = WIDTHS_DEG.iter().map(|&g| (Some(g), 0.0)).collect();
    let preloads: Vec<f64> = PRELOAD_SHARES
        .iter()
        .map(|s| s * tau_b)
        .filter(|p| *p <= reach)
        .collect();
    jobs.extend(preloads.iter().map(|&p| (Some(preload_gap), p)));
    jobs.push((None, 0.0));
    let cycles: Vec<Cycle> = jobs
        .par_iter()
        .enumerate()
        .map(|(i, &(gap, pre))| {
            let m = joint(preset, gap)?;
            let csv = out.join(format!("backlash-cycle-{label}-{i}.csv"));
            let c = hold(&m, pre, seed, &csv);
            let _ = std::fs::remove_file(&csv);
            c
        })
        .collect::<Result<_>>()?;
    let engaged = ROTOR_INERTIA + preset.plant.output_inertia.value / (n * n);
    let bound = |i: f64| 0.686 * i / 1e-6;
    let w = WIDTHS_DEG.len();
    Ok(Experiment {
        preset: label.to_string(),
        inertia_ratio: engaged / ROTOR_INERTIA,
        gain_motor: kd_rad / (n * n),
        rotor_bound: bound(ROTOR_INERTIA),
        engaged_bound: bound(engaged),
        widths: cycles[..w].to_vec(),
        preload_gap_deg: preload_gap,
        tau_b,
        preloads: cycles[w..w + preloads.len()].to_vec(),
        own: cycles[cycles.len() - 1],
    })
}

impl Experiment {
    /// The two sweeps as text.
    pub fn table(&self) -> String {
        let mut s = format!(
            "  rotor 1e-5 kg·m² before the gap, engaged {:.0}× that; the gain at the motor {:.1} \
             N·m/rad against the discrete bound 0.686·I/T² of the rotor {:.1} and of the \
             engaged joint {:.0}\n",
            self.inertia_ratio, self.gain_motor, self.rotor_bound, self.engaged_bound
        );
        s += &format!(
            "  {:>10} {:>14} {:>8} {:>10}\n",
            "gap (°)", "motor p-p (°)", "counts", "saturated"
        );
        for c in &self.widths {
            s += &format!(
                "  {:>10} {:>14.3} {:>8} {:>9.0}%\n",
                c.gap_deg,
                c.motor_pp_deg,
                c.counts,
                100.0 * c.saturated
            );
        }
        s += &format!(
            "  preload on the output, gap {:.2}°, τb = Kd·ε = {:.1} N·m\n",
            self.preload_gap_deg, self.tau_b
        );
        s += &format!(
            "  {:>10} {:>8} {:>14} {:>8} {:>10}\n",
            "preload", "÷ τb", "motor p-p (°)", "counts", "saturated"
        );
        for c in &self.preloads {
            s += &format!(
                "  {:>10.2} {:>8.2} {:>14.3} {:>8} {:>9.0}%\n",
                c.preload_nm,
                c.preload_nm / self.tau_b,
                c.motor_pp_deg,
                c.counts,
                100.0 * c.saturated
            );
        }
        s
    }
}

/// The plots in `out`: the cycle's amplitude against the gap's width, and against the
/// preload over τb.
pub fn plot(out: &Path, runs: &[Experiment]) -> Result<Vec<PathBuf>> {
    let colours = [RED, BLUE, GREEN, MAGENTA, BLACK];
    let lines = |f: &dyn Fn(&Experiment) -> Vec<(f64, f64)>| -> (Vec<Line>, f64) {
        let mut y_max: f64 = 0.1;
        let l = runs
            .iter()
            .zip(colours)
            .map(|(e, colour)| {
                let points = f(e);
                y_max = points.iter().map(|q| q.1).fold(y_max, f64::max);
                Line {
                    name: e.preset.clone(),
                    colour,
                    points,
                }
            })
            .collect();
        (l, y_max)
    };
    let (w, wy) = lines(&|e| {
        e.widths
            .iter()
            .map(|c| (c.gap_deg, c.motor_pp_deg))
            .collect()
    });
    let widths = out.join("backlash-cycle-width.png");
    let w_max = WIDTHS_DEG.iter().cloned().fold(0.0, f64::max);
    line_chart(
        &widths,
        "Backlash limit cycle at 68 N·m/deg vs the gap's width (thesis rotor before the gap)",
        ("gap width, output °", 0.0..w_max * 1.05),
        ("motor peak-to-peak, output °", 0.0..wy * 1.15),
        w,
    )?;
    let (p, py) = lines(&|e| {
        e.preloads
            .iter()
            .map(|c| (c.preload_nm / e.tau_b.max(1e-9), c.motor_pp_deg))
            .collect()
    });
    let preloads = out.join("backlash-cycle-preload.png");
    let p_max = PRELOAD_SHARES.iter().cloned().fold(0.0, f64::max);
    line_chart(
        &preloads,
        "Backlash limit cycle vs a preload on the output, in units of τb = Kd·ε",
        ("preload ÷ τb", 0.0..p_max * 1.05),
        ("motor peak-to-peak, output °", 0.0..py * 1.15),
        p,
    )?;
    Ok(vec![widths, preloads])
}

/// The presets the thesis names for its high-gain test: the two with backlash, and the cable,
/// which "never cycles".
pub const PRESETS: [&str; 2] = ["cyclo-29", "kamo-ball-10"];
/// The preset without backlash.
pub const NO_GAP: &str = "whoi-cable-30";

/// The cable's hold with the thesis's rotor: it has no gap to cycle in.
pub fn no_gap(seed: u64, out: &Path) -> Result<Cycle> {
    let preset = sim_plant::presets::preset(NO_GAP).ok_or_else(|| anyhow!("no preset {NO_GAP}"))?;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let csv = out.join(format!("backlash-cycle-{NO_GAP}.csv"));
    let c = hold(&joint(&preset, None)?, 0.0, seed, &csv);
    let _ = std::fs::remove_file(&csv);
    c
}
