//! Hidden-effect trials: simulate a joint with one (or two) effects the model does not have,
//! and check that `diagnose` names it, `fit --add` removes it, `--auto` finds a pair, and null
//! trials stay quiet — on several independently written truths, each reported on its own.
//!
//! * **Truths** ([`truths`]): [`rk4::Rk4`] (an RK4 two-mass joint with LuGre friction),
//!   [`physicist::VerletKarnopp`] (velocity Verlet, switching friction with Karnopp stick
//!   detection, backlash as a dead-zone spring with contact damping), and the HIL lab's card
//!   against a `sim-plant` preset ([`lab`]). They share no code with each other or with the
//!   workbench; [`record`] is the interface they answer.
//! * **Conditions** ([`conditions`]) are drawn from the trial's seed, the same for every
//!   truth: sample rate 250 Hz–5 kHz, encoder 2¹²–2²⁰ counts/rev, excitation (PD or PID
//!   tracking, open-loop chirp, multisine with PRBS dither), input-noise level; the logging
//!   convention (zero-order hold or mid-sample) is a stratum of its own.
//! * **The referee** ([`referee`]) measures the strength ρ and the noise floor from the truth
//!   (its noise-free signals and its noise), never from the workbench's fits. The amplitude of
//!   each hidden effect is set by secant steps on ρ alone, on the effect-free plant.
//! * **What counts**: a draw whose truth diverges does not count (the truth says so, not the
//!   workbench); every other trial does, and a workbench error or panic is a failure.

pub mod lab;
pub mod physicist;
pub mod record;
pub mod referee;
pub mod rk4;
pub mod truth;

use std::panic::{catch_unwind, AssertUnwindSafe};

use jointlab_workbench::data::{Columns, Recording};
use jointlab_workbench::diagnose::{diagnose, Options};
use jointlab_workbench::model::Model;
use jointlab_workbench::refine;
use jointlab_workbench::residual::Prepared;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_plant::effects::{EffectKind, Intersample, Shape};

pub use record::{Conditions, Excitation, Family, Logging, Truth, TruthRecord, Which};

/// Every truth, in report order.
pub fn truths() -> Vec<Box<dyn Truth>> {
    vec![
        Box::new(rk4::Rk4),
        Box::new(physicist::VerletKarnopp),
        Box::new(lab::LabTruth),
    ]
}

/// The truth called `name`.
pub fn truth(name: &str) -> Option<Box<dyn Truth>> {
    truths().into_iter().find(|t| t.name() == name)
}

/// The pairs `--auto` is asked to find (each effect at the target strength on its own).
pub const PAIRS: [(Family, Family); 5] = [
    (Family::Coulomb, Family::Offset),
    (Family::Coulomb, Family::Ripple),
    (Family::Gravity, Family::Asymmetry),
    (Family::Offset, Family::Delay),
    (Family::Asymmetry, Family::Ripple),
];

/// Record length of every trial (s).
pub const DURATION: f64 = 12.0;

/// Seed offset of the conditions' stream: the plant and excitation draws of a truth use the
/// seed itself.
const CONDITIONS_STREAM: u64 = 0xC0_4D17_1045;

/// The recording conditions of trial `seed`, logged by `logging`: the same for every truth.
pub fn conditions(seed: u64, logging: Logging) -> Conditions {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ CONDITIONS_STREAM);
    let rates = [250.0, 500.0, 1000.0, 2000.0, 5000.0];
    let rate = rates[rng.random_range(0..rates.len())];
    let bits = [12, 14, 16, 18, 20][rng.random_range(0..5)];
    let excitation = Excitation::ALL[rng.random_range(0..Excitation::ALL.len())];
    let noise = (rng.random_range(0.3f64.ln()..3f64.ln())).exp();
    Conditions {
        dt: 1.0 / rate,
        duration: DURATION,
        counts_per_rev: f64::from(1u32 << bits),
        logging,
        excitation,
        noise,
    }
}

/// Why a draw does not count: from the truth, never from the workbench.
#[derive(Debug, Clone, PartialEq)]
pub enum Skip {
    /// The truth's loop diverged with the effect(s).
    Diverged(String),
    /// The strength could not be brought near its target (ρ not finite, or over 20× it; a
    /// null trial's at or above [`INDISTINCT`]).
    Strength(f64),
    /// The joint hardly moved (its true position spans fewer than [`MIN_TRAVEL_COUNTS`]
    /// encoder counts on a record): stuck in its friction, nothing to identify.
    Stuck(f64),
}

/// Fewest encoder counts the true motor position must span on each record for a trial to
/// count.
pub const MIN_TRAVEL_COUNTS: f64 = 100.0;

/// A generated trial: both records and the referee's numbers.
#[derive(Debug, Clone)]
pub struct Trial {
    /// Truth's name.
    pub truth: &'static str,
    /// Seed.
    pub seed: u64,
    /// Hidden families (empty = null trial) and their amplitudes.
    pub effects: Vec<(Family, f64)>,
    /// Recording conditions.
    pub cond: Conditions,
    /// Cut-off given to the workbench and used by the referee (Hz).
    pub cutoff: f64,
    /// Estimation record.
    pub est: TruthRecord,
    /// Validation record.
    pub val: TruthRecord,
    /// Measured strength on the estimation record (all effects together), beyond what the
    /// start model leaves of the joint without them ([`referee::beyond`]).
    pub rho: f64,
    /// Noise floor of the estimation record.
    pub floor_est: f64,
    /// Noise floor of the validation record for a rigid model.
    pub floor_val: f64,
    /// Noise floor of the validation record for the model a refit of the single hidden
    /// family is judged as: with the transmission's spring for compliance, on both encoders
    /// for backlash (fitted on the measured deflection), rigid otherwise; and with what the
    /// start model leaves of the joint without the effect ([`Trial::base_val`]).
    pub floor_val_refit: f64,
    /// What the start model leaves of the joint without the hidden effect, on the validation
    /// record, over its floor (0 for spring and gap families and for nulls and pairs): part of
    /// [`Trial::floor_val_refit`].
    pub base_val: f64,
    /// Gravity's strength beyond what a constant explains ([`referee::excess_with`] over the
    /// floor; in a pair, of gravity on its own); `None` without gravity.
    pub rho_beyond_offset: Option<f64>,
    /// A lone backlash's strength beyond what a linear spring explains
    /// ([`referee::Also::Spring`]); `None` otherwise.
    pub rho_beyond_spring: Option<f64>,
}

impl Trial {
    /// Hidden families.
    pub fn families(&self) -> Vec<Family> {
        self.effects.iter().map(|(f, _)| *f).collect()
    }
}

/// Whether the start model has Coulomb friction (Stribeck refines it).
fn start_has_coulomb(families: &[Family]) -> bool {
    families.contains(&Family::Stribeck)
}

/// The truth's joint without `hidden` but with what the start model holds: a Stribeck
/// truth's Coulomb friction (its Stribeck excess at 0). A dynamic Coulomb law (the `rk4`
/// truth's LuGre bristles) is not a static sign of the velocity: around a slow reversal
/// its bristles deflect (presliding). That belongs to the Coulomb law, not to the excess
/// hidden above it; a Stribeck refit that also takes some of it only scores lower.
fn base_joint(hidden: &[Family]) -> Vec<(Family, f64)> {
    if hidden.contains(&Family::Stribeck) {
        vec![(Family::Stribeck, 0.0)]
    } else {
        Vec::new()
    }
}

/// Generate a trial of `truth` with `families` hidden, each scaled on its own to the target
/// strength `target_rho` by the referee.
pub fn generate(
    truth: &dyn Truth,
    seed: u64,
    families: &[Family],
    target_rho: f64,
    logging: Logging,
) -> Result<Trial, Skip> {
    generate_in(truth, seed, families, target_rho, conditions(seed, logging))
}

/// [`generate`] under given conditions.
pub fn generate_in(
    truth: &dyn Truth,
    seed: u64,
    families: &[Family],
    target_rho: f64,
    cond: Conditions,
) -> Result<Trial, Skip> {
    let coulomb = start_has_coulomb(families);
    let rec = |effects: &[(Family, f64)], which| {
        truth
            .record(seed, effects, &cond, which)
            .map_err(Skip::Diverged)
    };
    // The band is the workbench's default for the record without the hidden effect (its
    // encoder and rate); the referee judges in it, and the workbench is given it.
    let probe = rec(&[], Which::Estimation)?;
    let fc = Prepared::default_cutoff(&recording(&probe, cond.logging, false, "probe"));
    // What the start model (with `also`) cannot explain of the joint without `of` (N·m, on
    // `which`); a truth that cannot be measured makes the draw not count, as a ρ that is not
    // finite does.
    let base = |of: &[Family], which: Which, also: referee::Also| -> Result<f64, Skip> {
        if of
            .iter()
            .any(|f| matches!(f, Family::Compliance | Family::Backlash))
        {
            return Ok(0.0);
        }
        let joint = base_joint(of);
        let e = if joint.is_empty() && which == Which::Estimation {
            referee::excess_with(&probe, fc, coulomb, also)
        } else {
            referee::excess_with(&rec(&joint, which)?, fc, coulomb, also)
        };
        if e.is_finite() {
            Ok(e)
        } else {
            Err(Skip::Strength(e))
        }
    };
    let mut effects = Vec::new();
    let mut base_of_each = Vec::new();
    for &f in families {
        let base_est = base(&[f], Which::Estimation, referee::Also::Nothing)?;
        base_of_each.push(base_est);
        // Secant steps on the amplitude (ρ is about linear in it); a quantiser's strength is
        // a ragged function of its step: two more.
        let mut a = truth.nominal_amplitude(seed, f, &cond);
        let steps = if f == Family::Quantization { 4 } else { 3 };
        for _ in 0..steps {
            let r = match rec(&[(f, a)], Which::Estimation) {
                Ok(r) => {
                    referee::beyond(referee::excess(&r, fc, coulomb), base_est)
                        / referee::floor(&r, fc)
                }
                Err(_) => f64::NAN,
            };
            a *= if !r.is_finite() {
                0.3 // diverged: back off
            } else if r > 1e-3 {
                (target_rho / r).clamp(0.05, 20.0)
            } else {
                20.0
            };
        }
        effects.push((f, a));
    }
    let est = rec(&effects, Which::Estimation)?;
    let val = rec(&effects, Which::Validation)?;
    let count = std::f64::consts::TAU / cond.counts_per_rev;
    for r in [&est, &val] {
        let (lo, hi) = r
            .position_true
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let counts = (hi - lo) / count;
        if counts.is_nan() || counts < MIN_TRAVEL_COUNTS {
            return Err(Skip::Stuck(counts));
        }
    }
    let floor_est = referee::floor(&est, fc);
    let floor_val = referee::floor(&val, fc);
    let path = match families {
        [Family::Compliance] => referee::NoisePath::Spring,
        [Family::Backlash] => referee::NoisePath::TwoEncoders,
        _ => referee::NoisePath::Rigid,
    };
    // What the start model cannot explain of the joint without the hidden effect (the `rk4`
    // truth's stiff transmission on a fast, fine record; a Coulomb law that is not a static
    // sign): no refit of the hidden effect alone gets below it, so it joins the floor a refit
    // is judged against — the null trials' rule (below) applied to the refit. A spring or a
    // gap replaces the stiff transmission: none there.
    let base_excess = match families {
        [_] => base(families, Which::Validation, referee::Also::Nothing)?,
        _ => 0.0,
    };
    let floor_val_refit = referee::floor_on(&val, fc, path).hypot(base_excess);
    // A hidden effect's strength is what it adds to what the start model leaves of the base
    // joint; a null trial's is all the start model leaves.
    let base_est = match (families, base_of_each.as_slice()) {
        ([], _) => 0.0,
        ([_], [b]) => *b,
        _ => base(families, Which::Estimation, referee::Also::Nothing)?,
    };
    let rho = referee::beyond(referee::excess(&est, fc, coulomb), base_est) / floor_est;
    // Gravity whose period is long against the record's travel is an offset to any data:
    // how much of it a constant cannot explain, beyond what a constant cannot explain of the
    // joint without it, from the truth (on its own in a pair, as each effect is scaled on its
    // own).
    let offset_base = || base(&[Family::Gravity], Which::Estimation, referee::Also::Offset);
    let rho_beyond_offset = match effects.as_slice() {
        [(Family::Gravity, _)] => Some(
            referee::beyond(
                referee::excess_with(&est, fc, coulomb, referee::Also::Offset),
                offset_base()?,
            ) / floor_est,
        ),
        _ => match effects.iter().find(|(f, _)| *f == Family::Gravity) {
            Some(&g) => {
                let r = rec(&[g], Which::Estimation)?;
                Some(
                    referee::beyond(
                        referee::excess_with(&r, fc, coulomb, referee::Also::Offset),
                        offset_base()?,
                    ) / referee::floor(&r, fc),
                )
            }
            None => None,
        },
    };
    // A gap behind a spring: how much of it no linear transmission explains.
    let rho_beyond_spring = (families == [Family::Backlash])
        .then(|| referee::excess_with(&est, fc, coulomb, referee::Also::Spring) / floor_est);
    // A null trial's joint must hold nothing the start model lacks, by the truth: a base
    // joint whose own dynamics (the `rk4` truth's stiff transmission, on a fast, fine record)
    // the start model leaves at half a floor or more is not a null.
    let in_reach = if families.is_empty() {
        rho < INDISTINCT
    } else {
        rho.is_finite() && rho <= 20.0 * target_rho.max(1.0)
    };
    if !in_reach {
        return Err(Skip::Strength(rho));
    }
    Ok(Trial {
        truth: truth.name(),
        seed,
        effects,
        cond,
        cutoff: fc,
        est,
        val,
        rho,
        floor_est,
        floor_val,
        floor_val_refit,
        base_val: base_excess / floor_val,
        rho_beyond_offset,
        rho_beyond_spring,
    })
}

/// A truth record as the workbench sees it: time, input, motor position (and the load
/// encoder with `load`), with the logging convention as its intersample behaviour.
pub fn recording(rec: &TruthRecord, logging: Logging, load: bool, label: &str) -> Recording {
    let intersample = match logging {
        Logging::Zoh => Intersample::Zoh,
        Logging::Mid => Intersample::Mid,
    };
    let mut columns = Columns::new("torque_Nm", "q_rad").with_intersample(intersample);
    columns.gear_ratio = rec.gear_ratio;
    if load {
        columns.load_output = Some("load_rad".into());
    }
    Recording {
        path: label.into(),
        time: rec.time.clone(),
        input: rec.input.clone(),
        output: rec.position.clone(),
        load_output: load.then(|| rec.load_position.clone()),
        dt: rec.dt,
        units: ("N·m".into(), "rad".into()),
        columns,
        resampled: None,
        recorded: None,
    }
}

/// Write a truth's record as a CSV the CLI reads (`torque_Nm`, `q_rad`, `load_rad`), to look
/// at one trial with `hil-host diagnose`.
fn dump(rec: &TruthRecord, path: &std::path::Path) -> std::io::Result<()> {
    use std::io::Write;
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "t_s,torque_Nm,q_rad,load_rad")?;
    for (i, t) in rec.time.iter().enumerate() {
        let at = |x: &[f64]| x.get(i).copied().unwrap_or(f64::NAN);
        writeln!(
            w,
            "{t},{},{},{}",
            at(&rec.input),
            at(&rec.position),
            at(&rec.load_position)
        )?;
    }
    w.flush()
}

/// The starting model a family is diagnosed against: the default baseline, plus Coulomb for
/// Stribeck (Stribeck is a refinement of Coulomb, so its truth always has Coulomb too).
pub fn start_model(families: &[Family]) -> Model {
    let mut m = Model::baseline();
    if start_has_coulomb(families) {
        m.add(EffectKind::Coulomb, Shape::default());
    }
    m
}

/// What one trial showed.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Outcome {
    /// Truth's name.
    pub truth: String,
    /// Seed.
    pub seed: u64,
    /// Hidden families' names.
    pub families: Vec<String>,
    /// Logging convention.
    pub logging: String,
    /// Sample rate (Hz).
    pub rate_hz: f64,
    /// Encoder bits.
    pub encoder_bits: u32,
    /// Excitation.
    pub excitation: String,
    /// Target strength.
    pub target_rho: f64,
    /// Measured strength (referee).
    pub rho: f64,
    /// Rank-1 candidate.
    pub top: Option<String>,
    /// Verdict (None = "no significant missing effect").
    pub verdict: Option<String>,
    /// Validation RMS after `fit --add <truth>` (or `--auto` for pairs) over the referee's
    /// validation floor (none for null trials and failed ones).
    pub val_ratio: Option<f64>,
    /// Effects `--auto` added (pair trials), final model minus start model.
    pub auto_added: Vec<String>,
    /// A workbench error or panic: the trial failed.
    pub error: Option<String>,
    /// The start model's residual RMS on the estimation record, the workbench's estimate of
    /// its noise floor, and the referee's floor (diagnostics of the floor estimate).
    #[serde(default)]
    pub floors: Option<[f64; 3]>,
    /// Backlash trials whose rank 1 is compliance: whether `--auto` then added backlash as
    /// the step after compliance (a gap behind a spring, from the motor encoder alone).
    #[serde(default)]
    pub backlash_after_compliance: Option<bool>,
    /// Trials with gravity: the strength of what a constant cannot explain ([`Trial`]'s).
    #[serde(default)]
    pub rho_beyond_offset: Option<f64>,
    /// Backlash trials: the strength of what a linear spring cannot explain ([`Trial`]'s).
    #[serde(default)]
    pub rho_beyond_spring: Option<f64>,
    /// Single-effect trials: what the start model leaves of the joint without the effect, on
    /// the validation record, in floors ([`Trial::base_val`]).
    #[serde(default)]
    pub base_val: Option<f64>,
    /// Single-effect trials whose refitted model `fit` would refuse to write (a parameter
    /// outside its physical range): why. Such a refit fails, whatever its score.
    #[serde(default)]
    pub refit_unphysical: Option<String>,
}

/// Below this strength beyond a simpler effect (the lower edge of the weak band), a record
/// cannot tell the hidden effect from the simpler one, and naming the simpler one is right:
/// an offset for gravity, the spring for a gap behind it.
pub const INDISTINCT: f64 = 0.5;

impl Outcome {
    /// Rank-1 candidate is the hidden effect.
    pub fn rank1_ok(&self) -> bool {
        self.names_hidden(self.top.as_deref())
    }
    /// The verdict (the significant missing effect) is the hidden one.
    pub fn verdict_ok(&self) -> bool {
        self.names_hidden(self.verdict.as_deref())
    }
    /// `named` is the single hidden effect, a simpler one the truth says stands for it, or
    /// (backlash) the spring after which `--auto` added the gap.
    fn names_hidden(&self, named: Option<&str>) -> bool {
        self.error.is_none()
            && self.families.len() == 1
            && (named.is_some() && named == self.families.first().map(String::as_str)
                || self.stands_in(named)
                || self.gap_after_spring(named))
    }
    /// A backlash trial named `compliance` whose `--auto` then added backlash as the next
    /// step: a gap behind a spring, named as the step after the spring (motor encoder only).
    fn gap_after_spring(&self, named: Option<&str>) -> bool {
        self.families == ["backlash"]
            && named == Some("compliance")
            && self.backlash_after_compliance == Some(true)
    }
    /// `named` is the simpler effect that explains the single hidden one to within
    /// [`INDISTINCT`] of the floor, by the truth: `offset` for gravity, `compliance` for
    /// backlash.
    pub fn stands_in(&self, named: Option<&str>) -> bool {
        let [hidden] = self.families.as_slice() else {
            return false;
        };
        match (hidden.as_str(), named) {
            ("gravity", Some("offset")) => self.gravity_is_an_offset(),
            ("backlash", Some("compliance")) => {
                self.rho_beyond_spring.is_some_and(|r| r < INDISTINCT)
            }
            _ => false,
        }
    }
    /// The trial's gravity is explained by a constant to within [`INDISTINCT`] of the floor,
    /// by the truth.
    fn gravity_is_an_offset(&self) -> bool {
        self.rho_beyond_offset.is_some_and(|r| r < INDISTINCT)
    }
    /// Null trial stayed quiet.
    pub fn null_ok(&self) -> bool {
        self.error.is_none() && self.families.is_empty() && self.verdict.is_none()
    }
    /// The refit's validation RMS is within `bar` × the referee's floor.
    pub fn refit_ok(&self, bar: f64) -> bool {
        self.error.is_none()
            && self.refit_unphysical.is_none()
            && self.val_ratio.is_some_and(|r| r <= bar)
    }
    /// The refit bar can tell a refit from none, by the truth: the start model alone, which
    /// leaves the effect (ρ) and the base joint ([`Outcome::base_val`]) on top of the noise,
    /// would score above `bar`. Where it would not, a refit that explains nothing passes, and
    /// the trial says nothing about the refit, as a null whose truth holds more than the
    /// start model says nothing about quiet (`rho` is the estimation record's; the two
    /// records share their draw). A spring or a gap is always judged: its refit's floor is
    /// not the rigid one ρ is measured in, and its base is none. A workbench error, or a
    /// strength that is not a number, always counts.
    pub fn refit_judgeable(&self, bar: f64) -> bool {
        let base = self.base_val.unwrap_or(0.0);
        let floor = 1.0 + base * base;
        let alone_passes = floor + self.rho * self.rho <= bar * bar * floor;
        let spring = matches!(
            self.families.first().map(String::as_str),
            Some("compliance" | "backlash")
        );
        self.families.len() == 1
            && (self.error.is_some() || self.refit_unphysical.is_some() || spring || !alone_passes)
    }
    /// `--auto` added exactly the two hidden effects (an extra effect is an error); an
    /// offset stands for gravity that a constant explains to within [`INDISTINCT`] of
    /// the floor, as in a single-effect trial.
    pub fn pair_ok(&self) -> bool {
        let sorted = |v: Vec<String>| {
            let mut v = v;
            v.sort();
            v
        };
        let got = sorted(self.auto_added.clone());
        let stand_in = !self.families.iter().any(|f| f == "offset") && self.gravity_is_an_offset();
        let with_offset = self.families.iter().map(|f| match f.as_str() {
            "gravity" => "offset".to_string(),
            _ => f.clone(),
        });
        self.error.is_none()
            && self.families.len() == 2
            && (got == sorted(self.families.clone())
                || (stand_in && got == sorted(with_offset.collect())))
    }
}

/// The refit bar of a family: ≤ 1.1× the floor, Stribeck ≤ 1.25× (a static friction form
/// cannot follow presliding below one count).
pub fn refit_bar(family: &str) -> f64 {
    if family == "stribeck" {
        1.25
    } else {
        1.1
    }
}

/// What the workbench reports on a trial: diagnose (motor encoder only); for one effect
/// `fit --add <truth>` validated on the validation record (backlash with the load encoder:
/// the refit bar is judged there); for two `--auto`.
fn judge(t: &Trial, out: &mut Outcome) -> Result<(), String> {
    let families = t.families();
    let motor = |r: &TruthRecord, which: &str, load: bool| {
        let rec = recording(
            r,
            t.cond.logging,
            load,
            &format!("{} seed {} {which}", t.truth, t.seed),
        );
        Prepared::new(&rec, Some(t.cutoff))
    };
    let pe = motor(&t.est, "est", false);
    let mut model = start_model(&families);
    refine::refit_all(&mut model, &pe).map_err(|e| format!("start model: {e}"))?;
    let opts = Options::default();
    let d = diagnose(&model, &pe, &opts);
    out.top = d.candidates.first().map(|c| c.effect.name().to_string());
    out.verdict = d.verdict.add.map(|k| k.name().to_string());
    out.floors = Some([d.baseline.rms, d.baseline.noise_floor_rms, t.floor_est]);
    let debug = std::env::var_os("HIDDEN_DEBUG").is_some();
    if let Some(path) = std::env::var_os("HIDDEN_DUMP") {
        // The estimation record at FILE, the validation record beside it (FILE.val.csv).
        let est = std::path::PathBuf::from(&path);
        let val = est.with_extension("val.csv");
        dump(&t.est, &est)
            .and_then(|()| dump(&t.val, &val))
            .map_err(|e| format!("HIDDEN_DUMP: {e}"))?;
    }
    if debug {
        eprintln!(
            "ρ = {:.2}, floor {:.3e}, amplitudes {:?}, base joint on val {:.2} floors\n{}",
            t.rho,
            t.floor_est,
            t.effects,
            t.base_val,
            d.to_text()
        );
    }
    if families == [Family::Backlash] && out.top.as_deref() == Some("compliance") {
        let mut m = model.clone();
        let run = refine::auto(&mut m, &pe, None, &opts, 3).map_err(|e| format!("--auto: {e}"))?;
        let added: Vec<Option<String>> =
            run.steps.iter().skip(1).map(|s| s.added.clone()).collect();
        if debug {
            for s in &run.steps {
                eprintln!("  step {}: {:?} — {}", s.step, s.added, s.verdict);
            }
            eprintln!(
                "--auto after compliance: {added:?}, stop: {}\n{}",
                run.stop,
                run.last.to_text()
            );
        }
        out.backlash_after_compliance = Some(
            added.first() == Some(&Some("compliance".into()))
                && added.get(1) == Some(&Some("backlash".into())),
        );
    }
    match families.as_slice() {
        [f] => {
            let load = *f == Family::Backlash;
            let (pe, pv) = if load {
                (motor(&t.est, "est", true), motor(&t.val, "val", true))
            } else {
                (pe, motor(&t.val, "val", false))
            };
            let kind = EffectKind::from_name(f.name()).ok_or("family is no library effect")?;
            let mut m = model.clone();
            let r = refine::fit_add(&mut m, &pe, Some(kind), Some(&pv))
                .map_err(|e| format!("fit --add {}: {e}", f.name()))?;
            let v = r.after_validation.ok_or("fit gave no validation score")?;
            let floor = t.floor_val_refit;
            out.val_ratio = Some(v.rms / floor);
            out.refit_unphysical = m.physical().err().map(|e| e.to_string());
            if debug {
                eprintln!(
                    "fit --add {}: estimation RMS/floor {:.3}, validation {:.3}; {:?}",
                    f.name(),
                    r.after.rms / t.floor_est,
                    v.rms / floor,
                    r.params
                );
            }
        }
        [_, _] => {
            let pv = motor(&t.val, "val", false);
            let mut m = model.clone();
            let run = refine::auto(&mut m, &pe, Some(&pv), &opts, 6)
                .map_err(|e| format!("--auto: {e}"))?;
            out.auto_added = m.effects[model.effects.len()..]
                .iter()
                .map(|e| e.kind.name().to_string())
                .collect();
            out.val_ratio = run
                .steps
                .last()
                .and_then(|s| s.validation)
                .map(|v| v.rms / t.floor_val);
            if debug {
                for s in &run.steps {
                    eprintln!(
                        "step {}: {:?} rms {:.4e} — {}",
                        s.step, s.added, s.score.rms, s.verdict
                    );
                }
                eprintln!("--auto stop: {}", run.stop);
            }
        }
        _ => {}
    }
    Ok(())
}

/// Run one trial of `truth`. `Err` when the draw does not count (see [`Skip`]); a workbench
/// error or panic is an `Ok` outcome with `error` set — a failed trial.
pub fn run(
    truth: &dyn Truth,
    seed: u64,
    families: &[Family],
    target_rho: f64,
    logging: Logging,
) -> Result<Outcome, Skip> {
    let t = generate(truth, seed, families, target_rho, logging)?;
    let mut out = Outcome {
        truth: t.truth.to_string(),
        seed,
        families: families.iter().map(|f| f.name().to_string()).collect(),
        logging: logging.name().to_string(),
        rate_hz: (1.0 / t.est.dt).round(),
        encoder_bits: t.cond.counts_per_rev.log2().round() as u32,
        excitation: t.cond.excitation.name().to_string(),
        target_rho,
        rho: t.rho,
        top: None,
        verdict: None,
        val_ratio: None,
        auto_added: Vec::new(),
        error: None,
        floors: None,
        backlash_after_compliance: None,
        rho_beyond_offset: t.rho_beyond_offset,
        rho_beyond_spring: t.rho_beyond_spring,
        base_val: (families.len() == 1).then_some(t.base_val),
        refit_unphysical: None,
    };
    match catch_unwind(AssertUnwindSafe(|| judge(&t, &mut out))) {
        Ok(Ok(())) => {}
        Ok(Err(e)) => out.error = Some(e),
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "panic".into());
            out.error = Some(format!("panic: {msg}"));
        }
    }
    Ok(out)
}

/// The conditions of the speed figures: 1 kHz, 2¹⁶ counts, PD tracking, logged as a drive
/// does, `duration` seconds.
pub fn speed_conditions(duration: f64) -> Conditions {
    Conditions {
        dt: 1e-3,
        duration,
        counts_per_rev: 65_536.0,
        logging: Logging::Zoh,
        excitation: Excitation::PdTracking,
        noise: 1.0,
    }
}

/// A long record for speed measurements: the RK4 truth's joint of `seed` (or the next stable
/// one) at 1 kHz with Coulomb friction hidden at ρ ≈ 2, its estimation and validation records
/// (each `seconds` long) alternated `repeats` times end to end on one clock.
pub fn long_record(seed: u64, seconds: f64, repeats: usize) -> Recording {
    let cond = speed_conditions(seconds);
    let t = (seed..)
        .find_map(|s| generate_in(&rk4::Rk4, s, &[Family::Coulomb], 2.0, cond).ok())
        .expect("a stable draw");
    let mut r = recording(&t.est, Logging::Zoh, false, "long record");
    for k in 1..repeats {
        let next = if k % 2 == 1 { &t.val } else { &t.est };
        let off = r.output.last().copied().unwrap_or(0.0) - next.position[0];
        r.input.extend(&next.input);
        r.output.extend(next.position.iter().map(|x| x + off));
    }
    r.time = (0..r.input.len()).map(|k| k as f64 * r.dt).collect();
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(added: &[&str], beyond_offset: Option<f64>) -> Outcome {
        outcome(&["gravity", "asymmetry"], added, beyond_offset)
    }

    fn outcome(families: &[&str], added: &[&str], beyond_offset: Option<f64>) -> Outcome {
        Outcome {
            truth: "t".into(),
            seed: 0,
            families: families.iter().map(|s| s.to_string()).collect(),
            logging: "zoh".into(),
            rate_hz: 1000.0,
            encoder_bits: 16,
            excitation: "pd".into(),
            target_rho: 2.0,
            rho: 2.0,
            top: None,
            verdict: None,
            val_ratio: None,
            auto_added: added.iter().map(|s| s.to_string()).collect(),
            error: None,
            floors: None,
            backlash_after_compliance: None,
            rho_beyond_offset: beyond_offset,
            rho_beyond_spring: None,
            base_val: None,
            refit_unphysical: None,
        }
    }

    /// The floor a refit is judged against holds what the start model leaves of the joint
    /// without the hidden effect, in quadrature: the `rk4` truth's stiff (350 Hz)
    /// transmission is part of it on a fast, fine record and next to none of it on a slow,
    /// coarse one; a spring family replaces that transmission and adds nothing.
    #[test]
    fn the_refit_floor_holds_what_the_start_model_leaves_of_the_base_joint() {
        let cond = |dt: f64, bits: f64| Conditions {
            dt,
            duration: 6.0,
            counts_per_rev: 2f64.powf(bits),
            logging: Logging::Zoh,
            excitation: Excitation::MultisinePrbs,
            noise: 1.0,
        };
        let trial = |families: &[Family], c: Conditions| {
            (1..)
                .find_map(|s| generate_in(&rk4::Rk4, s, families, 2.0, c).ok())
                .expect("a stable draw")
        };
        let fast = trial(&[Family::Offset], cond(2e-4, 20.0));
        let slow = trial(&[Family::Offset], cond(4e-3, 12.0));
        assert!(
            fast.base_val > 0.3 && slow.base_val < 0.05,
            "base beyond the start model: fast {:.3}, slow {:.3} floors",
            fast.base_val,
            slow.base_val
        );
        for t in [&fast, &slow] {
            let rigid = referee::floor_on(&t.val, t.cutoff, referee::NoisePath::Rigid);
            let with_base = rigid.hypot(t.base_val * t.floor_val);
            assert!((t.floor_val_refit / with_base - 1.0).abs() < 1e-12);
        }
        let spring = trial(&[Family::Compliance], cond(2e-4, 20.0));
        assert_eq!(spring.base_val, 0.0);
    }

    /// A Stribeck trial's base joint keeps the truth's own Coulomb law (its Stribeck excess
    /// at 0): the `rk4` truth's LuGre bristles deflect (presliding) around a slow reversal, which the
    /// start model's static sign cannot follow, and that is no part of the Stribeck effect's
    /// strength. On a slow, coarse PD record (1 kHz, 2¹² counts) it shows on some of the first
    /// ten draws, while the joint without friction leaves next to nothing.
    #[test]
    fn a_stribeck_trial_is_measured_beyond_its_truths_own_coulomb_law() {
        let c = Conditions {
            dt: 1e-3,
            duration: 6.0,
            counts_per_rev: 4096.0,
            logging: Logging::Zoh,
            excitation: Excitation::PdTracking,
            noise: 1.0,
        };
        let truth = rk4::Rk4;
        let mut presliding = 0;
        for seed in 1..=10 {
            let Ok(t) = generate_in(&truth, seed, &[Family::Stribeck], 1.0, c) else {
                continue;
            };
            let record = |effects: &[(Family, f64)], which| {
                truth.record(seed, effects, &c, which).expect("base joint")
            };
            let coulomb_only = [(Family::Stribeck, 0.0)];
            let base_val =
                referee::excess(&record(&coulomb_only, Which::Validation), t.cutoff, true);
            assert!((t.base_val - base_val / t.floor_val).abs() < 1e-9);
            let base_est =
                referee::excess(&record(&coulomb_only, Which::Estimation), t.cutoff, true);
            let effect = referee::excess(&t.est, t.cutoff, true);
            let rho = (effect.powi(2) - base_est.powi(2)).max(0.0).sqrt() / t.floor_est;
            assert!(
                (t.rho - rho).abs() < 1e-9,
                "seed {seed}: ρ {} against {rho}",
                t.rho
            );
            let frictionless = referee::excess(&record(&[], Which::Validation), t.cutoff, true);
            assert!(
                frictionless < 0.05 * t.floor_val,
                "seed {seed}: the joint without friction leaves {:.3} floors",
                frictionless / t.floor_val
            );
            presliding += usize::from(t.base_val >= INDISTINCT);
        }
        assert!(presliding > 0, "no draw shows presliding of half a floor");
    }

    /// A refit counts only where a refit that adds nothing would fail its bar: the effect
    /// (ρ) and the base joint leave √(1 + b² + ρ²) floors, judged against √(1 + b²); a spring
    /// is always judged, and so is a strength that is not a number or a refit `fit` would not
    /// write.
    #[test]
    fn a_refit_counts_only_where_adding_nothing_would_fail() {
        let single = |rho: f64, base: f64| {
            let mut o = outcome(&["offset"], &[], None);
            o.rho = rho;
            o.base_val = Some(base);
            o
        };
        // Nothing added would score 1.092.
        assert!(!single(1.1, 2.3).refit_judgeable(1.1));
        assert!(single(1.1, 2.3).refit_judgeable(1.05));
        assert!(single(0.5, 0.0).refit_judgeable(1.1)); // 1.118
        assert!(!single(0.4, 0.0).refit_judgeable(1.1)); // 1.077
        assert!(!single(0.7, 0.0).refit_judgeable(1.25)); // 1.221
        assert!(single(0.8, 0.0).refit_judgeable(1.25)); // 1.281
        let mut failed = single(0.1, 0.0);
        failed.error = Some("panicked".into());
        assert!(failed.refit_judgeable(1.1));
        // A refit `fit` would not write fails and is always judged, whatever its score.
        let mut unphysical = single(0.4, 0.0);
        unphysical.val_ratio = Some(1.0);
        assert!(unphysical.refit_ok(1.1));
        unphysical.refit_unphysical = Some("gain = -9.5 is outside [0, 1]".into());
        assert!(unphysical.refit_judgeable(1.1) && !unphysical.refit_ok(1.1));
        assert!(!outcome(&["offset", "coulomb"], &[], None).refit_judgeable(1.1));
        assert!(single(f64::NAN, 0.0).refit_judgeable(1.1));
        let mut spring = outcome(&["compliance"], &[], None);
        spring.rho = 0.3;
        assert!(spring.refit_judgeable(1.1));
    }

    /// In a pair, an offset stands for gravity only where the truth says a constant explains
    /// that gravity; an extra or missing effect still fails.
    #[test]
    fn an_offset_stands_for_gravity_in_a_pair_only_below_the_bar() {
        assert!(pair(&["asymmetry", "gravity"], Some(2.0)).pair_ok());
        assert!(pair(&["offset", "asymmetry"], Some(0.3)).pair_ok());
        assert!(pair(&["gravity", "asymmetry"], Some(0.3)).pair_ok());
        assert!(!pair(&["offset", "asymmetry"], Some(0.8)).pair_ok());
        assert!(!pair(&["offset", "asymmetry"], None).pair_ok());
        assert!(!pair(&["offset", "asymmetry", "coulomb"], Some(0.3)).pair_ok());
        assert!(!pair(&["asymmetry"], Some(0.3)).pair_ok());
    }

    /// A lone backlash named `compliance` counts only where the truth says a linear spring
    /// explains the gap to within the bar, or where `--auto` added the gap after the spring.
    #[test]
    fn the_spring_stands_for_a_gap_only_below_the_bar() {
        let backlash = |top: &str, beyond: Option<f64>, after: Option<bool>| {
            let mut o = outcome(&["backlash"], &[], None);
            o.top = Some(top.into());
            o.rho_beyond_spring = beyond;
            o.backlash_after_compliance = after;
            o
        };
        assert!(backlash("backlash", Some(2.0), None).rank1_ok());
        assert!(backlash("compliance", Some(0.3), Some(false)).rank1_ok());
        assert!(backlash("compliance", Some(2.0), Some(true)).rank1_ok());
        assert!(!backlash("compliance", Some(0.8), Some(false)).rank1_ok());
        assert!(!backlash("compliance", None, None).rank1_ok());
        assert!(!backlash("deadband", Some(0.1), None).rank1_ok());
        // Gravity's stand-in is not the spring's.
        let mut g = outcome(&["gravity"], &[], Some(0.1));
        g.top = Some("compliance".into());
        g.rho_beyond_spring = Some(0.1);
        assert!(!g.rank1_ok());
        g.top = Some("offset".into());
        assert!(g.rank1_ok());
    }
}
