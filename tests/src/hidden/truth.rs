//! The truth plant: written independently of `sim-plant` and of the workbench model.
//!
//! Where the workbench fits a *rigid* inertia with *static* friction features evaluated on
//! smoothed derivatives, the truth is a **two-mass** joint (motor J1 | spring K with damping,
//! optionally with a backlash dead zone | load J2) with **dynamic LuGre friction** on the load
//! (bristle state z), torque ripple and gravity on the load, an input path with a pure delay
//! (history buffer with linear interpolation) and D/A quantisation, integrated by its own
//! fixed-step **RK4** at 10 sub-steps per 1 ms sample. Nothing here calls `sim_plant` or
//! `hil_host`, so a diagnosis cannot pass by sharing code with the thing it diagnoses.

/// Physical parameters of the truth joint (SI, rotary).
#[derive(Debug, Clone, Copy)]
pub struct Plant {
    /// Motor inertia.
    pub j1: f64,
    /// Load inertia.
    pub j2: f64,
    /// Transmission stiffness.
    pub k: f64,
    /// Transmission damping.
    pub c: f64,
    /// Backlash total width (0 = none).
    pub backlash: f64,
    /// Viscous friction for positive / negative load velocity.
    pub b_pos: f64,
    /// Viscous friction for negative velocity.
    pub b_neg: f64,
    /// Coulomb level.
    pub fc: f64,
    /// Static (break-away) level (≥ fc).
    pub fs: f64,
    /// Stribeck velocity.
    pub vs: f64,
    /// LuGre bristle deflection scale (σ0 = max(fs, fc)/z_scale).
    pub z_scale: f64,
    /// Constant torque offset on the load.
    pub offset: f64,
    /// Ripple amplitude.
    pub ripple_amp: f64,
    /// Ripple period (load angle).
    pub ripple_period: f64,
    /// Ripple phase.
    pub ripple_phase: f64,
    /// Gravity amplitude m·g·l.
    pub gravity: f64,
    /// Gravity phase.
    pub gravity_phase: f64,
    /// Input delay (s).
    pub delay: f64,
    /// D/A quantum (0 = none).
    pub quantum: f64,
}

impl Plant {
    /// A stiff, frictionless-but-viscous joint (what the baseline model can represent).
    pub fn rigid(j1: f64, j2: f64, b: f64) -> Self {
        // 350 Hz first mode: far above the excitation and the differentiator's band.
        let w = 2.0 * std::f64::consts::PI * 350.0;
        let jr = j1 * j2 / (j1 + j2);
        Plant {
            j1,
            j2,
            k: jr * w * w,
            c: 2.0 * 0.05 * jr * w,
            backlash: 0.0,
            b_pos: b,
            b_neg: b,
            fc: 0.0,
            fs: 0.0,
            vs: 0.1,
            z_scale: 1e-5,
            offset: 0.0,
            ripple_amp: 0.0,
            ripple_period: 1.0,
            ripple_phase: 0.0,
            gravity: 0.0,
            gravity_phase: 0.0,
            delay: 0.0,
            quantum: 0.0,
        }
    }

    /// State derivative for state [x1, v1, x2, v2, z] under applied torque `tau`, `age` after
    /// the start of the RK4 sub-step (see the bristle note below).
    fn deriv(&self, s: &[f64; 5], tau: f64, age: f64) -> [f64; 5] {
        let [x1, v1, x2, v2, z] = *s;
        let d = x1 - x2;
        let half = 0.5 * self.backlash;
        let defl = if d > half {
            d - half
        } else if d < -half {
            d + half
        } else {
            0.0
        };
        let in_contact = defl != 0.0 || self.backlash == 0.0;
        let spring = self.k * defl + if in_contact { self.c * (v1 - v2) } else { 0.0 };
        // LuGre friction on the load. The bristle state z is advanced exactly (see
        // `advance_bristle`) between RK4 sub-steps; within one it is not an RK state, so at a
        // stage `age` into the sub-step it is relaxed exactly from its start value toward the
        // steady state of the stage's velocity. Using the start value itself (the earlier
        // form) put the bristle off its slow manifold at every later stage: the damping σ1·ż
        // (σ1 is large — critically damped bristles) then added a spurious force
        // σ1·(h/2)·a·|v|·g'(|v|)/g(|v|) across the Stribeck transition, an O(h) integration
        // error several times the physical bristle transient σ1·g'·a/σ0.
        let fz = if self.fc > 0.0 || self.fs > 0.0 {
            let (s0, s1, lambda) = self.lugre(v2);
            let z = if lambda * age > 1e-12 {
                let zss = v2 / lambda;
                zss + (z - zss) * (-lambda * age).exp()
            } else {
                z + v2 * age
            };
            let dz = v2 - lambda * z;
            s0 * z + s1 * dz
        } else {
            0.0
        };
        let dz = 0.0;
        let visc = if v2 >= 0.0 {
            self.b_pos * v2
        } else {
            self.b_neg * v2
        };
        let ripple = self.ripple_amp
            * (std::f64::consts::TAU * x2 / self.ripple_period + self.ripple_phase).sin();
        let grav = self.gravity * (x2 + self.gravity_phase).sin();
        let load = spring - fz - visc - ripple - grav - self.offset;
        [v1, (tau - spring) / self.j1, v2, load / self.j2, dz]
    }
}

impl Plant {
    /// (σ0, σ1, λ) of the LuGre model at load velocity `v`: ż = v − λ·z.
    fn lugre(&self, v: f64) -> (f64, f64, f64) {
        let g = (self.fc + (self.fs - self.fc) * (-(v / self.vs).powi(2)).exp()).max(1e-12);
        let s0 = self.fs.max(self.fc) / self.z_scale;
        // Critically damped bristles.
        let s1 = 2.0 * (s0 * self.j2).sqrt();
        (s0, s1, s0 * v.abs() / g)
    }

    /// Exact solution of ż = v − λz over `h` with v frozen (the bristle dynamics are far
    /// faster than anything else, so an explicit step would need a microsecond step).
    fn advance_bristle(&self, s: &mut [f64; 5], h: f64) {
        if self.fc <= 0.0 && self.fs <= 0.0 {
            return;
        }
        let v = s[3];
        let (_, _, lambda) = self.lugre(v);
        if lambda * h < 1e-12 {
            s[4] += v * h;
        } else {
            let zss = v / lambda;
            s[4] = zss + (s[4] - zss) * (-lambda * h).exp();
        }
    }
}

/// What the excitation does at each sample.
pub trait Controller {
    /// Commanded torque at sample `k` given the measured motor position.
    fn command(&mut self, k: usize, measured_position: f64) -> f64;
}

/// Simulated measurements.
#[derive(Debug, Clone)]
pub struct Measured {
    /// Time (s).
    pub time: Vec<f64>,
    /// Commanded torque as computed (before any hidden delay or quantiser).
    pub command: Vec<f64>,
    /// Motor position as the log's encoder reports it.
    pub motor_position: Vec<f64>,
    /// Load position (truth) at the logged instants.
    pub load_position: Vec<f64>,
    /// Motor position (truth, before the encoder), at the same instants as `motor_position`.
    pub motor_true: Vec<f64>,
    /// The held command at every sub-step (before any hidden delay or quantiser), plus the
    /// disturbance.
    pub fine_command: Vec<f64>,
    /// True motor position at every sub-step.
    pub fine_position: Vec<f64>,
}

/// The two views of the motor encoder.
#[allow(missing_debug_implementations)]
pub struct Sensors<'a> {
    /// What the controller measures at the start of each sample.
    pub control: &'a mut dyn FnMut(f64) -> f64,
    /// What the recording holds, read `log_at` sub-steps into the sample; `None` when the log
    /// holds what the controller read (a drive's log: zero-order hold).
    pub log: Option<&'a mut dyn FnMut(f64) -> f64>,
    /// Sub-step of the sample at which a separate log reading is taken.
    pub log_at: usize,
}

/// Integrate the plant for `n` samples of `dt`, `sub` RK4 sub-steps per sample.
///
/// `disturbance[k]` (if not empty) is a torque added at the motor over sample `k`, after the
/// delay and the quantiser: current-loop noise and cogging-like disturbances of a real drive,
/// which no recording of the command shows.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    p: &Plant,
    ctl: &mut dyn Controller,
    n: usize,
    dt: f64,
    sub: usize,
    x0: f64,
    sensors: Sensors,
    disturbance: &[f64],
) -> Measured {
    let Sensors {
        control: sense,
        mut log,
        log_at,
    } = sensors;
    let mut s = [x0, 0.0, x0, 0.0, 0.0];
    let mut out = Measured {
        time: Vec::with_capacity(n),
        command: Vec::with_capacity(n),
        motor_position: Vec::with_capacity(n),
        load_position: Vec::with_capacity(n),
        motor_true: Vec::with_capacity(n),
        fine_command: Vec::with_capacity(n * sub),
        fine_position: Vec::with_capacity(n * sub),
    };
    // Command history for the delay line (one entry per sample, held constant over it).
    let mut hist: Vec<f64> = Vec::with_capacity(n);
    let h = dt / sub as f64;
    for k in 0..n {
        let t = k as f64 * dt;
        let meas = sense(s[0]);
        let u = ctl.command(k, meas);
        out.time.push(t);
        out.command.push(u);
        hist.push(u);
        if log.is_none() {
            out.motor_position.push(meas);
            out.load_position.push(s[2]);
            out.motor_true.push(s[0]);
        }
        for j in 0..sub {
            if let Some(log) = log.as_mut().filter(|_| j == log_at) {
                out.motor_position.push(log(s[0]));
                out.load_position.push(s[2]);
                out.motor_true.push(s[0]);
            }
            let w = disturbance.get(k).copied().unwrap_or(0.0);
            // The command plus the torque disturbance after the D/A: what the start model
            // takes as input (the referee's excess is then the hidden effect alone).
            out.fine_command.push(u + w);
            out.fine_position.push(s[0]);
            // Applied torque at the sub-step midpoint time, delayed and quantised.
            let applied = |tt: f64| -> f64 {
                let td = tt - p.delay;
                let idx = (td / dt).floor();
                let v = if idx < 0.0 {
                    hist[0]
                } else {
                    hist[(idx as usize).min(hist.len() - 1)]
                };
                if p.quantum > 0.0 {
                    p.quantum * (v / p.quantum).round()
                } else {
                    v
                }
            };
            let t0 = t + j as f64 * h;
            let (ua, ub, uc) = (
                applied(t0) + w,
                applied(t0 + 0.5 * h) + w,
                applied(t0 + h) + w,
            );
            let k1 = p.deriv(&s, ua, 0.0);
            let s2 = add(&s, &k1, 0.5 * h);
            let k2 = p.deriv(&s2, ub, 0.5 * h);
            let s3 = add(&s, &k2, 0.5 * h);
            let k3 = p.deriv(&s3, ub, 0.5 * h);
            let s4 = add(&s, &k3, h);
            let k4 = p.deriv(&s4, uc, h);
            for i in 0..4 {
                s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
            p.advance_bristle(&mut s, h);
        }
    }
    out
}

fn add(s: &[f64; 5], k: &[f64; 5], h: f64) -> [f64; 5] {
    let mut o = *s;
    for i in 0..5 {
        o[i] += h * k[i];
    }
    o
}
