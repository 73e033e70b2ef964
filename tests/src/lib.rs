//! End-to-end tests across crates live in `tests/tests/`; shared fixtures live here.

pub mod hidden;
