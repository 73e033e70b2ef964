//! The slots effects install into, evaluated by the integrator every substep.
//!
//! Effects combine additively into a few physical places of the drive chain (thesis §3.2):
//! the actuator (command → applied torque), the friction curve of the friction node, the
//! transmission spring, and position-periodic / gravity torques. Keeping these as plain
//! structs of numbers (not trait objects) keeps the 10 kHz inner loop branch-light and
//! allocation-free. All values are output-referred SI.

use super::stribeck;

/// Friction curve of the friction node: direction-dependent Coulomb, stiction excess with a
/// Stribeck transition, and viscous (Table 4.1 columns), thesis §3.2 "Friction".
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrictionLaw {
    /// Coulomb level for positive motion (N·m, ≥ 0).
    pub coulomb_pos: f64,
    /// Coulomb level for negative motion (magnitude, N·m, ≥ 0).
    pub coulomb_neg: f64,
    /// Stiction minus Coulomb, positive direction (N·m, ≥ 0).
    pub excess_pos: f64,
    /// Stiction minus Coulomb, negative direction (magnitude, N·m, ≥ 0).
    pub excess_neg: f64,
    /// Stribeck velocity vs (rad/s, > 0 when an excess is present).
    pub stribeck_velocity: f64,
    /// Stribeck exponent δ.
    pub stribeck_exponent: f64,
    /// 1/vs (0 without a Stribeck excess), set by [`EffectLaws::finalize`].
    pub inv_stribeck_velocity: f64,
    /// Viscous coefficient, positive motion (N·m·s/rad).
    pub viscous_pos: f64,
    /// Viscous coefficient, negative motion (N·m·s/rad).
    pub viscous_neg: f64,
}

impl FrictionLaw {
    /// Static (breakaway) level for impending motion in direction `dir` (±1).
    #[inline(always)]
    pub fn breakaway(&self, dir: f64) -> f64 {
        if dir >= 0.0 {
            self.coulomb_pos + self.excess_pos
        } else {
            self.coulomb_neg + self.excess_neg
        }
    }

    /// Whether there is any dry friction (and hence a stick state).
    pub fn has_dry(&self) -> bool {
        self.coulomb_pos + self.coulomb_neg + self.excess_pos + self.excess_neg > 0.0
    }

    /// Whether the law is all zero.
    pub fn is_zero(&self) -> bool {
        !self.has_dry() && self.viscous_pos == 0.0 && self.viscous_neg == 0.0
    }

    /// Resisting torque while sliding with velocity `v ≠ 0` (same sign as `v`).
    ///
    /// Summed as `(coulomb + viscous·v) + excess·decay`: the Stribeck term is the last to be
    /// ready (an exp of the velocity), so it is added last, and the excess is folded into
    /// the exp's table factor ([`stribeck::excess_decay`]).
    #[inline(always)]
    pub fn sliding(&self, v: f64) -> f64 {
        if v > 0.0 {
            let base = self.coulomb_pos + self.viscous_pos * v;
            // Without a stiction excess the Stribeck term is exactly 0: skip its exp().
            if self.excess_pos > 0.0 {
                base + stribeck::excess_decay(
                    v,
                    self.inv_stribeck_velocity,
                    self.stribeck_exponent,
                    self.excess_pos,
                )
            } else {
                base
            }
        } else if v < 0.0 {
            let base = self.viscous_neg * v - self.coulomb_neg;
            if self.excess_neg > 0.0 {
                base - stribeck::excess_decay(
                    -v,
                    self.inv_stribeck_velocity,
                    self.stribeck_exponent,
                    self.excess_neg,
                )
            } else {
                base
            }
        } else {
            0.0
        }
    }
}

impl FrictionLaw {
    /// [`FrictionLaw::sliding`] in the friction node's form: (Coulomb + viscous part,
    /// Stribeck part, Stribeck part × `h`); the first two sum to `sliding(v)`. The Stribeck
    /// part is the last to be ready (an exp of the velocity), so the node subtracts it last,
    /// already multiplied by its h/I.
    #[inline(always)]
    pub fn sliding_parts(&self, v: f64, h: f64) -> (f64, f64, f64) {
        if v > 0.0 {
            let base = self.coulomb_pos + self.viscous_pos * v;
            if self.excess_pos > 0.0 {
                let (s, hs) = stribeck::excess_decay_pair(
                    v,
                    self.inv_stribeck_velocity,
                    self.stribeck_exponent,
                    self.excess_pos,
                    h,
                );
                (base, s, hs)
            } else {
                (base, 0.0, 0.0)
            }
        } else if v < 0.0 {
            let base = self.viscous_neg * v - self.coulomb_neg;
            if self.excess_neg > 0.0 {
                let (s, hs) = stribeck::excess_decay_pair(
                    -v,
                    self.inv_stribeck_velocity,
                    self.stribeck_exponent,
                    self.excess_neg,
                    h,
                );
                (base, -s, -hs)
            } else {
                (base, 0.0, 0.0)
            }
        } else {
            (0.0, 0.0, 0.0)
        }
    }
}

/// Transmission spring: soft-zone/stiffening compliance plus a backlash dead zone, and
/// structural damping while in contact (thesis §3.2 "Backlash", "Soft-zone").
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpringLaw {
    /// Whether a spring exists at all (compliance or backlash present); without one the
    /// transmission is rigid.
    pub present: bool,
    /// Stiffness beyond the knee (N·m/rad).
    pub k_hard: f64,
    /// Stiffness inside the soft zone (N·m/rad).
    pub k_soft: f64,
    /// Torque at the knee (N·m); 0 = linear spring.
    pub knee_torque: f64,
    /// Deflection at the knee (rad), set by [`EffectLaws::finalize`].
    pub knee_deflection: f64,
    /// Structural damping in contact (N·m·s/rad).
    pub damping: f64,
    /// Total backlash width (rad at the output).
    pub backlash: f64,
}

impl SpringLaw {
    /// Deflection beyond the backlash gap (0 inside the gap).
    #[inline(always)]
    pub fn engaged(&self, deflection: f64) -> f64 {
        super::backlash::dead_zone(deflection, 0.5 * self.backlash)
    }

    /// Transmitted torque for a deflection `d` (input minus output, rad) and deflection
    /// rate `dd`, from motor side to output side.
    #[inline(always)]
    pub fn torque(&self, d: f64, dd: f64) -> f64 {
        let e = self.engaged(d);
        if e == 0.0 {
            return 0.0;
        }
        super::compliance::elastic_with(
            e,
            self.k_soft,
            self.k_hard,
            self.knee_torque,
            self.knee_deflection,
        ) + self.damping * dd
    }

    /// Largest incremental stiffness (N·m/rad), for the integrator's stability check.
    pub fn max_stiffness(&self) -> f64 {
        self.k_hard.max(self.k_soft)
    }
}

/// Actuator chain: command → D/A quantisation → transport delay → deadband and
/// torque-constant nonlinearity (thesis §3.2 "Torque linearity", "Quantization", §2.7).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ActuatorLaw {
    /// D/A step (N·m, output-referred); 0 = none.
    pub quant_step: f64,
    /// How much of the quantisation error is present (1 = all).
    pub quant_gain: f64,
    /// Transport delay (s).
    pub delay: f64,
    /// Deadband half-width (N·m).
    pub deadband: f64,
    /// Torque-constant sag c: applied = dz(u)·(1 − c·|u|/scale), dz = the deadband.
    pub nonlinearity: f64,
    /// Scale of the nonlinearity (N·m).
    pub input_scale: f64,
}

impl ActuatorLaw {
    /// Applied torque for an (already delayed) command `u`, before the offset: quantised, then
    /// the deadband removed, then the torque constant sagging with |command|. Each effect's
    /// residual is exactly its fingerprint column times its amplitude.
    #[inline(always)]
    pub fn shape(&self, u: f64) -> f64 {
        let q = if self.quant_step > 0.0 {
            u - self.quant_gain * super::quantization::error(u, self.quant_step)
        } else {
            u
        };
        let mut x = q;
        if self.deadband > 0.0 {
            x -= super::deadband::dead(q, self.deadband);
        }
        if self.nonlinearity != 0.0 && self.input_scale > 0.0 {
            x -= self.nonlinearity * x * q.abs() / self.input_scale;
        }
        x
    }
}

/// Position-periodic torque `sin·sin(2πq/P) + cos·cos(2πq/P)`, optionally growing with load.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeriodicTorque {
    /// Sine amplitude (N·m).
    pub sin: f64,
    /// Cosine amplitude (N·m).
    pub cos: f64,
    /// Spatial angular frequency 2π/P (rad⁻¹ of the angle it is a function of).
    pub wavenumber: f64,
    /// Amplitude growth per N·m of transmitted torque (1/(N·m)).
    pub load_gain: f64,
}

impl PeriodicTorque {
    /// Resisting torque at angle `q` with transmitted torque `load`.
    #[inline(always)]
    pub fn torque(&self, q: f64, load: f64) -> f64 {
        let (s, c) = crate::fastmath::sin_cos(self.wavenumber * q);
        (self.sin * s + self.cos * c) * (1.0 + self.load_gain * load.abs())
    }

    /// The integrator's form of `sin·sin(k·q) + cos·cos(k·q)` (without the load growth): a
    /// precomputed [`Harmonic`](crate::fastmath::Harmonic).
    pub fn harmonic(&self) -> crate::fastmath::Harmonic {
        crate::fastmath::Harmonic::new(self.sin, self.cos, self.wavenumber)
    }

    /// Whether the torque is identically zero.
    pub fn is_zero(&self) -> bool {
        self.sin == 0.0 && self.cos == 0.0
    }
}

impl EffectLaws {
    /// Called once after every effect has installed: effects add into shared slots, and only
    /// the sums have physical bounds (friction levels cannot be negative).
    pub fn finalize(&mut self) {
        let f = &mut self.friction;
        for x in [
            &mut f.coulomb_pos,
            &mut f.coulomb_neg,
            &mut f.excess_pos,
            &mut f.excess_neg,
            &mut f.viscous_pos,
            &mut f.viscous_neg,
        ] {
            *x = x.max(0.0);
        }
        f.inv_stribeck_velocity = if f.stribeck_velocity > 0.0 {
            1.0 / f.stribeck_velocity
        } else {
            0.0
        };
        let s = &mut self.spring;
        s.knee_deflection = super::compliance::knee_deflection(s.k_soft, s.knee_torque);
        if s.knee_deflection == 0.0 {
            s.knee_torque = 0.0;
        }
    }
}

/// Which node an [`AdditiveTorque`] acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Node {
    /// The motor node (angle/velocity passed output-referred).
    Motor,
    /// The output node (the rigid plant's only node).
    Output,
}

/// Extension point: a resisting torque `law(params, q, v, load)` on one node, for a new effect
/// that fits none of the dedicated slots. Its module's `install` pushes one of these, and the
/// integrator sums them — so such an effect needs no change to the integrator. (`q`, `v` are
/// output-referred; `load` is the transmitted torque.)
#[derive(Clone, Copy, Debug)]
pub struct AdditiveTorque {
    /// Where it acts.
    pub node: Node,
    /// The torque law.
    pub law: fn(&[f64; 4], f64, f64, f64) -> f64,
    /// Up to four numbers for the law.
    pub params: [f64; 4],
}

/// Everything the effects of a model install; the integrator evaluates it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EffectLaws {
    /// Friction at the friction node (the output for geared plants: Table 4.1 is output-side).
    pub friction: FrictionLaw,
    /// Transmission spring (compliance + backlash).
    pub spring: SpringLaw,
    /// Actuator chain.
    pub actuator: ActuatorLaw,
    /// Transmission ripple, a function of output angle.
    pub ripple: PeriodicTorque,
    /// Motor cogging; `wavenumber` is per rad of *motor* angle (cycles per motor rev).
    pub cogging: PeriodicTorque,
    /// Gravity: `sin·sin(q) + cos·cos(q)` of the output angle (a PeriodicTorque with k = 1).
    pub gravity: PeriodicTorque,
    /// Further resisting torques of effects without a dedicated slot (see [`AdditiveTorque`]).
    pub additive: Vec<AdditiveTorque>,
}

impl PartialEq for AdditiveTorque {
    fn eq(&self, other: &Self) -> bool {
        self.node == other.node
            && self.params == other.params
            && std::ptr::fn_addr_eq(self.law, other.law)
    }
}

impl EffectLaws {
    /// Sum of the additive torques on `node`.
    #[inline(always)]
    pub fn additive_on(&self, node: Node, q: f64, v: f64, load: f64) -> f64 {
        self.additive
            .iter()
            .filter(|a| a.node == node)
            .map(|a| (a.law)(&a.params, q, v, load))
            .sum()
    }
}
