//! Fast, deterministic sine/cosine for the position-periodic torques (ripple, cogging,
//! gravity) evaluated every substep, and a libm-free `round`.
//!
//! Both trig routines reduce the angle to the nearest of 256 table points and correct with a
//! short polynomial of the remainder (|r| ≤ π/256), which is accurate to a few 1e-16 and has
//! no branches, no state and a short dependency chain (the angle depends on the previous
//! substep, so *latency* is what counts). The table is computed at compile time by `const fn`
//! (IEEE-754 arithmetic in a fixed order), so results are bit-identical on every platform,
//! unlike libm's, whose last bits may differ between implementations.

use std::f64::consts::TAU;

/// Table points per period.
const N: usize = 256;
/// 1.5·2⁵²: `y + MAGIC` rounds `y` to an integer (|y| < 2⁵¹), held in the low mantissa bits.
const MAGIC: f64 = 6_755_399_441_055_744.0;
/// Table spacing 2π/N (rad).
const STEP: f64 = TAU / N as f64;
/// Table points per radian, N/2π.
const PER_RAD: f64 = N as f64 / TAU;
// Remainder polynomials in the table fraction f ∈ [−½, ½] (r = f·STEP):
// sin r = f·(S1 + f²·(S3 + f²·S5)), truncation r⁷/7! < 1e-17;
// cos r − 1 = f²·(C2 + f²·(C4 + f²·C6)), truncation r⁸/8! < 2e-20.
const S1: f64 = STEP;
const S3: f64 = -STEP * STEP * STEP / 6.0;
const S5: f64 = STEP * STEP * STEP * STEP * STEP / 120.0;
const C2: f64 = -STEP * STEP / 2.0;
const C4: f64 = STEP * STEP * STEP * STEP / 24.0;
const C6: f64 = -STEP * STEP * STEP * STEP * STEP * STEP / 720.0;

/// (sin x, cos x) of x ∈ [0, π/4] by Taylor series to x²⁵ (compile time only).
const fn taylor_sin_cos(x: f64) -> (f64, f64) {
    let x2 = x * x;
    let mut s = 0.0;
    let mut c = 0.0;
    let mut ts = x; // x^(2k+1)/(2k+1)!·(−1)^k
    let mut tc = 1.0; // x^(2k)/(2k)!·(−1)^k
    let mut k = 0;
    while k < 13 {
        s += ts;
        c += tc;
        let a = (2 * k + 2) as f64;
        let b = (2 * k + 3) as f64;
        ts = -ts * x2 / (a * b);
        tc = -tc * x2 / ((a - 1.0) * a);
        k += 1;
    }
    (s, c)
}

/// `[sin, cos]` of j·2π/N for j in 0..N, from the first octant by exact symmetries.
const fn build_table() -> [[f64; 2]; N] {
    let mut t = [[0.0; 2]; N];
    let quarter = N / 4;
    let mut j = 0;
    while j < N {
        let quadrant = j / quarter;
        let i = j % quarter; // angle i·STEP ∈ [0, π/2)
        let (s, c) = if 2 * i <= quarter {
            taylor_sin_cos(i as f64 * STEP)
        } else {
            let (s, c) = taylor_sin_cos((quarter - i) as f64 * STEP);
            (c, s)
        };
        t[j] = match quadrant {
            0 => [s, c],
            1 => [c, -s],
            2 => [-s, -c],
            _ => [-c, s],
        };
        j += 1;
    }
    t
}

/// `[sin, cos]` of j·2π/256.
static TABLE: [[f64; 2]; N] = build_table();

/// Table index and fraction for the angle `y` in table steps: y = index + f (mod N).
#[inline(always)]
fn reduce(y: f64) -> (usize, f64) {
    let shifted = y + MAGIC;
    let index = (shifted.to_bits() as usize) & (N - 1); // the integer, mod N
    (index, y - (shifted - MAGIC))
}

/// (sin r − …) pieces of the remainder: (cos r − 1, sin r) for r = f·STEP.
#[inline(always)]
fn remainder(f: f64) -> (f64, f64) {
    let f2 = f * f;
    (
        f2 * (C2 + f2 * (C4 + f2 * C6)),
        f * (S1 + f2 * (S3 + f2 * S5)),
    )
}

/// (sin x, cos x) with |error| < 1e-15 + |x|·2⁻⁵³ for |x| < 1e13; beyond |x| ≈ 5e13 the
/// table index is lost and the result is meaningless.
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    let (j, f) = reduce(x * PER_RAD);
    let (cm1, sr) = remainder(f);
    let [s, c] = TABLE[j];
    (s + (s * cm1 + c * sr), c + (c * cm1 - s * sr))
}

/// S7 of the remainder polynomial, needed by [`Harmonic`] whose fraction may reach |f| = 1
/// (truncation r⁹/9! < 1e-20 there; cos's r⁸/8! < 4e-18 is below an ulp of the amplitude).
const S7: f64 = -STEP * STEP * STEP * STEP * STEP * STEP * STEP / 5040.0;

/// `a·sin(k·q) + b·cos(k·q)` with the amplitudes folded into the table, the integrator's form
/// of a position-periodic torque. Per table point the value is stored as its Taylor
/// polynomial in the table fraction f (degree 7, valid for |f| ≤ 1), so an evaluation is one
/// table load and an Estrin polynomial: f → value takes five multiply/add levels, where
/// value-and-derivative times the remainder's cos/sin took eight. Same accuracy as
/// [`sin_cos`].
///
/// The integrator does not reduce the angle every substep: it carries a [`Phase`] (table
/// index + fraction) and advances it by the substep's increment ([`Harmonic::predict`],
/// [`Harmonic::advance`]), which takes the multiply by the wavenumber and the rounding off the
/// substep's dependency chain.
#[derive(Clone)]
pub struct Harmonic {
    /// k·N/2π: table steps per unit of q.
    steps_per_unit: f64,
    /// Per table point j (angle φj), with p = a·sin φj + b·cos φj and d = a·cos φj − b·sin φj
    /// (the value and its derivative by the angle): the coefficients c0..c7 of
    /// p·cos(f·STEP) + d·sin(f·STEP) in powers of f, [p, d·S1, p·C2, d·S3, p·C4, d·S5, p·C6,
    /// d·S7], stored interleaved as [c0, c4, c1, c5, c2, c6, c3, c7] — one 64-byte line per
    /// point.
    table: Box<[[f64; 8]; N]>,
}

/// A position on a [`Harmonic`]'s table: index `j` (mod N) plus fraction `f` in table steps,
/// |f| ≤ 1 where it is evaluated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Phase {
    j: usize,
    f: f64,
}

impl std::fmt::Debug for Harmonic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Harmonic")
            .field("steps_per_unit", &self.steps_per_unit)
            .field("table", &format_args!("[{N} points]"))
            .finish()
    }
}

impl Harmonic {
    /// `a·sin(k·q) + b·cos(k·q)`.
    pub fn new(a: f64, b: f64, k: f64) -> Self {
        let mut table = Box::new([[0.0; 8]; N]);
        for (out, [s, c]) in table.iter_mut().zip(TABLE.iter()) {
            let p = a * s + b * c;
            let d = a * c - b * s;
            // Interleaved low/high halves: lanes (c0, c4), (c1, c5), (c2, c6), (c3, c7).
            *out = [p, p * C4, d * S1, d * S5, p * C2, p * C6, d * S3, d * S7];
        }
        Self {
            steps_per_unit: k * PER_RAD,
            table,
        }
    }

    /// Table steps per unit of q (an increment of q times this is a [`Phase`] increment).
    pub fn steps_per_unit(&self) -> f64 {
        self.steps_per_unit
    }

    /// The phase of `q` (nearest table point, |f| ≤ ½).
    #[inline(always)]
    pub fn phase(&self, q: f64) -> Phase {
        let (j, f) = reduce(q * self.steps_per_unit);
        Phase { j, f }
    }

    /// The value at a phase with |f| ≤ 1.
    #[inline(always)]
    pub fn at(&self, p: Phase) -> f64 {
        let c = &self.table[p.j & (N - 1)];
        let f = p.f;
        let f2 = f * f;
        let f4 = f2 * f2;
        // The low (c0..c3) and high (c4..c7) halves side by side, as two-lane operations the
        // compiler keeps in one SSE2 register each.
        let a = [c[0] + c[2] * f, c[1] + c[3] * f];
        let b = [c[4] + c[6] * f, c[5] + c[7] * f];
        let lohi = [a[0] + f2 * b[0], a[1] + f2 * b[1]];
        lohi[0] + f4 * lohi[1]
    }

    /// The value at `q`.
    #[inline(always)]
    pub fn eval(&self, q: f64) -> f64 {
        self.at(self.phase(q))
    }

    /// Anchor for the next phase, computed *before* its increment is known: `p` re-centred on
    /// the table point nearest to `p + guess`, where `guess` is the previous increment
    /// (velocity changes little in one substep). [`Harmonic::advance`] then only adds the true
    /// increment, so the rounding is off the dependency chain through the velocity.
    #[inline(always)]
    pub fn predict(p: Phase, guess: f64) -> Phase {
        let shifted = (p.f + guess) + MAGIC;
        let d = shifted - MAGIC;
        Phase {
            j: p.j.wrapping_add(shifted.to_bits() as usize) & (N - 1),
            f: p.f - d,
        }
    }

    /// `anchor` advanced by `inc` table steps; re-centred (a predictable branch) only when the
    /// guess was off by more than half a table step, so the result always has |f| ≤ 1.
    #[inline(always)]
    pub fn advance(anchor: Phase, inc: f64) -> Phase {
        let f = anchor.f + inc;
        if f.abs() <= 1.0 {
            Phase { j: anchor.j, f }
        } else {
            let (dj, r) = reduce(f);
            Phase {
                j: anchor.j.wrapping_add(dj) & (N - 1),
                f: r,
            }
        }
    }
}

/// Table points per octave of [`exp_neg`].
const EN: usize = 256;

/// 2^(j/256) for j in 0..256 by the Taylor series of e^(j·ln2/256) (compile time only; positive
/// terms summed smallest first, so the sum is within about an ulp).
const fn build_exp2_table() -> [f64; EN] {
    let mut t = [0.0; EN];
    let mut j = 0;
    while j < EN {
        let x = j as f64 * std::f64::consts::LN_2 / EN as f64;
        // Terms x^k/k!, summed smallest first (the rounding of the large ones last).
        let mut terms = [0.0; 24];
        let mut term = 1.0;
        let mut k = 0;
        while k < 24 {
            terms[k] = term;
            term = term * x / (k + 1) as f64;
            k += 1;
        }
        let mut sum = 0.0;
        while k > 0 {
            k -= 1;
            sum += terms[k];
        }
        t[j] = sum;
        j += 1;
    }
    t
}

/// 2^(j/256).
static EXP2_TABLE: [f64; EN] = build_exp2_table();
/// 256/ln 2: [`exp_neg_scaled_t`]'s argument per unit of −x.
pub const EXP_PER_LN2: f64 = EN as f64 / std::f64::consts::LN_2;
/// ln2/256.
const EXP_LN2_PER: f64 = std::f64::consts::LN_2 / EN as f64;

/// `scale·e^−x` for 0 ≤ x ≤ 700 (the Stribeck decay times the stiction excess).
#[inline(always)]
pub fn exp_neg_scaled(x: f64, scale: f64) -> f64 {
    exp_neg_scaled_t(x * -EXP_PER_LN2, scale)
}

/// `scale·e^−x` given t = −x·256/ln2 (−258 600 ≤ t ≤ 0), so that a caller can fold the
/// 256/ln2 into its own constants (the Stribeck decay computes t = v²·(−256/(ln2·vs²)), one
/// multiply less on the friction node's dependency chain). At low speed this is on that
/// chain every substep, where a libm `exp` is a call with its own range checks; here it is
/// inline and identical on every platform: t = k + φ (k integer), e^−x = 2^(k>>8)·
/// 2^((k&255)/256)·e^(φ·ln2/256), a table of 2^(j/256) with `scale` folded in (off the
/// chain), a degree-4 Estrin polynomial of the remainder |r| ≤ ln2/512 (truncation
/// r⁵/120 < 4e-17) and an exponent add. The remainder is taken as (t − k)·ln2/256 from the
/// rounded t rather than by a two-part Cody–Waite reduction (two operations shorter): the
/// absolute error that costs, |x|·2⁻⁵³ relative to a value e^−x, stays below 1e-16·scale.
#[inline(always)]
pub fn exp_neg_scaled_t(t: f64, scale: f64) -> f64 {
    exp_neg_scaled_t2(t, scale, 0.0).0
}

/// [`exp_neg_scaled_t`] with two scales, (a·e^−x, b·e^−x) from one evaluation: the friction
/// node wants the Stribeck term both as a torque and times h/I, and folding h/I into the
/// table factor takes a multiply off its dependency chain.
#[inline(always)]
pub fn exp_neg_scaled_t2(t: f64, a: f64, b: f64) -> (f64, f64) {
    let shifted = t + MAGIC;
    let k = shifted - MAGIC; // round(t)
    let ki = shifted.to_bits() as i64; // its low bits, two's complement
    let r = (t - k) * EXP_LN2_PER;
    let r2 = r * r;
    let p = (1.0 + r) + r2 * ((0.5 + r * (1.0 / 6.0)) + r2 * (1.0 / 24.0));
    // 2^(k/256) = 2^(k >> 8) · table[k & 255]: add k >> 8 to the table entry's exponent.
    let j = (ki as usize) & (EN - 1);
    let e = ((ki << 44) >> 52) as u64; // sign-extended bits 8..19 of the low 20 bits: k >> 8
    let two_k = f64::from_bits(EXP2_TABLE[j].to_bits().wrapping_add(e << 52));
    ((a * two_k) * p, (b * two_k) * p)
}

/// e^−x for 0 ≤ x ≤ 700 ([`exp_neg_scaled`] with scale 1).
#[inline(always)]
pub fn exp_neg(x: f64) -> f64 {
    exp_neg_scaled(x, 1.0)
}

/// `x.round()` (half away from zero) without the libm call baseline x86-64 makes for it:
/// bit-identical to `f64::round` for every input, signed zeros and NaN included.
#[inline(always)]
pub fn round(x: f64) -> f64 {
    // 2⁵²: every f64 at or beyond it is an integer (and the branch also routes NaN).
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64; // toward zero, exact here
        let frac = x - t as f64; // exact
        let r = if frac >= 0.5 {
            t + 1
        } else if frac <= -0.5 {
            t - 1
        } else {
            t
        };
        (r as f64).copysign(x)
    } else {
        x
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
        // The reduction of |x| ≤ 2000 alone costs up to 2000·2⁻⁵³ ≈ 2.2e-13.
        assert!(worst < 5e-13, "worst error {worst:e}");
        let mut worst: f64 = 0.0;
        let mut x = -7.0;
        while x < 7.0 {
            let (s, c) = sin_cos(x);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
            x += 0.000_913;
        }
        assert!(worst < 2e-15, "worst error near 0 {worst:e}");
    }

    #[test]
    fn table_is_exact_to_a_few_ulps() {
        // The reference's own argument j·STEP is rounded (a few ulps of 2π), hence 1e-15.
        for (j, [s, c]) in TABLE.iter().enumerate() {
            let a = j as f64 * STEP;
            assert!((s - a.sin()).abs() < 1e-15, "{j}: {:e}", s - a.sin());
            assert!((c - a.cos()).abs() < 1e-15, "{j}: {:e}", c - a.cos());
        }
    }

    #[test]
    fn harmonic_matches_its_formula() {
        let h = Harmonic::new(0.7, -1.3, 540.0);
        let mut worst: f64 = 0.0;
        let mut q: f64 = -3.0;
        while q < 3.0 {
            let exact = 0.7 * (540.0 * q).sin() - 1.3 * (540.0 * q).cos();
            worst = worst.max((h.eval(q) - exact).abs());
            q += 0.000_031_7;
        }
        assert!(worst < 1e-12, "worst error {worst:e}");
    }

    #[test]
    fn advanced_phase_matches_direct_evaluation() {
        let h = Harmonic::new(0.7, -1.3, 540.0);
        let spu = h.steps_per_unit();
        let (mut q, mut prev) = (0.3_f64, 0.0_f64);
        let mut p = h.phase(q);
        let mut worst: f64 = 0.0;
        for i in 0..20_000 {
            // Up to ±50 rad/s (±2.7 rad, ±110 table steps per substep), with jumps (impacts).
            let t = i as f64 * 1e-4;
            let jump = if (i / 997) % 2 == 1 { 3.0 } else { 0.0 };
            let v = 50.0 * (TAU * 3.0 * t).cos() + jump;
            let dq = 1e-4 * v;
            q += dq;
            if i % 10 == 0 {
                // Re-anchored once per step, as the integrator does.
                p = h.phase(q);
            } else {
                let anchor = Harmonic::predict(p, prev);
                p = Harmonic::advance(anchor, dq * spu);
            }
            prev = dq * spu;
            assert!(p.f.abs() <= 1.0);
            let exact = 0.7 * (540.0 * q).sin() - 1.3 * (540.0 * q).cos();
            worst = worst.max((h.at(p) - exact).abs());
        }
        // The angle's own rounding (540·|q|·2⁻⁵³ per substep) dominates.
        assert!(worst < 2e-11, "worst error {worst:e}");
    }

    #[test]
    fn exp_neg_matches_libm() {
        // Relative error below (1 + x) ulps (see `exp_neg_scaled`): absolute within 3e-16.
        let (mut worst_abs, mut worst_rel): (f64, f64) = (0.0, 0.0);
        let mut x: f64 = 0.0;
        while x < 40.0 {
            let e = (-x).exp();
            let err = (exp_neg(x) - e).abs();
            worst_abs = worst_abs.max(err);
            worst_rel = worst_rel.max(err / e / (1.0 + x));
            x += 0.000_731;
        }
        assert!(worst_abs < 3e-16, "worst absolute error {worst_abs:e}");
        assert!(
            worst_rel < 6e-16,
            "worst relative error / (1 + x) {worst_rel:e}"
        );
        assert_eq!(exp_neg(0.0), 1.0);
    }

    #[test]
    fn round_is_f64_round() {
        for x in [
            0.0,
            -0.0,
            0.49,
            0.5,
            -0.5,
            -0.3,
            2.5,
            -2.5,
            0.499_999_999_999_999_94,
            4_503_599_627_370_495.5,
            4_503_599_627_370_497.0,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            assert_eq!(round(x).to_bits(), x.round().to_bits(), "{x}");
        }
        assert!(round(f64::NAN).is_nan());
    }
}
