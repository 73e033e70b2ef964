//! SocketCAN transport (Linux): a raw `CAN_RAW` socket bound to one interface.
//!
//! * Opens by interface name (`vcan0`, `can0`). ENODEV (19) and EAFNOSUPPORT (97) become
//!   [`BusError::NoSuchInterface`]/[`BusError::NoCanSupport`], whose messages give the exact
//!   commands to create `vcan0`.
//! * Error frames are enabled on open (`CAN_RAW_ERR_FILTER` = all classes) and every
//!   received error frame is returned as `Err(BusError::Fault { .. })` with the decoded
//!   [`BusFault`] (bus-off, error-passive, controller problems, missing ACK, …).
//! * Receive with timeout uses `SO_RCVTIMEO` (`set_read_timeout`, only re-set when the
//!   timeout changes); `EAGAIN`/`EWOULDBLOCK`/`ETIMEDOUT` map to `Ok(None)`. A zero timeout
//!   polls (`poll(2)` with 0 ms) because `SO_RCVTIMEO = 0` would mean "block forever".
//! * Loopback semantics are the kernel defaults: other sockets on the host see our frames,
//!   we do not see our own (see [`SocketCanBus::set_recv_own`]).

use std::io;
use std::time::{Duration, Instant};

pub use ::socketcan as sys;
use ::socketcan::{CanFrame, CanSocket, Socket, SocketOptions};

use super::fault::{BusError, BusFault};
use super::frame::{convert, ClassicFrame};
use super::CanBus;

const EINPROGRESS: i32 = 115;
const ENOBUFS: i32 = 105;

/// A node on a SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanBus {
    sock: CanSocket,
    iface: String,
    timeout: Option<Duration>,
}

impl SocketCanBus {
    /// Opens a raw CAN socket on `iface` with all error classes enabled.
    pub fn open(iface: &str) -> Result<Self, BusError> {
        let sock = CanSocket::open(iface).map_err(|e| BusError::from_open(iface, e))?;
        let bus = Self {
            sock,
            iface: iface.to_string(),
            timeout: None,
        };
        bus.sock
            .set_error_filter_accept_all()
            .map_err(|e| bus.io("enable error frames (CAN_RAW_ERR_FILTER)", e))?;
        Ok(bus)
    }

    fn io(&self, op: &'static str, source: io::Error) -> BusError {
        BusError::Io {
            bus: self.iface.clone(),
            op,
            source,
        }
    }

    /// The interface name.
    pub fn iface(&self) -> &str {
        &self.iface
    }

    /// The underlying socket (for options this type does not wrap).
    pub fn socket(&self) -> &CanSocket {
        &self.sock
    }

    /// The error classes this socket receives as error frames (all, after [`open`](Self::open)).
    pub fn error_mask(&self) -> Result<u32, BusError> {
        self.sock
            .error_filter()
            .map_err(|e| self.io("read CAN_RAW_ERR_FILTER", e))
    }

    /// Also receive our own frames (`CAN_RAW_RECV_OWN_MSGS`).
    pub fn set_recv_own(&self, on: bool) -> Result<(), BusError> {
        self.sock
            .set_recv_own_msgs(on)
            .map_err(|e| self.io("set CAN_RAW_RECV_OWN_MSGS", e))
    }

    /// Kernel-side receive filters: a frame is delivered if `frame_id & mask == id & mask`
    /// for any `(id, mask)` pair (SocketCAN `CAN_RAW_FILTER`; IDs are raw `can_id` values,
    /// so add `CAN_EFF_FLAG` 0x80000000 to match 29-bit IDs). Error frames are not affected.
    pub fn set_filters(&self, filters: &[(u32, u32)]) -> Result<(), BusError> {
        let f: Vec<sys::CanFilter> = filters
            .iter()
            .map(|&(id, mask)| sys::CanFilter::new(id, mask))
            .collect();
        self.sock
            .set_filters(&f)
            .map_err(|e| self.io("set CAN_RAW_FILTER", e))
    }

    /// Writes an error frame (fault injection, e.g. on vcan in tests: other sockets with
    /// error frames enabled receive it exactly like a controller-generated one).
    pub fn inject_fault(&self, fault: &BusFault) -> Result<(), BusError> {
        let frame =
            sys::CanErrorFrame::new_error(fault.class_bits(), fault.data()).map_err(|e| {
                BusError::Unrepresentable {
                    bus: self.iface.clone(),
                    reason: e.to_string(),
                }
            })?;
        self.sock
            .write_frame(&CanFrame::Error(frame))
            .map_err(|e| self.io("write error frame", e))
    }

    fn decode(&self, frame: CanFrame) -> Result<ClassicFrame, BusError> {
        match frame {
            CanFrame::Error(ef) => Err(BusError::Fault {
                bus: self.iface.clone(),
                fault: BusFault::from_raw(ef.error_bits(), embedded_can::Frame::data(&ef)),
            }),
            other => convert(&other).ok_or_else(|| BusError::Unrepresentable {
                bus: self.iface.clone(),
                reason: "received frame is not a classic CAN frame".into(),
            }),
        }
    }
}

fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
    ) || e.raw_os_error() == Some(EINPROGRESS)
}

impl CanBus for SocketCanBus {
    fn send(&mut self, frame: &ClassicFrame) -> Result<(), BusError> {
        let f: CanFrame = convert(frame).ok_or_else(|| BusError::Unrepresentable {
            bus: self.iface.clone(),
            reason: format!("{frame} is not a valid classic frame"),
        })?;
        // A real controller's TX queue can be full (ENOBUFS); give it up to 100 ms to drain.
        let give_up = Instant::now() + Duration::from_millis(100);
        loop {
            match self.sock.write_frame(&f) {
                Ok(()) => return Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e)
                    if (e.raw_os_error() == Some(ENOBUFS) || is_timeout(&e))
                        && Instant::now() < give_up =>
                {
                    std::thread::sleep(Duration::from_micros(100));
                }
                Err(e) => return Err(self.io("send", e)),
            }
        }
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<ClassicFrame>, BusError> {
        loop {
            let res = if timeout.is_zero() {
                self.sock.read_frame_timeout(Duration::ZERO)
            } else {
                // SO_RCVTIMEO has microsecond resolution and 0 means "forever".
                let t = timeout.max(Duration::from_micros(1));
                if self.timeout != Some(t) {
                    self.sock
                        .set_read_timeout(t)
                        .map_err(|e| self.io("set SO_RCVTIMEO", e))?;
                    self.timeout = Some(t);
                }
                self.sock.read_frame()
            };
            return match res {
                Ok(frame) => self.decode(frame).map(Some),
                Err(e) if is_timeout(&e) => Ok(None),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => Err(self.io("receive", e)),
            };
        }
    }

    fn name(&self) -> &str {
        &self.iface
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a host without the interface (or without AF_CAN) opening fails with the
    /// how-to message; with vcan0 present it opens. Either way the result is checked.
    #[test]
    fn open_missing_interface_names_the_fix() {
        match SocketCanBus::open("jlabnone0") {
            Err(e @ BusError::NoSuchInterface { .. }) => {
                assert!(e.to_string().contains(super::super::VCAN_HOWTO), "{e}")
            }
            Err(e @ BusError::NoCanSupport { .. }) => {
                assert!(e.to_string().contains("lacks CAN support"), "{e}")
            }
            other => panic!("expected ENODEV/EAFNOSUPPORT mapping, got {other:?}"),
        }
    }
}
