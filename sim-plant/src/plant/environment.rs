//! What the output shaft touches (thesis §2 "Kf", Ch. 4/5 test set-ups).

use serde::{Deserialize, Serialize};

/// The environment at the output. Set with [`crate::plant::Plant::set_environment`]; can be
/// changed between steps (e.g. crank speed sweeps).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Environment {
    /// Nothing attached.
    Free,
    /// Torque sensor + surface: τ_env = −Kf·(q − rest) − Df·q̇ (thesis τenv = Kf·x2; Kf ≈ 15×
    /// the stiffest transmission in Ch. 3).
    Spring {
        /// Kf (N·m/rad).
        stiffness: f64,
        /// Df (N·m·s/rad).
        #[serde(default)]
        damping: f64,
        /// Output angle at which the spring is relaxed (rad).
        #[serde(default)]
        rest: f64,
    },
    /// One-sided wall at `position`: pushes back only when penetrated from `side` (+1: the
    /// output moving positive hits it; −1: negative) and never pulls.
    Wall {
        /// Wall position (rad).
        position: f64,
        /// Contact stiffness (N·m/rad).
        stiffness: f64,
        /// Contact damping (N·m·s/rad), active only while penetrating.
        #[serde(default)]
        damping: f64,
        /// +1 or −1.
        side: f64,
    },
    /// A hand or weight applying a torque to the output (N·m, positive = positive direction).
    Torque {
        /// Applied torque (N·m).
        torque: f64,
    },
    /// Output clamped at its current angle (stiffness tests: output locked, input torqued).
    Locked,
    /// Hand crank driving the output at a prescribed speed (backdrive / damper tests).
    Crank {
        /// Output speed (rad/s).
        speed: f64,
    },
}

impl Environment {
    /// Torque the environment applies to the output at angle `q`, velocity `v` (force-type
    /// environments; 0 for kinematic ones).
    #[inline(always)]
    pub fn torque(&self, q: f64, v: f64) -> f64 {
        match *self {
            Environment::Free | Environment::Locked | Environment::Crank { .. } => 0.0,
            Environment::Spring {
                stiffness,
                damping,
                rest,
            } => -stiffness * (q - rest) - damping * v,
            Environment::Wall {
                position,
                stiffness,
                damping,
                side,
            } => {
                let pen = side * (q - position);
                if pen > 0.0 {
                    -side * (stiffness * pen + damping * side * v).max(0.0)
                } else {
                    0.0
                }
            }
            Environment::Torque { torque } => torque,
        }
    }

    /// Prescribed output velocity for kinematic environments.
    #[inline(always)]
    pub fn prescribed_velocity(&self) -> Option<f64> {
        match *self {
            Environment::Locked => Some(0.0),
            Environment::Crank { speed } => Some(speed),
            _ => None,
        }
    }

    /// Largest stiffness and damping the environment adds (for the step-size check).
    pub fn stiffness_damping(&self) -> (f64, f64) {
        match *self {
            Environment::Spring {
                stiffness, damping, ..
            }
            | Environment::Wall {
                stiffness, damping, ..
            } => (stiffness, damping),
            _ => (0.0, 0.0),
        }
    }

    /// Potential energy stored in the environment at output angle `q` (J).
    pub fn potential(&self, q: f64) -> f64 {
        match *self {
            Environment::Spring {
                stiffness, rest, ..
            } => 0.5 * stiffness * (q - rest) * (q - rest),
            Environment::Wall {
                position,
                stiffness,
                side,
                ..
            } => {
                let pen = (side * (q - position)).max(0.0);
                0.5 * stiffness * pen * pen
            }
            _ => 0.0,
        }
    }
}
