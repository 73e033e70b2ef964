//! The joint: a motor rotor and a load, either welded (rigid) or joined by a shaft or a gear mesh
//! with free play, and the velocity-Verlet step that moves them.
//!
//! Why velocity Verlet ("kick–drift–kick"): for a torque held constant over a sub-step it moves a
//! free body *exactly* (no first-order position lag as in symplectic Euler), and for the shaft
//! mode it is symplectic and second order, so the mode neither gains nor loses energy
//! numerically. The dissipative torques (viscous drag, dry friction) are not forces of a
//! potential; they enter each half kick implicitly, which keeps drag unconditionally stable and
//! lets the dry-friction kick land exactly on zero velocity when the contact sticks.

use super::torques::{
    backlash_torque, bias_torque, gravity_torque, ripple_torque, shaft_torque, viscous_coefficient,
    DryFriction,
};
use std::f64::consts::TAU;

/// Smallest half-width of the Karnopp stick band, rad/s.
const MIN_STICK_BAND: f64 = 1e-5;

/// What connects the motor rotor to the load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Coupling {
    /// One body: the load turns with the motor.
    Rigid,
    /// A lightly damped elastic shaft.
    Shaft { stiffness: f64, damping: f64 },
    /// A gear mesh with total free play `gap`, tooth stiffness and contact damping.
    Backlash {
        gap: f64,
        stiffness: f64,
        damping: f64,
    },
}

/// Everything that makes torque in the joint. Friction acts at the motor (the bearing the drive
/// sees); ripple and gravity act at the load (they follow the load's position).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Rotor inertia J1, kg·m².
    pub j_motor: f64,
    /// Load inertia J2, kg·m².
    pub j_load: f64,
    /// Viscous drag on the motor side, N·m·s/rad.
    pub b_motor: f64,
    /// Viscous drag on the load side, N·m·s/rad.
    pub b_load: f64,
    /// Extra viscous drag while the motor turns positively, N·m·s/rad.
    pub b_positive: f64,
    /// Dry friction at the motor.
    pub friction: DryFriction,
    /// Constant torque bias at the motor, N·m.
    pub bias: f64,
    /// The transmission.
    pub coupling: Coupling,
    /// Ripple amplitude (N·m), spatial period (rad) and phase.
    pub ripple: (f64, f64, f64),
    /// Gravity m·g·l (N·m) and phase.
    pub gravity: (f64, f64),
}

/// Positions (rad) and velocities (rad/s) of the two bodies.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct State {
    pub q_motor: f64,
    pub v_motor: f64,
    pub q_load: f64,
    pub v_load: f64,
}

impl Joint {
    /// A rigid, frictionless body of inertia `j` with viscous drag `b` (all on the motor).
    pub fn rigid(j: f64, b: f64) -> Joint {
        Joint {
            j_motor: j,
            j_load: 0.0,
            b_motor: b,
            b_load: 0.0,
            b_positive: 0.0,
            friction: DryFriction::NONE,
            bias: 0.0,
            coupling: Coupling::Rigid,
            ripple: (0.0, 1.0, 0.0),
            gravity: (0.0, 0.0),
        }
    }

    /// J1 + J2: the inertia of the rigid limit.
    pub fn total_inertia(&self) -> f64 {
        self.j_motor + self.j_load
    }

    /// Two-body reduced inertia J1·J2/(J1+J2): the inertia that swings in the shaft mode.
    pub fn reduced_inertia(&self) -> f64 {
        self.j_motor * self.j_load / self.total_inertia()
    }

    /// Frequency (Hz) of the fastest motion the integrator must resolve: the free-free shaft
    /// (or tooth-contact) mode, or the small-oscillation frequency of the load-side potentials.
    pub fn fastest_mode_hz(&self) -> f64 {
        let j = self.total_inertia();
        let (ra, rp, _) = self.ripple;
        let potential = (ra.abs() * TAU / rp + self.gravity.0.abs()) / j;
        let mut w = potential.sqrt();
        match self.coupling {
            Coupling::Rigid => {}
            Coupling::Shaft { stiffness, .. } | Coupling::Backlash { stiffness, .. } => {
                w = w.max((stiffness / self.reduced_inertia()).sqrt());
            }
        }
        w / TAU
    }

    /// Torque on the load from the transmission, given the state (the motor feels its opposite).
    pub fn transmission_torque(&self, s: &State) -> f64 {
        let twist = s.q_motor - s.q_load;
        let rate = s.v_motor - s.v_load;
        match self.coupling {
            Coupling::Rigid => 0.0,
            Coupling::Shaft { stiffness, damping } => shaft_torque(twist, rate, stiffness, damping),
            Coupling::Backlash {
                gap,
                stiffness,
                damping,
            } => backlash_torque(twist, rate, gap, stiffness, damping),
        }
    }

    /// Torques that depend on the load's position only (they derive from a potential).
    pub fn load_potential_torque(&self, q_load: f64) -> f64 {
        let (ra, rp, rph) = self.ripple;
        let (mgl, gph) = self.gravity;
        ripple_torque(q_load, ra, rp, rph) + gravity_torque(q_load, mgl, gph)
    }

    /// Advance the state by `h` under the motor torque `tau` (held over the sub-step).
    pub fn step(&self, s: &mut State, tau: f64, h: f64) {
        let k = 0.5 * h;
        let drive = tau + bias_torque(self.bias);
        match self.coupling {
            Coupling::Rigid => {
                let j = self.total_inertia();
                let b = self.b_motor + self.b_load;
                let kick = |v: f64, q: f64| {
                    let t = drive + self.load_potential_torque(q);
                    friction_kick(v, t, k, j, b, self.b_positive, &self.friction)
                };
                s.v_motor = kick(s.v_motor, s.q_motor);
                s.q_motor += h * s.v_motor;
                s.v_motor = kick(s.v_motor, s.q_motor);
                s.q_load = s.q_motor;
                s.v_load = s.v_motor;
            }
            _ => {
                self.two_body_kick(s, drive, k);
                s.q_motor += h * s.v_motor;
                s.q_load += h * s.v_load;
                self.two_body_kick(s, drive, k);
            }
        }
    }

    /// Half kick of both bodies with the transmission torque of the current state.
    fn two_body_kick(&self, s: &mut State, drive: f64, k: f64) {
        let t = self.transmission_torque(s);
        s.v_motor = friction_kick(
            s.v_motor,
            drive - t,
            k,
            self.j_motor,
            self.b_motor,
            self.b_positive,
            &self.friction,
        );
        let t_load = t + self.load_potential_torque(s.q_load);
        s.v_load = (s.v_load + k * t_load / self.j_load) / (1.0 + k * self.b_load / self.j_load);
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self, s: &State) -> f64 {
        match self.coupling {
            Coupling::Rigid => 0.5 * self.total_inertia() * s.v_motor * s.v_motor,
            _ => 0.5 * (self.j_motor * s.v_motor * s.v_motor + self.j_load * s.v_load * s.v_load),
        }
    }

    /// Elastic energy stored in the transmission, J.
    pub fn elastic_energy(&self, s: &State) -> f64 {
        let twist = s.q_motor - s.q_load;
        match self.coupling {
            Coupling::Rigid => 0.0,
            Coupling::Shaft { stiffness, .. } => 0.5 * stiffness * twist * twist,
            Coupling::Backlash { gap, stiffness, .. } => {
                let pen = (twist.abs() - 0.5 * gap).max(0.0);
                0.5 * stiffness * pen * pen
            }
        }
    }
}

/// Half kick of the body that carries the dry friction, with Karnopp stick detection.
///
/// `tau` is every torque on the body except drag and dry friction, `k` the kick length,
/// `b`/`b_positive` the viscous coefficients (taken implicitly, at the new velocity).
///
/// * Inside the stick band |v| < Δv the contact holds whatever net torque stays below
///   breakaway: the velocity is set to exactly zero (no chatter). Above breakaway the body leaves
///   against the breakaway level.
/// * While sliding, the kinetic level opposes the motion. If the kick would carry the velocity
///   through zero (or into the band), the body stops there: it sticks if the net torque is below
///   breakaway, otherwise it reverses for the rest of the kick.
///
/// Δv is the speed one kick of breakaway torque can change, so a sliding body cannot jump the band.
pub fn friction_kick(
    v: f64,
    tau: f64,
    k: f64,
    j: f64,
    b: f64,
    b_positive: f64,
    fr: &DryFriction,
) -> f64 {
    let implicit = |v0: f64, torque: f64, dir: f64| {
        let bb = viscous_coefficient(dir, b, b_positive);
        (v0 + k * torque / j) / (1.0 + k * bb / j)
    };
    if !fr.is_active() {
        return implicit(v, tau, v);
    }
    let band = (2.0 * k * fr.breakaway / j).max(MIN_STICK_BAND);
    if v.abs() < band {
        if tau.abs() <= fr.breakaway {
            return 0.0;
        }
        let dir = tau.signum();
        return implicit(v, tau - dir * fr.breakaway, dir);
    }
    let dir = v.signum();
    let v_new = implicit(v, tau - dir * fr.kinetic_level(v), v);
    if v_new * dir > 0.0 {
        if v_new.abs() >= band || tau.abs() > fr.breakaway {
            return v_new;
        }
        return 0.0;
    }
    if tau.abs() <= fr.breakaway {
        return 0.0;
    }
    // Reverses inside the kick: the fraction of the kick spent coming to rest, then the rest
    // of it accelerating the other way against breakaway.
    let rest = v / (v - v_new);
    let dir = tau.signum();
    (1.0 - rest) * k * (tau - dir * fr.breakaway) / j
}
