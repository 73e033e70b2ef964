//! `TelemetryTorque` (kind 9, card → supervisor, DLC 6): torque command, measured output
//! torque and limiting flags (see `telemetry_motion` for why telemetry is two frames).
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 2 | i16 LE | torque_cmd | motor torque command sent, 0.1 mN·m/LSB |
//! | 2 | 2 | i16 LE | output_torque | measured output torque, 0.01 N·m/LSB (0 if no valid reading) |
//! | 4 | 1 | u8 | seq | sensor `seq` of the tick sampled |
//! | 5 | 1 | u8 | limits | [`LimitFlags`] of that tick (bits 6–7 reserved) |

use super::field::{self, packet};
use super::{Error, Kind, LimitFlags};

packet!(Kind::TelemetryTorque, 6);

mod off {
    pub const TORQUE_CMD: usize = 0;
    pub const OUTPUT_TORQUE: usize = 2;
    pub const SEQ: usize = 4;
    pub const LIMITS: usize = 5;
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw torque command.
    pub fn torque_cmd(&self) -> i16 {
        field::i16_at(self.buf(), off::TORQUE_CMD)
    }
    /// Raw measured output torque.
    pub fn output_torque(&self) -> i16 {
        field::i16_at(self.buf(), off::OUTPUT_TORQUE)
    }
    /// Sequence number.
    pub fn seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SEQ)
    }
    /// Raw limit-flags byte.
    pub fn limits(&self) -> u8 {
        field::u8_at(self.buf(), off::LIMITS)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the torque command.
    pub fn set_torque_cmd(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::TORQUE_CMD, v)
    }
    /// Sets the measured output torque.
    pub fn set_output_torque(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::OUTPUT_TORQUE, v)
    }
    /// Sets the sequence number.
    pub fn set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SEQ, v)
    }
    /// Sets the limit-flags byte.
    pub fn set_limits(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::LIMITS, v)
    }
}

/// A decoded `TelemetryTorque` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Motor torque command, 0.1 mN·m/LSB.
    pub torque_cmd: i16,
    /// Measured output torque, 0.01 N·m/LSB.
    pub output_torque: i16,
    /// Sensor sequence number of the sampled tick.
    pub seq: u8,
    /// Limits active at that tick.
    pub limits: LimitFlags,
}

impl Repr {
    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        Ok(Repr {
            torque_cmd: p.torque_cmd(),
            output_torque: p.output_torque(),
            seq: p.seq(),
            limits: LimitFlags::from_bits(p.limits()).ok_or(Error::ReservedBits {
                kind: KIND,
                field: "limits",
            })?,
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_torque_cmd(self.torque_cmd);
        p.set_output_torque(self.output_torque);
        p.set_seq(self.seq);
        p.set_limits(self.limits.bits());
    }
}
