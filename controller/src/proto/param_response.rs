//! `ParamResponse` (kind 13, card → supervisor, DLC 8): the answer to a `ParamRead` (always),
//! a `ParamWrite` (only when the write is rejected — accepted writes are silent to halve
//! configuration traffic; the commit answer is the verdict), or a `ParamCommit` (always).
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 1 | u8 | bits 0–3 reply_to, bits 4–7 status | [`ReplyTo`] 1..=3, [`ParamStatus`] 0..=10 |
//! | 1 | 1 | u8 | set_seq | Write/Commit: the staged set concerned; Read: 0 |
//! | 2 | 2 | u16 LE | param_id | Read/Write: the parameter; Commit: offending id, or 0 |
//! | 4 | 4 | i32 LE | value | Read+Ok: active value; Read+error: 0; Write: the rejected value; Commit: entries the card had staged |

use super::field::{self, packet, wire_enum};
use super::{Error, Kind};

packet!(Kind::ParamResponse, 8);

mod off {
    pub const CODE: usize = 0;
    pub const SET_SEQ: usize = 1;
    pub const PARAM_ID: usize = 2;
    pub const VALUE: usize = 4;
}

wire_enum! {
    /// Which request a `ParamResponse` answers.
    pub enum ReplyTo {
        /// A `ParamRead`.
        Read = 1,
        /// A rejected `ParamWrite`.
        Write = 2,
        /// A `ParamCommit`.
        Commit = 3,
    }
}

wire_enum! {
    /// Result of a parameter request.
    pub enum ParamStatus {
        /// Done (read value returned / set applied).
        Ok = 0,
        /// No parameter with this id.
        UnknownId = 1,
        /// The parameter cannot be written.
        ReadOnly = 2,
        /// The value is outside the parameter's documented range.
        OutOfRange = 3,
        /// The staging buffer is full; the set will be rejected at commit.
        StagingFull = 4,
        /// The parameter cannot change in the current state (e.g. plant constants while
        /// `Enabled`).
        NotAllowedInState = 5,
        /// Commit: `set_seq` does not match the staging.
        SequenceMismatch = 6,
        /// Commit: the card staged a different number of entries (a write was lost).
        CountMismatch = 7,
        /// Commit: CRC-32 over the staged entries differs (a write was corrupted/reordered).
        ChecksumMismatch = 8,
        /// Commit: nothing is staged.
        NothingStaged = 9,
        /// Commit: every value is in range but the set as a whole is invalid (min > max,
        /// gains beyond the discrete stability guard, table length > entries written …);
        /// `param_id` names the first offending parameter.
        InconsistentSet = 10,
    }
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw reply-to nibble.
    pub fn reply_to(&self) -> u8 {
        field::u8_at(self.buf(), off::CODE) & 0x0F
    }
    /// Raw status nibble.
    pub fn status(&self) -> u8 {
        field::u8_at(self.buf(), off::CODE) >> 4
    }
    /// Staged-set sequence.
    pub fn set_seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SET_SEQ)
    }
    /// Parameter id.
    pub fn param_id(&self) -> u16 {
        field::u16_at(self.buf(), off::PARAM_ID)
    }
    /// Value.
    pub fn value(&self) -> i32 {
        field::i32_at(self.buf(), off::VALUE)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets reply-to (low nibble) and status (high nibble).
    pub fn set_code(&mut self, reply_to: u8, status: u8) {
        field::set_u8(
            self.buf_mut(),
            off::CODE,
            (reply_to & 0x0F) | ((status & 0x0F) << 4),
        )
    }
    /// Sets the staged-set sequence.
    pub fn set_set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SET_SEQ, v)
    }
    /// Sets the parameter id.
    pub fn set_param_id(&mut self, v: u16) {
        field::set_u16(self.buf_mut(), off::PARAM_ID, v)
    }
    /// Sets the value.
    pub fn set_value(&mut self, v: i32) {
        field::set_i32(self.buf_mut(), off::VALUE, v)
    }
}

/// A decoded `ParamResponse` frame. Flat on purpose: the meaning of `param_id`/`value` per
/// `reply_to` is in the table above, and every combination round-trips.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Which request this answers.
    pub reply_to: ReplyTo,
    /// Outcome.
    pub status: ParamStatus,
    /// Staged set concerned (0 for reads).
    pub set_seq: u8,
    /// Parameter (or offending parameter, or 0).
    pub param_id: u16,
    /// Value (see the table).
    pub value: i32,
}

impl Repr {
    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            reply_to: ReplyTo::from_u8(p.reply_to()).ok_or(Error::OutOfRange {
                kind: KIND,
                field: "reply_to",
            })?,
            status: ParamStatus::from_u8(p.status()).ok_or(Error::OutOfRange {
                kind: KIND,
                field: "status",
            })?,
            set_seq: p.set_seq(),
            param_id: p.param_id(),
            value: p.value(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_code(self.reply_to.as_u8(), self.status.as_u8());
        p.set_set_seq(self.set_seq);
        p.set_param_id(self.param_id);
        p.set_value(self.value);
    }
}
