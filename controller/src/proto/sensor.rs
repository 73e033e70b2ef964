//! `Sensor` (kind 3, plant or the MCU's sensor ISR → card, 1 kHz, DLC 8). This frame *is*
//! the card's tick: the card runs one control step per accepted `Sensor` frame and answers
//! with one `Actuator` frame echoing `seq`.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 4 | u32 LE | motor_counts | free-running motor encoder count, wraps mod 2³² |
//! | 4 | 2 | i16 LE | output_torque | torque sensor, 0.01 N·m/LSB; must be 0 if not valid |
//! | 6 | 1 | u8 | seq | increments by 1 per tick, wraps 255 → 0 |
//! | 7 | 1 | u8 | flags | bit0 torque_valid, bit1 output_encoder, bit2 encoder_error, 3–7 reserved |
//!
//! Multi-turn: the receiver keeps `pos += (raw_k.wrapping_sub(raw_{k-1})) as i32`, which is
//! exact while the motor moves less than 2³¹ counts between two accepted frames — at 1 kHz
//! and 2304 counts/rev that is ~9×10⁸ rev/s, i.e. never; it only matters across long gaps
//! (lost frames), which the sensor timeout bounds far below that.

use super::field::{self, packet};
use super::{Error, Kind};

packet!(Kind::Sensor, 8);

mod off {
    pub const MOTOR_COUNTS: usize = 0;
    pub const OUTPUT_TORQUE: usize = 4;
    pub const SEQ: usize = 6;
    pub const FLAGS: usize = 7;
}

/// Flag bit: `output_torque` holds a valid reading.
pub const FLAG_TORQUE_VALID: u8 = 0x01;
/// Flag bit: an `OutputEncoder` frame with the same `seq` was sent just before this one.
pub const FLAG_OUTPUT_ENCODER: u8 = 0x02;
/// Flag bit: the motor encoder reports an error; `motor_counts` is the last good value.
pub const FLAG_ENCODER_ERROR: u8 = 0x04;
const FLAGS_DEFINED: u8 = FLAG_TORQUE_VALID | FLAG_OUTPUT_ENCODER | FLAG_ENCODER_ERROR;

impl<T: AsRef<[u8]>> Packet<T> {
    /// Free-running motor count.
    pub fn motor_counts(&self) -> u32 {
        field::u32_at(self.buf(), off::MOTOR_COUNTS)
    }
    /// Raw torque-sensor field.
    pub fn output_torque(&self) -> i16 {
        field::i16_at(self.buf(), off::OUTPUT_TORQUE)
    }
    /// Sequence number.
    pub fn seq(&self) -> u8 {
        field::u8_at(self.buf(), off::SEQ)
    }
    /// Raw flags byte.
    pub fn flags(&self) -> u8 {
        field::u8_at(self.buf(), off::FLAGS)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the motor count.
    pub fn set_motor_counts(&mut self, v: u32) {
        field::set_u32(self.buf_mut(), off::MOTOR_COUNTS, v)
    }
    /// Sets the raw torque field.
    pub fn set_output_torque(&mut self, v: i16) {
        field::set_i16(self.buf_mut(), off::OUTPUT_TORQUE, v)
    }
    /// Sets the sequence number.
    pub fn set_seq(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::SEQ, v)
    }
    /// Sets the raw flags byte.
    pub fn set_flags(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::FLAGS, v)
    }
}

/// A decoded `Sensor` frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Repr {
    /// Free-running motor encoder count (wraps mod 2³²).
    pub motor_counts: u32,
    /// Output torque, 0.01 N·m/LSB; `None` when the sensor has no valid reading (the
    /// wire field is then 0, so a stale number can never be mistaken for a reading).
    pub output_torque: Option<i16>,
    /// Tick sequence number.
    pub seq: u8,
    /// An `OutputEncoder` frame with this `seq` preceded this frame.
    pub output_encoder: bool,
    /// The motor encoder flagged an error.
    pub encoder_error: bool,
}

impl Repr {
    /// Validates and decodes: reserved flag bits and a non-zero torque without the valid
    /// flag are rejected.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        let flags = p.flags();
        if flags & !FLAGS_DEFINED != 0 {
            return Err(Error::ReservedBits {
                kind: KIND,
                field: "flags",
            });
        }
        let output_torque = if flags & FLAG_TORQUE_VALID != 0 {
            Some(p.output_torque())
        } else if p.output_torque() == 0 {
            None
        } else {
            return Err(Error::Inconsistent {
                kind: KIND,
                field: "output_torque",
            });
        };
        Ok(Repr {
            motor_counts: p.motor_counts(),
            output_torque,
            seq: p.seq(),
            output_encoder: flags & FLAG_OUTPUT_ENCODER != 0,
            encoder_error: flags & FLAG_ENCODER_ERROR != 0,
        })
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        let mut flags = 0;
        if self.output_torque.is_some() {
            flags |= FLAG_TORQUE_VALID;
        }
        if self.output_encoder {
            flags |= FLAG_OUTPUT_ENCODER;
        }
        if self.encoder_error {
            flags |= FLAG_ENCODER_ERROR;
        }
        p.set_motor_counts(self.motor_counts);
        p.set_output_torque(self.output_torque.unwrap_or(0));
        p.set_seq(self.seq);
        p.set_flags(flags);
    }
}

/// Signed change between two samples of a free-running wrapping count (motor or output
/// encoder): exact while the true change is within ±2³¹ − 1 counts (see the module docs).
pub const fn count_delta(prev: u32, now: u32) -> i32 {
    now.wrapping_sub(prev) as i32
}

/// Multi-turn position from a free-running u32 count, exactly as `docs/protocol.md`
/// § Multi-turn positions specifies: the first sample gives `raw as i32`, later samples add
/// [`count_delta`] with wrapping i32 arithmetic (continuous joints wrap like the raw count).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Unwrap {
    last: Option<u32>,
    position: i32,
}

impl Unwrap {
    /// No sample yet.
    pub const fn new() -> Self {
        Unwrap {
            last: None,
            position: 0,
        }
    }

    /// Feeds one raw sample and returns the position in counts.
    pub fn update(&mut self, raw: u32) -> i32 {
        self.position = match self.last {
            None => raw as i32,
            Some(prev) => self.position.wrapping_add(count_delta(prev, raw)),
        };
        self.last = Some(raw);
        self.position
    }

    /// The last position (0 before the first sample).
    pub const fn position(&self) -> i32 {
        self.position
    }
}
