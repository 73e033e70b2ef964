//! The first truth behind the [`Truth`] interface: the RK4 two-mass LuGre joint of
//! [`mod@super::truth`], its plant and excitations drawn from the seed.
//!
//! * Plant: motor J1 1–10 g·m², load J2 3–30 g·m², viscous friction over a decade, a stiff
//!   transmission (350 Hz) unless the hidden effect is compliance or backlash; backlash sits
//!   in a transmission of its own finite stiffness (a 40–60 Hz mode, drawn).
//! * Excitations: a multisine + rounded-triangle reference tracked by a PD (with or without
//!   feed-forward, drawn) or a PID, a multisine tracked with a PRBS torque dither, or an
//!   open-loop torque chirp.
//! * Noise: input noise σ 2–10 mN·m × the conditions' multiplier on the logged command (or on
//!   the applied torque for a hidden D/A quantiser), 0.2 counts of sensor noise before the
//!   encoder's quantisation.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::record::{Conditions, Excitation, Family, Logging, Truth, TruthRecord, Which};
use super::truth::{self, Controller, Plant};

/// The RK4 two-mass LuGre truth.
#[derive(Debug, Clone, Copy, Default)]
pub struct Rk4;

/// Seed offset of the load encoder's noise stream.
const LOAD_ENCODER_STREAM: u64 = 0x10AD_E4C0_DE00_0000;
/// Sensor noise before the encoder's quantisation, in counts.
const SENSOR_COUNTS: f64 = 0.2;
/// Fastest mode of the stiff transmission (Hz).
const RIGID_MODE_HZ: f64 = 350.0;

/// What is drawn for one seed besides the excitation.
#[derive(Debug, Clone)]
struct Draw {
    base: Plant,
    shape: f64,
    phase: f64,
    sign: f64,
    backlash_hz: f64,
    noise_u: f64,
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

fn draw(seed: u64) -> Draw {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let j1 = log_uniform(&mut rng, 1e-3, 1e-2);
    let j2 = log_uniform(&mut rng, 3e-3, 3e-2);
    let b = log_uniform(&mut rng, 0.005, 0.05);
    let noise_u = log_uniform(&mut rng, 0.002, 0.01);
    Draw {
        base: Plant::rigid(j1, j2, b),
        shape: rng.random_range(0.0..1.0),
        phase: rng.random_range(0.0..std::f64::consts::TAU),
        sign: if rng.random_bool(0.5) { 1.0 } else { -1.0 },
        backlash_hz: rng.random_range(40.0..60.0),
        noise_u,
    }
}

/// The excitation of one record.
#[derive(Debug, Clone)]
struct Drive {
    reference: Vec<f64>,
    velocity: Vec<f64>,
    accel: Vec<f64>,
    /// Torque added to the command (dither, PRBS, or the open-loop chirp itself).
    torque: Vec<f64>,
    kp: f64,
    kd: f64,
    ki: f64,
    feedforward: bool,
    closed_loop: bool,
}

/// A smooth reference: `k` sines and (optionally) a triangle, box-smoothed (3 × 50 ms).
fn reference(rng: &mut ChaCha8Rng, n: usize, dt: f64, triangle: bool) -> Vec<f64> {
    let mut r = vec![0.0; n];
    let travel = log_uniform(rng, 0.8, 3.0);
    let k = rng.random_range(2..=4);
    for _ in 0..k {
        let f = log_uniform(rng, 0.1, 1.2);
        let a = travel / k as f64 * rng.random_range(0.5..1.0);
        let ph = rng.random_range(0.0..std::f64::consts::TAU);
        for (i, v) in r.iter_mut().enumerate() {
            *v += a * (std::f64::consts::TAU * f * i as f64 * dt + ph).sin();
        }
    }
    if triangle {
        // Constant-velocity plateaus (friction maps) and clean reversals.
        let tp = rng.random_range(2.0..6.0);
        let ta = travel * rng.random_range(0.2..0.5);
        for (i, v) in r.iter_mut().enumerate() {
            let ph = (i as f64 * dt / tp).rem_euclid(1.0);
            *v += ta * (4.0 * (ph - 0.5).abs() - 1.0);
        }
    }
    let w = ((0.025 / dt).round() as usize).max(1);
    for _ in 0..3 {
        let mut prefix = Vec::with_capacity(n + 1);
        prefix.push(0.0);
        for v in &r {
            prefix.push(prefix.last().copied().unwrap_or(0.0) + v);
        }
        for (i, ri) in r.iter_mut().enumerate() {
            let (lo, hi) = (i.saturating_sub(w), (i + w).min(n - 1));
            *ri = (prefix[hi + 1] - prefix[lo]) / (hi - lo + 1) as f64;
        }
    }
    r
}

fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| (x[(i + 1).min(n - 1)] - x[i.saturating_sub(1)]) / (2.0 * dt))
        .collect()
}

fn drive(seed: u64, which: Which, cond: &Conditions, j: f64, b: f64) -> Drive {
    let stream = match which {
        Which::Estimation => 1,
        Which::Validation => 2,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (stream << 56) ^ 0x005E_ED0F_D21E);
    let dt = cond.dt;
    let n = samples(cond) + 4;
    let dn = Normal::new(0.0, 1.0).expect("unit normal");
    let triangle = cond.excitation != Excitation::MultisinePrbs;
    let r = reference(&mut rng, n, dt, triangle);
    let vel = derivative(&r, dt);
    let acc = derivative(&vel, dt);
    let feedforward = cond.excitation == Excitation::PdTracking && rng.random_bool(0.5);
    let wc = std::f64::consts::TAU
        * if feedforward {
            log_uniform(&mut rng, 0.5, 2.0)
        } else {
            log_uniform(&mut rng, 3.0, 8.0)
        };
    let dither_level = log_uniform(&mut rng, 0.1, 0.5) * j;
    let mut torque: Vec<f64> = (0..n).map(|_| dither_level * dn.sample(&mut rng)).collect();
    let (mut kp, mut kd, mut ki) = (j * wc * wc, 2.0 * 0.7 * j * wc, 0.0);
    let mut closed_loop = true;
    match cond.excitation {
        Excitation::PdTracking => {}
        Excitation::PidTracking => ki = kp * wc / 5.0,
        Excitation::MultisinePrbs => {
            // ±level, switching on a 5 ms clock with probability ½.
            let level = 4.0 * dither_level;
            let clock = ((5e-3 / dt).round() as usize).max(1);
            let mut s = 1.0;
            for (i, t) in torque.iter_mut().enumerate() {
                if i % clock == 0 && rng.random_bool(0.5) {
                    s = -s;
                }
                *t = s * level;
            }
        }
        Excitation::OpenLoopChirp => {
            // A torque chirp 0.2 → 4 Hz whose peak speed is about 2 rad/s.
            closed_loop = false;
            (kp, kd, ki) = (0.0, 0.0, 0.0);
            let (f0, f1) = (0.2, 4.0);
            let dur = n as f64 * dt;
            let amp = 2.0 * b.hypot(j * std::f64::consts::TAU * f0);
            let ph0 = rng.random_range(0.0..std::f64::consts::TAU);
            for (i, t) in torque.iter_mut().enumerate() {
                let tt = i as f64 * dt;
                let phase = std::f64::consts::TAU * (f0 * tt + (f1 - f0) * tt * tt / (2.0 * dur));
                *t = amp * (phase + ph0).sin() + 0.05 * *t;
            }
        }
    }
    Drive {
        reference: r,
        velocity: vel,
        accel: acc,
        torque,
        kp,
        kd,
        ki,
        feedforward,
        closed_loop,
    }
}

fn samples(cond: &Conditions) -> usize {
    (cond.duration / cond.dt).round().max(16.0) as usize
}

/// The loop: PD/PID on the measured motor position with a 150 Hz velocity filter, as a motor
/// card would have, the drive's torque added.
struct Loop<'a> {
    d: &'a Drive,
    dt: f64,
    prev: f64,
    vf: f64,
    integral: f64,
    j: f64,
    b: f64,
}

impl Controller for Loop<'_> {
    fn command(&mut self, k: usize, meas: f64) -> f64 {
        let d = self.d;
        if !d.closed_loop {
            return d.torque[k];
        }
        let v = if k == 0 {
            0.0
        } else {
            (meas - self.prev) / self.dt
        };
        self.prev = meas;
        let alpha = 1.0 - (-std::f64::consts::TAU * 150.0 * self.dt).exp();
        self.vf += alpha * (v - self.vf);
        let e = d.reference[k] - meas;
        self.integral += e * self.dt;
        let mut u =
            d.kp * e + d.kd * (d.velocity[k] - self.vf) + d.ki * self.integral + d.torque[k];
        if d.feedforward {
            u += self.j * d.accel[k] + self.b * d.velocity[k];
        }
        u
    }
}

/// The plant with the effect of `family` at amplitude `a` added to `p`.
fn with_effect(d: &Draw, p: &mut Plant, family: Family, a: f64) {
    let base = d.base;
    // `shape` ∈ [0,1) → a decade.
    let decade = |lo: f64| lo * 10f64.powf(d.shape);
    let jr = p.j1 * p.j2 / (p.j1 + p.j2);
    match family {
        Family::Offset => p.offset = d.sign * a,
        Family::Coulomb => {
            p.fc = a;
            p.fs = a;
        }
        Family::Asymmetry => p.b_pos = base.b_pos + a,
        Family::Stribeck => {
            p.fs = p.fc + a;
            p.vs = decade(0.02);
        }
        Family::Backlash => {
            p.backlash = a;
            let w = std::f64::consts::TAU * d.backlash_hz;
            p.k = jr * w * w;
            p.c = 2.0 * 0.05 * jr * w;
        }
        Family::Compliance => {
            let f = (60.0 / a.max(1e-6).sqrt()).max(6.0);
            let w = std::f64::consts::TAU * f;
            p.k = jr * w * w;
            p.c = 2.0 * 0.05 * jr * w;
        }
        Family::Ripple => {
            p.ripple_amp = a;
            p.ripple_period = 2.0 / decade(3.0);
            p.ripple_phase = d.phase;
        }
        Family::Gravity => {
            p.gravity = a;
            p.gravity_phase = d.phase;
        }
        Family::Delay => p.delay = a.min(0.006),
        Family::Quantization => p.quantum = a,
    }
}

impl Truth for Rk4 {
    fn name(&self) -> &'static str {
        "rk4"
    }

    fn record(
        &self,
        seed: u64,
        effects: &[(Family, f64)],
        cond: &Conditions,
        which: Which,
    ) -> Result<TruthRecord, String> {
        let d = draw(seed);
        let mut p = d.base;
        if effects.iter().any(|(f, _)| *f == Family::Stribeck) {
            // Coulomb is part of a Stribeck truth: 1–10 noise levels.
            let fc = d.noise_u * 10f64.powf(d.shape) * 2.0;
            p.fc = fc;
            p.fs = fc;
        }
        for &(f, a) in effects {
            if !(a.is_finite() && a >= 0.0) {
                return Err(format!(
                    "amplitude {a} of {} is not finite and ≥ 0",
                    f.name()
                ));
            }
            with_effect(&d, &mut p, f, a);
        }
        let dt = cond.dt;
        let n = samples(cond);
        let j = p.j1 + p.j2;
        let drv = drive(seed, which, cond, j, p.b_pos);
        let quantiser = effects.iter().any(|(f, _)| *f == Family::Quantization);
        let stream = match which {
            Which::Estimation => 3,
            Which::Validation => 4,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (stream << 56));
        let dn = Normal::new(0.0, 1.0).expect("unit normal");
        let noise_u = d.noise_u * cond.noise;
        let input_noise: Vec<f64> = (0..n).map(|_| noise_u * dn.sample(&mut rng)).collect();
        let count = std::f64::consts::TAU / cond.counts_per_rev;
        let sensor: Vec<f64> = (0..2 * n)
            .map(|_| SENSOR_COUNTS * count * dn.sample(&mut rng))
            .collect();
        let mut lrng = ChaCha8Rng::seed_from_u64(seed ^ LOAD_ENCODER_STREAM ^ (stream << 48));
        let load_noise: Vec<f64> = (0..n)
            .map(|_| SENSOR_COUNTS * count * dn.sample(&mut lrng))
            .collect();
        let encoder = |x: f64| count * (x / count).round();
        // Sub-steps: at least 10 a sample, 20 a period of the fastest mode, an even number.
        let fastest = if p.k > 0.0 {
            (p.k * (1.0 / p.j1 + 1.0 / p.j2)).sqrt() / std::f64::consts::TAU
        } else {
            0.0
        }
        .max(RIGID_MODE_HZ);
        let sub = ((dt * fastest * 20.0).ceil() as usize).max(10).div_ceil(2) * 2;
        let mut ctl = Loop {
            d: &drv,
            dt,
            prev: drv.reference[0],
            vf: 0.0,
            integral: 0.0,
            j,
            b: p.b_pos,
        };
        let mut k = 0;
        let mut sense = |x: f64| {
            let m = encoder(x + sensor[k]);
            k += 1;
            m
        };
        let mut l = 0;
        let mut mid_log = |x: f64| {
            let m = encoder(x + sensor[n + l]);
            l += 1;
            m
        };
        let log: Option<&mut dyn FnMut(f64) -> f64> = match cond.logging {
            Logging::Zoh => None,
            Logging::Mid => Some(&mut mid_log),
        };
        let m = truth::simulate(
            &p,
            &mut ctl,
            n,
            dt,
            sub,
            drv.reference[0],
            truth::Sensors {
                control: &mut sense,
                log,
                log_at: sub / 2,
            },
            if quantiser { &input_noise } else { &[] },
        );
        let bounded = m
            .motor_true
            .iter()
            .chain(&m.command)
            .all(|x| x.is_finite() && x.abs() < 1e6)
            && m.motor_true.iter().all(|x| x.abs() < 50.0);
        if !bounded {
            return Err("the loop diverged (|q| ≥ 50 rad, |u| ≥ 10⁶ or not finite)".into());
        }
        let load_position_true = m.load_position.clone();
        let load_position = m
            .load_position
            .iter()
            .zip(&load_noise)
            .map(|(x, e)| encoder(x + e))
            .collect();
        let input = if quantiser {
            m.command.clone()
        } else {
            m.command
                .iter()
                .zip(&input_noise)
                .map(|(u, e)| u + e)
                .collect()
        };
        Ok(TruthRecord {
            dt,
            time: m.time,
            input,
            position: m.motor_position,
            load_position,
            input_noise,
            position_true: m.motor_true,
            fine_dt: dt / sub as f64,
            fine_command: m.fine_command,
            fine_position: m.fine_position,
            inertia: j,
            inertia_load: p.j2,
            // The dead zone's spring acts only in contact: not a linear transmission.
            spring: (p.backlash == 0.0).then_some((p.k, p.c)),
            load_position_true,
            gear_ratio: 1.0,
        })
    }

    fn nominal_amplitude(&self, seed: u64, family: Family, cond: &Conditions) -> f64 {
        let d = draw(seed);
        // A torque scale of the record: the input noise, and the motion's J·a.
        let u = d.noise_u * cond.noise.max(0.1);
        match family {
            Family::Offset | Family::Coulomb => 2.0 * u,
            Family::Asymmetry => 2.0 * u,
            Family::Stribeck => 4.0 * u,
            Family::Backlash => 0.01,
            Family::Compliance => 1.0,
            Family::Ripple | Family::Gravity => 3.0 * u,
            Family::Delay => 0.002,
            Family::Quantization => 7.0 * u,
        }
    }
}
