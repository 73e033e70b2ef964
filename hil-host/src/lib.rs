//! # hil-host: the std side of jointlab
//!
//! Bus transports (SocketCAN and an in-process bus, both behind `embedded-can`), the card node
//! (runs the `controller` card on the PC), the plant node (runs a `sim-plant` model), the
//! supervisor, recordings, and the command line, whose `compare`/`diagnose`/`fit` call the
//! model-vs-measurement workbench (`jointlab-workbench`).

pub mod bus;
pub mod candump;
pub mod cli;
pub mod lab;
