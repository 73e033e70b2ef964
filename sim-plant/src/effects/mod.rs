//! The library of physical effects, shared by the simulator, the fitter and the diagnosis.
//!
//! One module per effect. Each module holds
//! * `DESCRIBE` — what the effect is physically and what it leaves in a residual
//!   (thesis-notes §7, Schempf 1990 §3.2 / §4);
//! * `Params` / `PARAMS` — its parameters with units, defaults and roles ([`ParamSpec`]);
//! * `install` — its contribution to the dynamics, written into [`EffectLaws`], the slots the
//!   integrator evaluates (friction curve, transmission spring, actuator chain, periodic torques);
//! * `fingerprint` / `shape_grid` — the regressor columns it adds to an inverse-dynamics
//!   (equation-error) residual, and the nonlinear shapes worth searching.
//!
//! All effects are registered in ONE place, the `registry!` invocation below: adding an effect
//! is one module plus one line there, which extends [`EffectKind`], [`EffectSet`] (the
//! `[effects]` section of a model file), [`fingerprint`], [`shape_grid`] and installation.
//! The module's `install` writes into an existing slot of [`EffectLaws`] (friction curve,
//! spring, actuator chain, periodic torques) or pushes an [`AdditiveTorque`] — a torque law on
//! the motor or output node that the integrator sums — so the integrator needs no change.
//!
//! A new module provides: `DESCRIBE`, `AMPLITUDES` (names of its fingerprint columns'
//! amplitudes), `SIGN` (admissible sign of the first), `FIT` (what the fitter needs to know
//! about it, a [`FitTraits`]), a `define_params!` table, and `install`, `fingerprint`,
//! `shape_grid`. Its shape is searched by one of the refit's searches ([`ShapeSearch`]); only
//! a fingerprint whose shape none of them fits needs a new search in the workbench.
//!
//! ## Sign convention
//! Every effect is written as a *resisting* torque `R` in the axis equation
//! `J·a = input − Σ R`, so an inverse-dynamics residual `r = input − model_input` of a model
//! missing the effect equals `R`, and the fingerprint columns are a basis of `R`.

pub mod intersample;
pub mod laws;
pub mod signal;

pub use intersample::Intersample;

pub use laws::{
    ActuatorLaw, AdditiveTorque, EffectLaws, FrictionLaw, Node, PeriodicTorque, SpringLaw,
};

use crate::param::ParamSpec;

/// A uniformly sampled trajectory in SI units, referred to the axis being modelled
/// (rotary: N·m, rad, rad/s; linear: N, m, m/s — the math is the same).
#[derive(Clone, Copy, Debug)]
pub struct Trajectory<'a> {
    /// Sample period (s).
    pub dt: f64,
    /// Applied torque/force.
    pub input: &'a [f64],
    /// Position.
    pub position: &'a [f64],
    /// Velocity.
    pub velocity: &'a [f64],
    /// Acceleration.
    pub acceleration: &'a [f64],
    /// The input as recorded, before any filtering or reconstruction (`input` may be a
    /// smoothed or motion-based stand-in for it). Fingerprints that are a *dynamic* function of
    /// the command (compliance, quantisation) are built from it. It may extend beyond the
    /// trajectory (the whole record, of which the trajectory is a window starting at
    /// `raw_offset`), so that filters see the command's history and not a start-up transient.
    pub raw_input: &'a [f64],
    /// Index in `raw_input` (and `raw_acceleration`) of the trajectory's first sample.
    pub raw_offset: usize,
    /// The acceleration over the same whole record as `raw_input` (empty when not available:
    /// the trajectory's own is used). Fingerprints that are a *dynamic* function of the motion
    /// (compliance's motion form) are filtered from the record's start, so that a lightly damped
    /// filter does not start with a wrong state where the trajectory begins (its free response
    /// would then be an error lasting several time constants).
    pub raw_acceleration: &'a [f64],
    /// Cut-off (Hz) of the zero-phase low-pass ([`signal::filtfilt`]) the residual went through
    /// (the smoothing differentiator's); 0 = none. Fingerprints built from `raw_input` apply it
    /// so that they see the bandwidth the residual saw.
    pub lowpass_hz: f64,
    /// Load-side position (an output encoder), sample for sample with `position` and processed
    /// like it (the same zero-phase low-pass, the same window); empty when the record has
    /// none. With it the motor-minus-load deflection δ = position − load_position is measured
    /// instead of inferred from the motor's motion (backlash uses it, see
    /// `backlash::fingerprint`).
    pub load_position: &'a [f64],
    /// How `raw_input` behaved between its samples: columns built from it are mapped onto the
    /// position's sample instants ([`Trajectory::input_lowpass`]) as the residual's input was.
    pub intersample: Intersample,
    /// Turns of `position` per turn of the joint's output: a gear's ratio N when the position
    /// is the motor shaft's, 1 when it is the output's. Gravity acts on the output angle.
    pub gear_ratio: f64,
    /// The position's resolution: the smallest change the record shows (an encoder's count;
    /// 0 when unknown, about 0 for unquantised data). Shapes measured in position (a gap's
    /// width) are searched down to it, as a lost motion the encoder resolves can show.
    pub position_step: f64,
    /// The speed a joint at rest shows: one position step flickering, through the
    /// differentiator that made `velocity` (0 when unknown). Dry friction's sign is held
    /// linear up to it, as a measured velocity that small is noise.
    pub rest_velocity: f64,
}

impl<'a> Trajectory<'a> {
    /// A trajectory that is its own whole record, seen unfiltered: the recorded input is
    /// `input`, there is no history before the first sample and no low-pass (a simulation's
    /// samples, a single state, a synthetic test signal).
    pub fn unfiltered(
        dt: f64,
        input: &'a [f64],
        position: &'a [f64],
        velocity: &'a [f64],
        acceleration: &'a [f64],
    ) -> Self {
        Trajectory {
            dt,
            input,
            position,
            velocity,
            acceleration,
            raw_input: input,
            raw_offset: 0,
            raw_acceleration: &[],
            lowpass_hz: 0.0,
            load_position: &[],
            intersample: Intersample::Bl,
            gear_ratio: 1.0,
            position_step: 0.0,
            rest_velocity: 0.0,
        }
    }

    /// The measured load position over the trajectory, if the record has one covering it.
    pub fn load(&self) -> Option<&[f64]> {
        let n = self.len();
        (n > 0 && self.load_position.len() >= n).then(|| &self.load_position[..n])
    }

    /// Number of samples (the shortest of the four series).
    pub fn len(&self) -> usize {
        self.input
            .len()
            .min(self.position.len())
            .min(self.velocity.len())
            .min(self.acceleration.len())
    }

    /// `x` low-passed as the residual was (see [`Trajectory::lowpass_hz`]).
    pub fn lowpass(&self, x: &[f64]) -> Vec<f64> {
        if self.lowpass_hz > 0.0 && self.dt > 0.0 {
            signal::filtfilt(x, self.lowpass_hz, 1.0 / self.dt)
        } else {
            x.to_vec()
        }
    }

    /// A column computed from the recorded input (`raw_input`, sample for sample), mapped onto
    /// the position's sample instants by the record's [`Intersample`] behaviour and low-passed
    /// as the residual was: what the residual's own input went through.
    pub fn input_lowpass(&self, x: &[f64]) -> Vec<f64> {
        let fs = if self.dt > 0.0 { 1.0 / self.dt } else { 0.0 };
        self.intersample.band_limited(x, self.lowpass_hz, fs)
    }

    /// The recorded input and the window of it the trajectory covers: `raw_input` (the whole
    /// record) if it covers the trajectory at `raw_offset`, else `input` itself.
    pub fn recorded_input(&self) -> (&[f64], std::ops::Range<usize>) {
        self.whole_record(self.raw_input, self.input)
    }

    /// The acceleration over the whole record and the window of it the trajectory covers
    /// (`raw_acceleration` if it covers the trajectory at `raw_offset`, else `acceleration`).
    pub fn recorded_acceleration(&self) -> (&[f64], std::ops::Range<usize>) {
        self.whole_record(self.raw_acceleration, self.acceleration)
    }

    /// `whole` and the trajectory's window in it if it covers the trajectory at `raw_offset`,
    /// else `window` itself (whole range).
    fn whole_record<'s>(
        &self,
        whole: &'s [f64],
        window: &'s [f64],
    ) -> (&'s [f64], std::ops::Range<usize>) {
        let n = self.len();
        if whole.len() >= self.raw_offset + n {
            (whole, self.raw_offset..self.raw_offset + n)
        } else {
            (&window[..n], 0..n)
        }
    }

    /// Whether the trajectory has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Largest |velocity| (0 for an empty trajectory).
    pub fn max_abs_velocity(&self) -> f64 {
        self.velocity[..self.len()]
            .iter()
            .fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Largest |input|.
    pub fn max_abs_input(&self) -> f64 {
        self.input[..self.len()]
            .iter()
            .fold(0.0, |m, v| m.max(v.abs()))
    }
}

/// Shape parameters that make a fingerprint linear in its amplitude(s). Each effect reads only
/// the fields it needs (listed per field). Defaults are sensible for output-referred rotary
/// data of the thesis's joints (velocities ~0.01–1 rad/s, torques ~1–100 N·m). Field names
/// follow the workbench's usage.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Shape {
    /// Coulomb, asymmetry, stribeck: |v| below which sign(v) is
    /// replaced by v/ε (a deadbanded sign: measured velocity near zero is mostly quantisation
    /// noise). Units of velocity.
    pub sign_epsilon: f64,
    /// Coulomb, asymmetry, stribeck: a time T (s) by which the sign's linear zone widens with
    /// the acceleration, ε + |a|·T, so that every reversal is smoothed over about 2T whatever
    /// its speed. What smooths a measured reversal acts over time (the band limit the
    /// residual went through, a pre-sliding displacement crossed at the reversal's pace); a
    /// zone in velocity alone spans 2ε/|a|, tens of milliseconds at a slow reversal when ε
    /// was fitted to fast ones. 0 = the zone in velocity alone.
    pub sign_time: f64,
    /// Stribeck: characteristic velocity vs of the stiction→Coulomb transition.
    pub stribeck_velocity: f64,
    /// Stribeck: exponent δ in exp(−(|v|/vs)^δ) (1 = exponential, 2 = Gaussian).
    pub stribeck_exponent: f64,
    /// Ripple: spatial period in units of the trajectory's position (tooth / lobe / roller
    /// spacing at the output).
    pub ripple_period: f64,
    /// Cogging: spatial period in units of the trajectory's position, 2π/(cycles·N) rad for
    /// output-referred data; 0 = unknown (the fingerprint is then empty: not testable).
    pub cogging_period: f64,
    /// Backlash: total width of the dead zone, position units.
    pub backlash_width: f64,
    /// Backlash: time constant J_load/b_load (s) of the load's viscous decay while it coasts
    /// through the gap; 0 = no decay (a frictionless load coasts at constant velocity).
    pub backlash_load_time: f64,
    /// Deadband: half-width of the input dead zone, input units.
    pub deadband_width: f64,
    /// Deadband (torque-constant nonlinearity): input scale the nonlinearity is normalised to
    /// (the actuator's maximum), input units.
    pub input_scale: f64,
    /// Quantization: step of the input (D/A) quantiser, input units; 0 = none.
    pub quantum: f64,
    /// Quantization: RMS σ of the noise on the recorded command (input units); 0 = none. The
    /// column is then the sawtooth's expectation given the recorded command, E[u − Q_Δ(u)]
    /// with u ~ N(recorded, σ²): the sawtooth with its k-th harmonic damped by
    /// exp(−2π²k²σ²/Δ²).
    pub quantum_blur: f64,
    /// Delay: the delay τs (s) the column is built for, (u(t) − u(t − τs))/τs; its amplitude
    /// is the delay and equals τs at the best shape. 0 = the derivative u̇ (small delays).
    pub delay: f64,
    /// Compliance, delay: length (samples) of the moving average that smooths signals before
    /// they are differentiated.
    pub smoothing: usize,
    /// Compliance: frequency (Hz) of the coupled transmission mode, ω = √(K·(1/J1 + 1/J2)).
    pub compliance_frequency: f64,
    /// Compliance: damping ratio ζ of the coupled mode, c·(1/J1 + 1/J2) = 2ζω.
    pub compliance_damping: f64,
    /// Compliance: 0 = the column is built from the recorded command (the diagnosis's form);
    /// positive = the motor-side inertia J1 of the fitted split, and the column is the motion
    /// form `J1·H₂(s)·a` (see the module; the refit's form, free of the command's noise).
    pub compliance_near_inertia: f64,
    /// Compliance, motion form: the inertia ratio J2/J1 that places the locked-motor mode
    /// ω₂ = ω/√(1 + J2/J1), ζ₂ = ζ/√(1 + J2/J1).
    pub compliance_ratio: f64,
    /// Compliance, motion form: viscous friction b on the load side (torque per velocity),
    /// which shapes the column as (J2·s + b)².
    pub compliance_load_damping: f64,
    /// Coulomb, asymmetry: time lead (s) of the velocity whose sign the column takes, sign_ε(v + lead·a):
    /// dynamic (LuGre) friction switches over a short pre-sliding displacement, so the torque
    /// reversal is offset from the measured velocity reversal by a fraction of a millisecond
    /// to a few milliseconds (negative = lag). 0 = the static sign(v).
    pub sign_lead: f64,
    /// Stribeck (and, copied by a fitter, Coulomb and asymmetry): velocity scale vh of the stick
    /// window exp(−(v/vh)⁴) inside which the joint counts as at rest — the friction is then
    /// the stribeck hold column (the applied torque) and the dry-friction slip columns are
    /// off (see `stribeck::fingerprint`). 0 = no window (the diagnosis's columns).
    pub stick_velocity: f64,
}

impl Shape {
    /// Takes `from`'s dry-friction sign zone, ε and T: one point of the sign grid, which a
    /// search moves as one.
    pub fn set_sign_zone(&mut self, from: &Shape) {
        self.sign_epsilon = from.sign_epsilon;
        self.sign_time = from.sign_time;
    }
}

impl Default for Shape {
    fn default() -> Self {
        Self {
            sign_epsilon: 1e-3,
            sign_time: 0.0,
            stribeck_velocity: 0.05,
            stribeck_exponent: 2.0,
            ripple_period: std::f64::consts::TAU / 100.0,
            cogging_period: 0.0,
            backlash_width: 0.01,
            backlash_load_time: 0.0,
            deadband_width: 0.05,
            input_scale: 1.0,
            quantum: 0.0,
            quantum_blur: 0.0,
            delay: 0.0,
            smoothing: 5,
            compliance_frequency: 20.0,
            compliance_damping: 0.05,
            compliance_near_inertia: 0.0,
            compliance_ratio: 0.0,
            compliance_load_damping: 0.0,
            sign_lead: 0.0,
            stick_velocity: 0.0,
        }
    }
}

/// The shape parameter Levenberg–Marquardt may refine together with the amplitudes, for an
/// effect whose fingerprint is smooth in it: how to read it from and write it to a [`Shape`].
#[derive(Clone, Copy, Debug)]
pub struct SmoothShape {
    /// The parameter's value in `shape`.
    pub get: fn(&Shape) -> f64,
    /// Set it in `shape`.
    pub set: fn(&mut Shape, f64),
    /// Its unit (canonical, rotary-named; see [`crate::units::Axis::unit`]).
    pub unit: &'static str,
}

/// A shape parameter of the model file and where the fit keeps it in [`Shape`]. The file holds
/// what a user measures (cycles per motor revolution), the fit what the columns use (a period
/// at the output), so reading and writing get the gear ratio.
#[derive(Clone, Copy, Debug)]
pub struct FileShape {
    /// The parameter's name in the model file (role `Shape`).
    pub param: &'static str,
    /// The file's value from the fit's shape and the gear ratio; `None` where the shape does
    /// not know it (an unknown period), so the file keeps its own.
    pub get: fn(&Shape, f64) -> Option<f64>,
    /// Writes the file's value (and the gear ratio) into the fit's shape.
    pub set: fn(&mut Shape, f64, f64),
}

/// A [`FileShape`] the file and the fit hold in the same units:
/// `same_shape!("width" => backlash_width)`.
macro_rules! same_shape {
    ($param:literal => $field:ident) => {
        $crate::effects::FileShape {
            param: $param,
            get: |s, _| Some(s.$field),
            set: |s, v, _| s.$field = v,
        }
    };
}

/// How the refit searches an effect's shape on a record. The effect declares which search
/// suits its fingerprint; the searches themselves live in the workbench's refit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeSearch {
    /// Nothing to search: a fixed shape, or one the model file gives.
    None,
    /// The sign function's smoothing ε and lead: the reversal shape of dry friction.
    Sign,
    /// A spatial period, on a log grid refined around the residual's periodogram peaks.
    Period,
    /// A transmission mode's frequency and damping.
    Mode,
    /// A quantiser's step and the blur of the recorded command.
    Quantum,
    /// A dead zone's width and the load's coast time through it.
    Gap,
    /// The stick window and the Stribeck curve's velocity and exponent.
    Stick,
    /// A pure delay τ, by a 1-D search on the delayed measured input, with its curvature σ.
    Delay,
}

/// What the fitter and the diagnosis need to know about an effect beyond its columns,
/// declared by the effect's module (`FIT`) so that no `match` on the effect lives in the
/// workbench.
#[derive(Clone, Copy, Debug)]
pub struct FitTraits {
    /// The shape is searched per record (a period, a width, a step): it costs one parameter
    /// in a model comparison on top of the amplitudes.
    pub searched_shape: bool,
    /// How the refit searches the shape.
    pub search: ShapeSearch,
    /// The smooth shape parameter the refit's LM refines, if any.
    pub smooth_shape: Option<SmoothShape>,
    /// The model file's shape parameters and their place in [`Shape`].
    pub file_shape: &'static [FileShape],
    /// Amplitudes the refit holds at a physical value instead of fitting them (name, value).
    pub held: &'static [(&'static str, f64)],
    /// The columns are built from unfiltered signals (a sign, a periodic function of the
    /// position) and must go through the residual's low-pass; false for columns already built
    /// from filtered signals or the instrument, and for constants.
    pub band_limit: bool,
    /// Part of the dry friction that holds a joint at rest (it joins the stick state).
    pub dry_friction: bool,
    /// The columns switch with the direction of motion through the dry friction's sign
    /// function: they share its smoothing, lead and stick window, so friction reverses as one.
    pub sign_shaped: bool,
    /// Whether the columns are linear functions of the measured motion for this shape (so the
    /// position's noise reaches them through a linear filter the noise model can follow).
    pub motion_linear: fn(&Shape) -> bool,
    /// The amplitude is the shape itself (a delay's τ), found by the search on the measured
    /// input and never by least squares, whose column would carry the input's noise; in the
    /// model the effect acts on the measured input.
    pub amplitude_by_search: bool,
    /// Effects a model must hold for this one to be physical (stribeck is the excess of
    /// stiction above a Coulomb level).
    pub requires: &'static [EffectKind],
    /// Effects this one contains as a special case (a ripple of period 2π is gravity): a
    /// swap between them is a nested comparison BIC can judge.
    pub nests: &'static [EffectKind],
    /// The period in the trajectory's position of an effect periodic in it (shape, gear
    /// ratio → period; 0 = unknown): a fit carries over only to the positions it saw, give or
    /// take what a period's error slips its phase there.
    pub position_period: Option<fn(&Shape, f64) -> f64>,
}

impl FitTraits {
    /// An effect with a fixed shape, columns from unfiltered signals, not dry friction,
    /// nesting nothing: the base the modules' `FIT` constants start from.
    pub const PLAIN: FitTraits = FitTraits {
        searched_shape: false,
        search: ShapeSearch::None,
        smooth_shape: None,
        file_shape: &[],
        held: &[],
        band_limit: true,
        dry_friction: false,
        sign_shaped: false,
        motion_linear: never,
        amplitude_by_search: false,
        requires: &[],
        nests: &[],
        position_period: None,
    };
}

/// [`FitTraits::motion_linear`] of effects whose columns are nonlinear in the motion.
fn never(_: &Shape) -> bool {
    false
}

/// Declares every effect once: enum variant ⇒ module. Generates [`EffectKind`], its name
/// table, [`EffectSet`] and the dispatchers.
macro_rules! registry {
    ($( $(#[doc = $doc:literal])* $variant:ident => $module:ident, )*) => {
        $( $(#[doc = $doc])* pub mod $module; )*

        /// Vocabulary shared by simulator, fitter and diagnosis (lowercase names are the
        /// CLI/JSON names).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "lowercase")]
        pub enum EffectKind { $( $(#[doc = $doc])* $variant, )* }

        const EFFECT_COUNT: usize = [$(stringify!($variant)),*].len();

        impl EffectKind {
            /// Every effect, in declaration order.
            pub const ALL: [EffectKind; EFFECT_COUNT] = [$(EffectKind::$variant),*];

            /// Lowercase name used in model files, the CLI and JSON.
            pub fn name(self) -> &'static str {
                match self { $( EffectKind::$variant => stringify!($module), )* }
            }

            /// Inverse of [`EffectKind::name`].
            pub fn from_name(s: &str) -> Option<Self> {
                match s { $( stringify!($module) => Some(EffectKind::$variant), )* _ => None }
            }

            /// One-line physical description and fingerprint in words.
            pub fn describe(self) -> &'static str {
                match self { $( EffectKind::$variant => $module::DESCRIBE, )* }
            }

            /// The effect's parameters (name, unit, default, role).
            pub fn params(self) -> &'static [ParamSpec] {
                match self { $( EffectKind::$variant => $module::PARAMS, )* }
            }

            /// Names of the amplitudes of the fingerprint columns, one per column, in order.
            /// Where a column's amplitude is a model parameter it has that parameter's name
            /// (see [`EffectKind::params`], role `Amplitude(i)`).
            pub fn param_names(self) -> &'static [&'static str] {
                match self { $( EffectKind::$variant => $module::AMPLITUDES, )* }
            }

            /// Physically admissible sign of the *first* amplitude in the convention
            /// r = input − model_input = Σ θ·column, or `None` if either sign is physical.
            /// Friction, delay, deadband and unseen quantisation are positive; compliance seen
            /// from a motor-side sensor is negative. A fit of the wrong sign is not evidence
            /// for the effect (usually errors-in-variables bias from noisy derivatives).
            pub fn admissible_sign(self) -> Option<f64> {
                match self { $( EffectKind::$variant => $module::SIGN, )* }
            }

            /// What the fitter and the diagnosis need to know about the effect
            /// ([`FitTraits`]).
            pub fn fit_traits(self) -> &'static FitTraits {
                match self { $( EffectKind::$variant => &$module::FIT, )* }
            }
        }

        /// The lowercase name (padding and alignment flags apply), as in JSON and the CLI.
        impl std::fmt::Display for EffectKind {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.pad(self.name())
            }
        }

        /// The `[effects]` section of a model file: which effects are present, with their
        /// parameters. Absent = the effect is not in the model.
        #[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct EffectSet {
            $(
                #[allow(missing_docs)]
                #[serde(default, skip_serializing_if = "Option::is_none")]
                pub $module: Option<$module::Params>,
            )*
        }

        impl EffectSet {
            /// Kinds present, in [`EffectKind::ALL`] order.
            pub fn kinds(&self) -> Vec<EffectKind> {
                let mut v = Vec::new();
                $( if self.$module.is_some() { v.push(EffectKind::$variant); } )*
                v
            }

            /// Whether `kind` is present.
            pub fn contains(&self, kind: EffectKind) -> bool {
                match kind { $( EffectKind::$variant => self.$module.is_some(), )* }
            }

            /// Add `kind` with its default parameters (no-op if present).
            pub fn insert_default(&mut self, kind: EffectKind) {
                match kind { $( EffectKind::$variant => {
                    if self.$module.is_none() { self.$module = Some(Default::default()); }
                } )* }
            }

            /// Remove `kind`.
            pub fn remove(&mut self, kind: EffectKind) {
                match kind { $( EffectKind::$variant => self.$module = None, )* }
            }

            /// Parameters of `kind` paired with their specs (empty if absent).
            pub fn params(&self, kind: EffectKind) -> Vec<(&'static ParamSpec, &crate::param::Param)> {
                match kind { $( EffectKind::$variant =>
                    self.$module.as_ref().map(|p| p.entries()).unwrap_or_default(), )* }
            }

            /// Mutable parameters of `kind` (empty if absent).
            pub fn params_mut(&mut self, kind: EffectKind) -> Vec<(&'static ParamSpec, &mut crate::param::Param)> {
                match kind { $( EffectKind::$variant =>
                    self.$module.as_mut().map(|p| p.entries_mut()).unwrap_or_default(), )* }
            }

            /// Write every present effect's contribution into `laws`, then finalize.
            pub fn install(&self, laws: &mut EffectLaws) {
                $( if let Some(p) = &self.$module { $module::install(p, laws); } )*
                laws.finalize();
            }
        }

        /// Regressor columns this effect would add to an inverse-dynamics (equation-error)
        /// residual r = input − model_input: each column is in input units per unit of a
        /// linear amplitude parameter (see each module for the derivation).
        pub fn fingerprint(kind: EffectKind, traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
            match kind { $( EffectKind::$variant => $module::fingerprint(traj, shape), )* }
        }

        /// Candidate shapes to search (e.g. a log-spaced grid of Stribeck velocities, ripple
        /// periods). Always non-empty.
        pub fn shape_grid(kind: EffectKind, traj: &Trajectory) -> Vec<Shape> {
            match kind { $( EffectKind::$variant => $module::shape_grid(traj), )* }
        }
    };
}

registry! {
    /// Constant resisting torque (bias, amplifier offset).
    Offset => offset,
    /// Viscous friction ∝ velocity.
    Viscous => viscous,
    /// Coulomb (dry, kinetic) friction, constant magnitude opposing motion.
    Coulomb => coulomb,
    /// Direction asymmetry of friction (extra friction in the positive direction).
    Asymmetry => asymmetry,
    /// Stiction above Coulomb and the Stribeck transition between them.
    Stribeck => stribeck,
    /// Backlash: a dead zone of lost motion in the transmission.
    Backlash => backlash,
    /// Transmission compliance with soft-zone / stiffening.
    Compliance => compliance,
    /// Position-periodic transmission ripple (tooth / lobe / roller spacing).
    Ripple => ripple,
    /// Motor cogging / torque ripple, periodic in rotor angle.
    Cogging => cogging,
    /// Gravity on the output, m·g·l·sin(q + φ).
    Gravity => gravity,
    /// Torque-constant nonlinearity and small input deadband of the actuator.
    Deadband => deadband,
    /// Transport delay of the actuator command.
    Delay => delay,
    /// Quantisation of the input (D/A steps) and measurement fuzz.
    Quantization => quantization,
}

/// Shapes near `best` (the winner of [`shape_grid`]) worth a second, finer look: a local grid
/// for effects whose fingerprint is sharp in its shape (ripple period, compliance mode,
/// quantiser step); empty for the others. See [`shape_search`].
pub fn refine_grid(kind: EffectKind, traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    match kind {
        EffectKind::Ripple => ripple::refine_grid(traj, best),
        EffectKind::Compliance => compliance::refine_grid(traj, best),
        EffectKind::Quantization => quantization::refine_grid(traj, best),
        EffectKind::Backlash => backlash::refine_grid(traj, best),
        _ => Vec::new(),
    }
}

/// Shapes a dense screen of the residual picks out for the exact test, beside
/// [`shape_grid`]'s, and how many the screen looked at: for effects whose fingerprint is
/// too sharp in its shape for any fixed grid to land on (a ripple's period over a long
/// travel, a quantiser's step across a wide command); none for the others.
pub fn screen(kind: EffectKind, traj: &Trajectory, residual: &[f64]) -> (Vec<Shape>, usize) {
    match kind {
        EffectKind::Ripple => ripple::screen(traj, residual),
        EffectKind::Quantization => quantization::screen(traj, residual),
        _ => (Vec::new(), 0),
    }
}

/// Record-specific columns for the unknown state an effect's internal dynamics start a record
/// in (the compliance mode's free responses, see `compliance::initial_state`); empty for
/// memoryless effects. They are nuisance regressors fitted on each record, never model
/// parameters.
pub fn initial_state(kind: EffectKind, traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    match kind {
        EffectKind::Compliance => compliance::initial_state(traj, shape),
        _ => Vec::new(),
    }
}

/// Why the record itself rules `kind` out, if it does (then it is not a candidate): a load
/// position whose deflection shows no gap rules out a backlash (`backlash::ruled_out`);
/// cogging of unknown period is ripple's fingerprint, tested once as ripple.
/// `None` for the other effects and for records without such evidence.
pub fn ruled_out(kind: EffectKind, traj: &Trajectory) -> Option<&'static str> {
    match kind {
        EffectKind::Backlash => backlash::ruled_out(traj),
        EffectKind::Cogging => cogging::ruled_out(traj),
        _ => None,
    }
}

/// What the record can and cannot identify of `kind` when it is the verdict, if that needs
/// saying: a gap and a transmission spring seen through the motor encoder alone
/// (`backlash::motor_only`). `None` for the other effects and for records that measure the
/// load too.
pub fn identifiability(kind: EffectKind, traj: &Trajectory) -> Option<&'static str> {
    match kind {
        EffectKind::Backlash | EffectKind::Compliance if traj.load().is_none() => {
            Some(backlash::MOTOR_ONLY)
        }
        _ => None,
    }
}

/// Whether the record resolves `shape` of `kind`: false when a shape search ends at the edge
/// of what the record can identify — a compliance mode at or above the top of its grid (above
/// the residual's bandwidth only `J2/(J1·ω²)` is identifiable, not the mode, and a stiff
/// transmission there is not a missing effect at this bandwidth). True for other effects.
pub fn resolved(kind: EffectKind, traj: &Trajectory, shape: &Shape) -> bool {
    match kind {
        EffectKind::Compliance => compliance::resolved(traj, shape),
        _ => true,
    }
}

/// Best shape of `kind` by `score` (higher is better; `None` = not testable at that shape):
/// scans [`shape_grid`] and what [`screen`] picks out of `residual`, then [`refine_grid`]
/// around the best of them. `score` rates a
/// batch of shapes at once (the caller may spread a batch over threads). Returns the best
/// shape, its score and the number of shapes scored (the search's multiplicity).
pub fn shape_search(
    kind: EffectKind,
    traj: &Trajectory,
    residual: &[f64],
    mut score: impl FnMut(&[Shape]) -> Vec<Option<f64>>,
) -> Option<(Shape, f64, usize)> {
    let mut best: Option<(Shape, f64)> = None;
    let mut tried = 0;
    let mut consider = |batch: Vec<Shape>, best: &mut Option<(Shape, f64)>| {
        tried += batch.len();
        let scores = score(&batch);
        for (s, v) in batch.into_iter().zip(scores) {
            if let Some(v) = v {
                if best.as_ref().is_none_or(|b| v > b.1) {
                    *best = Some((s, v));
                }
            }
        }
    };
    let (screened, looked_at) = screen(kind, traj, residual);
    let mut first = shape_grid(kind, traj);
    first.extend(screened);
    consider(first, &mut best);
    if let Some((b, _)) = best.clone() {
        consider(refine_grid(kind, traj, &b), &mut best);
    }
    // The screen's wavenumbers count as shapes tried: its peaks were chosen among them.
    best.map(|(s, v)| (s, v, tried + looked_at))
}

/// The default shape for `kind` given a trajectory: the middle of its [`shape_grid`].
pub fn default_shape(kind: EffectKind, traj: &Trajectory) -> Shape {
    let mut grid = shape_grid(kind, traj);
    let mid = grid.len() / 2;
    grid.swap_remove(mid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_are_lowercase() {
        assert_eq!(EffectKind::ALL.len(), 13);
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_name(k.name()), Some(k));
            assert_eq!(k.name(), k.name().to_lowercase());
            let json = format!("\"{}\"", k.name());
            let back: EffectKind = serde_json_like(&json);
            assert_eq!(back, k);
            assert!(!k.describe().is_empty());
            for p in k.params() {
                assert!(
                    p.min <= p.default && p.default <= p.max,
                    "{}.{}",
                    k.name(),
                    p.name
                );
            }
        }
        assert_eq!(EffectKind::from_name("nonsense"), None);
        assert_eq!(EffectKind::Quantization.name(), "quantization");
    }

    /// Deserialize through toml (the crate has no JSON dependency): `k = "name"`.
    fn serde_json_like(quoted: &str) -> EffectKind {
        #[derive(serde::Deserialize)]
        struct W {
            k: EffectKind,
        }
        toml::from_str::<W>(&format!("k = {quoted}")).unwrap().k
    }

    /// What the workbench asks of every registered effect: a smooth shape is a searched shape
    /// whose accessors round-trip and which its own grid varies (else LM would refine a
    /// parameter the search never moved); an effect nests only others; fingerprints exist
    /// for the shapes it searches.
    #[test]
    fn every_effect_declares_what_the_fitter_needs() {
        let n = 400;
        let dt = 1e-3;
        let q: Vec<f64> = (0..n).map(|i| (2.0 * i as f64 * dt).sin()).collect();
        let v: Vec<f64> = (0..n).map(|i| 2.0 * (2.0 * i as f64 * dt).cos()).collect();
        let a: Vec<f64> = q.iter().map(|q| -4.0 * q).collect();
        let u: Vec<f64> = a.iter().zip(&v).map(|(a, v)| 0.2 * a + 0.3 * v).collect();
        let traj = Trajectory::unfiltered(dt, &u, &q, &v, &a);
        let mut smooth = 0;
        for k in EffectKind::ALL {
            let f = k.fit_traits();
            assert!(!f.nests.contains(&k), "{k} nests itself");
            let grid = shape_grid(k, &traj);
            if let Some(acc) = f.smooth_shape {
                smooth += 1;
                assert!(f.searched_shape, "{k}: a smooth shape is a searched one");
                let mut s = Shape::default();
                (acc.set)(&mut s, 0.123);
                assert_eq!((acc.get)(&s), 0.123, "{k}");
                let vals: Vec<f64> = grid.iter().map(|s| (acc.get)(s)).collect();
                assert!(
                    vals.iter().any(|x| *x != vals[0]),
                    "{k}: its grid does not vary the smooth shape {vals:?}"
                );
            }
            if f.searched_shape && k != EffectKind::Cogging {
                assert!(grid.len() > 1, "{k}: a searched shape needs a grid");
            }
            // The file's shape parameters are the effect's `Shape` parameters, each written
            // back as read (at a gear ratio other than 1, so a conversion must be inverted).
            for fs in f.file_shape {
                let spec = k.params().iter().find(|p| p.name == fs.param);
                assert!(
                    spec.is_some_and(|p| p.role == crate::param::Role::Shape),
                    "{k}: file shape `{}` is not a shape parameter",
                    fs.param
                );
                let mut s = Shape::default();
                (fs.set)(&mut s, 0.37, 7.0);
                let back = (fs.get)(&s, 7.0).unwrap_or(f64::NAN);
                assert!(
                    (back - 0.37).abs() < 1e-12,
                    "{k}: `{}` reads {back}",
                    fs.param
                );
            }
            for (name, _) in f.held {
                assert!(k.param_names().contains(name), "{k} holds unknown `{name}`");
            }
            assert!(!f.requires.contains(&k), "{k} requires itself");
            if f.search == ShapeSearch::Period {
                assert!(
                    f.smooth_shape.is_some(),
                    "{k}: a period search refines the smooth shape"
                );
            }
            assert!(
                !f.amplitude_by_search || f.search != ShapeSearch::None,
                "{k}: an amplitude found by search needs a search"
            );
        }
        assert!(smooth > 0);
    }

    #[test]
    fn every_fingerprint_has_trajectory_length_and_every_grid_is_nonempty() {
        let n = 500;
        let dt = 1e-3;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let q: Vec<f64> = t.iter().map(|t| (3.0 * t).sin()).collect();
        let v: Vec<f64> = t.iter().map(|t| 3.0 * (3.0 * t).cos()).collect();
        let a: Vec<f64> = t.iter().map(|t| -9.0 * (3.0 * t).sin()).collect();
        let u: Vec<f64> = a.iter().zip(&v).map(|(a, v)| 0.1 * a + 0.5 * v).collect();
        let traj = Trajectory::unfiltered(dt, &u, &q, &v, &a);
        for k in EffectKind::ALL {
            let grid = shape_grid(k, &traj);
            assert!(!grid.is_empty(), "{}", k.name());
            for shape in grid.iter().take(3) {
                let cols = fingerprint(k, &traj, shape);
                assert!(!cols.is_empty(), "{}", k.name());
                for c in &cols {
                    assert_eq!(c.len(), n, "{}", k.name());
                    assert!(c.iter().all(|x| x.is_finite()), "{}", k.name());
                }
                let amps = k
                    .params()
                    .iter()
                    .filter(|p| matches!(p.role, crate::param::Role::Amplitude(_)))
                    .count();
                // Either every column is one named amplitude parameter, or the amplitude is a
                // derived combination documented in the module (backlash, compliance).
                assert!(
                    amps == 0 || amps == cols.len(),
                    "{}: amplitude params vs columns",
                    k.name()
                );
            }
        }
    }
}
