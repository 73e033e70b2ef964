//! `ParamCommit` (kind 11, supervisor → card, DLC 6): apply staged set `set_seq` atomically
//! at the next cycle boundary — or reject it whole. The card checks that `set_seq` matches
//! its staging, that it staged exactly `count` entries, and that the CRC-32 over the staged
//! entries in arrival order ([`crate::proto::checksum`]) equals `crc`; then it range-checks
//! every entry and cross-checks the set. Any failure discards the staging and leaves the
//! active configuration untouched; the answer is a `ParamResponse` with `reply_to = Commit`.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 1 | u8 | set_seq | the staged set to apply |
//! | 1 | 1 | u8 | count | number of `ParamWrite` frames the supervisor sent in this set |
//! | 2 | 4 | u32 LE | crc | CRC-32/ISO-HDLC over the entries (id u16 LE ‖ value i32 LE) |

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::ParamCommit, 6);

mod off {
    pub const SET_SEQ: usize = 0;
    pub const COUNT: usize = 1;
    pub const CRC: usize = 2;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Staged-set sequence.
    pub fn set_seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SET_SEQ)
    }
    /// Entry count.
    pub fn count(&self) -> u8 {
        field::u8_at(self.buf(), off::COUNT)
    }
    /// Checksum.
    pub fn crc(&self) -> u32 {
        field::u32_at(self.buf(), off::CRC)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the staged-set sequence.
    pub fn set_set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SET_SEQ, v)
    }
    /// Sets the entry count.
    pub fn set_count(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::COUNT, v)
    }
    /// Sets the checksum.
    pub fn set_crc(&mut self, v: u32) {
        field::set_u32(self.buf_mut(), off::CRC, v)
    }
}

/// A decoded `ParamCommit` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Staged-set sequence.
    pub set_seq: u8,
    /// Entries in the set.
    pub count: u8,
    /// CRC-32 over the set.
    pub crc: u32,
}

impl Repr {
    /// Decodes (every bit pattern of the right length is valid; a count of 0 is answered by
    /// the card with `NothingStaged`).
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            set_seq: p.set_seq(),
            count: p.count(),
            crc: p.crc(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_set_seq(self.set_seq);
        p.set_count(self.count);
        p.set_crc(self.crc);
    }
}
