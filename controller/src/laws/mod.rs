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
//!
//! # How the card runtime drives it
//!
//! ```
//! use controller::laws::{Feedback, JointConfig, JointState, Measurements, Mode, Setpoint};
//! use controller::sensing::{TrackingObserver, Unwrapper};
//! use controller::units::{self, PositionSi, Scale};
//!
//! // configuration time (supervisor side or card commit): SI → machine gains, guard
//! let scale = Scale::thesis(30.0);
//! let si = PositionSi { ke: 0.4, be: 0.009, ki: 0.0, i_limit_nm: 0.0, tau_max_nm: 2.0,
//!                       feedback: Feedback::Colocated };
//! units::pd_stability(si.ke, si.be, 1e-4, scale.period_s, units::DEFAULT_MARGIN).unwrap();
//! let cfg = JointConfig { mode: Mode::Position(units::position_config(&scale, &si).unwrap()),
//!                         tau_max: 20000, ..JointConfig::default() };
//! let obs_cfg = units::observer_config(&scale, 30.0, 1.0, 2000).unwrap();
//!
//! // 1 kHz: raw counts → multi-turn → velocity → law → i16 command
//! let (mut unwrap, mut obs, mut st) = (Unwrapper::new(), TrackingObserver::new(), JointState::new());
//! let x1 = unwrap.update(0xFFFF_FFF0);           // raw 32-bit counter
//! let (v1, _flags) = obs.step(&obs_cfg, x1);
//! let m = Measurements { x1, v1, ..Measurements::default() };
//! let sp = Setpoint { x_d: 100, ..Setpoint::default() };
//! let out = st.step(&cfg, &sp, &m);
//! let cmd: i16 = out.command();
//! assert!(cmd > 0 && out.out.flags.is_empty());
//!
//! // a committed gain set or a mode switch: bumpless
//! let new_cfg = JointConfig { transfer_shift: 7, ..cfg.clone() };
//! st.init_bumpless(&new_cfg, out.out.tau, &sp, &m);
//! assert_eq!(st.step(&new_cfg, &sp, &m).out.tau, out.out.tau);
//! ```
#![deny(clippy::float_arithmetic)]

pub mod damping;
pub mod force;
pub mod friction;
pub mod gravity;
pub mod impcomp;
pub mod impedance;
pub mod joint;
pub mod pid;
pub mod position;
pub mod ripple;
pub mod velocity;

pub use damping::{DamperConfig, DamperLaw, InputDamping};
pub use force::{ForceConfig, ForceDamping, ForceLaw};
pub use friction::{FrictionComp, FrictionConfig, DEFAULT_UNDERCOMP};
pub use gravity::Gravity;
pub use impcomp::{ImpComp, ImpCompConfig};
pub use impedance::{ImpedanceConfig, ImpedanceLaw};
pub use joint::{JointConfig, JointOutput, JointState, Measurements, Mode, ModeKind, Setpoint};
pub use pid::{PidConfig, PidState};
pub use position::{Feedback, PositionConfig, PositionLaw};
pub use ripple::{RippleError, RippleTable, RIPPLE_MAX};
pub use velocity::{VelocityConfig, VelocityLaw};
