//! Sensing at 1 kHz: multi-turn unwrap of a wrapping encoder count, and velocity estimation.
//!
//! Why an estimator at all (notes §1, \[D\]): differencing a 2304 cpr encoder at 1 kHz gives
//! 2π/2304·1000 = 2.73 rad/s per count — ≈15 000× coarser than the thesis's Sensorimotor
//! velocity (1.8·10⁻⁴ rad/s). The thesis blames coarse velocity for "roughened damped behavior
//! … at high damping gain levels" and motor humming, and its input-velocity damping (§2.4) is
//! only as good as the velocity signal. [`TrackingObserver`] is a 2nd-order integer tracking
//! loop (PLL-style α-β filter) that interpolates between counts; [`BackwardDifference`] is the
//! thesis's plain backward difference, kept because the §2.9 stability guard is derived for it.
#![deny(clippy::float_arithmetic)]

mod unwrap;
mod velocity;

pub use unwrap::Unwrapper;
pub use velocity::{BackwardDifference, ObserverConfig, ObserverState, TrackingObserver};
