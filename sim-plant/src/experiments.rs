//! The thesis's bench tests, simulated: what Tables 4.1/4.2 were measured with (Ch. 4,
//! thesis-notes §3.2 "Identification", §5). Used by the preset tests, and by anyone who wants
//! to "measure" a model the way the thesis measured the hardware.
//!
//! * [`stiffness_test`]: output locked, motor torque ramped slowly to ±max and back; deflection
//!   from the **motor encoder** (motor/N, as the thesis did: output position was never measured)
//!   against the output torque sensor. Analysis: per direction, a continuous two-segment line
//!   (soft zone, stiff zone) fitted by least squares with a grid-searched knee; the θ-intercepts
//!   of the two directions differ by the backlash.
//! * [`backdrive_test`]: breakaway by a slowly rising hand torque on the output until "a few
//!   successive non-zero velocity measurements" (thesis §3.2); then the output cranked at
//!   constant speeds in both directions with the motor unpowered, the torque averaged over whole
//!   output revolutions (so position-periodic ripple and cogging average out), and
//!   τ(v) = τc + B·v fitted per direction.

use std::f64::consts::TAU;

use crate::model::Model;
use crate::plant::{Environment, Plant, PlantError, PlantOptions};

/// 1 kHz, the card's rate.
pub const SAMPLE_DT: f64 = 1e-3;

/// Result of a simulated stiffness test.
#[derive(Clone, Debug, PartialEq)]
pub struct StiffnessReport {
    /// Soft-zone stiffness [positive, negative torque] (N·m/rad).
    pub soft: [f64; 2],
    /// Stiff-zone stiffness [positive, negative torque] (N·m/rad).
    pub stiff: [f64; 2],
    /// Knee torque found [positive, negative] (N·m, magnitudes).
    pub knee: [f64; 2],
    /// Width of the flat zone: deflection range over which the torque sensor reads zero
    /// (within 5σ of its noise), i.e. the backlash plus 2·5σ/K (rad).
    pub backlash: f64,
    /// Recorded (deflection from motor counts, sensor torque) pairs (rad, N·m).
    pub points: Vec<(f64, f64)>,
}

impl StiffnessReport {
    /// Mean of the two directions' soft-zone stiffness.
    pub fn k_min(&self) -> f64 {
        0.5 * (self.soft[0] + self.soft[1])
    }

    /// Mean of the two directions' stiff-zone stiffness.
    pub fn k_max(&self) -> f64 {
        0.5 * (self.stiff[0] + self.stiff[1])
    }
}

/// Output locked; motor torque 0 → +max → −max → 0 as a triangle of `period` seconds
/// (quasi-static for every preset at ≥ 8 s), after 0.5 s of rest. The motor also emulates a
/// damper on its own velocity sensor (ζ ≈ 0.7 for the locked-output mode) so that crossing a
/// backlash gap does not ring the transmission; quasi-statically it adds nothing, and the
/// torque sensor of a locked output reads the transmission torque whatever the motor does.
pub fn stiffness_test(
    model: &Model,
    period: f64,
    seed: u64,
) -> Result<StiffnessReport, PlantError> {
    let mut plant = Plant::new(
        model,
        PlantOptions {
            seed,
            environment: Environment::Locked,
            ..Default::default()
        },
    )?;
    let tmax = model.motor.max_torque.value;
    let n = model.plant.gear_ratio.value;
    let cpr = model.motor.counts_per_rev.value;
    let k_guess = model
        .effects
        .compliance
        .as_ref()
        .map(|c| c.stiffness.value)
        .unwrap_or(crate::effects::compliance::DEFAULT_STIFFNESS);
    let damper = 1.4 * (k_guess / (n * n) * model.motor.inertia.value).sqrt();
    let steps = (period / SAMPLE_DT).round() as usize;
    let rest = (0.5 / SAMPLE_DT) as usize;
    let mut points = Vec::with_capacity(steps);
    let mut s = plant.step(0.0, SAMPLE_DT);
    let c0 = s.motor_counts;
    for _ in 1..rest {
        s = plant.step(-damper * s.motor_velocity, SAMPLE_DT);
    }
    for k in 0..steps {
        let phase = k as f64 / steps as f64; // 0..1
        let tri = if phase < 0.25 {
            4.0 * phase
        } else if phase < 0.75 {
            2.0 - 4.0 * phase
        } else {
            4.0 * phase - 4.0
        };
        s = plant.step(tri * tmax - damper * s.motor_velocity, SAMPLE_DT);
        let counts = s.motor_counts.wrapping_sub(c0);
        let deflection = f64::from(counts) * TAU / cpr / n;
        points.push((deflection, s.torque));
    }
    // Points within the sensor's noise of zero torque are the dead zone (if any).
    let flat =
        (5.0 * model.sensors.torque_noise.value).max(3.0 * model.sensors.torque_resolution.value);
    let pos = fit_two_segments(&points, 1.0, 2.0 * flat);
    let neg = fit_two_segments(&points, -1.0, 2.0 * flat);
    let (lo, hi) = points
        .iter()
        .filter(|p| p.1.abs() <= flat)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            (l.min(p.0), h.max(p.0))
        });
    Ok(StiffnessReport {
        soft: [pos.k_soft, neg.k_soft],
        stiff: [pos.k_stiff, neg.k_stiff],
        knee: [pos.knee, neg.knee],
        backlash: if hi > lo { hi - lo } else { 0.0 },
        points,
    })
}

/// A per-direction two-segment fit of deflection against torque.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoSegment {
    /// Deflection at zero torque, extrapolated from the soft segment (rad).
    pub intercept: f64,
    /// Soft-segment stiffness (N·m/rad).
    pub k_soft: f64,
    /// Stiff-segment stiffness (N·m/rad).
    pub k_stiff: f64,
    /// Knee torque magnitude (N·m).
    pub knee: f64,
}

/// Fit s·θ = c0 + min(s·τ, τk)/K1 + max(s·τ − τk, 0)/K2 to the points with s·τ > threshold
/// (s = ±1: the loading direction), grid-searching τk over 200 values; least squares for c0,
/// 1/K1, 1/K2. The reported intercept is s·c0, the zero-torque deflection of that side.
pub fn fit_two_segments(points: &[(f64, f64)], sign: f64, threshold: f64) -> TwoSegment {
    let sel: Vec<(f64, f64)> = points
        .iter()
        .filter(|(_, t)| sign * t > threshold)
        .map(|&(d, t)| (sign * d, sign * t))
        .collect();
    let tmax = sel.iter().fold(0.0f64, |m, p| m.max(p.1));
    let mut best: Option<(f64, [f64; 3], f64)> = None;
    for i in 1..200 {
        let tk = threshold + (tmax - threshold) * i as f64 / 200.0;
        let rows = sel
            .iter()
            .map(|&(d, t)| ([1.0, t.min(tk), (t - tk).max(0.0)], d));
        let Some(beta) = crate::lstsq::solve_rows(rows.clone()) else {
            continue;
        };
        let sse: f64 = rows
            .map(|(x, y)| {
                let e = y - (beta[0] + beta[1] * x[1] + beta[2] * x[2]);
                e * e
            })
            .sum();
        if best.as_ref().is_none_or(|b| sse < b.2) {
            best = Some((tk, beta, sse));
        }
    }
    match best {
        Some((tk, b, _)) => TwoSegment {
            intercept: sign * b[0],
            k_soft: 1.0 / b[1],
            k_stiff: 1.0 / b[2],
            knee: tk,
        },
        None => TwoSegment {
            intercept: f64::NAN,
            k_soft: f64::NAN,
            k_stiff: f64::NAN,
            knee: f64::NAN,
        },
    }
}

/// Straight-line fit y = a + b·x; returns (a, b).
pub fn line_fit(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let b = sxy / sxx;
    (my - b * mx, b)
}

/// Result of a simulated backdrive test; pairs are [positive, negative] direction magnitudes.
#[derive(Clone, Debug, PartialEq)]
pub struct BackdriveReport {
    /// Breakaway torque (N·m).
    pub stiction: [f64; 2],
    /// Intercept of the torque-speed line (N·m).
    pub coulomb: [f64; 2],
    /// Slope of the torque-speed line (N·m·s/rad).
    pub viscous: [f64; 2],
    /// (signed speed, mean friction torque magnitude) per run.
    pub points: Vec<(f64, f64)>,
}

/// Breakaway torque in direction `dir` (±1): hand torque rising at `rate` N·m/s on the output,
/// motor unpowered, until 3 successive non-zero motor velocity readings; returns |sensor torque|
/// at detection (N·m), or NaN if it never moved within `limit` N·m.
pub fn breakaway(
    model: &Model,
    dir: f64,
    rate: f64,
    limit: f64,
    seed: u64,
) -> Result<f64, PlantError> {
    let mut plant = Plant::new(
        model,
        PlantOptions {
            seed,
            ..Default::default()
        },
    )?;
    let mut moving = 0;
    let steps = (limit / rate / SAMPLE_DT).ceil() as usize;
    for k in 0..steps {
        let torque = dir * rate * k as f64 * SAMPLE_DT;
        plant.set_environment(Environment::Torque { torque })?;
        let s = plant.step(0.0, SAMPLE_DT);
        if s.motor_velocity != 0.0 {
            moving += 1;
            if moving >= 3 {
                return Ok(s.torque.abs());
            }
        } else {
            moving = 0;
        }
    }
    Ok(f64::NAN)
}

/// Mean friction torque magnitude while cranking the output at `speed` (rad/s, signed) with the
/// motor unpowered: the crank speeds up over 1 s (a hand, not a step — a step would ring the
/// motor side for seconds), 2 s to settle, then the mean over one whole output revolution.
pub fn crank_torque(model: &Model, speed: f64, seed: u64) -> Result<f64, PlantError> {
    let mut plant = Plant::new(
        model,
        PlantOptions {
            seed,
            ..Default::default()
        },
    )?;
    let ramp = (1.0 / SAMPLE_DT) as usize;
    for k in 1..=ramp {
        plant.set_environment(Environment::Crank {
            speed: speed * k as f64 / ramp as f64,
        })?;
        plant.advance(0.0, SAMPLE_DT);
    }
    for _ in 0..(2.0 / SAMPLE_DT) as usize {
        plant.advance(0.0, SAMPLE_DT);
    }
    let samples = (TAU / speed.abs() / SAMPLE_DT).round() as usize;
    let mut sum = 0.0;
    for _ in 0..samples {
        sum += plant.step(0.0, SAMPLE_DT).torque;
    }
    // The output pushes back against the crank: the sensor reads −sign(v)·friction.
    Ok(-speed.signum() * sum / samples as f64)
}

/// Breakaway in both directions and the torque-speed lines at `speeds` (positive values; each
/// is run in both directions).
pub fn backdrive_test(
    model: &Model,
    speeds: &[f64],
    seed: u64,
) -> Result<BackdriveReport, PlantError> {
    let limit = 2.0 * model.motor.max_torque.value * model.plant.gear_ratio.value;
    let stiction = [
        breakaway(model, 1.0, 2.0, limit, seed)?,
        breakaway(model, -1.0, 2.0, limit, seed)?,
    ];
    let mut points = Vec::new();
    let mut lines = [(0.0, 0.0); 2];
    for (i, dir) in [1.0, -1.0].into_iter().enumerate() {
        let mut pts = Vec::new();
        for &v in speeds {
            let t = crank_torque(model, dir * v, seed)?;
            pts.push((v, t));
            points.push((dir * v, t));
        }
        lines[i] = line_fit(&pts);
    }
    Ok(BackdriveReport {
        stiction,
        coulomb: [lines[0].0, lines[1].0],
        viscous: [lines[0].1, lines[1].1],
        points,
    })
}
