//! Velocity PI on the motor encoder: `τm = Kv·(v_d − ẋ1) + I`, `I_k = I_{k−1} + Ki·T·(v_d −
//! ẋ1)`, the speed loop closed on the motor side of the machine-tool paper's validation (its
//! 1 s velocity pulse). `v_d` is the setpoint's velocity. The integrator is the PID core's,
//! with its anti-windup clamp; `Ki·∫(v_d − ẋ1)dt` is Ki times the position error against the
//! integrated reference, which is why Ki is set through the position law's Ke and Kv through
//! its Be.

use super::pid::{PidConfig, PidState};
use crate::fixed_math::{Flags, Output, Vel};

/// Velocity PI configuration: `pid.kp` = Kv in torque LSB per (1/16 count/s), `pid.ki_t` =
/// Ki·T in 2⁻¹⁶ torque LSB per (1/16 count/s) per tick; `pid.kd` is not used.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityConfig {
    /// Gains and limits.
    pub pid: PidConfig,
}

/// Velocity law state (the integrator).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VelocityLaw {
    /// PID core state.
    pub pid: PidState,
}

impl VelocityLaw {
    /// Fresh state.
    pub const NEW: VelocityLaw = VelocityLaw {
        pid: PidState::ZERO,
    };

    /// One step: setpoint velocity `v_d`, measured motor velocity `v`.
    #[inline]
    pub fn step(&mut self, cfg: &VelocityConfig, v_d: Vel, v: Vel) -> Output {
        let e = v_d.to_bits().saturating_sub(v.to_bits());
        let clamped = e == i32::MAX || e == i32::MIN;
        let mut out = self.pid.step(&cfg.pid, e, 0);
        out.flags.set_if(clamped, Flags::INPUT_CLAMPED);
        out
    }
}
