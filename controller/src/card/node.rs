//! The card as a bus node: which time the card sees, and in which order its frames go out.
//!
//! Every place that runs the card — the HIL lab's card thread, the firmware's CAN ISR, the
//! QEMU image that replays a recording — wraps [`Card`] in this one adapter, so "the same
//! card" means the same bytes on the bus, not just the same control law.
//!
//! * **Time.** In lockstep the card's clock is the count of its own `Sensor` frames times
//!   the period (a run is then reproducible bit for bit whatever the host's speed); in real
//!   time it is the caller's monotonic clock.
//! * **Order.** After a tick, a fault raised in that tick goes out before the `Actuator`
//!   frame (it is the most urgent thing the card has to say), then everything else the card
//!   queued, in its queue order.

use embedded_can::Frame;

use super::{Card, OUTBOX_CAPACITY};
use crate::proto::{id, Kind, Message, NodeId};

/// A [`Card`] with its clock rule and its transmit order. See the module docs.
#[derive(Debug)]
pub struct CardNode {
    card: Card,
    now_us: u64,
    period_us: u64,
    lockstep: bool,
}

impl CardNode {
    /// Wraps `card`. In `lockstep`, time advances `period_us` per own `Sensor` frame.
    pub fn new(card: Card, period_us: u64, lockstep: bool) -> Self {
        CardNode {
            card,
            now_us: 0,
            period_us,
            lockstep,
        }
    }

    /// The card inside.
    pub fn card(&self) -> &Card {
        &self.card
    }

    /// The card inside, mutable (e.g. to report a bus error).
    pub fn card_mut(&mut self) -> &mut Card {
        &mut self.card
    }

    /// Card time, µs.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// True if `raw_id` is this card's `Sensor` identifier (the tick).
    pub fn is_own_sensor(&self, raw_id: u16) -> bool {
        raw_id == id::compose(Kind::Sensor, self.card.node())
    }

    /// Handles one received frame at `now_us` (ignored in lockstep, where the card's own
    /// `Sensor` frames define time). `send` gets every message to transmit, in bus order.
    /// Returns true if the frame was the card's tick.
    pub fn on_frame<F: Frame>(
        &mut self,
        now_us: u64,
        frame: &F,
        mut send: impl FnMut(&Message),
    ) -> bool {
        if !self.lockstep {
            self.now_us = now_us;
        } else if matches!(frame.id(), embedded_can::Id::Standard(s) if self.is_own_sensor(s.as_raw()))
        {
            self.now_us = self.now_us.saturating_add(self.period_us);
        }
        match self.card.handle_frame(self.now_us, frame) {
            Some(act) => {
                // Faults first, then the actuator, then the rest in queue order. The outbox
                // holds at most OUTBOX_CAPACITY messages, so `rest` cannot overflow.
                let mut rest: heapless::Vec<Message, OUTBOX_CAPACITY> = heapless::Vec::new();
                while let Some(m) = self.card.poll_transmit() {
                    if matches!(m, Message::Fault(_)) {
                        send(&m);
                    } else if let Err(m) = rest.push(m) {
                        send(&m);
                    }
                }
                send(&Message::Actuator(act));
                for m in &rest {
                    send(m);
                }
                true
            }
            None => {
                self.drain(&mut send);
                false
            }
        }
    }

    /// Nothing arrived: the card checks its timeouts at `now_us` (in lockstep the caller
    /// decides how much time has passed; the clock never runs backwards).
    pub fn on_idle(&mut self, now_us: u64, mut send: impl FnMut(&Message)) {
        self.now_us = self.now_us.max(now_us);
        self.card.poll(self.now_us);
        self.drain(&mut send);
    }

    /// The card's own bus failed (bus-off, error-passive): safe state, then its frames.
    pub fn on_bus_error(&mut self, code: i32, mut send: impl FnMut(&Message)) {
        self.card.bus_error(code);
        self.drain(&mut send);
    }

    /// The card's bus is degraded but still carries frames (warning level, protocol error,
    /// missing ACK, receive overflow): counted by the card ([`Card::bus_warning`]), then
    /// its frames.
    pub fn on_bus_warning(&mut self, mut send: impl FnMut(&Message)) {
        self.card.bus_warning();
        self.drain(&mut send);
    }

    /// Hands out whatever the card has queued, without running anything.
    pub fn flush(&mut self, mut send: impl FnMut(&Message)) {
        self.drain(&mut send);
    }

    fn drain(&mut self, send: &mut impl FnMut(&Message)) {
        while let Some(m) = self.card.poll_transmit() {
            send(&m);
        }
    }

    /// This card's node number.
    pub fn node(&self) -> NodeId {
        self.card.node()
    }
}
