//! # jointlab motor card
//!
//! The joint servo that runs at 1 kHz on a motor-controller card (the SEIBERCO card of
//! Schempf 1990, here a Cortex-M or a PC thread in the HIL lab). Everything in this crate is
//! `#![no_std]`, allocation-free and panic-free: integer / fixed-point arithmetic with
//! saturation flags, bounded loops, and no floats in the 1 kHz path (`units` converts SI gains
//! to machine gains at configuration time, where `micromath` float math is acceptable).
//!
//! Data flow through the modules:
//!
//! ```text
//! CAN frame ─► proto (frame ↔ typed message) ─► card (state machine, staged config,
//!              watchdogs) ─► sensing (velocity estimate) ─► laws (PD/PID/force/impedance
//!              + compensations) ─► card limits ─► actuator command ─► proto ─► CAN frame
//!                                                                   └► power_stage (PWM)
//! ```
//!
//! The card is sans-IO: it never reads a clock or a bus. The host (`hil-host`) or a firmware
//! crate feeds it time, sensor values and received frames, and sends what it returns.
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

pub mod card;
pub mod fixed_math;
pub mod laws;
pub mod power_stage;
pub mod proto;
pub mod sensing;
pub mod slcan;
pub mod units;
