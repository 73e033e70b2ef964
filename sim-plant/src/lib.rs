//! # sim-plant: the motor, transmission and load the card drives
//!
//! Physics of a geared robot joint (Schempf 1990 §3): a 2-mass plant (motor inertia I1 | a
//! transmission of ratio N and stiffness KT | output inertia I2) and a 3-mass variant, the
//! environment the output touches, sensors as the card sees them, and a library of physical
//! effects — one module per effect — shared by the simulator, the fitter and the diagnosis.

pub mod effects;
pub mod fastmath;
pub mod param;
pub mod units;

pub use effects::{fingerprint, shape_grid, EffectKind, EffectSet, Shape, Trajectory};
pub use param::{Param, ParamSpec, Role};
pub mod model;
pub use model::{Model, ModelError, PlantKind};
pub mod plant;
pub use plant::{Environment, Plant, PlantError, PlantOptions, Sensors, TrueState};
pub mod presets;
pub use presets::{preset, preset_names, preset_toml};
pub mod experiments;
