//! Position-periodic ripple / cogging compensation (notes §2.11: friction FF "cannot fix
//! ripple, which would need a high bandwidth position-dependent compensation loop"; §2.12:
//! HD ripple of 2–8 N·m dominated once friction was removed).
//!
//! A table of `n ≤ 64` torque corrections spans one period of `period` counts (e.g. the
//! motor's cogging period 2304/18 = 128 counts, or a harmonic-drive's 2-per-wave-generator-rev
//! ripple). Entry `i` sits at phase `i·period/n`; between entries the correction is linearly
//! interpolated, wrapping from the last entry back to the first. Lookup is a Euclidean
//! remainder, one multiply and one division — bounded, no loops.

use crate::fixed_math::{sat_i32, Counts, Torque};
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

/// The ripple table (motor-side torque LSB per entry).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RippleTable {
    period: u32,
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
        Ok(RippleTable { period, table })
    }

    /// Period in counts.
    pub fn period(&self) -> u32 {
        self.period
    }

    /// The entries.
    pub fn entries(&self) -> &[i16] {
        &self.table
    }

    /// Interpolated correction at multi-turn position `x` (motor counts).
    #[inline]
    pub fn torque(&self, x: Counts) -> Torque {
        let n = self.table.len() as u64; // 2..=64
        let period = u64::from(self.period); // ≥ n ≥ 2
                                             // phase in [0, period)
        let phase = x.checked_rem_euclid(i64::from(self.period)).unwrap_or(0) as u64;
        // scaled position in table units: phase·n < 2³²·2⁶
        let s = phase.wrapping_mul(n);
        let idx = s.checked_div(period).unwrap_or(0);
        let frac = s.checked_rem(period).unwrap_or(0); // in [0, period)
        let i0 = idx as usize;
        let i1 = if idx.wrapping_add(1) >= n {
            0
        } else {
            i0.wrapping_add(1)
        };
        let a = i64::from(self.table.get(i0).copied().unwrap_or(0));
        let b = i64::from(self.table.get(i1).copied().unwrap_or(0));
        // (b − a)·frac: |b−a| < 2¹⁷, frac < 2³² ⇒ < 2⁴⁹. Rounded division (half away from 0).
        let num = b.wrapping_sub(a).wrapping_mul(frac as i64);
        let p = period as i64;
        let half = p.wrapping_shr(1);
        let q = if num >= 0 {
            num.wrapping_add(half).checked_div(p).unwrap_or(0)
        } else {
            num.wrapping_sub(half).checked_div(p).unwrap_or(0)
        };
        sat_i32(a.wrapping_add(q)).0
    }
}
