//! The excitations: a smooth position reference (what the joint is asked to do), the torque
//! that would make the unperturbed rigid plant do it exactly, and the dither.
//!
//! The feed-forward for sample k is the *average* over the hold [t_k, t_k+T) of J·r̈ + B·ṙ,
//! i.e. J·Δṙ/T + B·Δr/T: held by the ZOH it moves the rigid viscous plant through r(t_k) at
//! every sample, so the open-loop chirp does not drift and the closed loops only fight effects.

use super::rng::{stream, Draw};
use crate::hidden::record::{Conditions, Excitation, Which};
use std::f64::consts::TAU;

/// Fade-in of the reference, s: position, speed and acceleration all start at zero.
const FADE: f64 = 1.0;

#[derive(Debug, Clone, Copy)]
enum Shape {
    /// A sine of position amplitude `amp`.
    Tone { amp: f64, hz: f64, phase: f64 },
    /// A triangle with rounded corners: amp·asin(ρ·sin θ)/asin(ρ).
    Triangle {
        amp: f64,
        hz: f64,
        phase: f64,
        rounding: f64,
    },
    /// Logarithmic sweep at constant speed amplitude `speed`.
    Chirp {
        speed: f64,
        hz0: f64,
        hz1: f64,
        span: f64,
    },
}

impl Shape {
    /// Position and velocity at time t (closed forms).
    fn at(&self, t: f64) -> (f64, f64) {
        match *self {
            Shape::Tone { amp, hz, phase } => {
                let w = TAU * hz;
                let th = w * t + phase;
                (amp * th.sin(), amp * w * th.cos())
            }
            Shape::Triangle {
                amp,
                hz,
                phase,
                rounding,
            } => {
                let w = TAU * hz;
                let th = w * t + phase;
                let x = rounding * th.sin();
                let norm = amp / rounding.asin();
                let rate = rounding * w * th.cos() / (1.0 - x * x).sqrt();
                (norm * x.asin(), norm * rate)
            }
            Shape::Chirp {
                speed,
                hz0,
                hz1,
                span,
            } => {
                let log_ratio = (hz1 / hz0).ln();
                let growth = (log_ratio * t / span).exp();
                let hz = hz0 * growth;
                let phase = TAU * hz0 * span / log_ratio * (growth - 1.0);
                let amp = speed / (TAU * hz);
                let amp_rate = -amp * log_ratio / span;
                (
                    amp * phase.sin(),
                    amp_rate * phase.sin() + amp * TAU * hz * phase.cos(),
                )
            }
        }
    }
}

/// Quintic smoothstep: C² fade-in from 0 to 1 over [0, FADE], and its rate.
fn fade_in(t: f64) -> (f64, f64) {
    let x = (t / FADE).clamp(0.0, 1.0);
    let w = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
    let rate = 30.0 * x * x * (1.0 - x) * (1.0 - x) / FADE;
    (w, rate)
}

/// A position reference: a faded sum of shapes, scaled to a travel.
#[derive(Debug, Clone)]
pub struct Reference {
    shapes: Vec<Shape>,
    gain: f64,
}

impl Reference {
    /// Unscaled position and velocity.
    fn raw(&self, t: f64) -> (f64, f64) {
        let (x, xd) = self
            .shapes
            .iter()
            .map(|s| s.at(t))
            .fold((0.0, 0.0), |(a, b), (p, v)| (a + p, b + v));
        let (w, wd) = fade_in(t);
        (w * x, wd * x + w * xd)
    }
    /// Position r(t), rad.
    pub fn position(&self, t: f64) -> f64 {
        self.gain * self.raw(t).0
    }
    /// Velocity ṙ(t), rad/s.
    pub fn velocity(&self, t: f64) -> f64 {
        self.gain * self.raw(t).1
    }
}

/// Tones log-spaced over [lo, hi] Hz with ±15 % jitter and random phases, equal speed `speed`.
fn tones(d: &mut Draw, count: usize, lo: f64, hi: f64, speed: f64) -> Vec<Shape> {
    (0..count)
        .map(|i| {
            let x = i as f64 / (count - 1) as f64;
            let hz = lo * (hi / lo).powf(x) * d.uniform(0.85, 1.15);
            Shape::Tone {
                amp: speed / (TAU * hz),
                hz,
                phase: d.uniform(0.0, TAU),
            }
        })
        .collect()
}

/// Everything the drive does in one record, sample by sample.
#[derive(Debug, Clone)]
pub struct Plan {
    pub reference: Reference,
    /// r(t_k), k = 0..n.
    pub r: Vec<f64>,
    /// Feed-forward torque per sample, N·m.
    pub feedforward: Vec<f64>,
    /// Dither torque per sample, N·m.
    pub dither: Vec<f64>,
    /// Position feedback on?
    pub closed_loop: bool,
    /// Integral action on?
    pub integral: bool,
    /// RMS of feed-forward plus dither: the a-priori RMS command.
    pub rms_command: f64,
    /// Mean positive reference speed, rad/s.
    pub mean_positive_speed: f64,
    /// RMS reference speed, rad/s.
    pub rms_speed: f64,
}

/// Number of samples of a record.
pub fn sample_count(cond: &Conditions) -> usize {
    (cond.duration / cond.dt).round().max(1.0) as usize
}

fn which_index(which: Which) -> u64 {
    match which {
        Which::Estimation => 0,
        Which::Validation => 1,
    }
}

/// Maximal-length 15-bit LFSR (x¹⁵ + x¹⁴ + 1), one ±1 chip per call.
#[derive(Debug)]
struct Prbs(u16);

impl Prbs {
    fn chip(&mut self) -> f64 {
        let bit = ((self.0 >> 14) ^ (self.0 >> 13)) & 1;
        self.0 = ((self.0 << 1) | bit) & 0x7FFF;
        if bit == 1 {
            1.0
        } else {
            -1.0
        }
    }
}

/// Build the plan for the rigid plant (J, B) of a seed.
pub fn plan(seed: u64, which: Which, cond: &Conditions, j: f64, b: f64) -> Plan {
    let mut d = stream(seed, "excitation", which_index(which));
    let n = sample_count(cond);
    let dt = cond.dt;
    let span = n as f64 * dt;
    let travel = d.uniform(1.5, 2.5);
    let shapes = match cond.excitation {
        Excitation::PdTracking | Excitation::PidTracking => {
            // Tone speeds comparable to the triangle's (raw amplitude 1, ~4 rad/s per Hz).
            let speed = d.uniform(0.4, 0.8);
            let mut s = tones(&mut d, 6, 0.25, 3.0, speed);
            s.push(Shape::Triangle {
                amp: 1.0,
                hz: 1.0 / d.uniform(3.0, 6.0),
                phase: d.uniform(0.0, TAU),
                rounding: d.uniform(0.85, 0.97),
            });
            s
        }
        Excitation::MultisinePrbs => tones(&mut d, 8, 0.12, 4.0, 1.0),
        Excitation::OpenLoopChirp => vec![Shape::Chirp {
            speed: 1.0,
            hz0: d.uniform(0.2, 0.4),
            hz1: d.uniform(5.0, 10.0),
            span,
        }],
    };
    let mut reference = Reference { shapes, gain: 1.0 };
    let raw: Vec<(f64, f64)> = (0..=n).map(|k| reference.raw(k as f64 * dt)).collect();
    let (lo, hi) = raw
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &(x, _)| {
            (l.min(x), h.max(x))
        });
    reference.gain = if hi > lo { travel / (hi - lo) } else { 1.0 };
    let r: Vec<f64> = raw.iter().map(|x| reference.gain * x.0).collect();
    let rd: Vec<f64> = raw.iter().map(|x| reference.gain * x.1).collect();
    let feedforward: Vec<f64> = (0..n)
        .map(|k| (j * (rd[k + 1] - rd[k]) + b * (r[k + 1] - r[k])) / dt)
        .collect();
    let rms_ff = rms(&feedforward);
    let peak_ff = feedforward.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let mean_positive_speed = rd[..n].iter().map(|v| v.max(0.0)).sum::<f64>() / n as f64;

    let mut dd = stream(seed, "dither", which_index(which));
    let dither: Vec<f64> = match cond.excitation {
        Excitation::PdTracking | Excitation::PidTracking => {
            let sigma = dd.uniform(0.005, 0.015) * rms_ff;
            dd.normals(n).into_iter().map(|x| sigma * x).collect()
        }
        Excitation::OpenLoopChirp => {
            let sigma = dd.uniform(0.001, 0.003) * rms_ff;
            dd.normals(n).into_iter().map(|x| sigma * x).collect()
        }
        Excitation::MultisinePrbs => {
            let level = dd.uniform(0.02, 0.05) * peak_ff;
            let hold = ((1e-3 / dt).round() as usize).max(1);
            let mut lfsr = Prbs(((dd.word() & 0x7FFE) | 1) as u16);
            let mut chip = lfsr.chip();
            (0..n)
                .map(|k| {
                    if k % hold == 0 {
                        chip = lfsr.chip();
                    }
                    level * chip
                })
                .collect()
        }
    };
    let rms_dither = rms(&dither);
    Plan {
        reference,
        r,
        feedforward,
        dither,
        closed_loop: cond.excitation != Excitation::OpenLoopChirp,
        integral: cond.excitation == Excitation::PidTracking,
        rms_command: (rms_ff * rms_ff + rms_dither * rms_dither).sqrt(),
        mean_positive_speed,
        rms_speed: rms(&rd[..n]),
    }
}

/// Root mean square.
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}
