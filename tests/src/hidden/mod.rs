//! Hidden-effect trials: simulate a joint with one (or two) effects the model does not have,
//! and check that `diagnose` names it, `fit --add` removes it, and null trials stay quiet.
//!
//! * The truth ([`truth`]) is an independent two-mass + LuGre + RK4 simulator.
//! * Each trial draws the plant (inertias, viscous friction over a decade), the excitation
//!   (closed-loop PD tracking, or feed-forward + soft PD, following a random multi-sine +
//!   triangle reference with enough reversals and travel), a little broadband dither on the
//!   command, input sensor noise and encoder quantisation (2¹⁶ counts/rev), and the hidden
//!   effect's shape parameters over a decade. For a hidden D/A quantiser the input noise is a
//!   torque disturbance after the converter and the recorded command is exact (see
//!   `NoiseAt`).
//! * **Strength** ρ = excess RMS of the best baseline fit over the noise:
//!   `ρ = √(RMS_b² − RMS_0²)/RMS_0`, where `RMS_b` is the baseline's equation-error RMS on the
//!   trial and `RMS_0` on its *twin* — the same excitation, noise and seeds with the effect
//!   switched off. The effect amplitude is set by two secant steps to hit a target ρ; the
//!   measured ρ is what is reported.
//! * **Noise floor** for the refit check = the baseline's RMS on the validation twin (fitted on
//!   the estimation twin): the best a correct model can do on that record.

pub mod lab;
pub mod record;
pub mod truth;

use hil_host::workbench::data::{Columns, Recording};
use hil_host::workbench::diagnose::{diagnose, Options};
use hil_host::workbench::model::Model;
use hil_host::workbench::refine;
use hil_host::workbench::residual::{self, Prepared};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use sim_plant::effects::{EffectKind, Intersample, Shape};

use truth::{Controller, Plant};

/// Hidden-effect families (the vocabulary minus `viscous`, which the baseline has).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Family {
    /// Constant torque offset.
    Offset,
    /// Coulomb friction (LuGre with Fs = Fc).
    Coulomb,
    /// Direction-dependent viscous friction.
    Asymmetry,
    /// Stiction above Coulomb (LuGre Fs > Fc); the starting model already has Coulomb.
    Stribeck,
    /// Dead zone in the transmission.
    Backlash,
    /// Finite transmission stiffness.
    Compliance,
    /// Load-position-periodic torque.
    Ripple,
    /// Gravity on the load.
    Gravity,
    /// Pure input delay.
    Delay,
    /// D/A quantisation of the applied torque.
    Quantization,
}

impl Family {
    /// All families.
    pub const ALL: [Family; 10] = [
        Family::Offset,
        Family::Coulomb,
        Family::Asymmetry,
        Family::Stribeck,
        Family::Backlash,
        Family::Compliance,
        Family::Ripple,
        Family::Gravity,
        Family::Delay,
        Family::Quantization,
    ];

    /// The workbench effect name it should be diagnosed as.
    pub fn name(self) -> &'static str {
        match self {
            Family::Offset => "offset",
            Family::Coulomb => "coulomb",
            Family::Asymmetry => "asymmetry",
            Family::Stribeck => "stribeck",
            Family::Backlash => "backlash",
            Family::Compliance => "compliance",
            Family::Ripple => "ripple",
            Family::Gravity => "gravity",
            Family::Delay => "delay",
            Family::Quantization => "quantization",
        }
    }

    /// Library effect.
    pub fn kind(self) -> EffectKind {
        EffectKind::from_name(self.name()).expect("family names are library names")
    }
}

/// Everything drawn for one trial except the effect amplitude.
#[derive(Debug, Clone)]
pub struct Draw {
    base: Plant,
    shape: f64,
    phase: f64,
    sign: f64,
    est: Excitation,
    val: Excitation,
    noise_u: f64,
}

#[derive(Debug, Clone)]
struct Excitation {
    reference: Vec<f64>,
    velocity: Vec<f64>,
    accel: Vec<f64>,
    dither: Vec<f64>,
    input_noise: Vec<f64>,
    sensor_noise: Vec<f64>,
    /// Noise of a load-side encoder (same kind and level as the motor encoder's), drawn from a
    /// stream of its own (see [`draw`]) so that the motor-only trials are unchanged.
    load_sensor_noise: Vec<f64>,
    kp: f64,
    kd: f64,
    feedforward: bool,
}

/// Differentiator cut-off for the trials, Hz (`HIDDEN_CUTOFF` overrides, for experiments).
pub fn cutoff() -> Option<f64> {
    std::env::var("HIDDEN_CUTOFF")
        .ok()
        .and_then(|s| s.parse().ok())
        .or(Some(CUTOFF_HZ))
}

/// The trials' differentiator cut-off: 5× above the fastest reference component and the
/// compliance modes down to 6 Hz, far enough below the rate at which 2¹⁶-count encoder
/// quantisation dominates the second derivative.
pub const CUTOFF_HZ: f64 = 40.0;

/// Samples per record (20 s at 1 kHz).
pub const N: usize = 20_000;
/// Sample period.
pub const DT: f64 = 1e-3;
const ENCODER: f64 = std::f64::consts::TAU / 65_536.0;
/// Seed offset of the load encoder's noise stream.
const LOAD_ENCODER_STREAM: u64 = 0x10AD_E4C0_DE00_0000;

/// How a trial is recorded, beyond its families and strength.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrialOptions {
    /// Record a load-side (output) encoder too and pass it as `Recording::load_output`: the
    /// same 2¹⁶ counts/rev quantisation and the same sensor noise level as the motor encoder
    /// (an independent draw), logged at the same instants. Off by default: the trials'
    /// recordings have the motor encoder only.
    pub load_encoder: bool,
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

fn excitation(rng: &mut ChaCha8Rng, j: f64, noise_u: f64) -> Excitation {
    let n = N + 4;
    let mut r = vec![0.0; n];
    let travel = log_uniform(rng, 0.8, 3.0);
    let k = rng.random_range(2..=4);
    for _ in 0..k {
        let f = log_uniform(rng, 0.1, 1.2);
        let a = travel / k as f64 * rng.random_range(0.5..1.0);
        let ph = rng.random_range(0.0..std::f64::consts::TAU);
        for (i, v) in r.iter_mut().enumerate() {
            *v += a * (std::f64::consts::TAU * f * i as f64 * DT + ph).sin();
        }
    }
    // A triangle gives constant-velocity plateaus (friction maps) and clean reversals.
    let tp = rng.random_range(2.0..6.0);
    let ta = travel * rng.random_range(0.2..0.5);
    for (i, v) in r.iter_mut().enumerate() {
        let ph = (i as f64 * DT / tp).rem_euclid(1.0);
        *v += ta * (4.0 * (ph - 0.5).abs() - 1.0);
    }
    // Smooth the corners so the reference acceleration stays bounded (3 passes of a 50 ms box).
    for _ in 0..3 {
        let w = 25;
        let c = r.clone();
        for (i, ri) in r.iter_mut().enumerate() {
            let (lo, hi) = (i.saturating_sub(w), (i + w).min(n - 1));
            *ri = c[lo..=hi].iter().sum::<f64>() / (hi - lo + 1) as f64;
        }
    }
    let vel: Vec<f64> = (0..n)
        .map(|i| (r[(i + 1).min(n - 1)] - r[i.saturating_sub(1)]) / (2.0 * DT))
        .collect();
    let acc: Vec<f64> = (0..n)
        .map(|i| (vel[(i + 1).min(n - 1)] - vel[i.saturating_sub(1)]) / (2.0 * DT))
        .collect();
    let feedforward = rng.random_bool(0.5);
    let wc = std::f64::consts::TAU
        * if feedforward {
            log_uniform(rng, 0.5, 2.0)
        } else {
            log_uniform(rng, 3.0, 8.0)
        };
    let dn = Normal::new(0.0, 1.0).expect("normal");
    let dither_level = log_uniform(rng, 0.1, 0.5) * j;
    Excitation {
        reference: r,
        velocity: vel,
        accel: acc,
        dither: (0..n).map(|_| dither_level * dn.sample(rng)).collect(),
        input_noise: (0..n).map(|_| noise_u * dn.sample(rng)).collect(),
        sensor_noise: (0..n).map(|_| 0.2 * ENCODER * dn.sample(rng)).collect(),
        load_sensor_noise: Vec::new(),
        kp: j * wc * wc,
        kd: 2.0 * 0.7 * j * wc,
        feedforward,
    }
}

/// Draw a trial's plant, shapes and excitations.
pub fn draw(seed: u64) -> Draw {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let j1 = log_uniform(&mut rng, 1e-3, 1e-2);
    let j2 = log_uniform(&mut rng, 3e-3, 3e-2);
    let b = log_uniform(&mut rng, 0.005, 0.05);
    let base = Plant::rigid(j1, j2, b);
    let noise_u = log_uniform(&mut rng, 0.002, 0.01);
    let shape = rng.random_range(0.0..1.0);
    let phase = rng.random_range(0.0..std::f64::consts::TAU);
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let mut est = excitation(&mut rng, j1 + j2, noise_u);
    let mut val = excitation(&mut rng, j1 + j2, noise_u);
    // The load encoder's noise comes from a separate stream: drawing it from `rng` would
    // shift every later draw and change the default (motor-encoder-only) trials.
    let mut lrng = ChaCha8Rng::seed_from_u64(seed ^ LOAD_ENCODER_STREAM);
    let dn = Normal::new(0.0, 1.0).expect("normal");
    for e in [&mut est, &mut val] {
        e.load_sensor_noise = (0..e.sensor_noise.len())
            .map(|_| 0.2 * ENCODER * dn.sample(&mut lrng))
            .collect();
    }
    Draw {
        base,
        shape,
        phase,
        sign,
        est,
        val,
        noise_u,
    }
}

/// The plant with `family` at amplitude `a` (the unit depends on the family).
pub fn with_effect(d: &Draw, base: &Plant, family: Family, a: f64, travel: f64) -> Plant {
    let mut p = *base;
    // `shape` ∈ [0,1) → a decade.
    let decade = |lo: f64| lo * 10f64.powf(d.shape);
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
        Family::Backlash => p.backlash = a,
        Family::Compliance => {
            let f = (60.0 / a.max(1e-6).sqrt()).max(6.0);
            let w = std::f64::consts::TAU * f;
            let jr = p.j1 * p.j2 / (p.j1 + p.j2);
            p.k = jr * w * w;
            p.c = 2.0 * 0.05 * jr * w;
        }
        Family::Ripple => {
            p.ripple_amp = a;
            p.ripple_period = travel / decade(3.0);
            p.ripple_phase = d.phase;
        }
        Family::Gravity => {
            p.gravity = a;
            p.gravity_phase = d.phase;
        }
        Family::Delay => p.delay = a.min(0.006),
        Family::Quantization => p.quantum = a,
    }
    p
}

struct Pd<'a> {
    e: &'a Excitation,
    prev: f64,
    vf: f64,
    j: f64,
    b: f64,
}

impl Controller for Pd<'_> {
    fn command(&mut self, k: usize, meas: f64) -> f64 {
        let v = if k == 0 { 0.0 } else { (meas - self.prev) / DT };
        self.prev = meas;
        // 1st-order 150 Hz velocity filter, as a motor card would have.
        let alpha = 1.0 - (-std::f64::consts::TAU * 150.0 * DT).exp();
        self.vf += alpha * (v - self.vf);
        let e = self.e;
        let mut u = e.kp * (e.reference[k] - meas) + e.kd * (e.velocity[k] - self.vf) + e.dither[k];
        if e.feedforward {
            u += self.j * e.accel[k] + self.b * e.velocity[k];
        }
        u
    }
}

/// Where a trial's input noise (σ = `noise_u`) enters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NoiseAt {
    /// On the recorded input: a measured torque/current with sensor noise.
    Recording,
    /// On the torque the motor applies, after the D/A converter: the recorded input is then
    /// the card's digital command, exact. This is the only consistent arrangement for a
    /// hidden *D/A quantiser*: a recorded value carrying sensor noise would be a measurement
    /// taken after the converter, and would already show its steps. The noise floor of the
    /// equation error is the same either way (`u + w = J·a + …` leaves −w in the residual).
    Torque,
}

impl NoiseAt {
    fn for_trial(families: &[Family]) -> Self {
        if families.contains(&Family::Quantization) {
            NoiseAt::Torque
        } else {
            NoiseAt::Recording
        }
    }
}

/// Simulate one record of plant `p` under excitation `e`.
fn record(p: &Plant, e: &Excitation, noise: NoiseAt, label: &str) -> Recording {
    record_with_load(p, e, noise, label, false).0
}

/// [`record`] and the truth's load and motor positions at the logged samples (never shown to
/// the workbench: probes compare with them). With `load_encoder` the recording also holds the
/// load position as a load-side encoder reports it (quantised, with its own sensor noise).
fn record_with_load(
    p: &Plant,
    e: &Excitation,
    noise: NoiseAt,
    label: &str,
    load_encoder: bool,
) -> (Recording, [Vec<f64>; 2]) {
    let mut ctl = Pd {
        e,
        prev: e.reference[0],
        vf: 0.0,
        j: p.j1 + p.j2,
        b: p.b_pos,
    };
    let mut k = 0;
    let mut sense = |x: f64| {
        let m = ENCODER * ((x + e.sensor_noise[k]) / ENCODER).round();
        k += 1;
        m
    };
    let mut j = 0;
    let mut log = |x: f64| {
        let m = ENCODER * ((x + e.sensor_noise[(j + N / 2) % N]) / ENCODER).round();
        j += 1;
        m
    };
    let m = truth::simulate(
        p,
        &mut ctl,
        N,
        DT,
        10,
        e.reference[0],
        truth::Sensors {
            control: &mut sense,
            log: &mut log,
        },
        if noise == NoiseAt::Torque {
            &e.input_noise
        } else {
            &[]
        },
    );
    let load_output = load_encoder.then(|| {
        m.load_position
            .iter()
            .zip(&e.load_sensor_noise)
            .map(|(x, n)| ENCODER * ((x + n) / ENCODER).round())
            .collect()
    });
    let rec = Recording {
        path: label.into(),
        input: match noise {
            NoiseAt::Recording => m
                .command
                .iter()
                .zip(&e.input_noise)
                .map(|(u, n)| u + n)
                .collect(),
            NoiseAt::Torque => m.command,
        },
        time: m.time,
        output: m.motor_position,
        load_output,
        dt: DT,
        units: ("N·m".into(), "rad".into()),
        // The truth logs each command with the position at the middle of its hold.
        columns: Columns::new("torque_Nm", "q_rad").with_intersample(Intersample::Mid),
        resampled: None,
        recorded: None,
    };
    (rec, [m.load_position, m.motor_true])
}

/// The starting model a family is diagnosed against: the default baseline, plus Coulomb for
/// Stribeck (Stribeck is a refinement of Coulomb, so its truth always has Coulomb too).
pub fn start_model(families: &[Family]) -> Model {
    let mut m = Model::baseline();
    if families.contains(&Family::Stribeck) {
        m.add(EffectKind::Coulomb, Shape::default());
    }
    m
}

fn fitted_rms(model: &Model, p: &Prepared) -> (f64, Model) {
    let mut m = model.clone();
    if refine::refit_all(&mut m, p).is_err() {
        return (f64::NAN, m);
    }
    let r = residual::equation_error(&m, p).residual;
    (
        (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt(),
        m,
    )
}

fn rho(b: f64, floor: f64) -> f64 {
    (b * b - floor * floor).max(0.0).sqrt() / floor
}

/// A generated trial: estimation and validation records with the hidden effect(s), and their
/// effect-free twins' numbers.
#[derive(Debug, Clone)]
pub struct Trial {
    /// Hidden families (empty = null trial).
    pub families: Vec<Family>,
    /// Estimation record.
    pub est: Recording,
    /// Validation record.
    pub val: Recording,
    /// Measured strength on the estimation record.
    pub rho: f64,
    /// Baseline RMS on the estimation twin.
    pub floor_est: f64,
    /// Noise floor on validation: baseline (fitted on the estimation twin) on the validation twin.
    pub floor_val: f64,
    /// Input sensor noise σ.
    pub noise_u: f64,
    /// The truth plant (for probes; the workbench never sees it).
    pub plant: Plant,
    /// The truth's load position on the estimation and validation records (for probes).
    pub load: [Vec<f64>; 2],
    /// The truth's motor position (before the encoder) on both records (for probes).
    pub motor: [Vec<f64>; 2],
}

/// A record whose loop stayed bounded (finite, |u| < 10⁶, |x| < 50 rad).
fn bounded(rec: &Recording) -> bool {
    rec.output
        .iter()
        .chain(&rec.input)
        .all(|x| x.is_finite() && x.abs() < 1e6)
        && rec.output.iter().all(|x| x.abs() < 50.0)
}

/// Generate a trial with `families` hidden, each scaled to `target_rho` on its own. `None` if
/// the drawn loop is unstable with the effect (a delay or backlash can destabilise the PD
/// loop; such runs are not a diagnosis problem and are counted separately).
pub fn generate(seed: u64, families: &[Family], target_rho: f64) -> Option<Trial> {
    generate_with(seed, families, target_rho, TrialOptions::default())
}

/// [`generate`] with recording options (a load encoder). Only the trial's estimation and
/// validation records change; the strength calibration and the noise floor (twins, baseline
/// fits) do not use a load position and are the same as without the options.
pub fn generate_with(
    seed: u64,
    families: &[Family],
    target_rho: f64,
    opts: TrialOptions,
) -> Option<Trial> {
    let d = draw(seed);
    let mut base = d.base;
    if families.contains(&Family::Stribeck) {
        // Coulomb is part of the truth (and of the starting model); 1–10 noise levels.
        let fc = d.noise_u * 10f64.powf(d.shape) * 2.0;
        base.fc = fc;
        base.fs = fc;
    }
    let start = start_model(families);
    let noise = NoiseAt::for_trial(families);
    let twin_e = record(&base, &d.est, noise, "twin-est");
    let twin_v = record(&base, &d.val, noise, "twin-val");
    // The twins are the floor's reference: a twin whose loop diverges (a PD on a stiff
    // two-mass base can go unstable on one excitation and not the other) leaves the trial
    // without a floor, so the draw counts as unstable like one the effect destabilises.
    if !bounded(&twin_e) || !bounded(&twin_v) {
        return None;
    }
    let pe0 = Prepared::new(&twin_e, cutoff());
    let (floor_est, m0) = fitted_rms(&start, &pe0);
    let pv0 = Prepared::new(&twin_v, cutoff());
    let rv = residual::equation_error(&m0, &pv0).residual;
    let floor_val = (rv.iter().map(|v| v * v).sum::<f64>() / rv.len() as f64).sqrt();
    let travel = {
        let (lo, hi) = pe0
            .position
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        hi - lo
    };
    let mean_speed = pe0.velocity.iter().map(|v| v.abs()).sum::<f64>() / pe0.len() as f64;
    let mut plant = base;
    for &f in families {
        let a0 = match f {
            Family::Offset | Family::Coulomb => floor_est,
            Family::Asymmetry => floor_est / mean_speed.max(1e-6),
            Family::Stribeck => 2.0 * floor_est,
            Family::Backlash => 0.01 * travel,
            Family::Compliance => 1.0,
            Family::Ripple | Family::Gravity => 1.4 * floor_est,
            Family::Delay => 0.002,
            Family::Quantization => 3.5 * floor_est,
        };
        // Two secant steps on the amplitude for the target strength (ρ is ~linear in it).
        // Each effect is calibrated on the effect-free plant, *on its own*: calibrating the
        // second of a pair on a plant that already carries the first would scale the pair's
        // combined strength to the target and leave the second effect far weaker.
        let mut a = a0;
        // A quantiser's strength is a ragged function of its step (how many steps the command
        // crosses, how they line up with its plateaus): two more secant steps.
        let steps = if f == Family::Quantization { 4 } else { 2 };
        for _ in 0..steps {
            let p = with_effect(&d, &base, f, a, travel);
            let r = record(&p, &d.est, noise, "calib");
            let (b, _) = fitted_rms(&start, &Prepared::new(&r, cutoff()));
            let rr = rho(b, floor_est);
            a *= if !rr.is_finite() {
                0.3 // diverged: back off
            } else if rr > 1e-3 {
                (target_rho / rr).clamp(0.05, 20.0)
            } else {
                20.0
            };
        }
        plant = with_effect(&d, &plant, f, a, travel);
    }
    if std::env::var_os("HIDDEN_DEBUG").is_some() {
        eprintln!("truth: {plant:?}; input noise σ {:.3e}", d.noise_u);
        let twin: Vec<String> = m0
            .params()
            .iter()
            .map(|p| format!("{} {:.6e}", p.name, p.value))
            .collect();
        eprintln!(
            "twin fit: {} (est floor {floor_est:.4e}, val floor {floor_val:.4e})",
            twin.join(", ")
        );
    }
    let (est, [est_load, est_motor]) = record_with_load(
        &plant,
        &d.est,
        noise,
        &format!("hidden seed {seed} est"),
        opts.load_encoder,
    );
    let (val, [val_load, val_motor]) = record_with_load(
        &plant,
        &d.val,
        noise,
        &format!("hidden seed {seed} val"),
        opts.load_encoder,
    );
    let (b, _) = fitted_rms(&start, &Prepared::new(&est, cutoff()));
    let r = rho(b, floor_est);
    if !r.is_finite() || r > 20.0 * target_rho.max(1.0) || !bounded(&est) || !bounded(&val) {
        return None;
    }
    Some(Trial {
        families: families.to_vec(),
        rho: r,
        est,
        val,
        floor_est,
        floor_val,
        noise_u: d.noise_u,
        plant,
        load: [est_load, val_load],
        motor: [est_motor, val_motor],
    })
}

/// What one trial showed.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Hidden families.
    pub families: Vec<Family>,
    /// Measured strength.
    pub rho: f64,
    /// Rank-1 candidate.
    pub top: Option<String>,
    /// Verdict (None = "no significant missing effect").
    pub verdict: Option<String>,
    /// Validation RMS after `fit --add <truth>` / noise floor.
    pub val_ratio: f64,
    /// Effects `--auto` added (pair trials).
    pub auto_added: Vec<String>,
}

impl Outcome {
    /// Rank-1 candidate is the hidden effect.
    pub fn rank1_ok(&self) -> bool {
        self.families.len() == 1 && self.top.as_deref() == Some(self.families[0].name())
    }
    /// Null trial stayed quiet.
    pub fn null_ok(&self) -> bool {
        self.families.is_empty() && self.verdict.is_none()
    }
    /// Both hidden effects were added by `--auto`.
    pub fn pair_ok(&self) -> bool {
        self.families.len() == 2
            && self
                .families
                .iter()
                .all(|f| self.auto_added.iter().any(|a| a == f.name()))
    }
}

/// Run one trial: diagnose; for single-effect trials `fit --add <truth>` and score validation;
/// for pairs `diagnose --auto`. `None` if the trial's loop was unstable.
pub fn run(seed: u64, families: &[Family], target_rho: f64) -> Option<Outcome> {
    run_with(seed, families, target_rho, TrialOptions::default())
}

/// [`run`] with recording options (see [`TrialOptions`]).
pub fn run_with(
    seed: u64,
    families: &[Family],
    target_rho: f64,
    opts: TrialOptions,
) -> Option<Outcome> {
    let t = generate_with(seed, families, target_rho, opts)?;
    let pe = Prepared::new(&t.est, cutoff());
    let pv = Prepared::new(&t.val, cutoff());
    let mut model = start_model(families);
    refine::refit_all(&mut model, &pe).ok()?;
    let opts = Options::default();
    let d = diagnose(&model, &pe, &opts);
    if std::env::var_os("HIDDEN_DEBUG").is_some() {
        eprintln!(
            "ρ = {:.2}, floor {:.3e}\n{}",
            t.rho,
            t.floor_est,
            d.to_text()
        );
        if let Some(c) = d.candidates.iter().find(|c| c.effect == "compliance") {
            eprintln!(
                "compliance shape: f {:.1} Hz, zeta {:.2}",
                c.shape.compliance_frequency, c.shape.compliance_damping
            );
        }
    }
    let mut out = Outcome {
        families: families.to_vec(),
        rho: t.rho,
        top: d.candidates.first().map(|c| c.effect.clone()),
        verdict: d.verdict.add.clone(),
        val_ratio: f64::NAN,
        auto_added: Vec::new(),
    };
    match families.len() {
        1 => {
            let mut m = model.clone();
            let r = refine::fit_add(&mut m, &pe, Some(families[0].kind()), Some(&pv)).ok()?;
            out.val_ratio = r.after_validation.expect("validation").rms / t.floor_val;
            if std::env::var_os("HIDDEN_DEBUG").is_some() {
                eprintln!(
                    "fit --add {}: estimation RMS/floor {:.3}, validation {:.3}; {:?}",
                    families[0].name(),
                    r.after.rms / t.floor_est,
                    out.val_ratio,
                    r.params
                );
                for e in &m.effects {
                    let sh = &e.shape;
                    eprintln!(
                        "  {}: sign ε {:.3e}, lead {:.2e} s; mode {:.2} Hz ζ {:.3} J1 {:.2e} \
                         ratio {:.2}; quantum {:.4e}; gap {:.4e} (measured {:.4e} / {:.4e}) τ {:.3}",
                        e.kind.name(),
                        sh.sign_epsilon,
                        sh.sign_lead,
                        sh.compliance_frequency,
                        sh.compliance_damping,
                        sh.compliance_near_inertia,
                        sh.compliance_ratio,
                        sh.quantum,
                        sh.backlash_width,
                        sim_plant::effects::backlash::measured_width(&pe.trajectory())
                            .unwrap_or(f64::NAN),
                        sim_plant::effects::backlash::measured_width(&pv.trajectory())
                            .unwrap_or(f64::NAN),
                        sh.backlash_load_time
                    );
                }
            }
        }
        2 => {
            let mut m = model.clone();
            let run = refine::auto(&mut m, &pe, Some(&pv), &opts, 6).ok()?;
            // What the final model holds beyond the start (a swap may have replaced one).
            out.auto_added = m.effects[model.effects.len()..]
                .iter()
                .map(|e| e.kind.name().to_string())
                .collect();
            if std::env::var_os("HIDDEN_DEBUG").is_some() {
                for s in &run.steps {
                    eprintln!("step {}: {:?} rms {:.4e}", s.step, s.added, s.score.rms);
                }
                eprintln!("last:\n{}", run.last.to_text());
            }
            out.val_ratio = run
                .steps
                .last()
                .and_then(|s| s.validation)
                .map(|v| v.rms / t.floor_val)
                .unwrap_or(f64::NAN);
        }
        _ => {}
    }
    Some(out)
}

/// A long record for speed measurements: one joint (the first stable draw from `seed` on, with
/// Coulomb friction hidden at ρ ≈ 2), its estimation and validation records alternated
/// `repeats` times end to end and re-timed to one uniform clock. One plant throughout, so the
/// diagnosis it times is the one a user would get (Coulomb); the joins are 1-sample jumps in
/// velocity that the differentiator smooths over a few milliseconds.
pub fn long_record(seed: u64, repeats: usize) -> Recording {
    let trial = (seed..)
        .find_map(|s| generate(s, &[Family::Coulomb], 2.0))
        .expect("a stable draw");
    let mut r = trial.est.clone();
    for k in 1..repeats {
        let next = if k % 2 == 1 { &trial.val } else { &trial.est };
        let off = r.output.last().copied().unwrap_or(0.0) - next.output[0];
        r.input.extend(&next.input);
        r.output.extend(next.output.iter().map(|x| x + off));
    }
    r.time = (0..r.input.len()).map(|k| k as f64 * DT).collect();
    r
}

/// The `SEED RHO [SEED RHO …]` arguments of the probe examples (ρ defaults to 2 for a last
/// seed without one). With none, or one that does not parse, prints `usage` and where the
/// bench's seeds come from, and exits with status 2: a probe that silently does nothing reads
/// like one that found nothing.
pub fn probe_args(args: &[String], usage: &str) -> Vec<(u64, f64)> {
    let parsed: Option<Vec<(u64, f64)>> = args
        .chunks(2)
        .map(|p| {
            let seed = p.first()?.parse().ok()?;
            let rho = match p.get(1) {
                Some(r) => r.parse().ok()?,
                None => 2.0,
            };
            Some((seed, rho))
        })
        .collect();
    match parsed {
        Some(v) if !v.is_empty() => v,
        _ => {
            eprintln!(
                "usage: {usage}\n\
                 A bench trial's SEED and target RHO: `HIDDEN_LIST=1 hidden-trials N --family \
                 FAMILY` lists them one per line (`--fails` only the misses)."
            );
            std::process::exit(2);
        }
    }
}
