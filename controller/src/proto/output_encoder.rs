//! `OutputEncoder` (kind 2, sensor → card, DLC 5): the output-side encoder sample of a tick,
//! for the non-colocated modes. A separate frame because the motor encoder, torque sensor,
//! sequence and flags already fill the 8-byte `Sensor` frame. Sent immediately *before* the
//! `Sensor` frame carrying the same `seq` (its lower ID also wins arbitration if both are
//! queued together), and that `Sensor` frame has its `output_encoder` flag set.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 4 | u32 LE | output_counts | free-running output encoder count, wraps mod 2³² |
//! | 4 | 1 | u8 | seq | the tick's sequence number (same as its `Sensor` frame) |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::OutputEncoder, 5);

mod off {
    pub const COUNTS: usize = 0;
    pub const SEQ: usize = 4;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Free-running output count.
    pub fn output_counts(&self) -> u32 {
        field::u32_at(self.buf(), off::COUNTS)
    }
    /// Sequence number.
    pub fn seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SEQ)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the output count.
    pub fn set_output_counts(&mut self, v: u32) {
        field::set_u32(self.buf_mut(), off::COUNTS, v)
    }
    /// Sets the sequence number.
    pub fn set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SEQ, v)
    }
}

/// A decoded `OutputEncoder` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Free-running output encoder count (unwrap by wrapping difference, like the motor's).
    pub output_counts: u32,
    /// Tick sequence number.
    pub seq: u8,
}

impl Repr {
    /// Validates and decodes (every bit pattern of the right length is valid).
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            output_counts: p.output_counts(),
            seq: p.seq(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_output_counts(self.output_counts);
        p.set_seq(self.seq);
    }
}
