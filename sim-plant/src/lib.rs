//! # sim-plant: the motor, transmission and load the card drives
//!
//! Physics of a geared robot joint (Schempf 1990 §3): a 2-mass plant (motor inertia I1 | a
//! transmission of ratio N and stiffness KT | output inertia I2) and a 3-mass variant, the
//! environment the output touches, sensors as the card sees them, and a library of physical
//! effects — one module per effect — shared by the simulator, the fitter and the diagnosis.

pub mod effects;
