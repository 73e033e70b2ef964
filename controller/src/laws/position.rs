//! Position PD / PID, colocated and non-colocated (notes §2.2).
//!
//! Colocated: `τm = Ke(xD − x1) − Be·ẋ1` (motor encoder); non-colocated: `τm = Ke(xD − x2) −
//! Be·ẋ2` (output encoder). Colocated is the robust choice: its gains enter the characteristic
//! polynomial beyond s¹ and s⁰ (§2.2, p.107); non-colocated stability is conditional on the
//! inertia ratio. With an integrator this is the position PID (Ki·T·Σe, §2.6 form); the thesis
//! warns integral action on sticky/backlash systems limit-cycles (§2.6, §2.9).

use super::pid::{PidConfig, PidState};
use crate::fixed_math::{pos_error, Counts, Flags, Output, Vel};

/// Which encoder a position law feeds back (notes §2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Feedback {
    /// Motor encoder x1 (setpoint in motor counts).
    #[default]
    Colocated,
    /// Output encoder x2 (setpoint in output counts).
    NonColocated,
}

/// Position PD/PID configuration. `pid.kp` = Ke in torque LSB per count, `pid.kd` = Be in
/// torque LSB per (1/16 count/s), `pid.ki_t` = Ki·T (see [`PidConfig`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PositionConfig {
    /// Gains and limits.
    pub pid: PidConfig,
    /// Encoder fed back.
    pub feedback: Feedback,
}

/// Position law state (the integrator).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PositionLaw {
    /// PID core state.
    pub pid: PidState,
}

impl PositionLaw {
    /// One step: setpoint `x_d`, measured position `x` and velocity `v` of the fed-back
    /// encoder. Position error is clamped to ±2³¹ counts (flagged).
    #[inline]
    pub fn step(&mut self, cfg: &PositionConfig, x_d: Counts, x: Counts, v: Vel) -> Output {
        let (e, clamped) = pos_error(x_d, x);
        let mut out = self.pid.step(&cfg.pid, e, v.to_bits());
        out.flags.set_if(clamped, Flags::INPUT_CLAMPED);
        out
    }
}
