//! Bus faults (decoded CAN error frames) and the bus error type.
//!
//! A [`BusFault`] is the harness-owned form of one Linux CAN error frame: the raw class bits
//! of the CAN ID plus the 8 data bytes (so it re-encodes losslessly, for candump logs and
//! fault injection), decoded into typed [`FaultCause`]s following `linux/can/error.h`.
//! It is portable (no Linux types), so the in-process bus can inject the same faults that
//! SocketCAN reports.

use core::fmt;
use std::io;

/// `CAN_ERR_FLAG`: the error-frame flag in a SocketCAN `can_id`.
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;
/// `CAN_ERR_MASK`: every error class bit.
pub const CAN_ERR_MASK: u32 = 0x1FFF_FFFF;

/// Error class bits (`can_id` of an error frame), `linux/can/error.h`.
pub mod class {
    /// TX timeout (by netdevice driver).
    pub const TX_TIMEOUT: u32 = 0x001;
    /// Lost arbitration; data\[0\] = bit position.
    pub const LOSTARB: u32 = 0x002;
    /// Controller problems; data\[1\].
    pub const CRTL: u32 = 0x004;
    /// Protocol violations; data\[2\] type, data\[3\] location.
    pub const PROT: u32 = 0x008;
    /// Transceiver status; data\[4\].
    pub const TRX: u32 = 0x010;
    /// Received no ACK on transmission.
    pub const ACK: u32 = 0x020;
    /// Bus off.
    pub const BUSOFF: u32 = 0x040;
    /// Bus error (may flood!).
    pub const BUSERROR: u32 = 0x080;
    /// Controller restarted.
    pub const RESTARTED: u32 = 0x100;
    /// TX error counter in data\[6\], RX error counter in data\[7\].
    pub const CNT: u32 = 0x200;
    /// All of the above.
    pub const KNOWN: u32 = 0x3FF;
}

/// Controller status bits (data\[1\] of a `CRTL` error frame).
pub mod ctrl {
    /// RX buffer overflow.
    pub const RX_OVERFLOW: u8 = 0x01;
    /// TX buffer overflow.
    pub const TX_OVERFLOW: u8 = 0x02;
    /// Reached warning level for RX errors.
    pub const RX_WARNING: u8 = 0x04;
    /// Reached warning level for TX errors.
    pub const TX_WARNING: u8 = 0x08;
    /// Reached error-passive status, RX.
    pub const RX_PASSIVE: u8 = 0x10;
    /// Reached error-passive status, TX.
    pub const TX_PASSIVE: u8 = 0x20;
    /// Recovered to error-active state.
    pub const ACTIVE: u8 = 0x40;
}

/// Protocol violation type bits (data\[2\] of a `PROT` error frame).
pub mod prot {
    /// Single bit error.
    pub const BIT: u8 = 0x01;
    /// Frame format error.
    pub const FORM: u8 = 0x02;
    /// Bit stuffing error.
    pub const STUFF: u8 = 0x04;
    /// Unable to send dominant bit.
    pub const BIT0: u8 = 0x08;
    /// Unable to send recessive bit.
    pub const BIT1: u8 = 0x10;
    /// Bus overload.
    pub const OVERLOAD: u8 = 0x20;
    /// Active error announcement.
    pub const ACTIVE: u8 = 0x40;
    /// Error occurred on transmission.
    pub const TX: u8 = 0x80;
}

/// Which direction of the controller a warning/passive state refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Receive error counter.
    Rx,
    /// Transmit error counter.
    Tx,
}

/// One condition reported by an error frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum FaultCause {
    /// The driver timed out transmitting.
    TxTimeout,
    /// Arbitration lost (bit position, `None` = unspecified).
    LostArbitration(Option<u8>),
    /// Controller RX or TX buffer overflow: frames were lost.
    Overflow(Direction),
    /// Error counter reached the warning level (≥ 96).
    ErrorWarning(Direction),
    /// Error counter reached the error-passive level (≥ 128).
    ErrorPassive(Direction),
    /// Controller recovered to error-active.
    BackToErrorActive,
    /// Controller problem with no or unknown detail bits (raw data\[1\]).
    ControllerOther(u8),
    /// Protocol violation: type bits (see [`prot`]) and location (data\[3\]).
    Protocol {
        /// Violation type bits, [`prot`].
        types: u8,
        /// Location code, `CAN_ERR_PROT_LOC_*`.
        location: u8,
    },
    /// Transceiver status (raw data\[4\]).
    Transceiver(u8),
    /// A transmitted frame was not acknowledged: nobody else on the bus, or wiring.
    NoAck,
    /// The controller went bus-off: it no longer transmits or receives.
    BusOff,
    /// Bus error.
    BusError,
    /// The controller was restarted (after bus-off).
    Restarted,
    /// Error counter values.
    Counters {
        /// TX error counter.
        tx: u8,
        /// RX error counter.
        rx: u8,
    },
    /// Class bits this decoder does not know.
    Unknown(u32),
}

impl fmt::Display for FaultCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use FaultCause::*;
        match *self {
            TxTimeout => write!(f, "TX timeout"),
            LostArbitration(Some(b)) => write!(f, "arbitration lost at bit {b}"),
            LostArbitration(None) => write!(f, "arbitration lost"),
            Overflow(d) => write!(f, "controller {d:?} buffer overflow"),
            ErrorWarning(d) => write!(f, "{d:?} error warning level"),
            ErrorPassive(d) => write!(f, "{d:?} error-passive"),
            BackToErrorActive => write!(f, "back to error-active"),
            ControllerOther(b) => write!(f, "controller problem (0x{b:02X})"),
            Protocol { types, location } => write!(
                f,
                "protocol violation types=0x{types:02X} location=0x{location:02X}"
            ),
            Transceiver(b) => write!(f, "transceiver status 0x{b:02X}"),
            NoAck => write!(f, "no ACK"),
            BusOff => write!(f, "bus-off"),
            BusError => write!(f, "bus error"),
            Restarted => write!(f, "controller restarted"),
            Counters { tx, rx } => write!(f, "error counters tx={tx} rx={rx}"),
            Unknown(bits) => write!(f, "unknown error class bits 0x{bits:X}"),
        }
    }
}

/// How a node should react to a fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// Informational (recovery, counters).
    Info,
    /// Degraded bus (warnings, lost frames, protocol errors, missing ACK): keep running but
    /// report it.
    Warning,
    /// The node can no longer rely on the bus (bus-off, TX error-passive, TX timeout): go to
    /// a safe state.
    Critical,
}

/// One decoded CAN error frame.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct BusFault {
    class: u32,
    data: [u8; 8],
}

impl BusFault {
    /// From the raw parts of an error frame: the class bits (the `can_id` without
    /// `CAN_ERR_FLAG`; extra flag bits are masked off) and up to 8 data bytes.
    pub fn from_raw(class: u32, data: &[u8]) -> Self {
        let mut d = [0u8; 8];
        let n = data.len().min(8);
        d[..n].copy_from_slice(&data[..n]);
        Self {
            class: class & CAN_ERR_MASK,
            data: d,
        }
    }

    /// A single-class fault with no detail bytes (for injection in tests).
    pub fn bus_off() -> Self {
        Self::from_raw(class::BUSOFF, &[])
    }

    /// A controller state change, as drivers report it (`CRTL | CNT`).
    pub fn controller(status: u8, tx_errors: u8, rx_errors: u8) -> Self {
        Self::from_raw(
            class::CRTL | class::CNT,
            &[0, status, 0, 0, 0, 0, tx_errors, rx_errors],
        )
    }

    /// A missing-ACK fault.
    pub fn no_ack() -> Self {
        Self::from_raw(class::ACK, &[])
    }

    /// The class bits (error frame `can_id` without `CAN_ERR_FLAG`).
    pub fn class_bits(&self) -> u32 {
        self.class
    }

    /// The 8 data bytes.
    pub fn data(&self) -> &[u8; 8] {
        &self.data
    }

    /// The SocketCAN `can_id` of this error frame (with `CAN_ERR_FLAG`).
    pub fn can_id(&self) -> u32 {
        self.class | CAN_ERR_FLAG
    }

    /// Decodes the causes in class-bit order.
    pub fn causes(&self) -> Vec<FaultCause> {
        use FaultCause::*;
        let (c, d) = (self.class, &self.data);
        let mut out = Vec::new();
        if c & class::TX_TIMEOUT != 0 {
            out.push(TxTimeout);
        }
        if c & class::LOSTARB != 0 {
            out.push(LostArbitration((d[0] != 0).then_some(d[0])));
        }
        if c & class::CRTL != 0 {
            let s = d[1];
            let known = [
                (ctrl::RX_OVERFLOW, Overflow(Direction::Rx)),
                (ctrl::TX_OVERFLOW, Overflow(Direction::Tx)),
                (ctrl::RX_WARNING, ErrorWarning(Direction::Rx)),
                (ctrl::TX_WARNING, ErrorWarning(Direction::Tx)),
                (ctrl::RX_PASSIVE, ErrorPassive(Direction::Rx)),
                (ctrl::TX_PASSIVE, ErrorPassive(Direction::Tx)),
                (ctrl::ACTIVE, BackToErrorActive),
            ];
            for (bit, cause) in known {
                if s & bit != 0 {
                    out.push(cause);
                }
            }
            if s == 0 || s & 0x80 != 0 {
                out.push(ControllerOther(s));
            }
        }
        if c & class::PROT != 0 {
            out.push(Protocol {
                types: d[2],
                location: d[3],
            });
        }
        if c & class::TRX != 0 {
            out.push(Transceiver(d[4]));
        }
        if c & class::ACK != 0 {
            out.push(NoAck);
        }
        if c & class::BUSOFF != 0 {
            out.push(BusOff);
        }
        if c & class::BUSERROR != 0 {
            out.push(BusError);
        }
        if c & class::RESTARTED != 0 {
            out.push(Restarted);
        }
        if c & class::CNT != 0 {
            out.push(Counters { tx: d[6], rx: d[7] });
        }
        if c & !class::KNOWN != 0 || c == 0 {
            out.push(Unknown(c & !class::KNOWN));
        }
        out
    }

    /// `true` if the controller reported bus-off.
    pub fn is_bus_off(&self) -> bool {
        self.class & class::BUSOFF != 0
    }

    /// `true` if the controller reported error-passive (RX or TX).
    pub fn is_error_passive(&self) -> bool {
        self.class & class::CRTL != 0 && self.data[1] & (ctrl::RX_PASSIVE | ctrl::TX_PASSIVE) != 0
    }

    /// The most severe reaction any cause calls for.
    pub fn severity(&self) -> Severity {
        use FaultCause::*;
        self.causes()
            .iter()
            .map(|c| match c {
                BusOff | TxTimeout | ErrorPassive(Direction::Tx) => Severity::Critical,
                BackToErrorActive | Restarted | Counters { .. } => Severity::Info,
                _ => Severity::Warning,
            })
            .max()
            .unwrap_or(Severity::Warning)
    }

    /// `true` when a node should go to its safe state ([`Severity::Critical`]).
    pub fn requires_safe_state(&self) -> bool {
        self.severity() == Severity::Critical
    }

    /// The closest [`embedded_can::ErrorKind`].
    pub fn kind(&self) -> embedded_can::ErrorKind {
        use embedded_can::ErrorKind;
        for cause in self.causes() {
            match cause {
                FaultCause::NoAck => return ErrorKind::Acknowledge,
                FaultCause::Overflow(_) => return ErrorKind::Overrun,
                FaultCause::Protocol { types, .. } => {
                    if types & (prot::BIT | prot::BIT0 | prot::BIT1) != 0 {
                        return ErrorKind::Bit;
                    }
                    if types & prot::FORM != 0 {
                        return ErrorKind::Form;
                    }
                    if types & prot::STUFF != 0 {
                        return ErrorKind::Stuff;
                    }
                }
                _ => {}
            }
        }
        ErrorKind::Other
    }
}

impl fmt::Display for BusFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, c) in self.causes().iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{c}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for BusFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "BusFault(class=0x{:03X}, data={:02X?}: {self})",
            self.class, self.data
        )
    }
}

/// The exact commands that create a virtual CAN interface on a Linux box.
pub const VCAN_HOWTO: &str =
    "sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0";

fn rig_hint(iface: &str) -> String {
    if iface.starts_with("vcan") {
        String::new()
    } else {
        format!(" (on a rig with a real controller: sudo ip link set {iface} up type can bitrate 1000000)")
    }
}

/// Errors of every [`CanBus`](super::CanBus).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BusError {
    /// The network interface does not exist (ENODEV, os error 19).
    #[error(
        "CAN interface `{iface}` does not exist (ENODEV, os error 19). Create a virtual CAN \
         interface with: {VCAN_HOWTO}{}. Or use the in-process bus: --bus inproc",
        rig_hint(iface)
    )]
    NoSuchInterface {
        /// The interface name that was asked for.
        iface: String,
    },
    /// The kernel has no AF_CAN (EAFNOSUPPORT, os error 97).
    #[error(
        "cannot open CAN interface `{iface}`: this kernel lacks CAN support (AF_CAN missing, \
         EAFNOSUPPORT, os error 97; it needs CONFIG_CAN, CONFIG_CAN_RAW and CONFIG_CAN_VCAN). \
         On a kernel with CAN modules, create vcan0 with: {VCAN_HOWTO}   On a machine without \
         them, run the SocketCAN tests in the QEMU guest (.ci/vm/run-vcan-tests.sh) or use the \
         in-process bus: --bus inproc"
    )]
    NoCanSupport {
        /// The interface name that was asked for.
        iface: String,
    },
    /// A SocketCAN interface was asked for, but this build has no SocketCAN transport
    /// (jointlab-can without its `socketcan` feature).
    #[error(
        "cannot open CAN interface `{iface}`: this build has no SocketCAN transport \
         (jointlab-can's `socketcan` feature is off); use --bus inproc or slcan:…"
    )]
    SocketCanNotBuilt {
        /// The interface name that was asked for.
        iface: String,
    },
    /// The controller reported a fault (a CAN error frame was received).
    #[error("bus fault on `{bus}`: {fault}")]
    Fault {
        /// Bus name.
        bus: String,
        /// The decoded error frame.
        fault: BusFault,
    },
    /// Any other I/O error.
    #[error("{op} on `{bus}` failed: {source}")]
    Io {
        /// Bus name.
        bus: String,
        /// What was being done.
        op: &'static str,
        /// The OS error.
        #[source]
        source: io::Error,
    },
    /// A bus spec that is neither an in-process bus nor a valid interface name.
    #[error("bad bus spec `{spec}`: {reason}")]
    BadSpec {
        /// The spec as given.
        spec: String,
        /// Why it was rejected.
        reason: String,
    },
    /// The SLCAN link misbehaved: a line that is not SLCAN, a refused command (BELL), no
    /// answer in time, the device or QEMU gone.
    #[error("SLCAN link `{bus}`: {reason}")]
    Slcan {
        /// Bus name.
        bus: String,
        /// What happened, with the offending line if there was one.
        reason: String,
    },
    /// A frame that the transport cannot carry.
    #[error("frame cannot be sent on `{bus}`: {reason}")]
    Unrepresentable {
        /// Bus name.
        bus: String,
        /// Why.
        reason: String,
    },
}

impl BusError {
    /// The fault, if this error is a received error frame.
    pub fn fault(&self) -> Option<&BusFault> {
        match self {
            BusError::Fault { fault, .. } => Some(fault),
            _ => None,
        }
    }

    /// `true` if a node should go to its safe state: a critical fault, or the bus is gone.
    pub fn requires_safe_state(&self) -> bool {
        match self {
            BusError::Fault { fault, .. } => fault.requires_safe_state(),
            _ => true,
        }
    }

    /// Maps an OS error from opening interface `iface`, naming the fix for ENODEV/EAFNOSUPPORT.
    pub fn from_open(iface: &str, e: io::Error) -> Self {
        match e.raw_os_error() {
            Some(19) => BusError::NoSuchInterface {
                iface: iface.to_string(),
            },
            Some(97) => BusError::NoCanSupport {
                iface: iface.to_string(),
            },
            _ => BusError::Io {
                bus: iface.to_string(),
                op: "open",
                source: e,
            },
        }
    }
}

impl embedded_can::Error for BusError {
    fn kind(&self) -> embedded_can::ErrorKind {
        match self {
            BusError::Fault { fault, .. } => fault.kind(),
            _ => embedded_can::ErrorKind::Other,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_typical_frames() {
        let f = BusFault::bus_off();
        assert_eq!(f.causes(), vec![FaultCause::BusOff]);
        assert!(f.requires_safe_state());
        assert_eq!(f.can_id(), 0x2000_0040);

        let f = BusFault::controller(ctrl::TX_PASSIVE | ctrl::RX_PASSIVE, 130, 128);
        assert_eq!(
            f.causes(),
            vec![
                FaultCause::ErrorPassive(Direction::Rx),
                FaultCause::ErrorPassive(Direction::Tx),
                FaultCause::Counters { tx: 130, rx: 128 }
            ]
        );
        assert!(f.is_error_passive());
        assert_eq!(f.severity(), Severity::Critical);

        let f = BusFault::controller(ctrl::RX_WARNING, 0, 97);
        assert_eq!(f.severity(), Severity::Warning);
        let f = BusFault::controller(ctrl::ACTIVE, 0, 0);
        assert_eq!(f.severity(), Severity::Info);

        let f = BusFault::no_ack();
        assert_eq!(f.kind(), embedded_can::ErrorKind::Acknowledge);
        assert!(!f.requires_safe_state());

        let f = BusFault::from_raw(class::PROT, &[0, 0, prot::STUFF, 0x0A]);
        assert_eq!(f.kind(), embedded_can::ErrorKind::Stuff);
        let f = BusFault::from_raw(0x400 | CAN_ERR_FLAG, &[]);
        assert_eq!(f.causes(), vec![FaultCause::Unknown(0x400)]);
    }

    #[test]
    fn open_errors_name_the_fix() {
        let e = BusError::from_open("vcan0", io::Error::from_raw_os_error(19));
        let msg = e.to_string();
        assert!(msg.contains("ENODEV"), "{msg}");
        assert!(
            msg.contains(
                "sudo modprobe vcan && sudo ip link add dev vcan0 type vcan && sudo ip link set up vcan0"
            ),
            "{msg}"
        );
        let e = BusError::from_open("can0", io::Error::from_raw_os_error(97));
        let msg = e.to_string();
        assert!(msg.contains("lacks CAN support"), "{msg}");
        assert!(msg.contains(VCAN_HOWTO), "{msg}");
        assert!(matches!(
            BusError::from_open("x", io::Error::from_raw_os_error(1)),
            BusError::Io { .. }
        ));
    }

    /// Our decoder agrees with socketcan's on every single class bit and the detail bytes.
    #[cfg(all(target_os = "linux", feature = "socketcan"))]
    #[test]
    fn agrees_with_socketcan_decoder() {
        use socketcan::CanErrorFrame;
        let data = [7u8, ctrl::TX_PASSIVE, prot::FORM, 0x08, 0x04, 0, 200, 10];
        for bit in 0..10 {
            let cls = 1u32 << bit;
            let ours = BusFault::from_raw(cls, &data);
            let theirs = CanErrorFrame::new_error(cls, &data).unwrap().into_error();
            assert_eq!(theirs.is_bus_off(), ours.is_bus_off(), "bit {bit}");
            assert_eq!(theirs.is_no_ack(), ours.causes() == [FaultCause::NoAck]);
            assert_eq!(
                theirs.counters(),
                ours.causes().iter().find_map(|c| match c {
                    FaultCause::Counters { tx, rx } => Some((*tx, *rx)),
                    _ => None,
                })
            );
            assert_eq!(
                theirs.controller().map(|p| p.bits()),
                (cls == class::CRTL).then_some(data[1])
            );
            assert_eq!(
                theirs.lost_arbitration(),
                (cls == class::LOSTARB).then_some(7)
            );
            assert_eq!(embedded_can::Error::kind(&theirs), ours.kind(), "bit {bit}");
        }
    }
}
