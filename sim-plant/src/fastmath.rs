//! A fast, deterministic sine/cosine for the position-periodic torques (ripple, cogging,
//! gravity) evaluated every substep. libm's `sincos` was 40 % of the run time; these torques
//! are model approximations at the percent level, so ~1e-9 absolute accuracy is plenty.
//! Pure f64 arithmetic in a fixed order: bit-identical on every IEEE-754 platform, unlike
//! libm, whose last bits may differ between implementations.

use std::f64::consts::FRAC_PI_2;

/// (sin x, cos x) with |error| < 2e-9 for |x| < 1e6 (the reduction loses ~|x|·1e-16);
/// beyond |x| ≈ 2e15 the quadrant is lost and the result is meaningless.
///
/// Why it looks like this: in the integrator the angle depends on the previous substep, so
/// what counts is *latency*, not throughput. Rounding uses the 1.5·2⁵² trick (two adds, no
/// int↔float conversions on the dependency chain) and the polynomials are evaluated in
/// Estrin's form (depth 3 instead of Horner's 6).
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    const PIO2_HI: f64 = FRAC_PI_2; // nearest f64 to π/2
    const PIO2_LO: f64 = 6.123_233_995_736_766e-17;
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5·2⁵²: x + MAGIC rounds x to an integer
    let y = x * (1.0 / FRAC_PI_2);
    let shifted = y + MAGIC;
    let quadrant = shifted.to_bits() & 3; // low mantissa bits = the integer, mod 4
    let k = shifted - MAGIC;
    let r = (x - k * PIO2_HI) - k * PIO2_LO; // r ∈ [−π/4, π/4]
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    // Taylor to r¹¹ / r¹²: truncation < (π/4)¹³/13! ≈ 7e-12.
    const S1: f64 = -1.0 / 6.0;
    const S2: f64 = 1.0 / 120.0;
    const S3: f64 = -1.0 / 5040.0;
    const S4: f64 = 1.0 / 362_880.0;
    const S5: f64 = -1.0 / 39_916_800.0;
    let sp = (1.0 + S1 * r2) + r4 * (S2 + S3 * r2) + r8 * (S4 + S5 * r2);
    const C1: f64 = -0.5;
    const C2: f64 = 1.0 / 24.0;
    const C3: f64 = -1.0 / 720.0;
    const C4: f64 = 1.0 / 40_320.0;
    const C5: f64 = -1.0 / 3_628_800.0;
    const C6: f64 = 1.0 / 479_001_600.0;
    let c = (1.0 + C1 * r2) + r4 * (C2 + C3 * r2) + r8 * ((C4 + C5 * r2) + C6 * r4);
    let s = r * sp;
    match quadrant {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Sine and cosine of an angle that moves a little between calls: the previous (sin, cos)
/// is rotated by the small increment (Taylor series of the increment, |Δ| < 1/16), which is
/// about half the latency of [`sin_cos`]. Larger jumps, and the first call after
/// [`Rotor::reset`], evaluate [`sin_cos`] afresh. The integrator resets its rotors every
/// 1 kHz step, so at most a few tens of rotations accumulate (error < 1e-11).
#[derive(Clone, Copy, Debug)]
pub struct Rotor {
    theta: f64,
    s: f64,
    c: f64,
}

impl Default for Rotor {
    fn default() -> Self {
        Self::new()
    }
}

impl Rotor {
    /// A rotor with no previous angle.
    pub const fn new() -> Self {
        Self {
            theta: f64::NAN,
            s: 0.0,
            c: 1.0,
        }
    }

    /// Forget the previous angle (the next call evaluates afresh).
    #[inline(always)]
    pub fn reset(&mut self) {
        self.theta = f64::NAN;
    }

    /// (sin θ, cos θ).
    #[inline(always)]
    pub fn sin_cos(&mut self, theta: f64) -> (f64, f64) {
        let d = theta - self.theta; // NaN after a reset: the comparison fails
        let (s, c) = if d.abs() < 0.0625 {
            // Truncation: sin |Δ|⁷/7! < 7e-13, cos Δ⁸/8! < 6e-15 at |Δ| = 1/16.
            let d2 = d * d;
            let d4 = d2 * d2;
            let sd = d * ((1.0 - d2 * (1.0 / 6.0)) + d4 * (1.0 / 120.0));
            let cd = (1.0 - d2 * 0.5) + d4 * (1.0 / 24.0 - d2 * (1.0 / 720.0));
            (self.s * cd + self.c * sd, self.c * cd - self.s * sd)
        } else {
            sin_cos(theta)
        };
        self.theta = theta;
        self.s = s;
        self.c = c;
        (s, c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_libm() {
        let mut worst: f64 = 0.0;
        let mut x = -2000.0;
        while x < 2000.0 {
            let (s, c) = sin_cos(x);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
            x += 0.0137;
        }
        assert!(worst < 2e-9, "worst error {worst:e}");
    }

    #[test]
    fn rotor_tracks_small_steps_and_jumps() {
        let mut r = Rotor::new();
        let mut worst: f64 = 0.0;
        let mut x = 0.3;
        for k in 0..10_000 {
            if k % 20 == 0 {
                r.reset();
            }
            x += if k % 97 == 0 { 1.0 } else { 0.0311 };
            let (s, c) = r.sin_cos(x);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
        }
        assert!(worst < 1e-10, "worst error {worst:e}");
    }
}
