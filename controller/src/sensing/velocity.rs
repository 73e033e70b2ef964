//! Velocity estimators (see the module docs of `sensing` for why).

use crate::fixed_math::{mul_i64_u32, round_shr, sat_i32, Counts, Flags, Vel, VEL_FRAC_BITS};

/// Largest |position| the observer accepts, in counts (2⁴⁶ ≈ 7·10¹³: 3·10¹⁰ rev at 2304 cpr,
/// 6.7·10⁷ rev at 2²⁰ cpr). Beyond it the input is clamped and flagged; re-home the unwrapper.
pub const OBSERVER_MAX_POS: Counts = 1 << 46;
/// Largest |velocity state| in Q32 counts/tick: 2¹⁸ counts/tick (2.6·10⁸ counts/s at 1 kHz),
/// chosen so the conversion to counts/s cannot overflow (2¹⁸⁺¹⁶ · rate < 2⁵⁰).
const V_MAX_Q32: i64 = 1 << 50;

/// Configuration of the [`TrackingObserver`].
///
/// The loop is the discrete α-β tracker
/// ```text
///   p⁻ = p + v·T            (predict)
///   r  = x_meas − p⁻        (residual, counts)
///   p  = p⁻ + α·r
///   v  = v + (β/T)·r
/// ```
/// which is the discretisation of a critically damped 2nd-order PLL
/// `ṗ = v + 2ζω·r, v̇ = ω²·r` with α = 2ζωT and β = (ωT)² (build it with
/// `units::observer_config`). It is a type-2 loop: at constant speed its mean velocity error
/// and its position lag are zero, a constant acceleration a gives a velocity lag 2ζ·a/ω; its
/// velocity noise from count quantisation falls with ω. Stable iff 0 < α < 2 and
/// 0 < β < 4 − 2α (checked by [`ObserverConfig::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObserverConfig {
    alpha_q24: u32,
    beta_q24: u32,
    rate_hz: u16,
    max_jump: i32,
}

/// Why an [`ObserverConfig`] was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ObserverConfigError {
    /// α or β is zero or outside the stability triangle 0 < α < 2, 0 < β < 4 − 2α.
    Unstable,
    /// `rate_hz` is 0.
    ZeroRate,
    /// `max_jump` must be in 1..=32767 counts.
    JumpRange,
}

impl ObserverConfig {
    /// α and β in Q24 (1.0 = 2²⁴), loop rate, and the largest residual (counts) treated as
    /// motion: a bigger jump (encoder glitch, re-homing) re-primes the position estimate and
    /// raises [`Flags::SENSOR_JUMP`] instead of kicking the velocity.
    pub const fn new(
        alpha_q24: u32,
        beta_q24: u32,
        rate_hz: u16,
        max_jump: i32,
    ) -> Result<Self, ObserverConfigError> {
        const ONE: u64 = 1 << 24;
        let a = alpha_q24 as u64;
        let b = beta_q24 as u64;
        if rate_hz == 0 {
            return Err(ObserverConfigError::ZeroRate);
        }
        if max_jump < 1 || max_jump > 32767 {
            return Err(ObserverConfigError::JumpRange);
        }
        // 4·ONE − 2a > 0 because a < 2·ONE.
        if a == 0
            || b == 0
            || a >= ONE.wrapping_mul(2)
            || b >= ONE.wrapping_mul(4).wrapping_sub(a.wrapping_mul(2))
        {
            return Err(ObserverConfigError::Unstable);
        }
        Ok(ObserverConfig {
            alpha_q24,
            beta_q24,
            rate_hz,
            max_jump,
        })
    }
    /// α in Q24.
    pub const fn alpha_q24(&self) -> u32 {
        self.alpha_q24
    }
    /// β in Q24.
    pub const fn beta_q24(&self) -> u32 {
        self.beta_q24
    }
    /// Loop rate in Hz.
    pub const fn rate_hz(&self) -> u16 {
        self.rate_hz
    }
}

/// State of the [`TrackingObserver`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ObserverState {
    /// Position estimate, Q16 counts.
    p_q16: i64,
    /// Velocity estimate, Q32 counts per tick.
    v_q32: i64,
    primed: bool,
}

/// 2nd-order integer tracking observer (see [`ObserverConfig`]). Cost per step: two
/// 32×32→64 multiplies, one 64×16 multiply, shifts and adds; no division.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackingObserver {
    /// The state (public for telemetry and bumpless re-init).
    pub state: ObserverState,
}

impl TrackingObserver {
    /// A fresh observer; the first sample primes it with zero velocity.
    pub const fn new() -> Self {
        TrackingObserver {
            state: ObserverState {
                p_q16: 0,
                v_q32: 0,
                primed: false,
            },
        }
    }

    /// Forget everything (next sample primes).
    pub fn reset(&mut self) {
        self.state = ObserverState::default();
    }

    /// Position estimate in Q16 counts.
    pub fn position_q16(&self) -> i64 {
        self.state.p_q16
    }

    /// One 1-tick step with a new measured multi-turn position; returns the velocity estimate.
    pub fn step(&mut self, cfg: &ObserverConfig, x: Counts) -> (Vel, Flags) {
        let mut flags = Flags::NONE;
        let xc = x.clamp(-OBSERVER_MAX_POS, OBSERVER_MAX_POS);
        flags.set_if(xc != x, Flags::INPUT_CLAMPED);
        let x_q16 = xc.wrapping_shl(16); // |xc| ≤ 2⁴⁶ ⇒ < 2⁶²
        let s = &mut self.state;
        if !s.primed {
            s.primed = true;
            s.p_q16 = x_q16;
            s.v_q32 = 0;
            return (Vel::ZERO, flags);
        }
        // predict
        let p_pred = s.p_q16.saturating_add(round_shr(s.v_q32, 16));
        let r = x_q16.saturating_sub(p_pred);
        let lim = i64::from(cfg.max_jump).wrapping_shl(16);
        if r > lim || r < lim.wrapping_neg() {
            // Not motion the loop should turn into velocity: re-prime position, keep velocity.
            s.p_q16 = x_q16;
            flags |= Flags::SENSOR_JUMP;
        } else {
            // |r| ≤ 2³¹ (Q16 of ≤ 32767 counts), α, β < 2²⁶ ⇒ products < 2⁵⁷.
            let dp = round_shr(mul_i64_u32(r, cfg.alpha_q24), 24);
            let dv = round_shr(mul_i64_u32(r, cfg.beta_q24), 8);
            s.p_q16 = p_pred.saturating_add(dp);
            s.v_q32 = s.v_q32.saturating_add(dv);
        }
        if s.v_q32 > V_MAX_Q32 || s.v_q32 < -V_MAX_Q32 {
            s.v_q32 = s.v_q32.clamp(-V_MAX_Q32, V_MAX_Q32);
            flags |= Flags::INPUT_CLAMPED;
        }
        (self.velocity(cfg), flags)
    }

    /// Current velocity estimate in counts/s (Q28.4), saturated to the `Vel` range.
    pub fn velocity(&self, cfg: &ObserverConfig) -> Vel {
        // Q32 counts/tick → Q16 counts/tick (|·| ≤ 2³⁴) → × rate (≤ 2¹⁶) → Q16 counts/s (< 2⁵⁰).
        let v_q16 = mul_i64_u32(round_shr(self.state.v_q32, 16), u32::from(cfg.rate_hz));
        let v_q4 = round_shr(v_q16, 16u32.wrapping_sub(VEL_FRAC_BITS));
        Vel::from_bits(sat_i32(v_q4).0)
    }
}

/// The thesis card's velocity: backward difference of counts, v = (x_k − x_{k−1})/T
/// (notes §2.9). One count per tick = `rate_hz` counts/s; kept for the §2.9 stability guard and
/// for fine encoders where it is good enough.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BackwardDifference {
    last: Counts,
    primed: bool,
}

impl BackwardDifference {
    /// Fresh differentiator (first sample gives 0).
    pub const fn new() -> Self {
        BackwardDifference {
            last: 0,
            primed: false,
        }
    }
    /// One step at `rate_hz`.
    pub fn step(&mut self, rate_hz: u16, x: Counts) -> (Vel, Flags) {
        let mut flags = Flags::NONE;
        let d = if self.primed {
            x.saturating_sub(self.last)
        } else {
            0
        };
        self.primed = true;
        self.last = x;
        // |d| clamped to 2³¹ ⇒ d·rate < 2⁴⁷, ×16 < 2⁵¹.
        let (d32, c) = sat_i32(d);
        let v = i64::from(d32)
            .wrapping_mul(i64::from(rate_hz))
            .wrapping_shl(VEL_FRAC_BITS);
        let (v32, c2) = sat_i32(v);
        flags.set_if(c || c2, Flags::INPUT_CLAMPED);
        (Vel::from_bits(v32), flags)
    }
}
