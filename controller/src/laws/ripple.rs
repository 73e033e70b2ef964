//! Position-periodic ripple / cogging compensation (notes §2.11: friction FF "cannot fix
//! ripple, which would need a high bandwidth position-dependent compensation loop"; §2.12:
//! HD ripple of 2–8 N·m dominated once friction was removed).
//!
//! A table of `n ≤ 64` torque corrections spans one period of `period` counts (e.g. the
//! motor's cogging period 2304/18 = 128 counts, or a harmonic-drive's 2-per-wave-generator-rev
//! ripple). Entry `i` sits at phase `i·period/n`; between entries the correction is linearly
//! interpolated, wrapping from the last entry back to the first. Lookup is a Euclidean
//! remainder, one multiply and two divisions — all three by the period, so they run on a
//! [`Reciprocal`] made when the table is built: no divide instruction or library call in
//! the 1 kHz path, and the result is still exact (rounded once, ≤ ½ LSB).

use crate::fixed_math::{mul_i64_u32, mul_u32_wide, sat_i32, Counts, Reciprocal, Torque};
use heapless::Vec;

/// Maximum number of table entries.
pub const RIPPLE_MAX: usize = 64;

/// Why a ripple table was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RippleError {
    /// Fewer than 2 or more than [`RIPPLE_MAX`] entries.
    Length,
    /// Period is 0 or smaller than the number of entries.
    Period,
}

/// A period of `P` counts on the multi-turn motor position, and the arithmetic that places a
/// position in it: shared by the ripple table and the gravity feed-forward.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Period {
    recip: Reciprocal,
    /// 2⁶³ mod period: moves an `i64` position into `u64` without changing its residue.
    offset: u32,
}

impl Period {
    /// A period of `counts` (≥ 2).
    pub fn new(counts: u32) -> Option<Self> {
        let recip = Reciprocal::new(counts)?;
        let (_, offset) = recip.div_rem(1u64 << 63);
        Some(Period { recip, offset })
    }

    /// Counts per period.
    pub fn counts(&self) -> u32 {
        self.recip.divisor()
    }

    /// Euclidean phase of `x` in [0, period).
    #[inline]
    pub fn phase(&self, x: Counts) -> u32 {
        let p = self.recip;
        let period = p.divisor();
        match u32::try_from(x.unsigned_abs()) {
            // |x| < 2³² (the usual case): a 32-bit remainder, mirrored for negative x.
            Ok(m) => {
                let (_, r) = p.div_rem_u32(m);
                if x >= 0 || r == 0 {
                    r
                } else {
                    period.wrapping_sub(r)
                }
            }
            // Otherwise x + 2⁶³ is a u64 whose residue is (x mod P) + offset.
            Err(_) => {
                let (_, r) = p.div_rem((x as u64) ^ (1u64 << 63));
                if r >= self.offset {
                    r.wrapping_sub(self.offset)
                } else {
                    r.wrapping_add(period.wrapping_sub(self.offset))
                }
            }
        }
    }

    /// Where `x` falls in an `n`-entry table over the period: the entry and the fraction
    /// past it, in units of 1/period.
    #[inline]
    pub fn locate(&self, x: Counts, n: u32) -> (usize, u32) {
        // phase·n < 2³²·2⁶
        let (idx, frac) = self.recip.div_rem(mul_u32_wide(self.phase(x), n));
        (idx as usize, frac)
    }

    /// `a + (b − a)·frac/period`, rounded half away from zero (|b − a| < 2¹⁷).
    #[inline]
    pub fn lerp(&self, a: i64, b: i64, frac: u32) -> i64 {
        // (b − a)·frac < 2¹⁷·2³² = 2⁴⁹
        let num = mul_i64_u32(b.wrapping_sub(a), frac);
        let half = u64::from(self.recip.divisor() >> 1);
        let (q, _) = self.recip.div_rem(num.unsigned_abs().wrapping_add(half));
        let q = q as i64;
        a.wrapping_add(if num >= 0 { q } else { q.wrapping_neg() })
    }
}

/// The ripple table (motor-side torque LSB per entry).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RippleTable {
    period: Period,
    /// Counts added to the position before the lookup, in [0, period).
    phase: u32,
    table: Vec<i16, RIPPLE_MAX>,
}

impl RippleTable {
    /// Build a table over `period` counts from `entries` (2..=64 of them, `period ≥ len`).
    pub fn new(period: u32, entries: &[i16]) -> Result<Self, RippleError> {
        if entries.len() < 2 || entries.len() > RIPPLE_MAX {
            return Err(RippleError::Length);
        }
        if period == 0 || (period as usize) < entries.len() {
            return Err(RippleError::Period);
        }
        let table = Vec::from_slice(entries).map_err(|_| RippleError::Length)?;
        // period ≥ len ≥ 2
        let period = Period::new(period).ok_or(RippleError::Period)?;
        Ok(RippleTable {
            period,
            phase: 0,
            table,
        })
    }

    /// The same table, looked up at `x + phase` (the phase taken modulo the period).
    pub fn with_phase(mut self, phase: u32) -> Self {
        self.phase = self.period.phase(i64::from(phase));
        self
    }

    /// Period in counts.
    pub fn period(&self) -> u32 {
        self.period.counts()
    }

    /// The entries.
    pub fn entries(&self) -> &[i16] {
        &self.table
    }

    /// Interpolated correction at multi-turn position `x` (motor counts).
    #[inline]
    pub fn torque(&self, x: Counts) -> Torque {
        let x = x.saturating_add(i64::from(self.phase));
        let n = self.table.len() as u32; // 2..=64
        let (i0, frac) = self.period.locate(x, n);
        let i1 = if (i0 as u32).wrapping_add(1) >= n {
            0
        } else {
            i0.wrapping_add(1)
        };
        let a = i64::from(self.table.get(i0).copied().unwrap_or(0));
        let b = i64::from(self.table.get(i1).copied().unwrap_or(0));
        sat_i32(self.period.lerp(a, b, frac)).0
    }
}
