//! `Fault` (kind 1, card → all, DLC 6): sent once, immediately on entering `FaultReaction`.
//! Most urgent kind so it wins arbitration over the 1 kHz traffic of every joint.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 1 | u8 | code | [`FaultCode`] 1..=12 (0 rejected: a fault frame always has a cause) |
//! | 1 | 1 | u8 | limits | [`LimitFlags`] at the fault tick (bits 6–7 reserved) |
//! | 2 | 4 | i32 LE | detail | fault-specific value, see [`FaultCode`] |

use super::field::{self, packet};
use super::{Error, FaultCode, Kind, LimitFlags};

packet!(Kind::Fault, 6);

mod off {
    pub const CODE: usize = 0;
    pub const LIMITS: usize = 1;
    pub const DETAIL: usize = 2;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw fault code byte.
    pub fn code(&self) -> u8 {
        field::u8_at(self.buf(), off::CODE)
    }
    /// Raw limit-flags byte.
    pub fn limits(&self) -> u8 {
        field::u8_at(self.buf(), off::LIMITS)
    }
    /// Fault-specific detail.
    pub fn detail(&self) -> i32 {
        field::i32_at(self.buf(), off::DETAIL)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the fault code byte.
    pub fn set_code(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::CODE, v)
    }
    /// Sets the limit-flags byte.
    pub fn set_limits(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::LIMITS, v)
    }
    /// Sets the detail.
    pub fn set_detail(&mut self, v: i32) {
        field::set_i32(self.buf_mut(), off::DETAIL, v)
    }
}

/// A decoded `Fault` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// What went wrong.
    pub code: FaultCode,
    /// Limits active at that tick.
    pub limits: LimitFlags,
    /// Fault-specific value (position, velocity, param id, elapsed time…).
    pub detail: i32,
}

impl Repr {
    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            code: FaultCode::from_u8(p.code()).ok_or(Error::OutOfRange {
                kind: KIND,
                field: "code",
            })?,
            limits: LimitFlags::from_bits(p.limits()).ok_or(Error::ReservedBits {
                kind: KIND,
                field: "limits",
            })?,
            detail: p.detail(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_code(self.code.as_u8());
        p.set_limits(self.limits.bits());
        p.set_detail(self.detail);
    }
}
