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
//! Fingerprint (linearised, rigid model, position measured on the motor side): after each
//! velocity reversal the motor traverses the gap b with the load decoupled, so the true input
//! is `J1·a` instead of the model's `J·a`; the residual `r = u − J·a = −J_load·a` while in the
//! gap. Column `[−a·gap_b(t)]` with `gap_b(t) = 1` until the position has moved b since the last
//! reversal; its amplitude is the inertia beyond the gap (kg·m², not a model parameter — the
//! width b is the shape). Thesis-notes §7.13: flat dead zone of width b at torque reversal,
//! load lags after reversal.

use super::signal::{log_space, positive_or};
use super::{EffectLaws, Shape, Trajectory};

/// One-line description and fingerprint.
pub const DESCRIBE: &str = "backlash dead zone of width b in the transmission; flat zone of \
     width b at torque reversal in a stiffness test, load lags after each reversal, \
     residual −J_load·a while crossing the gap";

crate::define_params! {
    /// Total width of the dead zone (rad at the output).
    width: "rad" = 0.0, [0.0, 1.0], Shape;
}

/// `x` minus its clamp to ±half: zero inside the gap, shifted outside.
#[inline]
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
    let b = shape.backlash;
    let eps = shape.sign_velocity;
    let mut col = Vec::with_capacity(n);
    let mut dir = 0.0;
    let mut anchor = f64::NAN; // NaN: not yet known to be in contact
    for i in 0..n {
        let v = traj.velocity[i];
        let q = traj.position[i];
        let s = if v > eps {
            1.0
        } else if v < -eps {
            -1.0
        } else {
            dir
        };
        if s != dir {
            if dir != 0.0 {
                anchor = q; // reversal: the gap must be crossed again
            }
            dir = s;
        }
        let in_gap = anchor.is_finite() && (q - anchor).abs() < b;
        col.push(if in_gap { -traj.acceleration[i] } else { 0.0 });
    }
    vec![col]
}

/// Widths log-spaced from 1e-4 to 0.1 of the position span.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = positive_or(hi - lo, 1.0);
    let vmax = positive_or(traj.max_abs_velocity(), 1.0);
    log_space(1e-4 * span, 0.1 * span, 8)
        .into_iter()
        .map(|b| Shape {
            backlash: b,
            sign_velocity: 1e-3 * vmax,
            ..Shape::default()
        })
        .collect()
}
