//! What a truth is asked to simulate and what it hands back: the one interface between the
//! independently written truths ([`mod@super::truth`], [`super::physicist`], [`super::lab`]) and
//! the harness. The workbench sees only `time`, `input`, `position` (and `load_position`); the
//! referee ([`super::referee`]) sees the rest.

/// When a log row's position is sampled relative to the command held in that row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Logging {
    /// Drive convention: row k holds q(t_k), read at the instant the controller reads it,
    /// and the command u_k computed from it, then held over [t_k, t_k + T).
    Zoh,
    /// Row k holds u_k (held over [t_k, t_k + T)) and q(t_k + T/2), the middle of its hold.
    Mid,
}

impl Logging {
    /// Both conventions.
    pub const ALL: [Logging; 2] = [Logging::Zoh, Logging::Mid];

    /// Short name (the workbench's `--intersample` value for it).
    pub fn name(self) -> &'static str {
        match self {
            Logging::Zoh => "zoh",
            Logging::Mid => "mid",
        }
    }
}

/// How the joint is excited while it is recorded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Excitation {
    /// Closed-loop PD on the measured motor position tracking a smooth reference (multisine
    /// and a rounded triangle: reversals and travel), small broadband torque dither.
    PdTracking,
    /// The same with an integral term (PID): the integrator holds position against offsets
    /// and gravity.
    PidTracking,
    /// Open-loop torque chirp (no feedback) and a tiny zero-mean dither.
    OpenLoopChirp,
    /// Closed-loop PD tracking a multisine with a PRBS torque dither added to the command.
    MultisinePrbs,
}

impl Excitation {
    /// Every excitation.
    pub const ALL: [Excitation; 4] = [
        Excitation::PdTracking,
        Excitation::PidTracking,
        Excitation::OpenLoopChirp,
        Excitation::MultisinePrbs,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Excitation::PdTracking => "pd",
            Excitation::PidTracking => "pid",
            Excitation::OpenLoopChirp => "chirp",
            Excitation::MultisinePrbs => "multisine-prbs",
        }
    }
}

/// Which of a trial's two records: the same plant, another excitation draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Which {
    /// The record the workbench diagnoses and fits.
    Estimation,
    /// The record the fit is validated on.
    Validation,
}

/// Hidden-effect families (the workbench's vocabulary minus `viscous`, which the baseline
/// has). Amplitude units are those of [`Truth::record`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    /// Constant torque offset (N·m; sign drawn from the seed).
    Offset,
    /// Coulomb friction, kinetic level (N·m), static = kinetic.
    Coulomb,
    /// Extra viscous friction in the positive direction (N·m·s/rad).
    Asymmetry,
    /// Static − Coulomb (N·m); the truth always has Coulomb friction of a drawn level too.
    Stribeck,
    /// Total gap width (rad), inside a transmission with its own finite stiffness.
    Backlash,
    /// Transmission compliance: a ≥ 0 puts the mode at max(6 Hz, 60 Hz/√a).
    Compliance,
    /// Load-position-periodic torque amplitude (N·m).
    Ripple,
    /// m·g·l (N·m).
    Gravity,
    /// Pure transport delay of the applied torque beyond the hold (s, at most 6 ms).
    Delay,
    /// D/A step of the applied command (N·m); the input noise is then a torque disturbance
    /// after the converter and the logged command is exact.
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

    /// Inverse of [`Family::name`].
    pub fn from_name(s: &str) -> Option<Family> {
        Family::ALL.into_iter().find(|f| f.name() == s)
    }
}

/// Recording conditions (drawn by the harness, not by the truth).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Sample period (s), 1/5000 … 1/250.
    pub dt: f64,
    /// Record length (s).
    pub duration: f64,
    /// Encoder counts per revolution, motor and load encoders alike (2¹² … 2²⁰).
    pub counts_per_rev: f64,
    /// Logging convention.
    pub logging: Logging,
    /// Excitation.
    pub excitation: Excitation,
    /// Input-noise multiplier (1 = the truth's nominal level), 0.3 … 3.
    pub noise: f64,
}

/// One simulated record and everything the referee needs.
#[derive(Debug, Clone)]
pub struct TruthRecord {
    /// Sample period (s). A truth that cannot honour [`Conditions::dt`] (the lab's card runs
    /// at 1 kHz) records at its own rate, and this is it.
    pub dt: f64,
    /// t_k = k·dt.
    pub time: Vec<f64>,
    /// Logged torque command (N·m), with the input noise where it is on the record.
    pub input: Vec<f64>,
    /// Motor encoder (rad), quantised.
    pub position: Vec<f64>,
    /// Load-side encoder (rad), same counts, own noise, same instants.
    pub load_position: Vec<f64>,
    /// The white noise that enters u = J·a + …: the noise on the logged input, or for
    /// [`Family::Quantization`] the torque disturbance after the D/A.
    pub input_noise: Vec<f64>,
    /// True motor position at the logged instants.
    pub position_true: Vec<f64>,
    /// The integrator's sub-step h (dt / an integer).
    pub fine_dt: f64,
    /// On the fine grid t = i·h: the noise-free command as held, before any hidden delay or
    /// quantiser, plus any torque disturbance applied after the D/A (what a model without
    /// the hidden effect takes as the input, so the referee's excess is that effect alone).
    pub fine_command: Vec<f64>,
    /// True motor position on the fine grid.
    pub fine_position: Vec<f64>,
    /// J1 + J2: the rigid limit seen at the motor.
    pub inertia: f64,
    /// J2, the load's inertia referred to the motor (J1 = `inertia` − J2).
    pub inertia_load: f64,
    /// A linear transmission spring (stiffness, damping, referred to the motor), when the
    /// joint has one: it shapes how the encoder's noise reaches a correct model's residual.
    pub spring: Option<(f64, f64)>,
    /// True load position at the logged instants, referred to the motor (as `load_position`).
    pub load_position_true: Vec<f64>,
    /// The joint's gear ratio (motor turns per output turn; 1 for a direct drive): what a user
    /// tells the workbench (`--gear-ratio`) so that gravity acts on the output angle.
    pub gear_ratio: f64,
}

/// A truth: deterministic in (seed, effects, conditions, which).
pub trait Truth: Sync {
    /// Short name (bench output, CI test names).
    fn name(&self) -> &'static str;
    /// Simulate one record of the joint drawn from `seed` with the hidden `effects` (each
    /// family at most once, at its amplitude; empty = none). The plant and the excitation
    /// depend on the seed only, so records of one seed differ in their effects alone.
    /// `Err(reason)` if the loop diverged.
    fn record(
        &self,
        seed: u64,
        effects: &[(Family, f64)],
        cond: &Conditions,
        which: Which,
    ) -> Result<TruthRecord, String>;
    /// A starting amplitude for the harness's calibration of the effect's strength.
    fn nominal_amplitude(&self, seed: u64, family: Family, cond: &Conditions) -> f64;
    /// The logging conventions this truth can record (a lab that only logs as a drive does
    /// is judged on that one).
    fn loggings(&self) -> &'static [Logging] {
        &Logging::ALL
    }
}
