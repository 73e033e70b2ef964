//! Multi-turn unwrap of a wrapping encoder count (design.md: "positions are integer encoder
//! counts with multi-turn handling, no float accumulation, wrap documented").

use crate::fixed_math::Counts;

/// Turns a wrapping raw count into a monotone multi-turn [`Counts`] value.
///
/// * Modulus 2³² (default, [`Unwrapper::new`]): a free-running 32-bit hardware counter. The
///   step between two samples is `raw.wrapping_sub(last) as i32`, so any motion of less than
///   2³¹ counts per sample is unwrapped correctly (at 2²⁰ cpr that is 2048 rev per 1 ms).
/// * Modulus m ([`Unwrapper::with_modulus`]): a single-turn absolute encoder reporting
///   `0..m` (e.g. 0..2303). Motion of less than m/2 per sample is unwrapped correctly.
///
/// The first sample defines the origin: a 2³² counter's raw value is read as `i32` (so a
/// counter that starts at 0 and moves backwards reads −1, not 4 294 967 295), a modulus-m
/// value as `0..m`. The output saturates at `i64` limits (≈ 4·10¹² rev at 2³¹ cpr — never
/// reached in practice; saturating keeps the no-panic rule).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Unwrapper {
    last: u32,
    pos: Counts,
    primed: bool,
    /// 0 means 2³².
    modulus: u32,
}

impl Unwrapper {
    /// Unwrapper for a free-running 32-bit counter.
    pub const fn new() -> Self {
        Unwrapper {
            last: 0,
            pos: 0,
            primed: false,
            modulus: 0,
        }
    }

    /// Unwrapper for a counter that wraps at `modulus` (values `0..modulus`). `modulus` 0 or 1
    /// is treated as 2³².
    pub const fn with_modulus(modulus: u32) -> Self {
        Unwrapper {
            last: 0,
            pos: 0,
            primed: false,
            modulus: if modulus <= 1 { 0 } else { modulus },
        }
    }

    /// Forget the history: the next sample defines the origin again.
    pub fn reset(&mut self) {
        self.primed = false;
    }

    /// Re-home: declare that the current raw reading `raw` is multi-turn position `pos`.
    pub fn set_position(&mut self, raw: u32, pos: Counts) {
        self.last = self.reduce(raw);
        self.pos = pos;
        self.primed = true;
    }

    /// Current multi-turn position.
    pub fn position(&self) -> Counts {
        self.pos
    }

    fn reduce(&self, raw: u32) -> u32 {
        if self.modulus == 0 {
            raw
        } else {
            raw.checked_rem(self.modulus).unwrap_or(raw)
        }
    }

    /// Feed one raw reading, get the multi-turn position.
    pub fn update(&mut self, raw: u32) -> Counts {
        let raw = self.reduce(raw);
        if !self.primed {
            self.primed = true;
            self.last = raw;
            self.pos = if self.modulus == 0 {
                Counts::from(raw as i32)
            } else {
                Counts::from(raw)
            };
            return self.pos;
        }
        let delta: i64 = if self.modulus == 0 {
            i64::from(raw.wrapping_sub(self.last) as i32)
        } else {
            let m = i64::from(self.modulus);
            // raw, last < m ⇒ d in (−m, m); fold into (−m/2, m/2].
            let d = i64::from(raw).wrapping_sub(i64::from(self.last));
            let half = m.wrapping_shr(1);
            if d > half {
                d.wrapping_sub(m)
            } else if d <= half.wrapping_neg() {
                d.wrapping_add(m)
            } else {
                d
            }
        };
        self.last = raw;
        self.pos = self.pos.saturating_add(delta);
        self.pos
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wraps_32() {
        let mut u = Unwrapper::new();
        assert_eq!(u.update(u32::MAX - 1), -2);
        assert_eq!(u.update(1), 1);
        let mut p = 0;
        for k in 0..20u32 {
            p = u.update(1u32.wrapping_add(k.wrapping_mul(0x4000_0000)));
        }
        assert_eq!(p, 1 + 19 * 0x4000_0000i64);
    }

    #[test]
    fn wraps_modulus() {
        let mut u = Unwrapper::with_modulus(2304);
        assert_eq!(u.update(2300), 2300);
        assert_eq!(u.update(3), 2307);
        assert_eq!(u.update(2303), 2303);
        assert_eq!(u.update(1300), 1300); // −1003: the short way
        assert_eq!(u.update(100), 2404); // −1200 < −m/2 ⇒ +1104 is the short way
    }
}
