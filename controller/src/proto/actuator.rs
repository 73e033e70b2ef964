//! `Actuator` (kind 4, card → plant / power stage, 1 kHz, DLC 4): the torque command that
//! answers one `Sensor` frame. Kept to 4 bytes because it is one of the two 1 kHz frames
//! that dominate the bus load: the limit flags use bits 0–5 of byte 3, the two status bits
//! fill bits 6–7 of the same byte.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 2 | i16 LE | torque | motor torque command, 0.1 mN·m/LSB; must be 0 unless `drive` |
//! | 2 | 1 | u8 | seq | the `Sensor.seq` this command answers |
//! | 3 | 1 | u8 | bits 0–5 limits, bit 6 drive, bit 7 fault | [`LimitFlags`]; drive = power stage on; fault = card in `FaultReaction`/`Fault` |
//!
//! `drive = 0` with a non-zero torque is rejected: a card that is not driving can never
//! command torque, whatever else goes wrong.

use super::field::{self, packet};
use super::{Error, Kind, LimitFlags};

packet!(Kind::Actuator, 4);

mod off {
    pub const TORQUE: usize = 0;
    pub const SEQ: usize = 2;
    pub const STATUS: usize = 3;
}

/// Status bit: power stage on (the plant applies `torque`).
pub const STATUS_DRIVE: u8 = 0x40;
/// Status bit: the card is in `FaultReaction` or `Fault`.
pub const STATUS_FAULT: u8 = 0x80;

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw torque command.
    pub fn torque(&self) -> i16 {
        field::i16_at(self.buf(), off::TORQUE)
    }
    /// Echoed sequence number.
    pub fn seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SEQ)
    }
    /// Raw status byte (limit flags and drive/fault bits).
    pub fn status(&self) -> u8 {
        field::u8_at(self.buf(), off::STATUS)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the torque command.
    pub fn set_torque(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::TORQUE, v)
    }
    /// Sets the echoed sequence number.
    pub fn set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SEQ, v)
    }
    /// Sets the status byte.
    pub fn set_status(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::STATUS, v)
    }
}

/// A decoded `Actuator` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Motor torque command, 0.1 mN·m/LSB (already limited by the card).
    pub torque: i16,
    /// The sensor sequence number this answers.
    pub seq: u8,
    /// What limited the command.
    pub limits: LimitFlags,
    /// Power stage on. When false, `torque` is 0.
    pub drive: bool,
    /// Card in `FaultReaction`/`Fault`.
    pub fault: bool,
}

impl Repr {
    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        let status = p.status();
        // Every bit of the status byte is defined: bits 0–5 limits, 6 drive, 7 fault.
        let limits = LimitFlags::from_bits_truncate(status);
        let drive = status & STATUS_DRIVE != 0;
        if !drive && p.torque() != 0 {
            return Err(Error::Inconsistent {
                kind: KIND,
                field: "torque",
            });
        }
        Ok(Repr {
            torque: p.torque(),
            seq: p.seq(),
            limits,
            drive,
            fault: status & STATUS_FAULT != 0,
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        let mut status = self.limits.bits();
        if self.drive {
            status |= STATUS_DRIVE;
        }
        if self.fault {
            status |= STATUS_FAULT;
        }
        p.set_torque(self.torque);
        p.set_seq(self.seq);
        p.set_status(status);
    }
}
