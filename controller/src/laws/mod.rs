//! Control laws of the motor card (notes §2), discretised by backward difference at the card
//! period T (1 ms): `ẋ ≈ (x_k − x_{k−1})/T`, `∫e ≈ Σ T·e_k` — the thesis's choice, "superior to
//! Tustin's mapping, especially in terms of complexity" for an integer card (notes §1).
//!
//! idsp style: every law has a `…Config` (gains and limits, set by the supervisor through
//! `units` and committed atomically by the card runtime) separate from its state, and a
//! `step` taking the measured quantities as arguments. Units (see `fixed_math`): positions in
//! counts, velocities in Q28.4 counts/s, torques in 0.1 mN·m. Every step returns the torque
//! with [`Flags`](crate::fixed_math::Flags) telling whether anything saturated.
//!
//! The runtime normally uses [`joint::JointState`] with a [`joint::JointConfig`]; the single
//! laws are public so they can be tested, benchmarked and composed differently.
#![deny(clippy::float_arithmetic)]

pub mod damping;
pub mod force;
pub mod friction;
pub mod impcomp;
pub mod impedance;
pub mod joint;
pub mod pid;
pub mod position;
pub mod ripple;

pub use damping::{DamperConfig, DamperLaw, InputDamping};
pub use force::{ForceConfig, ForceDamping, ForceLaw};
pub use friction::{FrictionComp, FrictionConfig, DEFAULT_UNDERCOMP};
pub use impcomp::{ImpComp, ImpCompConfig};
pub use impedance::{ImpedanceConfig, ImpedanceLaw};
pub use joint::{JointConfig, JointOutput, JointState, Measurements, Mode, ModeKind, Setpoint};
pub use pid::{PidConfig, PidState};
pub use position::{Feedback, PositionConfig, PositionLaw};
pub use ripple::{RippleError, RippleTable, RIPPLE_MAX};
