//! Figures extracted from a recording: what the thesis measured on its rig.

use super::recorder::Row;
use super::scenario::{Scenario, ScenarioKind, SETTLE_S};

/// The summary table of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// (name, value, unit) in display order.
    pub rows: Vec<(String, f64, String)>,
}

impl Summary {
    fn push(&mut self, name: &str, v: f64, unit: &str) {
        self.rows.push((name.to_string(), v, unit.to_string()));
    }
    /// Value of a named figure.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.rows.iter().find(|r| r.0 == name).map(|r| r.1)
    }
    /// A plain-text table.
    pub fn table(&self) -> String {
        let w = self.rows.iter().map(|r| r.0.len()).max().unwrap_or(10);
        let mut s = String::new();
        for (n, v, u) in &self.rows {
            if v.is_nan() {
                // A figure that does not exist for this run (a step that ends outside its
                // settling band): say so instead of printing NaN.
                s.push_str(&format!("  {n:<w$}  {:>12}\n", "not reached"));
            } else if u.is_empty() && v.fract() == 0.0 && v.abs() < 1e9 {
                // A count (velocity reversals): no decimals to suggest a measurement.
                s.push_str(&format!("  {n:<w$}  {v:>6.0}\n"));
            } else {
                s.push_str(&format!("  {n:<w$}  {v:>12.5}  {u}\n"));
            }
        }
        s
    }
}

/// Least-squares line y = a + b·x; returns (a, b).
pub fn fit_line(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len().min(y.len()) as f64;
    if n < 2.0 {
        return (0.0, 0.0);
    }
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (my - b * mx, b)
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Computes the scenario's figures. `bus_load` is the measured exact-bit load (0..1).
pub fn summarize(sc: &Scenario, rows: &[Row], bus_load: f64, bus_load_worst: f64) -> Summary {
    let mut s = Summary::default();
    let n = sc.scale.gear_ratio;
    let run: Vec<&Row> = rows.iter().filter(|r| r.time_s > SETTLE_S).collect();
    let peak = rows
        .iter()
        .map(|r| r.torque_cmd_nm.abs())
        .fold(0.0, f64::max);
    // Tracking of the position setpoint by the motor encoder (colocated), output rad.
    let err = |r: &&Row| r.setpoint_pos_rad - r.motor_pos_rad / n;
    match sc.kind {
        ScenarioKind::Stiffness => {
            let crank: Vec<&&Row> = run.iter().filter(|r| r.time_s > SETTLE_S + 0.3).collect();
            let x: Vec<f64> = crank
                .iter()
                .map(|r| r.output_pos_rad - r.setpoint_pos_rad)
                .collect();
            let y: Vec<f64> = crank.iter().map(|r| -r.torque_sensor_nm).collect();
            let (_, k) = fit_line(&x, &y);
            s.push("desired stiffness", sc.desired, "N·m/rad (output)");
            s.push("achieved stiffness", k, "N·m/rad (output)");
            s.push("achieved / desired", k / sc.desired, "");
            // Loop area ∮τ dθ over the recording: energy lost per crank cycle.
            let area: f64 = crank
                .windows(2)
                .map(|w| {
                    let d = w[1].output_pos_rad - w[0].output_pos_rad;
                    -0.5 * (w[1].torque_sensor_nm + w[0].torque_sensor_nm) * d
                })
                .sum();
            s.push("loop area (work lost)", area, "J");
            let travel = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - x.iter().cloned().fold(f64::INFINITY, f64::min);
            s.push("deflection travel", travel, "rad (output)");
        }
        ScenarioKind::Damper => {
            // Mean torque and speed on the steady part of each 1 s crank segment.
            let (mut xs, mut ys) = (vec![], vec![]);
            for seg in 0..6 {
                let t0 = SETTLE_S + seg as f64 + 0.4;
                let t1 = SETTLE_S + seg as f64 + 0.95;
                let part: Vec<&&Row> = run
                    .iter()
                    .filter(|r| r.time_s > t0 && r.time_s < t1)
                    .collect();
                if part.is_empty() {
                    continue;
                }
                let m = part.len() as f64;
                xs.push(part.iter().map(|r| r.output_vel_rad_s).sum::<f64>() / m);
                ys.push(part.iter().map(|r| -r.torque_sensor_nm).sum::<f64>() / m);
            }
            // Split Coulomb (sign) from viscous by fitting τ = c·sign(ω) + B·ω.
            let (b, c) = fit_viscous_coulomb(&xs, &ys);
            s.push("desired damping", sc.desired, "N·m·s/rad (output)");
            s.push("achieved damping", b, "N·m·s/rad (output)");
            s.push("achieved / desired", b / sc.desired, "");
            s.push("Coulomb offset", c, "N·m (output)");
        }
        ScenarioKind::Step => {
            let target = run.last().map(|r| r.setpoint_pos_rad).unwrap_or(0.0);
            let pos = |r: &Row| r.motor_pos_rad / n;
            // The step instant: the first sample whose setpoint is nearer the target than the
            // start; the response starts from where the joint was one sample before.
            let k_step = rows
                .iter()
                .position(|r| (r.setpoint_pos_rad - target).abs() < 0.5 * target.abs())
                .unwrap_or(0);
            let from_step = rows.get(k_step..).unwrap_or_default();
            let start = rows.get(k_step.saturating_sub(1)).map_or(0.0, pos);
            let t0 = from_step.first().map_or(0.0, |r| r.time_s);
            // The value the response ends at (mean of the last 0.2 s): a PD against friction
            // stops short of the setpoint, so "settled" and "at the setpoint" differ.
            let tail: Vec<f64> = from_step.iter().rev().take(200).map(pos).collect();
            let fin = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
            let span = fin - start;
            let dir = (target - start).signum();
            let furthest = from_step
                .iter()
                .map(|r| (pos(r) - start) * dir)
                .fold(f64::NEG_INFINITY, f64::max);
            let over = if target != start {
                ((furthest - (target - start).abs()) / (target - start).abs() * 100.0).max(0.0)
            } else {
                0.0
            };
            // Rise 10 → 90 % and settling to ±2 % of the final value (MATLAB `stepinfo`'s
            // convention), and settling into ±2 % of the setpoint (never, if friction holds
            // the joint outside it: the thesis's error band ≈ stiction / K). The bands are
            // at least two encoder counts wide.
            let floor = 2.0 * std::f64::consts::TAU / sc.scale.motor_cpr / n;
            let crossing = |frac: f64| {
                from_step
                    .iter()
                    .find(|r| (pos(r) - start) * span.signum() >= frac * span.abs())
                    .map_or(f64::NAN, |r| r.time_s)
            };
            let rise = crossing(0.9) - crossing(0.1);
            let settling = |centre: f64, band: f64| match from_step
                .iter()
                .rposition(|r| (pos(r) - centre).abs() > band)
            {
                None => 0.0,
                Some(i) => from_step.get(i + 1).map_or(f64::NAN, |r| r.time_s - t0),
            };
            let settle_final = settling(fin, (0.02 * span.abs()).max(floor));
            let settle_set = settling(target, (0.02 * (target - start).abs()).max(floor));
            s.push("step size", target - start, "rad (output)");
            s.push("overshoot", over, "%");
            s.push("rise time (10–90 % of final)", rise, "s");
            s.push("settling time (2 % of final)", settle_final, "s");
            s.push("settling time (2 % of setpoint)", settle_set, "s");
            s.push("steady-state error", target - fin, "rad (output)");
        }
        ScenarioKind::Wall => {
            let late: Vec<&&Row> = run
                .iter()
                .filter(|r| r.time_s > SETTLE_S + sc.duration_s - 0.5)
                .collect();
            let m = late.len().max(1) as f64;
            let mean_err = late
                .iter()
                .map(|r| r.setpoint_torque_nm - r.torque_sensor_nm)
                .sum::<f64>()
                / m;
            s.push("desired contact torque", sc.desired, "N·m (output)");
            s.push("steady force error", mean_err, "N·m");
            s.push(
                "force error RMS (last 0.5 s)",
                rms(late
                    .iter()
                    .map(|r| r.setpoint_torque_nm - r.torque_sensor_nm)),
                "N·m",
            );
        }
        ScenarioKind::Backlash => {
            let late: Vec<&&Row> = run
                .iter()
                .filter(|r| r.time_s > SETTLE_S + sc.duration_s - 1.0)
                .collect();
            let pk = |f: &dyn Fn(&Row) -> f64| {
                let hi = late.iter().map(|r| f(r)).fold(f64::NEG_INFINITY, f64::max);
                let lo = late.iter().map(|r| f(r)).fold(f64::INFINITY, f64::min);
                (hi - lo).to_degrees()
            };
            s.push(
                "motor limit cycle p-p",
                pk(&|r| r.motor_pos_rad / n),
                "deg (output)",
            );
            s.push(
                "output limit cycle p-p",
                pk(&|r| r.output_pos_rad),
                "deg (output)",
            );
        }
        ScenarioKind::Identify => {
            // What makes a recording identifiable: reversals (friction's sign), a range of
            // speeds (viscous vs Coulomb), travel (position-periodic effects).
            let v: Vec<f64> = run.iter().map(|r| r.output_vel_rad_s).collect();
            let reversals = v
                .windows(2)
                .filter(|w| w[0].signum() != w[1].signum() && w[0] != 0.0)
                .count();
            let vmax = v.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
            let (lo, hi) = run
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
                    (l.min(r.output_pos_rad), h.max(r.output_pos_rad))
                });
            s.push("velocity reversals", reversals as f64, "");
            s.push("peak output speed", vmax, "rad/s");
            s.push("output travel", hi - lo, "rad");
        }
    }
    if matches!(
        sc.kind,
        ScenarioKind::Stiffness
            | ScenarioKind::Step
            | ScenarioKind::Backlash
            | ScenarioKind::Identify
    ) {
        s.push(
            "tracking error RMS",
            rms(run.iter().map(err)),
            "rad (output)",
        );
    }
    s.push("peak torque command", peak, "N·m (motor)");
    s.push("bus load (exact bits)", bus_load * 100.0, "% of 1 Mbit/s");
    s.push(
        "bus load (worst-case stuffing)",
        bus_load_worst * 100.0,
        "% of 1 Mbit/s",
    );
    s
}

/// LS fit τ = c·sign(ω) + B·ω; returns (B, c).
pub fn fit_viscous_coulomb(w: &[f64], tau: &[f64]) -> (f64, f64) {
    // normal equations for two regressors
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&x, &y) in w.iter().zip(tau) {
        let sg = x.signum();
        a11 += x * x;
        a12 += x * sg;
        a22 += 1.0;
        b1 += x * y;
        b2 += sg * y;
    }
    let det = a11 * a22 - a12 * a12;
    if det.abs() < 1e-300 {
        return (0.0, 0.0);
    }
    ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A count prints without decimals, its units digit under the measurements'; a ratio
    /// (no unit, not whole) and a measurement keep five decimals.
    #[test]
    fn table_prints_counts_as_whole_numbers() {
        let mut s = Summary::default();
        s.push("velocity reversals", 8.0, "");
        s.push("achieved / desired", 0.97793, "");
        s.push("peak output speed", 2.0, "rad/s");
        let t = s.table();
        let lines: Vec<&str> = t.lines().collect();
        assert_eq!(lines[0], "  velocity reversals       8", "{t}");
        assert!(lines[1].ends_with("     0.97793  "), "{t}");
        assert!(lines[2].ends_with("     2.00000  rad/s"), "{t}");
        let units_digit = |l: &str, from_end: usize| l.chars().count() - from_end;
        assert_eq!(units_digit(lines[0], 1), units_digit(lines[1], 9));
    }

    #[test]
    fn fits() {
        let x = [1.0, 2.0, 3.0];
        let y = [3.0, 5.0, 7.0];
        assert_eq!(fit_line(&x, &y), (1.0, 2.0));
        let w = [0.1, -0.1, 0.2, -0.2];
        let t: Vec<f64> = w
            .iter()
            .map(|&v: &f64| 0.5 * v.signum() + 3.0 * v)
            .collect();
        let (b, c) = fit_viscous_coulomb(&w, &t);
        assert!((b - 3.0).abs() < 1e-9 && (c - 0.5).abs() < 1e-9);
    }

    /// A first-order response y = y∞(1 − e^(−t/τ)) stopping short of the setpoint (as a PD
    /// against friction does): rise τ·ln 9, settling to 2 % of the final value τ·ln 50, the
    /// setpoint band never reached, steady-state error = setpoint − y∞.
    #[test]
    fn step_figures_follow_stepinfo() {
        let model = sim_plant::presets::preset("whoi-cable-30").expect("preset");
        let sc = Scenario::new(ScenarioKind::Step, &model).expect("scenario");
        let n = sc.scale.gear_ratio;
        let (tau, y_inf, target, t_step) = (0.05, 0.098, 0.1, 0.6);
        let rows: Vec<Row> = (1..=2000)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let after = t >= t_step;
                let y = if after {
                    y_inf * (1.0 - (-(t - t_step + 1e-3) / tau).exp())
                } else {
                    0.0
                };
                Row {
                    time_s: t,
                    seq: 0,
                    setpoint_pos_rad: if after { target } else { 0.0 },
                    setpoint_torque_nm: 0.0,
                    motor_pos_rad: y * n,
                    output_pos_rad: y,
                    motor_vel_est_rad_s: 0.0,
                    motor_vel_rad_s: 0.0,
                    output_vel_rad_s: 0.0,
                    torque_cmd_nm: 0.0,
                    torque_sensor_nm: 0.0,
                    output_torque_true_nm: 0.0,
                    state: controller::proto::State::Enabled,
                    flags: 0,
                    fault: false,
                }
            })
            .collect();
        let s = summarize(&sc, &rows, 0.0, 0.0);
        let get = |k: &str| s.get(k).expect(k);
        assert!((get("rise time (10–90 % of final)") - tau * 9f64.ln()).abs() < 1.5e-3);
        assert!((get("settling time (2 % of final)") - tau * 50f64.ln()).abs() < 1.5e-3);
        assert!(get("settling time (2 % of setpoint)").is_nan());
        assert!((get("steady-state error") - (target - y_inf)).abs() < 1e-6);
        assert!((get("step size") - target).abs() < 1e-12);
        assert_eq!(get("overshoot"), 0.0);
    }
}
