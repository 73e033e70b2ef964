//! Frames as physical signals with units, read from a DBC database: by default the protocol's
//! own, `docs/jointlab.dbc` (kept equal to the codec by golden vectors), so `hil-host replay`
//! prints what cantools or a bus analyser would, and a log becomes a table of signals.
//!
//! Node addressing follows the protocol: a frame's 11-bit id is `kind << 7 | node`, and the
//! database lists each message for node 1; a frame matches the message of its kind.

use can_dbc::{ByteOrder, Dbc, MessageId, ValueType};
use thiserror::Error;

use crate::bus::ClassicFrame;

/// The protocol's DBC text (docs/jointlab.dbc).
pub const JOINTLAB_DBC: &str = include_str!("../../docs/jointlab.dbc");

/// A DBC that cannot be used.
#[derive(Debug, Error)]
#[error("DBC: {0}")]
pub struct DbcError(String);

/// One signal's layout and scaling.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalDef {
    /// Name (`motor_counts`).
    pub name: String,
    start: u32,
    size: u32,
    signed: bool,
    /// Raw → physical: `raw · factor + offset`.
    pub factor: f64,
    /// See `factor`.
    pub offset: f64,
    /// Unit as the DBC writes it (`N.m`, `counts/s`, empty).
    pub unit: String,
    /// Value names (`2` → `Enabled`), empty if none.
    pub labels: Vec<(i64, String)>,
}

/// One message kind.
#[derive(Debug, Clone, PartialEq)]
pub struct MessageDef {
    /// Name (`Sensor`).
    pub name: String,
    /// The id's kind bits (`id >> 7`).
    pub kind: u32,
    /// Payload length the database gives.
    pub len: usize,
    /// Its signals, in database order.
    pub signals: Vec<SignalDef>,
}

/// A decoded signal.
#[derive(Debug, Clone, PartialEq)]
pub struct Value<'a> {
    /// Its definition.
    pub def: &'a SignalDef,
    /// The raw integer.
    pub raw: i64,
    /// Physical value.
    pub value: f64,
}

impl Value<'_> {
    /// `name=value unit` (or `name=Label`).
    pub fn text(&self) -> String {
        if let Some((_, l)) = self.def.labels.iter().find(|(v, _)| *v == self.raw) {
            return format!("{}={l}", self.def.name);
        }
        let v = if self.def.factor.fract() == 0.0 && self.def.offset.fract() == 0.0 {
            format!("{}", self.value)
        } else {
            // As many decimals as the factor resolves.
            let d = (-self.def.factor.abs().log10()).ceil().max(0.0) as usize;
            format!("{:.*}", d, self.value)
        };
        if self.def.unit.is_empty() {
            format!("{}={v}", self.def.name)
        } else {
            format!("{}={v} {}", self.def.name, self.def.unit)
        }
    }
}

/// A frame read through the database.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoded<'a> {
    /// The message.
    pub message: &'a MessageDef,
    /// The node (`id & 0x7F`).
    pub node: u8,
    /// Every signal of the message.
    pub values: Vec<Value<'a>>,
}

/// Why a frame was not decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Undecoded {
    /// An extended or remote frame (the protocol uses neither).
    NotProtocol,
    /// No message of this kind.
    UnknownKind,
    /// Shorter than the message's length.
    Short {
        /// Bytes present.
        got: usize,
        /// Bytes the message has.
        want: usize,
    },
}

/// The messages of a DBC, ready to decode frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Database {
    /// Every message.
    pub messages: Vec<MessageDef>,
}

impl Database {
    /// The protocol's database.
    pub fn jointlab() -> Result<Self, DbcError> {
        Self::parse(JOINTLAB_DBC)
    }

    /// A DBC's messages with 11-bit ids and little-endian signals of up to 64 bits (what the
    /// protocol uses); anything else is an error naming it.
    pub fn parse(text: &str) -> Result<Self, DbcError> {
        let dbc = Dbc::try_from(text).map_err(|e| DbcError(format!("{e:?}")))?;
        let mut messages = Vec::new();
        for m in &dbc.messages {
            let MessageId::Standard(id) = m.id else {
                return Err(DbcError(format!("{}: extended id", m.name)));
            };
            let mut signals = Vec::new();
            for s in &m.signals {
                let (Ok(start), Ok(size)) = (u32::try_from(s.start_bit), u32::try_from(s.size))
                else {
                    return Err(DbcError(format!("{}.{}: layout", m.name, s.name)));
                };
                if s.byte_order != ByteOrder::LittleEndian || size == 0 || start + size > 64 {
                    return Err(DbcError(format!(
                        "{}.{}: only little-endian signals within 8 bytes are read",
                        m.name, s.name
                    )));
                }
                let labels = dbc
                    .value_descriptions_for_signal(m.id, &s.name)
                    .map(|v| v.iter().map(|d| (d.id, d.description.clone())).collect())
                    .unwrap_or_default();
                signals.push(SignalDef {
                    name: s.name.clone(),
                    start,
                    size,
                    signed: s.value_type == ValueType::Signed,
                    factor: s.factor,
                    offset: s.offset,
                    unit: s.unit.clone(),
                    labels,
                });
            }
            messages.push(MessageDef {
                name: m.name.clone(),
                kind: u32::from(id) >> 7,
                len: usize::try_from(m.size).unwrap_or(usize::MAX),
                signals,
            });
        }
        Ok(Database { messages })
    }

    /// The message named `name`.
    pub fn message(&self, name: &str) -> Option<&MessageDef> {
        self.messages.iter().find(|m| m.name == name)
    }

    /// `frame` as signals.
    pub fn decode(&self, frame: &ClassicFrame) -> Result<Decoded<'_>, Undecoded> {
        if frame.is_extended() || frame.is_remote() {
            return Err(Undecoded::NotProtocol);
        }
        let id = frame.raw_id();
        let message = self
            .messages
            .iter()
            .find(|m| m.kind == id >> 7)
            .ok_or(Undecoded::UnknownKind)?;
        let data = frame.data();
        if data.len() < message.len {
            return Err(Undecoded::Short {
                got: data.len(),
                want: message.len,
            });
        }
        let mut bytes = [0u8; 8];
        for (b, d) in bytes.iter_mut().zip(data) {
            *b = *d;
        }
        let word = u64::from_le_bytes(bytes);
        let values = message
            .signals
            .iter()
            .map(|def| {
                let bits = (word >> def.start) & (u64::MAX >> (64 - def.size));
                let raw = if def.signed && def.size < 64 && bits >> (def.size - 1) & 1 == 1 {
                    (bits | (u64::MAX << def.size)) as i64
                } else {
                    bits as i64
                };
                Value {
                    def,
                    raw,
                    value: raw as f64 * def.factor + def.offset,
                }
            })
            .collect();
        Ok(Decoded {
            message,
            node: (id & 0x7F) as u8,
            values,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller::proto::{Message, NodeId, RawFrame, Sensor};

    #[test]
    fn the_protocols_dbc_reads_what_the_codec_writes() {
        let db = Database::jointlab().unwrap();
        assert_eq!(db.messages.len(), 14);
        let node = NodeId::new(5).unwrap();
        let s = Sensor {
            motor_counts: 4_000_000_000,
            output_torque: Some(-1234),
            seq: 77,
            output_encoder: false,
            encoder_error: true,
        };
        let raw: RawFrame = Message::Sensor(s).encode(node).unwrap();
        let (id, data) = (raw.standard_id().unwrap(), embedded_can::Frame::data(&raw));
        let f = ClassicFrame::std(id, data).unwrap();
        let d = db.decode(&f).unwrap();
        assert_eq!((d.message.name.as_str(), d.node), ("Sensor", 5));
        let get = |n: &str| d.values.iter().find(|v| v.def.name == n).unwrap();
        assert_eq!(get("motor_counts").raw, 4_000_000_000);
        assert!((get("output_torque").value + 12.34).abs() < 1e-9);
        assert_eq!(get("output_torque").text(), "output_torque=-12.34 N.m");
        assert_eq!(get("seq").raw, 77);
        assert_eq!(get("encoder_error").raw, 1);
        assert_eq!(get("torque_valid").raw, 1);
        let short = ClassicFrame::std(id, &data[..3]).unwrap();
        assert_eq!(db.decode(&short), Err(Undecoded::Short { got: 3, want: 8 }));
        let unknown = ClassicFrame::std(0x7FF & !0x7F, &[0; 8]).unwrap();
        assert!(db.decode(&unknown).is_err());
    }
}
