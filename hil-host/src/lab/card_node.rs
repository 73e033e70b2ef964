//! The card node: the `controller` card running on the PC, fed only through the bus.
//!
//! A thin adapter over [`controller::card::node::CardNode`] — the same clock rule and transmit
//! order the firmware uses — that frames what the card sends as [`ClassicFrame`]s for the
//! caller to put on the bus. It owns no clock: the caller passes the card's time — in
//! lockstep the tick count derived from `Sensor` frames (so a run is bit-reproducible), in
//! real time a monotonic clock.

use controller::card::node::CardNode as Node;
use controller::card::{Card, ConfigError};
use controller::proto::{Message, NodeId};

use jointlab_can::bus::{BusFault, ClassicFrame, Severity};

/// What to send after handling one frame.
#[derive(Debug, Default)]
pub struct Outgoing {
    /// Frames to transmit, most urgent first (fault, actuator, then the rest).
    pub frames: Vec<ClassicFrame>,
    /// The frame was this card's `Sensor` frame (a tick was run).
    pub ticked: bool,
}

/// The card on the bus.
#[derive(Debug)]
pub struct CardNode {
    node: Node,
}

/// Control period of the card in lockstep, µs.
pub const PERIOD_US: u64 = 1000;

impl CardNode {
    /// A card for `node`. In `lockstep`, time advances one period per sensor frame.
    pub fn new(node: NodeId, lockstep: bool) -> Result<Self, ConfigError> {
        Ok(CardNode {
            node: Node::new(Card::new(node)?, PERIOD_US, lockstep),
        })
    }

    /// The card inside.
    pub fn card(&self) -> &Card {
        self.node.card()
    }

    /// Card time, µs.
    pub fn now_us(&self) -> u64 {
        self.node.now_us()
    }

    /// Handles one received frame at `now_us` (ignored in lockstep, where sensor frames
    /// define time).
    pub fn on_frame(&mut self, now_us: u64, frame: &ClassicFrame) -> Outgoing {
        let me = self.node.node();
        let mut out = Outgoing::default();
        out.ticked = self
            .node
            .on_frame(now_us, frame, |m| push(&mut out.frames, me, m));
        out
    }

    /// Nothing arrived: let the card check its timeouts (real time only; in lockstep the
    /// caller passes the time it decided has passed).
    pub fn on_idle(&mut self, now_us: u64) -> Outgoing {
        let me = self.node.node();
        let mut out = Outgoing::default();
        self.node.on_idle(now_us, |m| push(&mut out.frames, me, m));
        out
    }

    /// The card's controller reported an error frame. Bus-off, a TX timeout or error-passive
    /// (either direction, as the firmware does) mean the card can no longer be sure to be
    /// heard: its safe state (`BusError`, torque off at the next tick). Warning level,
    /// protocol errors, a missing ACK or a receive overflow are counted by the card
    /// ([`controller::card::Card::bus_warning`]). Recovery and counter reports change
    /// nothing.
    pub fn on_bus_fault(&mut self, fault: &BusFault) -> Outgoing {
        let me = self.node.node();
        let mut out = Outgoing::default();
        if fault.requires_safe_state() || fault.is_error_passive() {
            let code = i32::try_from(fault.class_bits()).unwrap_or(i32::MAX);
            self.node
                .on_bus_error(code, |m| push(&mut out.frames, me, m));
        } else if fault.severity() == Severity::Warning {
            self.node.on_bus_warning(|m| push(&mut out.frames, me, m));
        } else {
            self.node.flush(|m| push(&mut out.frames, me, m));
        }
        out
    }
}

fn push(frames: &mut Vec<ClassicFrame>, node: NodeId, m: &Message) {
    if let Ok(f) = m.encode::<ClassicFrame>(node) {
        frames.push(f);
    }
}

/// The protocol kind of a standard frame (ID bits 10..7).
pub fn kind_of(f: &ClassicFrame) -> Option<u16> {
    if f.is_extended() {
        return None;
    }
    u16::try_from(f.raw_id() >> 7).ok()
}
