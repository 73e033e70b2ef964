//! The PID core shared by position PD/PID (notes §2.2, \[D\] backward difference) and force
//! P/PD/PI/PID (§2.3, §2.6): `τ = Kp·e − Kd·r + I`, `I_k = I_{k−1} + Ki·T·e_k`.
//!
//! * `e` is the error (counts, or torque LSB for force), `r` the *measured* rate the D term acts
//!   on, with a minus sign (thesis §2 notation: "D terms act on the measured signal") — velocity
//!   (Q28.4 counts/s bits), force rate, or input velocity. D on the measurement rather than on
//!   the error means a setpoint step does not kick the output.
//! * The integrator is kept in **output units** (torque, Q16) so a change of Ki changes only its
//!   future slope, never the present output: gain commits are bumpless for the I term by
//!   construction.
//! * Anti-windup by **clamping / conditional integration**: the integrator may move towards
//!   zero freely, but may only grow in the direction of the output while the output stays
//!   inside ±`tau_max`, and never beyond ±`i_limit`. The clamp is a composition of min/max,
//!   i.e. continuous in the inputs, so the fixed-point law and its f64 reference cannot take
//!   different discrete branches and diverge (that is what makes the LSB bound provable).
//!   Back-calculation would need a tracking gain and a second tuning knob; the thesis warns
//!   (§2.6) that integral action on sticky systems limit-cycles, so the simplest robust clamp
//!   is preferred.

use crate::fixed_math::{clamp_sym, round_shr, Flags, Gain, Output, Torque};

/// Gains and limits of the PID core. Produced by `units` from SI values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidConfig {
    /// Proportional gain: torque LSB per error LSB.
    pub kp: Gain,
    /// Derivative gain: torque LSB per rate LSB (applied as `−kd·r`).
    pub kd: Gain,
    /// Integral gain times the period, Ki·T: **2⁻¹⁶ torque LSB** per error LSB per tick.
    pub ki_t: Gain,
    /// |integrator| limit, torque LSB.
    pub i_limit: Torque,
    /// |output| limit, torque LSB.
    pub tau_max: Torque,
}

impl PidConfig {
    /// A PD (no integrator).
    pub const fn pd(kp: Gain, kd: Gain, tau_max: Torque) -> Self {
        PidConfig {
            kp,
            kd,
            ki_t: Gain::ZERO,
            i_limit: 0,
            tau_max,
        }
    }
    /// True if the integrator is in use.
    pub const fn has_integrator(&self) -> bool {
        !self.ki_t.is_zero() && self.i_limit != 0
    }
}

/// PID state: the integrator in Q16 torque LSB.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PidState {
    i_q16: i64,
}

impl PidState {
    /// Zero integrator.
    pub const ZERO: PidState = PidState { i_q16: 0 };

    /// Integrator value in torque LSB (rounded).
    pub fn integrator(&self) -> Torque {
        crate::fixed_math::sat_i32(round_shr(self.i_q16, 16)).0
    }

    /// Integrator in Q16 torque LSB.
    pub fn integrator_q16(&self) -> i64 {
        self.i_q16
    }

    /// Zero the integrator.
    pub fn reset(&mut self) {
        self.i_q16 = 0;
    }

    /// Add `delta` torque LSB to the integrator, limited to ±`i_limit`; returns the part that
    /// was absorbed (the rest must go elsewhere, e.g. a transfer offset).
    pub fn absorb(&mut self, cfg: &PidConfig, delta: Torque) -> Torque {
        let lim = i64::from(cfg.i_limit).wrapping_abs().wrapping_shl(16);
        let before = self.i_q16;
        let want = before.saturating_add(i64::from(delta).wrapping_shl(16));
        self.i_q16 = want.clamp(lim.wrapping_neg(), lim);
        let got = self.i_q16.saturating_sub(before);
        crate::fixed_math::sat_i32(round_shr(got, 16)).0
    }

    /// Bumpless initialisation: set the integrator so that a step with the same `e`, `r`
    /// (before this tick's integration) reproduces `prev_output`. Returns the torque that the
    /// integrator could not take (because of `i_limit`).
    pub fn init_bumpless(
        &mut self,
        cfg: &PidConfig,
        prev_output: Torque,
        e: i32,
        r: i32,
    ) -> Torque {
        let pd = cfg.kp.apply(e).saturating_sub(cfg.kd.apply(r));
        let (want, _) = crate::fixed_math::sat_i32(i64::from(prev_output).saturating_sub(pd));
        self.i_q16 = 0;
        let got = self.absorb(cfg, want);
        want.saturating_sub(got)
    }

    /// One step: error `e`, measured rate `r`. Output clamped to ±`tau_max` (flagged).
    #[inline]
    pub fn step(&mut self, cfg: &PidConfig, e: i32, r: i32) -> Output {
        let mut flags = Flags::NONE;
        // |kp·e|, |kd·r| ≤ 2⁶² ⇒ difference saturating (flagged) only in absurd configs.
        let p = cfg.kp.apply(e);
        let d = cfg.kd.apply(r);
        let pd = p.saturating_sub(d);
        flags.set_if(pd == i64::MAX || pd == i64::MIN, Flags::OVERFLOW);
        if cfg.has_integrator() {
            let di = cfg.ki_t.apply(e); // Q16 torque
            let ilim = i64::from(cfg.i_limit).wrapping_abs().wrapping_shl(16);
            let tmax = i64::from(cfg.tau_max).wrapping_abs().wrapping_shl(16);
            // pd in Q16, clamped so the shifts cannot overflow (|pd| ≤ 2⁴⁶ LSB is beyond any limit).
            let pd_q16 = pd.clamp(-(1i64 << 46), 1i64 << 46).wrapping_shl(16);
            let i0 = self.i_q16;
            // |i0| ≤ 2⁴⁷ (the integrator limit), |di| ≤ 2⁶², |tmax| ≤ 2⁴⁷, |pd_q16| ≤ 2⁶²:
            // none of these sums can wrap.
            let cand = i0.wrapping_add(di);
            let mut i1 = cand;
            if cand > i0 {
                // growing: stop where the output reaches +tau_max (but never force it down)
                let head = tmax.wrapping_sub(pd_q16);
                i1 = i1.min(i0.max(head));
            } else if cand < i0 {
                let head = tmax.wrapping_neg().wrapping_sub(pd_q16);
                i1 = i1.max(i0.min(head));
            }
            let i2 = i1.clamp(ilim.wrapping_neg(), ilim);
            flags.set_if(i2 != cand, Flags::INTEGRATOR_LIMITED);
            self.i_q16 = i2;
        } else {
            // A PD has no hidden bias: an integrator left over from an earlier PID gain set
            // would otherwise stay frozen in the output forever. (Bumpless transfer into a PD
            // goes through the decaying offset of `JointState` instead.)
            self.i_q16 = 0;
        }
        let u = pd.saturating_add(round_shr(self.i_q16, 16));
        let (tau, sat) = clamp_sym(u, cfg.tau_max);
        flags.set_if(sat, Flags::OUTPUT_SATURATED);
        Output { tau, flags }
    }
}
