//! The card node: the `controller` card running on the PC, fed only through the bus.
//!
//! The node is a thin adapter: every received frame goes to [`Card::handle_frame`], the
//! actuator command it returns and everything the card queued are framed and handed back to
//! the caller to send. It owns no clock: the caller passes the card's time — in lockstep the
//! tick count derived from `Sensor` frames (so a run is bit-reproducible), in real time a
//! monotonic clock.

use controller::card::{Card, ConfigError};
use controller::proto::{Message, NodeId};

use crate::bus::{BusFault, ClassicFrame};

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
    card: Card,
    /// Card time (µs) advanced by one period per `Sensor` frame in lockstep.
    now_us: u64,
    period_us: u64,
    lockstep: bool,
}

impl CardNode {
    /// A card for `node`. In `lockstep`, time advances one `period_us` per sensor frame.
    pub fn new(node: NodeId, lockstep: bool) -> Result<Self, ConfigError> {
        Ok(CardNode {
            card: Card::new(node)?,
            now_us: 0,
            period_us: 1000,
            lockstep,
        })
    }

    /// The card inside.
    pub fn card(&self) -> &Card {
        &self.card
    }

    /// Card time, µs.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    fn encode(&self, m: &Message) -> Option<ClassicFrame> {
        m.encode::<ClassicFrame>(self.card.node()).ok()
    }

    fn drain(&mut self, out: &mut Outgoing) {
        while let Some(m) = self.card.poll_transmit() {
            if let Some(f) = self.encode(&m) {
                out.frames.push(f);
            }
        }
    }

    /// Handles one received frame at `now_us` (ignored in lockstep, where sensor frames
    /// define time).
    pub fn on_frame(&mut self, now_us: u64, frame: &ClassicFrame) -> Outgoing {
        if !self.lockstep {
            self.now_us = now_us;
        } else if is_sensor_for(frame, self.card.node()) {
            self.now_us = self.now_us.saturating_add(self.period_us);
        }
        let mut out = Outgoing::default();
        if let Some(act) = self.card.handle_frame(self.now_us, frame) {
            out.ticked = true;
            // A fault raised in this very tick goes before the actuator frame.
            let mut rest = Outgoing::default();
            self.drain(&mut rest);
            let (faults, others): (Vec<_>, Vec<_>) =
                rest.frames.into_iter().partition(|f| kind_of(f) == Some(1));
            out.frames.extend(faults);
            if let Some(f) = self.encode(&Message::Actuator(act)) {
                out.frames.push(f);
            }
            out.frames.extend(others);
        } else {
            self.drain(&mut out);
        }
        out
    }

    /// Nothing arrived: let the card check its timeouts (real time only; in lockstep the
    /// caller passes the time it decided has passed).
    pub fn on_idle(&mut self, now_us: u64) -> Outgoing {
        self.now_us = self.now_us.max(now_us);
        self.card.poll(self.now_us);
        let mut out = Outgoing::default();
        self.drain(&mut out);
        out
    }

    /// The bus reported a fault that needs a safe state (bus-off, error-passive).
    pub fn on_bus_fault(&mut self, fault: &BusFault) -> Outgoing {
        if fault.requires_safe_state() {
            self.card
                .bus_error(i32::try_from(fault.class_bits()).unwrap_or(i32::MAX));
        }
        let mut out = Outgoing::default();
        self.drain(&mut out);
        out
    }
}

/// The protocol kind of a standard frame (ID bits 10..7).
pub fn kind_of(f: &ClassicFrame) -> Option<u16> {
    if f.is_extended() {
        return None;
    }
    u16::try_from(f.raw_id() >> 7).ok()
}

fn is_sensor_for(f: &ClassicFrame, node: NodeId) -> bool {
    !f.is_extended()
        && f.raw_id()
            == u32::from(controller::proto::id::compose(
                controller::proto::Kind::Sensor,
                node,
            ))
}
