//! Gravity feed-forward `s·sin θ + c·cos θ`, θ the output angle (one output revolution of
//! motor counts from count 0): the load a fitted model names `gravity` (thesis §3.2, an arm
//! on the joint), cancelled before the position loop has to hold it.
//!
//! The sine comes from a 64-entry table in flash, interpolated (within 0.12 % of the
//! amplitude): no table in RAM per configuration (the M0 card has 16 KiB) and no float in
//! the 1 kHz path. The position is placed in the revolution by the ripple table's [`Period`].

use super::ripple::Period;
use crate::fixed_math::{sat_i32, Counts, Torque};

/// sin(2πi/64) in Q15, i = 0..64.
const SINE: [i16; 64] = [
    0, 3212, 6393, 9512, 12539, 15446, 18204, 20787, 23170, 25329, 27245, 28898, 30273, 31356,
    32137, 32609, 32767, 32609, 32137, 31356, 30273, 28898, 27245, 25329, 23170, 20787, 18204,
    15446, 12539, 9512, 6393, 3212, 0, -3212, -6393, -9512, -12539, -15446, -18204, -20787, -23170,
    -25329, -27245, -28898, -30273, -31356, -32137, -32609, -32767, -32609, -32137, -31356, -30273,
    -28898, -27245, -25329, -23170, -20787, -18204, -15446, -12539, -9512, -6393, -3212,
];

/// The gravity feed-forward (motor-side torque LSB amplitudes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gravity {
    rev: Period,
    sin: Torque,
    cos: Torque,
}

impl Gravity {
    /// Amplitudes `sin`, `cos` (|·| ≤ 32767) over `counts_per_rev` motor counts per output
    /// revolution (≥ 64); `None` outside those ranges.
    pub fn new(counts_per_rev: u32, sin: Torque, cos: Torque) -> Option<Self> {
        let amp = i32::from(i16::MAX);
        if counts_per_rev < SINE.len() as u32 || sin.abs() > amp || cos.abs() > amp {
            return None;
        }
        Some(Gravity {
            rev: Period::new(counts_per_rev)?,
            sin,
            cos,
        })
    }

    /// Feed-forward at motor position `x`.
    #[inline]
    pub fn torque(&self, x: Counts) -> Torque {
        let (i, frac) = self.rev.locate(x, SINE.len() as u32);
        // i < 64; cos θ = sin(θ + π/2), 16 entries on
        let at = |k: usize| i64::from(SINE.get(k & 63).copied().unwrap_or(0));
        let s = self.rev.lerp(at(i), at(i.wrapping_add(1)), frac);
        let c = self
            .rev
            .lerp(at(i.wrapping_add(16)), at(i.wrapping_add(17)), frac);
        // |amplitude| ≤ 2¹⁵, |s|, |c| ≤ 2¹⁵: the sum < 2³¹
        let sum = i64::from(self.sin)
            .wrapping_mul(s)
            .wrapping_add(i64::from(self.cos).wrapping_mul(c));
        // round half up, /2¹⁵
        sat_i32(sum.wrapping_add(1 << 14) >> 15).0
    }
}
