//! `ParamRead` (kind 12, supervisor → card, DLC 2): read the *active* value of one
//! parameter (staged values are not readable: what you read is what the loop uses).
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 2 | u16 LE | param_id | parameter id, 0 rejected (reserved) |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::ParamRead, 2);

mod off {
    pub const PARAM_ID: usize = 0;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Parameter id.
    pub fn param_id(&self) -> u16 {
        field::u16_at(self.buf(), off::PARAM_ID)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the parameter id.
    pub fn set_param_id(&mut self, v: u16) {
        field::set_u16(self.buf_mut(), off::PARAM_ID, v)
    }
}

/// A decoded `ParamRead` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Parameter id (non-zero).
    pub param_id: u16,
}

impl Repr {
    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        if p.param_id() == 0 {
            return Err(Error::OutOfRange {
                kind: KIND,
                field: "param_id",
            });
        }
        Ok(Repr {
            param_id: p.param_id(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_param_id(self.param_id);
    }
}
