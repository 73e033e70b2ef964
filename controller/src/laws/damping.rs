//! Input-velocity damping `−B1e·ẋ1`, addable to any law (notes §2.4, Eqn 3.3.12), and the
//! damper mode `τm = −Bdes·ω` (§2.10 damper emulation).
//!
//! B1e "reflects the equivalent electronic damping at the input shaft". Because it enters the
//! characteristic polynomial beyond s¹, there is no hard stability limit on it with ideal
//! sensing — the real limit is velocity resolution, which is why `sensing::TrackingObserver`
//! exists. The damper mode is PD with Ke = 0; it is its own type so the supervisor can size
//! Bdes "to avoid saturation at top speed" (§2.10) against its own limit.

use crate::fixed_math::{clamp_sym, Flags, Gain, Output, Torque, Vel};

/// Input-velocity damping term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InputDamping {
    /// B1e: torque LSB per (1/16 count/s) of the motor velocity. `Gain::ZERO` = off.
    pub b1e: Gain,
}

impl InputDamping {
    /// `−B1e·ẋ1` in torque LSB, unclamped (|·| < 2⁶²; the caller sums and clamps).
    #[inline]
    pub fn torque(&self, v1: Vel) -> i64 {
        self.b1e.apply(v1.to_bits()).wrapping_neg()
    }
}

/// Damper-mode configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DamperConfig {
    /// Bdes: torque LSB per (1/16 count/s) of the motor velocity.
    pub b: Gain,
    /// |output| limit.
    pub tau_max: Torque,
}

/// Damper mode `τ = −Bdes·ω` (stateless).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DamperLaw;

impl DamperLaw {
    /// One step with the motor velocity.
    #[inline]
    pub fn step(&mut self, cfg: &DamperConfig, v1: Vel) -> Output {
        let (tau, sat) = clamp_sym(cfg.b.apply(v1.to_bits()).wrapping_neg(), cfg.tau_max);
        let mut flags = Flags::NONE;
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        Output { tau, flags }
    }
}
