//! CAN identifier layout: `id = kind << 7 | node` (11-bit standard ID).
//!
//! Why this layout: CAN arbitration lets the numerically lowest ID win, so putting the
//! message *kind* in the top 4 bits makes urgency a property of the kind for the whole bus —
//! a fault from any joint beats every 1 kHz sensor frame, every sensor frame beats every
//! actuator frame, and so on down to heartbeats. Within one kind, lower node numbers win,
//! which is a fixed and therefore analysable tie-break. 7 node bits give joints 1..=127
//! (node 0 is broadcast), the same split as CANopen's COB-ID, so existing tooling habits
//! carry over. Kind 15 is reserved because IDs 0x7F0..=0x7FF (the top 7 bits all recessive)
//! are forbidden by CAN 2.0A; kind 0 (0x000..=0x07F, the most urgent IDs) is kept free for a
//! future bus-wide emergency/sync message.

use super::Error;

super::field::wire_enum! {
    /// Message kind: the top 4 bits of the 11-bit ID, in priority order (lower = more urgent).
    pub enum Kind {
        /// Card → all: entered a fault (sent once, immediately).
        Fault = 1,
        /// Plant / sensor ISR → card: output-encoder sample, sent just before the `Sensor` frame
        /// of the same tick (its lower ID wins arbitration when both are queued together).
        OutputEncoder = 2,
        /// Plant / sensor ISR → card, 1 kHz: motor encoder, output torque, sequence. The card's tick.
        Sensor = 3,
        /// Card → plant / power stage, 1 kHz: torque command answering one `Sensor` frame.
        Actuator = 4,
        /// Supervisor → card: position, velocity feed-forward, motor torque feed-forward.
        SetpointMotion = 5,
        /// Supervisor → card: desired output torque for the force modes.
        SetpointForce = 6,
        /// Supervisor → card (or broadcast): state-machine command and mode select.
        ControlWord = 7,
        /// Card → supervisor: position and velocity estimate.
        TelemetryMotion = 8,
        /// Card → supervisor: torque command, measured output torque, limiting flags.
        TelemetryTorque = 9,
        /// Supervisor → card: stage one parameter value.
        ParamWrite = 10,
        /// Supervisor → card: apply the staged set atomically (sequence + count + CRC-32).
        ParamCommit = 11,
        /// Supervisor → card: read one active parameter.
        ParamRead = 12,
        /// Card → supervisor: answer to a read, a rejected write, or a commit.
        ParamResponse = 13,
        /// Card → supervisor: periodic state, fault, flags, reject counters, protocol version.
        Heartbeat = 14,
    }
}

/// Which way a kind travels relative to the card it names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Consumed by the card whose node the id carries (from the sensor side or the
    /// supervisor).
    ToCard,
    /// Produced by the card whose node the id carries.
    FromCard,
}

impl Kind {
    /// Direction of this kind: a card acts on `ToCard` frames addressed to its node (or
    /// broadcast) and ignores everything else on the bus, including other cards' output.
    pub const fn direction(self) -> Direction {
        match self {
            Kind::OutputEncoder
            | Kind::Sensor
            | Kind::SetpointMotion
            | Kind::SetpointForce
            | Kind::ControlWord
            | Kind::ParamWrite
            | Kind::ParamCommit
            | Kind::ParamRead => Direction::ToCard,
            Kind::Fault
            | Kind::Actuator
            | Kind::TelemetryMotion
            | Kind::TelemetryTorque
            | Kind::ParamResponse
            | Kind::Heartbeat => Direction::FromCard,
        }
    }

    /// Whether node 0 (broadcast) is a valid address for this kind. Only the control word
    /// is: one frame can quick-stop or disable every joint at once. Everything else concerns
    /// exactly one card.
    pub const fn allows_broadcast(self) -> bool {
        matches!(self, Kind::ControlWord)
    }
}

/// A node (joint) number, 0..=127; 0 is the broadcast address.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NodeId(u8);

impl NodeId {
    /// Node 0: every card. Valid only where [`Kind::allows_broadcast`].
    pub const BROADCAST: NodeId = NodeId(0);
    /// Highest node number that fits the 7 node bits.
    pub const MAX: u8 = 127;

    /// `None` above 127.
    pub const fn new(n: u8) -> Option<NodeId> {
        if n <= Self::MAX {
            Some(NodeId(n))
        } else {
            None
        }
    }

    /// The node number.
    pub const fn get(self) -> u8 {
        self.0
    }

    /// True for node 0.
    pub const fn is_broadcast(self) -> bool {
        self.0 == 0
    }
}

/// Builds the 11-bit identifier. Never exceeds 0x77F (kind ≤ 14, node ≤ 127).
pub const fn compose(kind: Kind, node: NodeId) -> u16 {
    ((kind.as_u8() as u16) << 7) | (node.0 as u16)
}

/// Splits an 11-bit identifier into kind and node, rejecting reserved kinds (0, 15).
pub fn split(raw: u16) -> Result<(Kind, NodeId), Error> {
    let kind_bits = ((raw >> 7) & 0x0F) as u8;
    let node = NodeId((raw & 0x7F) as u8);
    match Kind::from_u8(kind_bits) {
        Some(k) => Ok((k, node)),
        None => Err(Error::UnknownKind { kind: kind_bits }),
    }
}
