//! Raw parameter store → typed, ready-to-run configuration.
//!
//! This runs when a `ParamCommit` (or an `Enable` that changes the mode) is accepted — at
//! configuration time, never inside the 1 kHz step — so it may use `f64` to rescale the wire
//! formats of `proto::params` (Q16.16 gains per count or per count/tick, output torque in
//! 0.01 N·m) into the law formats of `fixed_math` (mantissa/shift gains per 1/16 count/s,
//! torques in 0.1 mN·m). The step only swaps in the finished [`CardConfig`].
//!
//! The §2.9 stability guard ([`crate::units::pd_stability`]) is applied here, so a gain set
//! that would make even a rigid rotor unstable under the card's sampling never reaches the
//! loop; the supervisor can run the very same check before it sends (`units`).

use crate::fixed_math::{Alpha, Gain, Torque};
use crate::laws::{
    DamperConfig, Feedback, ForceConfig, ForceDamping, FrictionConfig, Gravity, ImpCompConfig,
    ImpedanceConfig, InputDamping, JointConfig, Mode as LawMode, PidConfig, PositionConfig,
    RippleTable, VelocityConfig,
};
use crate::proto::params::{self as p, WatchdogReaction};
use crate::proto::scale::{MOTOR_TORQUE_NM_PER_LSB, OUTPUT_TORQUE_IN_MOTOR_LSB};
use crate::proto::Mode;
use crate::sensing::ObserverConfig;
use crate::units::{self, StabilityError};

use super::store::ParamStore;

/// Bandwidth of the motor-velocity tracking observer. At 2304 cpr a lower bandwidth gives a
/// smoother estimate but more lag; 100 Hz keeps it ≥ 5× above the position loops the
/// stability guard admits at the thesis's inertia (see `sensing::velocity`).
pub const OBSERVER_BANDWIDTH_HZ: f64 = 100.0;

/// Largest single-tick encoder jump (counts) the observer treats as motion.
pub const OBSERVER_MAX_JUMP: i32 = 4096;

/// Why a parameter set cannot be turned into a running configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// A value cannot be represented in its law format (the id names which).
    Unrepresentable {
        /// Parameter id.
        param: u16,
    },
    /// The §2.9 stability guard refused the (Ke, Be) pair.
    Unstable {
        /// Which bound.
        why: StabilityError,
    },
    /// Position soft limits with min > max.
    LimitsInverted,
    /// A non-colocated mode without an output encoder.
    NeedsOutputEncoder,
}

impl ConfigError {
    /// The parameter id most responsible (for `Fault.detail` / `ParamResponse.param_id`).
    pub fn param(&self) -> u16 {
        match self {
            ConfigError::Unrepresentable { param } => *param,
            ConfigError::Unstable { .. } => p::KE,
            ConfigError::LimitsInverted => p::POSITION_MIN,
            ConfigError::NeedsOutputEncoder => p::OUTPUT_COUNTS_PER_REV,
        }
    }
}

/// Everything the step needs, derived once per commit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CardConfig {
    /// The composed law set for the active mode.
    pub joint: JointConfig,
    /// Motor velocity observer.
    pub observer: ObserverConfig,
    /// Output velocity observer (same bandwidth, output encoder).
    pub output_observer: ObserverConfig,
    /// Final |τ| limit (τLSB), applied last.
    pub torque_limit: Torque,
    /// |ẋ1| limit in law velocity units (1/16 count/s).
    pub velocity_limit: i64,
    /// Soft limits (counts), if enabled.
    pub position_limits: Option<(i64, i64)>,
    /// |τenv| limit in output LSB (0.01 N·m).
    pub output_torque_limit: i32,
    /// The hold-position reaction's law: colocated PD with the active Ke/Be.
    pub hold: PositionConfig,
    /// Quick-stop / fault-reaction damping: τLSB per (1/16 count/s).
    pub quick_stop_damping: Gain,
    /// Below this |ẋ1| (1/16 count/s) a quick stop is complete.
    pub standstill_velocity: i64,
    /// Gain that turns the velocity feed-forward (1/16 count/s) into torque (= Be).
    pub velocity_ff_gain: Gain,
    /// Supervisor watchdog timeout, µs.
    pub supervisor_timeout_us: u64,
    /// What to do when it fires.
    pub watchdog_reaction: WatchdogReaction,
    /// Sensor timeout, µs.
    pub sensor_timeout_us: u64,
    /// Lost sensor frames tolerated in a row.
    pub max_seq_skip: u8,
    /// Ticks per telemetry frame (0 = off).
    pub telemetry_divider: u16,
    /// Heartbeat period, µs.
    pub heartbeat_period_us: u64,
}

fn gain(param: u16, v: f64) -> Result<Gain, ConfigError> {
    units::gain_from_f64("param", v).map_err(|_| ConfigError::Unrepresentable { param })
}

/// Q16.16 raw → real.
fn q16(raw: i32) -> f64 {
    f64::from(raw) / 65536.0
}

/// Q0.16 (65536 = 1.0) → the laws' `Alpha` (U1F15).
fn alpha(raw: i32) -> Alpha {
    let bits = u16::try_from(raw.clamp(0, 65536) >> 1).unwrap_or(u16::MAX);
    Alpha::from_bits(bits)
}

/// A Q0.16 factor that may exceed 1 (the parameter's range bounds it) → U1F15.
fn factor(raw: i32) -> Alpha {
    let bits = u16::try_from(raw.clamp(0, 131_070) >> 1).unwrap_or(u16::MAX);
    Alpha::from_bits(bits)
}

fn ms_to_us(ms: i32) -> u64 {
    u64::from(ms.unsigned_abs()).saturating_mul(1000)
}

fn counts_per_s_to_law(v: i32) -> i64 {
    i64::from(v).saturating_mul(16)
}

/// Loop rate implied by `CONTROL_PERIOD` (µs), at least 1 Hz.
pub fn rate_hz(s: &ParamStore) -> u16 {
    let period = s.raw(p::CONTROL_PERIOD).max(1);
    u16::try_from(1_000_000i32.checked_div(period).unwrap_or(1000)).unwrap_or(u16::MAX)
}

/// The stability guard on the store's (Ke, Be) read as motor-side PD gains with the store's
/// rotor inertia, period and margin, Be less what a viscous friction feed-forward takes away.
/// In `mode`'s non-colocated forms the gains are per output count, taken at the motor through
/// the gear ratio (the rigid joint the guard assumes). Passes when both gains are zero.
pub fn check_stability(s: &ParamStore, mode: Option<Mode>) -> Result<(), ConfigError> {
    let (ke_raw, be_raw) = (s.raw(p::KE), s.raw(p::BE));
    if ke_raw == 0 && be_raw == 0 {
        return Ok(());
    }
    // Motor rad per count of the encoder the law feeds back, and of the motor's (B1E and the
    // viscous feed-forward act on ẋ1 in every mode).
    let motor_rad_per_count =
        core::f64::consts::TAU / f64::from(s.raw(p::MOTOR_COUNTS_PER_REV).max(1));
    let rad_per_count = if mode.is_some_and(|m| m.needs_output_encoder()) {
        let cpr = f64::from(s.raw(p::OUTPUT_COUNTS_PER_REV).max(1));
        core::f64::consts::TAU / cpr * q16(s.raw(p::GEAR_RATIO))
    } else {
        motor_rad_per_count
    };
    let period_s = f64::from(s.raw(p::CONTROL_PERIOD)) * 1e-6;
    let ke_si = q16(ke_raw) * MOTOR_TORQUE_NM_PER_LSB / rad_per_count;
    let per_tick_on = |raw: i32, rad: f64| q16(raw) * MOTOR_TORQUE_NM_PER_LSB / rad * period_s;
    let per_tick = |raw: i32| per_tick_on(raw, motor_rad_per_count);
    // A viscous friction feed-forward is +u·Bv·ẋ1: negative damping on the rotor, which the
    // input damping B1e offsets first and the law's Be after it (the friction it cancels acts
    // beyond the transmission, where the rotor's fast mode does not feel it). On the
    // setpoint's velocity it is no feedback at all.
    let negative = if s.raw(p::FRICTION_ENABLE) != 0 && s.raw(p::FRICTION_SOURCE) == 0 {
        let u = f64::from(s.raw(p::UNDER_COMPENSATION)) / 65536.0;
        (u * per_tick(s.raw(p::VISCOUS_POS)) - per_tick(s.raw(p::B1E))).max(0.0)
    } else {
        0.0
    };
    let be_si = per_tick_on(be_raw, rad_per_count) - negative;
    let inertia = f64::from(s.raw(p::ROTOR_INERTIA)) * 1e-9;
    let margin = 1.0 - f64::from(s.raw(p::STABILITY_MARGIN)) / 65536.0;
    units::pd_stability(
        ke_si,
        be_si,
        inertia,
        period_s,
        margin.clamp(0.0, 0.999_999),
    )
    .map(|_| ())
    .map_err(|why| ConfigError::Unstable { why })
}

/// The gravity feed-forward `gravity_sin·sin θ + gravity_cos·cos θ`, θ the output angle
/// over one output revolution of motor counts. `None` when both amplitudes are 0.
fn gravity(s: &ParamStore) -> Result<Option<Gravity>, ConfigError> {
    let (gs, gc) = (s.raw(p::GRAVITY_SIN), s.raw(p::GRAVITY_COS));
    if gs == 0 && gc == 0 {
        return Ok(None);
    }
    let bad = ConfigError::Unrepresentable {
        param: p::GEAR_RATIO,
    };
    // counts per output rev = cpr · N, N in Q16.16 (both positive by their ranges)
    let per_rev = i64::from(s.raw(p::MOTOR_COUNTS_PER_REV))
        .saturating_mul(i64::from(s.raw(p::GEAR_RATIO)))
        .saturating_add(1 << 15)
        >> 16;
    let per_rev = u32::try_from(per_rev).map_err(|_| bad)?;
    Gravity::new(per_rev, gs, gc).map(Some).ok_or(bad)
}

/// Builds the running configuration for `mode` (or with no main law, for `None`).
pub fn build(s: &ParamStore, mode: Option<Mode>) -> Result<CardConfig, ConfigError> {
    check_stability(s, mode)?;
    let rate = f64::from(rate_hz(s));
    // Q16.16 per count/tick → per (1/16 count/s): divide by 16·rate.
    let per_rate = |param: u16| gain(param, q16(s.raw(param)) / (16.0 * rate));
    let out_lsb = f64::from(OUTPUT_TORQUE_IN_MOTOR_LSB);
    let torque_limit = s.raw(p::TORQUE_LIMIT).clamp(0, i32::from(i16::MAX));

    let ke = gain(p::KE, q16(s.raw(p::KE)))?;
    let be = per_rate(p::BE)?;
    let ki_t = gain(p::KI, f64::from(s.raw(p::KI)))?;
    let i_limit = s.raw(p::INTEGRATOR_LIMIT);
    // Motor counts per count of the encoder the law feeds back (the joint taken as rigid).
    let motor_counts_per_law_count = match mode {
        Some(m) if m.needs_output_encoder() && s.raw(p::OUTPUT_COUNTS_PER_REV) > 0 => {
            f64::from(s.raw(p::MOTOR_COUNTS_PER_REV)) * q16(s.raw(p::GEAR_RATIO))
                / f64::from(s.raw(p::OUTPUT_COUNTS_PER_REV))
        }
        _ => 1.0,
    };
    let feedback = match mode {
        Some(Mode::PositionPdNonColocated | Mode::ImpedanceNonColocated) => {
            if s.raw(p::OUTPUT_COUNTS_PER_REV) == 0 {
                return Err(ConfigError::NeedsOutputEncoder);
            }
            Feedback::NonColocated
        }
        _ => Feedback::Colocated,
    };
    let position = |ki_t: Gain| PositionConfig {
        pid: PidConfig {
            kp: ke,
            kd: be,
            ki_t,
            i_limit,
            tau_max: torque_limit,
        },
        feedback,
    };
    let force = |kd: Gain, ki_t: Gain, damping: ForceDamping| ForceConfig {
        pid: PidConfig {
            kp: gain(p::FORCE_KP, q16(s.raw(p::FORCE_KP)) / out_lsb).unwrap_or(Gain::ZERO),
            kd,
            ki_t,
            i_limit: s.raw(p::FORCE_INTEGRATOR_LIMIT),
            tau_max: torque_limit,
        },
        damping,
    };
    // Force gains are validated once here so the closure above can default silently.
    gain(p::FORCE_KP, q16(s.raw(p::FORCE_KP)) / out_lsb)?;
    let force_kd = gain(p::FORCE_KD, q16(s.raw(p::FORCE_KD)) / out_lsb)?;
    let force_ki = gain(p::FORCE_KI, f64::from(s.raw(p::FORCE_KI)) / out_lsb)?;
    let km = gain(p::KM, q16(s.raw(p::KM)) / out_lsb)?;

    let law = match mode {
        None | Some(Mode::TorquePassthrough) => LawMode::Off,
        Some(Mode::PositionPdColocated | Mode::PositionPdNonColocated) => {
            LawMode::Position(position(Gain::ZERO))
        }
        Some(Mode::PositionPid) => LawMode::Position(position(ki_t)),
        // Ki·T per (1/16 count/s) per tick in 2⁻¹⁶ torque LSB: Ke·(1/16)·T·2¹⁶.
        Some(Mode::Velocity) => LawMode::Velocity(VelocityConfig {
            pid: PidConfig {
                kp: be,
                kd: Gain::ZERO,
                ki_t: gain(p::KE, q16(s.raw(p::KE)) * 4096.0 / rate)?,
                i_limit,
                tau_max: torque_limit,
            },
        }),
        Some(Mode::Damper) => LawMode::Damper(DamperConfig {
            b: be,
            tau_max: torque_limit,
        }),
        Some(Mode::ForceP) => LawMode::Force(force(Gain::ZERO, Gain::ZERO, ForceDamping::None)),
        Some(Mode::ForcePd) => LawMode::Force(force(
            force_kd,
            Gain::ZERO,
            ForceDamping::ForceRate {
                alpha: alpha(s.raw(p::FORCE_RATE_FILTER)),
            },
        )),
        Some(Mode::ForcePi) => LawMode::Force(force(Gain::ZERO, force_ki, ForceDamping::None)),
        Some(Mode::ImpedanceColocated | Mode::ImpedanceNonColocated) => {
            LawMode::Impedance(ImpedanceConfig {
                ke,
                be,
                km,
                tau_max: torque_limit,
                feedback,
            })
        }
    };

    let friction_law = if s.raw(p::FRICTION_ENABLE) != 0 {
        // Transition: a linear ramp through zero velocity of half-width `FRICTION_DEADBAND`
        // (see laws::friction) — τc/ω_r as the slope.
        let w = f64::from(s.raw(p::FRICTION_DEADBAND).max(1)) * 16.0;
        // On the setpoint's velocity in a non-colocated mode the velocity is in output
        // counts/s: the ramp and the viscous term per motor count/s are scaled to it.
        let per = if s.raw(p::FRICTION_SOURCE) == 1 {
            motor_counts_per_law_count
        } else {
            1.0
        };
        Some(FrictionConfig {
            tau_c_pos: s.raw(p::COULOMB_POS),
            tau_c_neg: s.raw(p::COULOMB_NEG),
            slope_pos: gain(p::COULOMB_POS, f64::from(s.raw(p::COULOMB_POS)) / w * per)?,
            slope_neg: gain(p::COULOMB_NEG, f64::from(s.raw(p::COULOMB_NEG)) / w * per)?,
            viscous: gain(
                p::VISCOUS_POS,
                q16(s.raw(p::VISCOUS_POS)) / (16.0 * rate) * per,
            )?,
            undercomp: factor(s.raw(p::UNDER_COMPENSATION)),
            limit: torque_limit,
            alpha: alpha(s.raw(p::FRICTION_FILTER)),
        })
    } else {
        None
    };

    let friction = friction_law;

    let imp_comp = if s.raw(p::IMPEDANCE_COMP_ENABLE) != 0 {
        Some(ImpCompConfig {
            kd: gain(
                p::IMPEDANCE_COMP_STIFFNESS,
                q16(s.raw(p::IMPEDANCE_COMP_STIFFNESS)) * out_lsb,
            )?,
            gain: gain(
                p::IMPEDANCE_COMP_GAIN,
                q16(s.raw(p::IMPEDANCE_COMP_GAIN)) / out_lsb,
            )?,
            alpha: alpha(s.raw(p::IMPEDANCE_COMP_FILTER)),
            limit: torque_limit,
        })
    } else {
        None
    };

    let ripple = if s.raw(p::RIPPLE_ENABLE) != 0 {
        let mut raw = [0i32; p::RIPPLE_TABLE_LEN as usize];
        s.run(p::RIPPLE_TABLE, &mut raw);
        let len = usize::try_from(s.raw(p::RIPPLE_LENGTH)).unwrap_or(0);
        let mut entries = [0i16; p::RIPPLE_TABLE_LEN as usize];
        for (e, r) in entries.iter_mut().zip(raw.iter()) {
            *e = i16::try_from(*r).unwrap_or(0);
        }
        let used = entries.get(..len).ok_or(ConfigError::Unrepresentable {
            param: p::RIPPLE_LENGTH,
        })?;
        let period = u32::try_from(s.raw(p::RIPPLE_PERIOD)).unwrap_or(0);
        let phase = u32::try_from(s.raw(p::RIPPLE_PHASE)).unwrap_or(0);
        Some(
            RippleTable::new(period, used)
                .map_err(|_| ConfigError::Unrepresentable {
                    param: p::RIPPLE_PERIOD,
                })?
                .with_phase(phase),
        )
    } else {
        None
    };
    let gravity = gravity(s)?;

    let (pmin, pmax) = (s.raw(p::POSITION_MIN), s.raw(p::POSITION_MAX));
    if pmin > pmax {
        return Err(ConfigError::LimitsInverted);
    }
    let position_limits =
        (s.raw(p::SOFT_LIMITS_ENABLE) != 0).then_some((i64::from(pmin), i64::from(pmax)));

    let observer_scale = |cpr: i32| units::Scale {
        period_s: f64::from(s.raw(p::CONTROL_PERIOD)) * 1e-6,
        motor_cpr: u32::try_from(cpr.max(1)).unwrap_or(1),
        output_cpr: 0,
        gear_ratio: 1.0,
        torque_lsb_nm: MOTOR_TORQUE_NM_PER_LSB,
    };
    let observer = units::observer_config(
        &observer_scale(s.raw(p::MOTOR_COUNTS_PER_REV)),
        OBSERVER_BANDWIDTH_HZ,
        1.0,
        OBSERVER_MAX_JUMP,
    )
    .map_err(|_| ConfigError::Unrepresentable {
        param: p::CONTROL_PERIOD,
    })?;
    let output_observer = observer;

    Ok(CardConfig {
        joint: JointConfig {
            mode: law,
            input_damping: InputDamping {
                b1e: per_rate(p::B1E)?,
            },
            friction,
            // On the setpoint's velocity the card adds it with that feed-forward.
            friction_on_setpoint: s.raw(p::FRICTION_SOURCE) == 1,
            imp_comp,
            ripple,
            offset: s.raw(p::TORQUE_OFFSET),
            gravity,
            tau_max: torque_limit,
            ..JointConfig::default()
        },
        observer,
        output_observer,
        torque_limit,
        velocity_limit: counts_per_s_to_law(s.raw(p::VELOCITY_LIMIT)),
        position_limits,
        output_torque_limit: s.raw(p::OUTPUT_TORQUE_LIMIT),
        // The hold is colocated: a non-colocated mode's gains taken to motor counts.
        hold: PositionConfig {
            pid: PidConfig {
                kp: gain(p::KE, q16(s.raw(p::KE)) / motor_counts_per_law_count)?,
                kd: gain(
                    p::BE,
                    q16(s.raw(p::BE)) / (16.0 * rate) / motor_counts_per_law_count,
                )?,
                ki_t: Gain::ZERO,
                i_limit: 0,
                tau_max: torque_limit,
            },
            feedback: Feedback::Colocated,
        },
        quick_stop_damping: per_rate(p::QUICK_STOP_DAMPING)?,
        standstill_velocity: counts_per_s_to_law(s.raw(p::STANDSTILL_VELOCITY)),
        velocity_ff_gain: be,
        supervisor_timeout_us: ms_to_us(s.raw(p::SUPERVISOR_TIMEOUT)),
        watchdog_reaction: WatchdogReaction::from_u8(
            u8::try_from(s.raw(p::WATCHDOG_REACTION)).unwrap_or(0),
        )
        .unwrap_or(WatchdogReaction::ZeroTorque),
        sensor_timeout_us: u64::from(s.raw(p::SENSOR_TIMEOUT).unsigned_abs()),
        max_seq_skip: u8::try_from(s.raw(p::MAX_SEQ_SKIP)).unwrap_or(u8::MAX),
        telemetry_divider: u16::try_from(s.raw(p::TELEMETRY_DIVIDER)).unwrap_or(0),
        heartbeat_period_us: ms_to_us(s.raw(p::HEARTBEAT_PERIOD)),
    })
}
