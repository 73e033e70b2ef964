//! The composed joint controller the card runtime calls once per tick:
//!
//! ```text
//! τ = clamp_{±tau_max}( main law(mode) − B1e·ẋ1 + friction FF + impedance comp + ripple
//!                        + gravity FF + offset FF + bumpless transfer offset )
//! ```
//!
//! * `main law` is one of [`Mode`]: off, position PD/PID (colocated / non-colocated), damper,
//!   force P/PD/PI/PID, impedance. Each is clamped to its own limit first.
//! * The additive terms are the thesis's proposals for what the 10 Hz supervisor could not do
//!   and belongs "at the motor controller level (running at 1000 Hz)" (notes §1, §2.11–2.12).
//! * **Bumpless transfer** ([`JointState::init_bumpless`]): when the runtime switches mode or
//!   commits new gains, it calls `init_bumpless(new_cfg, previous_output, setpoint, meas)`
//!   before the first `step` with the new configuration. The next output then equals
//!   `previous_output` (±1 LSB) for unchanged inputs. The difference between what the new
//!   configuration would produce and the previous output goes into the integrator if the new
//!   law has one (it stays there, as in any bumpless PID), otherwise into a transfer offset
//!   that decays geometrically (`offset −= offset >> transfer_shift` per tick, at least 1 LSB),
//!   so a new PD gain set takes full effect after ≈ 2^shift ticks instead of as a step.

use super::damping::{DamperConfig, DamperLaw, InputDamping};
use super::force::{ForceConfig, ForceLaw};
use super::friction::{FrictionComp, FrictionConfig};
use super::gravity::Gravity;
use super::impcomp::{ImpComp, ImpCompConfig};
use super::impedance::{ImpedanceConfig, ImpedanceLaw};
use super::position::{Feedback, PositionConfig, PositionLaw};
use super::ripple::RippleTable;
use super::velocity::{VelocityConfig, VelocityLaw};
use crate::fixed_math::{clamp_sym, sat_i32, Counts, Flags, Output, Torque, TorqueCmd, Vel};

/// The main control law.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// Zero torque from the main law (additive terms still apply unless disabled).
    #[default]
    Off,
    /// Position PD / PID (spring mode when Be = Ki = 0, §2.10).
    Position(PositionConfig),
    /// Pure damper −Bdes·ẋ1 (§2.10).
    Damper(DamperConfig),
    /// Force P / PD / PI / PID (§2.3–2.6).
    Force(ForceConfig),
    /// Impedance (§2.8).
    Impedance(ImpedanceConfig),
    /// Velocity PI on the motor encoder against the setpoint's velocity.
    Velocity(VelocityConfig),
}

/// Discriminant of [`Mode`] (for telemetry and the runtime's switch logic).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModeKind {
    /// [`Mode::Off`]
    #[default]
    Off,
    /// [`Mode::Position`]
    Position,
    /// [`Mode::Damper`]
    Damper,
    /// [`Mode::Force`]
    Force,
    /// [`Mode::Impedance`]
    Impedance,
    /// [`Mode::Velocity`]
    Velocity,
}

impl Mode {
    /// Which kind of law this is.
    pub const fn kind(&self) -> ModeKind {
        match self {
            Mode::Off => ModeKind::Off,
            Mode::Position(_) => ModeKind::Position,
            Mode::Damper(_) => ModeKind::Damper,
            Mode::Force(_) => ModeKind::Force,
            Mode::Impedance(_) => ModeKind::Impedance,
            Mode::Velocity(_) => ModeKind::Velocity,
        }
    }
    /// Encoder the position-type laws feed back (colocated for the others).
    pub const fn feedback(&self) -> Feedback {
        match self {
            Mode::Position(c) => c.feedback,
            Mode::Impedance(c) => c.feedback,
            _ => Feedback::Colocated,
        }
    }
}

/// Full joint configuration (what a committed gain set becomes). Not `Copy` because of the
/// ripple table; the runtime keeps an active and a staged copy and swaps at a tick boundary.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JointConfig {
    /// Main law.
    pub mode: Mode,
    /// Input-velocity damping −B1e·ẋ1 added to any law (`Gain::ZERO` = off).
    pub input_damping: InputDamping,
    /// Friction feed-forward on ẋ1.
    pub friction: Option<FrictionConfig>,
    /// The friction feed-forward is the caller's, on the setpoint's velocity: the law skips it.
    pub friction_on_setpoint: bool,
    /// Impedance compensation (active in position and impedance modes; uses the same encoder
    /// and setpoint as the main law).
    pub imp_comp: Option<ImpCompConfig>,
    /// Ripple / cogging table on x1.
    pub ripple: Option<RippleTable>,
    /// Constant feed-forward (a measured offset), LSB.
    pub offset: Torque,
    /// Gravity feed-forward on the output angle.
    pub gravity: Option<Gravity>,
    /// Final |τ| limit, LSB (values above `i16::MAX` are treated as `i16::MAX`).
    pub tau_max: Torque,
    /// Transfer-offset decay shift (τ ≈ 2^shift ticks); 0 means "no offset, jump".
    pub transfer_shift: u8,
}

impl Default for JointConfig {
    fn default() -> Self {
        JointConfig {
            mode: Mode::Off,
            input_damping: InputDamping::default(),
            friction: None,
            friction_on_setpoint: false,
            imp_comp: None,
            ripple: None,
            offset: 0,
            gravity: None,
            tau_max: 0,
            transfer_shift: 6,
        }
    }
}

/// Setpoints latched by the runtime.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Setpoint {
    /// Desired position in counts of the encoder the active law feeds back.
    pub x_d: Counts,
    /// Desired output torque (force modes), sensor LSB.
    pub tau_d: Torque,
    /// Desired motor velocity (velocity mode).
    pub v_d: Vel,
}

/// Measured quantities for one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurements {
    /// Motor position (multi-turn counts).
    pub x1: Counts,
    /// Motor velocity estimate.
    pub v1: Vel,
    /// Output position (output encoder counts; 0 if none).
    pub x2: Counts,
    /// Output velocity estimate.
    pub v2: Vel,
    /// Output torque sensor (0.1 mN·m output side).
    pub tau_env: Torque,
}

/// All law states (kept across mode switches so switching back is clean).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointState {
    /// Position PID state.
    pub position: PositionLaw,
    /// Force law state.
    pub force: ForceLaw,
    /// Velocity PI state.
    pub velocity: VelocityLaw,
    /// Impedance compensation state.
    pub imp_comp: ImpComp,
    /// Friction compensation state (its velocity low-pass).
    pub friction: FrictionComp,
    /// Bumpless-transfer offset, torque LSB.
    pub offset: Torque,
    last_kind: ModeKind,
}

/// Result of one joint step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointOutput {
    /// Final torque (within ±`tau_max`) and the OR of all flags.
    pub out: Output,
    /// The main law's contribution (for telemetry).
    pub law: Torque,
}

impl JointOutput {
    /// The `i16` torque command.
    pub fn command(&self) -> TorqueCmd {
        crate::fixed_math::to_command(self.out.tau).0
    }
}

impl JointState {
    /// Fresh state.
    pub const fn new() -> Self {
        JointState {
            position: PositionLaw {
                pid: super::pid::PidState::ZERO,
            },
            force: ForceLaw::NEW,
            velocity: VelocityLaw::NEW,
            imp_comp: ImpComp::NEW,
            friction: FrictionComp::NEW,
            offset: 0,
            last_kind: ModeKind::Off,
        }
    }

    /// Reset everything (integrators, filters, offset) — e.g. on disable.
    pub fn reset(&mut self) {
        *self = JointState::new();
    }

    /// Kind of the last law stepped.
    pub fn last_kind(&self) -> ModeKind {
        self.last_kind
    }

    fn sel(cfg: &JointConfig, m: &Measurements) -> (Counts, Vel) {
        match cfg.mode.feedback() {
            Feedback::Colocated => (m.x1, m.v1),
            Feedback::NonColocated => (m.x2, m.v2),
        }
    }

    /// Sum of all terms without the transfer offset and without the final clamp.
    fn raw(&mut self, cfg: &JointConfig, sp: &Setpoint, m: &Measurements) -> (i64, Torque, Flags) {
        let (x, v) = Self::sel(cfg, m);
        let law = match &cfg.mode {
            Mode::Off => Output::default(),
            Mode::Position(c) => self.position.step(c, sp.x_d, x, v),
            Mode::Damper(c) => DamperLaw.step(c, m.v1),
            Mode::Force(c) => self.force.step(c, sp.tau_d, m.tau_env, m.v1),
            Mode::Impedance(c) => ImpedanceLaw.step(c, sp.x_d, x, v, m.tau_env),
            Mode::Velocity(c) => self.velocity.step(c, sp.v_d, m.v1),
        };
        let mut flags = law.flags;
        // Every term but the damping is an i32; the damping (|·| < 2⁶²) is clamped to ±2⁴⁰,
        // far beyond any torque limit, so the sum of seven terms stays < 2⁴³ and plain adds
        // are exact — and the final clamp sees the same sign and saturation as the exact sum.
        let damping = cfg
            .input_damping
            .torque(m.v1)
            .clamp(-(1i64 << 40), 1i64 << 40);
        let mut sum = i64::from(law.tau).wrapping_add(damping);
        if let (Some(f), false) = (&cfg.friction, cfg.friction_on_setpoint) {
            let o = self.friction.step(f, m.v1);
            flags |= o.flags;
            sum = sum.wrapping_add(i64::from(o.tau));
        }
        if let Some(ic) = &cfg.imp_comp {
            if matches!(cfg.mode, Mode::Position(_) | Mode::Impedance(_)) {
                let o = self.imp_comp.step(ic, sp.x_d, x, m.tau_env);
                flags |= o.flags;
                sum = sum.wrapping_add(i64::from(o.tau));
            }
        }
        if let Some(r) = &cfg.ripple {
            sum = sum.wrapping_add(i64::from(r.torque(m.x1)));
        }
        if let Some(g) = &cfg.gravity {
            sum = sum.wrapping_add(i64::from(g.torque(m.x1)));
        }
        sum = sum.wrapping_add(i64::from(cfg.offset));
        self.last_kind = cfg.mode.kind();
        (sum, law.tau, flags)
    }

    /// One 1 kHz step.
    #[inline]
    pub fn step(&mut self, cfg: &JointConfig, sp: &Setpoint, m: &Measurements) -> JointOutput {
        let (sum, law, mut flags) = self.raw(cfg, sp, m);
        let total = sum.wrapping_add(i64::from(self.offset)); // < 2⁴⁴: exact
        let lim = cfg.tau_max.clamp(0, i32::from(i16::MAX));
        let (tau, sat) = clamp_sym(total, lim);
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        if self.offset != 0 {
            flags |= Flags::TRANSFER_ACTIVE;
            let mut d = self
                .offset
                .wrapping_shr(u32::from(cfg.transfer_shift.min(30)));
            if d == 0 || cfg.transfer_shift == 0 {
                d = if cfg.transfer_shift == 0 {
                    self.offset
                } else {
                    self.offset.signum()
                };
            }
            self.offset = self.offset.saturating_sub(d);
        }
        JointOutput {
            out: Output { tau, flags },
            law,
        }
    }

    /// Bumpless transfer hook: call after committing `cfg` (new gains and/or new mode) and
    /// before the next [`JointState::step`], with the last torque actually commanded. See the
    /// module docs. Entering a mode whose filters hold stale data (force-rate differentiator,
    /// impedance-compensation low-pass) primes them from the current measurements first.
    pub fn init_bumpless(
        &mut self,
        cfg: &JointConfig,
        previous_output: Torque,
        sp: &Setpoint,
        m: &Measurements,
    ) {
        let kind = cfg.mode.kind();
        if kind != self.last_kind {
            self.friction.prime(m.v1);
            self.force.prime(m.tau_env);
            if let Some(ic) = &cfg.imp_comp {
                let (x, _) = Self::sel(cfg, m);
                self.imp_comp.prime(ic, sp.x_d, x, m.tau_env);
            }
            if kind != ModeKind::Position {
                self.position.pid.reset();
            }
            if kind != ModeKind::Force {
                self.force.pid.reset();
            }
            if kind != ModeKind::Velocity {
                self.velocity.pid.reset();
            }
        }
        self.offset = 0;
        let mut trial = *self;
        let (y0, _, _) = trial.raw(cfg, sp, m);
        let (delta, _) = sat_i32(i64::from(previous_output).saturating_sub(y0));
        match &cfg.mode {
            Mode::Position(c) if c.pid.has_integrator() => {
                self.position.pid.absorb(&c.pid, delta);
            }
            Mode::Force(c) if c.pid.has_integrator() => {
                self.force.pid.absorb(&c.pid, delta);
            }
            Mode::Velocity(c) if c.pid.has_integrator() => {
                self.velocity.pid.absorb(&c.pid, delta);
            }
            _ => {}
        }
        // Whatever the integrator could not take (its limit, the law's own clamp) goes into
        // the decaying offset: evaluate again with the preloaded integrator.
        let mut trial = *self;
        let (y1, _, _) = trial.raw(cfg, sp, m);
        let (rest, _) = sat_i32(i64::from(previous_output).saturating_sub(y1));
        self.offset = if cfg.transfer_shift == 0 { 0 } else { rest };
        self.last_kind = kind;
    }
}
