//! Every reason a frame is rejected, as a typed value, and saturating counters of them.
//!
//! The card never acts on a frame it cannot fully account for: a frame is either decoded into
//! a [`Message`](super::Message) whose every bit is defined by `docs/protocol.md`, or rejected
//! with one of these variants and counted. The counters go into the heartbeat so a supervisor
//! (or a person with `candump`) can see a noisy bus or a mismatched peer.

use super::Kind;

/// Why a frame was rejected (decode) or a message could not be framed (encode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error {
    /// Remote-transmission-request frame: the protocol never polls with RTR.
    RemoteFrame,
    /// 29-bit identifier: the protocol is CAN 2.0A only.
    ExtendedId,
    /// The kind bits (ID bits 10..7) name no message: 0 and 15 are reserved.
    UnknownKind {
        /// The 4 kind bits found.
        kind: u8,
    },
    /// Node 0 (broadcast) used with a kind that addresses exactly one card.
    BroadcastNotAllowed {
        /// The kind that was broadcast.
        kind: Kind,
    },
    /// DLC differs from the kind's exact length.
    WrongLength {
        /// The message kind.
        kind: Kind,
        /// Its defined length.
        expected: u8,
        /// The frame's length.
        got: u8,
    },
    /// A bit the spec marks reserved (must be 0) is set.
    ReservedBits {
        /// The message kind.
        kind: Kind,
        /// The field holding the bit.
        field: &'static str,
    },
    /// An enum/code field holds a value the spec does not define, or a number outside its
    /// documented range.
    OutOfRange {
        /// The message kind.
        kind: Kind,
        /// The offending field.
        field: &'static str,
    },
    /// Fields contradict each other (e.g. a torque command with the drive flag clear).
    Inconsistent {
        /// The message kind.
        kind: Kind,
        /// The field that contradicts another.
        field: &'static str,
    },
    /// Encode side only: the typed value has no exact wire form (it would not decode back to
    /// itself), or the frame type refused the identifier/data.
    Unencodable {
        /// The message kind.
        kind: Kind,
    },
}

/// What `decode` returns on failure; the same type as [`Error`].
pub type DecodeError = Error;

/// Saturating per-category reject counters the card embeds and reports.
///
/// Saturating (not wrapping) because a counter that wraps back to a small number hides a
/// storm of bad frames; a stuck-at-max counter is unmistakable.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RejectCounters {
    /// [`Error::RemoteFrame`].
    pub remote: u16,
    /// [`Error::ExtendedId`].
    pub extended: u16,
    /// [`Error::UnknownKind`].
    pub unknown_kind: u16,
    /// [`Error::BroadcastNotAllowed`].
    pub broadcast: u16,
    /// [`Error::WrongLength`].
    pub length: u16,
    /// [`Error::ReservedBits`].
    pub reserved_bits: u16,
    /// [`Error::OutOfRange`].
    pub out_of_range: u16,
    /// [`Error::Inconsistent`] (and [`Error::Unencodable`], which a receiver never sees).
    pub inconsistent: u16,
    /// Well-formed frames the card refused in its current state (counted by the card via
    /// [`RejectCounters::record_refused`]).
    pub refused: u16,
}

impl RejectCounters {
    /// All zero.
    pub const fn new() -> Self {
        RejectCounters {
            remote: 0,
            extended: 0,
            unknown_kind: 0,
            broadcast: 0,
            length: 0,
            reserved_bits: 0,
            out_of_range: 0,
            inconsistent: 0,
            refused: 0,
        }
    }

    /// Counts one decode rejection in its category.
    pub fn record(&mut self, e: &Error) {
        let c = match e {
            Error::RemoteFrame => &mut self.remote,
            Error::ExtendedId => &mut self.extended,
            Error::UnknownKind { .. } => &mut self.unknown_kind,
            Error::BroadcastNotAllowed { .. } => &mut self.broadcast,
            Error::WrongLength { .. } => &mut self.length,
            Error::ReservedBits { .. } => &mut self.reserved_bits,
            Error::OutOfRange { .. } => &mut self.out_of_range,
            Error::Inconsistent { .. } | Error::Unencodable { .. } => &mut self.inconsistent,
        };
        *c = c.saturating_add(1);
    }

    /// Counts one well-formed frame refused in the current state.
    pub fn record_refused(&mut self) {
        self.refused = self.refused.saturating_add(1);
    }

    /// Sum of all malformed-frame categories (everything but `refused`), saturating; this is
    /// the heartbeat's `rejected_malformed`.
    pub fn malformed_total(&self) -> u16 {
        [
            self.remote,
            self.extended,
            self.unknown_kind,
            self.broadcast,
            self.length,
            self.reserved_bits,
            self.out_of_range,
            self.inconsistent,
        ]
        .iter()
        .fold(0u16, |a, &b| a.saturating_add(b))
    }

    /// `refused` saturated to the heartbeat's 8-bit field.
    pub fn refused_u8(&self) -> u8 {
        u8::try_from(self.refused).unwrap_or(u8::MAX)
    }
}
