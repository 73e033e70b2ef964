//! Wire units ("LSB" = value of one count of the integer field). One place for each scale;
//! `docs/protocol.md`, the DBC factors and the golden vectors all state the same numbers.
//!
//! Choices, all integer so the 1 kHz path never touches floats:
//! * positions are raw encoder counts (i32 / wrapping u32), as on the thesis's card;
//! * motor torque LSB 0.1 mN·m in i16: ±3.2767 N·m covers the ≤ 2 N·m thesis motor with
//!   headroom, resolution 0.005 % of 2 N·m;
//! * output torque LSB 0.01 N·m in i16: ±327.67 N·m covers the ±60 N·m transmission outputs;
//! * velocity LSB 8 counts/s in i16: ±262 136 counts/s (≈ 6 800 rpm at 2304 counts/rev),
//!   125× finer than differencing counts at 1 kHz (1 000 counts/s per count).

/// Motor torque (commands, feed-forwards, limits): newton-metres per LSB.
pub const MOTOR_TORQUE_NM_PER_LSB: f64 = 1.0e-4;
/// Output (torque-sensor) torque: newton-metres per LSB.
pub const OUTPUT_TORQUE_NM_PER_LSB: f64 = 1.0e-2;
/// One output-torque LSB in motor-torque LSBs, the laws' torque unit: the card rescales a
/// sensor reading or a force setpoint by this integer in the 1 kHz path, where
/// `OUTPUT_TORQUE_NM_PER_LSB / MOTOR_TORQUE_NM_PER_LSB` (a float) may not be used.
pub const OUTPUT_TORQUE_IN_MOTOR_LSB: i32 = 100;
/// Velocity on the wire: encoder counts per second per LSB.
pub const VELOCITY_COUNTS_PER_S_PER_LSB: i32 = 8;
/// Nominal sensor / control period, µs (1 kHz).
pub const NOMINAL_PERIOD_US: u32 = 1_000;

/// Converts a velocity in counts/s to the wire field, rounding to nearest (ties away from
/// zero) and saturating. Returns the field and whether it saturated (the card then sets
/// [`LimitFlags::WIRE_SATURATED`](super::LimitFlags::WIRE_SATURATED)).
pub fn velocity_to_wire(counts_per_s: i32) -> (i16, bool) {
    let lsb = VELOCITY_COUNTS_PER_S_PER_LSB;
    let half = lsb.checked_div(2).unwrap_or(0);
    let biased = if counts_per_s >= 0 {
        counts_per_s.saturating_add(half)
    } else {
        counts_per_s.saturating_sub(half)
    };
    // `lsb` is a non-zero constant, so `checked_div` never returns `None` here.
    let q = biased.checked_div(lsb).unwrap_or(0);
    match i16::try_from(q) {
        Ok(v) => (v, false),
        Err(_) => (if q > 0 { i16::MAX } else { i16::MIN }, true),
    }
}

/// Converts the wire velocity field back to counts/s (exact).
pub fn velocity_from_wire(v: i16) -> i32 {
    i32::from(v).saturating_mul(VELOCITY_COUNTS_PER_S_PER_LSB)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_torque_ratio_matches_the_two_lsbs() {
        let ratio = OUTPUT_TORQUE_NM_PER_LSB / MOTOR_TORQUE_NM_PER_LSB;
        assert!((ratio - f64::from(OUTPUT_TORQUE_IN_MOTOR_LSB)).abs() < 1e-9);
    }
}
