//! The second truth, written from scratch and independently of [`mod@super::truth`] and of the
//! workbench: a robot joint as a physicist would write it.
//!
//! Physics: a motor rotor and a load, rigid or joined by an elastic shaft or a gear mesh with
//! free play (dead-zone spring with contact damping); viscous drag; switching Coulomb/Stribeck
//! friction with Karnopp stick detection at the motor; position-periodic ripple and gravity at
//! the load; a torque bias; an actuator path with D/A quantisation and transport delay.
//!
//! Numerics: velocity Verlet on a fixed fine grid (h = T/m, m even, ≥ 10 per sample,
//! ≥ 20 per period of the fastest mode, h ≤ 50 µs), drag and dry friction taken implicitly in
//! each half kick. See [`joint`] for why.
//!
//! Without a hidden effect the joint is one rigid body with viscous drag.
//!
//! Conventions worth knowing:
//! * Backlash at amplitude 0 is the rigid null; any gap > 0 brings its 40–60 Hz tooth
//!   stiffness with it. Compliance at 0 (mode at ∞) and above 5 kHz is rigid too.
//! * Stribeck at amplitude 0 keeps its drawn Coulomb level ("Coulomb only").
//! * Quantization, at every amplitude including 0: the logged command is exact and
//!   `input_noise[k]` is the torque *added* after the D/A over [t_k, t_k+T):
//!   `applied = dac(u_k) + input_noise[k]`. Elsewhere `input[k] = u_k + input_noise[k]` and
//!   the motor gets u_k.
//! * The input-noise σ is a fraction (drawn per seed, 0.2–1 %) of the *planned* RMS command
//!   (feed-forward + dither), so the null and effect records of a seed carry identical noise.
//! * The controller always reads q(t_k); Mid logging only moves the logged sample to
//!   t_k + T/2 (m is even, so that instant is on the fine grid).

pub mod control;
pub mod excite;
pub mod joint;
pub mod plant;
pub mod rng;
pub mod sim;
pub mod torques;

use crate::hidden::record::{Conditions, Excitation, Family, Truth, TruthRecord, Which};
use excite::plan;
use plant::{draw_plant, MAX_DELAY};
use sim::scenario;
use std::f64::consts::TAU;

/// How far (rad) the open-loop chirp may drift at the nominal amplitude of an effect that pushes
/// one way (bias, one-sided drag): without feedback nothing pulls the joint back.
const OPEN_LOOP_DRIFT: f64 = 0.5;

/// The truth: velocity-Verlet joint with Karnopp friction.
#[derive(Debug, Default, Clone, Copy)]
pub struct VerletKarnopp;

impl Truth for VerletKarnopp {
    fn name(&self) -> &'static str {
        "physicist"
    }

    fn record(
        &self,
        seed: u64,
        effects: &[(Family, f64)],
        cond: &Conditions,
        which: Which,
    ) -> Result<TruthRecord, String> {
        scenario(seed, effects, cond, which)?
            .run()
            .map(|(rec, _)| rec)
    }

    fn nominal_amplitude(&self, seed: u64, family: Family, cond: &Conditions) -> f64 {
        nominal_amplitude(seed, family, cond)
    }
}

/// Starting amplitudes: torque effects at ~5 % of the RMS command (gravity 20 %, at most a fifth
/// of the loop stiffness), a 10 mrad gap, a 20 Hz shaft mode, a 1.5 ms delay. With the open-loop
/// chirp a bias, gravity or one-sided drag makes the joint drift (nothing pulls it back), so
/// there they are capped to ~0.5 rad of drift over the record.
pub fn nominal_amplitude(seed: u64, family: Family, cond: &Conditions) -> f64 {
    let p = draw_plant(seed);
    let j = p.joint.total_inertia();
    let b = p.joint.b_motor + p.joint.b_load;
    let dur = cond.duration.max(cond.dt);
    let pl = plan(seed, Which::Estimation, cond, j, b);
    let u = pl.rms_command;
    let open = cond.excitation == Excitation::OpenLoopChirp;
    // Displacement per N·m of steady bias from rest: (1/B)·(T − τ(1 − e^(−T/τ))), τ = J/B.
    let tau = j / b;
    let drift_per_torque = (dur - tau * (1.0 - (-dur / tau).exp())) / b;
    let bias_cap = |a: f64| {
        if open {
            a.min(OPEN_LOOP_DRIFT / drift_per_torque)
        } else {
            a
        }
    };
    match family {
        Family::Offset => bias_cap(0.05 * u),
        Family::Coulomb | Family::Stribeck | Family::Ripple | Family::Quantization => 0.05 * u,
        Family::Asymmetry => {
            let a = 0.05 * u / pl.rms_speed.max(1e-6);
            if open {
                // Mean drag a·⟨v⁺⟩ drives a drift speed a·⟨v⁺⟩/B.
                a.min(OPEN_LOOP_DRIFT * b / (pl.mean_positive_speed.max(1e-6) * dur))
            } else {
                a
            }
        }
        Family::Gravity => {
            // Open loop the arm starts off its hanging point: the sag acts as a bias.
            let kp = j * (TAU * p.loop_hz).powi(2);
            bias_cap((0.2 * u).min(0.2 * kp))
        }
        Family::Backlash => 0.01,
        Family::Compliance => 9.0,
        Family::Delay => 1.5e-3_f64.min(MAX_DELAY),
    }
}
