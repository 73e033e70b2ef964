//! # jointlab-can: the CAN side of jointlab
//!
//! The bus transports (in-process, SocketCAN, SLCAN), link impairment and error frames, and
//! the candump `-L` log reader/writer, with no lab, CLI or workbench attached. The lab in
//! `hil-host`, the end-to-end tests and the firmware's replay tests all talk through these
//! types; keeping them in their own crate lets a consumer that needs only the wire (a
//! fuzzer of the log reader, a small tool) build them without hil-host's plotting, CLI and
//! fitting dependencies. The `socketcan` feature (on by default, Linux only) adds the
//! SocketCAN transport.

pub mod bus;
pub mod candump;
pub mod signals;
