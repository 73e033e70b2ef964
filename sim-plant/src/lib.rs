//! # sim-plant: the motor, transmission and load the card drives
//!
//! Physics of a geared robot joint (Schempf 1990 §3): a rigid single inertia, the 2-mass plant
//! (motor inertia I1 | transmission of ratio N, stiffness KT | output inertia I2) and the 3-mass
//! variant of Eqn 3.3.26; the environment the output touches; sensors as the card sees them;
//! and a library of physical effects — one module per effect — shared by the simulator, the
//! fitter and the diagnosis.
//!
//! ## Using it
//! ```
//! use sim_plant::{preset, Environment, Model, Plant, PlantOptions};
//!
//! // A preset (the thesis's transmissions, `preset_names()`), or a model file:
//! let model: Model = preset("harmonic-drive-60").unwrap();
//! let same = Model::from_toml_str(&model.to_toml_string(), "hd.toml").unwrap();
//! assert_eq!(same, model);
//!
//! let mut plant = Plant::new(&model, PlantOptions { seed: 7, ..Default::default() }).unwrap();
//! for _ in 0..100 {
//!     // What the HIL plant node does at 1 kHz: motor torque (N·m at the motor) in,
//!     // sensors out (raw wrapping encoder counts, torque sensor, motor velocity).
//!     let s = plant.step(0.5, 1e-3);
//!     let _ = (s.motor_counts, s.torque, s.motor_velocity);
//! }
//! let truth = plant.state(); // angles, velocities, torques, stick flag — for recordings
//! assert!(truth.time > 0.099);
//! plant.set_environment(Environment::Locked).unwrap(); // or Crank, Spring, Wall, Torque
//! ```
//!
//! ## Conventions
//! * SI units, **referred to the output shaft** (the thesis's Tables 4.1/4.2 convention):
//!   effect parameters, output inertia, stiffness are output-side; only `[motor]` (inertia,
//!   damping, torque limit, encoder) is at the motor shaft. Sensors report motor-side counts.
//! * Effects are resisting torques: `J·a = input − Σ R`, so a model missing an effect leaves
//!   `R` in the inverse-dynamics residual `input − model_input`, and the effect's
//!   [`fingerprint`] columns are a basis of `R` (tests/fingerprints.rs pins this).
//! * Deterministic: same model, options, seed and inputs → bit-identical outputs.
//!
//! ## Map
//! * [`effects`] — `EffectKind`, `Trajectory`, `Shape`, `fingerprint`, `shape_grid`, one module
//!   per effect with its parameters, dynamics contribution and fingerprint, registered once;
//! * [`model`] — model files (TOML): parse with file:line:col errors, write, round-trip;
//! * [`plant`] — the integrator (Störmer–Verlet with a proper stick state), environments,
//!   sensors, true state;
//! * [`presets`] — the thesis's transmissions from `presets/transmissions.toml`;
//! * [`experiments`] — the thesis's stiffness and backdrive tests, simulated;
//! * [`lstsq`] — the workspace's one linear least-squares solver;
//! * [`param`], [`units`], [`fastmath`] — parameters with specs, unit spellings, sin/cos.

pub mod effects;
pub mod experiments;
pub mod fastmath;
pub mod lstsq;
pub mod model;
pub mod param;
pub mod plant;
pub mod presets;
pub mod units;

pub use effects::{fingerprint, shape_grid, EffectKind, EffectSet, Shape, Trajectory};
pub use model::{Model, ModelError, PlantKind};
pub use param::{Param, ParamSpec, Role};
pub use plant::{Environment, Plant, PlantError, PlantOptions, Sensors, TrueState};
pub use presets::{preset, preset_names, preset_toml};
