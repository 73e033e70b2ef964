//! # jointlab firmware
//!
//! The `controller` card on a microcontroller. Three binaries share one card loop
//! ([`controller::card::node::CardNode`]):
//!
//! * `firmware` — the NUCLEO-G474RE board: FDCAN1 at 1 Mbit/s, the 1 kHz tick from a basic
//!   timer's interrupt, quadrature encoders on timers, torque out through
//!   [`controller::power_stage`] to a PWM + direction current-mode amplifier, defmt over RTT.
//! * `qemu-card` — the same card loop under QEMU (mps2-an386 Cortex-M4F, microbit
//!   Cortex-M0): it reads received frames from a [`stream`] file through semihosting and
//!   writes the frames the card sends, so a host recording can be replayed bit for bit.
//! * `qemu-bench` — instruction counts per step of every law, the full pipeline, one card
//!   tick and one configuration build ([`mod@bench`]), measured with SysTick under
//!   `-icount shift=0`.
//!
//! On the host the binaries are stubs and only this library builds: the stream format, the
//! benchmark set-ups, and ([`host`]) the helpers that build the images and run QEMU for the
//! tests and the instruction-count bench.
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::arithmetic_side_effects
    )
)]

#[cfg(not(target_os = "none"))]
extern crate std;

// Links cortex-m's single-core critical-section implementation into every image.
#[cfg(target_os = "none")]
use cortex_m as _;

pub mod bench;
#[cfg(not(target_os = "none"))]
pub mod host;
#[cfg(all(target_os = "none", feature = "qemu"))]
pub mod semihosting;
pub mod stream;
#[cfg(all(target_os = "none", feature = "qemu"))]
pub mod uart;
