//! # hil-host: the std side of jointlab
//!
//! The card node (runs the `controller` card on the PC), the plant node (runs a `sim-plant`
//! model), the supervisor, recordings, and the command line, whose `compare`/`diagnose`/`fit`
//! call the model-vs-measurement workbench (`jointlab-workbench`). The bus transports and
//! candump logs they use live in `jointlab-can`.

pub mod cli;
pub mod lab;
