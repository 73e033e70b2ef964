//! `SetpointMotion` (kind 5, supervisor → card, DLC 8): latched and used by every tick until
//! the next one (the supervisor runs at 20–400 Hz, the card at 1 kHz).
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 4 | i32 LE | position | desired position, motor counts (the card's unwrapped count space) |
//! | 4 | 2 | i16 LE | velocity_ff | velocity feed-forward, 8 counts/s per LSB |
//! | 6 | 2 | i16 LE | torque_ff | motor torque feed-forward, 0.1 mN·m/LSB (`TorquePassthrough`: the command) |
//!
//! Non-colocated modes interpret `position` in *output* encoder counts.

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::SetpointMotion, 8);

mod off {
    pub const POSITION: usize = 0;
    pub const VELOCITY_FF: usize = 4;
    pub const TORQUE_FF: usize = 6;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Desired position (counts).
    pub fn position(&self) -> i32 {
        field::i32_at(self.buf(), off::POSITION)
    }
    /// Raw velocity feed-forward.
    pub fn velocity_ff(&self) -> i16 {
        field::i16_at(self.buf(), off::VELOCITY_FF)
    }
    /// Raw torque feed-forward.
    pub fn torque_ff(&self) -> i16 {
        field::i16_at(self.buf(), off::TORQUE_FF)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the position.
    pub fn set_position(&mut self, v: i32) {
        field::set_i32(self.buf_mut(), off::POSITION, v)
    }
    /// Sets the velocity feed-forward.
    pub fn set_velocity_ff(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::VELOCITY_FF, v)
    }
    /// Sets the torque feed-forward.
    pub fn set_torque_ff(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::TORQUE_FF, v)
    }
}

/// A decoded `SetpointMotion` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Desired position, counts.
    pub position: i32,
    /// Velocity feed-forward, 8 counts/s per LSB.
    pub velocity_ff: i16,
    /// Motor torque feed-forward, 0.1 mN·m/LSB.
    pub torque_ff: i16,
}

impl Repr {
    /// Decodes (every bit pattern of the right length is valid).
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            position: p.position(),
            velocity_ff: p.velocity_ff(),
            torque_ff: p.torque_ff(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_position(self.position);
        p.set_velocity_ff(self.velocity_ff);
        p.set_torque_ff(self.torque_ff);
    }
}
