//! The third truth: recordings from the HIL lab itself — the real card code against a
//! `sim-plant` joint, logged as the lab's recorder logs a drive.
//!
//! Where [`mod@super::truth`] is an independent simulator written for the trials, this one is the
//! project's own stack end to end, so a workbench judged on it is judged on what a lab run
//! would hand it:
//!
//! * **Card**: `controller::card::Card` in a [`CardNode`] (fixed-point laws, its velocity
//!   observer, its torque LSB of 0.1 mN·m, its faults), fed only through CAN frames on an
//!   in-process bus, in lockstep exactly as `hil_host::lab::Lab::step` orders a tick.
//! * **Supervisor**: the lab's [`Supervisor`] commits the gain set (through the card's own
//!   §2.9 stability guard), arms the card and streams the setpoints at 400 Hz requested, i.e.
//!   one `SetpointMotion` every 3 ticks (it rounds 1000/rate), which the card latches.
//! * **Plant**: a [`PlantNode`] around a `sim_plant::Plant` built from a thesis preset
//!   (`presets/transmissions.toml`: gear ratio, motor inertia, viscous friction), with every
//!   other preset effect removed so that the base joint is what a rigid inertia + viscous
//!   model explains, and the hidden effects switched on through `sim_plant::effects`.
//!
//! ## Excitations on the card
//! * `PdTracking`: mode `PositionPdColocated` (Ke on the motor encoder, Be on the card's
//!   observer velocity) following a multisine + rounded triangle the supervisor streams; a
//!   small Gaussian torque dither rides in the same frames' `torque_ff` (the card adds
//!   `torque_ff` in its position modes), held like the setpoint for 3 ticks.
//! * `PidTracking`: the same reference and dither in mode `PositionPid` (the card's integral
//!   term with its anti-windup clamp).
//! * `OpenLoopChirp`: mode `TorquePassthrough` — the card's direct torque command
//!   (τ = `torque_ff`, no feedback; limits still apply), the supervisor streaming a torque
//!   chirp (target `Torque`) plus a tiny dither. The chirp is the nominal rigid model's
//!   torque J·r̈ + b·ṙ for a faded-in position chirp (constant velocity amplitude), so the
//!   effect-free joint neither drifts nor runs away; an effect that pushes (offset, gravity)
//!   moves it as it would move an unfed joint.
//! * `MultisinePrbs`: `PositionPdColocated` following a multisine (no triangle) with a PRBS
//!   torque dither in `torque_ff`, clocked at 1–3 setpoint frames.
//!
//! ## What is logged
//! Rows at the card's 1 kHz (`TruthRecord::dt` = 1 ms whatever `Conditions::dt` asks), after
//! 0.6 s of streaming (the reference fades in over the first 0.4 s): the actuator frame's
//! torque as the [`Recorder`] logs it (`input`, N·m at the motor), and the encoders in motor
//! radians. The load (output) encoder has `Conditions::counts_per_rev` per *output* rev and is
//! referred to the motor side (× N), so both positions are on one axis (its steps are N times
//! coarser there).
//!
//! Both [`Logging`] modes: the plant is driven through each tick in its own substeps
//! ([`PlantNode::advance_in_parts`]: the same Störmer–Verlet substeps as the lab's one call per
//! tick, only the merged half-drifts split — rounding, not physics; tested below), so the
//! state mid-hold and on the fine grid is the lab's. `Zoh` logs the counts the card read at
//! the tick; `Mid` latches the same encoders at the middle of the hold.
//!
//! ## Effects (amplitudes are those of [`Family`]; sim-plant's parameters are output-referred)
//! N is the preset's ratio; a torque `a` at the motor is `a·N` at the output, a damping `a·N²`,
//! an angle `a/N`.
//! * Offset → `offset.torque = ±a·N` (sign from the seed).
//! * Coulomb → `coulomb.torque = a·N` (static = kinetic: the integrator's stick state).
//! * Asymmetry → `asymmetry.viscous_extra = a·N²`.
//! * Stribeck → `stribeck.excess = a·N`, velocity = the table's 0.02 rad/s (output) × a
//!   drawn half-decade either way, exponent 2; plus `coulomb.torque` of 2–20 nominal noise σ.
//! * Backlash → `backlash.width = a/N` (a = total gap on the motor axis) inside a linear
//!   `compliance` spring whose engaged mode is drawn at 150–300 Hz (ζ = the table's 0.05):
//!   a finite stiffness as the physics needs, above the band a 1 kHz record resolves.
//! * Compliance → a linear `compliance` spring (no soft zone) with the coupled mode at
//!   max(6 Hz, 60 Hz/√a) (capped at 5 kHz), ζ 0.05; the viscous friction stays on the output
//!   (sim-plant's friction node, where Table 4.1 measured it).
//! * Ripple → `ripple` of amplitude a·N on the output angle, no load growth, with a whole
//!   number of lobes per output rev drawn so that a record crosses ~3–30 periods (the
//!   presets' lobe counts put one period per motor rev, a few per record).
//! * Gravity → `gravity` m·g·l = a·N on the **output** angle, phase from the seed: on the
//!   motor axis of the record its period is 2π·N rad, so over a record it is a slowly
//!   varying torque, not sin/cos of the motor angle.
//! * Delay → `delay` = a (≤ 6 ms), at the substep's resolution.
//! * Quantization → `quantization.step = a·N` (the D/A of the plant's actuator, after the
//!   card's own 0.1 mN·m wire LSB, which the log shows and is no hidden effect).
//!
//! ## Noise
//! σ = (0.2–1 % drawn) × the torque scale the excitation is drawn to × `Conditions::noise`,
//! one sequence per (seed, record), independent of the effects so a record and its
//! effect-free twin share it. It is added to the logged command; with a hidden D/A quantiser
//! it is instead a torque disturbance after the converter (an `Environment::Torque` on the
//! output node — the only node of a rigid joint; the output of a compliant one) and the log is
//! the exact command, a multiple of the wire LSB. The encoders add only their quantisation.
//!
//! A card fault (velocity limit, a refused gain set, …) or a run-away joint is an `Err`: no
//! recording of the joint.

use std::f64::consts::TAU;

use controller::proto::scale::MOTOR_TORQUE_NM_PER_LSB;
use controller::proto::{Message, Mode, NodeId};
use hil_host::lab::card_node::CardNode;
use hil_host::lab::gains::{self, GainSet, JointScale};
use hil_host::lab::plant_node::PlantNode;
use hil_host::lab::recorder::Recorder;
use hil_host::lab::supervisor::{fault_words, Event, Phase, Supervisor, Target};
use hil_host::lab::trajectory::Trajectory;
use jointlab_can::bus::{CanBus, InprocBus, InprocHub};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use sim_plant::effects::{
    asymmetry, backlash, compliance, coulomb, delay, gravity, offset, quantization, ripple,
    stribeck, viscous, EffectSet,
};
use sim_plant::param::Param;
use sim_plant::plant::sensors::encoder_counts;
use sim_plant::{presets, Environment, Model, Plant, PlantOptions};

use super::record::{Conditions, Excitation, Family, Logging, Truth, TruthRecord, Which};

/// The HIL lab as a truth (see the module docs).
#[derive(Debug, Clone, Copy, Default)]
pub struct LabTruth;

/// The card's control period (s): the record's sample period.
const PERIOD: f64 = 1e-3;
/// Streaming ticks before the first logged row (the reference fades in over [`FADE_TICKS`]).
const LEAD_TICKS: usize = 600;
/// Ticks over which the reference (or the chirp) fades in from rest.
const FADE_TICKS: usize = 400;
/// Setpoint rate asked of the supervisor (it streams every round(1000/rate) = 3 ticks).
const SETPOINT_RATE_HZ: f64 = 400.0;
/// Ticks between two setpoint frames at [`SETPOINT_RATE_HZ`].
const FRAME_TICKS: usize = 3;
/// Largest reference speed at the motor (rad/s): the travel gives way to it.
const V_MAX: f64 = 40.0;
/// A joint beyond this (motor rad) has run away.
const RUNAWAY_RAD: f64 = 1e5;
/// Base substep rate of the plant (the lab's default).
const SUBSTEP_RATE: f64 = 10_000.0;
/// Ticks the supervisor may take to configure and arm the card.
const ARM_TICKS: u64 = 100;

/// Seed offsets of the independent random streams: the plant draw (seed only), the
/// excitation and the noise (seed and record), so one never shifts another's draws.
const PLANT_STREAM: u64 = 0x1AB7_0000_0000_0001;
const EXCITE_STREAM: u64 = 0x1AB7_0000_0000_0E0C;
const NOISE_STREAM: u64 = 0x1AB7_0000_0000_4015;

fn which_tag(w: Which) -> u64 {
    match w {
        Which::Estimation => 0x0E57_0000,
        Which::Validation => 0x07A1_0000_0000,
    }
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo.ln()..hi.ln()).exp()
}

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Everything drawn from the seed alone: the joint, its loop gains, the noise level and the
/// hidden effects' shapes.
#[derive(Debug, Clone)]
struct Joint {
    /// Gear ratio N.
    n: f64,
    /// Motor inertia (kg·m², motor side).
    i1: f64,
    /// Load inertia referred to the motor (kg·m²).
    j2: f64,
    /// The preset with only inertia and viscous friction left (counts per rev not yet set).
    base: Model,
    /// Torque scale (N·m, motor) the excitations are drawn to: RMS of the nominal J·r̈.
    tau: f64,
    /// Position-loop bandwidth (Hz).
    bandwidth_hz: f64,
    /// Input noise σ as a fraction of `tau` (at `Conditions::noise` = 1).
    noise_frac: f64,
    /// A uniform draw in [0, 1) for the shapes that span a decade.
    shape: f64,
    phase: f64,
    sign: f64,
    /// Engaged mode of a backlash's transmission (Hz).
    contact_hz: f64,
    /// Damping ratio of transmission modes (the table's assumption).
    damping_ratio: f64,
    /// Ripple lobes per output revolution.
    ripple_lobes: f64,
    /// Stribeck velocity (rad/s at the output).
    stribeck_velocity: f64,
    /// Stribeck exponent (the table's).
    stribeck_exponent: f64,
}

impl Joint {
    /// Rigid-limit inertia at the motor.
    fn inertia(&self) -> f64 {
        self.i1 + self.j2
    }
    /// Viscous friction at the motor (N·m·s/rad).
    fn viscous(&self) -> f64 {
        self.base
            .effects
            .viscous
            .as_ref()
            .map(|v| v.damping.value)
            .unwrap_or(0.0)
            / (self.n * self.n)
    }
    /// Input noise σ under `cond`.
    fn sigma(&self, cond: &Conditions) -> f64 {
        self.noise_frac * self.tau * cond.noise
    }
}

/// The plant draw: a thesis preset, its load inertia scaled to 0.3–3× the motor's (the
/// presets' 0.05 kg·m² output is a few % of the reflected rotor, which would hide a
/// transmission), stripped to inertia + the table's viscous friction.
fn joint(seed: u64) -> Result<Joint, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ PLANT_STREAM);
    let names = presets::preset_names();
    if names.is_empty() {
        return Err("no presets".into());
    }
    let name = names[rng.random_range(0..names.len())];
    let row = presets::row(name).ok_or_else(|| format!("preset `{name}` has no row"))?;
    let defaults = &presets::table().defaults;
    let mut base = presets::preset(name).ok_or_else(|| format!("unknown preset `{name}`"))?;
    let n = row.ratio;
    let i1 = base.motor.inertia.value;
    let j2 = log_uniform(&mut rng, 0.3, 3.0) * i1;
    let p = &mut base.plant;
    p.output_inertia = Param::fixed(j2 * n * n);
    // The 3-mass cable's proximal stage goes too: at most a 2-mass plant, by a hidden effect.
    p.middle_inertia = Param::fixed(0.0);
    p.proximal_stiffness = Param::fixed(0.0);
    p.proximal_damping = Param::fixed(0.0);
    p.output_damping = Param::fixed(0.0);
    base.motor.damping = Param::fixed(0.0);
    base.effects = EffectSet {
        viscous: Some(viscous::Params {
            damping: Param::fixed(row.viscous()[1]),
        }),
        ..Default::default()
    };
    let tau = log_uniform(&mut rng, 0.05, 0.25);
    let bandwidth_hz = log_uniform(&mut rng, 2.0, 6.0);
    let noise_frac = log_uniform(&mut rng, 0.002, 0.01);
    let shape = rng.random_range(0.0..1.0);
    let phase = rng.random_range(0.0..TAU);
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let contact_hz = log_uniform(&mut rng, 150.0, 300.0);
    // Ripple: a length scale of the references (amplitude at 0.5 Hz, capped by V_MAX), cut
    // into 3–30 periods per ~2.5 of it, rounded to whole lobes per output rev.
    let j = i1 + j2;
    let w = TAU * 0.5;
    let length = (tau / (j * w * w)).min(V_MAX / w);
    let period = 2.5 * length / log_uniform(&mut rng, 3.0, 30.0);
    let ripple_lobes = (TAU * n / period).round().max(1.0);
    let stribeck_velocity = defaults.stribeck_velocity * 10f64.powf(shape - 0.5);
    Ok(Joint {
        n,
        i1,
        j2,
        base,
        tau,
        bandwidth_hz,
        noise_frac,
        shape,
        phase,
        sign,
        contact_hz,
        damping_ratio: defaults.damping_ratio,
        ripple_lobes,
        stribeck_velocity,
        stribeck_exponent: defaults.stribeck_exponent,
    })
}

/// What the supervisor streams and how the card is run for one record.
#[derive(Debug, Clone)]
struct Drive {
    mode: Mode,
    target: Target,
    /// Per streaming tick: the reference (motor rad) or, open loop, the torque (motor N·m).
    signal: Vec<f64>,
    /// Per streaming tick: torque feed-forward put into the setpoint frames (N·m; empty =
    /// none).
    dither: Vec<f64>,
    /// Motor-side PD(+I) gains: N·m/rad, N·m·s/rad, N·m/(rad·s).
    kp: f64,
    kd: f64,
    ki: f64,
    /// Peak speed of the reference (motor rad/s), for the card's velocity limit.
    v_peak: f64,
}

/// `x` smoothed by `passes` centred moving averages of `2·half + 1` samples (prefix sums).
fn smooth(x: &mut [f64], half: usize, passes: usize) {
    let n = x.len();
    for _ in 0..passes {
        let mut pre = Vec::with_capacity(n + 1);
        pre.push(0.0);
        for v in x.iter() {
            pre.push(pre[pre.len() - 1] + v);
        }
        for (i, xi) in x.iter_mut().enumerate() {
            let (lo, hi) = (i.saturating_sub(half), (i + half).min(n - 1));
            *xi = (pre[hi + 1] - pre[lo]) / (hi - lo + 1) as f64;
        }
    }
}

/// 0 → 1 with zero slope at both ends.
fn fade(i: usize) -> f64 {
    let x = (i as f64 / FADE_TICKS as f64).min(1.0);
    x * x * (3.0 - 2.0 * x)
}

/// RMS acceleration and peak speed of `r` (1 ms grid) over the logged part.
fn motion_scale(r: &[f64]) -> (f64, f64) {
    let (mut a2, mut vmax, mut m) = (0.0, 0.0f64, 0usize);
    for i in LEAD_TICKS.max(1)..r.len().saturating_sub(1) {
        let a = (r[i + 1] - 2.0 * r[i] + r[i - 1]) / (PERIOD * PERIOD);
        let v = (r[i + 1] - r[i - 1]) / (2.0 * PERIOD);
        a2 += a * a;
        vmax = vmax.max(v.abs());
        m += 1;
    }
    ((a2 / m.max(1) as f64).sqrt(), vmax)
}

/// A multisine (2–4 components, 0.15–1.2 Hz) and optionally a rounded triangle (reversals
/// and travel), faded in from rest, scaled to J·a_rms = `torque` unless that is faster than
/// [`V_MAX`]. Returns the reference (motor rad) and its peak speed.
fn reference(
    rng: &mut ChaCha8Rng,
    ns: usize,
    j: f64,
    torque: f64,
    triangle: bool,
) -> (Vec<f64>, f64) {
    let mut r = vec![0.0; ns];
    let k = rng.random_range(2..=4);
    for _ in 0..k {
        let f = log_uniform(rng, 0.15, 1.2);
        let a = rng.random_range(0.5..1.0) / k as f64;
        let ph = rng.random_range(0.0..TAU);
        for (i, v) in r.iter_mut().enumerate() {
            *v += a * (TAU * f * i as f64 * PERIOD + ph).sin();
        }
    }
    if triangle {
        let tp = rng.random_range(3.0..8.0);
        let ta = rng.random_range(0.3..0.7);
        let off = rng.random_range(0.0..1.0);
        for (i, v) in r.iter_mut().enumerate() {
            let ph = (i as f64 * PERIOD / tp + off).rem_euclid(1.0);
            *v += ta * (4.0 * (ph - 0.5).abs() - 1.0);
        }
    }
    // Round the triangle's corners (3 passes of a 51 ms box): bounded acceleration.
    smooth(&mut r, 25, 3);
    for (i, v) in r.iter_mut().enumerate().take(FADE_TICKS) {
        *v *= fade(i);
    }
    let (a_rms, v_pk) = motion_scale(&r);
    let s = (torque / (j * a_rms.max(1e-12))).min(V_MAX / v_pk.max(1e-12));
    r.iter_mut().for_each(|v| *v *= s);
    (r, v_pk * s)
}

/// A maximal-length 16-bit PRBS of ±`level`, one bit per `clock` ticks.
fn prbs(rng: &mut ChaCha8Rng, ns: usize, level: f64, clock: usize) -> Vec<f64> {
    let mut s: u16 = rng.random_range(1..=u16::MAX);
    let mut bit = 0.0;
    (0..ns)
        .map(|i| {
            if i % clock == 0 {
                let lsb = s & 1;
                s >>= 1;
                if lsb == 1 {
                    s ^= 0xB400;
                }
                bit = if lsb == 1 { level } else { -level };
            }
            bit
        })
        .collect()
}

/// Open loop: the torque J·r̈ + b·ṙ of a logarithmic position chirp f0 → f1 with constant
/// velocity amplitude, faded in from rest, scaled to RMS `torque`; a tiny dither on top.
fn chirp(rng: &mut ChaCha8Rng, ns: usize, jt: &Joint, torque: f64) -> (Vec<f64>, f64) {
    let f0 = log_uniform(rng, 0.3, 0.6);
    let f1 = log_uniform(rng, 3.0, 6.0);
    let dur = ns as f64 * PERIOD;
    let k = (f1 / f0).ln() / dur;
    let pos: Vec<f64> = (0..ns)
        .map(|i| {
            let t = i as f64 * PERIOD;
            let g = (k * t).exp();
            let phi = TAU * f0 * (g - 1.0) / k;
            fade(i) * (phi.sin() / g)
        })
        .collect();
    let (j, b) = (jt.inertia(), jt.viscous());
    let mut u: Vec<f64> = (0..ns)
        .map(|i| {
            if i == 0 || i + 1 == ns {
                return 0.0;
            }
            let a = (pos[i + 1] - 2.0 * pos[i] + pos[i - 1]) / (PERIOD * PERIOD);
            let v = (pos[i + 1] - pos[i - 1]) / (2.0 * PERIOD);
            j * a + b * v
        })
        .collect();
    let logged = &u[LEAD_TICKS.min(ns)..];
    let rms = (logged.iter().map(|x| x * x).sum::<f64>() / logged.len().max(1) as f64).sqrt();
    // Velocity amplitude of the unit chirp is 2π·f0.
    let s = (torque / rms.max(1e-12)).min(V_MAX / (TAU * f0));
    let level = 0.01 * torque;
    for x in u.iter_mut() {
        *x = s * *x + level * normal(rng);
    }
    (u, s * TAU * f0)
}

/// The excitation of one record (`rows` logged ticks) of `kind`, drawn from (seed, which).
fn drive(jt: &Joint, seed: u64, which: Which, kind: Excitation, rows: usize) -> Drive {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ EXCITE_STREAM ^ which_tag(which));
    let ns = LEAD_TICKS + rows + 4 * FRAME_TICKS;
    let j = jt.inertia();
    let torque = jt.tau * rng.random_range(0.7..1.4);
    let w = TAU * jt.bandwidth_hz;
    let (kp, kd) = (j * w * w, 2.0 * 0.7 * j * w);
    match kind {
        Excitation::PdTracking | Excitation::PidTracking | Excitation::MultisinePrbs => {
            let prbs_case = kind == Excitation::MultisinePrbs;
            let (signal, v_peak) = reference(&mut rng, ns, j, torque, !prbs_case);
            let dither = if prbs_case {
                let level = log_uniform(&mut rng, 0.1, 0.3) * jt.tau;
                let clock = FRAME_TICKS * rng.random_range(1..=3);
                prbs(&mut rng, ns, level, clock)
            } else {
                let level = log_uniform(&mut rng, 0.02, 0.06) * jt.tau;
                (0..ns).map(|_| level * normal(&mut rng)).collect()
            };
            let (mode, ki) = if kind == Excitation::PidTracking {
                (Mode::PositionPid, kp * w / 3.0)
            } else {
                (Mode::PositionPdColocated, 0.0)
            };
            Drive {
                mode,
                target: Target::Position,
                signal,
                dither,
                kp,
                kd,
                ki,
                v_peak,
            }
        }
        Excitation::OpenLoopChirp => {
            let (signal, v_peak) = chirp(&mut rng, ns, jt, torque);
            Drive {
                mode: Mode::TorquePassthrough,
                target: Target::Torque,
                signal,
                dither: Vec::new(),
                kp: 0.0,
                kd: 0.0,
                ki: 0.0,
                v_peak,
            }
        }
    }
}

/// The compliance family's linear spring referred to the motor (stiffness, damping), or none
/// (a rigid transmission, or backlash's contact spring, which acts only in contact).
fn motor_side_spring(jt: &Joint, effects: &[(Family, f64)]) -> Option<(f64, f64)> {
    if effects
        .iter()
        .any(|(f, a)| *f == Family::Backlash && *a > 0.0)
    {
        return None;
    }
    let (_, a) = effects
        .iter()
        .find(|(f, a)| *f == Family::Compliance && *a > 0.0)?;
    let hz = (60.0 / a.sqrt()).clamp(6.0, 5000.0);
    let jr = jt.i1 * jt.j2 / (jt.i1 + jt.j2);
    let w = TAU * hz;
    Some((jr * w * w, 2.0 * jt.damping_ratio * jr * w))
}

/// Linear transmission spring with its coupled mode at `hz` (ζ of the table).
fn spring(jt: &Joint, hz: f64) -> compliance::Params {
    let n2 = jt.n * jt.n;
    let (j1, j2) = (n2 * jt.i1, n2 * jt.j2);
    let jr = j1 * j2 / (j1 + j2);
    let w = TAU * hz;
    compliance::Params {
        stiffness: Param::fixed(jr * w * w),
        soft_stiffness: Param::fixed(0.0),
        knee: Param::fixed(0.0),
        damping: Param::fixed(2.0 * jt.damping_ratio * jr * w),
    }
}

/// The joint's model with the hidden `effects` and the encoders of `cpr`, and the substep
/// rate its stiffest mode needs (≥ the lab's 10 kHz, an even number of substeps per tick so
/// the middle of a hold is a substep boundary).
fn model(jt: &Joint, effects: &[(Family, f64)], cpr: f64) -> (Model, f64) {
    let mut m = jt.base.clone();
    m.motor.counts_per_rev = Param::fixed(cpr.round().max(1.0));
    m.sensors.output_counts_per_rev = Param::fixed(cpr.round().max(1.0));
    let n = jt.n;
    let e = &mut m.effects;
    let mut coulomb_out = 0.0;
    let mut mode_hz: f64 = 0.0;
    for &(family, a) in effects {
        match family {
            Family::Offset => {
                e.offset = Some(offset::Params {
                    torque: Param::fixed(jt.sign * a * n),
                })
            }
            Family::Coulomb => coulomb_out += a.max(0.0) * n,
            Family::Asymmetry => {
                e.asymmetry = Some(asymmetry::Params {
                    viscous_extra: Param::fixed(a * n * n),
                    ..Default::default()
                })
            }
            Family::Stribeck => {
                // The Coulomb level the Stribeck excess sits on: 2–20 nominal noise σ.
                let level = 2.0 * 10f64.powf(jt.shape) * jt.noise_frac * jt.tau;
                coulomb_out += level * n;
                e.stribeck = Some(stribeck::Params {
                    excess: Param::fixed(a.max(0.0) * n),
                    velocity: Param::fixed(jt.stribeck_velocity),
                    exponent: Param::fixed(jt.stribeck_exponent),
                });
            }
            Family::Backlash => {
                if a > 0.0 {
                    e.backlash = Some(backlash::Params {
                        width: Param::fixed((a / n).min(1.0)),
                    });
                    if e.compliance.is_none() {
                        e.compliance = Some(spring(jt, jt.contact_hz));
                        mode_hz = mode_hz.max(jt.contact_hz);
                    }
                }
            }
            Family::Compliance => {
                if a > 0.0 {
                    let hz = (60.0 / a.sqrt()).clamp(6.0, 5000.0);
                    e.compliance = Some(spring(jt, hz));
                    mode_hz = mode_hz.max(hz);
                }
            }
            Family::Ripple => {
                e.ripple = Some(ripple::Params {
                    sin: Param::fixed(a * n * jt.phase.cos()),
                    cos: Param::fixed(a * n * jt.phase.sin()),
                    period: Param::fixed(TAU / jt.ripple_lobes),
                    load_gain: Param::fixed(0.0),
                })
            }
            Family::Gravity => {
                e.gravity = Some(gravity::Params {
                    sin: Param::fixed(a * n * jt.phase.cos()),
                    cos: Param::fixed(a * n * jt.phase.sin()),
                })
            }
            Family::Delay => {
                e.delay = Some(delay::Params {
                    delay: Param::fixed(a.clamp(0.0, 0.006)),
                })
            }
            Family::Quantization => {
                if a > 0.0 {
                    e.quantization = Some(quantization::Params {
                        step: Param::fixed(a * n),
                        gain: Param::fixed(1.0),
                    })
                }
            }
        }
    }
    if coulomb_out > 0.0 {
        e.coulomb = Some(coulomb::Params {
            torque: Param::fixed(coulomb_out),
        });
    }
    // ω·h ≤ 1/4 for the stiffest mode, in whole 2 kHz steps.
    let needed = 4.0 * TAU * mode_hz;
    let rate = 2000.0 * (needed.max(SUBSTEP_RATE) / 2000.0).ceil();
    (m, rate)
}

/// One lab run's log, before the input noise.
#[derive(Debug, Clone, Default)]
struct Log {
    command: Vec<f64>,
    position: Vec<f64>,
    load_position: Vec<f64>,
    position_true: Vec<f64>,
    /// True output angle at the logged instants, referred to the motor (×N).
    load_position_true: Vec<f64>,
    fine_dt: f64,
    fine_command: Vec<f64>,
    fine_position: Vec<f64>,
}

fn send(bus: &mut InprocBus, node: NodeId, m: &Message) -> Result<(), String> {
    let f = m.encode(node).map_err(|e| format!("encode {m:?}: {e:?}"))?;
    bus.send(&f).map_err(|e| format!("bus: {e}"))
}

fn recv(bus: &mut InprocBus) -> Result<Option<jointlab_can::bus::ClassicFrame>, String> {
    bus.try_recv().map_err(|e| format!("bus: {e}"))
}

/// Runs card, supervisor and plant in lockstep (the order of `Lab::step`) and logs `rows`
/// ticks after the lead-in. `disturbance` (one value per row, N·m at the motor) is a torque
/// on the joint after the actuator, for the D/A quantiser's noise.
fn run(
    jt: &Joint,
    d: &Drive,
    effects: &[(Family, f64)],
    cond: &Conditions,
    rows: usize,
    disturbance: Option<&[f64]>,
    seed: u64,
) -> Result<Log, String> {
    let cpr = cond.counts_per_rev.round().max(1.0);
    let (model, rate) = model(jt, effects, cpr);
    let plant = Plant::new(
        &model,
        PlantOptions {
            substep_rate: rate,
            seed,
            environment: Environment::Free,
        },
    )
    .map_err(|e| format!("plant: {e}"))?;
    let parts = ((PERIOD * rate).round() as usize).max(2);
    let n = jt.n;
    let node = NodeId::new(1).ok_or("node 1 is no node number")?;
    let scale = JointScale::new(PERIOD, cpr, cpr, n, jt.i1);
    // The smallest integral gain the card's Q16.16 KI can hold at this encoder.
    let ki_lsb = MOTOR_TORQUE_NM_PER_LSB / (TAU / cpr) / PERIOD / 65536.0;
    let n2 = n * n;
    let v_limit = 3.0 * d.v_peak + 30.0;
    let set = GainSet {
        stiffness: d.kp * n2,
        damping: d.kd * n2,
        integral: if d.ki > 0.0 {
            d.ki.max(ki_lsb) * n2
        } else {
            0.0
        },
        integrator_limit: 1.0,
        torque_limit: model.motor.max_torque.value.min(2.0),
        velocity_limit: v_limit / n,
        quick_stop_damping: 2.0 * 0.7 * jt.inertia() * TAU * 5.0 * n2,
        ..GainSet::default()
    };
    let entries = set
        .entries(&scale, d.mode)
        .map_err(|e| format!("gains: {e}"))?;
    gains::check(&entries, d.mode).map_err(|e| format!("gains: {e}"))?;
    // The supervisor evaluates its trajectory only at its frames: samples there (its
    // piecewise-linear lookup scans them from the start at every frame).
    let samples: Vec<(f64, f64)> = d
        .signal
        .iter()
        .enumerate()
        .step_by(FRAME_TICKS)
        .map(|(i, &v)| {
            let v = if d.target == Target::Position {
                v / n
            } else {
                v
            };
            (i as f64 * PERIOD, v)
        })
        .collect();
    let stream_s = d.signal.len() as f64 * PERIOD;
    let mut sup = Supervisor::new(
        node,
        scale,
        entries,
        d.mode,
        d.target,
        Trajectory::Samples(samples),
        SETPOINT_RATE_HZ,
        Some(stream_s),
    );
    let mut card = CardNode::new(node, true).map_err(|e| format!("card: {e:?}"))?;
    let mut plant = PlantNode::new(plant, node);
    let mut rec = Recorder::new(node, cpr, n);
    let hub = InprocHub::new("lab-truth");
    let mut card_bus = hub.attach("card");
    let mut plant_bus = hub.attach("plant");
    let mut sup_bus = hub.attach("supervisor");
    let mut monitor = hub.attach("recorder");

    let count = parts;
    let mid = count / 2;
    let rad = TAU / cpr;
    let mut log = Log {
        fine_dt: PERIOD / count as f64,
        ..Default::default()
    };
    let mut started: Option<u64> = None;
    let mut tick: u64 = 0;
    while log.command.len() < rows {
        tick += 1;
        let t = tick as f64 * PERIOD;
        // 1. supervisor; the dither rides in its setpoint frames' torque feed-forward
        let msgs = sup.on_tick(tick);
        if started.is_none() && sup.phase() == Phase::Running {
            started = Some(tick);
        }
        let k = started.map(|s| (tick - s) as usize);
        for mut m in msgs {
            if let (Message::SetpointMotion(sp), Some(k)) = (&mut m, k) {
                if let Some(&tff) = d.dither.get(k) {
                    sp.torque_ff = (tff / MOTOR_TORQUE_NM_PER_LSB)
                        .round()
                        .clamp(-32767.0, 32767.0) as i16;
                }
            }
            send(&mut sup_bus, node, &m)?;
        }
        // 2. the plant's sensor frames of this tick
        for f in plant.sensor_frames() {
            plant_bus.send(&f).map_err(|e| format!("bus: {e}"))?;
        }
        // 3. the card, everything queued in bus order
        while let Some(f) = recv(&mut card_bus)? {
            for g in card.on_frame(0, &f).frames {
                card_bus.send(&g).map_err(|e| format!("bus: {e}"))?;
            }
        }
        // 4. the plant takes the actuator frame; 5. the supervisor hears the card
        while let Some(f) = recv(&mut plant_bus)? {
            plant.on_frame(&f);
        }
        while let Some(f) = recv(&mut sup_bus)? {
            if let Ok((from, m)) = Message::decode(&f) {
                sup.on_message(from, &m);
            }
        }
        // 6. record
        while let Some(f) = recv(&mut monitor)? {
            rec.observe(t, &f).map_err(|e| format!("recorder: {e}"))?;
        }
        rec.tick(t, &plant).map_err(|e| format!("recorder: {e}"))?;
        if let Some((code, detail)) = card.card().fault() {
            return Err(format!(
                "card fault at {t:.3} s: {}",
                fault_words(code, detail)
            ));
        }
        for e in &sup.events {
            match e {
                Event::Refused(why) => return Err(format!("supervisor: {why}")),
                Event::Fault(why) => return Err(format!("card fault at {t:.3} s: {why}")),
                Event::Committed => {}
            }
        }
        if started.is_none() && tick > ARM_TICKS {
            return Err("the supervisor never armed the card".into());
        }
        // 7. integrate the tick in its substeps, logging inside the hold when recording
        let row = k.and_then(|k| k.checked_sub(LEAD_TICKS));
        match (row, rec.rows.last()) {
            (Some(r), Some(last)) => {
                let u = last.torque_cmd_nm;
                let w = disturbance.and_then(|w| w.get(r).copied()).unwrap_or(0.0);
                if disturbance.is_some() {
                    plant
                        .plant_mut()
                        .set_environment(Environment::Torque { torque: n * w })
                        .map_err(|e| format!("plant: {e}"))?;
                }
                let zoh_load = plant
                    .sensors()
                    .output_counts
                    .map(|c| f64::from(c) * rad * n)
                    .unwrap_or(f64::NAN);
                let zoh = (last.motor_pos_rad, zoh_load);
                let zoh_output = plant.state().output_angle * n;
                let mut at_mid = None;
                let fine = &mut log.fine_position;
                plant.advance_in_parts(count, |j, p| {
                    let s = p.state();
                    fine.push(s.motor_angle);
                    if j == mid {
                        at_mid = Some(s);
                    }
                });
                // The command plus the disturbance at the motor: what the start model takes
                // as input (the referee's excess is then the hidden effect alone).
                log.fine_command.extend(std::iter::repeat_n(u + w, count));
                log.command.push(u);
                match (cond.logging, at_mid) {
                    (Logging::Mid, Some(s)) => {
                        log.position
                            .push(f64::from(encoder_counts(s.motor_angle, cpr)) * rad);
                        log.load_position
                            .push(f64::from(encoder_counts(s.output_angle, cpr)) * rad * n);
                        log.position_true.push(s.motor_angle);
                        log.load_position_true.push(s.output_angle * n);
                    }
                    _ => {
                        log.position.push(zoh.0);
                        log.load_position.push(zoh.1);
                        log.position_true.push(log.fine_position[r * count]);
                        log.load_position_true.push(zoh_output);
                    }
                }
            }
            _ => plant.advance_in_parts(count, |_, _| {}),
        }
        let s = plant.state();
        if !(s.motor_angle.is_finite() && s.motor_angle.abs() < RUNAWAY_RAD) {
            return Err(format!("the joint ran away at {t:.3} s"));
        }
    }
    Ok(log)
}

/// Rows of a record of `cond.duration`.
fn rows(cond: &Conditions) -> usize {
    ((cond.duration / PERIOD).round() as usize).max(1)
}

impl Truth for LabTruth {
    fn name(&self) -> &'static str {
        "lab"
    }

    fn record(
        &self,
        seed: u64,
        effects: &[(Family, f64)],
        cond: &Conditions,
        which: Which,
    ) -> Result<TruthRecord, String> {
        let jt = joint(seed)?;
        let n = rows(cond);
        let d = drive(&jt, seed, which, cond.excitation, n);
        let sigma = jt.sigma(cond);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ NOISE_STREAM ^ which_tag(which));
        let noise: Vec<f64> = (0..n).map(|_| sigma * normal(&mut rng)).collect();
        let at_torque = effects
            .iter()
            .any(|&(f, a)| f == Family::Quantization && a > 0.0);
        let log = run(
            &jt,
            &d,
            effects,
            cond,
            n,
            at_torque.then_some(noise.as_slice()),
            seed,
        )?;
        let input = if at_torque {
            log.command.clone()
        } else {
            log.command.iter().zip(&noise).map(|(u, w)| u + w).collect()
        };
        Ok(TruthRecord {
            dt: PERIOD,
            time: (0..n).map(|k| k as f64 * PERIOD).collect(),
            input,
            position: log.position,
            load_position: log.load_position,
            input_noise: noise,
            position_true: log.position_true,
            fine_dt: log.fine_dt,
            fine_command: log.fine_command,
            fine_position: log.fine_position,
            inertia: jt.inertia(),
            inertia_load: jt.j2,
            spring: motor_side_spring(&jt, effects),
            load_position_true: log.load_position_true,
            gear_ratio: jt.n,
        })
    }

    fn nominal_amplitude(&self, seed: u64, family: Family, cond: &Conditions) -> f64 {
        let Ok(jt) = joint(seed) else {
            return 0.0;
        };
        let sigma = jt.sigma(cond);
        let d = drive(&jt, seed, Which::Estimation, cond.excitation, rows(cond));
        let logged = &d.signal[LEAD_TICKS.min(d.signal.len())..];
        // Travel and mean speed of the reference (open loop: of the chirp's nominal motion,
        // whose velocity amplitude is v_peak).
        let (travel, mean_speed) = if d.target == Target::Position {
            let (lo, hi) = logged
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            let speed = logged
                .windows(2)
                .map(|w| (w[1] - w[0]).abs() / PERIOD)
                .sum::<f64>()
                / logged.len().max(2) as f64;
            (hi - lo, speed)
        } else {
            (
                d.v_peak / (TAU * 0.5),
                d.v_peak * 2.0 / std::f64::consts::PI,
            )
        };
        match family {
            Family::Offset | Family::Coulomb => sigma,
            Family::Asymmetry => sigma / mean_speed.max(1e-6),
            Family::Stribeck => 2.0 * sigma,
            Family::Backlash => 0.01 * travel,
            Family::Compliance => 1.0,
            Family::Ripple | Family::Gravity => 1.4 * sigma,
            Family::Delay => 0.002,
            Family::Quantization => 3.5 * sigma,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cond(excitation: Excitation, logging: Logging, duration: f64) -> Conditions {
        Conditions {
            dt: 1.0 / 2000.0,
            duration,
            counts_per_rev: 65536.0,
            logging,
            excitation,
            noise: 1.0,
        }
    }

    fn rms(x: &[f64]) -> f64 {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }

    /// Least squares of u = J·a + b·v on the fine grid: (J, b, residual RMS). The second
    /// difference of Störmer–Verlet positions at a substep boundary answers the mean of the
    /// two adjacent substeps' torques, hence the averaged command.
    fn rigid_fit(r: &TruthRecord) -> (f64, f64, f64) {
        let (q, u, h) = (&r.fine_position, &r.fine_command, r.fine_dt);
        let rows: Vec<(f64, f64, f64)> = (1..q.len() - 1)
            .map(|i| {
                let a = (q[i + 1] - 2.0 * q[i] + q[i - 1]) / (h * h);
                let v = (q[i + 1] - q[i - 1]) / (2.0 * h);
                (a, v, 0.5 * (u[i - 1] + u[i]))
            })
            .collect();
        let (mut saa, mut sav, mut svv, mut sau, mut svu) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(a, v, u) in &rows {
            saa += a * a;
            sav += a * v;
            svv += v * v;
            sau += a * u;
            svu += v * u;
        }
        let det = saa * svv - sav * sav;
        let j = (sau * svv - svu * sav) / det;
        let b = (saa * svu - sav * sau) / det;
        let res: Vec<f64> = rows.iter().map(|&(a, v, u)| u - j * a - b * v).collect();
        (j, b, rms(&res))
    }

    #[test]
    fn deterministic_and_validation_is_another_draw_of_the_same_joint() {
        let c = cond(Excitation::PdTracking, Logging::Zoh, 12.0);
        let t0 = std::time::Instant::now();
        let a = LabTruth
            .record(7, &[(Family::Coulomb, 0.01)], &c, Which::Estimation)
            .unwrap();
        eprintln!("one 12 s record: {:.3} s", t0.elapsed().as_secs_f64());
        let b = LabTruth
            .record(7, &[(Family::Coulomb, 0.01)], &c, Which::Estimation)
            .unwrap();
        assert_eq!(a.input, b.input);
        assert_eq!(a.position, b.position);
        assert_eq!(a.load_position, b.load_position);
        assert_eq!(a.fine_position, b.fine_position);
        assert_eq!(a.input_noise, b.input_noise);
        assert_eq!(a.dt, 1e-3, "the card's rate, not Conditions::dt");
        assert_eq!(a.time.len(), 12_000);
        assert_eq!(a.fine_command.len(), a.fine_position.len());
        assert_eq!(a.fine_position.len(), 12_000 * 10);
        let v = LabTruth
            .record(7, &[(Family::Coulomb, 0.01)], &c, Which::Validation)
            .unwrap();
        assert_eq!(v.inertia, a.inertia);
        assert_ne!(v.input, a.input);
        // The noise is the seed's, not the effect's: the effect-free twin shares it.
        let twin = LabTruth.record(7, &[], &c, Which::Estimation).unwrap();
        assert_eq!(twin.input_noise, a.input_noise);
        assert_ne!(twin.position, a.position);
    }

    #[test]
    fn every_family_and_excitation_records_at_its_nominal_amplitude() {
        // The encoder and noise extremes of `Conditions`, both loggings.
        for (seed, cpr, noise, logging) in [
            (3u64, 4096.0, 0.3, Logging::Zoh),
            (11, 1048576.0, 3.0, Logging::Mid),
        ] {
            for excitation in Excitation::ALL {
                let c = Conditions {
                    counts_per_rev: cpr,
                    noise,
                    ..cond(excitation, logging, 3.0)
                };
                for family in Family::ALL {
                    let a = LabTruth.nominal_amplitude(seed, family, &c);
                    assert!(a.is_finite() && a > 0.0, "{family:?}: {a}");
                    let r = LabTruth
                        .record(seed, &[(family, a)], &c, Which::Estimation)
                        .unwrap_or_else(|e| panic!("seed {seed} {family:?} {excitation:?}: {e}"));
                    assert_eq!(r.input.len(), 3000);
                    for x in [&r.input, &r.position, &r.load_position, &r.position_true] {
                        assert!(x.iter().all(|v| v.is_finite()), "{family:?} {excitation:?}");
                    }
                    // It moved: several hundred counts of travel at least.
                    let (lo, hi) = r
                        .position
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                            (a.min(x), b.max(x))
                        });
                    assert!(hi - lo > 0.5, "{family:?} {excitation:?}: {}", hi - lo);
                    // The D/A quantiser's log is the card's exact command (wire LSBs).
                    let exact = r.input.iter().all(|u| {
                        ((u / MOTOR_TORQUE_NM_PER_LSB) - (u / MOTOR_TORQUE_NM_PER_LSB).round())
                            .abs()
                            < 1e-6
                    });
                    assert_eq!(exact, family == Family::Quantization, "{family:?}");
                }
            }
        }
    }

    #[test]
    fn the_effect_free_record_is_a_rigid_inertia_with_viscous_friction() {
        for (seed, excitation) in [
            (5u64, Excitation::PdTracking),
            (8, Excitation::OpenLoopChirp),
            (13, Excitation::PidTracking),
            (21, Excitation::MultisinePrbs),
        ] {
            let c = cond(excitation, Logging::Zoh, 4.0);
            let free = LabTruth.record(seed, &[], &c, Which::Estimation).unwrap();
            let (j, b, res) = rigid_fit(&free);
            let jt = joint(seed).unwrap();
            assert!(
                (j / free.inertia - 1.0).abs() < 2e-3,
                "J {j} vs {}",
                free.inertia
            );
            assert!(
                (b / jt.viscous() - 1.0).abs() < 0.05,
                "b {b} vs {}",
                jt.viscous()
            );
            let u = rms(&free.fine_command);
            assert!(res < 1e-3 * u, "seed {seed}: residual {res:.3e} of {u:.3e}");
            // The same fit on records with an effect at its nominal amplitude leaves far more.
            for family in [
                Family::Coulomb,
                Family::Offset,
                Family::Quantization,
                Family::Delay,
            ] {
                let a = LabTruth.nominal_amplitude(seed, family, &c);
                let r = LabTruth
                    .record(seed, &[(family, a)], &c, Which::Estimation)
                    .unwrap();
                let (_, _, with) = rigid_fit(&r);
                assert!(
                    with > 10.0 * res,
                    "{family:?}: {with:.3e} vs free {res:.3e}"
                );
            }
        }
    }

    #[test]
    fn the_backlash_gap_is_on_the_motor_axis_and_the_load_encoder_shows_it() {
        let c = Conditions {
            counts_per_rev: 1048576.0,
            ..cond(Excitation::PdTracking, Logging::Zoh, 4.0)
        };
        for seed in [0u64, 2] {
            let a = LabTruth.nominal_amplitude(seed, Family::Backlash, &c);
            let r = LabTruth
                .record(seed, &[(Family::Backlash, a)], &c, Which::Estimation)
                .unwrap();
            let (lo, hi) = r
                .position
                .iter()
                .zip(&r.load_position)
                .map(|(m, l)| m - l)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(x), b.max(x))
                });
            // The motor-minus-load deflection spans the gap (plus the stiff spring's wind-up).
            assert!(
                (hi - lo) / a > 0.98 && (hi - lo) / a < 1.15,
                "gap {a:.4}, span {:.4}",
                hi - lo
            );
            let free = LabTruth.record(seed, &[], &c, Which::Estimation).unwrap();
            let span = free
                .position
                .iter()
                .zip(&free.load_position)
                .map(|(m, l)| (m - l).abs())
                .fold(0.0, f64::max);
            // Rigid: the two encoders agree to the load encoder's step on the motor axis.
            let step = TAU / 1048576.0 * (joint(seed).unwrap().n + 1.0);
            assert!(span <= step + 1e-12, "{span:.3e} vs step {step:.3e}");
        }
    }

    #[test]
    fn mid_logs_the_same_run_half_a_tick_later() {
        let seed = 9;
        let zc = cond(Excitation::PdTracking, Logging::Zoh, 4.0);
        let mc = Conditions {
            logging: Logging::Mid,
            ..zc
        };
        let z = LabTruth
            .record(seed, &[(Family::Backlash, 0.02)], &zc, Which::Estimation)
            .unwrap();
        let m = LabTruth
            .record(seed, &[(Family::Backlash, 0.02)], &mc, Which::Estimation)
            .unwrap();
        // Logging does not touch the physics or the command.
        assert_eq!(z.fine_position, m.fine_position);
        assert_eq!(z.input, m.input);
        let c = (z.dt / z.fine_dt).round() as usize;
        for k in 0..z.time.len() {
            assert_eq!(z.position_true[k], z.fine_position[k * c]);
            assert_eq!(m.position_true[k], m.fine_position[k * c + c / 2]);
        }
        // mid − zoh = v·T/2: regress on the central-difference velocity.
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for k in 1..z.time.len() - 1 {
            let v = (z.position_true[k + 1] - z.position_true[k - 1]) / (2.0 * z.dt);
            let d = m.position_true[k] - z.position_true[k];
            sxy += v * d;
            sxx += v * v;
        }
        let lag = sxy / sxx;
        assert!((lag / (0.5 * z.dt) - 1.0).abs() < 0.02, "lag {lag:.4e} s");
        // The logged encoders follow (to their counts).
        let q = TAU / 65536.0;
        for k in 0..z.time.len() {
            assert!((m.position[k] - m.position_true[k]).abs() <= q + 1e-12);
            assert!((z.position[k] - z.position_true[k]).abs() <= q + 1e-12);
        }
    }

    #[test]
    fn driving_the_plant_in_substeps_is_the_lab_physics() {
        let jt = joint(4).unwrap();
        let fx = [
            (Family::Compliance, 1.0),
            (Family::Ripple, 0.01),
            (Family::Delay, 0.001),
        ];
        let (m, rate) = model(&jt, &fx, 65536.0);
        let opts = PlantOptions {
            substep_rate: rate,
            seed: 1,
            environment: Environment::Free,
        };
        let node = NodeId::new(1).unwrap();
        let mut whole = PlantNode::new(Plant::new(&m, opts).unwrap(), node);
        let mut split = PlantNode::new(Plant::new(&m, opts).unwrap(), node);
        let parts = (PERIOD * rate).round() as usize;
        for k in 0..2000u32 {
            for p in [&mut whole, &mut split] {
                for f in p.sensor_frames() {
                    let _ = f;
                }
                let seq = p.seq();
                let torque = (3000.0 * (f64::from(k) * 0.01).sin()) as i16;
                let a = controller::proto::Actuator {
                    torque,
                    seq,
                    limits: controller::proto::LimitFlags::NONE,
                    drive: true,
                    fault: false,
                };
                let f: jointlab_can::bus::ClassicFrame = Message::Actuator(a).encode(node).unwrap();
                p.on_frame(&f);
            }
            whole.advance();
            split.advance_in_parts(parts, |_, _| {});
            let (a, b) = (whole.state(), split.state());
            assert!(
                (a.motor_angle - b.motor_angle).abs() < 1e-9 * (1.0 + a.motor_angle.abs()),
                "tick {k}: {} vs {}",
                a.motor_angle,
                b.motor_angle
            );
            assert!((a.output_angle - b.output_angle).abs() < 1e-9 * (1.0 + a.output_angle.abs()));
        }
    }

    #[test]
    fn a_fault_or_a_runaway_is_an_error_not_a_record() {
        // Open loop, a bias torque far above the chirp: the joint runs into the card's
        // velocity limit (or away), which is no recording of the joint.
        let c = cond(Excitation::OpenLoopChirp, Logging::Zoh, 6.0);
        let e = LabTruth.record(3, &[(Family::Offset, 1.5)], &c, Which::Estimation);
        let why = e.expect_err("a runaway joint must not be recorded");
        assert!(
            why.contains("velocity") || why.contains("ran away"),
            "{why}"
        );
        // A transport delay far beyond what a few-Hz loop tolerates is still bounded at 6 ms
        // and records.
        let c = cond(Excitation::PdTracking, Logging::Zoh, 2.0);
        assert!(LabTruth
            .record(3, &[(Family::Delay, 1.0)], &c, Which::Estimation)
            .is_ok());
    }
}
