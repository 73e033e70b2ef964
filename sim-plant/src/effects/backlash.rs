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
//! Fingerprint (rigid model, position measured on the motor side): with δ = x_motor − x_load
//! the true input is `J1·a + J2·a_load + b·v_load`, so a rigid model `J·a + b·v` (J = J1 + J2)
//! leaves exactly `r = −J2·(δ̈ + δ̇/τ)`, τ = J2/b the load's viscous time constant — zero while
//! the gap is closed (δ = ±b/2 constant), the lost motion while it is crossed. The column is
//! that expression for a δ(t) simulated from the measured motion: the load is a mass that
//! coasts through the gap with its own viscous decay (velocity × e^(−t/τ)) and is pushed along
//! when the motor reaches an edge of the gap (a play operator with inertia). Separation needs
//! no trigger: it happens when the motor decelerates faster than the coasting load, whether
//! because the velocity reverses, the input reverses or the loop chatters; the impact at the
//! far edge is inelastic (the load takes on the motor's velocity if that pushes it faster).
//! δ goes through the residual's low-pass before it is differentiated, as the motion did.
//! Amplitude: the load inertia J2 (kg·m², not a model parameter); shapes: the width b and τ.
//! Thesis-notes §7.13: flat dead zone of width b at torque reversal, load lags after reversal.

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

/// Motor-minus-load deflection δ(t) of a load that coasts inside a gap of total width `b`
/// (viscous time constant `tau`, 0 = none) and is pushed along at its edges by the motor
/// (`position`, `velocity`).
pub fn gap_deflection(position: &[f64], velocity: &[f64], b: f64, tau: f64, dt: f64) -> Vec<f64> {
    let half = 0.5 * b;
    let n = position.len().min(velocity.len());
    let (decay, drift) = if tau > 0.0 {
        let d = (-dt / tau).exp();
        (d, tau * (1.0 - d))
    } else {
        (1.0, dt)
    };
    let mut out = Vec::with_capacity(n);
    let (mut x2, mut v2) = match (position.first(), velocity.first()) {
        (Some(&x), Some(&v)) => (x, v),
        _ => return out,
    };
    for i in 0..n {
        if i > 0 {
            x2 += drift * v2;
            v2 *= decay;
        }
        let (x, v) = (position[i], velocity[i]);
        let d = x - x2;
        if d > half {
            x2 = x - half;
            v2 = v2.max(v);
        } else if d < -half {
            x2 = x + half;
            v2 = v2.min(v);
        }
        out.push(x - x2);
    }
    out
}

/// Seconds of the record before the trajectory over which [`gap_deflection`] runs: the load's
/// place in the gap at the trajectory's first sample is then set by the motion before it (any
/// reversal sweeps the gap) instead of being assumed mid-gap. Bounded so that a shape search on
/// a window of a long record does not simulate the whole record for every shape.
pub const PRE_ROLL_S: f64 = 2.0;

/// Cut-off periods of the record after the trajectory that the low-pass of δ sees, so that the
/// trajectory's last samples are not at the forward–backward filter's edge.
pub const POST_ROLL_PERIODS: f64 = 5.0;

/// `[−(δ̈ + δ̇/τ)]` of the low-passed [`gap_deflection`], simulated over the trajectory and up
/// to [`PRE_ROLL_S`] of the record before it (and low-passed with [`POST_ROLL_PERIODS`] after
/// it) when the trajectory carries its whole record's motion
/// ([`Trajectory::recorded_motion`]).
pub fn fingerprint(traj: &Trajectory, shape: &Shape) -> Vec<Vec<f64>> {
    let n = traj.len();
    let tau = shape.backlash_load_time;
    let dt = traj.dt;
    let (x, v, win) = traj.recorded_motion();
    let pre = if dt > 0.0 {
        ((PRE_ROLL_S / dt).ceil() as usize).min(win.start)
    } else {
        0
    };
    let post = if dt > 0.0 && traj.lowpass_hz > 0.0 {
        ((POST_ROLL_PERIODS / (traj.lowpass_hz * dt)).ceil() as usize).min(x.len() - win.end)
    } else {
        0
    };
    let span = win.start - pre..win.end + post;
    let delta = gap_deflection(
        &x[span.clone()],
        &v[span],
        shape.backlash_width,
        tau,
        dt,
    );
    let d = traj.lowpass(&delta);
    let mut col = vec![0.0; n];
    for (i, c) in col.iter_mut().enumerate() {
        let k = pre + i;
        if k == 0 || k + 1 >= d.len() {
            continue;
        }
        let acc = (d[k + 1] - 2.0 * d[k] + d[k - 1]) / (dt * dt);
        let vel = (d[k + 1] - d[k - 1]) / (2.0 * dt);
        *c = -(acc + if tau > 0.0 { vel / tau } else { 0.0 });
    }
    // The record's own first/last samples have no neighbour: repeat the next one in.
    if n >= 3 {
        if pre == 0 {
            col[0] = col[1];
        }
        if post == 0 {
            col[n - 1] = col[n - 2];
        }
    }
    vec![col]
}

/// Load time constants of the shape grid (s; 0 = no decay), besides the ones scaled on the
/// record's own rigid time constant (see [`shape_grid`]).
pub const LOAD_TIMES: [f64; 4] = [0.1, 0.5, 2.5, 0.0];

/// Fractions of the rigid time constant J/b in the shape grid: the load's own J2/b_load is
/// that fraction J2/J when all the viscous friction is on the load side.
pub const LOAD_FRACTIONS: [f64; 4] = [0.3, 0.5, 0.7, 0.9];

/// J/b of the rigid fit `input ≈ J·a + b·v + c·sign v + d` on the trajectory (None if either
/// is not positive): the scale of the load's viscous time constant.
pub fn rigid_time_constant(traj: &Trajectory) -> Option<f64> {
    let rows = (0..traj.len()).map(|i| {
        let (v, a) = (traj.velocity[i], traj.acceleration[i]);
        let s = if v == 0.0 { 0.0 } else { v.signum() };
        ([a, v, s, 1.0], traj.input[i])
    });
    let x = crate::experiments::least_squares(rows)?;
    let (j, b) = (x[0], x[1]);
    (j > 0.0 && b > 0.0 && (j / b).is_finite()).then(|| j / b)
}

/// Widths log-spaced from 3e-4 to 0.1 of the position span, for each of [`LOAD_TIMES`] and
/// [`LOAD_FRACTIONS`] of the record's [`rigid_time_constant`]. The fit is sharp in τ (it sets
/// the load's deceleration while it crosses the gap, against a relative deceleration of the
/// motor that is often a small fraction of it), so the generic ×5 steps alone miss it.
pub fn shape_grid(traj: &Trajectory) -> Vec<Shape> {
    let n = traj.len();
    let (lo, hi) = traj.position[..n]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &q| (l.min(q), h.max(q)));
    let span = positive_or(hi - lo, 1.0);
    let mut taus = LOAD_TIMES.to_vec();
    if let Some(t) = rigid_time_constant(traj) {
        taus.extend(LOAD_FRACTIONS.iter().map(|f| f * t));
    }
    let mut out = Vec::new();
    for tau in taus {
        for b in log_space(3e-4 * span, 0.1 * span, 7) {
            out.push(Shape {
                backlash_width: b,
                backlash_load_time: tau,
                ..Shape::default()
            });
        }
    }
    out
}

/// Around the best grid shape: widths within ±60 % (steps of 8 %; the coarse grid's step is
/// ×2.6 and the fit's minimum in the width only about ±15 % wide) and load time constants
/// within a factor 2 (steps of 20 %; from "no decay": the long ones above the grid's 2.5 s).
pub fn refine_grid(_traj: &Trajectory, best: &Shape) -> Vec<Shape> {
    let (b0, t0) = (best.backlash_width, best.backlash_load_time);
    let taus: Vec<f64> = if t0 > 0.0 {
        (-4..=4).map(|k| t0 * 1.2f64.powi(k)).collect()
    } else {
        vec![4.0, 6.3, 10.0, 0.0]
    };
    let mut out = Vec::new();
    for &tau in &taus {
        for k in -6..=6 {
            out.push(Shape {
                backlash_width: b0 * 1.08f64.powi(k),
                backlash_load_time: tau,
                ..Shape::default()
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shape grid's time-constant scale is J/b of the rigid fit, whatever the Coulomb
    /// level and offset riding on the input.
    #[test]
    fn rigid_time_constant_is_inertia_over_damping() {
        let n = 2000;
        let dt = 1e-3;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let q: Vec<f64> = t.iter().map(|t| (3.0 * t).sin() + 0.3 * (11.0 * t).sin()).collect();
        let v: Vec<f64> = t
            .iter()
            .map(|t| 3.0 * (3.0 * t).cos() + 3.3 * (11.0 * t).cos())
            .collect();
        let a: Vec<f64> = t
            .iter()
            .map(|t| -9.0 * (3.0 * t).sin() - 36.3 * (11.0 * t).sin())
            .collect();
        let u: Vec<f64> = v
            .iter()
            .zip(&a)
            .map(|(v, a)| 0.02 * a + 0.05 * v + 0.1 * v.signum() - 0.03)
            .collect();
        let traj = Trajectory::unfiltered(dt, &u, &q, &v, &a);
        let tau = rigid_time_constant(&traj).expect("J and b positive");
        assert!((tau - 0.4).abs() < 1e-9, "J/b = {tau}");
        assert_eq!(shape_grid(&traj).len(), 7 * (LOAD_TIMES.len() + LOAD_FRACTIONS.len()));
    }

    /// A window of a record gets the column the whole record has there: the load's place in
    /// the gap at the window's start comes from the motion before it (pre-roll), not from an
    /// assumed mid-gap start — which, with the motion parked at an edge, is a crossing that
    /// never happened.
    #[test]
    fn window_column_is_the_records_column_there() {
        let dt = 1e-3;
        let n = 3000;
        let q: Vec<f64> = (0..n)
            .map(|k| 0.2 * (std::f64::consts::TAU * 0.7 * k as f64 * dt).sin())
            .collect();
        let v: Vec<f64> = (0..n)
            .map(|k| {
                0.2 * std::f64::consts::TAU * 0.7 * (std::f64::consts::TAU * 0.7 * k as f64 * dt).cos()
            })
            .collect();
        let zero = vec![0.0; n];
        let shape = Shape {
            backlash_width: 0.02,
            backlash_load_time: 0.3,
            ..Shape::default()
        };
        let whole = fingerprint(&Trajectory::unfiltered(dt, &zero, &q, &v, &zero), &shape);
        let w = 700..2200;
        let mut traj = Trajectory::unfiltered(
            dt,
            &zero[w.clone()],
            &q[w.clone()],
            &v[w.clone()],
            &zero[w.clone()],
        );
        traj.raw_offset = w.start;
        traj.raw_position = &q;
        traj.raw_velocity = &v;
        let got = fingerprint(&traj, &shape);
        for (i, (a, b)) in got[0].iter().zip(&whole[0][w.clone()]).enumerate() {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "sample {i}: {a} vs {b}");
        }
        // Without the record's motion the window starts its load mid-gap: a different column.
        traj.raw_position = &[];
        let alone = fingerprint(&traj, &shape);
        let diff = alone[0]
            .iter()
            .zip(&whole[0][w])
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff > 1.0, "window-started column equals the record's ({diff})");
    }
}
