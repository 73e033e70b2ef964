//! The drawn plant and the hidden effects put into it.
//!
//! The plant (inertias, drag, controller gains, noise level) is a function of the seed alone; the
//! effect parameters that are not the amplitude (phases, periods, stiffnesses) of the seed and
//! the family. So the Estimation and Validation records of a seed share one joint, and the null
//! and effect versions of a seed differ only by the effect.

use super::joint::{Coupling, Joint};
use super::rng::stream;
use super::torques::DryFriction;
use crate::hidden::record::Family;
use std::f64::consts::TAU;

/// Travel (rad) around which the ripple period is drawn; the excitations span 1.5–2.5 rad.
pub const NOMINAL_TRAVEL: f64 = 2.0;
/// Longest transport delay the actuator model accepts, s.
pub const MAX_DELAY: f64 = 6e-3;
/// A shaft mode above this (Hz) is treated as rigid: its effect below 100 Hz is < 4·10⁻⁴.
pub const RIGID_ABOVE_HZ: f64 = 5000.0;

/// The seed's plant and controller, before any hidden effect.
#[derive(Debug, Clone, Copy)]
pub struct Plant {
    /// The joint with no effect: rigid body with viscous drag.
    pub joint: Joint,
    /// Loop bandwidth of the position controller, Hz.
    pub loop_hz: f64,
    /// Damping ratio of the PD design.
    pub loop_zeta: f64,
    /// Integral corner as a fraction of the loop bandwidth (PID only).
    pub integral_ratio: f64,
    /// Input-noise σ as a fraction of the RMS command, at noise multiplier 1.
    pub noise_fraction: f64,
    /// Sensor noise before quantisation, in encoder counts (σ).
    pub sensor_counts: f64,
}

/// Effect parameters that are drawn rather than set by the amplitude.
#[derive(Debug, Clone, Copy)]
pub struct EffectDraws {
    pub offset_sign: f64,
    /// Coulomb level of the Stribeck truth as a fraction of the plant's torque scale.
    pub stribeck_coulomb_fraction: f64,
    pub stribeck_velocity: f64,
    pub backlash_hz: f64,
    pub backlash_zeta: f64,
    pub shaft_zeta: f64,
    /// Ripple periods per `NOMINAL_TRAVEL`.
    pub ripple_cycles: f64,
    pub ripple_phase: f64,
    pub gravity_phase: f64,
}

/// The actuator path: command → D/A → transport delay → (+ disturbance) → motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuator {
    /// D/A step, N·m (0 = ideal converter).
    pub dac_step: f64,
    /// Transport delay on top of the hold, s.
    pub delay: f64,
    /// Whether the input noise is a torque disturbance after the D/A (else it is on the log).
    pub noise_after_dac: bool,
}

impl Actuator {
    pub const IDEAL: Actuator = Actuator {
        dac_step: 0.0,
        delay: 0.0,
        noise_after_dac: false,
    };
}

/// A torque scale of the plant alone: the torque that gives 30 rad/s², about the RMS
/// acceleration of the excitations.
pub fn torque_scale(joint: &Joint) -> f64 {
    30.0 * joint.total_inertia()
}

/// Draw the plant of a seed.
pub fn draw_plant(seed: u64) -> Plant {
    let mut d = stream(seed, "plant", 0);
    let j = d.log_uniform(1e-3, 3e-2);
    let load_share = d.uniform(0.3, 0.7);
    let time_constant = d.log_uniform(0.3, 3.0); // J/B: the drag spans a decade
    let b = j / time_constant;
    let drag_share = d.uniform(0.3, 0.7);
    let loop_hz = d.uniform(2.0, 4.0);
    let loop_zeta = d.uniform(0.7, 1.0);
    let integral_ratio = d.uniform(0.15, 0.25);
    let noise_fraction = d.log_uniform(0.002, 0.01);
    let sensor_counts = d.uniform(0.05, 0.2);
    let joint = Joint {
        j_motor: j * (1.0 - load_share),
        j_load: j * load_share,
        b_motor: b * (1.0 - drag_share),
        b_load: b * drag_share,
        ..Joint::rigid(j, b)
    };
    Plant {
        joint,
        loop_hz,
        loop_zeta,
        integral_ratio,
        noise_fraction,
        sensor_counts,
    }
}

/// Draw the effect parameters of a seed (all families, in a fixed order).
pub fn draw_effects(seed: u64) -> EffectDraws {
    let mut d = stream(seed, "effects", 0);
    EffectDraws {
        offset_sign: d.sign(),
        stribeck_coulomb_fraction: d.uniform(0.03, 0.1),
        stribeck_velocity: d.log_uniform(0.03, 0.3),
        backlash_hz: d.uniform(40.0, 60.0),
        backlash_zeta: d.uniform(0.05, 0.15),
        shaft_zeta: d.uniform(0.02, 0.1),
        ripple_cycles: d.log_uniform(5.0, 18.0),
        ripple_phase: d.uniform(0.0, TAU),
        gravity_phase: d.uniform(0.0, TAU),
    }
}

/// Shaft mode frequency of the Compliance family at amplitude `a` (∞ at a = 0).
pub fn compliance_hz(a: f64) -> f64 {
    if a > 0.0 {
        (60.0 / a.sqrt()).max(6.0)
    } else {
        f64::INFINITY
    }
}

/// Put the hidden effects (family, amplitude) into the plant.
pub fn with_effects(
    plant: &Plant,
    fx: &EffectDraws,
    effects: &[(Family, f64)],
) -> (Joint, Actuator) {
    let mut joint = plant.joint;
    let mut act = Actuator::IDEAL;
    for &(family, a) in effects {
        with_effect(&mut joint, &mut act, fx, family, a);
    }
    (joint, act)
}

/// Put the hidden effect of `family` at amplitude `a` into `joint` and `act`.
fn with_effect(joint: &mut Joint, act: &mut Actuator, fx: &EffectDraws, family: Family, a: f64) {
    let stiffness_for = |hz: f64, jr: f64| (TAU * hz).powi(2) * jr;
    match family {
        Family::Offset => joint.bias = fx.offset_sign * a,
        Family::Coulomb => {
            joint.friction = DryFriction {
                coulomb: a,
                breakaway: a,
                stribeck_velocity: 1.0,
            }
        }
        Family::Asymmetry => joint.b_positive = a,
        Family::Stribeck => {
            let coulomb = fx.stribeck_coulomb_fraction * torque_scale(joint);
            joint.friction = DryFriction {
                coulomb,
                breakaway: coulomb + a,
                stribeck_velocity: fx.stribeck_velocity,
            };
        }
        Family::Backlash => {
            if a > 0.0 {
                let jr = joint.reduced_inertia();
                let w = TAU * fx.backlash_hz;
                joint.coupling = Coupling::Backlash {
                    gap: a,
                    stiffness: stiffness_for(fx.backlash_hz, jr),
                    damping: 2.0 * fx.backlash_zeta * w * jr,
                };
            }
        }
        Family::Compliance => {
            let hz = compliance_hz(a);
            if hz <= RIGID_ABOVE_HZ {
                let jr = joint.reduced_inertia();
                joint.coupling = Coupling::Shaft {
                    stiffness: stiffness_for(hz, jr),
                    damping: 2.0 * fx.shaft_zeta * TAU * hz * jr,
                };
            }
        }
        Family::Ripple => {
            joint.ripple = (a, NOMINAL_TRAVEL / fx.ripple_cycles, fx.ripple_phase);
        }
        Family::Gravity => joint.gravity = (a, fx.gravity_phase),
        Family::Delay => act.delay = a.min(MAX_DELAY),
        Family::Quantization => {
            act.dac_step = a;
            act.noise_after_dac = true;
        }
    }
}
