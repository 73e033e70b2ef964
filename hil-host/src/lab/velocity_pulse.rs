//! `demo --scenario velocity-pulse`: the machine-tool paper's validation experiment on the
//! lab. The card runs its velocity loop (PI on the motor velocity); from rest the supervisor
//! steps the speed setpoint negative and back to zero after 1 s. Motor and load velocity are
//! compared; the paper found the load's response after the two steps "quite different". Here
//! each step's load response is measured (delay to half the step, overshoot, settling), so the
//! asymmetry is a number per transmission: a gap must be crossed before the load follows the
//! start, and friction stops the load at the end.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use controller::proto::Mode;
use plotters::style::colors::{BLACK, BLUE, RED};
use sim_plant::Model;

use super::plot::{line_chart, Line};
use super::recorder::Row;
use super::scenario::{Scenario, ScenarioKind};
use super::trajectory::Trajectory;

/// The pulse's speed, output rad/s (negative, as the paper's).
pub const PULSE_SPEED: f64 = -0.5;
/// The pulse's length, s.
pub const PULSE_S: f64 = 1.0;
/// Rest before the pulse, s (from the trajectory's start, when the card is enabled).
const LEAD_S: f64 = 0.3;
/// Time after the pulse's end, s.
const TAIL_S: f64 = 0.7;
/// The velocity loop's bandwidth on the joint's whole inertia, Hz.
const LOOP_HZ: f64 = 10.0;

/// One step's load response.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StepResponse {
    /// From the setpoint's step until the load has covered half the step, s.
    pub delay_s: f64,
    /// The load's overshoot beyond the new speed, as a share of the step.
    pub overshoot: f64,
    /// From the setpoint's step until the load stays within 10 % of the step of the new
    /// speed, s (the window's end if never).
    pub settle_s: f64,
}

/// What the pulse measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Pulse {
    /// Preset or model label.
    pub label: String,
    /// The load after the start step (0 → pulse speed).
    pub start: StepResponse,
    /// The load after the stop step (pulse speed → 0).
    pub stop: StepResponse,
    /// The motor (÷ N) after the start step, for comparison.
    pub motor_start: StepResponse,
    /// The motor (÷ N) after the stop step.
    pub motor_stop: StepResponse,
    /// The motor's mean velocity (÷ N) over the pulse's second half, output rad/s.
    pub motor_mean: f64,
    /// The model's backlash, output rad (0: none).
    pub backlash_rad: f64,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// The scenario: velocity mode, Kv and Ki for a 10 Hz loop on the joint's inertia,
/// the speed pulse as the trajectory's velocity.
pub fn scenario(model: &Model) -> Result<Scenario> {
    let mut sc = Scenario::new(ScenarioKind::Identify, model)?;
    let n = sc.scale.gear_ratio();
    let j = sc.scale.rotor_inertia * n * n + model.plant.output_inertia.value;
    let w = TAU * LOOP_HZ;
    sc.mode = Mode::Velocity;
    sc.gains.damping = j * w; // Kv, output N·m·s/rad
    sc.gains.stiffness = j * w * w / 4.0; // Ki, output N·m/rad
    sc.gains.integral = 0.0;
    sc.gains.integrator_limit = 0.5 * model.motor.max_torque.value;
    sc.gains.velocity_limit = sc.gains.velocity_limit.max(4.0 * PULSE_SPEED.abs());
    let t0 = LEAD_S;
    let t1 = t0 + PULSE_S;
    sc.trajectory = Trajectory::Samples(vec![
        (0.0, 0.0),
        (t0, 0.0),
        (t1, PULSE_SPEED * PULSE_S),
        (t1 + TAIL_S, PULSE_SPEED * PULSE_S),
    ]);
    sc.duration_s = t1 + TAIL_S;
    sc.velocity_ff = true;
    Ok(sc)
}

/// Runs the pulse on `model`; `out` receives the recording and the plot.
pub fn run(model: &Model, label: &str, seed: u64, out: &Path) -> Result<Pulse> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let sc = scenario(model)?;
    let n = sc.scale.gear_ratio();
    let csv = out.join(format!("velocity-pulse-{label}.csv"));
    let (rows, lab) =
        super::close_loop::run(model, sc, seed, &csv).context("the velocity pulse")?;
    let t_start = lab.supervisor.trajectory_start_s().unwrap_or(0.0) + LEAD_S;
    let t_stop = t_start + PULSE_S;
    let load = |r: &Row| r.output_vel_rad_s;
    let motor = |r: &Row| r.motor_vel_rad_s / n;
    let png = out.join(format!("velocity-pulse-{label}.png"));
    plot(&png, label, &rows, n, t_start)?;
    let held: Vec<f64> = rows
        .iter()
        .filter(|r| r.time_s >= t_start + 0.5 * PULSE_S && r.time_s < t_stop)
        .map(motor)
        .collect();
    let motor_mean = held.iter().sum::<f64>() / held.len().max(1) as f64;
    Ok(Pulse {
        label: label.to_string(),
        start: response(&rows, t_start, t_stop, 0.0, PULSE_SPEED, load),
        stop: response(&rows, t_stop, f64::INFINITY, PULSE_SPEED, 0.0, load),
        motor_start: response(&rows, t_start, t_stop, 0.0, PULSE_SPEED, motor),
        motor_stop: response(&rows, t_stop, f64::INFINITY, PULSE_SPEED, 0.0, motor),
        motor_mean,
        backlash_rad: model
            .effects
            .backlash
            .as_ref()
            .map_or(0.0, |b| b.width.value),
        files: vec![csv, png],
    })
}

/// The response of `v` to a setpoint step from `from` to `to` at `t0`, over [t0, t1).
fn response(
    rows: &[Row],
    t0: f64,
    t1: f64,
    from: f64,
    to: f64,
    v: impl Fn(&Row) -> f64,
) -> StepResponse {
    let step = to - from;
    let window: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.time_s >= t0 && r.time_s < t1)
        .map(|r| (r.time_s - t0, (v(r) - from) / step))
        .collect();
    let end = window.last().map_or(0.0, |w| w.0);
    let delay_s = window.iter().find(|w| w.1 >= 0.5).map_or(end, |w| w.0);
    let overshoot = window.iter().map(|w| w.1 - 1.0).fold(0.0, f64::max);
    // The first sample after the last one outside the band (0 if none was outside; the
    // window's end if the last sample still is).
    let settle_s = match window.iter().rposition(|w| (w.1 - 1.0).abs() > 0.1) {
        None => 0.0,
        Some(i) => window.get(i + 1).map_or(end, |w| w.0),
    };
    StepResponse {
        delay_s,
        overshoot,
        settle_s,
    }
}

impl Pulse {
    /// The table: each step's load and motor response side by side.
    pub fn table(&self) -> String {
        let mut s = format!(
            "  {:<24} {:>13} {:>12} {:>12}\n",
            "", "delay to ½", "overshoot", "settled"
        );
        for (name, r) in [
            ("load after the start", self.start),
            ("load after the stop", self.stop),
            ("motor/N after the start", self.motor_start),
            ("motor/N after the stop", self.motor_stop),
        ] {
            s += &format!(
                "  {name:<24} {:>10.1} ms {:>10.0} % {:>9.1} ms\n",
                1e3 * r.delay_s,
                100.0 * r.overshoot,
                1e3 * r.settle_s
            );
        }
        s
    }
}

/// Motor (÷ N) and load velocity against the setpoint's, the paper's Fig. 13.
fn plot(path: &Path, label: &str, rows: &[Row], n: f64, t_start: f64) -> Result<()> {
    let t1 = rows.iter().map(|r| r.time_s).fold(1e-3, f64::max);
    let vs: Vec<f64> = rows
        .iter()
        .flat_map(|r| [r.output_vel_rad_s, r.motor_vel_rad_s / n])
        .collect();
    let lo = vs.iter().copied().fold(PULSE_SPEED, f64::min) * 1.1;
    let hi = vs.iter().copied().fold(0.0, f64::max) + 0.1 * PULSE_SPEED.abs();
    let t_stop = t_start + PULSE_S;
    let setpoint = |t: f64| {
        if t >= t_start && t < t_stop {
            PULSE_SPEED
        } else {
            0.0
        }
    };
    let line = |name: &str, colour, f: &dyn Fn(&Row) -> f64| Line {
        name: name.to_string(),
        colour,
        points: rows.iter().map(|r| (r.time_s, f(r))).collect(),
    };
    line_chart(
        path,
        &format!("{label}: a {PULSE_S} s velocity pulse under the card's velocity loop"),
        ("time (s)", 0.0..t1),
        ("velocity (output rad/s)", lo..hi),
        vec![
            line("setpoint", BLACK, &|r| setpoint(r.time_s)),
            line("motor / N", BLUE, &|r| r.motor_vel_rad_s / n),
            line("load", RED, &|r| r.output_vel_rad_s),
        ],
    )
}
