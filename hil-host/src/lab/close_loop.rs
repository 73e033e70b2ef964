//! `demo --scenario compensate`: the workbench's finding compensated on the card, and the
//! tracking error measured without and with it. Identify (a chirp under colocated PD) →
//! `diagnose --auto` on the recording → [`Compensation`] → the same tasks twice.
//!
//! The tasks and their figures are the thesis's (§5): a position trajectory (tracking RMS and
//! peak error), a step held at its end (steady-state error and the limit cycle's peak-to-peak
//! in motor encoder counts) and a stiffness-emulation crank cycle (loop area, the work lost
//! per cycle).

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context, Result};
use jointlab_workbench::data::{self, Columns};
use jointlab_workbench::diagnose::Options;
use jointlab_workbench::model::Model as WbModel;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;
use jointlab_workbench::units::eng;
use sim_plant::Model;

use super::compensate::Compensation;
use super::recorder::{read_rows, Row};
use super::scenario::{Scenario, ScenarioKind, SETTLE_S};
use super::trajectory::Trajectory;
use super::{Lab, LabOptions};

/// The figures of one set of tasks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Figures {
    /// Tracking error RMS over the trajectory, output rad.
    pub tracking_rms: f64,
    /// Largest tracking error, output rad.
    pub peak_error: f64,
    /// Mean error over the last 0.5 s of the held step, output rad.
    pub steady_state: f64,
    /// Peak-to-peak of the motor encoder over the last 0.5 s of the held step, counts.
    pub limit_cycle_counts: f64,
    /// Work lost per stiffness-emulation cycle, J.
    pub loop_area: f64,
}

/// What the scenario did, for the table and the tests.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Without compensation.
    pub before: Figures,
    /// With it.
    pub after: Figures,
    /// The model's (mean of the two directions), N·m at the motor.
    pub model_coulomb: f64,
    /// The held step's limit cycle (motor counts p-p) with the friction compensated on the
    /// measured velocity instead, at under-compensation 1 and at the one asked for.
    pub hold: [(f64, f64); 2],
    /// The compensation applied.
    pub compensation: Compensation,
    /// The model `diagnose --auto` wrote.
    pub model_file: PathBuf,
    /// Effects `--auto` added, in order.
    pub added: Vec<String>,
    /// Every file written.
    pub files: Vec<PathBuf>,
}

impl Outcome {
    /// Why the compensation must not be kept, if it must not: it made tracking worse, or it
    /// took more of the emulated spring's loss away than friction compensated at `under`
    /// can (that loss is friction plus the damping asked for, and `under` leaves at least
    /// 1 − under of the friction's: half that margin is allowed for the fit's scatter).
    pub fn refusal(&self, under: f64) -> Option<String> {
        let (b, a) = (&self.before, &self.after);
        if a.tracking_rms > b.tracking_rms {
            return Some(format!(
                "the compensation made tracking worse ({} → {} rad RMS): the model does not \
                 describe this joint",
                eng(b.tracking_rms),
                eng(a.tracking_rms)
            ));
        }
        let floor = 0.5 * (1.0 - under) * b.loop_area;
        if a.loop_area < floor {
            return Some(format!(
                "the compensation took the emulated spring's loss from {} to {} J, below the \
                 {} J that friction compensated at {under} leaves: the model's friction is \
                 more than the joint's (over-compensation injects energy); refused",
                eng(b.loop_area),
                eng(a.loop_area),
                eng(floor)
            ));
        }
        None
    }

    /// The before/after table.
    pub fn table(&self) -> String {
        let b = &self.before;
        let a = &self.after;
        let rows: [(&str, f64, f64, &str); 5] = [
            (
                "tracking error RMS",
                b.tracking_rms,
                a.tracking_rms,
                "rad (output)",
            ),
            (
                "peak tracking error",
                b.peak_error,
                a.peak_error,
                "rad (output)",
            ),
            (
                "steady-state error",
                b.steady_state,
                a.steady_state,
                "rad (output)",
            ),
            (
                "limit cycle p-p",
                b.limit_cycle_counts,
                a.limit_cycle_counts,
                "counts (motor)",
            ),
            ("stiffness loop area", b.loop_area, a.loop_area, "J"),
        ];
        let mut s = format!(
            "  {:<24} {:>12} {:>12} {:>9}\n",
            "", "before", "after", "change"
        );
        for (name, x, y, unit) in rows {
            let change = if x.abs() > 0.0 {
                format!("{:+.0} %", 100.0 * (y - x) / x.abs())
            } else {
                String::new()
            };
            s += &format!(
                "  {name:<24} {:>12} {:>12} {change:>9}  {unit}\n",
                eng(x),
                eng(y)
            );
        }
        s
    }
}

/// The stiffness emulation's damping, as a share of the stiffness scenario's (ζ ≈ 0.7).
const SPRING_DAMPING: f64 = 0.3;

/// Seconds of the tracking trajectory's motion.
const TRACK_S: f64 = 8.0;

/// The tracking trajectory: a triangle at 0.1 rad/s between ±0.2 rad (constant speeds, as in
/// the thesis's crank tests, where friction rather than inertia makes the error), then a
/// hold at 0.
fn tracking() -> Trajectory {
    Trajectory::Samples(vec![
        (0.0, 0.0),
        (2.0, 0.2),
        (6.0, -0.2),
        (TRACK_S, 0.0),
        (TRACK_S + 1.0, 0.0),
    ])
}

/// Seconds of the identification run.
const IDENTIFY_S: f64 = 23.0;

/// The identification trajectory: back and forth over ±0.15 rad at 0.05, 0.1, 0.2 and
/// 0.4 rad/s (friction is read at constant speeds, as the thesis measured its Table 4.1), with
/// a 5 mrad, 3 Hz dither on top (the accelerations that separate inertia from friction).
fn identification() -> Trajectory {
    let tri = Trajectory::Samples(identification_corners());
    let n = (IDENTIFY_S / 0.002) as usize;
    Trajectory::Samples(
        (0..=n)
            .map(|k| {
                let t = k as f64 * 0.002;
                (t, tri.at(t) + 0.005 * (TAU * 3.0 * t).sin())
            })
            .collect(),
    )
}

/// The identification triangle's corners (time, output rad).
fn identification_corners() -> Vec<(f64, f64)> {
    let a = 0.15;
    let mut corners = vec![(0.0, 0.0)];
    let mut t = 0.0;
    for v in [0.05, 0.1, 0.2, 0.4] {
        for (to, dist) in [(a, a), (-a, 2.0 * a), (0.0, a)] {
            t += dist / v;
            corners.push((t, to));
        }
    }
    corners
}

/// Runs `sc` on `model` to the end, writing its recording to `csv`; returns the rows.
pub(super) fn run(model: &Model, sc: Scenario, seed: u64, csv: &Path) -> Result<(Vec<Row>, Lab)> {
    let opts = LabOptions {
        seed,
        ..LabOptions::default()
    };
    let mut lab = Lab::new(model, sc, &opts)?;
    lab.recorder.write_csv(csv)?;
    lab.run(|_, _| {})?;
    let rows = read_rows(csv)?.collect::<Result<Vec<Row>>>()?;
    Ok((rows, lab))
}

/// The tasks with `comp` on the card (None: without), their recordings in `out` tagged
/// `tag`; returns the figures and the tracking run's rows.
pub fn tasks(
    model: &Model,
    comp: Option<&Compensation>,
    seed: u64,
    out: &Path,
    tag: &str,
    files: &mut Vec<PathBuf>,
) -> Result<(Figures, Vec<Row>)> {
    // A position task's friction is compensated on its reference velocity (the supervisor
    // sends it): nothing is added at a hold, so nothing can hunt there. The emulated spring,
    // whose motion comes from outside, on the measured one.
    let with = |mut sc: Scenario, on_setpoint: bool| {
        if let Some(c) = comp {
            let mut c = c.clone();
            if on_setpoint {
                if let Some(f) = &mut c.friction {
                    f.on_setpoint = true;
                }
            } else {
                c.within_damping(&sc.gains);
            }
            sc.gains.friction = c.friction;
            sc.gains.feedforward = c.feedforward;
        }
        sc
    };
    let mut f = Figures::default();
    let csv = out.join(format!("track-{tag}.csv"));
    let (rms, peak, track) = track(model, seed, &csv, |sc| with(sc, true))?;
    files.push(csv);
    f.tracking_rms = rms;
    f.peak_error = peak;
    // A step held at its end: steady-state error and the limit cycle.
    let held = held_step(model, seed, &out.join(format!("step-{tag}.csv")), |sc| {
        with(sc, true)
    })?;
    files.push(out.join(format!("step-{tag}.csv")));
    f.steady_state = held.steady_state;
    f.limit_cycle_counts = held.limit_cycle_counts;
    // Stiffness emulation against the crank.
    // A spring, lightly damped (ζ ≈ 0.2 instead of the scenario's 0.7): the loop's area is
    // then the transmission's friction, not the damping asked for.
    let mut sc = Scenario::new(ScenarioKind::Stiffness, model)?;
    sc.gains.damping *= SPRING_DAMPING;
    let csv = out.join(format!("stiffness-{tag}.csv"));
    let (_, mut lab) = run(model, with(sc, false), seed, &csv).context("the stiffness cycle")?;
    files.push(csv);
    f.loop_area = lab
        .summary()?
        .get("loop area (work lost)")
        .unwrap_or(f64::NAN);
    Ok((f, track))
}

/// The tracking task (the constant-speed triangle at the thesis's high stiffness, the
/// supervisor sending the reference velocity), its gains set by `with`: the tracking error's
/// RMS and peak (output rad) while the reference moves, and the rows.
pub(super) fn track(
    model: &Model,
    seed: u64,
    csv: &Path,
    with: impl FnOnce(Scenario) -> Scenario,
) -> Result<(f64, f64, Vec<Row>)> {
    let mut sc = Scenario::new(ScenarioKind::Identify, model)?;
    let high = Scenario::new(ScenarioKind::Step, model)?;
    sc.gains.stiffness = high.gains.stiffness;
    sc.gains.damping = high.gains.damping;
    sc.trajectory = tracking();
    sc.duration_s = TRACK_S + 1.0;
    sc.velocity_ff = true;
    let (rows, lab) = run(model, with(sc), seed, csv).context("the tracking task")?;
    let t0 = lab.supervisor.trajectory_start_s().unwrap_or(0.0);
    let moving: Vec<&Row> = rows
        .iter()
        .filter(|r| r.time_s > t0 + 0.05 && r.time_s < t0 + TRACK_S)
        .collect();
    let err = |r: &Row| r.setpoint_pos_rad - r.output_pos_rad;
    let rms =
        (moving.iter().map(|r| err(r).powi(2)).sum::<f64>() / moving.len().max(1) as f64).sqrt();
    let peak = moving.iter().map(|r| err(r).abs()).fold(0.0, f64::max);
    Ok((rms, peak, rows))
}

/// The held step's figures over its last 0.5 s.
#[derive(Clone, Debug, Default)]
pub(super) struct Held {
    /// Mean error, output rad.
    pub steady_state: f64,
    /// The motor encoder's peak-to-peak, counts.
    pub limit_cycle_counts: f64,
    /// Mean power the motor puts into the mechanism, W: zero at rest, what a limit cycle
    /// dissipates while the card sustains it.
    pub power_w: f64,
    /// The rows of the hold.
    pub rows: Vec<Row>,
}

/// The step scenario held at its end, its gains set by `with`.
pub(super) fn held_step(
    model: &Model,
    seed: u64,
    csv: &Path,
    with: impl FnOnce(Scenario) -> Scenario,
) -> Result<Held> {
    let sc = Scenario::new(ScenarioKind::Step, model)?;
    let cpr = sc.scale.motor_cpr();
    let end = SETTLE_S + sc.duration_s;
    let (rows, _) = run(model, with(sc), seed, csv).context("the step")?;
    let held: Vec<Row> = rows.into_iter().filter(|r| r.time_s > end - 0.5).collect();
    if held.is_empty() {
        return Ok(Held::default());
    }
    let n = held.len() as f64;
    let steady = held
        .iter()
        .map(|r| r.setpoint_pos_rad - r.output_pos_rad)
        .sum::<f64>()
        / n;
    let (lo, hi) = held
        .iter()
        .map(|r| (r.motor_pos_rad / TAU * cpr).round())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), c| {
            (a.min(c), b.max(c))
        });
    let power_w = held
        .iter()
        .map(|r| r.torque_cmd_nm * r.motor_vel_rad_s)
        .sum::<f64>()
        / n;
    Ok(Held {
        steady_state: steady,
        limit_cycle_counts: hi - lo,
        power_w,
        rows: held,
    })
}

/// The thesis's §5 hazard of compensating on the measured velocity at a high-gain hold:
/// the limit cycle (motor counts p-p) of the held step with `comp`'s friction on the
/// measured velocity at under-compensation 1 and at `under`.
pub fn hold_limit_cycles(
    model: &Model,
    comp: &Compensation,
    under: f64,
    seed: u64,
    out: &Path,
) -> Result<[(f64, f64); 2]> {
    let mut r = [(1.0, 0.0), (under, 0.0)];
    for (u, lc) in r.iter_mut() {
        let csv = out.join(format!("hold-u{u}.csv"));
        let held = held_step(model, seed, &csv, |mut sc| {
            let mut c = comp.clone();
            if let Some(f) = &mut c.friction {
                f.under = *u;
            }
            c.within_damping(&sc.gains);
            sc.gains.friction = c.friction;
            sc
        })?;
        *lc = held.limit_cycle_counts;
    }
    Ok(r)
}

/// Identify, diagnose, compensate, compare. `out` receives the recordings, the model and
/// the plot.
pub fn run_all(
    model: &Model,
    label: &str,
    seed: u64,
    under: f64,
    given: Option<&Path>,
    out: &Path,
    mut progress: impl FnMut(&str),
) -> Result<Outcome> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut files = vec![];
    // 1. identify
    progress("identify: constant speeds both ways, with a dither, under colocated PD");
    let mut sc = Scenario::new(ScenarioKind::Identify, model)?;
    sc.trajectory = identification();
    sc.duration_s = IDENTIFY_S;
    // The thesis's "high" stiffness (as the step's): the joint must move through its
    // friction for the record to show it, and at the medium stiffness a 60:1 cycloid's
    // 19 N·m of friction holds it still.
    let step = Scenario::new(ScenarioKind::Step, model)?;
    sc.gains.stiffness = step.gains.stiffness;
    sc.gains.damping = step.gains.damping;
    let csv = out.join(format!("identify-{label}.csv"));
    let scale = sc.scale;
    run(model, sc, seed, &csv).context("the identification run")?;
    files.push(csv.clone());
    // 2. diagnose --auto (or the model given)
    let (wb, added, model_file) = match given {
        Some(f) => (WbModel::load(f)?, vec![], f.to_path_buf()),
        None => {
            progress("diagnose --auto: which effects the recording needs");
            let rec = data::load(&csv, &Columns::new("torque_cmd_Nm", "motor_pos_rad"))?;
            // Identified in the card's velocity-observer band, the band the compensation will
            // act in: the card's 2304-count encoder would set a 10 Hz default, where a
            // friction sign taken from the filtered velocity of a 2 Hz chirp is no longer the
            // sign the card switches on (the fitted levels then compensate worse).
            let band = controller::card::config::OBSERVER_BANDWIDTH_HZ;
            let p = Prepared::checked(&rec, Some(band)).map_err(|e| anyhow!("{e:?}"))?;
            let mut wb = WbModel::baseline();
            wb.on_axis(p.axis, &p.input_unit)?;
            let auto = refine::auto(&mut wb, &p, None, &Options::default(), 6)?;
            let added = auto.steps.iter().filter_map(|s| s.added.clone()).collect();
            let model_file = out.join(format!("model-{label}.toml"));
            wb.save(&model_file)?;
            files.push(model_file.clone());
            (wb, added, model_file)
        }
    };
    // 3. compensate
    let compensation = Compensation::from_model(&wb.to_sim(), &scale, under)
        .with_context(|| format!("compensating {}", model_file.display()))?;
    let model_coulomb = compensation.friction.map_or(0.0, |f| {
        0.5 * (f.coulomb_pos + f.coulomb_neg) / scale.gear_ratio()
    });
    // 4. the tasks, without and with
    progress("tasks without compensation");
    let (before, rows_b) = tasks(model, None, seed, out, "before", &mut files)?;
    progress("tasks with compensation");
    let (after, rows_a) = tasks(model, Some(&compensation), seed, out, "after", &mut files)?;
    progress("the hold with friction compensated on the measured velocity");
    let hold = hold_limit_cycles(model, &compensation, under, seed, out)?;
    let png = out.join(format!("compensate-{label}.png"));
    super::plot::plot_before_after(
        &png,
        &format!("tracking on {label}: without and with compensation"),
        &rows_b,
        &rows_a,
    )?;
    files.push(png);
    Ok(Outcome {
        before,
        after,
        model_coulomb,
        hold,
        compensation,
        model_file,
        added,
        files,
    })
}
