//! `SetpointForce` (kind 6, supervisor → card, DLC 2): desired *output* torque τD for the
//! force modes. Its own frame (rather than reusing `torque_ff`) so every field has one unit:
//! force laws compare τD with the torque sensor, in the sensor's 0.01 N·m LSB.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 2 | i16 LE | output_torque | desired output torque τD, 0.01 N·m/LSB |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::SetpointForce, 2);

mod off {
    pub const OUTPUT_TORQUE: usize = 0;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw desired output torque.
    pub fn output_torque(&self) -> i16 {
        field::i16_at(self.buf(), off::OUTPUT_TORQUE)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the desired output torque.
    pub fn set_output_torque(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::OUTPUT_TORQUE, v)
    }
}

/// A decoded `SetpointForce` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Desired output torque τD, 0.01 N·m/LSB.
    pub output_torque: i16,
}

impl Repr {
    /// Decodes (every bit pattern of the right length is valid).
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            output_torque: p.output_torque(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_output_torque(self.output_torque);
    }
}
