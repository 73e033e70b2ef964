//! CAN wire protocol: typed messages ↔ CAN 2.0A frames. The normative layout is
//! `docs/protocol.md`; golden vectors in `docs/golden-vectors.toml` tie spec, codec and DBC.
