//! Friction compensation at 1 kHz (notes §2.11): direction-dependent Coulomb feed-forward
//! τc⁺ / τc⁻, an optional viscous term, and an under-compensation factor.
//!
//! `τff = u · ( ramp(ω) + Bv·ω )`, with
//! `ramp(ω) = min(τc⁺, s⁺·ω)` for ω ≥ 0 and `max(−τc⁻, s⁻·ω)` for ω < 0, `s± = τc±/ω_r`.
//!
//! **Transition near zero velocity: a smooth (linear) ramp of width ω_r, not a deadband with
//! hysteresis.** Why:
//! * The thesis's 10 Hz version waited for "several velocity measurements of the same sign"
//!   (a hysteresis) and still produced spikes at slow speeds and reversals (§2.11): switching
//!   the full τc in one step is exactly a spike. A ramp is continuous in ω, so velocity-estimate
//!   noise (±1 count/tick at 2304 cpr without the observer) maps to bounded torque noise of
//!   slope s±, no chattering limit cycle is possible from the switching itself.
//! * Near zero the ramp under-compensates (|τff| < τc), which is the side the thesis asks for:
//!   the FF should be "equal to (physically impossible) or slightly below the actual frictional
//!   torque" — over-compensation injects energy. Inside ±ω_r the ramp acts as extra positive
//!   viscous damping, never negative damping (Armstrong's destabilising stiction→Coulomb
//!   transition, §2.11, is not reproduced).
//! * Cost: below ω_r friction is only partly cancelled; choose ω_r a few times the velocity
//!   noise floor.
//!
//! **The velocity it acts on is low-passed** (`alpha`, 1.0 = none). Friction sits in the
//! transmission and the load, the feed-forward on the rotor: `+τff(ω)` rising with ω is
//! negative damping on the rotor's own fast mode against the transmission spring (slope s±
//! inside the ramp, Bv outside it), which that friction does not damp. A low-pass well below
//! that mode leaves the rotor the law's damping and still follows the load's slower motion.
//!
//! `u` (`undercomp`, default 0.8) scales everything so an experimentally determined τc± is
//! deliberately not fully cancelled ("slightly below"; direction-dependent friction makes full
//! compensation only conditionally stable).

use crate::fixed_math::{
    clamp_sym, mul_i64_u32, round_shr, Alpha, Flags, Gain, LowPass, Output, Torque, Vel,
};

/// Default under-compensation factor 0.8 (U1F15).
pub const DEFAULT_UNDERCOMP: Alpha = Alpha::from_bits(26214);

/// Friction compensation configuration (all motor side).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrictionConfig {
    /// Coulomb torque in the positive direction, LSB (≥ 0).
    pub tau_c_pos: Torque,
    /// Coulomb torque magnitude in the negative direction, LSB (≥ 0).
    pub tau_c_neg: Torque,
    /// τc⁺/ω_r: LSB per (1/16 count/s).
    pub slope_pos: Gain,
    /// τc⁻/ω_r: LSB per (1/16 count/s).
    pub slope_neg: Gain,
    /// Viscous compensation Bv: LSB per (1/16 count/s). `Gain::ZERO` = off.
    pub viscous: Gain,
    /// Under-compensation factor u (U1F15; < 1 recommended, default 0.8).
    pub undercomp: Alpha,
    /// |output| limit.
    pub limit: Torque,
    /// Low-pass coefficient of the velocity the compensation acts on (1.0 = none).
    pub alpha: Alpha,
}

impl Default for FrictionConfig {
    fn default() -> Self {
        FrictionConfig {
            tau_c_pos: 0,
            tau_c_neg: 0,
            slope_pos: Gain::ZERO,
            slope_neg: Gain::ZERO,
            viscous: Gain::ZERO,
            undercomp: DEFAULT_UNDERCOMP,
            limit: 0,
            alpha: Alpha::ONE,
        }
    }
}

/// Friction compensation: a function of the low-passed velocity estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrictionComp {
    lp: LowPass,
}

impl FrictionComp {
    /// Zero state.
    pub const NEW: FrictionComp = FrictionComp { lp: LowPass::NEW };

    /// Set the filter to `v` (no transient when the compensation is switched on).
    pub fn prime(&mut self, v: Vel) {
        self.lp.reset(v.to_bits());
    }

    /// Feed-forward torque for motor velocity `v`.
    #[inline]
    pub fn step(&mut self, cfg: &FrictionConfig, v: Vel) -> Output {
        let vb = if cfg.alpha >= Alpha::ONE {
            v.to_bits()
        } else {
            self.lp.step(v.to_bits(), cfg.alpha)
        };
        let coulomb = if vb >= 0 {
            cfg.slope_pos
                .apply(vb)
                .min(i64::from(cfg.tau_c_pos).wrapping_abs())
        } else {
            cfg.slope_neg
                .apply(vb)
                .max(i64::from(cfg.tau_c_neg).wrapping_abs().wrapping_neg())
        };
        // coulomb ≤ 2³¹, viscous ≤ 2⁶²: clamp the sum to 2⁴⁶ before the ×u (u < 2¹⁶).
        let raw = coulomb
            .saturating_add(cfg.viscous.apply(vb))
            .clamp(-(1i64 << 46), 1i64 << 46);
        let scaled = round_shr(mul_i64_u32(raw, u32::from(cfg.undercomp.to_bits())), 15);
        let (tau, sat) = clamp_sym(scaled, cfg.limit);
        let mut flags = Flags::NONE;
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        Output { tau, flags }
    }
}
