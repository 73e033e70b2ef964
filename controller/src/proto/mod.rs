//! CAN wire protocol: typed messages ↔ CAN 2.0A frames.
//!
//! The normative layout is `docs/protocol.md`; `docs/jointlab.dbc` describes the same frames
//! for standard CAN tools, and `docs/golden-vectors.toml` ties spec, codec and DBC together
//! (checked by `controller/tests/golden.rs` and `docs/check_dbc.py`).
//!
//! Structure (smoltcp style): one module per message kind, each with a `Packet<T>` that
//! wraps a length-checked buffer (field accessors that cannot panic) and a `Repr` with
//! `parse`/`emit`. [`Message`] unifies them with [`Message::decode`] / [`Message::encode`]
//! over any [`embedded_can::Frame`]. Every rejection is an [`Error`] variant, counted by
//! [`RejectCounters`].
//!
//! Identifier: `id = kind << 7 | node` ([`id`]). Everything is little-endian.

mod field;

pub mod actuator;
pub mod checksum;
pub mod control_word;
pub mod error;
pub mod fault;
pub mod frame;
pub mod heartbeat;
pub mod id;
pub mod output_encoder;
pub mod param_commit;
pub mod param_read;
pub mod param_response;
pub mod param_write;
pub mod params;
pub mod scale;
pub mod sensor;
pub mod setpoint_force;
pub mod setpoint_motion;
pub mod staging;
pub mod state;
pub mod telemetry_motion;
pub mod telemetry_torque;

pub use checksum::{Crc32, SetChecksum};
pub use control_word::Command;
pub use error::{DecodeError, Error, RejectCounters};
pub use frame::RawFrame;
pub use id::{Direction, Kind, NodeId};
pub use param_response::{ParamStatus, ReplyTo};
pub use state::{FaultCode, LimitFlags, Mode, State};

pub use actuator::Repr as Actuator;
pub use control_word::Repr as ControlWord;
pub use fault::Repr as Fault;
pub use heartbeat::Repr as Heartbeat;
pub use output_encoder::Repr as OutputEncoder;
pub use param_commit::Repr as ParamCommit;
pub use param_read::Repr as ParamRead;
pub use param_response::Repr as ParamResponse;
pub use param_write::Repr as ParamWrite;
pub use sensor::Repr as Sensor;
pub use setpoint_force::Repr as SetpointForce;
pub use setpoint_motion::Repr as SetpointMotion;
pub use telemetry_motion::Repr as TelemetryMotion;
pub use telemetry_torque::Repr as TelemetryTorque;

use embedded_can::{Frame, Id, StandardId};

/// Protocol version carried in every heartbeat. Bumped on any incompatible layout change.
pub const PROTOCOL_VERSION: u8 = 1;

/// Largest data length of any message (classic CAN).
pub const MAX_LEN: usize = 8;

impl Kind {
    /// The exact data length (DLC) of this kind; any other length is rejected.
    pub const fn dlc(self) -> usize {
        match self {
            Kind::Fault => fault::LEN,
            Kind::OutputEncoder => output_encoder::LEN,
            Kind::Sensor => sensor::LEN,
            Kind::Actuator => actuator::LEN,
            Kind::SetpointMotion => setpoint_motion::LEN,
            Kind::SetpointForce => setpoint_force::LEN,
            Kind::ControlWord => control_word::LEN,
            Kind::TelemetryMotion => telemetry_motion::LEN,
            Kind::TelemetryTorque => telemetry_torque::LEN,
            Kind::ParamWrite => param_write::LEN,
            Kind::ParamCommit => param_commit::LEN,
            Kind::ParamRead => param_read::LEN,
            Kind::ParamResponse => param_response::LEN,
            Kind::Heartbeat => heartbeat::LEN,
        }
    }

    /// Worst-case bits on the bus of one frame of this kind, stuff bits included:
    /// `47 + 8n + ⌊(34 + 8n − 1) / 4⌋` (see `docs/protocol.md` § Bus load).
    pub const fn worst_case_bits(self) -> u32 {
        let data_bits = (self.dlc() as u32).saturating_mul(8);
        // Stuffable region is 34 + 8n bits; one stuff bit per 4 after the first.
        let stuff = match 33u32.saturating_add(data_bits).checked_div(4) {
            Some(v) => v,
            None => 0,
        };
        47u32.saturating_add(data_bits).saturating_add(stuff)
    }
}

/// Any protocol message, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    /// Kind 1.
    Fault(Fault),
    /// Kind 2.
    OutputEncoder(OutputEncoder),
    /// Kind 3.
    Sensor(Sensor),
    /// Kind 4.
    Actuator(Actuator),
    /// Kind 5.
    SetpointMotion(SetpointMotion),
    /// Kind 6.
    SetpointForce(SetpointForce),
    /// Kind 7.
    ControlWord(ControlWord),
    /// Kind 8.
    TelemetryMotion(TelemetryMotion),
    /// Kind 9.
    TelemetryTorque(TelemetryTorque),
    /// Kind 10.
    ParamWrite(ParamWrite),
    /// Kind 11.
    ParamCommit(ParamCommit),
    /// Kind 12.
    ParamRead(ParamRead),
    /// Kind 13.
    ParamResponse(ParamResponse),
    /// Kind 14.
    Heartbeat(Heartbeat),
}

impl Message {
    /// The kind of this message.
    pub const fn kind(&self) -> Kind {
        match self {
            Message::Fault(_) => Kind::Fault,
            Message::OutputEncoder(_) => Kind::OutputEncoder,
            Message::Sensor(_) => Kind::Sensor,
            Message::Actuator(_) => Kind::Actuator,
            Message::SetpointMotion(_) => Kind::SetpointMotion,
            Message::SetpointForce(_) => Kind::SetpointForce,
            Message::ControlWord(_) => Kind::ControlWord,
            Message::TelemetryMotion(_) => Kind::TelemetryMotion,
            Message::TelemetryTorque(_) => Kind::TelemetryTorque,
            Message::ParamWrite(_) => Kind::ParamWrite,
            Message::ParamCommit(_) => Kind::ParamCommit,
            Message::ParamRead(_) => Kind::ParamRead,
            Message::ParamResponse(_) => Kind::ParamResponse,
            Message::Heartbeat(_) => Kind::Heartbeat,
        }
    }

    /// Decodes the data bytes of a frame of `kind` (the identifier already split).
    pub fn parse_payload(kind: Kind, data: &[u8]) -> Result<Message, Error> {
        Ok(match kind {
            Kind::Fault => Message::Fault(Fault::parse(&fault::Packet::new_checked(data)?)?),
            Kind::OutputEncoder => Message::OutputEncoder(OutputEncoder::parse(
                &output_encoder::Packet::new_checked(data)?,
            )?),
            Kind::Sensor => Message::Sensor(Sensor::parse(&sensor::Packet::new_checked(data)?)?),
            Kind::Actuator => {
                Message::Actuator(Actuator::parse(&actuator::Packet::new_checked(data)?)?)
            }
            Kind::SetpointMotion => Message::SetpointMotion(SetpointMotion::parse(
                &setpoint_motion::Packet::new_checked(data)?,
            )?),
            Kind::SetpointForce => Message::SetpointForce(SetpointForce::parse(
                &setpoint_force::Packet::new_checked(data)?,
            )?),
            Kind::ControlWord => Message::ControlWord(ControlWord::parse(
                &control_word::Packet::new_checked(data)?,
            )?),
            Kind::TelemetryMotion => Message::TelemetryMotion(TelemetryMotion::parse(
                &telemetry_motion::Packet::new_checked(data)?,
            )?),
            Kind::TelemetryTorque => Message::TelemetryTorque(TelemetryTorque::parse(
                &telemetry_torque::Packet::new_checked(data)?,
            )?),
            Kind::ParamWrite => {
                Message::ParamWrite(ParamWrite::parse(&param_write::Packet::new_checked(data)?)?)
            }
            Kind::ParamCommit => Message::ParamCommit(ParamCommit::parse(
                &param_commit::Packet::new_checked(data)?,
            )?),
            Kind::ParamRead => {
                Message::ParamRead(ParamRead::parse(&param_read::Packet::new_checked(data)?)?)
            }
            Kind::ParamResponse => Message::ParamResponse(ParamResponse::parse(
                &param_response::Packet::new_checked(data)?,
            )?),
            Kind::Heartbeat => {
                Message::Heartbeat(Heartbeat::parse(&heartbeat::Packet::new_checked(data)?)?)
            }
        })
    }

    /// Decodes a received frame. Checks, in this order (the first failure is returned):
    /// extended ID, remote frame, kind, broadcast use, exact length, field values.
    pub fn decode<F: Frame>(frame: &F) -> Result<(NodeId, Message), Error> {
        let raw = match frame.id() {
            Id::Standard(s) => s.as_raw(),
            Id::Extended(_) => return Err(Error::ExtendedId),
        };
        if frame.is_remote_frame() {
            return Err(Error::RemoteFrame);
        }
        let (kind, node) = id::split(raw)?;
        if node.is_broadcast() && !kind.allows_broadcast() {
            return Err(Error::BroadcastNotAllowed { kind });
        }
        Ok((node, Message::parse_payload(kind, frame.data())?))
    }

    /// Writes the data bytes into `buf` and returns the length used. Does not validate;
    /// [`Message::encode`] does.
    pub fn emit_payload(&self, buf: &mut [u8; MAX_LEN]) -> usize {
        macro_rules! emit {
            ($m:ident, $r:expr) => {{
                if let Some(b) = buf.get_mut(..$m::LEN) {
                    $r.emit(&mut $m::Packet::new_unchecked(b));
                }
                $m::LEN
            }};
        }
        match self {
            Message::Fault(r) => emit!(fault, r),
            Message::OutputEncoder(r) => emit!(output_encoder, r),
            Message::Sensor(r) => emit!(sensor, r),
            Message::Actuator(r) => emit!(actuator, r),
            Message::SetpointMotion(r) => emit!(setpoint_motion, r),
            Message::SetpointForce(r) => emit!(setpoint_force, r),
            Message::ControlWord(r) => emit!(control_word, r),
            Message::TelemetryMotion(r) => emit!(telemetry_motion, r),
            Message::TelemetryTorque(r) => emit!(telemetry_torque, r),
            Message::ParamWrite(r) => emit!(param_write, r),
            Message::ParamCommit(r) => emit!(param_commit, r),
            Message::ParamRead(r) => emit!(param_read, r),
            Message::ParamResponse(r) => emit!(param_response, r),
            Message::Heartbeat(r) => emit!(heartbeat, r),
        }
    }

    /// The 11-bit identifier and data bytes for `node`, validated: the bytes are decoded
    /// again and must give back exactly `self`, so the encoder can never put a frame on the
    /// bus that a receiver would reject or read differently (e.g. an `Actuator` with torque
    /// but no drive flag, or a `Heartbeat` in `Fault` without a fault code).
    pub fn to_bytes(&self, node: NodeId) -> Result<(u16, [u8; MAX_LEN], usize), Error> {
        let kind = self.kind();
        if node.is_broadcast() && !kind.allows_broadcast() {
            return Err(Error::BroadcastNotAllowed { kind });
        }
        let mut buf = [0u8; MAX_LEN];
        let len = self.emit_payload(&mut buf);
        let data = buf.get(..len).ok_or(Error::Unencodable { kind })?;
        match Message::parse_payload(kind, data) {
            Ok(back) if back == *self => Ok((id::compose(kind, node), buf, len)),
            Ok(_) => Err(Error::Unencodable { kind }),
            Err(e) => Err(e),
        }
    }

    /// True if a card with node `me` should act on this frame: a to-card kind addressed to
    /// `me` or broadcast. (Frames for other nodes, and every card's own output kinds, are
    /// simply not for it — that is not a rejection and is not counted.)
    pub fn is_for(node: NodeId, kind: Kind, me: NodeId) -> bool {
        kind.direction() == Direction::ToCard && (node == me || node.is_broadcast())
    }

    /// Builds a frame for `node` (see [`Message::to_bytes`] for the validation).
    pub fn encode<F: Frame>(&self, node: NodeId) -> Result<F, Error> {
        let kind = self.kind();
        let (raw, buf, len) = self.to_bytes(node)?;
        let sid = StandardId::new(raw).ok_or(Error::Unencodable { kind })?;
        let data = buf.get(..len).ok_or(Error::Unencodable { kind })?;
        F::new(sid, data).ok_or(Error::Unencodable { kind })
    }
}
