//! `ControlWord` (kind 7, supervisor → card or broadcast to node 0, DLC 2): drives the
//! CiA-402-shaped state machine (see [`State`](super::State)) and selects the mode. Every
//! accepted control word also feeds the supervisor watchdog, so `KeepAlive` exists to do only
//! that.
//!
//! | off | width | type | field | meaning |
//! |---|---|---|---|---|
//! | 0 | 1 | u8 | command | [`Command`] 0..=5 |
//! | 1 | 1 | u8 | mode | `Enable`: [`Mode`] 1..=10; every other command: 0 (reserved) |

use super::field::{self, packet, wire_enum};
use super::{Error, Kind, Mode};

packet!(Kind::ControlWord, 2);

mod off {
    pub const COMMAND: usize = 0;
    pub const MODE: usize = 1;
}

wire_enum! {
    /// The command byte.
    pub enum Command {
        /// No state change; feeds the supervisor watchdog.
        KeepAlive = 0,
        /// `Disabled` → `Ready` (arm: the card validates the active configuration).
        Shutdown = 1,
        /// `Ready` → `Enabled(mode)`, or switch mode while `Enabled` (bumpless).
        Enable = 2,
        /// Any non-fault state → `Disabled` (torque off at once).
        Disable = 3,
        /// `Enabled` → `QuickStop` (brake with quick-stop damping, then `Disabled`).
        QuickStop = 4,
        /// `Fault` → `Disabled`.
        ClearFault = 5,
    }
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Raw command byte.
    pub fn command(&self) -> u8 {
        field::u8_at(self.buf(), off::COMMAND)
    }
    /// Raw mode byte.
    pub fn mode(&self) -> u8 {
        field::u8_at(self.buf(), off::MODE)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    /// Sets the command byte.
    pub fn set_command(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::COMMAND, v)
    }
    /// Sets the mode byte.
    pub fn set_mode(&mut self, v: u8) {
        field::set_u8(self.buf_mut(), off::MODE, v)
    }
}

/// A decoded `ControlWord`: the mode travels only with `Enable`, so a mode can never be
/// selected by accident alongside another command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Repr {
    /// Feed the watchdog only.
    KeepAlive,
    /// Arm.
    Shutdown,
    /// Run (or switch to) this mode.
    Enable(Mode),
    /// Torque off.
    Disable,
    /// Brake to standstill.
    QuickStop,
    /// Leave `Fault`.
    ClearFault,
}

impl Repr {
    /// The command byte of this control word.
    pub const fn command(&self) -> Command {
        match self {
            Repr::KeepAlive => Command::KeepAlive,
            Repr::Shutdown => Command::Shutdown,
            Repr::Enable(_) => Command::Enable,
            Repr::Disable => Command::Disable,
            Repr::QuickStop => Command::QuickStop,
            Repr::ClearFault => Command::ClearFault,
        }
    }

    /// The mode travelling with `Enable`.
    pub const fn mode(&self) -> Option<Mode> {
        match self {
            Repr::Enable(m) => Some(*m),
            _ => None,
        }
    }

    /// Validates and decodes.
    pub fn parse<T: AsRef<[u8]>>(p: &Packet<T>) -> Result<Repr, Error> {
        p.check_len()?;
        let command = Command::from_u8(p.command()).ok_or(Error::OutOfRange {
            kind: KIND,
            field: "command",
        })?;
        let mode = p.mode();
        match command {
            Command::Enable => Mode::from_u8(mode)
                .map(Repr::Enable)
                .ok_or(Error::OutOfRange {
                    kind: KIND,
                    field: "mode",
                }),
            _ if mode != 0 => Err(Error::ReservedBits {
                kind: KIND,
                field: "mode",
            }),
            Command::KeepAlive => Ok(Repr::KeepAlive),
            Command::Shutdown => Ok(Repr::Shutdown),
            Command::Disable => Ok(Repr::Disable),
            Command::QuickStop => Ok(Repr::QuickStop),
            Command::ClearFault => Ok(Repr::ClearFault),
        }
    }

    /// Writes every byte of the packet.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, p: &mut Packet<T>) {
        p.set_command(self.command().as_u8());
        p.set_mode(Mode::opt_to_u8(self.mode()));
    }
}
