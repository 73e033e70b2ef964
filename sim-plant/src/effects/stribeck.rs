//! Stiction above Coulomb and the Stribeck transition (thesis §3.2, §2.11 Armstrong 1988;
//! Table 4.1 stiction columns: τs/τc ≈ 1.6–2.5).
//!
//! Dynamics: the breakaway level is τc + excess; while sliding the dry friction is
//! `τc + excess·exp(−(|v|/vs)^δ)` — a negative slope at low speed that drives stick-slip. The
//! stick state itself (hold below breakaway, release above) lives in the integrator.
//!
//! Fingerprint: `[sign_ε(v)·exp(−(|v|/vs)^δ)]`, shapes vs and δ (thesis-notes §7.2/7.3: residual
//! peaks near velocity zero-crossings and grows as speed falls).

use super::signal::{log_space, positive_or, smooth_sign};
use super::{EffectLaws, Shape, Trajectory};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "stiction above Coulomb with a Stribeck transition, \
     τc + Δ·exp(-(|v|/vs)^δ); residual peaks at low speed and velocity zero-crossings, \
     delayed breakaway, stick-slip";

/// Names of the fingerprint columns' amplitudes, in column order (the fitter's names).
pub const AMPLITUDES: &[&str] = &["excess"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

crate::define_params! {
    /// Stiction minus Coulomb, Δ = τs − τc (N·m), both directions.
    excess: "N·m" = 0.0, [0.0, 1e6], Amplitude(0);
    /// Stribeck velocity vs (rad/s, output).
    velocity: "rad/s" = 0.02, [1e-9, 1e6], Shape;
    /// Stribeck exponent δ (1 = exponential, 2 = Gaussian).
    exponent: "1" = 2.0, [0.1, 10.0], Shape;
}

/// `exp(−(v/vs)^δ)` for `v ≥ 0`, cheap for the common δ = 2 and far from zero.
#[inline(always)]
pub fn decay(v: f64, vs: f64, delta: f64) -> f64 {
    if vs <= 0.0 {
        return 0.0;
    }
    decay_inv(v, 1.0 / vs, delta)
}

/// [`decay`] with 1/vs precomputed.
#[inline(always)]
pub fn decay_inv(v: f64, inv_vs: f64, delta: f64) -> f64 {
    excess_decay(v, inv_vs, delta, 1.0)
}

/// `excess·exp(−(v/vs)^δ)` for `v ≥ 0` with 1/vs precomputed: the integrator's form, with no
/// division on the friction node's dependency chain and the excess folded into the exp
/// ([`crate::fastmath::exp_neg_scaled`], inline and table-based: at low speed this is on the
/// chain every substep).
#[inline(always)]
pub fn excess_decay(v: f64, inv_vs: f64, delta: f64, excess: f64) -> f64 {
    if delta == 2.0 {
        // The common Gaussian case: the exp's argument straight from v² (the constant is
        // loop-invariant in the integrator), one multiply shorter than (v/vs)² then ·256/ln2.
        let v2 = v * v;
        let e = v2 * (inv_vs * inv_vs);
        // exp(−36) ≈ 2e-16: below f64 resolution of any friction level, skip the exp().
        return if e > 36.0 {
            0.0
        } else {
            let t = v2 * (inv_vs * inv_vs * -crate::fastmath::EXP_PER_LN2);
            crate::fastmath::exp_neg_scaled_t(t, excess)
        };
    }
    let x = v * inv_vs;
    let e = if delta == 1.0 { x } else { x.powf(delta) };
    if e > 36.0 {
        0.0
    } else {
        crate::fastmath::exp_neg_scaled(e, excess)
    }
}

/// [`excess_decay`] and the same times `h` (the friction node's h/I), from one exp.
#[inline(always)]
pub fn excess_decay_pair(v: f64, inv_vs: f64, delta: f64, excess: f64, h: f64) -> (f64, f64) {
    if delta == 2.0 {
        let v2 = v * v;
        let e = v2 * (inv_vs * inv_vs);
        return if e > 36.0 {
            (0.0, 0.0)
        } else {
            let t = v2 * (inv_vs * inv_vs * -crate::fastmath::EXP_PER_LN2);
            crate::fastmath::exp_neg_scaled_t2(t, excess, excess * h)
        };
    }
    let d = excess_decay(v, inv_vs, delta, excess);
    (d, d * h)
}

/// Add the excess to both directions and set the transition shape.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    let f = &mut laws.friction;
    f.excess_pos += p.excess.value;
    f.excess_neg += p.excess.value;
    f.stribeck_velocity = p.velocity.value;
    f.stribeck_exponent = p.exponent.value;
}

/// `[sign_ε(v)·exp(−(|v|/vs)^δ)]` (exact exponent, no cut-off).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let vs = positive_or(shape.stribeck_velocity, 1e-3);
    let d = shape.stribeck_exponent;
    vec![traj.velocity[..traj.len()]
        .iter()
        .map(|&v| smooth_sign(v, shape.sign_epsilon) * (-(v.abs() / vs).powf(d)).exp())
        .collect()]
}

/// Log grid of vs from 0.3 % to 30 % of the largest |v|, for δ = 1 and 2.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    let mut out = Vec::new();
    for delta in [1.0, 2.0] {
        for vs in log_space(3e-3 * vmax, 0.3 * vmax, 8) {
            out.push(Shape {
                stribeck_velocity: vs,
                stribeck_exponent: delta,
                sign_epsilon: 1e-3 * vmax,
                ..Shape::default()
            });
        }
    }
    out
}
