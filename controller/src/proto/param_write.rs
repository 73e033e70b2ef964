//! `ParamWrite` (kind 10, supervisor → card, DLC 7): stage one parameter value into the
//! staged set `set_seq`. Nothing staged is used until a matching `ParamCommit` applies the
//! whole set at a cycle boundary, so a half-written gain set is never active.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 2 | u16 LE | param_id | parameter id (see `params`), 0 rejected (reserved) |
//! | 2 | 4 | i32 LE | value | raw value in the parameter's Q format / unit |
//! | 6 | 1 | u8 | set_seq | staged-set sequence; a new `set_seq` discards the old staging |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::ParamWrite, 7);

mod off {
    pub const PARAM_ID: usize = 0;
    pub const VALUE: usize = 2;
    pub const SET_SEQ: usize = 6;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Parameter id.
    pub fn param_id(&self) -> u16 {
        field::u16_at(self.buf(), off::PARAM_ID)
    }
    /// Raw value.
    pub fn value(&self) -> i32 {
        field::i32_at(self.buf(), off::VALUE)
    }
    /// Staged-set sequence.
    pub fn set_seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SET_SEQ)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the parameter id.
    pub fn set_param_id(&mut self, v: u16) {
        field::set_u16(self.buf_mut(), off::PARAM_ID, v)
    }
    /// Sets the value.
    pub fn set_value(&mut self, v: i32) {
        field::set_i32(self.buf_mut(), off::VALUE, v)
    }
    /// Sets the staged-set sequence.
    pub fn set_set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SET_SEQ, v)
    }
}

/// A decoded `ParamWrite` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Parameter id (non-zero; whether it exists is the card's business, answered with
    /// `ParamStatus::UnknownId`).
    pub param_id: u16,
    /// Raw value.
    pub value: i32,
    /// Staged-set sequence.
    pub set_seq: u8,
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
            value: p.value(),
            set_seq: p.set_seq(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_param_id(self.param_id);
        p.set_value(self.value);
        p.set_set_seq(self.set_seq);
    }
}
