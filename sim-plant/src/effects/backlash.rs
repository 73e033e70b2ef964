//! Backlash: a dead zone of lost motion in the transmission (thesis §3.2 "Backlash": Cyclo
//! 29:1 0.8°, KAMO 10:1 1.1° at low preload; §4.63 inside the gap only the motor-side inertia
//! remains, ωn* = ωn·√(M_total/M_s)).
//!
//! Dynamics: the transmission spring sees the deflection minus the gap,
//! `δ_e = dead_zone(δ, b/2)`; inside the gap no torque and no structural damping is
//! transmitted, so the plant switches between "motor alone" and "motor + load" (contact and
//! separation fall out of the spring law, no event logic needed). Lumped at the output, in
//! output radians (the thesis lumps it at the input; the two differ by N).
//!
//! Fingerprint (linearised, rigid model, position measured on the motor side): the gap is
//! crossed whenever the transmitted torque changes sign — at a velocity reversal for a
//! friction-dominated load (the thesis's "load lags the motor after each reversal"), at a sign
//! change of the input for an inertia-dominated one (`Shape::backlash_on_input`; the grid
//! offers both). While crossing, the motor moves with the load decoupled, so the true input is
//! `J1·a` instead of the model's `J·a`, and the residual `r = u − J·a = −J_load·a`. Column
//! `[−a·gap_b(t)]` with `gap_b(t) = 1` from the trigger until the motor has moved b relative
//! to the decoupled load, which coasts on at the velocity it had at the trigger; its
//! amplitude is the inertia beyond the gap (kg·m², not a model parameter — the width b is the
//! shape). The impacts at the ends of the gap are outside this linearisation. Thesis-notes
//! §7.13: flat dead zone of width b at torque reversal, load lags after reversal.

use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "backlash dead zone of width b in the transmission; flat zone of \
     width b at torque reversal in a stiffness test, load lags after each reversal, \
     residual −J_load·a while crossing the gap";

/// Amplitude of the fingerprint column: the inertia beyond the gap (kg·m²), a derived
/// quantity, not a model parameter.
pub const AMPLITUDES: &[&str] = &["load_inertia"];

/// Admissible sign of the first amplitude: positive (the effect consumes input).
pub const SIGN: Option<f64> = Some(1.0);

crate::define_params! {
    /// Total width of the dead zone (rad at the output).
    width: "rad" = 0.0, [0.0, 1.0], Shape;
}

/// `x` minus its clamp to ±half: zero inside the gap, shifted outside.
#[inline(always)]
pub fn dead_zone(x: f64, half: f64) -> f64 {
    if x > half {
        x - half
    } else if x < -half {
        x + half
    } else {
        0.0
    }
}

/// A spring must exist for backlash to mean anything; compliance sets its stiffness.
pub fn install(p: &Params, laws: &mut EffectLaws) {
    laws.spring.present = true;
    laws.spring.backlash = p.width.value;
    if laws.spring.k_hard == 0.0 {
        // No compliance effect: contact stiffness of the compliance default.
        laws.spring.k_hard = super::compliance::DEFAULT_STIFFNESS;
        laws.spring.k_soft = super::compliance::DEFAULT_STIFFNESS;
    }
}

/// `[−a·gap_b(t)]`.
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let b = shape.backlash_width;
    let (trigger, eps) = if shape.backlash_on_input {
        (&traj.input[..n], 1e-3 * traj.max_abs_input())
    } else {
        (&traj.velocity[..n], shape.sign_epsilon)
    };
    let mut col = Vec::with_capacity(n);
    let mut dir = 0.0;
    // Load position, velocity and sample index at the last trigger (NaN: not yet in contact).
    let (mut anchor, mut anchor_v, mut anchor_i) = (f64::NAN, 0.0, 0);
    for (i, (&x, &q)) in trigger.iter().zip(&traj.position[..n]).enumerate() {
        let s = if x > eps {
            1.0
        } else if x < -eps {
            -1.0
        } else {
            dir
        };
        if s != dir {
            if dir != 0.0 {
                // The transmitted torque reversed: the gap must be crossed.
                anchor = q;
                anchor_v = traj.velocity[i];
                anchor_i = i;
            }
            dir = s;
        }
        let load = anchor + anchor_v * (i - anchor_i) as f64 * traj.dt;
        let in_gap = anchor.is_finite() && (q - load).abs() < b;
        col.push(if in_gap { -traj.acceleration[i] } else { 0.0 });
    }
    vec![col]
}

/// Widths log-spaced from 1e-4 to 0.1 of the position span, for both triggers.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = positive_or(hi - lo, 1.0);
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    let mut out = Vec::new();
    for on_input in [false, true] {
        for b in log_space(1e-4 * span, 0.1 * span, 8) {
            out.push(Shape {
                backlash_width: b,
                backlash_on_input: on_input,
                sign_epsilon: 1e-3 * vmax,
                ..Shape::default()
            });
        }
    }
    out
}
