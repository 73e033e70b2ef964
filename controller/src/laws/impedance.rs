//! Impedance control (notes §2.8, Eqns 3.3.19–20):
//! `τm = Ke(xD − x) − Be·ẋ + Km·τenv`, `Km = 1 − Ia/Id` (−∞ < Km < 1), colocated (x = x1) or
//! non-colocated (x = x2).
//!
//! Km > 0 makes the joint feel lighter than it is (Id > Ia), Km < 0 heavier. Statically,
//! with the environment torque equal to the motor torque, the stiffness seen by the
//! environment is Ke/(1 − Km) (tested in `laws_closed_loop`). The thesis calls these "naive"
//! controllers; reducing desired inertia (Km < 0 … here: Id < Ia) shrinks stability, and only
//! the colocated form avoids an undamped response — prefer `Feedback::Colocated`.

use super::position::Feedback;
use crate::fixed_math::{clamp_sym, pos_error, Counts, Flags, Gain, Output, Torque, Vel};

/// Impedance law configuration.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImpedanceConfig {
    /// Ke: torque LSB per count of the fed-back encoder.
    pub ke: Gain,
    /// Be: torque LSB per (1/16 count/s).
    pub be: Gain,
    /// Km/N: motor torque LSB per sensor (output) torque LSB; may be negative.
    pub km: Gain,
    /// |output| limit, torque LSB.
    pub tau_max: Torque,
    /// Encoder fed back.
    pub feedback: Feedback,
}

/// Impedance law (stateless: D uses the estimated velocity; kept as a type for symmetry).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImpedanceLaw;

impl ImpedanceLaw {
    /// One step: setpoint `x_d`, measured `x`, `v` of the fed-back encoder, sensor `tau_env`.
    #[inline]
    pub fn step(
        &mut self,
        cfg: &ImpedanceConfig,
        x_d: Counts,
        x: Counts,
        v: Vel,
        tau_env: Torque,
    ) -> Output {
        let mut flags = Flags::NONE;
        let (e, clamped) = pos_error(x_d, x);
        flags.set_if(clamped, Flags::INPUT_CLAMPED);
        let u = cfg
            .ke
            .apply(e)
            .saturating_sub(cfg.be.apply(v.to_bits()))
            .saturating_add(cfg.km.apply(tau_env));
        let (tau, sat) = clamp_sym(u, cfg.tau_max);
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        Output { tau, flags }
    }
}
