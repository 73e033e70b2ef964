//! Shared fixed-point helpers for the 1 kHz path: the scaled-integer [`Gain`], saturation with
//! flags, and the internal unit types.
//!
//! # Internal units (one place, used by `laws`, `sensing`, `units`, `power_stage`)
//!
//! | quantity | type | unit / format |
//! |---|---|---|
//! | position | [`Counts`] = `i64` | encoder counts after multi-turn unwrap (motor encoder for x1, output encoder for x2) |
//! | position error | `i32` | counts; an `i64` difference is clamped to `i32` and [`Flags::INPUT_CLAMPED`] is raised |
//! | velocity | [`Vel`] = `I28F4` | counts/s, 4 fractional bits: 1/16 count/s = 1.7·10⁻⁴ rad/s at 2304 cpr, the resolution of the thesis's Sensorimotor velocity (1.8·10⁻⁴ rad/s, notes §1); range ±1.3·10⁸ counts/s (±58 000 rev/s at 2304 cpr, ±128 rev/s at 2²⁰ cpr) |
//! | torque | [`Torque`] = `i32` | the wire's motor-torque LSB ([`MOTOR_TORQUE_NM_PER_LSB`](crate::proto::scale::MOTOR_TORQUE_NM_PER_LSB) = 0.1 mN·m) by default (`units::Scale::torque_lsb_nm` can choose another LSB; the laws are LSB-agnostic). Motor-side for commands; a force-sensor value is output-side in the same LSB (gains carry the 1/N) |
//! | torque command | [`TorqueCmd`] = `i16` | 0.1 mN·m motor side, ±3.2767 N·m (the thesis motor is ≤ 2 N·m) |
//!
//! # Why a mantissa/shift gain
//! The thesis (notes §1) needs ≈320:1 of stiffness range at one encoder, and this project also
//! runs from 2304 cpr to 2²⁰ cpr encoders: a fixed Q format either overflows at the top or
//! rounds small gains to zero. A [`Gain`] is `mant / 2^shift` with a 31-bit mantissa, i.e. a
//! tiny floating point number whose exponent is chosen once at configuration time (`units`).
//! At run time a product is one 32×32→64 multiply, a rounding add and a shift: it cannot
//! overflow (|x·mant| < 2⁶²), and its relative representation error is ≤ 2⁻³⁰.
#![deny(clippy::float_arithmetic)]

use fixed::types::I28F4;

/// Multi-turn position in encoder counts.
pub type Counts = i64;
/// Velocity in counts/s, Q28.4 (see module docs).
pub type Vel = I28F4;
/// Torque in motor-torque LSBs ([`MOTOR_TORQUE_NM_PER_LSB`](crate::proto::scale::MOTOR_TORQUE_NM_PER_LSB)), internal width.
pub type Torque = i32;
/// Final torque command sent to the power stage / actuator frame.
pub type TorqueCmd = i16;
/// Fractional bits of [`Vel`].
pub const VEL_FRAC_BITS: u32 = 4;

/// Status flags a law reports with every output. Bit set = the event happened this step.
///
/// The design rule "never overflow silently" (design.md) is implemented by every saturating
/// operation OR-ing one of these bits in, so the card can forward them in telemetry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Flags(pub u16);

impl Flags {
    /// No event.
    pub const NONE: Flags = Flags(0);
    /// The output was clamped to the law's torque limit.
    pub const OUTPUT_SATURATED: Flags = Flags(1);
    /// An input (position error, force error, velocity) was clamped to its documented range.
    pub const INPUT_CLAMPED: Flags = Flags(1 << 1);
    /// The integrator hit its limit or integration was suspended (anti-windup active).
    pub const INTEGRATOR_LIMITED: Flags = Flags(1 << 2);
    /// An intermediate sum saturated (should not happen with sane limits; reported anyway).
    pub const OVERFLOW: Flags = Flags(1 << 3);
    /// A bumpless-transfer offset is still decaying.
    pub const TRANSFER_ACTIVE: Flags = Flags(1 << 4);
    /// A sensing input jumped further than the estimator accepts in one step (clamped).
    pub const SENSOR_JUMP: Flags = Flags(1 << 5);

    /// True if any bit of `other` is set in `self`.
    #[inline]
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0 && other.0 != 0
    }
    /// True if no flag is set.
    #[inline]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Set `other` if `cond`.
    #[inline]
    pub fn set_if(&mut self, cond: bool, other: Flags) {
        if cond {
            self.0 |= other.0;
        }
    }
}

impl core::ops::BitOr for Flags {
    type Output = Flags;
    #[inline]
    fn bitor(self, rhs: Flags) -> Flags {
        Flags(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for Flags {
    #[inline]
    fn bitor_assign(&mut self, rhs: Flags) {
        self.0 |= rhs.0;
    }
}

/// A torque (or other) value together with the flags raised while computing it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Output {
    /// Value in [`Torque`] LSB (motor side) unless stated otherwise.
    pub tau: Torque,
    /// What happened on the way.
    pub flags: Flags,
}

/// Maximum shift of a [`Gain`]: a product `i32 × i32` is < 2⁶², so shifting by more than 62
/// always gives 0 or −1.
pub const GAIN_MAX_SHIFT: u8 = 62;

/// A real gain `mant / 2^shift` (see module docs for why).
///
/// The rounding offset `2^(shift−1)` is computed once, when the gain is made, so the 1 kHz
/// product is a multiply, a 64-bit add and a shift whose width class (< 32 or ≥ 32 bits) the
/// code states explicitly — a 32-bit core then needs no generic 64-bit shift sequence.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Gain {
    mant: i32,
    shift: u8,
    half: i64,
}

impl Gain {
    /// The zero gain (a disabled term).
    pub const ZERO: Gain = Gain {
        mant: 0,
        shift: 0,
        half: 0,
    };
    /// The unity gain.
    pub const ONE: Gain = Gain {
        mant: 1,
        shift: 0,
        half: 0,
    };

    /// Build from raw parts; `None` if `shift > 62`.
    pub const fn from_parts(mant: i32, shift: u8) -> Option<Gain> {
        if shift > GAIN_MAX_SHIFT {
            None
        } else {
            let half = if shift == 0 {
                0
            } else {
                1i64.wrapping_shl((shift as u32).wrapping_sub(1))
            };
            Some(Gain { mant, shift, half })
        }
    }

    /// Mantissa.
    #[inline]
    pub const fn mant(self) -> i32 {
        self.mant
    }
    /// Binary exponent (value = mant / 2^shift).
    #[inline]
    pub const fn shift(self) -> u8 {
        self.shift
    }
    /// True for the zero gain.
    #[inline]
    pub const fn is_zero(self) -> bool {
        self.mant == 0
    }

    /// The exact real value (configuration time, tests and telemetry only).
    pub fn to_f64(self) -> f64 {
        #[allow(clippy::float_arithmetic)]
        {
            self.mant as f64 / (1u64 << self.shift) as f64
        }
    }

    /// `round(x · mant / 2^shift)` exactly, half rounded towards +∞. Cannot overflow:
    /// |x·mant| ≤ 2⁶², the rounding offset ≤ 2⁶¹. With `shift ≥ 32` the result fits an
    /// `i32` (|·| ≤ 2³⁰).
    #[inline]
    pub fn apply(self, x: i32) -> i64 {
        let p = mul_i32_wide(x, self.mant).wrapping_add(self.half);
        let s = u32::from(self.shift);
        if s >= 32 {
            // The high word shifted by s − 32: one 32-bit shift.
            i64::from(((p >> 32) as i32).wrapping_shr(s & 31))
        } else {
            p.wrapping_shr(s & 31)
        }
    }
}

/// `a · b` exactly. ARMv6-M (Cortex-M0, the only Arm profile here without CAS atomics) has
/// no 32×32→64 multiply: four 16×16 products beat the generic 64×64 library call there.
#[inline]
pub fn mul_i32_wide(a: i32, b: i32) -> i64 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        let neg = (a < 0) != (b < 0);
        let m = mul_u32_wide(a.unsigned_abs(), b.unsigned_abs()) as i64;
        if neg {
            m.wrapping_neg()
        } else {
            m
        }
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        i64::from(a).wrapping_mul(i64::from(b))
    }
}

/// `a · b` exactly, unsigned (see [`mul_i32_wide`] for the ARMv6-M path).
#[inline]
pub fn mul_u32_wide(a: u32, b: u32) -> u64 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        mul_u32_by_halves(a, b)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        u64::from(a).wrapping_mul(u64::from(b))
    }
}

/// `x · k`, exact whenever the product fits an `i64` (the callers' bounds guarantee it).
/// One 32×32→64 multiply and one 32-bit multiply — on ARMv6-M that is far cheaper than the
/// generic 64×64 library call an `i64` product becomes.
#[inline]
pub fn mul_i64_u32(x: i64, k: u32) -> i64 {
    let lo = x as u32;
    let hi = (x >> 32) as i32;
    // |x·k| < 2⁶³ ⇒ |hi·k| < 2³¹: the 32-bit product is exact (two's complement mod 2³²).
    let hk = hi.wrapping_mul(k as i32);
    (i64::from(hk) << 32).wrapping_add(mul_u32_wide(lo, k) as i64)
}

/// `a · b` from four 16×16→32 products (the ARMv6-M path of [`mul_u32_wide`]; compiled
/// everywhere so the host tests check it).
#[inline]
pub fn mul_u32_by_halves(a: u32, b: u32) -> u64 {
    let (a0, a1) = (a & 0xFFFF, a >> 16);
    let (b0, b1) = (b & 0xFFFF, b >> 16);
    // Each partial product < 2³²; the middle sum < 2³³ is carried in u64.
    let lo = u64::from(a0.wrapping_mul(b0));
    let mid = u64::from(a1.wrapping_mul(b0)).wrapping_add(u64::from(a0.wrapping_mul(b1)));
    let hi = u64::from(a1.wrapping_mul(b1));
    lo.wrapping_add(mid << 16).wrapping_add(hi << 32)
}

/// High 64 bits of the 128-bit product `a · b`.
#[inline]
fn mul_hi_u64(a: u64, b: u64) -> u64 {
    let (a0, a1) = (a as u32, (a >> 32) as u32);
    let (b0, b1) = (b as u32, (b >> 32) as u32);
    let p00 = mul_u32_wide(a0, b0);
    let p01 = mul_u32_wide(a0, b1);
    let p10 = mul_u32_wide(a1, b0);
    let p11 = mul_u32_wide(a1, b1);
    // < 3·2³², no overflow
    let mid = (p00 >> 32)
        .wrapping_add(p01 & 0xFFFF_FFFF)
        .wrapping_add(p10 & 0xFFFF_FFFF);
    p11.wrapping_add(p01 >> 32)
        .wrapping_add(p10 >> 32)
        .wrapping_add(mid >> 32)
}

/// Division by an invariant `u32` divisor without a divide instruction or library call:
/// a reciprocal `m = ⌊(2⁶⁴−1)/d⌋` made at configuration time, then per division one
/// high-half multiply, one back-multiply and at most one correction (the estimate
/// `⌊n·m/2⁶⁴⌋` is never above the true quotient and at most one below it, because
/// `n/d − n·m/2⁶⁴ < n/2⁶⁴ ≤ 1`). Exact for every `u64` numerator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reciprocal {
    d: u32,
    m: u64,
    /// ⌊(2³²−1)/d⌋: the same scheme for numerators below 2³², one 32×32→64 multiply.
    m32: u32,
}

impl Reciprocal {
    /// The reciprocal of `d`; `None` for 0 and 1 (1 needs no division, and `m` would not
    /// fit).
    pub const fn new(d: u32) -> Option<Reciprocal> {
        if d < 2 {
            return None;
        }
        // d ≥ 2: the divisions cannot fail (checked only to keep the no-panic lints).
        let (Some(m), Some(m32)) = (u64::MAX.checked_div(d as u64), u32::MAX.checked_div(d)) else {
            return None;
        };
        Some(Reciprocal { d, m, m32 })
    }

    /// The divisor.
    #[inline]
    pub const fn divisor(self) -> u32 {
        self.d
    }

    /// `(n / d, n % d)`.
    #[inline]
    pub fn div_rem(self, n: u64) -> (u64, u32) {
        if let Ok(n32) = u32::try_from(n) {
            let (q, r) = self.div_rem_u32(n32);
            return (u64::from(q), r);
        }
        let q = mul_hi_u64(n, self.m);
        let d = u64::from(self.d);
        // q ≤ n/d ⇒ q·d ≤ n: no wrap.
        let r = n.wrapping_sub(mul_hi_free(q, self.d));
        if r >= d {
            (q.wrapping_add(1), r.wrapping_sub(d) as u32)
        } else {
            (q, r as u32)
        }
    }
}

impl Reciprocal {
    /// `(n / d, n % d)` for a 32-bit numerator (same bound: the estimate is at most one
    /// below the quotient).
    #[inline]
    pub fn div_rem_u32(self, n: u32) -> (u32, u32) {
        let q = (mul_u32_wide(n, self.m32) >> 32) as u32;
        // q ≤ n/d ⇒ q·d ≤ n
        let r = n.wrapping_sub(q.wrapping_mul(self.d));
        if r >= self.d {
            (q.wrapping_add(1), r.wrapping_sub(self.d))
        } else {
            (q, r)
        }
    }
}

/// `q · d` (exact while it fits u64, which the caller guarantees).
#[inline]
fn mul_hi_free(q: u64, d: u32) -> u64 {
    mul_u32_wide(q as u32, d).wrapping_add(mul_u32_wide((q >> 32) as u32, d) << 32)
}

/// `round(p / 2^s)` with half towards +∞, for |p| ≤ 2⁶² and s ≤ 62 (no overflow possible).
#[inline]
pub fn round_shr(p: i64, s: u32) -> i64 {
    if s == 0 {
        return p;
    }
    let half = 1i64.wrapping_shl(s.wrapping_sub(1));
    // |p| ≤ 2⁶², half ≤ 2⁶¹: no overflow.
    p.wrapping_add(half).wrapping_shr(s)
}

/// Saturate an `i64` to `i32`; the bool is true if it had to clamp.
#[inline]
pub fn sat_i32(x: i64) -> (i32, bool) {
    // One "does the high word only repeat the sign" test instead of two 64-bit compares.
    let lo = x as i32;
    if i64::from(lo) == x {
        (lo, false)
    } else if x < 0 {
        (i32::MIN, true)
    } else {
        (i32::MAX, true)
    }
}

/// Clamp to `[-lim, +lim]` (lim taken as |lim|, at most `i32::MAX`); the bool is true if it
/// clamped.
#[inline]
pub fn clamp_sym(x: i64, lim: i32) -> (i32, bool) {
    // |i32::MIN| is not an i32: treat it as i32::MAX.
    let l = i64::from(lim).wrapping_abs().min(i64::from(i32::MAX));
    if x > l {
        (l as i32, true)
    } else if x < l.wrapping_neg() {
        (l.wrapping_neg() as i32, true)
    } else {
        (x as i32, false)
    }
}

/// Position error `a − b` in counts, clamped to `i32` (flag on clamp).
#[inline]
pub fn pos_error(a: Counts, b: Counts) -> (i32, bool) {
    sat_i32(a.saturating_sub(b))
}

/// Final torque command: clamp to the `i16` command range.
#[inline]
pub fn to_command(tau: Torque) -> (TorqueCmd, bool) {
    if tau > i32::from(i16::MAX) {
        (i16::MAX, true)
    } else if tau < -32767 {
        // Symmetric: −32767, never −32768, so |command| is representable.
        (-i16::MAX, true)
    } else {
        (tau as i16, false)
    }
}

/// A first-order low-pass `y += α(u − y)` in Q16 of its input unit. α is a `U1F15` fraction
/// in (0, 1] (larger values are treated as 1). Used for force-rate filtering and impedance compensation (notes §2.3, §2.12:
/// the thesis used digital differentiation plus low-pass filtering).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LowPass {
    y_q16: i64,
}

/// Filter coefficient type: α in [0, 2), 15 fractional bits (`fixed` U1F15).
pub type Alpha = fixed::types::U1F15;

impl LowPass {
    /// Zero state.
    pub const NEW: LowPass = LowPass { y_q16: 0 };

    /// Reset the state to `y` (in input units).
    pub fn reset(&mut self, y: i32) {
        self.y_q16 = i64::from(y).wrapping_shl(16);
    }
    /// One step; returns the filtered value rounded to input units. α is limited to 1.0
    /// (its documented range): then |u − y| < 2³² LSB = 2⁴⁸ in Q16, × α ≤ 2¹⁵ stays < 2⁶³,
    /// and y remains a convex combination of past inputs (|y| ≤ 2³¹).
    #[inline]
    pub fn step(&mut self, u: i32, alpha: Alpha) -> i32 {
        let u_q16 = i64::from(u).wrapping_shl(16);
        let diff = u_q16.wrapping_sub(self.y_q16);
        let a = i64::from(alpha.to_bits().min(1 << 15));
        let inc = round_shr(mul_i64_u32(diff, a as u32), 15);
        self.y_q16 = self.y_q16.wrapping_add(inc);
        sat_i32(round_shr(self.y_q16, 16)).0
    }
    /// Current value in input units.
    pub fn value(&self) -> i32 {
        sat_i32(round_shr(self.y_q16, 16)).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_mul_rounds() {
        let g = Gain::from_parts(3, 1).unwrap(); // 1.5
        assert_eq!(g.apply(3), 5); // 4.5 → 5
        assert_eq!(g.apply(-3), -4); // −4.5 → −4 (half up)
        assert_eq!(Gain::ONE.apply(i32::MIN), i64::from(i32::MIN));
        let big = Gain::from_parts(i32::MIN, 0).unwrap();
        assert_eq!(big.apply(i32::MIN), 1i64 << 62);
        // both shift classes, both signs, at the extremes
        for (m, sh) in [
            (i32::MIN, 62),
            (i32::MAX, 32),
            (-3, 33),
            (i32::MIN, 31),
            (7, 1),
        ] {
            let g = Gain::from_parts(m, sh).unwrap();
            for x in [i32::MIN, i32::MAX, -1, 1, 12345, -12345] {
                let exact = (i128::from(x) * i128::from(m) + (1i128 << (sh - 1))) >> sh;
                assert_eq!(i128::from(g.apply(x)), exact, "{m} {sh} {x}");
            }
        }
    }

    #[test]
    fn wide_multiplies_and_reciprocal_division_are_exact() {
        for (a, b) in [
            (i32::MIN, i32::MIN),
            (i32::MIN, i32::MAX),
            (-1, 1),
            (0x1234_5678, -0x7654_3210),
        ] {
            assert_eq!(mul_i32_wide(a, b), i64::from(a) * i64::from(b));
            let (ua, ub) = (a as u32, b as u32);
            assert_eq!(mul_u32_wide(ua, ub), u64::from(ua) * u64::from(ub));
            assert_eq!(mul_u32_by_halves(ua, ub), u64::from(ua) * u64::from(ub));
        }
        for (x, k) in [
            (-(1i64 << 48), 1u32 << 14),
            ((1 << 46) - 3, 65535),
            (-5, u32::MAX),
            (i64::from(i32::MIN), 7),
            (0x1_2345_6789, 0x7FFF),
        ] {
            assert_eq!(
                i128::from(mul_i64_u32(x, k)),
                i128::from(x) * i128::from(k),
                "{x} {k}"
            );
        }
        assert_eq!(Reciprocal::new(1), None);
        for d in [
            2u32,
            3,
            7,
            10,
            128,
            1000,
            2304,
            65_537,
            0x8000_0000,
            u32::MAX - 1,
            u32::MAX,
        ] {
            let r = Reciprocal::new(d).unwrap();
            for n in [
                0u64,
                1,
                d as u64 - 1,
                d as u64,
                d as u64 + 1,
                1 << 38,
                (1 << 49) + 17,
                u64::MAX,
                u64::MAX - 1,
                0x8000_0000_0000_0000,
                0x7FFF_FFFF_FFFF_FFFF,
            ] {
                assert_eq!(
                    r.div_rem(n),
                    (n / u64::from(d), (n % u64::from(d)) as u32),
                    "{n} / {d}"
                );
                let n32 = n as u32;
                assert_eq!(r.div_rem_u32(n32), (n32 / d, n32 % d), "{n32} / {d}");
            }
        }
    }

    #[test]
    fn command_is_symmetric() {
        assert_eq!(to_command(1 << 20), (i16::MAX, true));
        assert_eq!(to_command(-(1 << 20)), (-i16::MAX, true));
        assert_eq!(to_command(-5), (-5, false));
    }

    #[test]
    fn lowpass_converges() {
        let mut f = LowPass::default();
        let a = Alpha::from_num(0.1);
        let mut y = 0;
        for _ in 0..300 {
            y = f.step(1000, a);
        }
        assert_eq!(y, 1000);
        for _ in 0..300 {
            y = f.step(i32::MIN, a);
        }
        assert!(y < -2_000_000_000);
    }
}
