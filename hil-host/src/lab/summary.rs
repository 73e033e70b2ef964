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
            let after: Vec<&&Row> = run.iter().filter(|r| r.time_s > SETTLE_S + 0.1).collect();
            let maxpos = after
                .iter()
                .map(|r| r.motor_pos_rad / n)
                .fold(f64::NEG_INFINITY, f64::max);
            let over = if target != 0.0 {
                ((maxpos - target) / target * 100.0).max(0.0)
            } else {
                0.0
            };
            let band =
                (0.02 * target.abs()).max(2.0 * std::f64::consts::TAU / sc.scale.motor_cpr / n);
            // Last time the response left the ±2 % band; NaN if it ends outside (friction
            // can stop a PD short of the band: the thesis's error band ≈ stiction/K).
            let settle = match after
                .iter()
                .rposition(|r| (r.motor_pos_rad / n - target).abs() > band)
            {
                None => 0.0,
                Some(i) => after
                    .get(i + 1)
                    .map(|r| r.time_s - SETTLE_S - 0.1)
                    .unwrap_or(f64::NAN),
            };
            let last = after.iter().rev().take(200);
            let ss = last.map(|r| err(r).abs()).fold(0.0, f64::max);
            s.push("step size", target, "rad (output)");
            s.push("overshoot", over, "%");
            s.push("settling time (2 %)", settle, "s");
            s.push("steady-state error", ss, "rad (output)");
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
}
