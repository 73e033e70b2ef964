//! `TelemetryMotion` (kind 8, card → supervisor, DLC 7): position and velocity estimate.
//! Telemetry is split in two frames because position (4 B), velocity (2 B), torque command
//! (2 B) and measured torque (2 B) exceed one 8-byte frame, and two frames per millisecond
//! would break the 40 % bus-load budget. The card alternates `TelemetryMotion` and
//! `TelemetryTorque` at the telemetry rate, so at divider 1 the bus carries one telemetry
//! frame per tick and each quantity arrives at 500 Hz (the supervisor runs at ≤ 400 Hz).
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 4 | i32 LE | position | motor position, counts (unwrapped, i32 wrapping) |
//! | 4 | 2 | i16 LE | velocity | velocity estimate, 8 counts/s per LSB (saturated; flag in TelemetryTorque) |
//! | 6 | 1 | u8 | seq | sensor `seq` of the tick sampled |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::TelemetryMotion, 7);

mod off {
    pub const POSITION: usize = 0;
    pub const VELOCITY: usize = 4;
    pub const SEQ: usize = 6;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Position, counts.
    pub fn position(&self) -> i32 {
        field::i32_at(self.buf(), off::POSITION)
    }
    /// Raw velocity field.
    pub fn velocity(&self) -> i16 {
        field::i16_at(self.buf(), off::VELOCITY)
    }
    /// Sequence number.
    pub fn seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SEQ)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the position.
    pub fn set_position(&mut self, v: i32) {
        field::set_i32(self.buf_mut(), off::POSITION, v)
    }
    /// Sets the raw velocity.
    pub fn set_velocity(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::VELOCITY, v)
    }
    /// Sets the sequence number.
    pub fn set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SEQ, v)
    }
}

/// A decoded `TelemetryMotion` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Motor position, counts.
    pub position: i32,
    /// Velocity estimate, 8 counts/s per LSB.
    pub velocity: i16,
    /// Sensor sequence number of the sampled tick.
    pub seq: u8,
}

impl Repr {
    /// Decodes (every bit pattern of the right length is valid).
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            position: p.position(),
            velocity: p.velocity(),
            seq: p.seq(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_position(self.position);
        p.set_velocity(self.velocity);
        p.set_seq(self.seq);
    }
}
