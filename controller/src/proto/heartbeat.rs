//! `Heartbeat` (kind 14, card → supervisor, DLC 8, every heartbeat period, param 0x0801):
//! the card's health page. Least urgent kind: it must never delay control traffic.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 1 | u8 | state | [`State`] 0..=5 |
//! | 1 | 1 | u8 | mode | [`Mode`] 1..=10 selected, 0 = none; must be non-zero when `Enabled`/`QuickStop` |
//! | 2 | 1 | u8 | fault | active [`FaultCode`], 0 = none; non-zero iff state is `FaultReaction`/`Fault` |
//! | 3 | 1 | u8 | limits | [`LimitFlags`] of the last tick (bits 6–7 reserved) |
//! | 4 | 2 | u16 LE | rejected_malformed | frames rejected by the decoder since boot, saturating |
//! | 6 | 1 | u8 | rejected_refused | well-formed frames refused in their state, saturating |
//! | 7 | 1 | u8 | protocol_version | [`PROTOCOL_VERSION`](super::PROTOCOL_VERSION) of the card |

use super::field::{self, packet};
use super::{Error, FaultCode, Kind, LimitFlags, Mode, State};

packet!(Kind::Heartbeat, 8);

mod off {
    pub const STATE: usize = 0;
    pub const MODE: usize = 1;
    pub const FAULT: usize = 2;
    pub const LIMITS: usize = 3;
    pub const MALFORMED: usize = 4;
    pub const REFUSED: usize = 6;
    pub const VERSION: usize = 7;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw state byte.
    pub fn state(&self) -> u8 {
        field::u8_at(self.buf(), off::STATE)
    }
    /// Raw mode byte.
    pub fn mode(&self) -> u8 {
        field::u8_at(self.buf(), off::MODE)
    }
    /// Raw fault byte.
    pub fn fault(&self) -> u8 {
        field::u8_at(self.buf(), off::FAULT)
    }
    /// Raw limits byte.
    pub fn limits(&self) -> u8 {
        field::u8_at(self.buf(), off::LIMITS)
    }
    /// Malformed-frame counter.
    pub fn rejected_malformed(&self) -> u16 {
        field::u16_at(self.buf(), off::MALFORMED)
    }
    /// Refused-frame counter.
    pub fn rejected_refused(&self) -> u8 {
        field::u8_at(self.buf(), off::REFUSED)
    }
    /// Protocol version.
    pub fn protocol_version(&self) -> u8 {
        field::u8_at(self.buf(), off::VERSION)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the state byte.
    pub fn set_state(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::STATE, v)
    }
    /// Sets the mode byte.
    pub fn set_mode(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::MODE, v)
    }
    /// Sets the fault byte.
    pub fn set_fault(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::FAULT, v)
    }
    /// Sets the limits byte.
    pub fn set_limits(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::LIMITS, v)
    }
    /// Sets the malformed-frame counter.
    pub fn set_rejected_malformed(&mut self, v: u16) {
        field::set_u16(self.buf_mut(), off::MALFORMED, v)
    }
    /// Sets the refused-frame counter.
    pub fn set_rejected_refused(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::REFUSED, v)
    }
    /// Sets the protocol version.
    pub fn set_protocol_version(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::VERSION, v)
    }
}

/// A decoded `Heartbeat` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Card state.
    pub state: State,
    /// Selected mode, if any.
    pub mode: Option<Mode>,
    /// Active fault, if any.
    pub fault: Option<FaultCode>,
    /// Limits of the last tick.
    pub limits: LimitFlags,
    /// [`RejectCounters::malformed_total`](super::RejectCounters::malformed_total).
    pub rejected_malformed: u16,
    /// [`RejectCounters::refused_u8`](super::RejectCounters::refused_u8).
    pub rejected_refused: u8,
    /// Card's protocol version.
    pub protocol_version: u8,
}

impl Repr {
    /// Validates and decodes, including the state/mode/fault consistency rules.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        let state = State::from_u8(p.state()).ok_or(Error::OutOfRange {
            kind: KIND,
            field: "state",
        })?;
        let mode = Mode::opt_from_u8(p.mode()).ok_or(Error::OutOfRange {
            kind: KIND,
            field: "mode",
        })?;
        let fault = FaultCode::opt_from_u8(p.fault()).ok_or(Error::OutOfRange {
            kind: KIND,
            field: "fault",
        })?;
        let limits = LimitFlags::from_bits(p.limits()).ok_or(Error::ReservedBits {
            kind: KIND,
            field: "limits",
        })?;
        let faulted = matches!(state, State::FaultReaction | State::Fault);
        if faulted != fault.is_some() {
            return Err(Error::Inconsistent {
                kind: KIND,
                field: "fault",
            });
        }
        if matches!(state, State::Enabled | State::QuickStop) && mode.is_none() {
            return Err(Error::Inconsistent {
                kind: KIND,
                field: "mode",
            });
        }
        Ok(Repr {
            state,
            mode,
            fault,
            limits,
            rejected_malformed: p.rejected_malformed(),
            rejected_refused: p.rejected_refused(),
            protocol_version: p.protocol_version(),
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_state(self.state.as_u8());
        p.set_mode(Mode::opt_to_u8(self.mode));
        p.set_fault(FaultCode::opt_to_u8(self.fault));
        p.set_limits(self.limits.bits());
        p.set_rejected_malformed(self.rejected_malformed);
        p.set_rejected_refused(self.rejected_refused);
        p.set_protocol_version(self.protocol_version);
    }
}
