//! One function per physical torque, each a plain formula of the state.
//!
//! Sign convention: every function returns the torque *acting on* the body it is named for,
//! positive in the direction of positive rotation.

use std::f64::consts::TAU;

/// Dry friction of the motor bearing: a breakaway (static) level and a kinetic level that falls
/// from it to the Coulomb level over the Stribeck velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DryFriction {
    /// Kinetic (Coulomb) level at high speed, N·m.
    pub coulomb: f64,
    /// Breakaway level: the largest net torque the contact holds while stuck, N·m (≥ coulomb).
    pub breakaway: f64,
    /// Speed over which the kinetic level decays from breakaway to Coulomb, rad/s.
    pub stribeck_velocity: f64,
}

impl DryFriction {
    /// No dry friction.
    pub const NONE: DryFriction = DryFriction {
        coulomb: 0.0,
        breakaway: 0.0,
        stribeck_velocity: 1.0,
    };

    /// Whether the contact can stick at all.
    pub fn is_active(&self) -> bool {
        self.breakaway > 0.0
    }

    /// Magnitude of the sliding friction at speed `v` (Gaussian Stribeck curve): the hump above
    /// Coulomb is what makes starting harder than sliding.
    pub fn kinetic_level(&self, v: f64) -> f64 {
        let x = v / self.stribeck_velocity;
        self.coulomb + (self.breakaway - self.coulomb) * (-x * x).exp()
    }
}

/// Viscous coefficient seen at velocity `v`: the symmetric part `b` plus, while turning
/// positively, the extra `b_positive` (a direction-dependent seal or gear drag).
pub fn viscous_coefficient(v: f64, b: f64, b_positive: f64) -> f64 {
    if v > 0.0 {
        b + b_positive
    } else {
        b
    }
}

/// Torque of a linear shaft (spring `k`, internal damping `c`) on the load, given the twist
/// `twist = q_motor − q_load` and its rate.
pub fn shaft_torque(twist: f64, twist_rate: f64, k: f64, c: f64) -> f64 {
    k * twist + c * twist_rate
}

/// Torque of a gear mesh with total free play `gap` on the load: nothing inside the gap, a stiff
/// tooth spring `k` past either flank, and contact damping `c` that acts only while the teeth
/// touch. A contact can push but never pull, so the damped force is clipped at zero as the teeth
/// part.
pub fn backlash_torque(twist: f64, twist_rate: f64, gap: f64, k: f64, c: f64) -> f64 {
    let half = 0.5 * gap;
    if twist > half {
        (k * (twist - half) + c * twist_rate).max(0.0)
    } else if twist < -half {
        (k * (twist + half) + c * twist_rate).min(0.0)
    } else {
        0.0
    }
}

/// Position-periodic torque ripple (cogging, gear-mesh ripple) on the load: amplitude `amp`,
/// spatial period `period` rad, phase `phase`.
pub fn ripple_torque(q_load: f64, amp: f64, period: f64, phase: f64) -> f64 {
    if amp == 0.0 {
        return 0.0;
    }
    amp * (TAU * q_load / period + phase).sin()
}

/// Gravity on an unbalanced arm, m·g·l = `mgl`; the arm hangs at rest where q_load + phase = 0.
pub fn gravity_torque(q_load: f64, mgl: f64, phase: f64) -> f64 {
    if mgl == 0.0 {
        return 0.0;
    }
    -mgl * (q_load + phase).sin()
}

/// The D/A converter: the command rounded to the nearest multiple of `step` (0 = ideal).
pub fn dac(u: f64, step: f64) -> f64 {
    if step > 0.0 {
        step * (u / step).round()
    } else {
        u
    }
}

/// A constant torque bias at the motor (current-sensor offset, preload), N·m.
pub fn bias_torque(bias: f64) -> f64 {
    bias
}
