//! Figures extracted from a recording: what the thesis measured on its rig.

use super::recorder::Row;
use super::scenario::{Scenario, ScenarioKind, SETTLE_S};

/// The summary table of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    /// (name, value, unit) in display order.
    pub rows: Vec<(String, f64, String)>,
    /// Where the run did not do what the scenario is for (the motor at its limit, a joint
    /// stuck in friction, no motion to identify from): the figures are then about that.
    pub warnings: Vec<String>,
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

/// Computes the scenario's figures from rows in memory. `bus_load` is the measured
/// exact-bit load (0..1).
pub fn summarize(sc: &Scenario, rows: &[Row], bus_load: f64, bus_load_worst: f64) -> Summary {
    let pass = || Ok::<_, anyhow::Error>(rows.iter().cloned().map(Ok));
    summarize_with(sc, pass, bus_load, bus_load_worst, None).unwrap_or_default()
}

/// Computes the scenario's figures from a recording, reading it in passes (one for most
/// scenarios, three for a step: its target, then its final value, then the times measured
/// against it), so memory does not grow with the length of the run. `pass` opens the
/// recording from its start. `withhold`: the scenario's figures are not computed (the
/// reason is in the report); peak torque and bus load still are.
pub fn summarize_with<I, F>(
    sc: &Scenario,
    mut pass: F,
    bus_load: f64,
    bus_load_worst: f64,
    withhold: Option<&str>,
) -> anyhow::Result<Summary>
where
    F: FnMut() -> anyhow::Result<I>,
    I: Iterator<Item = anyhow::Result<Row>>,
{
    let mut s = Summary::default();
    let mut acc = Pass1::new(sc);
    for r in pass()? {
        acc.add(&r?);
    }
    if withhold.is_none() {
        acc.figures(sc, &mut s, &mut pass)?;
        s.warnings = acc.warnings(sc, &s);
        if matches!(
            sc.kind,
            ScenarioKind::Stiffness
                | ScenarioKind::Step
                | ScenarioKind::Backlash
                | ScenarioKind::Identify
        ) {
            s.push("tracking error RMS", acc.tracking.rms(), "rad (output)");
        }
    }
    s.push("peak torque command", acc.peak, "N·m (motor)");
    s.push("bus load (exact bits)", bus_load * 100.0, "% of 1 Mbit/s");
    s.push(
        "bus load (worst-case stuffing)",
        bus_load_worst * 100.0,
        "% of 1 Mbit/s",
    );
    Ok(s)
}

/// Running sum of squares.
#[derive(Clone, Copy, Debug, Default)]
struct Rms {
    sum: f64,
    n: usize,
}

impl Rms {
    fn add(&mut self, x: f64) {
        self.sum += x * x;
        self.n += 1;
    }
    fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum / self.n as f64).sqrt()
        }
    }
}

/// Running least-squares line (Welford's updates, as stable as the two-pass form).
#[derive(Clone, Copy, Debug, Default)]
struct Line {
    n: f64,
    mx: f64,
    my: f64,
    sxx: f64,
    sxy: f64,
}

impl Line {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        let dx = x - self.mx;
        self.mx += dx / self.n;
        self.my += (y - self.my) / self.n;
        self.sxx += dx * (x - self.mx);
        self.sxy += dx * (y - self.my);
    }
    /// Slope of y = a + b·x (0 when undetermined), as [`fit_line`].
    fn slope(&self) -> f64 {
        if self.n < 2.0 || self.sxx <= 0.0 {
            0.0
        } else {
            self.sxy / self.sxx
        }
    }
}

/// Running minimum and maximum.
#[derive(Clone, Copy, Debug)]
struct Span {
    lo: f64,
    hi: f64,
}

impl Default for Span {
    fn default() -> Self {
        Span {
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        }
    }
}

impl Span {
    fn add(&mut self, x: f64) {
        self.lo = self.lo.min(x);
        self.hi = self.hi.max(x);
    }
    fn width(&self) -> f64 {
        self.hi - self.lo
    }
}

/// Everything one pass over the rows gives.
#[derive(Debug)]
struct Pass1 {
    n: f64,
    duration_s: f64,
    rows: usize,
    peak: f64,
    tracking: Rms,
    last_run_setpoint: Option<f64>,
    // stiffness
    crank: Line,
    area: f64,
    prev_crank: Option<(f64, f64)>,
    deflection: Span,
    // damper: (Σω, Στ, n) per 1 s segment
    segments: [(f64, f64, usize); 6],
    // wall
    force_err: Rms,
    force_err_sum: f64,
    // backlash
    motor_late: Span,
    output_late: Span,
    // identify
    prev_vel: Option<f64>,
    reversals: usize,
    vmax: f64,
    travel: Span,
    // saturation, after the settling time
    torque_limit: f64,
    run_rows: usize,
    at_limit: usize,
}

impl Pass1 {
    fn new(sc: &Scenario) -> Self {
        Pass1 {
            n: sc.scale.gear_ratio(),
            duration_s: sc.duration_s,
            rows: 0,
            peak: 0.0,
            tracking: Rms::default(),
            last_run_setpoint: None,
            crank: Line::default(),
            area: 0.0,
            prev_crank: None,
            deflection: Span::default(),
            segments: [(0.0, 0.0, 0); 6],
            force_err: Rms::default(),
            force_err_sum: 0.0,
            motor_late: Span::default(),
            output_late: Span::default(),
            prev_vel: None,
            reversals: 0,
            vmax: 0.0,
            travel: Span::default(),
            torque_limit: sc.gains.torque_limit,
            run_rows: 0,
            at_limit: 0,
        }
    }

    fn add(&mut self, r: &Row) {
        self.rows += 1;
        self.peak = self.peak.max(r.torque_cmd_nm.abs());
        self.last_run_setpoint = None;
        if r.time_s <= SETTLE_S {
            return;
        }
        self.last_run_setpoint = Some(r.setpoint_pos_rad);
        self.run_rows += 1;
        if r.torque_cmd_nm.abs() >= 0.98 * self.torque_limit {
            self.at_limit += 1;
        }
        // Tracking of the position setpoint by the motor encoder (colocated), output rad.
        self.tracking
            .add(r.setpoint_pos_rad - r.motor_pos_rad / self.n);
        // stiffness: the cranked part
        if r.time_s > SETTLE_S + 0.3 {
            let x = r.output_pos_rad - r.setpoint_pos_rad;
            self.crank.add(x, -r.torque_sensor_nm);
            self.deflection.add(x);
            // Loop area ∮τ dθ over the recording: energy lost per crank cycle.
            if let Some((pos, tau)) = self.prev_crank {
                self.area += -0.5 * (r.torque_sensor_nm + tau) * (r.output_pos_rad - pos);
            }
            self.prev_crank = Some((r.output_pos_rad, r.torque_sensor_nm));
        }
        // damper: the steady part of each 1 s crank segment
        for (seg, acc) in self.segments.iter_mut().enumerate() {
            let t0 = SETTLE_S + seg as f64 + 0.4;
            let t1 = SETTLE_S + seg as f64 + 0.95;
            if r.time_s > t0 && r.time_s < t1 {
                acc.0 += r.output_vel_rad_s;
                acc.1 += -r.torque_sensor_nm;
                acc.2 += 1;
            }
        }
        // wall: the last 0.5 s
        if r.time_s > SETTLE_S + self.duration_s - 0.5 {
            let e = r.setpoint_torque_nm - r.torque_sensor_nm;
            self.force_err.add(e);
            self.force_err_sum += e;
        }
        // backlash: the last second
        if r.time_s > SETTLE_S + self.duration_s - 1.0 {
            self.motor_late.add(r.motor_pos_rad / self.n);
            self.output_late.add(r.output_pos_rad);
        }
        // identify
        let v = r.output_vel_rad_s;
        if let Some(w0) = self.prev_vel {
            if w0.signum() != v.signum() && w0 != 0.0 {
                self.reversals += 1;
            }
        }
        self.prev_vel = Some(v);
        self.vmax = self.vmax.max(v.abs());
        self.travel.add(r.output_pos_rad);
    }

    /// What says the run did not do what its scenario is for, from its own figures.
    fn warnings(&self, sc: &Scenario, s: &Summary) -> Vec<String> {
        let mut w = Vec::new();
        let share = self.at_limit as f64 / self.run_rows.max(1) as f64;
        if share > 0.2 {
            w.push(format!(
                "the motor was at its torque limit (±{:.2} N·m) on {:.0} % of the ticks: the \
                 figures describe that limit, not the control law (ask for less, or give the \
                 joint a stronger motor)",
                self.torque_limit,
                100.0 * share
            ));
        }
        let ratio = s.get("achieved / desired").filter(|r| r.is_finite());
        if let Some(r) = ratio.filter(|r| !(0.5..=2.0).contains(r)) {
            w.push(format!(
                "achieved / desired is {r:.3}: the joint does not emulate the {} asked for",
                match sc.kind {
                    ScenarioKind::Damper => "damping",
                    _ => "stiffness",
                }
            ));
        }
        let desired = sc.desired();
        if let Some(e) = s.get("steady force error").filter(|_| desired != 0.0) {
            if e.abs() > 0.5 * desired.abs() {
                w.push(format!(
                    "the contact torque never reached its setpoint (steady error {e:.3} of \
                     {desired:.3} N·m): the joint is stuck (static friction above what the \
                     law commands, or the motor at its limit)"
                ));
            }
        }
        if let (Some(size), Some(e)) = (s.get("step size"), s.get("steady-state error")) {
            if size != 0.0 && e.abs() > 0.2 * size.abs() {
                w.push(format!(
                    "the step ended {:.0} % short of its setpoint: the joint stuck in friction \
                     before it got there",
                    100.0 * e.abs() / size.abs()
                ));
            }
        }
        if sc.kind == ScenarioKind::Identify && (self.reversals < 2 || self.travel.width() < 1e-3) {
            w.push(format!(
                "the output hardly moved ({} velocity reversals, {:.2e} rad of travel): the \
                 record holds too little motion to identify the plant from",
                self.reversals,
                self.travel.width()
            ));
        }
        w
    }

    fn figures<I, F>(&self, sc: &Scenario, s: &mut Summary, pass: &mut F) -> anyhow::Result<()>
    where
        F: FnMut() -> anyhow::Result<I>,
        I: Iterator<Item = anyhow::Result<Row>>,
    {
        match sc.kind {
            ScenarioKind::Stiffness => {
                let k = self.crank.slope();
                s.push("desired stiffness", sc.desired(), "N·m/rad (output)");
                s.push("achieved stiffness", k, "N·m/rad (output)");
                s.push("achieved / desired", k / sc.desired(), "");
                s.push("loop area (work lost)", self.area, "J");
                s.push("deflection travel", self.deflection.width(), "rad (output)");
            }
            ScenarioKind::Damper => {
                let (mut xs, mut ys) = (vec![], vec![]);
                for &(w, tau, m) in self.segments.iter().filter(|seg| seg.2 > 0) {
                    xs.push(w / m as f64);
                    ys.push(tau / m as f64);
                }
                // Split Coulomb (sign) from viscous by fitting τ = c·sign(ω) + B·ω.
                let (b, c) = fit_viscous_coulomb(&xs, &ys);
                s.push("desired damping", sc.desired(), "N·m·s/rad (output)");
                s.push("achieved damping", b, "N·m·s/rad (output)");
                s.push("achieved / desired", b / sc.desired(), "");
                s.push("Coulomb offset", c, "N·m (output)");
            }
            ScenarioKind::Step => {
                let target = self.last_run_setpoint.unwrap_or(0.0);
                step_figures(sc, s, target, self.rows, pass)?;
            }
            ScenarioKind::Wall => {
                let m = self.force_err.n.max(1) as f64;
                s.push("desired contact torque", sc.desired(), "N·m (output)");
                s.push("steady force error", self.force_err_sum / m, "N·m");
                s.push("force error RMS (last 0.5 s)", self.force_err.rms(), "N·m");
            }
            ScenarioKind::Backlash => {
                s.push(
                    "motor limit cycle p-p",
                    self.motor_late.width().to_degrees(),
                    "deg (output)",
                );
                s.push(
                    "output limit cycle p-p",
                    self.output_late.width().to_degrees(),
                    "deg (output)",
                );
            }
            ScenarioKind::Identify => {
                // What makes a recording identifiable: reversals (friction's sign), a range
                // of speeds (viscous vs Coulomb), travel (position-periodic effects).
                s.push("velocity reversals", self.reversals as f64, "");
                s.push("peak output speed", self.vmax, "rad/s");
                s.push("output travel", self.travel.width(), "rad");
            }
        }
        Ok(())
    }
}

/// When a response last left its band: the time of the sample after its last excursion
/// (NaN while the latest sample is outside).
#[derive(Clone, Copy, Debug)]
struct Settling {
    outside: bool,
    pending: bool,
    after: f64,
}

impl Default for Settling {
    fn default() -> Self {
        Settling {
            outside: false,
            pending: false,
            after: f64::NAN,
        }
    }
}

impl Settling {
    fn add(&mut self, outside: bool, t: f64) {
        if self.pending {
            self.after = t;
            self.pending = false;
        }
        if outside {
            self.outside = true;
            self.after = f64::NAN;
            self.pending = true;
        }
    }
}

/// The step response's figures, in two more passes over the rows (`n` of them).
fn step_figures<I, F>(
    sc: &Scenario,
    s: &mut Summary,
    target: f64,
    n: usize,
    pass: &mut F,
) -> anyhow::Result<()>
where
    F: FnMut() -> anyhow::Result<I>,
    I: Iterator<Item = anyhow::Result<Row>>,
{
    let g = sc.scale.gear_ratio();
    let pos = |r: &Row| r.motor_pos_rad / g;
    // Pass 2. The step instant: the first sample whose setpoint is nearer the target than
    // the start; the response starts from where the joint was one sample before. The value
    // the response ends at is the mean of its last 0.2 s: a PD against friction stops short
    // of the setpoint, so "settled" and "at the setpoint" differ.
    let mut k_step: Option<usize> = None;
    let (mut start, mut t0) = (0.0, 0.0);
    let mut prev: Option<f64> = None;
    let (mut tail_sum, mut tail_n) = (0.0, 0usize);
    let mut furthest_pos = f64::NEG_INFINITY;
    let mut furthest_neg = f64::NEG_INFINITY;
    for (i, r) in pass()?.enumerate() {
        let r = r?;
        if k_step.is_none() && (r.setpoint_pos_rad - target).abs() < 0.5 * target.abs() {
            k_step = Some(i);
            start = prev.unwrap_or(pos(&r));
            t0 = r.time_s;
        }
        prev = Some(pos(&r));
        if let Some(k) = k_step {
            if i >= k.max(n.saturating_sub(200)) {
                tail_sum += pos(&r);
                tail_n += 1;
            }
            furthest_pos = furthest_pos.max(pos(&r) - start);
            furthest_neg = furthest_neg.max(start - pos(&r));
        }
    }
    if k_step.is_none() {
        // No sample near the target: the response is taken from the first row.
        let mut first = true;
        for r in pass()? {
            let r = r?;
            if first {
                start = pos(&r);
                t0 = r.time_s;
                first = false;
            }
            furthest_pos = furthest_pos.max(pos(&r) - start);
            furthest_neg = furthest_neg.max(start - pos(&r));
        }
        k_step = Some(0);
        tail_n = 0;
        for (i, r) in pass()?.enumerate() {
            if i >= n.saturating_sub(200) {
                tail_sum += pos(&r?);
                tail_n += 1;
            }
        }
    }
    let k_step = k_step.unwrap_or(0);
    let fin = tail_sum / tail_n.max(1) as f64;
    let span = fin - start;
    let dir = (target - start).signum();
    let furthest = if dir < 0.0 {
        furthest_neg
    } else {
        furthest_pos
    };
    let over = if target != start {
        ((furthest - (target - start).abs()) / (target - start).abs() * 100.0).max(0.0)
    } else {
        0.0
    };
    // Pass 3. Rise 10 → 90 % and settling to ±2 % of the final value (MATLAB `stepinfo`'s
    // convention), and settling into ±2 % of the setpoint (never, if friction holds the
    // joint outside it: the thesis's error band ≈ stiction / K). The bands are at least two
    // encoder counts wide.
    let floor = 2.0 * std::f64::consts::TAU / sc.scale.motor_cpr() / g;
    let band_final = (0.02 * span.abs()).max(floor);
    let band_set = (0.02 * (target - start).abs()).max(floor);
    let (mut c10, mut c90) = (f64::NAN, f64::NAN);
    let mut settle_final = Settling::default();
    let mut settle_set = Settling::default();
    for r in pass()?.skip(k_step) {
        let r = r?;
        let p = pos(&r);
        let moved = (p - start) * span.signum();
        if c10.is_nan() && moved >= 0.1 * span.abs() {
            c10 = r.time_s;
        }
        if c90.is_nan() && moved >= 0.9 * span.abs() {
            c90 = r.time_s;
        }
        settle_final.add((p - fin).abs() > band_final, r.time_s);
        settle_set.add((p - target).abs() > band_set, r.time_s);
    }
    let settling = |st: Settling| if st.outside { st.after - t0 } else { 0.0 };
    s.push("step size", target - start, "rad (output)");
    s.push("overshoot", over, "%");
    s.push("rise time (10–90 % of final)", c90 - c10, "s");
    s.push("settling time (2 % of final)", settling(settle_final), "s");
    s.push("settling time (2 % of setpoint)", settling(settle_set), "s");
    s.push("steady-state error", target - fin, "rad (output)");
    Ok(())
}

/// LS fit τ = c·sign(ω) + B·ω; returns (B, c).
pub fn fit_viscous_coulomb(w: &[f64], tau: &[f64]) -> (f64, f64) {
    let rows = w.iter().zip(tau).map(|(&x, &y)| ([x, x.signum()], y));
    sim_plant::lstsq::solve_rows(rows).map_or((0.0, 0.0), |[b, c]| (b, c))
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
        let n = sc.scale.gear_ratio();
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
                    cmd_missing: false,
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
