//! Bus transports behind one boundary: the `embedded-can` frame trait.
//!
//! * [`ClassicFrame`]: the harness-owned classic frame; implements [`embedded_can::Frame`].
//!   [`convert`] turns any `embedded_can::Frame` into any other.
//! * [`CanBus`]: send, and receive **with a timeout** (lockstep needs it; embedded-can's
//!   blocking `receive` has none). [`Blocking`] adapts any `CanBus` to
//!   `embedded_can::blocking::Can` for code written against that trait.
//! * [`InprocHub`]/[`InprocBus`]: an in-process broadcast bus with bus-load accounting.
//! * [`Impaired`]: any node's receive side with injected losses, delays and jitter.
//! * `SocketCanBus` (Linux, feature `socketcan`): `socketcan::CanSocket` with error frames
//!   decoded into [`BusFault`]s.
//! * [`SlcanBus`]: a node behind a serial line speaking SLCAN (a USB adapter, or the
//!   firmware's QEMU image on a socket).
//! * [`open_bus`]: `"inproc"`/`"mem"` (optionally `":name"`), `"slcan:…"`, or an interface
//!   name.
//!
//! Errors: every operation returns [`BusError`]. A received CAN error frame is returned as
//! `Err(BusError::Fault { .. })` from `recv_timeout` (like `embedded_can::blocking::Can`
//! does), so a node sees it at the place it waits for frames and can call
//! [`BusError::requires_safe_state`].

pub mod bits;
pub mod fault;
pub mod frame;
pub mod impair;
pub mod inproc;
pub mod slcan;
#[cfg(all(target_os = "linux", feature = "socketcan"))]
pub mod socketcan_bus;

use std::time::Duration;

/// Re-export, so users of this module name the same `embedded-can` version.
pub use embedded_can;

#[cfg(all(target_os = "linux", feature = "socketcan"))]
pub use self::socketcan_bus::SocketCanBus;
pub use fault::{BusError, BusFault, Direction, FaultCause, Severity, VCAN_HOWTO};
pub use frame::{convert, ClassicFrame};
pub use impair::{Impaired, LinkClock, LinkFault, LinkStats};
pub use inproc::{BusStats, InprocBus, InprocHub};
pub use slcan::{SlcanBus, SlcanTarget};

/// A node's connection to a CAN bus.
///
/// Semantics shared by every implementation:
/// * `send` queues one frame for transmission; it does not wait for other nodes.
/// * A node does not receive its own frames (SocketCAN's default: `CAN_RAW_LOOPBACK` on,
///   `CAN_RAW_RECV_OWN_MSGS` off — other sockets/nodes see the frame, the sender does not).
/// * `recv_timeout` returns `Ok(None)` when nothing arrived within `timeout`
///   (`Duration::ZERO` polls), `Ok(Some(frame))` for a frame, and
///   `Err(BusError::Fault{..})` for a CAN error frame.
pub trait CanBus: Send {
    /// Transmits one frame.
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError>;

    /// Receives the next frame, waiting at most `timeout`.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError>;

    /// Receives a frame if one is already queued.
    fn try_recv(&mut self) -> Result<Option<ClassicFrame>, BusError> {
        self.recv_timeout(Duration::ZERO)
    }

    /// A human-readable name (interface name, or `inproc:<hub>/<node>`).
    fn name(&self) -> &str;
}

impl<B: CanBus + ?Sized> CanBus for Box<B> {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        (**self).send(frame)
    }
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        (**self).recv_timeout(timeout)
    }
    fn try_recv(&mut self) -> Result<Option<ClassicFrame>, BusError> {
        (**self).try_recv()
    }
    fn name(&self) -> &str {
        (**self).name()
    }
}

/// Sending and receiving any [`embedded_can::Frame`] type over a [`CanBus`].
pub trait CanBusExt: CanBus {
    /// Converts `frame` to a [`ClassicFrame`] and sends it.
    fn send_frame<F: embedded_can::Frame>(&mut self, frame: &F) -> Result<(), BusError> {
        let f: ClassicFrame = convert(frame).ok_or_else(|| BusError::Unrepresentable {
            bus: self.name().to_string(),
            reason: format!(
                "not a classic CAN frame ({} data bytes, dlc {})",
                frame.data().len(),
                frame.dlc()
            ),
        })?;
        self.send(&f)
    }

    /// Receives and converts to `F`. A frame `F` cannot represent is an error.
    fn recv_frame_timeout<F: embedded_can::Frame>(
        &mut self,
        timeout: Duration,
    ) -> Result<Option<F>, BusError> {
        match self.recv_timeout(timeout)? {
            None => Ok(None),
            Some(f) => convert(&f)
                .map(Some)
                .ok_or_else(|| BusError::Unrepresentable {
                    bus: self.name().to_string(),
                    reason: format!("received {f} does not fit the target frame type"),
                }),
        }
    }
}

impl<B: CanBus + ?Sized> CanBusExt for B {}

/// Adapts a [`CanBus`] to [`embedded_can::blocking::Can`] (blocking receive, no timeout).
#[derive(Debug)]
pub struct Blocking<B>(pub B);

impl<B: CanBus> embedded_can::blocking::Can for Blocking<B> {
    type Frame = ClassicFrame;
    type Error = BusError;

    fn transmit(&mut self, frame: &Self::Frame) -> Result<(), Self::Error> {
        self.0.send(frame)
    }

    fn receive(&mut self) -> Result<Self::Frame, Self::Error> {
        loop {
            if let Some(f) = self.0.recv_timeout(Duration::from_secs(3600))? {
                return Ok(f);
            }
        }
    }
}

/// Which transport a bus spec names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BusSpec {
    /// The process-wide in-process hub of this name (`"inproc"` → `"default"`).
    Inproc(String),
    /// A SocketCAN network interface (`vcan0`, `can0`, …).
    SocketCan(String),
    /// An SLCAN line (`slcan:/dev/ttyACM0`, `slcan:unix:PATH`, `slcan:tcp:HOST:PORT`).
    Slcan(SlcanTarget),
}

impl BusSpec {
    /// Parses `inproc`, `mem`, `inproc:NAME`, `mem:NAME`, `slcan:…`, or a Linux interface
    /// name.
    pub fn parse(spec: &str) -> Result<Self, BusError> {
        let bad = |reason: &str| BusError::BadSpec {
            spec: spec.to_string(),
            reason: reason.to_string(),
        };
        let s = spec.trim();
        for prefix in ["inproc", "mem"] {
            if s == prefix {
                return Ok(BusSpec::Inproc("default".into()));
            }
            if let Some(name) = s.strip_prefix(prefix).and_then(|r| r.strip_prefix(':')) {
                if name.is_empty() {
                    return Err(bad("empty in-process hub name after ':'"));
                }
                return Ok(BusSpec::Inproc(name.to_string()));
            }
        }
        if let Some(rest) = s.strip_prefix("slcan:") {
            return SlcanTarget::parse(rest)
                .map(BusSpec::Slcan)
                .map_err(|r| bad(&r));
        }
        if s.is_empty() {
            return Err(bad(
                "empty; use `inproc` or an interface name such as vcan0",
            ));
        }
        if s.len() > 15 {
            return Err(bad("interface names are at most 15 bytes (IFNAMSIZ - 1)"));
        }
        if s.bytes()
            .any(|b| b == b'/' || b == b':' || b.is_ascii_whitespace() || !b.is_ascii_graphic())
        {
            return Err(bad(
                "not an interface name (no '/', ':', spaces or control characters); \
                 use `inproc`, `inproc:NAME`, `mem`, `slcan:/dev/ttyACM0` or an interface \
                 such as vcan0/can0",
            ));
        }
        Ok(BusSpec::SocketCan(s.to_string()))
    }
}

/// Opens a bus by spec: `"inproc"`/`"mem"` (optionally `":NAME"`) attaches a new node to the
/// process-wide in-process hub of that name (so card, plant and supervisor threads that each
/// call `open_bus("inproc")` share one bus); `"slcan:…"` opens an SLCAN line; anything else
/// is a SocketCAN interface name.
pub fn open_bus(spec: &str) -> Result<Box<dyn CanBus>, BusError> {
    match BusSpec::parse(spec)? {
        BusSpec::Inproc(name) => Ok(Box::new(InprocHub::named(&name).attach(spec.trim()))),
        #[cfg(all(target_os = "linux", feature = "socketcan"))]
        BusSpec::SocketCan(iface) => Ok(Box::new(SocketCanBus::open(&iface)?)),
        #[cfg(all(target_os = "linux", not(feature = "socketcan")))]
        BusSpec::SocketCan(iface) => Err(BusError::SocketCanNotBuilt { iface }),
        #[cfg(not(target_os = "linux"))]
        BusSpec::SocketCan(iface) => Err(BusError::NoCanSupport { iface }),
        BusSpec::Slcan(t) => Ok(Box::new(SlcanBus::open(&t)?)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_parsing() {
        assert_eq!(
            BusSpec::parse("inproc").unwrap(),
            BusSpec::Inproc("default".into())
        );
        assert_eq!(
            BusSpec::parse("mem:lab").unwrap(),
            BusSpec::Inproc("lab".into())
        );
        assert_eq!(
            BusSpec::parse("vcan0").unwrap(),
            BusSpec::SocketCan("vcan0".into())
        );
        assert!(BusSpec::parse("").is_err());
        assert!(BusSpec::parse("inproc:").is_err());
        assert!(BusSpec::parse("a/b").is_err());
        assert!(BusSpec::parse("udp:1.2.3.4").is_err());
        assert_eq!(
            BusSpec::parse("slcan:/dev/ttyACM0").unwrap(),
            BusSpec::Slcan(SlcanTarget::Device {
                path: "/dev/ttyACM0".into(),
                bitrate: 1_000_000
            })
        );
        let e = BusSpec::parse("slcan:/dev/ttyACM0,7")
            .unwrap_err()
            .to_string();
        assert!(e.contains("bit rate 7"), "{e}");
        let e = BusSpec::parse("abcdefghijklmnop").unwrap_err().to_string();
        assert!(e.contains("15 bytes"), "{e}");
    }

    #[test]
    fn open_bus_inproc_shares_named_hub() {
        let mut a = open_bus("inproc:spec-test").unwrap();
        let mut b = open_bus("inproc:spec-test").unwrap();
        let mut other = open_bus("inproc:spec-test-2").unwrap();
        let f = ClassicFrame::std(0x10, &[1]).unwrap();
        a.send(&f).unwrap();
        assert_eq!(b.recv_timeout(Duration::from_secs(1)).unwrap(), Some(f));
        assert_eq!(other.try_recv().unwrap(), None);
        assert_eq!(a.try_recv().unwrap(), None, "no self-echo");
    }

    #[test]
    fn blocking_adapter_and_generic_frames() {
        use embedded_can::blocking::Can;
        let hub = InprocHub::new("blocking");
        let mut a = Blocking(hub.attach("a"));
        let mut b = Blocking(hub.attach("b"));
        let f = ClassicFrame::ext(0x1234, &[9, 8]).unwrap();
        a.transmit(&f).unwrap();
        assert_eq!(b.receive().unwrap(), f);
        a.0.send_frame(&f).unwrap();
        let g: Option<ClassicFrame> = b.0.recv_frame_timeout(Duration::from_secs(1)).unwrap();
        assert_eq!(g, Some(f));
    }
}
